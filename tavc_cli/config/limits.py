"""Plausible limits: how long and how large a run may be, checked before anything is written or
allocated.

Refused unless ``force: true``: whatever is estimated to take longer than a day (`DAY_S`) on this
machine's cores: `tavc run`'s trials, `tavc model`'s and `tavc calibrate`'s measurements. The
estimate is the simulator's measured throughput (`estimates.TICKS_PER_CORE_S`) applied to the
control periods to simulate; it is rough (within a factor of two or so), and the messages say so.

Refused even with ``force: true``: whatever could never run. A trial longer than its clock
counts (`MAX_TICKS`); more trials, Q-table snapshots or pose frames than this machine's memory
holds (a run keeps every trial's plan from the start and its analysis loads every record at
once); a team or a batch of trials larger than memory; score values whose sum over a trial's
deliveries, squared in a spread, no float holds.

Each refusal is one line naming the key that is out of bounds, what it would cost and, for the
estimates, that ``force=true`` runs it anyway.
"""

from __future__ import annotations

import math
import os
import sys
from dataclasses import dataclass

from omegaconf import DictConfig, OmegaConf

from tavc_cli.config.checks import check, fail
from tavc_cli.estimates import (
    BENCH_DT_S,
    BENCH_RAYS,
    BENCH_ROBOTS,
    DAY_S,
    MAX_TICKS,
    PLAN_BYTES,
    POSE_FRAME_BYTES,
    POSE_ROBOT_BYTES,
    Q_SNAPSHOT_BYTES,
    RECORD_BYTES,
    about,
    batch_bytes,
    in_bytes,
    physical_memory,
    speed_note,
    trial_cost_s,
)
from tavc_cli.experiments.plan import plan_run  # the simulator's modules, only once a config is checked
from tavc_cli.learning.registry import BASELINES
from tavc_cli.settings import CalibrationConfig, ModelConfig, PaperConfig

# --------------------------------------------------------------------------------------------
# What a run simulates
# --------------------------------------------------------------------------------------------


# The largest scale.time_factor of the project's own scales (scale=converged): a larger one is
# named as what makes trials too long, before the durations it multiplies.
USUAL_TIME_FACTOR = 40.0
# The chapter's longest trial (value_change: 36,000 s of warm-up, then 18,000) at that factor.
USUAL_SPAN_S = 54_000.0 * USUAL_TIME_FACTOR


@dataclass(frozen=True)
class Trials:
    """Trials of one kind: how many (counted by `key`), each how long (made so by `length_key`)
    and with how many robots."""

    key: str
    label: str
    count: int
    span_s: float        # simulated seconds each, from its first tick (warm-up included)
    n_robots: int
    length_key: str
    q_tables: bool = True  # whether it keeps Q-table snapshots (the baselines learn nothing)
    usual_count: float = PaperConfig.trials  # what the project's own scales run, to tell which key is out of line
    usual_span_s: float = USUAL_SPAN_S


@dataclass(frozen=True)
class Timing:
    """What a trial's cost depends on besides its length, and where the trials run."""

    dt_s: float
    substeps: int
    n_rays: int
    cores: int
    robots_key: str = "team.n_robots"
    time_factor: float = 1.0  # scale.time_factor, where it multiplied the trials' lengths


def sources(cfg: DictConfig) -> dict[str, str]:
    """Before resolution: the trial counts and duration it will derive, each with the key its
    value will come from (`resolve`'s rules), so that a refusal names the key the user set."""
    out: dict[str, str] = {}
    cap, paper = cfg.scale.trials, cfg.paper
    for key, given, fallback in (("trials", paper.trials, None),
                                 ("baseline_trials", paper.baseline_trials, "trials"),
                                 ("static_trials", paper.static_trials, "baseline_trials")):
        if cfg[key] is not None:
            continue
        if given is None:
            out[key] = out.get(fallback, fallback)
        else:
            out[key] = "scale.trials" if cap is not None and cap < given else f"paper.{key}"
    if cfg.duration_s is None:
        out["duration_s"] = "paper.duration_s"
    if cfg.tasks.score_values is None:
        out["tasks.score_values"] = "tasks.values"
    return out


def run_trials(cfg: DictConfig, named: dict[str, str] | None = None) -> list[Trials]:
    """`tavc run`'s trials, as `experiments.build.trial_specs` will plan them (without planning them);
    their keys as `named` (`sources`) says."""
    named = named or {}
    plan = plan_run(OmegaConf.to_object(cfg))
    n_robots = int(cfg.team.n_robots)
    duration_s, warmup_s = float(cfg.duration_s), float(cfg.sim.warmup_s)
    longer = named.get("duration_s", "duration_s") if duration_s >= warmup_s else "sim.warmup_s"
    slower = (cfg.scale.baseline_time_factor is not None
              and float(cfg.scale.baseline_time_factor) > float(cfg.scale.time_factor))
    out = []
    for k, entry in enumerate(plan.controllers):
        label, count, theirs = entry.label, entry.trials, entry.schedule
        start_s = theirs.start_s - theirs.trial_warmup_s
        if k == 0:
            learns = cfg.learner.name not in BASELINES  # the baselines keep no Q-tables
            out.append(Trials(named.get("trials", "trials"), label, count, duration_s + warmup_s, n_robots, longer,
                              q_tables=learns))
        else:
            key = "static_trials" if label == "static" else "baseline_trials"
            out.append(Trials(named.get(key, key), label, count, float(theirs.duration_s) - start_s, n_robots,
                              "scale.baseline_time_factor" if slower else named.get("duration_s", "duration_s"),
                              q_tables=False))
    return out


def run_timing(cfg: DictConfig, named: dict[str, str] | None = None) -> Timing:
    """Where the run's trials run and what else than their length their cost depends on (the
    time factor, where resolution scaled duration_s by it: `named` says)."""
    factor = float(cfg.scale.time_factor) if "duration_s" in (named or {}) else 1.0
    return Timing(float(cfg.sim.dt_s), int(cfg.sim.physics_substeps), int(cfg.robot.laser.n_rays),
                  _cores(cfg.executor), time_factor=factor)


def measurement_trials(cfg: DictConfig, group: str, points: int = 1) -> list[Trials]:
    """`tavc model`'s (`group` = model) or `tavc calibrate`'s (calibration, at `points` grid points)
    static trials: every split of up to the team's robots, as `model.measure.measurement_specs`."""
    settings = cfg[group]
    count = int(settings.trials_per_split)
    if cfg.scale.trials:  # the scale caps them as `model.api._scaled_measurement` does
        count = max(2, min(count, int(cfg.scale.trials)))
    factor = float(cfg.scale.time_factor)
    warmup_s, measure_s = float(settings.warmup_s) * factor, float(settings.measure_s) * factor
    longer = f"{group}.measure_s" if measure_s >= warmup_s else f"{group}.warmup_s"
    n_circuits = len(cfg.arena.circuits)
    usual = {"model": ModelConfig, "calibration": CalibrationConfig}[group]
    usual_span_s = (usual.warmup_s + usual.measure_s) * USUAL_TIME_FACTOR
    out = []
    for m in range(1, _measured_robots(cfg, group) + 1):
        splits = points * math.comb(m + n_circuits - 1, n_circuits - 1)
        out.append(Trials(f"{group}.trials_per_split", f"the {m}-robot splits", count * splits, warmup_s + measure_s,
                          m, longer, q_tables=False, usual_count=usual.trials_per_split * splits,
                          usual_span_s=usual_span_s))
    return out


def measurement_timing(cfg: DictConfig, group: str) -> Timing:
    """`run_timing` for `tavc model` or `tavc calibrate`."""
    robots = "model.max_robots" if group == "model" and cfg.model.max_robots is not None else "team.n_robots"
    return Timing(float(cfg.sim.dt_s), int(cfg.sim.physics_substeps), int(cfg.robot.laser.n_rays),
                  _cores(cfg.executor), robots, float(cfg.scale.time_factor))


def _measured_robots(cfg: DictConfig, group: str) -> int:
    return int(cfg.model.max_robots or cfg.team.n_robots) if group == "model" else int(cfg.team.n_robots)


def _cores(executor: DictConfig) -> int:
    """Processes that run trials at once: ``executor.n_jobs``, at most this machine's cores when local."""
    n_jobs = int(executor.n_jobs)
    return min(n_jobs, os.cpu_count() or 1) if executor.backend == "local" else n_jobs


def grid_points(cfg: DictConfig) -> int:
    """Points of `tavc calibrate`'s grid: every combination of its axes' values."""
    return math.prod(len(axis["values"]) for axis in cfg.calibration.grid)


# --------------------------------------------------------------------------------------------
# The checks
# --------------------------------------------------------------------------------------------


def validate_scaled(cfg: DictConfig) -> None:
    """Before resolution multiplies the paper's values by the scale and lists the team's members:
    products no float holds, trials shorter than a control period, a team memory never could."""
    paper, factor, dt_s = cfg.paper, cfg.scale.time_factor, cfg.sim.dt_s
    check(math.isfinite(paper.duration_s * factor), "scale.time_factor",
          f"{factor:g} times paper.duration_s = {paper.duration_s:g} is more than a float holds")
    if cfg.duration_s is None and 0 < dt_s < math.inf:  # named as set: trials last the product
        named = ("sim.dt_s" if dt_s > BENCH_DT_S else "scale.time_factor" if factor < 0.02
                 else "paper.duration_s")  # whichever is out of the usual: the period, or the smoke scale's factor
        check(paper.duration_s * factor >= dt_s, named,
              f"paper.duration_s x scale.time_factor = {paper.duration_s:g} s x {factor:g} makes trials shorter than "
              f"one control period (sim.dt_s = {dt_s:g} s)")
    if paper.deliveries is not None:
        count_factor = cfg.scale.deliveries_factor or factor
        check(math.isfinite(paper.deliveries * count_factor), "scale.deliveries_factor",
              f"{count_factor:g} times paper.deliveries = {paper.deliveries} is more than a float holds")
    memory = physical_memory()
    for key, n in (("team.n_robots", cfg.team.n_robots), ("model.max_robots", cfg.model.max_robots)):
        if n is not None and batch_bytes(1, n, 0) > memory:
            fail(key, f"{n:,} robots would need about {in_bytes(batch_bytes(1, n, 0))} of memory to simulate, "
                      f"more than this machine's {in_bytes(memory)}; not even force=true runs that")


def validate_limits(cfg: DictConfig, named: dict[str, str] | None = None) -> None:
    """Every limit of the module docstring: what could never run, then (unless ``force``) a run
    that would take more than a day, naming derived keys as `named` (`sources`) says. `tavc model`
    and `tavc calibrate` check their own time (`validate_measurement_time`): a run need not wait
    for them."""
    run = run_trials(cfg, named)
    plans = [(run, run_timing(cfg, named), "the run"), *(_measurement(cfg, group) for group in MEASUREMENTS)]
    for trials, timing, what in plans:
        _validate_clock(trials, timing)
        _validate_count_memory(trials, what)
    _validate_record_memory(cfg, run, plans[0][1])
    _validate_scores(cfg, run, plans[0][1], named or {})
    _validate_batch(cfg, run)
    if not cfg.force:
        _validate_time(*plans[0])


MEASUREMENTS = {"model": "tavc model", "calibration": "tavc calibrate"}


def validate_measurement_time(cfg: DictConfig, group: str) -> None:
    """`tavc model` (`group` model) or `tavc calibrate` (calibration) estimated to take more than a
    day is refused unless ``force``."""
    if not cfg.force:
        _validate_time(*_measurement(cfg, group))


def _measurement(cfg: DictConfig, group: str) -> tuple[list[Trials], Timing, str]:
    points = grid_points(cfg) if group == "calibration" else 1
    return measurement_trials(cfg, group, points), measurement_timing(cfg, group), MEASUREMENTS[group]


def _validate_clock(trials: list[Trials], timing: Timing) -> None:
    """No trial longer than its clock counts."""
    span_s = max(t.span_s for t in trials)
    ticks = span_s / timing.dt_s
    if ticks <= MAX_TICKS:
        return
    longest = max(trials, key=lambda t: t.span_s)
    if timing.dt_s < BENCH_DT_S and span_s / BENCH_DT_S <= MAX_TICKS:
        key = "sim.dt_s"
    elif timing.time_factor > USUAL_TIME_FACTOR and span_s * _usual(timing) / timing.dt_s <= MAX_TICKS:
        key = "scale.time_factor"
    else:
        key = longest.length_key
    fail(key, f"a trial of {span_s:,.6g} simulated s at sim.dt_s = {timing.dt_s:g} s is {ticks:.3g} "
              f"control periods, more than a trial's clock counts (2**53 = {MAX_TICKS:.3g}: beyond it, tick x sim.dt_s "
              "no longer tells one period from the next); not even force=true runs that")


def _validate_count_memory(trials: list[Trials], what: str) -> None:
    """No more trials than memory holds: every trial's plan from the start, every record at the end."""
    memory = physical_memory()
    total = sum(t.count for t in trials)
    if total * (PLAN_BYTES + RECORD_BYTES) <= memory:
        return
    key = max(trials, key=lambda t: t.count).key
    fail(key, f"{total:,} trials in {what} would need about {in_bytes(total * (PLAN_BYTES + RECORD_BYTES))} of "
              f"memory (about {in_bytes(PLAN_BYTES + RECORD_BYTES)} each for its plan and its record, all held at "
              f"once), more than this machine's {in_bytes(memory)}; not even force=true runs that")


def _validate_record_memory(cfg: DictConfig, trials: list[Trials], timing: Timing) -> None:
    """The run's records: no more Q-table snapshots and pose frames than memory holds. Named: the
    interval, when even a run cut to a day's work would keep too many, else what makes it long."""
    memory = physical_memory()
    n_circuits = len(cfg.arena.circuits)
    kinds = (("sim.q_snapshot_every_s", "Q-table snapshots", float(cfg.sim.q_snapshot_every_s),
              lambda t: Q_SNAPSHOT_BYTES + 8 * t.n_robots * n_circuits**2 if t.q_tables else 0),
             ("sim.pose_every_s", "pose frames", float(cfg.sim.pose_every_s),
              lambda t: POSE_FRAME_BYTES + POSE_ROBOT_BYTES * t.n_robots))
    for key, what, every_s, bytes_each in kinds:
        if every_s <= 0:
            continue

        def need(span_of, every_s=every_s, bytes_each=bytes_each) -> float:
            return sum((span_of(t) / every_s + 1) * bytes_each(t) * t.count for t in trials)

        if need(lambda t: t.span_s) <= memory:
            continue
        cut = min(1.0, DAY_S / max(_costs(trials, timing)))
        a_day = need(lambda t, cut=cut: t.span_s * cut)
        longest = max(trials, key=lambda t: t.span_s)
        if a_day <= memory:
            key = "scale.time_factor" if timing.time_factor > USUAL_TIME_FACTOR else longest.length_key
        fail(key, f"one every {every_s:g} s is {longest.span_s / every_s + 1:,.6g} {what} per trial of "
                  f"{longest.span_s:,.6g} simulated s, about {in_bytes(need(lambda t: t.span_s))} for the run's "
                  f"{sum(t.count for t in trials):,} trials, more than this machine's {in_bytes(memory)} of memory; "
                  "not even force=true runs that")


def _validate_scores(cfg: DictConfig, trials: list[Trials], timing: Timing, named: dict[str, str]) -> None:
    """Score values whose sum over a trial's deliveries, squared in a spread over trials, a float
    still holds: a robot delivers at most once a control period."""
    most = max(t.n_robots * math.ceil(t.span_s / timing.dt_s) for t in trials)
    bound = math.sqrt(sys.float_info.max) / most
    follows = named.get("tasks.score_values")
    for index, value in enumerate(cfg.tasks.score_values):
        check(value <= bound, f"{follows or 'tasks.score_values'}[{index}]",
              f"{value:g} is more than {bound:.3g}: scores are summed over a trial's deliveries (at most "
              f"{most:,}, one per robot and control period) and squared in the spread over trials, and that must "
              f"stay a finite number{' (tasks.score_values follows it)' if follows else ''}")


def _validate_batch(cfg: DictConfig, trials: list[Trials]) -> None:
    """No batch (trials advanced together in one process) larger than memory: as
    `experiments.build.make_batches`, at most one controller's trials."""
    batch = min(int(cfg.executor.batch_size), max(t.count for t in trials))
    n_rays = int(cfg.robot.laser.n_rays)
    need, memory = batch_bytes(batch, int(cfg.team.n_robots), n_rays), physical_memory()
    if need <= memory:
        return
    key = "robot.laser.n_rays" if batch_bytes(batch, int(cfg.team.n_robots), BENCH_RAYS) <= memory else \
        "executor.batch_size"
    fail(key, f"{batch:,} trials of {cfg.team.n_robots} robots with {n_rays:,} laser rays each, advanced together "
              f"in one process, would need about {in_bytes(need)} of memory, more than this machine's "
              f"{in_bytes(memory)}; not even force=true runs that")


def _validate_time(trials: list[Trials], timing: Timing, what: str) -> None:
    """Nothing estimated to take more than a day: no single trial (it runs on one core) and not
    all of them on the cores they get."""
    one, wall = _costs(trials, timing)
    if one > DAY_S:
        longest = max(trials, key=lambda t: _costs([t], timing)[0])
        fail(_culprit(trials, timing, 0) or longest.length_key,
             f"one trial of {what} ({longest.span_s:,.6g} simulated s, {longest.n_robots} robots at sim.dt_s = "
             f"{timing.dt_s:g} s{_substeps(timing)}) would take about {about(one)} on one core {speed_note()}; "
             "more than a day: make it shorter, or set force=true to run it anyway")
    if wall > DAY_S:
        # named: the count or the length, whichever is further beyond what the project runs
        longest = max(trials, key=lambda t: _costs([t], timing)[0])
        most = max(trials, key=lambda t: t.count / t.usual_count)
        length_first = longest.span_s / longest.usual_span_s >= most.count / most.usual_count
        counts = ", ".join(f"{t.count:,} of {t.label}" for t in trials if t.count)
        fail(_culprit(trials, timing, 1) or (longest.length_key if length_first else most.key),
             f"{what}'s {sum(t.count for t in trials):,} trials ({counts}) of up to {longest.span_s:,.6g} simulated s "
             f"at sim.dt_s = {timing.dt_s:g} s{_substeps(timing)} would take about {about(wall)} on {timing.cores} "
             f"core{'s' if timing.cores > 1 else ''} {speed_note()}; more than a day: run fewer or shorter trials, or "
             "set force=true to run them anyway")


def _costs(trials: list[Trials], timing: Timing, dt_s: float | None = None, substeps: int | None = None,
           robots: int | None = None, n_rays: int | None = None, factor: float = 1.0) -> tuple[float, float]:
    """Wall seconds of the longest trial on one core and of all trials on the cores they get, with
    sim.dt_s, the substeps, the team size (at most `robots`), the rays or the lengths (times
    `factor`) put at other values if given."""
    each = [trial_cost_s(t.span_s * factor, dt_s or timing.dt_s, min(t.n_robots, robots or t.n_robots),
                         substeps or timing.substeps, n_rays or timing.n_rays) for t in trials]
    return max(each), sum(c * t.count for c, t in zip(each, trials, strict=True)) / timing.cores


def _culprit(trials: list[Trials], timing: Timing, which: int) -> str | None:
    """The first of sim.dt_s, sim.physics_substeps, the rays, the team size and the time factor
    whose usual value would bring the longest trial (`which` 0) or all trials (1) within a day;
    None when none would."""
    usual = (("sim.dt_s", timing.dt_s < BENCH_DT_S, {"dt_s": BENCH_DT_S}),
             ("sim.physics_substeps", timing.substeps > 1, {"substeps": 1}),
             ("robot.laser.n_rays", timing.n_rays > BENCH_RAYS, {"n_rays": BENCH_RAYS}),
             (timing.robots_key, max(t.n_robots for t in trials) > BENCH_ROBOTS, {"robots": BENCH_ROBOTS}),
             ("scale.time_factor", timing.time_factor > USUAL_TIME_FACTOR, {"factor": _usual(timing)}))
    return next((key for key, applies, values in usual
                 if applies and _costs(trials, timing, **values)[which] <= DAY_S), None)


def _usual(timing: Timing) -> float:
    """What the trials' lengths shrink by at the largest usual time factor."""
    return min(1.0, USUAL_TIME_FACTOR / timing.time_factor)


def _substeps(timing: Timing) -> str:
    """The costs beside the robots and the period, where they differ from the benchmark's."""
    return ("" if timing.substeps == 1 else f", {timing.substeps:,} physics substeps") + \
        ("" if timing.n_rays == BENCH_RAYS else f", {timing.n_rays:,} laser rays")
