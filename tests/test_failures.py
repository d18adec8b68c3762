"""When things go wrong: a trial that fails is contained, two runs never share a folder, an
unreachable cluster is refused before anything is written, a killed run resumes to the same
tables."""

import math
import os
import random
import re
import shutil
import signal
import subprocess
import sys
import time
from functools import partial

import pytest
from typer.testing import CliRunner

from tavc_cli.analysis.table_schemas import TABLE_NAMES
from tavc_cli.cli import app
from tavc_cli.config import load_config, settings
from tavc_cli.errors import TavcError
from tavc_cli.experiments import engine
from tavc_cli.experiments.arrivals import ArrivalDesk
from tavc_cli.experiments.build import trial_specs
from tavc_cli.experiments.store import FAILURES_LOG
from tavc_cli.io import LOCK_NAME, claim_folder
from tavc_cli.ownership import MANIFEST, trial_path
from tavc_cli.pipeline import run_experiment
from tests.helpers import run_settings

SMOKE = ["scale=smoke", "duration_s=120", "convergence_s=20", "arena=two_circuits", "learner=random",
         "executor.n_jobs=1"]


_cfg = partial(run_settings, SMOKE)  # the settings of a smoke run into a folder, then more overrides


def _cli(out_dir, *extra):
    return CliRunner().invoke(app, ["run", *SMOKE, f"output_dir={out_dir}", *extra])


def _files(folder):
    return sorted(str(p.relative_to(folder)) for p in folder.rglob("*") if p.is_file())


@pytest.fixture
def reference(finished_run):
    """An uneventful run of 4 trials: what every recovered run must reproduce (shared, never changed)."""
    return finished_run(*SMOKE, "trials=4")


def _fault_on_tick(monkeypatch, trial: int, tick: int, fault) -> None:
    """Make `fault(engine, global robot index)` happen to robot 0 of `trial` at `tick`, in this
    process and in worker processes forked from it."""
    real_init = engine.BatchEngine.__init__

    def init(self, specs):
        real_init(self, specs)
        targets = [tr.lo for tr in self.trials if tr.spec.trial == trial]

        def on_tick(eng):
            if eng.tick == tick:
                for g in targets:
                    fault(eng, g)

        self.on_tick = on_tick

    monkeypatch.setattr(engine.BatchEngine, "__init__", init)


def _nan_pose(eng, g):
    eng.world._parts[g][0].position = (math.nan, math.nan)


def _teleport(eng, g):
    eng.world._parts[g][0].position = (-5.0, -5.0)


def _assert_recovers(out, reference, n_reused):
    """The rerun computes only the missing trials and writes the uneventful run's tables."""
    summary = run_experiment(_cfg(out, "trials=4"))
    assert summary["n_reused"] == n_reused
    tables = sorted(p.name for p in reference.glob("*.csv"))
    assert {"state_time.csv", "performance.csv"} <= set(tables)
    for name in tables:
        assert (out / name).read_bytes() == (reference / name).read_bytes(), name
    assert not (out / FAILURES_LOG).exists()
    for j in range(4):
        assert trial_path(out, "random", j).read_bytes() == trial_path(reference, "random", j).read_bytes()


# --- failures inside a trial ------------------------------------------------------------------

@pytest.mark.parametrize("n_jobs", [1, 2])
def test_a_pose_that_is_not_a_number_stops_only_its_trial(tmp_path, monkeypatch, reference, n_jobs):
    seed = next(s.seed for s in trial_specs(_cfg(tmp_path, "trials=4")) if s.trial == 1)
    _fault_on_tick(monkeypatch, trial=1, tick=40, fault=_nan_pose)
    result = _cli(tmp_path, "trials=4", "executor.batch_size=2", f"executor.n_jobs={n_jobs}")
    assert result.exit_code == 1
    line = result.output.strip().splitlines()[-1]
    assert line.startswith(f"error: trial random_001 (seed {list(seed)}) failed: robot 0 has no valid pose at t = ")
    assert f"the other 3 trials are kept in {tmp_path / 'trials'}" in line
    # the other trials are kept, nothing of the run's analysis is written
    assert _files(tmp_path) == [MANIFEST, "config.yaml", FAILURES_LOG, "plan.json",
                                *[f"trials/random_{j:03d}.npz" for j in (0, 2, 3)]]
    assert "random_001" in (tmp_path / FAILURES_LOG).read_text()
    monkeypatch.undo()
    _assert_recovers(tmp_path, reference, n_reused=3)


def test_a_robot_outside_the_walls_stops_its_trial(tmp_path, monkeypatch, reference):
    _fault_on_tick(monkeypatch, trial=3, tick=10, fault=_teleport)
    result = _cli(tmp_path, "trials=4", "executor.batch_size=4")
    assert result.exit_code == 1
    assert "trial random_003 (seed" in result.output
    assert re.search(r"failed: robot 0 is outside the walls at \(-?[\d.]+, -[\d.]+\) m at t = [\d.]+ s;", result.output)
    monkeypatch.undo()
    _assert_recovers(tmp_path, reference, n_reused=3)


def test_an_exception_inside_a_trial_is_named_and_the_others_finish(tmp_path, monkeypatch, reference):
    real_log = ArrivalDesk.log_arrival  # every arrival is logged, served by Python or compiled code

    def log_arrival(tr, *row):
        if tr.spec.trial in (0, 2):
            raise ZeroDivisionError("a made-up fault in the simulation")
        real_log(tr, *row)

    monkeypatch.setattr(ArrivalDesk, "log_arrival", staticmethod(log_arrival))
    result = _cli(tmp_path, "trials=4", "executor.batch_size=4")
    assert result.exit_code == 1
    assert len(result.output.strip().splitlines()) == 1
    assert result.output.startswith("error: 2 trials failed, the first random_000 (seed ")
    assert "ZeroDivisionError: a made-up fault in the simulation; the other 2 trials are kept" in result.output
    log = (tmp_path / FAILURES_LOG).read_text()
    assert "trial random_002" in log and "Traceback" in log  # the details are kept for a bug report
    assert _files(tmp_path) == [MANIFEST, "config.yaml", FAILURES_LOG, "plan.json", "trials/random_001.npz",
                                "trials/random_003.npz"]
    monkeypatch.undo()
    _assert_recovers(tmp_path, reference, n_reused=2)


# --- one run per folder -----------------------------------------------------------------------

_HOLD = """
import sys, time
from pathlib import Path
from tavc_cli.io import claim_folder
with claim_folder(Path(sys.argv[1])):
    print("held", flush=True)
    time.sleep(120)
"""


def test_a_second_run_on_a_folder_in_use_stops_and_writes_nothing(tmp_path):
    holder = subprocess.Popen([sys.executable, "-c", _HOLD, str(tmp_path)], stdout=subprocess.PIPE, text=True)
    try:
        assert holder.stdout.readline().strip() == "held"
        result = _cli(tmp_path, "trials=2")
        assert result.exit_code == 1
        assert result.output.strip() == result.output.strip().splitlines()[0]
        assert f"error: output_dir: {tmp_path} is in use by another tavc run (pid {holder.pid} on " in result.output
        assert "wait for it to finish or choose another folder" in result.output
        assert _files(tmp_path) == [LOCK_NAME]
    finally:
        holder.send_signal(signal.SIGKILL)  # a crash: the lock goes with the process
        holder.wait()
    result = _cli(tmp_path, "trials=2")
    assert result.exit_code == 0, result.output
    assert not (tmp_path / LOCK_NAME).exists()  # released on a normal exit


def test_the_folder_is_released_after_a_refused_or_failed_run(tmp_path, monkeypatch):
    boom = staticmethod(lambda *a: (_ for _ in ()).throw(RuntimeError("boom")))
    monkeypatch.setattr(ArrivalDesk, "log_arrival", boom)
    with pytest.raises(TavcError, match="failed: RuntimeError: boom"):
        run_experiment(_cfg(tmp_path, "trials=1"))
    assert not (tmp_path / LOCK_NAME).exists()
    with claim_folder(tmp_path):  # free again
        with pytest.raises(TavcError, match="in use by another tavc run"):
            with claim_folder(tmp_path):
                pass


def test_a_file_of_the_users_by_the_locks_name_is_neither_emptied_nor_removed(tmp_path):
    """A lock a killed run left (its own text) is taken and removed as tavc's; a file of the
    user's by that name, refused in one line, is left as it was."""
    left = tmp_path / "left"
    left.mkdir()
    (left / LOCK_NAME).write_text("pid 41 on elsewhere, since 2026-01-02 03:04:05: tavc run\n")  # kill -9's
    with claim_folder(left):
        pass
    assert not (left / LOCK_NAME).exists()
    mine = tmp_path / "mine"
    mine.mkdir()
    (mine / LOCK_NAME).write_text("my notes\n")
    with pytest.raises(TavcError) as refused:
        with claim_folder(mine):
            pass
    assert str(refused.value) == (f"output_dir: {mine / LOCK_NAME} was not written by tavc, which keeps its lock "
                                  "under that name; move it away")
    assert (mine / LOCK_NAME).read_text() == "my notes\n"


# --- clusters that do not answer ----------------------------------------------------------------

@pytest.mark.parametrize("backend", ["dask", "ray"])
def test_an_unreachable_cluster_is_refused_before_anything_is_written(tmp_path, backend):
    pytest.importorskip("distributed" if backend == "dask" else "ray")
    import socket

    with socket.socket() as s:  # a port nobody listens on
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    out = tmp_path / "out"
    result = _cli(out, "trials=2", f"executor.backend={backend}", f"executor.address=tcp://127.0.0.1:{port}")
    assert result.exit_code == 1
    assert result.output.startswith("error: executor.address: cannot reach the ")
    assert f"at tcp://127.0.0.1:{port}" in result.output
    assert not out.exists()


# --- a run killed at any moment ------------------------------------------------------------------

_KILLED_RUN = [sys.executable, "-m", "tavc_cli", "run", *SMOKE, "trials=6", "executor.batch_size=1",
               "executor.n_jobs=2", "duration_s=1500", "convergence_s=300"]


@pytest.fixture(scope="module")
def uninterrupted(tmp_path_factory):
    """The run the killed ones are held to, made once, and how long it took (seconds)."""
    whole = tmp_path_factory.mktemp("uninterrupted") / "whole"
    start = time.perf_counter()
    subprocess.run([*_KILLED_RUN, f"output_dir={whole}"], check=True, capture_output=True)
    return whole, time.perf_counter() - start


@pytest.mark.slow
@pytest.mark.parametrize("moment_seed", [1, 5, 2])
def test_a_run_killed_with_sigkill_resumes_to_the_same_tables(tmp_path, uninterrupted, moment_seed):
    """kill -9 at a random moment of the run (starting, simulating or writing): the rerun
    reuses what was finished and writes tables byte-identical to an uninterrupted run's."""
    (whole, took), killed = uninterrupted, tmp_path / "killed"
    moment = random.Random(moment_seed).uniform(0.05, 0.95) * took
    proc = subprocess.Popen([*_KILLED_RUN, f"output_dir={killed}"], stdout=subprocess.DEVNULL,
                            stderr=subprocess.DEVNULL, start_new_session=True)
    time.sleep(moment)
    os.killpg(proc.pid, signal.SIGKILL)  # the run and its worker processes
    proc.wait()
    subprocess.run([*_KILLED_RUN, f"output_dir={killed}"], check=True, capture_output=True)
    assert [p.name for p in killed.rglob(".*.tmp")] == []  # what the kill left half-written is gone
    tables = sorted(p.name for p in whole.glob("*.csv"))
    assert {"state_time.csv", "performance.csv"} <= set(tables)
    for name in tables:
        assert (killed / name).read_bytes() == (whole / name).read_bytes(), name
    for j in range(6):
        assert trial_path(killed, "random", j).read_bytes() == trial_path(whole, "random", j).read_bytes()


def _long_run(out_dir):
    """A run of two worker processes that lasts well beyond the test's patience."""
    return subprocess.Popen([sys.executable, "-m", "tavc_cli", "run", *SMOKE, "trials=4", "executor.batch_size=1",
                             "executor.n_jobs=2", "duration_s=40000", "convergence_s=100", f"output_dir={out_dir}"],
                            stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)


def _wait_for_workers(proc, n: int = 2, timeout_s: float = 60.0) -> list[int]:
    """The pids of the run's worker processes, once `n` of them simulate."""
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        children = subprocess.run(["pgrep", "-P", str(proc.pid)], capture_output=True, text=True).stdout.split()
        if len(children) >= n + 1:  # the pool's workers and the progress queue's server
            return [int(c) for c in children]
        time.sleep(0.2)
    raise AssertionError("the run started no workers")


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    with open(f"/proc/{pid}/stat") as fh:  # a zombie has finished
        return fh.read().split(")")[-1].split()[0] != "Z"


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="process checks read /proc")
def test_sigterm_stops_the_run_and_its_workers_and_frees_the_folder(tmp_path):
    proc = _long_run(tmp_path)
    children = _wait_for_workers(proc)
    proc.send_signal(signal.SIGTERM)
    assert proc.wait(timeout=30) == 143
    assert proc.stderr.read().strip() == "error: terminated"
    deadline = time.monotonic() + 10
    while any(_alive(c) for c in children) and time.monotonic() < deadline:
        time.sleep(0.1)
    assert not any(_alive(c) for c in children)
    assert not (tmp_path / LOCK_NAME).exists()


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="process checks read /proc")
def test_a_run_killed_alone_leaves_no_worker_holding_its_folder(tmp_path):
    proc = _long_run(tmp_path)
    children = _wait_for_workers(proc)
    proc.send_signal(signal.SIGKILL)  # the run only, not its process group: its workers are orphaned
    proc.wait()
    deadline = time.monotonic() + 10
    while any(_alive(c) for c in children) and time.monotonic() < deadline:
        time.sleep(0.1)
    assert not any(_alive(c) for c in children)  # they die with the run
    with claim_folder(tmp_path):  # and none of them held the folder
        pass


_HOLD_AND_FORK = """
import os, sys, time
from pathlib import Path
from tavc_cli.io import claim_folder
with claim_folder(Path(sys.argv[1])):
    ready_r, ready_w = os.pipe()
    if os.fork() == 0:  # a child outliving the run, as an orphaned worker would
        os.write(ready_w, b"x")  # the fork hooks have run by the time the child's own code does
        time.sleep(60)
        os._exit(0)
    os.read(ready_r, 1)  # the child has been scheduled at least once
    print("held", flush=True)
    time.sleep(60)
"""


def test_a_forked_child_does_not_inherit_the_folder(tmp_path):
    holder = subprocess.Popen([sys.executable, "-c", _HOLD_AND_FORK, str(tmp_path)], stdout=subprocess.PIPE,
                              text=True, start_new_session=True)
    try:
        assert holder.stdout.readline().strip() == "held"
        holder.send_signal(signal.SIGKILL)  # the holder dies without cleaning up; its child lives on
        holder.wait()
        assert (tmp_path / LOCK_NAME).exists()
        with claim_folder(tmp_path):
            pass
    finally:
        os.killpg(holder.pid, signal.SIGKILL)


def test_a_folder_reused_for_another_experiment_keeps_none_of_its_tables(tmp_path):
    run_experiment(settings(load_config(["experiment=breakdown", "scale=smoke", f"output_dir={tmp_path}"])))
    assert (tmp_path / "vacancy.csv").is_file() and (tmp_path / "claims.csv").is_file()
    assert {p.stem for p in tmp_path.glob("*.csv")} <= set(TABLE_NAMES)  # the list knows every table
    (tmp_path / "my_notes.csv").write_text("mine\n")
    run_experiment(_cfg(tmp_path, "trials=2", "overwrite=true"))  # random robots, no event: no vacancies, no claims
    assert not (tmp_path / "vacancy.csv").exists() and not (tmp_path / "claims.csv").exists()
    assert (tmp_path / "state_time.csv").is_file() and (tmp_path / "my_notes.csv").read_text() == "mine\n"


def test_a_damaged_trial_file_is_run_again_and_said_so(tmp_path, reference, capsys):
    run_experiment(_cfg(tmp_path, "trials=4"))
    trial_path(tmp_path, "random", 2).write_bytes(b"not a trial record")
    capsys.readouterr()
    run_experiment(_cfg(tmp_path, "trials=4"))
    assert "are damaged or unreadable (random_002.npz); running those trials again" in capsys.readouterr().out
    assert trial_path(tmp_path, "random", 2).read_bytes() == trial_path(reference, "random", 2).read_bytes()


def test_something_in_the_way_of_the_trial_records_is_one_line(tmp_path):
    run_experiment(_cfg(tmp_path, "trials=1"))  # the folder is a run's: only the records' places are in the way
    shutil.rmtree(tmp_path / "trials")
    (tmp_path / "trials").write_text("")
    with pytest.raises(TavcError, match=r"trials: a file stands where tavc writes its trial records; move it away$"):
        run_experiment(_cfg(tmp_path, "trials=1"))
    # refused before the folder is rewritten: a rerun that only runs elsewhere leaves the run finished
    with pytest.raises(TavcError, match=r"trials: a file stands where tavc writes its trial records; move it away$"):
        run_experiment(_cfg(tmp_path, "trials=1", "executor.batch_size=3"))
    assert (tmp_path / "provenance.json").is_file()
    (tmp_path / "trials").unlink()
    trial_path(tmp_path, "random", 0).mkdir(parents=True)
    with pytest.raises(TavcError, match=r"random_000.npz: a folder stands where tavc writes its trial records"):
        run_experiment(_cfg(tmp_path, "trials=1"))



def _deaf_to_sigterm(ready) -> None:
    """A pool worker that has not yet replaced a SIGTERM handler that lets it live (dying with the
    test all the same), counted in `ready` once it is so."""
    from tavc_cli.confine import die_with_parent

    die_with_parent()
    signal.signal(signal.SIGTERM, lambda *_: None)
    with ready.get_lock():
        ready.value += 1


def _touch_and_sleep(path: str) -> None:
    with open(path, "w"):
        pass
    time.sleep(30)


def _until(condition, timeout_s: float = 20.0) -> None:
    end = time.monotonic() + timeout_s
    while not condition():
        assert time.monotonic() < end, "gave up waiting"
        time.sleep(0.02)


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="forked workers")
def test_stopping_a_pool_stops_a_worker_that_does_not_heed_sigterm(tmp_path):
    """`stop_workers` ends every worker, even one deaf to SIGTERM, so that waiting for the pool
    ends too (a worker left alive would wait for good on the pool's queue): both workers deaf and
    one of them busy before it is called."""
    import multiprocessing as mp
    import threading
    from concurrent.futures import ProcessPoolExecutor

    from tavc_cli.experiments.pool import stop_workers

    ctx = mp.get_context("fork")
    ready = ctx.Value("i", 0)
    pool = ProcessPoolExecutor(max_workers=2, mp_context=ctx, initializer=_deaf_to_sigterm, initargs=(ready,))
    started = tmp_path / "started"
    try:
        busy = pool.submit(_touch_and_sleep, str(started))
        _until(lambda: ready.value == 2 and started.exists())
        stopper = threading.Thread(target=stop_workers, args=(pool,), daemon=True)
        stopper.start()
        stopper.join(timeout=20)
        assert not stopper.is_alive(), "stop_workers waited for a worker it did not stop"
        assert busy.done()
        stop_workers(pool)  # again, on a pool already shut down (an interrupt after it ended): nothing to do
    finally:  # whatever happened, no worker outlives the test
        for worker in list((getattr(pool, "_processes", None) or {}).values()):
            worker.kill()
