"""Plausible limits: sizes no machine could run are refused in one line naming the key, before
anything is written; a run longer than a day is refused unless force=true; the project's own
scales pass."""

import math
import re

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from typer.testing import CliRunner

from tavc_cli import estimates
from tavc_cli.cli import app
from tavc_cli.config import check_measurement, limits, load_config

runner = CliRunner()
EXPERIMENTS = ["initial_distribution", "breakdown", "breakdown_no_vacancy", "value_change", "heterogeneous",
               "spatiotemporal"]
GB = 1e9


@pytest.fixture(autouse=True)
def _a_machine_of_8_gb_that_never_simulates(monkeypatch):
    """Memory limits as on a machine of 8 GB, whatever this one has; a run that got past its
    limits fails at once instead of simulating."""
    monkeypatch.setattr(limits, "physical_memory", lambda: 8 * GB)
    monkeypatch.setattr(estimates, "physical_memory", lambda: 8 * GB)

    def simulate(*args, **kwargs):
        raise AssertionError("a run that should have been refused was started")

    import tavc_cli.pipeline

    monkeypatch.setattr(tavc_cli.pipeline, "run_experiment", simulate)


def _one_error_line(result, key: str) -> str:
    assert result.exit_code == 1, result.output
    lines = result.output.strip().splitlines()
    assert len(lines) == 1 and "Traceback" not in result.output, result.output
    assert lines[0].startswith(f"error: {key}: "), lines[0]
    return lines[0]


# ------------------------------------------------------------------------------- the estimate


def test_the_estimate_is_the_measured_throughput():
    # 11,000 simulated s of a 6-robot trial at dt 0.1 s take one wall second on one core;
    # 24 robots cost 7.3 times as much per simulated second (PERFORMANCE.md), one physics
    # substep more adds the physics' share (1 / 1.67) once more
    assert estimates.trial_cost_s(11_000, 0.1, 6) == pytest.approx(1.0)
    assert estimates.trial_cost_s(11_000, 0.1, 24) == pytest.approx(7.3)
    assert estimates.trial_cost_s(11_000, 0.1, 6, substeps=2) == pytest.approx(1 + 1 / 1.67)
    assert estimates.trial_cost_s(11_000, 0.05, 6) == pytest.approx(2.0)


def test_paper_scale_is_estimated_near_its_measured_wall_time():
    # make reproduce-all took 313 s wall on 2 cores (PERFORMANCE.md), the model included
    total = 0.0
    for name in EXPERIMENTS:
        cfg = load_config([f"experiment={name}", "scale=paper", "executor.n_jobs=2"])
        total += limits._costs(limits.run_trials(cfg), limits.run_timing(cfg))[1]
    assert 150 < total < 600


@pytest.mark.parametrize("seconds, text", [(40, "40 s"), (720, "12 min"), (5.5 * 3600, "5.5 h"),
                                           (3.25 * 86400, "3.2 days"), (1250 * 365.25 * 86400, "1,250 years"),
                                           (math.inf, "longer than any number of years a float can hold")])
def test_wall_times_read_roughly(seconds, text):
    assert estimates.about(seconds) == text


# ------------------------------------------------------------------------------- never runnable


@pytest.mark.parametrize("overrides, key, words", [
    (["duration_s=1e300"], "duration_s", "more than a trial's clock counts"),
    (["sim.dt_s=1e-300"], "sim.dt_s", "more than a trial's clock counts"),
    (["scale.time_factor=1e13"], "scale.time_factor", "more than a trial's clock counts"),
    (["scale.time_factor=1e306"], "scale.time_factor", "more than a float holds"),
    ([f"trials={2**63}"], "trials", "of memory"),
    (["trials=100000000"], "trials", "of memory"),
    (["scale=paper", "paper.trials=100000000"], "paper.trials", "of memory"),
    (["experiment=breakdown", "scale=paper", "paper.static_trials=100000000"], "paper.static_trials", "of memory"),
    (["trials=150000", "executor.batch_size=150000"], "executor.batch_size", "advanced together in one process"),
    (["team.n_robots=10000000"], "team.n_robots", "of memory to simulate"),
    (["learner=tavc_egreedy", "duration_s=1e12"], "duration_s", "Q-table snapshots"),
    (["learner=tavc_egreedy", "sim.q_snapshot_every_s=1e-6"], "sim.q_snapshot_every_s", "Q-table snapshots"),
    (["experiment=spatiotemporal", "sim.pose_every_s=1e-4"], "sim.pose_every_s", "pose frames"),
    (["model.max_robots=100000"], "model.max_robots", "cannot start"),
])
def test_what_could_never_run_is_refused_even_with_force(tmp_path, overrides, key, words):
    out = tmp_path / "out"
    for force in ("false", "true"):
        result = runner.invoke(app, ["run", "scale=smoke", *overrides, f"force={force}", f"output_dir={out}"])
        line = _one_error_line(result, key)
        assert words in line
        assert "not even force=true" in line or "float" in line or "cannot start" in line
        assert not out.exists()  # refused before anything is written


# ------------------------------------------------------------------------------- longer than a day


@pytest.mark.parametrize("overrides, key, words", [
    (["duration_s=1e9"], "duration_s", "one trial of the run"),
    (["sim.dt_s=1e-9"], "sim.dt_s", "one trial of the run"),
    (["sim.physics_substeps=1000000", "duration_s=10000"], "sim.physics_substeps", "one trial of the run"),
    (["trials=100000", "duration_s=10000", "executor.n_jobs=1"], "trials", "100,000 trials"),
    (["duration_s=1e8", "trials=20", "executor.n_jobs=1", "learner=tavc_egreedy", "baselines=[random]"],
     "duration_s", "40 trials (20 of tavc, 20 of random)"),
    (["scale=paper", "paper.duration_s=1e9"], "paper.duration_s", "one trial of the run"),
])
def test_a_run_longer_than_a_day_is_refused_unless_forced(tmp_path, overrides, key, words):
    out = tmp_path / "out"
    result = runner.invoke(app, ["run", "scale=smoke", *overrides, f"output_dir={out}"])
    line = _one_error_line(result, key)
    assert words in line
    assert re.search(r"would take about [\d.,]+ (h|days|years)", line), line
    assert "more than a day" in line and "force=true" in line
    assert not out.exists()
    forced = runner.invoke(app, ["config", "scale=smoke", *overrides, "force=true"])
    assert forced.exit_code == 0, forced.output


def test_the_projects_own_scales_pass():
    for scale, extra in (("paper", []), ("long", []), ("quick", []),
                         ("converged", ["executor.batch_size=2"])):  # as make reproduce-converged runs it
        for name in EXPERIMENTS:
            load_config([f"experiment={name}", f"scale={scale}", *extra])
    values = "[4000,2000]"  # the value-ratio sweeps of the Makefile, at their largest ratio
    for scale, extra in (("paper", []), ("long", []), ("converged", ["trials=8", "executor.batch_size=2"])):
        load_config(["experiment=initial_distribution", f"scale={scale}", "baselines=[]", f"tasks.values={values}",
                     *extra])
    for scale in ("quick", "paper", "converged"):  # tavc model and tavc calibrate with their defaults
        check_measurement(["experiment=initial_distribution", f"scale={scale}"], "model")
        check_measurement([f"scale={scale}"], "calibration")


def test_a_run_as_long_as_converged_with_one_core_is_still_within_a_day():
    cfg = load_config(["experiment=value_change", "scale=converged", "executor.n_jobs=1"])
    assert limits._costs(limits.run_trials(cfg), limits.run_timing(cfg))[1] < estimates.DAY_S


@pytest.mark.parametrize("command, overrides, key", [
    ("model", ["scale=paper", "model.measure_s=1e7"], "model.measure_s"),
    ("model", ["scale=paper", "model.trials_per_split=100000"], "model.trials_per_split"),
    ("calibrate", ["scale=paper", "calibration.trials_per_split=5000"], "calibration.trials_per_split"),
])
def test_model_and_calibrate_refuse_a_measurement_longer_than_a_day(tmp_path, command, overrides, key):
    out = tmp_path / "out"
    line = _one_error_line(runner.invoke(app, [command, *overrides, f"output_dir={out}"]), key)
    assert f"tavc {command}" in line and "force=true" in line
    assert not out.exists()


def test_a_measurement_too_long_for_tavc_model_does_not_hold_up_tavc_run():
    load_config(["scale=paper", "model.measure_s=1e7"])


# ------------------------------------------------------------------------------- tavc bench


@pytest.mark.parametrize("args, key, words", [
    (["--duration-s", "1e9"], "--duration-s", "more than a day"),
    (["--repeats", "100000000"], "--repeats", "more than a day"),
    (["--n-robots", "24", "--duration-s", "1e7", "--no-scaling"], "--duration-s", "more than a day"),
    (["--batch", "1000000000"], "--batch", "of memory"),
    (["--duration-s", "1e300"], "--duration-s", "clock counts"),
])
def test_bench_refuses_sizes_beyond_a_day_or_memory(args, key, words):
    line = _one_error_line(runner.invoke(app, ["bench", *args]), key)
    assert words in line


def test_bench_runs_what_is_too_long_when_forced(monkeypatch):
    import tavc_cli.bench as bench

    monkeypatch.setattr(bench, "run_bench", lambda settings_for, **options: {"ran": True})
    assert runner.invoke(app, ["bench", "--duration-s", "1e9"]).exit_code == 1
    result = runner.invoke(app, ["bench", "--duration-s", "1e9", "--force", "--json"])
    assert result.exit_code == 0 and '"ran": true' in result.output


# ------------------------------------------------------------------------------- any number


KEYS = ["duration_s", "convergence_s", "trials", "baseline_trials", "static_trials", "paper.duration_s",
        "paper.trials", "paper.baseline_trials", "scale.trials", "scale.time_factor", "sim.warmup_s", "sim.dt_s",
        "executor.batch_size", "model.measure_s", "model.trials_per_split", "calibration.trials_per_split",
        "calibration.measure_s"]
NUMBERS = st.one_of(
    st.integers(-10, 10**30), st.just(2**63), st.just(-(2**63)),
    st.floats(allow_nan=True, allow_infinity=True), st.sampled_from([1e300, -1e300, 1e-300, 5e-324, 1e15, 1e9]))


# each example composes a whole config (about 0.6 s): 30 a run, drawn afresh every run
@settings(max_examples=30, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(key=st.sampled_from(KEYS), value=NUMBERS, force=st.booleans())
def test_any_number_is_a_valid_config_or_one_line_naming_its_key(key, value, force):
    text = repr(value) if isinstance(value, float) else str(value)
    result = runner.invoke(app, ["config", "scale=smoke", "experiment=breakdown", f"{key}={text}",
                                 f"force={str(force).lower()}"])
    assert "Traceback" not in result.output
    if result.exit_code == 0:
        return
    assert result.exit_code == 1, result.output
    lines = result.output.strip().splitlines()
    assert len(lines) == 1, result.output
    # the key set, or one it fixes: convergence_s follows duration_s, events follow the warm-up
    named = re.match(r"error: ([\w.\[\]]+): ", lines[0])
    assert named, lines[0]
    related = {"duration_s": {"convergence_s"}, "paper.duration_s": {"paper.convergence_s", "scale.time_factor"},
               "sim.warmup_s": {"events.breakdowns[0].time_s"}, "scale.time_factor": {"paper.duration_s"},
               "sim.dt_s": {"analysis.performance_bin_s", "duration_s"}}
    assert named.group(1) in {key, *related.get(key, set())}, lines[0]
