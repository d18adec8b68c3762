"""Validation: each check raises one ``TavcError("<key>: <problem>")`` line."""

import importlib.util
import math
from typing import Optional

from omegaconf import DictConfig, OmegaConf

from tavc_cli.config.checks import (
    angle,
    at_least,
    check,
    fail,
    finite,
    one_of,
    per_circuit,
    positive,
    unique,
)
from tavc_cli.config.limits import validate_limits, validate_scaled
from tavc_cli.config.validate_learner import validate_allocation, validate_learner, validate_model_learner
from tavc_cli.config.validate_world import (
    validate_arena,
    validate_docks,
    validate_model_team,
    validate_periods,
    validate_reachable,
    validate_sim,
    validate_start,
)
from tavc_cli.confine import CONFINE_CHOICES, confinement
from tavc_cli.experiments.clock import due_tick, end_tick
from tavc_cli.io import folder_problem, plain_name
from tavc_cli.learning.registry import BASELINES, MODEL_LEARNERS
from tavc_cli.settings import (
    ANALYSIS_STATES,
    AVAILABLE_BACKENDS,
    BACKENDS,
    MIN_DOCK_CLEARANCE_M,
    STABLE_WINDOWS,
    TIME_UNITS,
)
from tavc_cli.settings_studies import EXPLORERS, SWITCHES
from tavc_cli.sim.arena import START_GAP_M, START_WALL_MARGIN_M, most_robots
from tavc_cli.vocabulary import ARRIVALS, PASSINGS, TIME_FROM

# The laser needs a ray ahead and one to either side: to read codes, avoid robots, follow walls.
MIN_LASER_RAYS = 3
# A robot is a disc of at least this radius (the chapter's Pioneer is 0.22 m): below it the disc's moment
# of inertia, mass x radius^2 / 2, can underflow to the zero pymunk refuses.
MIN_RADIUS_M = 0.01
# An experiment's name names a folder and, in a report, files of its figures (a figure's name adds
# a few dozen bytes to it); file systems take 255 bytes to a name. tavc's longest is 20.
MAX_NAME_BYTES = 100
# The module each cluster backend needs (its extra is the backend's name), as ``experiments.executors``.
BACKEND_MODULES = {"dask": "distributed", "ray": "ray"}


def check_no_missing(cfg: DictConfig) -> None:
    """Every ``???`` in the schema must have been filled by a config file or override."""
    missing = sorted(OmegaConf.missing_keys(cfg))
    if missing:
        fail(missing[0], "missing value (set it in its config file or on the command line)")


def validate_scaling(cfg: DictConfig) -> None:
    """Check what resolution derives values from, so errors name the key the user set."""
    if not plain_name(str(cfg.scale.name)):
        fail("scale.name", f"{str(cfg.scale.name)!r} is not a plain name; runs go to runs/<scale.name>/ by default")
    positive("scale.time_factor", cfg.scale.time_factor)
    one_of("scale.stable_window", cfg.scale.stable_window, STABLE_WINDOWS)
    for key in ("deliveries_factor", "baseline_time_factor"):
        if cfg.scale[key] is not None:
            positive(f"scale.{key}", cfg.scale[key])
    if cfg.scale.trials is not None:
        at_least("scale.trials", cfg.scale.trials, 1)
    paper = cfg.paper
    at_least("paper.trials", paper.trials, 1)
    if paper.baseline_trials is not None:
        at_least("paper.baseline_trials", paper.baseline_trials, 1)
    if paper.static_trials is not None:
        at_least("paper.static_trials", paper.static_trials, 1)
    positive("paper.duration_s", paper.duration_s)
    if paper.deliveries is not None:
        at_least("paper.deliveries", paper.deliveries, 1)
    if cfg.deliveries is not None:
        at_least("deliveries", cfg.deliveries, 1)
    # before resolution scales them, so that the message shows the value the user wrote
    at_least("sim.warmup_s", cfg.sim.warmup_s, 0)
    if cfg.baseline_lead_s is not None:
        positive("baseline_lead_s", cfg.baseline_lead_s)  # a baseline needs a moment before its first event
    check(
        0 <= paper.convergence_s < paper.duration_s,
        "paper.convergence_s",
        f"must be in [0, paper.duration_s = {paper.duration_s:g}), got {paper.convergence_s!r}",
    )
    validate_scaled(cfg)  # before resolution multiplies them out and lists the team's members


def validate(cfg: DictConfig, named: Optional[dict[str, str]] = None) -> None:
    """Validate a resolved config; `named` maps the keys resolution derived to the keys their values
    came from (`limits.sources`), for the limits' messages."""
    validate_arena(cfg.arena)
    _validate_robot(cfg.robot)
    validate_docks(cfg.arena, cfg.robot)
    validate_reachable(cfg.arena, cfg.robot)
    _validate_team(cfg.team, cfg.arena, cfg.robot)
    n_circuits, n_robots = len(cfg.arena.circuits), cfg.team.n_robots
    _validate_executor(cfg.executor)  # before the learner: where a learner from outside tavc may run
    confined = False
    if cfg.learner.target is not None:  # a learner from outside tavc: where its trials run held, or said why not
        confinement(str(cfg.executor.confine), str(cfg.executor.backend))
        confined = confinement(str(cfg.executor.confine))  # loaded and rehearsed here, held where Landlock is
    validate_learner(cfg.learner, n_circuits, n_robots, confined=confined)
    if cfg.learner.name in MODEL_LEARNERS and cfg.learner.target is None:
        validate_model_learner(cfg.learner, n_circuits, n_robots, len(cfg.events.breakdowns))
    _validate_run(cfg)
    if cfg.static_allocation is not None:
        validate_allocation("static_allocation", cfg.static_allocation, n_circuits, n_robots)
    _validate_tasks(cfg.tasks, n_circuits)
    validate_sim(cfg.sim)
    validate_periods(cfg)
    _validate_model(cfg.model)
    _validate_calibration(cfg.calibration)
    _validate_surrogate(cfg.surrogate)
    validate_model_team(cfg)
    validate_limits(cfg, named)  # before anything counts the trials' ticks or plans them
    _validate_events(cfg, n_circuits)  # after sim: events fall due on its control periods
    one_of("analysis.state", cfg.analysis.state, ANALYSIS_STATES)
    positive("analysis.performance_bin_s", cfg.analysis.performance_bin_s)
    if cfg.analysis.before_s is not None:
        positive("analysis.before_s", cfg.analysis.before_s)
    validate_start(cfg)  # last: beyond what always fits, it builds the trials to place their teams


def _validate_model(model: DictConfig) -> None:
    """Measurement settings of the TAVC model."""
    at_least("model.trials_per_split", model.trials_per_split, 2)
    at_least("model.warmup_s", model.warmup_s, 0)
    positive("model.measure_s", model.measure_s)
    check(0 < model.confidence < 1, "model.confidence", f"must be in (0, 1), got {model.confidence!r}")
    if model.max_robots is not None:
        at_least("model.max_robots", model.max_robots, 1)


def _validate_calibration(cal: DictConfig) -> None:
    """The world search: measurement settings and a grid over existing config keys."""
    at_least("calibration.trials_per_split", cal.trials_per_split, 2)
    at_least("calibration.warmup_s", cal.warmup_s, 0)
    positive("calibration.measure_s", cal.measure_s)
    for index, axis in enumerate(cal.grid):
        key = f"calibration.grid[{index}]"
        check(len(axis["values"]) >= 1, f"{key}.values", "needs at least one value")
        check(OmegaConf.select(cal._get_root(), axis.key, default="__absent__") != "__absent__", f"{key}.key",
              f"no config key named {axis.key!r}")
        for value in axis["values"]:  # the search tabulates and ranks worlds by numeric settings
            check(isinstance(value, int | float) and not isinstance(value, bool) and math.isfinite(value),
                  f"{key}.values", f"{value!r} is not a number; the search varies numeric settings of the world")


def _validate_surrogate(sur: DictConfig) -> None:
    """The surrogate's measurement of tasks and how it draws them."""
    at_least("surrogate.trials_per_makeup", sur.trials_per_makeup, 1)
    at_least("surrogate.warmup_s", sur.warmup_s, 0)
    positive("surrogate.measure_s", sur.measure_s)
    one_of("surrogate.calibration", sur.calibration, ("makeup", "stayers"))
    one_of("surrogate.switches", sur.switches, SWITCHES)
    check(not (sur.switches == EXPLORERS and sur.calibration == "stayers"), "surrogate.switches",
          "explorers measure switching tasks, which surrogate.calibration=stayers never draws")
    at_least("surrogate.explore_trials", sur.explore_trials, 1)
    at_least("surrogate.explore_min_tasks", sur.explore_min_tasks, 1)
    if sur.explore_epsilon is not None:
        check(0 < sur.explore_epsilon <= 1, "surrogate.explore_epsilon", "must be in (0, 1]")


def _validate_robot(robot: DictConfig) -> None:
    """Body, drive and sensors."""
    body = (
        "radius_m",
        "mass_kg",
        "speed_mps",
        "turn_rate_radps",
        "drive_force_n",
        "drive_torque_nm",
    )
    for name in body:
        positive(f"robot.{name}", robot[name])
    check(robot.radius_m >= MIN_RADIUS_M, "robot.radius_m",
          f"must be at least {MIN_RADIUS_M:g} m (a smaller disc falls between the laser's rays and its moment of "
          f"inertia vanishes in the physics), got {robot.radius_m:g}")
    check(robot.radius_m < START_WALL_MARGIN_M, "robot.radius_m",
          f"must be less than {START_WALL_MARGIN_M:g} m (robots start with their centres "
          f"{START_WALL_MARGIN_M:g} m from the walls), got {robot.radius_m:g}")
    check(robot.laser.n_rays >= MIN_LASER_RAYS, "robot.laser.n_rays",
          f"must be >= {MIN_LASER_RAYS} (a ray ahead to read bar-codes and rays to the sides to avoid robots "
          f"and follow walls), got {robot.laser.n_rays!r}")
    angle("robot.laser.fov_deg", robot.laser.fov_deg, 360.0)
    positive("robot.laser.range_m", robot.laser.range_m)
    angle("robot.camera.fov_deg", robot.camera.fov_deg, 360.0)
    positive("robot.camera.range_m", robot.camera.range_m)
    angle("robot.camera.side_sector_deg", robot.camera.side_sector_deg, 180.0)
    for name, value in robot.odometry.items():
        at_least(f"robot.odometry.{name}", value, 0)
    for name in ("avoid_dist_m", "arrive_dist_m", "wall_dist_m", "relocalise_dist_m", "stall_s", "escape_s",
                 "progress_m"):
        positive(f"robot.behaviour.{name}", robot.behaviour[name])
    for name in ("stop_dist_m", "visible_margin_m"):
        at_least(f"robot.behaviour.{name}", robot.behaviour[name], 0)
    one_of("robot.behaviour.arrival", robot.behaviour.arrival, ARRIVALS)
    one_of("robot.behaviour.passing", robot.behaviour.passing, PASSINGS)
    positive("robot.behaviour.read_range_m", robot.behaviour.read_range_m)
    if robot.behaviour.arrival == "range":
        check(robot.behaviour.read_range_m <= robot.laser.range_m, "robot.behaviour.read_range_m",
              f"must be within the laser's range, robot.laser.range_m = {robot.laser.range_m:g} m (the code is read "
              f"by the laser), got {robot.behaviour.read_range_m:g}")
    check(robot.behaviour.avoid_dist_m > robot.behaviour.stop_dist_m, "robot.behaviour.avoid_dist_m",
          f"must exceed robot.behaviour.stop_dist_m ({robot.behaviour.stop_dist_m:g}), "
          f"got {robot.behaviour.avoid_dist_m:g}")
    # the dock spot: the robot reads its code at arrive_dist_m from its centre, so its front
    # must stay clear of the wall there (a few cm at least) or it could never get that close
    clearance = robot.radius_m + MIN_DOCK_CLEARANCE_M
    check(robot.behaviour.arrive_dist_m >= clearance, "robot.behaviour.arrive_dist_m",
          f"must be at least robot.radius_m + {MIN_DOCK_CLEARANCE_M:g} = {clearance:g} (the robot reads "
          f"its code from the dock spot in front of the wall), got {robot.behaviour.arrive_dist_m:g}")
    dock = robot.dock
    for name in ("lateral_tol_m", "approach_m", "backout_m", "occupied_m", "hold_margin_m", "patience_s"):
        positive(f"robot.dock.{name}", dock[name])
    at_least("robot.dock.dwell_s", dock.dwell_s, 0)
    angle("robot.dock.heading_tol_deg", dock.heading_tol_deg, 90.0)
    # from the start of the final approach the robot must read its code to line up on it
    reach = robot.behaviour.arrive_dist_m + dock.approach_m
    check(robot.laser.range_m >= reach, "robot.laser.range_m",
          f"must reach the start of the final approach, robot.behaviour.arrive_dist_m + robot.dock.approach_m "
          f"= {reach:g} m, got {robot.laser.range_m:g}")


def _validate_team(team: DictConfig, arena: DictConfig, robot: DictConfig) -> None:
    """Team size (one that could ever start in the arena), and members matching it."""
    at_least("team.n_robots", team.n_robots, 1)
    most = most_robots(arena.width_m, arena.height_m, robot.radius_m)
    check(team.n_robots <= most, "team.n_robots",
          f"{team.n_robots} robots of robot.radius_m = {robot.radius_m:g} cannot start {START_GAP_M:g} m apart in "
          f"the {arena.width_m:g} x {arena.height_m:g} m arena: at most {most} would fit even packed as closely "
          "as discs can be")
    check(
        len(team.members) == team.n_robots,
        "team.n_robots",
        f"{team.n_robots} does not match the {len(team.members)} robots listed in team.members",
    )
    for index, member in enumerate(team.members):
        positive(f"team.members[{index}].speed_mps", member.speed_mps)
        check(bool(member.group), f"team.members[{index}].group", "must not be empty")


def _validate_run(cfg: DictConfig) -> None:
    """Seed, trial counts, durations, baselines, output folder."""
    at_least("seed", cfg.seed, 0)
    at_least("trials", cfg.trials, 1)
    at_least("baseline_trials", cfg.baseline_trials, 1)
    at_least("static_trials", cfg.static_trials, 1)
    positive("duration_s", cfg.duration_s)
    check(
        0 <= cfg.convergence_s < cfg.duration_s,
        "convergence_s",
        f"must be in [0, duration_s = {cfg.duration_s:g}), got {cfg.convergence_s!r}",
    )
    for index, baseline in enumerate(cfg.baselines):
        one_of(f"baselines[{index}]", baseline, BASELINES)
    unique("baselines", list(cfg.baselines), "controller")
    # a trial counted in deliveries counts them from t = 0: where its baselines start is no part of it
    check(not cfg.baselines or cfg.baseline_lead_s is None or cfg.deliveries is None, "baseline_lead_s",
          "baselines can start late only in runs without a delivery count (deliveries); set baseline_lead_s=null")
    check(plain_name(str(cfg.experiment_name)), "experiment_name",
          f"{str(cfg.experiment_name)!r} is not a plain name; runs go to runs/<scale.name>/<experiment_name>/ by "
          "default")
    check(len(str(cfg.experiment_name).encode()) <= MAX_NAME_BYTES, "experiment_name",
          f"at most {MAX_NAME_BYTES} bytes (it names the run's folder and, in a report, files of its figures), "
          f"got {len(str(cfg.experiment_name).encode())}")
    problem = folder_problem(cfg.output_dir or "")
    check(problem is None, "output_dir", problem or "")


def _validate_tasks(tasks: DictConfig, n_circuits: int) -> None:
    """One learning value and one score value per circuit."""
    for name in ("values", "score_values"):
        key = f"tasks.{name}"
        per_circuit(key, tasks[name], n_circuits, "value")
        for index, value in enumerate(tasks[name]):
            problem = f"must be a finite number, got {value!r}"
            check(math.isfinite(value), f"{key}[{index}]", problem)
            if name == "values":
                _learning_value(f"{key}[{index}]", value)
            else:
                at_least(f"{key}[{index}]", value, 0)
    one_of("tasks.time_unit", tasks.time_unit, TIME_UNITS)
    one_of("tasks.time_from", tasks.time_from, TIME_FROM)


def _learning_value(key: str, value: float) -> None:
    """A circuit's learning value w is positive: the reward is w over the task's time, and the
    model compares circuits by their ratios."""
    check(value > 0, key, f"must be > 0 (the reward is the value over the task time), got {value!r}")


def _validate_events(cfg: DictConfig, n_circuits: int) -> None:
    """Scheduled breakdowns and value changes fall inside the simulated time."""
    n_robots = cfg.team.n_robots
    breakdowns = cfg.events.breakdowns
    check(
        len(breakdowns) < n_robots,
        "events.breakdowns",
        f"{len(breakdowns)} breakdowns would leave none of the {n_robots} robots running",
    )
    for index, change in enumerate(cfg.events.value_changes):
        key = f"events.value_changes[{index}]"
        _validate_event_time(f"{key}.time_s", change.time_s, cfg)
        per_circuit(f"{key}.values", change["values"], n_circuits, "value")
        for position, value in enumerate(change["values"]):
            finite(f"{key}.values[{position}]", value)
            _learning_value(f"{key}.values[{position}]", value)
    for index, breakdown in enumerate(breakdowns):
        key = f"events.breakdowns[{index}]"
        _validate_event_time(f"{key}.time_s", breakdown.time_s, cfg)
        _validate_breakdown_target(key, breakdown, n_robots, n_circuits)
        if breakdown.circuit in ("high", "low"):
            _validate_extreme_circuit(f"{key}.circuit", breakdown, cfg)
    robots = [breakdown.robot for breakdown in breakdowns if breakdown.robot is not None]
    unique("events.breakdowns", robots, "robot")


def _validate_extreme_circuit(key: str, breakdown: DictConfig, cfg: DictConfig) -> None:
    """``high`` and ``low`` name one circuit under the values in force when the robot breaks down.

    A breakdown comes before a value change at the same instant (``experiments.events``).
    """
    values, since = list(cfg.tasks["values"]), None
    for change in sorted(cfg.events.value_changes, key=lambda change: change.time_s):
        if change.time_s < breakdown.time_s:
            values, since = list(change["values"]), change.time_s
    extreme = max(values) if breakdown.circuit == "high" else min(values)
    source = "tasks.values" if since is None else f"the values from the value change at {since:g} s"
    check(values.count(extreme) == 1, key,
          f"{breakdown.circuit!r} names no single circuit: {source} tie at {extreme:g} ({values}); "
          "give a circuit index")


def _validate_event_time(key: str, time_s: float, cfg: DictConfig) -> None:
    """Events happen between the start of the warm-up (negative time) and the end of a trial;
    one falls due at the first control period that starts at or after it, so one after the
    last period's start would never happen."""
    start_s = 0.0 - cfg.sim.warmup_s  # not -warmup_s: that prints "-0" when there is none
    check(
        start_s <= time_s < cfg.duration_s,
        key,
        f"{time_s:g} s (after scaling) is outside the simulated time "
        f"[-sim.warmup_s = {start_s:g}, duration_s = {cfg.duration_s:g})",
    )
    dt_s, warmup_s = cfg.sim.dt_s, cfg.sim.warmup_s
    due, end = due_tick(time_s + warmup_s, dt_s), end_tick(-warmup_s, cfg.duration_s, dt_s)  # as the engine counts
    check(due < end, key,
          f"{time_s:g} s (after scaling) would fall due at tick {due}, after the trial's last tick, {end - 1} "
          f"(its {end} periods of sim.dt_s = {dt_s:g} s from the start of the warm-up), so it would never happen")


def _validate_breakdown_target(
    key: str, breakdown: DictConfig, n_robots: int, n_circuits: int
) -> None:
    """A breakdown names a robot, a circuit (high, low or an index), or neither (random robot)."""
    if breakdown.robot is not None:
        check(
            0 <= breakdown.robot < n_robots,
            f"{key}.robot",
            f"must be a robot index in [0, {n_robots}), got {breakdown.robot!r}",
        )
        check(breakdown.circuit is None, key, "give robot or circuit, not both")
    circuit = breakdown.circuit
    if circuit is None or circuit in ("high", "low"):
        return
    check(
        circuit.isascii() and circuit.isdigit() and int(circuit) < n_circuits,  # not "²", a digit to Python
        f"{key}.circuit",
        f"must be null, high, low or a circuit index in [0, {n_circuits}), got {circuit!r}",
    )


def _validate_executor(executor: DictConfig) -> None:
    """Backend and parallelism."""
    one_of("executor.backend", executor.backend, BACKENDS)
    check(executor.backend in AVAILABLE_BACKENDS, "executor.backend",
          f"'{executor.backend}' is not available in this version; use one of {', '.join(AVAILABLE_BACKENDS)}")
    module = BACKEND_MODULES.get(executor.backend)
    check(module is None or importlib.util.find_spec(module) is not None, "executor.backend",
          f"'{executor.backend}' needs {module}, which is not installed: pip install 'tavc[{executor.backend}]'")
    at_least("executor.n_jobs", executor.n_jobs, 1)
    at_least("executor.batch_size", executor.batch_size, 1)
    one_of("executor.confine", executor.confine, CONFINE_CHOICES)
