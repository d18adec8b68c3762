"""Commands never overwrite the committed results: runs go to ``runs/<scale>/<experiment>`` unless
told otherwise, and a model, a world search or saved calibration of other settings is refused in
one line naming the difference, unless ``overwrite=true``. The README's quickstart runs as printed
from a copy of the repository and leaves ``git status`` clean."""

from __future__ import annotations

import json
import os
import re
import shlex
import shutil
import subprocess
import sys
from functools import partial
from pathlib import Path

import pytest
import yaml
from typer.testing import CliRunner

from tavc_cli import config
from tavc_cli.cli import app
from tavc_cli.errors import TavcError
from tavc_cli.model.api import model_identity
from tavc_cli.ownership import recorded_differences, refuse_other_settings
from tests import helpers
from tests.helpers import REPO

SMOKE = yaml.safe_load((REPO / "conf" / "scale" / "smoke.yaml").read_text())


def invoke(args: list[str]):
    return CliRunner().invoke(app, args)


def test_a_run_goes_under_runs_by_scale_and_experiment():
    assert config.load_config(["experiment=breakdown", "scale=smoke"]).output_dir == "runs/smoke/breakdown"
    assert config.load_config(["experiment=breakdown"]).output_dir == "runs/quick/breakdown"  # quick: the default
    assert config.load_config(["experiment=breakdown", "output_dir=results/x"]).output_dir == "results/x"


def test_reproduce_and_ladder_default_to_runs_of_their_scale():
    assert config.results_root(["scale=smoke", "seed=3"]) == Path("runs/smoke")
    assert config.results_root([]) == Path("runs/quick")
    assert config.results_root([], "converged") == Path("runs/converged")
    assert config.results_root(["scale=paper"], "converged") == Path("runs/paper")
    cfgs = config.load_experiments(["breakdown", "value_change"], ["scale=smoke"])
    assert [c.output_dir for c in cfgs] == ["runs/smoke/breakdown", "runs/smoke/value_change"]
    rungs = config.load_ladder([1, 4], ["trials=2"])
    assert [c.output_dir for c in rungs] == ["runs/converged/ladder/x1", "runs/converged/ladder/x4"]


@pytest.mark.parametrize("name", ["a/b", "..", "", " x"])
def test_a_scale_name_that_is_not_a_plain_name_is_refused(name):
    with pytest.raises(TavcError, match="scale.name"):
        config.load_config([f"scale.name='{name}'"])


@pytest.mark.parametrize("name", ["/tmp/elsewhere", "../../out", "a/b", "", "."])
def test_an_experiment_name_that_is_not_a_plain_name_is_refused(name):
    """The default folder is runs/<scale.name>/<experiment_name>: a name that is a path would lead out."""
    with pytest.raises(TavcError, match="^experiment_name: .* is not a plain name"):
        config.load_config([f"experiment_name='{name}'"])


@pytest.mark.parametrize(("args", "line"), [
    (["reproduce", "scale=smoke", "--experiments", "breakdown", "--results", "/"], "Invalid value for '--results': /"),
    (["ladder", "scale=smoke", "--factors", "1", "--results", "/"], "Invalid value for '--results': /"),
    (["compare", "scale=smoke", "--results", "/"], "Invalid value for '--results': /"),
    (["report", "/"], "Invalid value for 'RESULTS_DIR': /"),
    (["run", "-m", "scale=smoke", "trials=1", "seed=0,1", "output_dir=/"], "output_dir: /"),
])
def test_the_root_of_the_file_system_is_no_commands_folder(args, line, tmp_path):
    """Refused in one line before anything is written: a sweep holds its jobs' folder, refused
    before any job runs."""
    result = helpers.tavc(*args, cwd=tmp_path)
    assert result.returncode in (1, 2), result.stderr
    assert result.stderr.startswith(f"error: {line} is the root of the file system; give the results a folder of "
                                    "their own"), result.stderr
    assert len(result.stderr.strip().splitlines()) == 1 and list(tmp_path.iterdir()) == []
    assert not Path("/0_seed=0").exists() and not Path("/breakdown").exists()


@pytest.mark.parametrize(("args", "line"), [
    (["reproduce", "scale=smoke", "--experiments", "breakdown", "--results", ""], "Invalid value for '--results': "),
    (["stay-switch", "--results", ""], "Invalid value for '--results': "),
    (["report", ""], "Invalid value for 'RESULTS_DIR': "),
    (["run", "-m", "scale=smoke", "trials=1", "seed=0,1", "output_dir="],
     "job 0 (scale=smoke trials=1 seed=0 output_dir=): output_dir: "),
])
def test_an_empty_folder_is_refused_not_taken_for_the_working_folder(args, line, tmp_path):
    result = helpers.tavc(*args, cwd=tmp_path)
    assert result.returncode in (1, 2), result.stderr
    assert result.stderr.startswith(f"error: {line}must not be empty"), result.stderr
    assert len(result.stderr.strip().splitlines()) == 1 and list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("command", [["reproduce", "--experiments", "breakdown"], ["ladder", "--factors", "1"],
                                     ["compare"], ["stay-switch"]])
def test_a_results_folder_holding_an_interpolation_is_refused(command, tmp_path):
    """Its runs' folders are named in their settings, where ``${oc.env:HOME}`` would be read: the
    run would go under the home folder."""
    result = helpers.tavc(*command, "scale=smoke", "--results", "x${oc.env:HOME}", cwd=tmp_path)
    assert result.returncode == 2, result.stderr
    assert result.stderr.startswith("error: Invalid value for '--results': x${oc.env:HOME} holds '${', which "
                                    "tavc's settings read as an interpolation"), result.stderr
    assert len(result.stderr.strip().splitlines()) == 1 and list(tmp_path.iterdir()) == []


def test_model_identity_is_what_model_json_records_at_that_scale():
    cfg = config.settings(config.load_config(["experiment=initial_distribution", "scale=smoke"]))
    identity = model_identity(cfg)
    factor = SMOKE["time_factor"]
    # by hand: trials per split min(12, scale.trials) but at least 2; times x the scale's factor
    assert identity["measurement"]["trials_per_split"] == max(2, min(12, SMOKE["trials"]))
    assert identity["measurement"]["warmup_s"] == pytest.approx(300.0 * factor)
    assert identity["measurement"]["measure_s"] == pytest.approx(3000.0 * factor)
    assert identity["values"] == [2200.0, 2000.0] and identity["n_robots"] == 6


def test_recorded_differences_name_the_settings_and_ignore_keys_one_side_lacks(tmp_path):
    record = tmp_path / "model.json"
    record.write_text(json.dumps({"values": [2200.0, 2000.0], "predicted_state": "3:3",
                                  "measurement": {"trials_per_split": 12, "measure_s": 3000.0, "n_trials_reused": 4}}))
    same = {"values": [2200.0, 2000.0], "measurement": {"trials_per_split": 12, "measure_s": 3000.0}, "new_key": 1}
    assert recorded_differences(record, same) == []
    other = {"values": [2200.0, 2000.0], "measurement": {"trials_per_split": 2, "measure_s": 60.0}}
    assert recorded_differences(record, other) == ["measurement.measure_s: 3000.0 -> 60.0",
                                                   "measurement.trials_per_split: 12 -> 2"]
    with pytest.raises(TavcError, match=r"model.json was made with other settings .*overwrite=true"):
        refuse_other_settings(record, other, "output_dir", overwrite=False)
    refuse_other_settings(record, other, "output_dir", overwrite=True)  # told to: no error
    assert recorded_differences(tmp_path / "none.json", other) == []


def _bytes(paths):
    return {p: p.read_bytes() for p in paths}


def test_a_smoke_model_is_refused_over_a_model_of_other_settings(tmp_path):
    folder = tmp_path / "run"
    (folder / "model").mkdir(parents=True)
    paper = config.settings(config.load_config(["experiment=initial_distribution", "scale=paper"]))
    (folder / "model" / "model.json").write_text(json.dumps(model_identity(paper)))
    (folder / "model" / ".tavc.json").write_text(json.dumps({"tavc": "model", "files": ["model.json"]}))
    before = _bytes((folder / "model").iterdir())
    result = invoke(["model", "experiment=initial_distribution", "scale=smoke", f"output_dir={folder}"])
    assert result.exit_code == 1
    line = result.output.strip()
    assert line.count("\n") == 0 and "other settings" in line and "overwrite=true" in line
    assert "trials_per_split: 12 -> 2" in line
    assert _bytes((folder / "model").iterdir()) == before  # nothing written, not even the list


@pytest.mark.slow
def test_save_calibration_of_other_settings_leaves_conf_untouched():
    kept = _bytes([*(REPO / "conf" / "tasks").rglob("*.*"), *(REPO / "conf" / "world").rglob("*.*")])
    model = invoke(["model", "experiment=initial_distribution", "scale=smoke", "--save-calibration",
                    "output_dir=/nonexistent/never-written"])
    assert model.exit_code == 1 and "--save-calibration" in model.output and "overwrite=true" in model.output
    search = invoke(["calibrate", "scale=smoke", "--save", "output_dir=/nonexistent/never-written/x"])
    assert search.exit_code == 1 and "--save" in search.output and "overwrite=true" in search.output
    assert "measurement.trials_per_split: 6 -> 2" in search.output
    assert not Path("/nonexistent").exists()
    assert _bytes(kept) == kept


# --- the README's quickstart, from a copy of the repository ---------------------------------------

QUICKSTART = re.compile(r"<!-- quickstart -->(.*?)<!-- /quickstart -->", re.S)


def quickstart_commands(readme: str) -> list[tuple[list[str], str | None]]:
    """Each ``tavc ...`` line of the README's quickstart block: its arguments, and the folder its
    comment says it writes (``-> PATH``), if any."""
    block = QUICKSTART.search(readme)
    assert block, "README.md has no quickstart block between <!-- quickstart --> and <!-- /quickstart -->"
    out = []
    for line in block.group(1).splitlines():
        line = line.strip()
        if not line.startswith("tavc "):
            continue
        command, _, comment = line.partition(" #")
        folder = re.search(r"->\s*(\S+)", comment)
        out.append((shlex.split(command)[1:], folder.group(1) if folder else None))
    return out


def test_quickstart_commands_are_parsed_with_their_folders():
    readme = ("x\n<!-- quickstart -->\n```sh\ntavc list   # the list\n"
              "tavc run experiment=breakdown scale=smoke  # -> runs/smoke/breakdown/\n```\n<!-- /quickstart -->\n")
    assert quickstart_commands(readme) == [(["list"], None),
                                           (["run", "experiment=breakdown", "scale=smoke"], "runs/smoke/breakdown/")]


def _copy_of_repository(dest: Path) -> None:
    tracked = subprocess.run(["git", "ls-files", "-z"], cwd=REPO, capture_output=True, check=True).stdout
    for name in filter(None, tracked.decode().split("\0")):
        source = REPO / name
        if source.is_file():
            (dest / name).parent.mkdir(parents=True, exist_ok=True)
            shutil.copy2(source, dest / name)
    git = ["git", "-c", "user.name=t", "-c", "user.email=t@t", "-c", "commit.gpgsign=false"]
    subprocess.run([*git, "init", "-q"], cwd=dest, check=True)
    subprocess.run([*git, "add", "-A"], cwd=dest, check=True)
    subprocess.run([*git, "commit", "-q", "-m", "copy"], cwd=dest, check=True)


def _share_compiled_kernels(clone: Path) -> None:
    """The checkout's compiled kernels, those it has, put where the copy's numba looks for its own,
    so that the quickstart compiles only what the checkout has not (the checkout compiles every
    kernel in its own first tests, as on a fresh machine). numba files a source folder's kernels
    under a hash of that folder's path and takes them when its source file has the same time and
    size, which `shutil.copy2` keeps; the folder of this version's kernels is named by the digest
    of the source, the same in both."""
    import hashlib

    from tavc_cli import compiled_code_cache, compiled_code_home

    ours, theirs = REPO / "tavc_cli", clone / "tavc_cli"
    source = compiled_code_cache(ours, compiled_code_home(ours))
    target = compiled_code_cache(theirs, compiled_code_home(theirs))
    if not source.is_dir() or source.name != target.name:
        return

    def filed(folder: Path) -> str:  # numba's name for the kernels of the sources in `folder`
        return f"{folder.name}_{hashlib.sha1(os.path.abspath(folder).encode()).hexdigest()}"

    for folder in [ours, *(d for d in ours.rglob("*") if d.is_dir() and "__pycache__" not in d.parts)]:
        if (source / filed(folder)).is_dir():
            shutil.copytree(source / filed(folder), target / filed(theirs / folder.relative_to(ours)),
                            dirs_exist_ok=True)  # one folder for both where the checkout is read-only (user cache)


@pytest.mark.slow
def test_the_quickstart_runs_as_printed_and_leaves_git_status_clean(tmp_path):
    if shutil.which("git") is None:
        pytest.skip("git is not installed")
    clone = tmp_path / "tavc"
    clone.mkdir()
    _copy_of_repository(clone)
    _share_compiled_kernels(clone)
    # the copy's kernels in its own folder, as on a fresh machine (the tests' process points numba at the checkout's)
    env = {**{k: v for k, v in os.environ.items() if k != "NUMBA_CACHE_DIR"}, "PYTHONPATH": str(clone)}

    tavc = partial(helpers.tavc, cwd=clone, env=env, timeout=900)

    where = subprocess.run([sys.executable, "-c", "import tavc_cli; print(tavc_cli.__file__)"], cwd=clone, env=env,
                           capture_output=True, text=True, check=True).stdout
    assert Path(where.strip()).is_relative_to(clone)  # the copy's code and conf/, not the checkout's
    commands = quickstart_commands((clone / "README.md").read_text())
    assert len(commands) >= 5
    for args, folder in commands:
        done = tavc(*args)
        assert done.returncode == 0, f"tavc {' '.join(args)}: {done.stderr[-2000:]}"
        if folder is not None:  # a placeholder such as <experiment> stands for any name
            pattern = re.sub(r"<[^>]+>", "*", folder.rstrip(",.;:").rstrip("/"))
            assert list(clone.glob(pattern)), f"tavc {' '.join(args)} did not write {folder} as the README says"
    # the three ways an earlier version replaced committed results, each refused in one line
    into = "output_dir=results/initial_distribution"
    refused = [tavc("run", "experiment=initial_distribution", "scale=smoke", into),
               tavc("model", "experiment=initial_distribution", "scale=smoke", into),
               tavc("calibrate", "scale=smoke", "--save")]
    for done in refused:
        assert done.returncode == 1 and done.stderr.strip().startswith("error: ") and "overwrite=true" in done.stderr
        assert done.stderr.strip().count("\n") == 0
    status = subprocess.run(["git", "status", "--porcelain"], cwd=clone, capture_output=True, text=True, check=True)
    assert status.stdout == ""


def test_a_run_may_follow_the_model_measured_in_its_folder(tmp_path):
    from tavc_cli.ownership import MODEL, RUN, Owned, run_files, take

    folder = tmp_path / "run"
    model = Owned(folder / "model", MODEL)
    (folder / "model").mkdir(parents=True)
    model.wrote("model.json")
    (folder / "model" / "model.json").write_text("{}")
    take(folder, RUN, run_files())  # `tavc model` first, then `tavc run` into the same folder: no refusal
    fresh = tmp_path / "fresh"
    (fresh / "model").mkdir(parents=True)
    (fresh / "model" / "model.json").write_text("{}")  # the user's own model/ folder stays the user's
    with pytest.raises(TavcError, match="model/"):
        take(fresh, RUN, run_files())


def test_a_run_adopts_the_folder_its_animation_was_written_to(tmp_path):
    from tavc_cli.ownership import ANIMATION, RUN, Owned, read, run_files, take

    folder = tmp_path / "run"
    folder.mkdir()
    Owned(folder, ANIMATION).wrote("animation.gif")  # `tavc animate` before `tavc run`, same default folder
    (folder / "animation.gif").write_bytes(b"GIF89a")
    take(folder, RUN, run_files())
    owned = read(folder)
    assert owned.kind == RUN and owned.owns("animation.gif")
