"""Faults injected on purpose: trial files damaged at random offsets, runs killed at random
moments of a rerun, tables damaged in a finished run, a full disk, SIGTERM while the tables are
written. Whatever happens, nothing finished is lost, the rerun heals the folder, its tables
equal an undisturbed run's byte for byte, and a failure is one line."""

import errno
import json
import os
import random
import shutil
import signal
import subprocess
import sys
import threading
import time
from functools import partial

import pytest
from hypothesis import HealthCheck, given
from hypothesis import settings as hyp_settings
from hypothesis import strategies as st
from typer.testing import CliRunner

from tavc_cli import io as tavc_io
from tavc_cli import pipeline
from tavc_cli.cli import app
from tavc_cli.errors import Terminated, sigterm_raises
from tavc_cli.experiments.records import TrialRecord, records_differ
from tavc_cli.ownership import trial_path
from tavc_cli.pipeline import run_experiment
from tests.helpers import run_settings, then_interrupted

SMOKE = ["scale=smoke", "duration_s=120", "convergence_s=20", "arena=two_circuits", "learner=random",
         "executor.n_jobs=1", "trials=3"]


_cfg = partial(run_settings, SMOKE)  # the settings of a smoke run into a folder, then more overrides


def _tables(folder):
    return {p.name: p.read_bytes() for p in sorted(folder.glob("*.csv"))}


@pytest.fixture
def undisturbed(finished_run):
    """What every disturbed run must come back to (shared: the tests disturb copies of it)."""
    return finished_run(*SMOKE)


def _assert_healed(out, undisturbed):
    assert _tables(out) == _tables(undisturbed)
    for j in range(3):  # the records' contents: damage to a zip field no checksum covers leaves them whole
        healed, whole = (TrialRecord.load(trial_path(d, "random", j)) for d in (out, undisturbed))
        assert records_differ(healed, whole) == []
    assert (out / "provenance.json").is_file()


@pytest.mark.slow
@hyp_settings(max_examples=8, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(trial=st.integers(0, 2), where=st.floats(0.0, 0.999), length=st.integers(1, 64), xor=st.integers(1, 255))
def test_a_trial_file_damaged_anywhere_is_named_and_run_again(undisturbed, tmp_path_factory, trial, where, length,
                                                             xor):
    out = tmp_path_factory.mktemp("damaged") / "run"
    shutil.copytree(undisturbed, out)
    path = trial_path(out, "random", trial)
    data = bytearray(path.read_bytes())
    start = int(where * len(data))
    for k in range(start, min(start + length, len(data))):
        data[k] ^= xor
    path.write_bytes(bytes(data))
    result = CliRunner().invoke(app, ["run", *SMOKE, f"output_dir={out}"])
    assert result.exit_code == 0, result.output
    damaged = [line for line in result.output.splitlines() if line.startswith("note:")]
    # damage in the zip's optional fields (a member's time stamp, its comment) leaves the record
    # whole: then nothing is run again, and nothing needs to be
    assert damaged in ([], [f"note: 1 trial files in {out / 'trials'} are damaged or unreadable ({path.name}); "
                            "running those trials again"])
    _assert_healed(out, undisturbed)


def test_swapped_trial_files_are_named_and_run_again(undisturbed, tmp_path):
    """Two records swapped (each whole, but each another trial's): named in a note, and healed."""
    out = tmp_path / "run"
    shutil.copytree(undisturbed, out)
    a, b = trial_path(out, "random", 0), trial_path(out, "random", 1)
    data = a.read_bytes()
    a.write_bytes(b.read_bytes())
    b.write_bytes(data)
    result = CliRunner().invoke(app, ["run", *SMOKE, f"output_dir={out}"])
    assert result.exit_code == 0, result.output
    assert (f"note: 2 trial files in {out / 'trials'} were made with other settings or another version of the "
            "simulator (random_000.npz, random_001.npz); running those trials again") in result.output.splitlines()
    _assert_healed(out, undisturbed)


def test_a_record_with_a_member_that_is_not_an_array_is_named_and_run_again(undisturbed, tmp_path):
    """A record whole to zip (every checksum right) with its key intact, but one member that
    does not read as an array: named in a note, run again, healed."""
    import zipfile

    out = tmp_path / "run"
    shutil.copytree(undisturbed, out)
    path = trial_path(out, "random", 1)
    with zipfile.ZipFile(path) as archive:
        members = {m: archive.read(m) for m in archive.namelist()}
    members["deliveries__reward.npy"] = b"not an array"
    with zipfile.ZipFile(path, "w") as archive:
        for name, data in members.items():
            archive.writestr(name, data)
    result = CliRunner().invoke(app, ["run", *SMOKE, f"output_dir={out}"])
    assert result.exit_code == 0, result.output
    assert (f"note: 1 trial files in {out / 'trials'} are damaged or unreadable (random_001.npz); running those "
            "trials again") in result.output.splitlines()
    _assert_healed(out, undisturbed)


@pytest.mark.parametrize("change", [["executor.batch_size=1"], ["executor.n_jobs=2"], []])
def test_a_rerun_stopped_after_writing_its_config_is_resumed_by_the_same_command(undisturbed, tmp_path, monkeypatch,
                                                                                 change):
    """A finished run rerun with only where or how fast it runs changed (or nothing), stopped
    between writing config.yaml and provenance.json: the same command resumes it, not refuses
    it as another configuration, and its tables are the undisturbed run's."""
    out = tmp_path / "run"
    shutil.copytree(undisturbed, out)
    monkeypatch.setattr(pipeline, "take_run_folder", then_interrupted(pipeline.take_run_folder))
    with pytest.raises(KeyboardInterrupt):
        run_experiment(_cfg(out, *change))
    monkeypatch.undo()
    result = CliRunner().invoke(app, ["run", *SMOKE, *change, f"output_dir={out}"])
    assert result.exit_code == 0, result.output
    _assert_healed(out, undisturbed)


@pytest.mark.parametrize("table", ["state_time.csv", "trial_stats.csv", "performance.csv", "robots.csv"])
def test_a_damaged_table_in_a_finished_run_is_rewritten_by_the_rerun(undisturbed, tmp_path, table):
    out = tmp_path / "run"
    shutil.copytree(undisturbed, out)
    text = (out / table).read_bytes()
    (out / table).write_bytes(text[: len(text) // 3])  # cut partway through
    run_experiment(_cfg(out))
    _assert_healed(out, undisturbed)


@pytest.mark.slow
@pytest.mark.parametrize("moment_seed", [3, 11])
def test_a_rerun_killed_at_any_moment_leaves_the_run_finished_and_the_next_heals(undisturbed, tmp_path,
                                                                                  moment_seed):
    """A finished run whose trials are damaged is run again and killed (kill -9) at a random
    moment: provenance.json (the mark of a finished run) is still there, and the next rerun
    comes back to the undisturbed tables."""
    out = tmp_path / "run"
    shutil.copytree(undisturbed, out)
    for j in range(3):
        trial_path(out, "random", j).write_bytes(b"damaged")
    run = [sys.executable, "-m", "tavc_cli", "run", *SMOKE, f"output_dir={out}"]
    start = time.perf_counter()
    subprocess.run(run, check=True, capture_output=True)  # how long a rerun of three trials takes
    took = time.perf_counter() - start
    for j in range(3):
        trial_path(out, "random", j).write_bytes(b"damaged")
    proc = subprocess.Popen(run, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, start_new_session=True)
    time.sleep(random.Random(moment_seed).uniform(0.1, 0.9) * took)
    os.killpg(proc.pid, signal.SIGKILL)
    proc.wait()
    assert json.loads((out / "provenance.json").read_text())["tables"]  # still a finished run
    subprocess.run(run, check=True, capture_output=True)
    _assert_healed(out, undisturbed)


def test_a_full_disk_is_one_line_and_the_rerun_heals(undisturbed, tmp_path, monkeypatch):
    """The disk fills up after the first trial's file: one line naming the cause, the finished
    trial kept, and a rerun (with space again) reuses it and writes the undisturbed tables."""
    out = tmp_path / "run"
    real_fsync, calls = os.fsync, []

    def fsync(fd):
        calls.append(fd)
        if len(calls) > 4:  # the folder's list, config.yaml, plan.json and one trial's record, then nothing fits
            raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))
        real_fsync(fd)

    monkeypatch.setattr(tavc_io.os, "fsync", fsync)
    result = CliRunner().invoke(app, ["run", *SMOKE, f"output_dir={out}"])
    assert result.exit_code != 0
    lines = result.output.strip().splitlines()
    assert lines[-1].startswith("error: ") and "No space left on device" in lines[-1]
    assert not any("Traceback" in line for line in lines)
    assert not list(out.rglob(".*.tmp"))  # nothing half-written left behind
    assert sorted(p.name for p in (out / "trials").iterdir()) == ["random_000.npz"]
    monkeypatch.setattr(tavc_io.os, "fsync", real_fsync)
    run_experiment(_cfg(out))
    _assert_healed(out, undisturbed)


def _slow_finish(cfg, run, owned):
    time.sleep(120)


@pytest.mark.skipif(not pipeline.CAN_FORK, reason="the tables are written in forked processes only where the "
                                                   "system forks")
def test_sigterm_while_tables_are_written_stops_at_once(monkeypatch, tmp_path):
    """SIGTERM while worker processes write several experiments' tables: the run stops within
    seconds, not when the workers are done."""
    monkeypatch.setattr(pipeline, "_finish_loaded", _slow_finish)
    cfgs = [_cfg(tmp_path / "a", "executor.n_jobs=2"), _cfg(tmp_path / "b", "executor.n_jobs=2")]
    threading.Timer(1.0, os.kill, (os.getpid(), signal.SIGTERM)).start()
    start = time.monotonic()
    with pytest.raises(Terminated), sigterm_raises():
        pipeline._finish_all(cfgs, [None, None], [None, None])
    assert time.monotonic() - start < 20


@pytest.mark.slow
@pytest.mark.parametrize("moment", [0.05, 0.3, *[random.Random(k).uniform(0.8, 6.0) for k in (1, 2)]])
def test_ctrl_c_at_any_moment_is_one_line_and_the_rerun_heals(undisturbed, tmp_path, moment):
    """Ctrl-C (SIGINT to the run's process group, as a terminal sends it) at a moment from the
    first imports to the tables: at most one line on standard error, no traceback, exit 130
    (or 0 if the run was already done), and the rerun comes back to the undisturbed tables."""
    out = tmp_path / "run"
    run = [sys.executable, "-m", "tavc_cli", "run", *SMOKE, f"output_dir={out}"]
    proc = subprocess.Popen(run, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True,
                            start_new_session=True)
    time.sleep(moment)
    os.killpg(proc.pid, signal.SIGINT)
    _, err = proc.communicate(timeout=60)
    # 130: stopped by the interrupt; 0: it came after the run was done; -SIGINT: it came while
    # the interpreter was exiting, whose last moments belong to the signal's default action
    # (a shell shows that as 130 too)
    assert proc.returncode in (0, 130, -signal.SIGINT), err
    assert "Traceback" not in err
    assert len([line for line in err.splitlines() if line.strip()]) <= 1, err
    subprocess.run(run, check=True, capture_output=True)
    _assert_healed(out, undisturbed)


def test_a_result_that_cannot_be_replaced_is_named_not_its_folder():
    """A table made unwritable (renaming the temporary over it fails): the line names the table."""
    from tavc_cli.console import os_error_text

    error = PermissionError(errno.EPERM, "Operation not permitted", "/r/.state_time.csv.ab12cd34.tmp", None,
                            "/r/state_time.csv")
    assert os_error_text(error).startswith("/r/state_time.csv: Operation not permitted; ")
    error = PermissionError(errno.EACCES, "Permission denied", "/r/trials/.random_000.npz.ab12cd34.tmp")
    assert os_error_text(error).startswith("/r/trials: Permission denied; ")  # no temporary could be made there
