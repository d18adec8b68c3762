"""A folder from somebody else never gives a wrong number: `tavc compare --reuse` reads a
controller's runs only from finished runs of the scenario, the learner and the comparison's
settings whose tables still have their digests, and the API (and the report) reads only the
trial records of the run itself (their keys those provenance.json lists). Every refusal is
one line, exit 1, nothing written and nothing of the folders read changed."""

from __future__ import annotations

import json
import os
import shutil
import threading
from pathlib import Path

import pytest
from typer.testing import CliRunner

from tavc_cli import api, reading, run_checks
from tavc_cli.cli import app
from tavc_cli.config import load_config
from tavc_cli.config import settings as to_settings
from tavc_cli.errors import TavcError
from tavc_cli.experiments.records import TrialRecord
from tavc_cli.pipeline import run_experiment
from tavc_cli.run_checks import this_code
from tests.helpers import file_digests

SETTINGS = {"scale": "smoke", "duration_s": "120", "convergence_s": "20", "trials": "1", "executor.n_jobs": "1"}
SMOKE = [f"{key}={value}" for key, value in SETTINGS.items()]
SCENARIOS = "initial_distribution,breakdown"
ADVICE = ("; name a folder holding this controller's finished runs at the comparison's settings, or leave it out "
          "of --reuse to run them")
REWRITE = "; rerun its experiment to rewrite it"
runner = CliRunner()


def _compare(results: Path, *reuse: str, overrides: dict[str, str] | None = None):
    """`tavc compare` of tavc and random at `SETTINGS` (but `overrides`) into `results`."""
    chosen = {**SETTINGS, **(overrides or {})}
    args = ["compare", *(f"{key}={value}" for key, value in chosen.items()), "--learners", "tavc,random",
            "--experiments", SCENARIOS, "--results", str(results), "--no-progress"]
    for item in reuse:
        args += ["--reuse", item]
    return runner.invoke(app, args)


@pytest.fixture(scope="module")
def compared(tmp_path_factory) -> Path:
    """A comparison of tavc and random on two scenarios, computed once: one trial of 120 s each."""
    results = tmp_path_factory.mktemp("compared") / "cmp"
    result = _compare(results)
    assert result.exit_code == 0, result.output
    return results


@pytest.fixture(scope="module")
def seed3(tmp_path_factory) -> Path:
    """A breakdown run on seed 3, TAVC's trial and random's: the source of a record of another seed."""
    folder = tmp_path_factory.mktemp("seed3") / "breakdown"
    overrides = ["experiment=breakdown", *SMOKE, "seed=3", "baselines=[random]", "baseline_trials=1",
                 f"output_dir={folder}"]
    run_experiment(to_settings(load_config(overrides)))
    return folder


def _copy_runs(compared: Path, tmp_path: Path, controller: str = "tavc") -> tuple[Path, Path]:
    """A copy of `controller`'s runs to reuse, and a sibling folder beside it (random's runs)."""
    mine, sibling = tmp_path / "reused" / controller, tmp_path / "reused" / "sibling"
    shutil.copytree(compared / "runs" / controller, mine)
    shutil.copytree(compared / "runs" / "random", sibling)
    return mine, sibling


def _refused(tmp_path: Path, line: str, *reuse: str, overrides: dict[str, str] | None = None) -> None:
    """The comparison with `reuse` refuses in the one line `line` (without its ``error: ``),
    exit 1, and writes nothing; the folders under tmp_path/reused are left as they were."""
    before = file_digests(tmp_path / "reused") if (tmp_path / "reused").is_dir() else {}
    result = _compare(tmp_path / "out", *reuse, overrides=overrides)
    assert result.exit_code == 1, result.output
    assert result.output.strip().splitlines() == [f"error: {line}"]
    assert not (tmp_path / "out").exists()
    if before:
        assert file_digests(tmp_path / "reused") == before


# --- compare --reuse --------------------------------------------------------------------------------


def test_a_genuine_reuse_gives_the_same_table_byte_for_byte(compared, tmp_path):
    before = file_digests(compared / "runs")
    result = _compare(tmp_path / "again", f"tavc={compared / 'runs' / 'tavc'}")
    assert result.exit_code == 0, result.output
    assert (tmp_path / "again" / "compare.csv").read_bytes() == (compared / "compare.csv").read_bytes()
    assert not (tmp_path / "again" / "runs" / "tavc").exists()  # read, not run again
    assert file_digests(compared / "runs") == before  # the folder reused and its sibling untouched


def test_swapped_scenario_folders_are_refused(compared, tmp_path):
    mine, _ = _copy_runs(compared, tmp_path)
    (mine / "initial_distribution").rename(mine / "held")
    (mine / "breakdown").rename(mine / "initial_distribution")
    (mine / "held").rename(mine / "breakdown")
    _refused(tmp_path, f"--reuse: {mine / 'initial_distribution'}: a run of breakdown, not of initial_distribution"
             + ADVICE, f"tavc={mine}")


def test_an_edited_trial_stats_is_refused(compared, tmp_path):
    mine, _ = _copy_runs(compared, tmp_path)
    path = mine / "breakdown" / "trial_stats.csv"
    header, row = path.read_text().splitlines()[:2]
    column = header.split(",").index("value_rate_stable")
    cells = row.split(",")
    cells[column] = "5.09"  # the shape of a table, another number
    path.write_text(path.read_text().replace(row, ",".join(cells)))
    _refused(tmp_path, f"--reuse: {path}: changed since its run wrote it (its SHA-256 is not the one "
             f"provenance.json recorded){REWRITE}", f"tavc={mine}")


def test_a_run_without_provenance_is_not_finished(compared, tmp_path):
    mine, _ = _copy_runs(compared, tmp_path)
    (mine / "breakdown" / "provenance.json").unlink()
    _refused(tmp_path, f"--reuse: {mine / 'breakdown'}: holds no finished run of breakdown (no provenance.json)"
             + ADVICE, f"tavc={mine}")


def test_a_run_of_another_version_of_tavcs_code_is_refused(compared, tmp_path):
    mine, _ = _copy_runs(compared, tmp_path)
    path = mine / "initial_distribution" / "provenance.json"
    prov = json.loads(path.read_text())
    prov["code_digest"] = "0123456789abcdef"  # as a run of an earlier simulator records it
    path.write_text(json.dumps(prov, indent=2))
    _refused(tmp_path, f"--reuse: {mine / 'initial_distribution'}: computed by another version of tavc's code "
             f"(0123456789abcdef; this tavc's: {this_code()})" + ADVICE, f"tavc={mine}")


def test_a_run_of_another_learner_is_refused(compared, tmp_path):
    mine, _ = _copy_runs(compared, tmp_path, controller="random")
    _refused(tmp_path, f"--reuse: {mine / 'initial_distribution'}: a run of learner random, not of tavc_egreedy"
             + ADVICE, f"tavc={mine}")


def test_runs_of_another_seed_scale_or_fewer_trials_are_refused(compared, tmp_path):
    mine, _ = _copy_runs(compared, tmp_path)
    where = mine / "initial_distribution"
    _refused(tmp_path, f"--reuse: {where}: a run at other settings than the comparison's (seed: 0 -> 3)" + ADVICE,
             f"tavc={mine}", overrides={"seed": "3"})
    result = _compare(tmp_path / "out", f"tavc={mine}", overrides={"scale": "quick"})
    assert result.exit_code == 1 and len(result.output.strip().splitlines()) == 1
    assert "a run at other settings than the comparison's (" in result.output and "scale.name: smoke -> quick" in \
        result.output and not (tmp_path / "out").exists()
    _refused(tmp_path, f"--reuse: {where}: no trial 1 of tavc among those its provenance.json lists; the comparison "
             "runs 2" + ADVICE, f"tavc={mine}", overrides={"trials": "2"})


# --- the API, and the report, read the run's own records --------------------------------------------


def test_a_record_of_another_seed_is_refused(compared, seed3, tmp_path):
    folder = tmp_path / "breakdown"
    shutil.copytree(compared / "runs" / "tavc" / "breakdown", folder)
    assert [r.meta["trial"] for r in api.load(folder).records()] == [0]  # its own record is read
    shutil.copy(seed3 / "trials" / "tavc_000.npz", folder / "trials" / "tavc_000.npz")
    line = (f"{folder / 'trials' / 'tavc_000.npz'} is not this run's trial (its key differs from provenance.json); "
            "rerun `tavc run` on the folder to recompute it")
    for read in (lambda: api.load(folder).records(), lambda: api.load(folder).events("deliveries")):
        with pytest.raises(TavcError) as info:
            read()
        assert str(info.value) == line
    # the report, which counts the deliveries of the records it lists, refuses it too
    results = tmp_path / "results"
    results.mkdir()
    folder.rename(results / "breakdown")
    before = file_digests(results)
    result = runner.invoke(app, ["report", str(results)])
    assert result.exit_code == 1, result.output
    assert result.output.strip().splitlines() == ["error: " + line.replace(str(folder), str(results / "breakdown"))]
    assert file_digests(results) == before


def test_a_record_declaring_more_arrays_than_tavc_writes_is_refused_unread(seed3, tmp_path, monkeypatch):
    """A trial record is a zip archive whose directory declares its arrays' sizes, and a file of
    kilobytes can declare gigabytes: one declaring more than a record of tavc's holds (4 GiB) is
    one line, nothing of it unpacked."""
    folder = tmp_path / "breakdown"
    shutil.copytree(seed3, folder)
    declared = {"random_000.npz": 5 << 30}
    monkeypatch.setattr(run_checks, "record_size", lambda path: declared.get(Path(path).name, 1))

    def unpacked(path):
        raise AssertionError(f"{path} was unpacked")

    monkeypatch.setattr(TrialRecord, "load", unpacked)
    with pytest.raises(TavcError) as info:
        api.load(folder).records("random")
    assert str(info.value) == (f"{folder / 'trials' / 'random_000.npz'}: declares 5.0 GiB of arrays, more than a "
                               "trial record of tavc's holds (4 GiB at the most)" + REWRITE)


def _two_gib_in_one_and_a_half(folder, monkeypatch) -> None:
    """With every record declaring 1 GiB and 1.5 GiB of memory, the folder's two records together
    are refused in one line."""
    monkeypatch.setattr(reading, "record_size", lambda path: 1 << 30)
    monkeypatch.setattr(reading, "physical_memory", lambda: 1.5 * 2**30)
    with pytest.raises(TavcError) as info:
        api.load(folder).records()
    assert str(info.value) == (f"{folder}: its 2 trial records declare 2.0 GiB of arrays, more than this machine's "
                               "1.5 GiB of memory; read one controller's at a time (records(controller), events(kind, "
                               "controller))")


def test_records_that_would_not_fit_in_memory_together_are_refused_before_any_is_read(seed3, tmp_path,
                                                                                         monkeypatch):
    folder = tmp_path / "breakdown"
    shutil.copytree(seed3, folder)
    assert [r.meta["controller"] for r in api.load(folder).records("random")] == ["random"]
    _two_gib_in_one_and_a_half(folder, monkeypatch)
    assert [r.meta["controller"] for r in api.load(folder).records("tavc")] == ["tavc"]  # 1 GiB: read
    assert set(api.load(folder).events("deliveries", "tavc")["controller"]) == {"tavc"}
    with pytest.raises(TavcError, match=f"^{folder}: no trials of static to read$"):
        api.load(folder).records("static")


def test_a_run_that_did_not_finish_is_held_to_memory_by_the_records_it_keeps(seed3, tmp_path, monkeypatch):
    """Of a run stopped before its end, a record in trials/ of other settings is left out, so it
    does not count against this machine's memory: with 1 GiB declared by each of two records and
    1.5 GiB of memory, random's of another key is read and dropped, TAVC's kept; with both this
    run's own, the second is refused in one line."""
    folder = tmp_path / "breakdown"
    shutil.copytree(seed3, folder)
    (folder / "provenance.json").unlink()
    _two_gib_in_one_and_a_half(folder, monkeypatch)
    keys = reading.keys_of

    def random_of_other_settings(*args):
        return {**keys(*args), ("random", 0): "another"}

    monkeypatch.setattr(reading, "keys_of", random_of_other_settings)
    assert [r.meta["controller"] for r in api.load(folder).records()] == ["tavc"]


def test_a_record_provenance_lists_but_missing_is_named(seed3, tmp_path):
    folder = tmp_path / "breakdown"
    shutil.copytree(seed3, folder)
    assert sorted(r.meta["controller"] for r in api.load(folder).records()) == ["random", "tavc"]
    (folder / "trials" / "random_000.npz").unlink()
    with pytest.raises(TavcError) as info:
        api.load(folder).events("deliveries")
    assert str(info.value) == f"{folder / 'trials' / 'random_000.npz'}: missing, though provenance.json lists it" \
        + REWRITE


@pytest.mark.parametrize("what", ["pipe", "device"])
def test_a_pipe_or_a_device_in_a_records_place_is_one_line_never_a_wait(seed3, tmp_path, what):
    """A named pipe, or a link to /dev/zero, where a trial record goes: reading the records names
    the file at once (a pipe's read would wait for a writer for ever, a device's never end)."""
    folder = tmp_path / "breakdown"
    shutil.copytree(seed3, folder)
    record = folder / "trials" / "tavc_000.npz"
    record.unlink()
    if what == "pipe":
        os.mkfifo(record)
    else:
        record.symlink_to("/dev/zero")

    raised = []

    def read():
        try:
            api.load(folder).records()
        except TavcError as error:
            raised.append(str(error))

    reader = threading.Thread(target=read, daemon=True)  # a wait stays in its thread: the test fails, not hangs
    reader.start()
    reader.join(60)
    assert not reader.is_alive(), "waited on the record"
    assert len(raised) == 1 and raised[0].startswith(f"{record}: ")
