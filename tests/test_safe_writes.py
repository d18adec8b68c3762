"""Nothing tavc writes goes through a link or lands outside the folder it holds (`io.owned_path`).

Each hostile case puts a link, a named pipe or a folder inside the folder a command holds,
pointing at a sibling folder of somebody else's files; the command refuses in one line naming
the path, and the sibling's files are byte for byte as they were.
"""

import os
import shutil
import sys

import matplotlib
import numpy as np
import pandas as pd
import pytest
from typer.testing import CliRunner

from tavc_cli import config
from tavc_cli.cli import app
from tavc_cli.errors import TavcError
from tavc_cli.experiments.build import trial_specs
from tavc_cli.experiments.records import TrialRecord
from tavc_cli.experiments.store import Executor, TrialStore, save_result
from tavc_cli.io import LOCK_NAME, claim_folder, write_text_atomic
from tavc_cli.ownership import RUN as RUN_KIND
from tavc_cli.ownership import check_inside, take_report_folders
from tavc_cli.viz.figures import plt, save_figure
from tavc_cli.viz.sweep import sweep_figure
from tests.helpers import tavc

matplotlib.use("Agg")
runner = CliRunner()

RUN = ["run", "experiment=initial_distribution", "scale=smoke", "trials=1", "duration_s=60", "convergence_s=20",
       "executor.n_jobs=1"]
THEIRS = b"somebody else's data, not tavc's\n"


def _snapshot(folder):
    """Every entry under `folder`, files with their bytes."""
    return {str(p.relative_to(folder)): p.read_bytes() if p.is_file() else None for p in sorted(folder.rglob("*"))}


@pytest.fixture
def sibling(tmp_path):
    """A folder beside the run's with a file of somebody else's in it."""
    folder = tmp_path / "sibling"
    folder.mkdir()
    (folder / "theirs.txt").write_bytes(THEIRS)
    return folder


def _hostile(path, sibling, how):
    """Put at `path` a link to the sibling's file, a dangling link into the sibling, a named pipe or a folder."""
    path.parent.mkdir(parents=True, exist_ok=True)
    if how == "link":
        path.symlink_to(sibling / "theirs.txt")
    elif how == "dangling":
        path.symlink_to(sibling / "new.txt")
    elif how == "fifo":
        os.mkfifo(path)
    else:
        path.mkdir()


def _one_line_naming(message, path):
    assert "\n" not in message and str(path) in message, message


def _lock_refused(run, sibling, how) -> str:
    """Claim `run` with a hostile lock in it: the one-line refusal, the sibling folder unchanged
    (neither truncated nor created)."""
    _hostile(run / LOCK_NAME, sibling, how)
    before = _snapshot(sibling)
    with pytest.raises(TavcError) as refused:
        with claim_folder(run):
            pass
    _one_line_naming(str(refused.value), run / LOCK_NAME)
    assert _snapshot(sibling) == before
    return str(refused.value)


@pytest.mark.parametrize("how", ["link", "dangling", "fifo"])
def test_a_lock_that_is_a_link_or_a_pipe_is_refused_and_nothing_outside_is_written(tmp_path, sibling, how):
    message = _lock_refused(tmp_path / "run", sibling, how)
    assert message.startswith("output_dir: ") and "move it away" in message


@pytest.mark.parametrize("how", ["link", "dangling", "fifo"])
def test_the_lock_is_never_opened_through_a_link_even_past_the_check(tmp_path, sibling, monkeypatch, how):
    """A link or pipe put there after the check looked: O_NOFOLLOW and the open file's type stop it."""
    monkeypatch.setattr("tavc_cli.io.owned_path", lambda root, path, **kw: path)
    _lock_refused(tmp_path / "run", sibling, how)


@pytest.mark.parametrize("how", ["link", "dangling", "fifo", "folder"])
@pytest.mark.parametrize("ext", ["png", "svg"])
def test_a_figure_path_that_is_not_a_regular_file_is_refused(tmp_path, sibling, how, ext):
    stem = tmp_path / "results" / "figures" / "state"
    _hostile(stem.with_suffix(f".{ext}"), sibling, how)
    before = _snapshot(sibling)
    fig, ax = plt.subplots()
    ax.plot([0, 1], [0, 1])
    with pytest.raises(TavcError) as refused:
        save_figure(fig, stem)
    _one_line_naming(str(refused.value), stem.with_suffix(f".{ext}"))
    assert _snapshot(sibling) == before
    assert fig.number not in plt.get_fignums()  # the figure is closed all the same


def test_a_sweep_figure_over_a_link_is_refused(tmp_path, sibling):
    table = pd.DataFrame({"controller": ["tavc", "tavc"], "state": ["0:1", "0:1"], "epsilon": [0.1, 0.2],
                          "mean_pct": [40.0, 60.0], "std_pct": [5.0, 5.0], "n_trials": [2, 2]})
    _hostile(tmp_path / "sweep.svg", sibling, "dangling")
    before = _snapshot(sibling)
    with pytest.raises(TavcError) as refused:
        sweep_figure(table, "epsilon", tmp_path / "sweep")
    _one_line_naming(str(refused.value), tmp_path / "sweep.svg")
    assert _snapshot(sibling) == before


def test_an_animation_over_a_link_is_refused_before_anything_is_simulated(tmp_path, sibling):
    out = tmp_path / "pictures" / "run.gif"
    _hostile(out.parent / "trajectories.png", sibling, "link")
    before = _snapshot(sibling)
    result = runner.invoke(app, ["animate", "team.n_robots=2", "--duration-s", "4", "--no-mp4", "--out", str(out)])
    assert result.exit_code == 1
    assert result.output.splitlines() == [
        f"error: --out: {out.parent / 'trajectories.png'} is a symbolic link to {sibling / 'theirs.txt'}, where tavc "
        "writes a file of its own; move it away or choose another folder"]
    assert _snapshot(sibling) == before and not out.exists()


def test_a_reports_figures_folder_that_is_a_link_is_refused(tmp_path, sibling):
    results = tmp_path / "results"
    results.mkdir()
    (results / "figures").symlink_to(sibling, target_is_directory=True)
    before = _snapshot(sibling)
    with pytest.raises(TavcError) as refused:
        take_report_folders(results)
    _one_line_naming(str(refused.value), results / "figures")
    assert "is a symbolic link" in str(refused.value)
    assert _snapshot(sibling) == before and not (results / "REPORT.md").exists()


@pytest.fixture(scope="module")
def finished(tmp_path_factory):
    """A finished smoke run, as `tavc run` writes it."""
    out = tmp_path_factory.mktemp("finished") / "run"
    result = CliRunner().invoke(app, [*RUN, f"output_dir={out}", "--no-progress"])
    assert result.exit_code == 0, result.output
    return out


def test_a_run_whose_trials_folder_is_a_link_is_refused(finished, tmp_path, sibling):
    """The run's own folder, its trials/ swapped for a link to somebody else's folder: a rerun
    would have read its records there and written them there."""
    run = tmp_path / "run"
    shutil.copytree(finished, run)
    shutil.copytree(run / "trials", sibling / "trials")  # the records, where the link leads
    shutil.rmtree(run / "trials")
    (run / "trials").symlink_to(sibling / "trials", target_is_directory=True)
    before = _snapshot(sibling)
    result = runner.invoke(app, [*RUN, f"output_dir={run}", "overwrite=true", "seed=5", "--no-progress"])
    assert result.exit_code == 1
    assert result.output.splitlines() == [
        f"error: output_dir: {run / 'trials'} is a symbolic link to {sibling / 'trials'}, where tavc keeps a folder "
        "of its own; move it away or choose another folder"]
    assert _snapshot(sibling) == before


@pytest.mark.parametrize("how", ["link", "dangling", "fifo"])
def test_the_stores_writer_refuses_a_link_as_trials_or_as_a_record(tmp_path, sibling, how):
    """Below `take`: the record writer (`save_result`) and the store's check before reading."""
    record = TrialRecord(meta={"key": "k"})
    spec = type("Spec", (), {"controller": "tavc", "trial": 0})()
    run = tmp_path / "run"
    if how == "link":  # trials/ itself leads to the sibling
        run.mkdir()
        (run / "trials").symlink_to(sibling, target_is_directory=True)
        bad = run / "trials"
    else:
        bad = run / "trials" / "tavc_000.npz"
        _hostile(bad, sibling, how)
    before = _snapshot(sibling)
    with pytest.raises(TavcError) as refused:
        save_result(([(spec, record)], []), run)
    _one_line_naming(str(refused.value), bad)
    with pytest.raises(TavcError) as refused:
        TrialStore(run, Executor()).check_paths([spec])
    _one_line_naming(str(refused.value), bad)
    assert _snapshot(sibling) == before


def test_a_record_put_in_another_trials_place_since_it_ran_is_refused_when_read_back(tmp_path):
    """What the run reads back after its trials (`TrialStore.load`): each record only if its key is
    its trial's, so another trial's record put in its place (by code that ran a trial) is one line."""

    run = tmp_path / "run"
    result = runner.invoke(app, ["run", "experiment=initial_distribution", "scale=smoke", "trials=2", "baselines=[]",
                                 "duration_s=60", "convergence_s=20", f"output_dir={run}", "--no-progress"])
    assert result.exit_code == 0, result.output
    specs = trial_specs(config.settings(config.load_config(
        ["experiment=initial_distribution", "scale=smoke", "trials=2", "baselines=[]", "duration_s=60",
         "convergence_s=20"])))
    assert len(TrialStore(run, Executor()).load(specs)) == 2  # as written: read
    shutil.copyfile(run / "trials" / "tavc_000.npz", run / "trials" / "tavc_001.npz")
    with pytest.raises(TavcError) as refused:
        TrialStore(run, Executor()).load(specs)
    assert str(refused.value) == (f"{run / 'trials' / 'tavc_001.npz'} is not the record its trial wrote (another "
                                  "trial's, damaged, or larger than tavc reads); run the same command again to "
                                  "compute it anew")


def test_a_record_of_the_right_key_but_not_of_numbers_is_one_line(finished, tmp_path):
    """Its key right, its contents not a record's (as code that ran the trial could leave it):
    refused in one line when read back, never a traceback in the analysis."""

    run = tmp_path / "run"
    shutil.copytree(finished, run)
    path = next((run / "trials").glob("tavc_*.npz"))
    record = TrialRecord.load(path)
    chosen = len(record.tables["choices"]["t_s"])
    assert chosen > 0  # every robot chooses at the start
    record.tables["choices"]["t_s"] = np.array(["soon"] * chosen)
    record.save(path)
    specs = [s for s in trial_specs(config.settings(config.load_config(RUN[1:-1] + [RUN[-1]])))
             if path.name == f"{s.controller}_{s.trial:03d}.npz"]
    with pytest.raises(TavcError) as refused:
        TrialStore(run, Executor()).load(specs)
    assert str(refused.value) == (f"{path} is not the record its trial wrote (an array that is not of numbers, or a "
                                  "column that is not flat); run the same command again to compute it anew")


def test_a_trials_folder_of_any_depth_is_checked_without_recursion(tmp_path):
    deep = tmp_path / "run" / "trials"
    deep.mkdir(parents=True)
    for _ in range(400):  # made level by level (pathlib's mkdir recurses too)
        deep = deep / "a"
        deep.mkdir()
    limit = sys.getrecursionlimit()
    sys.setrecursionlimit(300)  # a tree deeper than recursion goes, as 1,500 levels are at Python's own limit
    try:
        check_inside(tmp_path / "run", RUN_KIND, [])  # folders only: nothing refused
    finally:
        sys.setrecursionlimit(limit)
    (deep / "x.npz").symlink_to(tmp_path / "elsewhere.npz")
    with pytest.raises(TavcError, match="x.npz is a symbolic link"):
        check_inside(tmp_path / "run", RUN_KIND, [])


def test_the_atomic_writer_refuses_a_link_as_parent_or_a_pipe_as_its_file(tmp_path, sibling):
    run = tmp_path / "run"
    run.mkdir()
    (run / "tables").symlink_to(sibling, target_is_directory=True)
    os.mkfifo(run / "state_time.csv")
    before = _snapshot(sibling)
    with pytest.raises(TavcError, match="tables is a symbolic link"):
        write_text_atomic(run / "tables" / "theirs.txt", "tavc's\n", root=run)
    with pytest.raises(TavcError, match="state_time.csv is a named pipe"):  # refused, not blocked on
        write_text_atomic(run / "state_time.csv", "tavc's\n")
    assert _snapshot(sibling) == before


def test_a_normal_run_still_writes_its_lock_figures_and_records(finished, tmp_path):
    # the records, regular files in a real folder; the lock gone once the run ended
    assert not (finished / "trials").is_symlink()
    records = sorted(p.name for p in (finished / "trials").iterdir())
    assert records == ["random_000.npz", "tavc_000.npz"]
    assert all((finished / "trials" / n).is_file() and not (finished / "trials" / n).is_symlink() for n in records)
    assert not (finished / LOCK_NAME).exists()
    # the lock, a regular file naming the run while it holds the folder
    with claim_folder(tmp_path / "held"):
        lock = tmp_path / "held" / LOCK_NAME
        assert lock.is_file() and not lock.is_symlink()
        assert lock.read_text().startswith(f"pid {os.getpid()} on ")
    # figures, written and replaced in place
    stem = tmp_path / "figures" / "state"
    for _ in range(2):
        fig, ax = plt.subplots()
        ax.plot([0, 1], [1, 0])
        assert save_figure(fig, stem) == [stem.with_suffix(".png"), stem.with_suffix(".svg")]
    assert sorted(p.name for p in stem.parent.iterdir()) == ["state.png", "state.svg"]  # no temporary left
    assert stem.with_suffix(".png").read_bytes().startswith(b"\x89PNG")
    assert b"<svg" in stem.with_suffix(".svg").read_bytes()


# each command names a folder below the one its user named; the link stands there
_BELOW = [
    ("initial_distribution", ["reproduce", "scale=smoke", "--experiments", "initial_distribution", "--results", "{X}"]),
    ("0_seed=0", ["run", "-m", *RUN[1:], "seed=0,1", "output_dir={X}"]),
    ("ladder", ["ladder", "--factors", "1", "scale=smoke", "--results", "{X}"]),
    ("ladder/x1", ["ladder", "--factors", "1", "scale=smoke", "--results", "{X}"]),
    ("runs", ["compare", "scale=smoke", "--learners", "tavc", "--experiments", "initial_distribution",
              "--results", "{X}"]),
    ("runs/tavc/initial_distribution", ["compare", "scale=smoke", "--learners", "tavc", "--experiments",
                                        "initial_distribution", "--results", "{X}"]),
    ("calibration", ["calibrate", "scale=smoke", "output_dir={X}"]),
    ("calibration/world", ["calibrate", "scale=smoke", "output_dir={X}"]),
    ("model", ["model", "experiment=initial_distribution", "scale=smoke", "output_dir={X}"]),
    ("turn_taking", ["model", "--turn-taking", "experiment=initial_distribution", "scale=smoke", "output_dir={X}"]),
]


@pytest.mark.parametrize(("below", "args"), _BELOW, ids=[b for b, _ in _BELOW])
def test_a_link_where_tavc_names_a_folder_below_the_users_is_refused_not_followed(below, args, tmp_path, sibling):
    """The folder the user names may be a link (their choice); the folders tavc makes below it may
    not: a link there is one line naming it, and nothing is written where it leads."""
    named = tmp_path / "named"
    (named / below).parent.mkdir(parents=True, exist_ok=True)
    (named / below).symlink_to(sibling, target_is_directory=True)
    before = _snapshot(sibling)
    result = runner.invoke(app, [a.replace("{X}", str(named)) for a in args])
    assert result.exit_code == 1, result.output
    assert result.output.startswith("error: ") and len(result.output.strip().splitlines()) == 1, result.output
    assert f"{named / below} is a symbolic link to {sibling}" in result.output, result.output
    assert _snapshot(sibling) == before


def test_a_surrogate_run_checks_its_folder_before_measuring_its_tasks_into_it(tmp_path, sibling):
    """A surrogate run in a folder of the user's keeps its measured tasks in its tasks/: a link
    there, or a file of the user's in the folder, is refused before anything is measured, and
    nothing is written where the link leads or beside the user's file."""
    linked = tmp_path / "linked"
    linked.mkdir()
    (linked / "tasks").symlink_to(sibling, target_is_directory=True)
    before = _snapshot(sibling)
    theirs = tmp_path / "theirs"
    theirs.mkdir()
    (theirs / "notes.txt").write_bytes(THEIRS)
    for folder in (linked, theirs):
        result = runner.invoke(app, ["surrogate", "experiment=breakdown", "scale=smoke", f"output_dir={folder}",
                                     "--no-progress"])
        assert result.exit_code == 1 and len(result.output.strip().splitlines()) == 1, result.output
        assert result.output.startswith(f"error: output_dir: {folder} holds files tavc did not write"), result.output
    assert _snapshot(sibling) == before
    assert sorted(p.name for p in theirs.iterdir()) == ["notes.txt"]


@pytest.mark.parametrize("command", [[*RUN, "output_dir={place}"], ["calibrate", "scale=smoke", "output_dir={place}"]])
def test_a_file_or_a_link_to_nothing_where_a_folder_goes_is_named_as_what_it_is(tmp_path, command):
    """Where tavc would make or write in a folder: a file there, a file above it, or a link to a
    place that does not exist is one line saying which, before anything is written."""
    (tmp_path / "notes.txt").write_bytes(THEIRS)
    (tmp_path / "gone").symlink_to(tmp_path / "nowhere", target_is_directory=True)
    before = _snapshot(tmp_path)
    for place, says in ((tmp_path / "notes.txt", f"{tmp_path / 'notes.txt'} is a file; name a folder"),
                        (tmp_path / "notes.txt" / "mine", f"{tmp_path / 'notes.txt' / 'mine'} lies below "
                                                          f"{tmp_path / 'notes.txt'}, which is a file; name a folder"),
                        (tmp_path / "gone" / "mine", f"{tmp_path / 'gone'} is a link to {tmp_path / 'nowhere'}, "
                                                     "which does not exist; make that folder or name another")):
        result = runner.invoke(app, [part.format(place=place) for part in command])
        assert result.exit_code == 1 and result.output == f"error: output_dir: {says}\n"
    assert _snapshot(tmp_path) == before


def test_a_file_given_as_the_results_folder_is_named_by_its_option(tmp_path):
    (tmp_path / "notes.txt").write_bytes(THEIRS)
    result = tavc("reproduce", "scale=smoke", "--experiments", "breakdown", "--results", "notes.txt", cwd=tmp_path)
    assert result.returncode == 2
    assert result.stderr == "error: Invalid value for '--results': notes.txt is a file; name a folder (tavc --help)\n"
    assert [p.name for p in tmp_path.iterdir()] == ["notes.txt"]


def test_reproduce_checks_every_folder_before_it_changes_any(tmp_path):
    """The first experiment's folder holds a run of other settings with its animation (replaced with
    overwrite=true), the second a file of the user's where a table goes: refused in one line, and
    the first run's animation is still there."""
    from tavc_cli.pipeline import run_experiments

    first, second = tmp_path / "breakdown", tmp_path / "initial_distribution"
    first.mkdir()
    (first / "config.yaml").write_text(config.to_yaml(config.load_config(["experiment=breakdown", "seed=9"])))
    (first / "animation.gif").write_bytes(b"GIF89a")
    (first / ".tavc.json").write_text('{"tavc": "run", "files": ["animation.gif", "config.yaml"]}')
    second.mkdir()
    (second / "performance.csv").write_text("mine\n")
    cfgs = [config.settings(config.load_config([f"experiment={folder.name}", "scale=smoke", "overwrite=true",
                                                f"output_dir={folder}"])) for folder in (first, second)]
    with pytest.raises(TavcError, match=r"holds files tavc did not write \(performance.csv\)"):
        run_experiments(cfgs)
    assert (first / "animation.gif").read_bytes() == b"GIF89a" and (second / "performance.csv").read_text() == "mine\n"
