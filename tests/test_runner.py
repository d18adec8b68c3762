"""Running experiments (tavc_cli.experiments.runner): outputs, reuse, atomic writes, the CLI."""

import json

import numpy as np
import pandas as pd
import pytest
from typer.testing import CliRunner

from tavc_cli.analysis.states import state_intervals, theory_pct
from tavc_cli.cli import app
from tavc_cli.config import load_config, settings
from tavc_cli.errors import TavcError
from tavc_cli.experiments.build import trial_specs
from tavc_cli.experiments.records import TrialRecord, records_differ
from tavc_cli.ownership import trial_path
from tavc_cli.pipeline import run_experiment
from tests.helpers import run_settings

SMOKE = [
    "scale=smoke",
    "duration_s=120",
    "convergence_s=20",
    "trials=2",
    "arena=two_circuits",
    "learner=random",
    "executor.n_jobs=1",
]


# A world with little crowding (no dwell, a small dock zone, the reading at 0.30 m, 31 rays),
# for tests whose expectations are computed by hand for it or assume near-independent robots.
LOW_CROWDING_WORLD = ["robot.behaviour.arrive_dist_m=0.30", "robot.dock.dwell_s=0", "robot.dock.occupied_m=0.6",
                      "robot.laser.n_rays=31"]

def _run(out_dir, *extra):
    return run_experiment(run_settings(SMOKE, out_dir, *extra))


def _tmp_files(out_dir):
    return sorted(p.name for p in out_dir.rglob(".*.tmp"))


def _assert_trial_files_equal(path_a, path_b):
    assert records_differ(TrialRecord.load(path_a), TrialRecord.load(path_b)) == []


@pytest.fixture(scope="module")
def first_run(tmp_path_factory):
    out = tmp_path_factory.mktemp("run")
    return out, _run(out)


def test_run_writes_config_provenance_and_tables(first_run):
    out, summary = first_run
    assert summary["n_trials"] == 2 and summary["n_reused"] == 0
    for name in ("config.yaml", "provenance.json", "state_time.csv", "performance.csv"):
        assert (out / name).is_file(), name
    assert sorted(p.name for p in (out / "trials").iterdir()) == [
        "random_000.npz",
        "random_001.npz",
    ]
    assert "duration_s: 120.0" in (out / "config.yaml").read_text()

    prov = json.loads((out / "provenance.json").read_text())
    assert prov["root_seed"] == 0
    # trial j of the random controller (code 1) is seeded with spawn key (seed, 1, j)
    assert [t["seed"] for t in prov["trials"]] == [[0, 1, 0], [0, 1, 1]]
    assert prov["wall_time_s"] > 0
    assert prov["wall_time_covers"].startswith("this run's trials")
    assert "git_commit" in prov
    assert {"numpy", "pymunk", "numba"} <= set(prov["packages"])

    state = pd.read_csv(out / "state_time.csv")
    assert list(state.columns) == ["state", "controller", "mean_pct", "std_pct", "n_trials"]
    assert set(state.controller) == {"random", "theory"}
    # the 7 states of 6 robots on 2 circuits, for the controller and for theory
    assert list(state[state.controller == "theory"].state) == [
        "0:6",
        "1:5",
        "2:4",
        "3:3",
        "4:2",
        "5:1",
        "6:0",
    ]
    perf = pd.read_csv(out / "performance.csv")
    assert list(perf.columns) == ["t_s", "controller", "mean", "std", "n_trials"]
    # one 600 s bin cut short at the 120 s duration: centred at 60 s
    assert perf.t_s.tolist() == [60.0] and perf.n_trials.tolist() == [2]
    assert _tmp_files(out) == []


def test_rerun_reuses_every_trial_and_gives_identical_tables(first_run):
    out, _ = first_run
    before = {name: (out / name).read_bytes() for name in ("state_time.csv", "performance.csv")}
    mtimes = {p.name: p.stat().st_mtime_ns for p in (out / "trials").iterdir()}
    summary = _run(out)
    assert summary["n_reused"] == summary["n_trials"] == 2
    assert {
        p.name: p.stat().st_mtime_ns for p in (out / "trials").iterdir()
    } == mtimes  # not rewritten
    for name, data in before.items():
        assert (out / name).read_bytes() == data, name
    assert json.loads((out / "provenance.json").read_text())["n_trials_reused"] == 2
    assert _tmp_files(out) == []


def test_a_changed_seed_recomputes_everything(tmp_path):
    _run(tmp_path)
    old = TrialRecord.load(trial_path(tmp_path, "random", 0))
    with pytest.raises(TavcError, match=r"holds a finished run of another configuration \(seed: 0 -> 5\); add "
                                         r"overwrite=true to replace it, or choose another output_dir$"):
        _run(tmp_path, "seed=5")
    summary = _run(tmp_path, "seed=5", "overwrite=true")
    assert summary["n_reused"] == 0
    new = TrialRecord.load(trial_path(tmp_path, "random", 0))
    assert new.meta["seed"] == [5, 1, 0] and old.meta["seed"] == [0, 1, 0]


def test_deleting_a_trial_file_reruns_only_what_is_missing(tmp_path):
    # one trial per batch, so this holds whether reuse goes by batch or by trial
    _run(tmp_path, "executor.batch_size=1")
    kept, lost = trial_path(tmp_path, "random", 0), trial_path(tmp_path, "random", 1)
    kept_mtime = kept.stat().st_mtime_ns
    reference = tmp_path / "reference.npz"
    reference.write_bytes(lost.read_bytes())
    lost.unlink()
    summary = _run(tmp_path, "executor.batch_size=1")
    assert summary["n_reused"] == 1
    assert kept.stat().st_mtime_ns == kept_mtime
    _assert_trial_files_equal(lost, reference)  # the rerun batch gives the same trial
    assert _tmp_files(tmp_path) == []


def test_process_pool_gives_the_same_trial_files_as_one_process(tmp_path):
    # 4 trials in 2 batches of 2: with n_jobs=2 they run in two worker processes
    common = ["trials=4", "executor.batch_size=2"]
    serial = _run(tmp_path / "serial", *common, "executor.n_jobs=1")
    pooled = _run(tmp_path / "pooled", *common, "executor.n_jobs=2")
    assert serial["n_trials"] == pooled["n_trials"] == 4
    for j in range(4):
        _assert_trial_files_equal(
            trial_path(tmp_path / "serial", "random", j),
            trial_path(tmp_path / "pooled", "random", j),
        )
    assert (tmp_path / "serial" / "state_time.csv").read_bytes() == (
        tmp_path / "pooled" / "state_time.csv"
    ).read_bytes()


def test_batch_size_does_not_change_results(tmp_path):
    one = _run(tmp_path / "one", "trials=3", "executor.batch_size=1")
    three = _run(tmp_path / "three", "trials=3", "executor.batch_size=3")
    assert one["n_trials"] == three["n_trials"] == 3
    for j in range(3):
        _assert_trial_files_equal(
            trial_path(tmp_path / "one", "random", j),
            trial_path(tmp_path / "three", "random", j),
        )


def _failing_savez(fh, **arrays):
    fh.write(b"PK\x03\x04 half a zip file")  # get part of the way, then fail
    raise OSError("disk full")


def test_failed_trial_write_leaves_no_file_and_no_temp(tmp_path, monkeypatch):
    monkeypatch.setattr(np, "savez_compressed", _failing_savez)
    with pytest.raises(OSError, match="disk full"):
        _run(tmp_path)
    assert list((tmp_path / "trials").iterdir()) == []
    assert _tmp_files(tmp_path) == []


def test_failed_overwrite_keeps_the_old_file(first_run, tmp_path, monkeypatch):
    out, _ = first_run
    path = tmp_path / "trial.npz"
    rec = TrialRecord.load(trial_path(out, "random", 0))
    rec.save(path)
    good = path.read_bytes()
    monkeypatch.setattr(np, "savez_compressed", _failing_savez)
    rec.meta["trial"] = 99
    with pytest.raises(OSError):
        rec.save(path)
    assert path.read_bytes() == good
    assert sorted(p.name for p in tmp_path.iterdir()) == ["trial.npz"]


def test_cli_run_exits_zero(tmp_path):
    result = CliRunner().invoke(app, ["run", *SMOKE, f"output_dir={tmp_path}", "--no-progress"])
    assert result.exit_code == 0, result.output
    assert "trials: 2 (0 reused)" in result.output
    assert (tmp_path / "state_time.csv").is_file()


def test_baselines_that_start_late_are_compared_over_the_stable_period_only(tmp_path):
    # 120 s trials, stable from 60 s, in 30 s bins; the random baseline starts 30 s before the
    # stable period, at 30 s: no rate for the convergence period or the bin [0, 30), a stable rate
    # and state shares like the learners'; the learners ran from 0 s
    summary = _run(tmp_path, "learner=tavc_egreedy", "baselines=[random]", "convergence_s=60",
                   "analysis.performance_bin_s=30", "baseline_lead_s=30", "scale.time_factor=1")
    starts = {c: TrialRecord.load(trial_path(tmp_path, c, 0)).start_s for c in ("tavc", "random")}
    assert starts == {"tavc": 0.0, "random": 30.0}
    stats = pd.read_csv(tmp_path / "trial_stats.csv").set_index("controller")
    assert stats.loc["random", "value_rate_convergence"].isna().all()
    assert stats.loc["tavc", "value_rate_convergence"].notna().all()
    assert stats.loc["random", "value_rate_stable"].notna().all()
    assert stats.loc["random", "settle_s"].isna().all()  # no convergence period to settle in
    perf = pd.read_csv(tmp_path / "performance.csv")
    random = perf[perf.controller == "random"].set_index("t_s")
    assert random["n_trials"].to_dict() == {15.0: 0, 45.0: 2, 75.0: 2, 105.0: 2}
    assert random.loc[15.0, ["mean", "std"]].isna().all()  # no trial ran there: no spread either
    allocation = pd.read_csv(tmp_path / "allocation.csv")
    assert allocation[allocation.controller == "random"].set_index("t_s").loc[15.0, "n_trials"] == 0
    shares = summary["tables"]["state_time"]
    assert shares[shares.controller == "random"]["mean_pct"].sum() == pytest.approx(100.0)


# --- the chapter's claim 4 -----------------------------------------------------------------------


@pytest.mark.slow
def test_random_allocation_matches_the_binomial_model(tmp_path):
    """Robots picking circuits at random spend time in each state as the binomial model says.

    6 robots on two_circuits, 8 trials of 2400 s, shares measured from 300 s. Across trials a
    state's share varies with a sample std of up to about 5.5 percentage points (3:3 and 2:4,
    the commonest states; 4.3 to 5.6 seen with this config over 8 and 15 trials), so an 8-trial
    mean has a standard error of at most about 5.5 / sqrt(8) = 1.9 points, and 6 points is over
    3 standard errors: P(|Z| > 3.1) = 0.2 % per state, under 1 % for the 7 states together, for
    a simulator whose states really follow the binomial row. The largest deviation seen with
    this seed is 2.9 points (2:4). The binomial row assumes robots that do not slow each
    other down, so the test runs in a world with little crowding; in the calibrated docking
    world crowded circuits are slow, which holds random robots longer in unbalanced splits
    they then leave, and 3:3 rises to about 37 %.
    """
    cfg = settings(load_config(
        [
            *LOW_CROWDING_WORLD,
            "scale=paper",
            "arena=two_circuits",
            "learner=random",
            "team.n_robots=6",
            "trials=8",
            "duration_s=2400",
            "convergence_s=300",
            "executor.batch_size=4",
            f"output_dir={tmp_path}",
        ]
    ))
    summary = run_experiment(cfg)
    # every trial has a defined state over the whole window (each robot keeps reaching targets);
    # otherwise a trial would add 0 % to every state and bias the means
    for j in range(8):
        rec = TrialRecord.load(trial_path(tmp_path, "random", j))
        defined = sum(
            min(b, 2400.0) - max(a, 300.0)
            for a, b, s in state_intervals(rec)
            if s is not None and b > 300.0
        )
        assert defined == pytest.approx(2100.0), f"trial {j}"
    table = summary["tables"]["state_time"].set_index(["controller", "state"])
    theory = theory_pct(6, 2, "circuits")
    for state, expected in theory.items():
        assert table.loc[("theory", state), "mean_pct"] == pytest.approx(expected)
        got = table.loc[("random", state), "mean_pct"]
        assert abs(got - expected) <= 6.0, f"{state}: {got:.2f} % vs binomial {expected:.2f} %"


def test_batches_give_every_worker_a_share_of_a_small_run():
    from tavc_cli.experiments.build import make_batches, trial_specs

    specs = trial_specs(settings(load_config([*SMOKE, "trials=8", "baselines=[]"])))
    assert len(specs) == 8
    # 8 trials on 2 workers: two batches of 4, not one of 8 on a single core
    assert [len(b.specs) for b in make_batches(specs, 8, workers=2)] == [4, 4]
    # the batch size still caps a large run, and one worker keeps whole batches
    assert [len(b.specs) for b in make_batches(specs, 3, workers=2)] == [3, 3, 2]
    assert [len(b.specs) for b in make_batches(specs, 8, workers=1)] == [8]
    # every trial is in exactly one batch, in order
    assert [s.trial for b in make_batches(specs, 8, workers=3) for s in b.specs] == list(range(8))


# --- one seed, the same tables on any executor --------------------------------------------------

DETERMINISM_BASE = ["experiment=breakdown", "scale=smoke"]
# every table of a breakdown run, claims included (random trials, static and learning controllers, an event)
DETERMINISM_TABLES = ("state_time", "performance", "claims", "trial_stats", "allocation", "vacancy", "q_values",
                      "robots", "comparison")


@pytest.fixture(scope="module")
def one_process(tmp_path_factory):
    """The breakdown experiment in one process: what every other executor must write."""
    out = tmp_path_factory.mktemp("one_process")
    run_experiment(settings(load_config([*DETERMINISM_BASE, "executor.n_jobs=1", f"output_dir={out}"])))
    return out


@pytest.mark.slow
@pytest.mark.parametrize("executor", [["executor.n_jobs=2"], ["executor.n_jobs=2", "executor.batch_size=1"],
                                      ["executor.backend=dask", "executor.n_jobs=2"],
                                      ["executor.backend=ray", "executor.n_jobs=2"]],
                         ids=["local-2", "local-2-unbatched", "dask", "ray"])
def test_every_executor_writes_the_tables_of_one_process(tmp_path, one_process, executor):
    """Two local workers, a real Dask LocalCluster and a real local Ray instance: the same seed,
    the same tables, byte for byte."""
    backend = next((o.split("=")[1] for o in executor if o.startswith("executor.backend=")), "local")
    if backend != "local":
        pytest.importorskip("distributed" if backend == "dask" else "ray")
    summary = run_experiment(settings(load_config([*DETERMINISM_BASE, *executor, f"output_dir={tmp_path}"])))
    assert summary["n_trials"] == 6 and summary["n_reused"] == 0
    for name in DETERMINISM_TABLES:
        assert (one_process / f"{name}.csv").read_bytes() == (tmp_path / f"{name}.csv").read_bytes(), name


def test_a_missing_cluster_package_is_one_line(monkeypatch):
    import builtins

    from tavc_cli.errors import TavcError
    from tavc_cli.experiments.executors import run_on_cluster

    real_import = builtins.__import__

    def no_dask(name, *args, **kwargs):
        if name.startswith("distributed"):
            raise ImportError(name)
        return real_import(name, *args, **kwargs)

    monkeypatch.setattr(builtins, "__import__", no_dask)
    with pytest.raises(TavcError, match=r"executor.backend=dask needs distributed: pip install 'tavc\[dask\]'"):
        run_on_cluster("dask", [], lambda b, r: None, 1, None)


def test_runs_started_together_compile_their_kernels_one_at_a_time(monkeypatch, tmp_path):
    """While a run compiles its kernels (`load_kernels`), another process cannot take the
    lock it holds; once it is done, it can: a second run started beside it then loads what
    the first wrote to numba's cache instead of compiling the same code at the same time."""
    import subprocess
    import sys

    from tavc_cli.experiments import pool
    from tavc_cli.experiments.build import Batch

    probe = ("import fcntl, sys\n"
             "with open(sys.argv[1], 'a') as f:\n"
             "    try:\n        fcntl.flock(f, fcntl.LOCK_EX | fcntl.LOCK_NB)\n    except BlockingIOError:\n"
             "        print('held')\n    else:\n        print('free')\n")

    def lock_state():
        return subprocess.run([sys.executable, "-c", probe, str(pool.kernel_lock_path())], capture_output=True,
                              text=True, check=True).stdout.strip()

    # a lock file of this test's own: the installation's is also taken by every other run of tavc
    # started meanwhile (the other tests, run in parallel)
    monkeypatch.setattr(pool, "kernel_lock_path", lambda: tmp_path / "kernels.lock")
    seen = []
    monkeypatch.setattr(pool, "run_trials", lambda specs: seen.append(lock_state()))
    spec = trial_specs(settings(load_config(["experiment=initial_distribution", "scale=smoke"])))[0]
    pool.load_kernels([Batch(spec.controller, 0, (spec,))])
    assert seen == ["held"]
    assert lock_state() == "free"


@pytest.mark.slow
def test_kernels_compiled_in_two_processes_are_found_in_the_cache(tmp_path):
    # with an empty cache, the copy compiles the behaviours and this process the rest; compiling
    # the entry points then loads the behaviours from the cache instead of compiling them again,
    # which it does only if the parts were compiled for the very types the entry points call
    # them with (any other type would compile a second signature)
    import os
    import subprocess
    import sys

    probe = (
        "from tavc_cli.config import load_config, settings\n"
        "from tavc_cli.experiments.build import trial_specs\n"
        "from tavc_cli.experiments.engine import BatchEngine\n"
        "from tavc_cli.experiments.pool import compile_in_two\n"
        "from tavc_cli.behaviours.navigation import behave\n"
        "from tavc_cli.sim.sensors import cast_laser\n"
        "spec = trial_specs(settings(load_config(['experiment=breakdown', 'scale=smoke'])))[0]\n"
        "compile_in_two(BatchEngine([spec]))\n"
        "BatchEngine([spec]).run()\n"
        "for k in (behave, cast_laser):\n"
        "    print(sum(k.stats.cache_hits.values()), sum(k.stats.cache_misses.values()), len(k.signatures))\n")
    out = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True, check=True,
                         env={**os.environ, "NUMBA_CACHE_DIR": str(tmp_path)}).stdout.split("\n")
    assert out[:2] == ["1 0 1", "0 1 1"]  # behaviours: found in the cache; laser: compiled here; once each
