"""A results folder made by somebody else is read bounded: a JSON file nested without end, a
YAML document of nested aliases, a named pipe, a device or a file too large for what it is are
each refused in one line naming the file, at once, and never end in a traceback or a hang."""

import json
import os
import signal
import zipfile
from contextlib import contextmanager
from pathlib import Path

import numpy as np
import pytest
import yaml
from omegaconf._utils import get_yaml_loader
from typer.testing import CliRunner

from tavc_cli import readers
from tavc_cli.cli import app
from tavc_cli.errors import TavcError
from tavc_cli.readers import MAX_DEPTH, json_depth, load_json, load_yaml, read_bounded

RESULTS = Path(__file__).resolve().parents[1] / "results"
SMOKE = ["scale=smoke", "duration_s=120", "convergence_s=20", "executor.n_jobs=1", "trials=2", "baseline_trials=2",
         "static_trials=2"]
NESTED = "[" * 100_000 + "]" * 100_000
BOMB = "a: &a [x, x, x, x, x, x, x, x, x]\n" + "".join(
    f"{chr(98 + k)}: &{chr(98 + k)} [{', '.join([f'*{chr(97 + k)}'] * 9)}]\n" for k in range(9))
runner = CliRunner()


@contextmanager
def within(seconds: int):
    """The block must end within `seconds` (SIGALRM raises otherwise)."""
    def _late(signum, frame):
        raise TimeoutError(f"still busy after {seconds} s")

    previous = signal.signal(signal.SIGALRM, _late)
    signal.alarm(seconds)
    try:
        yield
    finally:
        signal.alarm(0)
        signal.signal(signal.SIGALRM, previous)


@pytest.fixture
def copied(finished_run, run_copy, tmp_path) -> tuple[Path, Path]:
    """A results folder holding a copy of a finished smoke run (shared, made once), and the copy."""
    return tmp_path / "results", run_copy(finished_run(*SMOKE, name="initial_distribution"), into="results")


def _refused(results: Path, path: Path) -> str:
    with within(20):
        result = runner.invoke(app, ["report", str(results)])
    assert result.exit_code == 1, result.output
    lines = result.output.strip().splitlines()
    assert len(lines) == 1 and "Traceback" not in result.output, result.output
    assert lines[0].startswith(f"error: {path}: cannot be read ("), lines[0]
    assert not (results / "REPORT.md").exists()
    return lines[0]


def test_a_nested_provenance_json_is_refused(copied):
    results, run = copied
    (run / "provenance.json").write_text(NESTED)
    line = _refused(results, run / "provenance.json")
    assert f"nested more than {MAX_DEPTH} levels deep" in line and line.endswith("rerun its experiment to rewrite it")


def test_a_nested_manifest_is_refused(copied):
    results, run = copied
    (run / ".tavc.json").write_text(NESTED)
    line = _refused(results, run / ".tavc.json")
    assert f"nested more than {MAX_DEPTH} levels deep" in line and line.endswith("taken as tavc's")


def test_an_alias_bomb_config_is_refused(copied):
    results, run = copied
    (run / "config.yaml").write_text(BOMB)
    line = _refused(results, run / "config.yaml")
    assert "a YAML alias" in line


def test_a_pipe_named_provenance_json_never_hangs(copied):
    results, run = copied
    (run / "provenance.json").unlink()
    os.mkfifo(run / "provenance.json")
    with within(20):
        result = runner.invoke(app, ["report", str(results)])
    assert result.exit_code != 0 and "Traceback" not in result.output, result.output
    assert len(result.output.strip().splitlines()) == 1, result.output  # a run without its provenance: unfinished
    with within(5), pytest.raises(TavcError, match=r"cannot be read \(it is a named pipe \(FIFO\), not a file\)"):
        load_json(run / "provenance.json")


def test_an_oversized_provenance_json_is_refused(copied):
    results, run = copied
    with open(run / "provenance.json", "ab") as fh:
        fh.truncate(readers.JSON_LIMIT + 1)  # sparse: nothing written
    line = _refused(results, run / "provenance.json")
    assert f"more than the {readers.JSON_LIMIT}" in line


def test_a_link_to_a_device_is_refused(tmp_path):
    path = tmp_path / "provenance.json"
    path.symlink_to("/dev/zero")
    with within(5), pytest.raises(TavcError, match=r"provenance.json: cannot be read \(it is a device, not a file\)"):
        load_json(path)


def test_read_bounded_just_under_and_over_the_limit(tmp_path):
    path = tmp_path / "f"
    path.write_bytes(b"x" * 100)
    assert read_bounded(path, 100) == b"x" * 100
    with pytest.raises(TavcError, match=rf"^{path}: cannot be read \(100 bytes, more than the 99 .*; rerun"):
        read_bounded(path, 99)
    with pytest.raises(FileNotFoundError):
        read_bounded(tmp_path / "missing", 100)


def test_json_depth_at_and_over_the_limit(tmp_path):
    path = tmp_path / "d.json"
    path.write_text("[" * MAX_DEPTH + "]" * MAX_DEPTH)
    assert json_depth(path.read_text()) == MAX_DEPTH
    assert load_json(path) is not None
    path.write_text('{"a": ' * MAX_DEPTH + '"[[[[{{{{"' + "}" * MAX_DEPTH)  # brackets in a string do not count
    assert load_json(path)["a"]
    path.write_text("[" * (MAX_DEPTH + 1) + "]" * (MAX_DEPTH + 1))
    with pytest.raises(TavcError, match="nested more than"):
        load_json(path)
    path.write_text("{not json")
    with pytest.raises(ValueError):
        load_json(path)


def test_one_yaml_alias_is_refused_and_deep_yaml_too(tmp_path):
    path = tmp_path / "config.yaml"
    path.write_text("a: &x 1\nb: *x\n")
    with pytest.raises(TavcError, match=r"cannot be read \(a YAML alias, \*x, on line 2"):
        load_yaml(path)
    path.write_text("a: &x 1\n")  # an anchor alone expands nothing
    assert load_yaml(path) == {"a": 1}
    path.write_text("[" * 10_000 + "]" * 10_000)
    with pytest.raises(TavcError, match="nested more than"):
        load_yaml(path)
    path.write_text("a: [\n")
    with pytest.raises(yaml.YAMLError):
        load_yaml(path)


def test_tavcs_own_files_read_as_before():
    config = RESULTS / "initial_distribution" / "config.yaml"
    assert load_yaml(config) == yaml.safe_load(config.read_text())
    for path in [*RESULTS.glob("*/provenance.json"), *RESULTS.glob("**/.tavc.json")]:
        assert load_json(path) == json.loads(path.read_text())


@pytest.mark.skipif(readers.CParser is None, reason="PyYAML without libyaml reads with its own parser only")
def test_libyaml_reads_every_committed_config_as_pyyaml_does_and_keeps_the_loaders_own_rules(tmp_path):
    assert issubclass(readers._SAFE, readers.CParser)  # the report's hundreds of configs parsed by libyaml
    configs = sorted(RESULTS.glob("*/config.yaml")) + sorted(RESULTS.glob("converged/*/config.yaml"))
    assert len(configs) >= 10
    for path in configs:
        assert load_yaml(path) == yaml.safe_load(path.read_text())
        assert load_yaml(path, loader=get_yaml_loader()) == yaml.load(path.read_text(), Loader=get_yaml_loader())
    # OmegaConf's loader refuses a key given twice and reads 1e3 as a number: so it does on libyaml
    path = tmp_path / "config.yaml"
    path.write_text("a: 1e3\n")
    assert load_yaml(path, loader=get_yaml_loader()) == {"a": 1000.0}
    path.write_text("a: 1\na: 2\n")
    with pytest.raises(yaml.YAMLError, match="duplicate key"):
        load_yaml(path, loader=get_yaml_loader())


def test_a_records_size_is_what_its_archive_declares_unpacked(tmp_path):
    """Each member of a NumPy archive is a .npy file: a 128-byte header, then the array's bytes;
    1,000 float64 and 10 int8 declare 128 + 8,000 and 128 + 10."""
    path = tmp_path / "record.npz"
    np.savez_compressed(path, a=np.zeros(1000), b=np.zeros(10, dtype=np.int8))
    assert path.stat().st_size < 1000  # zeros pack small; their declared size is what counts
    assert readers.record_size(path) == 128 + 8000 + 128 + 10
    path.write_text("not an archive")
    with pytest.raises(zipfile.BadZipFile):
        readers.record_size(path)
