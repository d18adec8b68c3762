"""Validation: each check raises one ``TavcError("<key>: <problem>")`` line."""

import importlib.util
import math
from collections.abc import Sequence
from typing import Any, NoReturn

from omegaconf import DictConfig, OmegaConf

from tavc_cli.config.schema import (
    ANALYSIS_STATES,
    AVAILABLE_BACKENDS,
    BACKENDS,
    MIN_DOCK_CLEARANCE_M,
    TARGET_KINDS,
    TIME_UNITS,
    WALL_TOLERANCE_M,
)
from tavc_cli.errors import TavcError
from tavc_cli.learning.registry import AVAILABLE as AVAILABLE_LEARNERS
from tavc_cli.learning.registry import BASELINES
from tavc_cli.learning.registry import NAMES as LEARNERS

# How ``experiments.engine.start_poses`` places a team: each centre drawn uniformly at least
# START_WALL_MARGIN_M from every wall, more than two radii plus START_GAP_M from the others,
# with up to 10 000 draws per robot (mirrored here: importing the engine loads numba).
START_WALL_MARGIN_M = 0.6
START_GAP_M = 0.3
# A team always fits if, with all but one robot placed, a draw still succeeds with at least this
# chance wherever the others stand: a robot then fails all its draws with a chance below
# 0.99 ** 10 000, about 1e-44. A larger team is placed by the engine's own code to check it.
START_MIN_CHANCE = 0.01
# The laser needs a ray ahead and one to either side: to read codes, avoid robots, follow walls.
MIN_LASER_RAYS = 3
# The module each cluster backend needs (its extra is the backend's name), as ``experiments.executors``.
BACKEND_MODULES = {"dask": "distributed", "ray": "ray"}


def _fail(key: str, problem: str) -> NoReturn:
    raise TavcError(f"{key}: {problem}")


def _check(ok: bool, key: str, problem: str) -> None:
    if not ok:
        _fail(key, problem)


def _positive(key: str, value: float) -> None:
    _check(math.isfinite(value) and value > 0, key, f"must be > 0, got {value!r}")


def _at_least(key: str, value: float, low: float) -> None:
    _check(math.isfinite(value) and value >= low, key, f"must be >= {low}, got {value!r}")


def _finite(key: str, value: float) -> None:
    _check(math.isfinite(value), key, f"must be a finite number, got {value!r}")


def _unit(key: str, value: float) -> None:
    _check(0 <= value <= 1, key, f"must be in [0, 1], got {value!r}")


def _angle(key: str, value: float, high: float) -> None:
    _check(0 < value <= high, key, f"must be in (0, {high:g}], got {value!r}")


def _one_of(key: str, value: Any, choices: Sequence[str]) -> None:
    _check(value in choices, key, f"must be one of {', '.join(choices)}; got {value!r}")


def _per_circuit(key: str, values: Sequence[Any], n_circuits: int, what: str) -> None:
    _check(
        len(values) == n_circuits,
        key,
        f"needs one {what} per circuit ({n_circuits}), got {len(values)}",
    )


def _unique(key: str, values: Sequence[Any], what: str) -> None:
    seen = set()
    for value in values:
        _check(value not in seen, key, f"{what} {value!r} appears more than once")
        seen.add(value)


def check_no_missing(cfg: DictConfig) -> None:
    """Every ``???`` in the schema must have been filled by a config file or override."""
    missing = sorted(OmegaConf.missing_keys(cfg))
    if missing:
        _fail(missing[0], "missing value (set it in its config file or on the command line)")


def validate_scaling(cfg: DictConfig) -> None:
    """Check what resolution derives values from, so errors name the key the user set."""
    _positive("scale.time_factor", cfg.scale.time_factor)
    if cfg.scale.trials is not None:
        _at_least("scale.trials", cfg.scale.trials, 1)
    paper = cfg.paper
    _at_least("paper.trials", paper.trials, 1)
    if paper.baseline_trials is not None:
        _at_least("paper.baseline_trials", paper.baseline_trials, 1)
    _positive("paper.duration_s", paper.duration_s)
    # before resolution scales it, so that the message shows the value the user wrote
    _at_least("sim.warmup_s", cfg.sim.warmup_s, 0)
    _check(
        0 <= paper.convergence_s < paper.duration_s,
        "paper.convergence_s",
        f"must be in [0, paper.duration_s = {paper.duration_s:g}), got {paper.convergence_s!r}",
    )


def validate(cfg: DictConfig) -> None:
    """Validate a resolved config."""
    _validate_arena(cfg.arena)
    _validate_robot(cfg.robot)
    _validate_docks(cfg.arena, cfg.robot)
    _validate_team(cfg.team)
    n_circuits, n_robots = len(cfg.arena.circuits), cfg.team.n_robots
    _validate_learner(cfg.learner, n_circuits, n_robots)
    _validate_run(cfg)
    if cfg.static_allocation is not None:
        _validate_allocation("static_allocation", cfg.static_allocation, n_circuits, n_robots)
    _validate_tasks(cfg.tasks, n_circuits)
    _validate_events(cfg, n_circuits)
    _validate_sim(cfg.sim)
    _validate_control_period(cfg)
    _validate_executor(cfg.executor)
    _one_of("analysis.state", cfg.analysis.state, ANALYSIS_STATES)
    _positive("analysis.performance_bin_s", cfg.analysis.performance_bin_s)
    if cfg.analysis.before_s is not None:
        _positive("analysis.before_s", cfg.analysis.before_s)
    _validate_model(cfg.model)
    _validate_calibration(cfg.calibration)
    _validate_start(cfg)  # last: beyond what always fits, it builds the trials to place their teams


def _validate_model(model: DictConfig) -> None:
    """Measurement settings of the TAVC model."""
    _at_least("model.trials_per_split", model.trials_per_split, 2)
    _at_least("model.warmup_s", model.warmup_s, 0)
    _positive("model.measure_s", model.measure_s)
    _check(0 < model.confidence < 1, "model.confidence", f"must be in (0, 1), got {model.confidence!r}")
    if model.max_robots is not None:
        _at_least("model.max_robots", model.max_robots, 1)


def _validate_calibration(cal: DictConfig) -> None:
    """The world search: measurement settings and a grid over existing config keys."""
    _at_least("calibration.trials_per_split", cal.trials_per_split, 2)
    _at_least("calibration.warmup_s", cal.warmup_s, 0)
    _positive("calibration.measure_s", cal.measure_s)
    for index, axis in enumerate(cal.grid):
        key = f"calibration.grid[{index}]"
        _check(len(axis["values"]) >= 1, f"{key}.values", "needs at least one value")
        _check(OmegaConf.select(cal._get_root(), axis.key, default="__absent__") != "__absent__", f"{key}.key",
               f"no config key named {axis.key!r}")


def _validate_arena(arena: DictConfig) -> None:
    """Walls, targets on walls, circuits between existing sources and sinks."""
    for name in ("width_m", "height_m"):
        _positive(f"arena.{name}", arena[name])
        low = 2 * START_WALL_MARGIN_M
        _check(arena[name] >= low, f"arena.{name}",
               f"must be at least {low:g} m (robots start at least {START_WALL_MARGIN_M:g} m from every wall), "
               f"got {arena[name]:g}")
    _positive("arena.barcode_width_m", arena.barcode_width_m)
    for index, wall in enumerate(arena.walls):
        _validate_wall(f"arena.walls[{index}]", wall, arena)
    for index, target in enumerate(arena.targets):
        _validate_target(f"arena.targets[{index}]", target, arena)
    _unique("arena.targets", [target.name for target in arena.targets], "name")
    _unique("arena.targets", [target.barcode for target in arena.targets], "barcode")
    _check(len(arena.circuits) >= 1, "arena.circuits", "needs at least one circuit")
    _unique("arena.circuits", [circuit.name for circuit in arena.circuits], "name")
    kinds = {target.name: target.kind for target in arena.targets}
    for index, circuit in enumerate(arena.circuits):
        for end in ("source", "sink"):
            key, name = f"arena.circuits[{index}].{end}", circuit[end]
            _check(name in kinds, key, f"no target named {name!r} in arena.targets")
            _check(kinds[name] == end, key, f"target {name!r} is a {kinds[name]}, not a {end}")


def _arena_size(arena: DictConfig) -> str:
    return f"the {arena.width_m:g} x {arena.height_m:g} m arena"


def _validate_target(key: str, target: DictConfig, arena: DictConfig) -> None:
    """A target lies on one of the four walls: its bar-code is mounted there."""
    _one_of(f"{key}.kind", target.kind, TARGET_KINDS)
    _at_least(f"{key}.barcode", target.barcode, 0)
    x, y, width, height = target.x, target.y, arena.width_m, arena.height_m
    where = f"target ({x!r}, {y!r})"
    for axis, value, size in (("x", x, width), ("y", y, height)):
        inside = -WALL_TOLERANCE_M <= value <= size + WALL_TOLERANCE_M
        _check(inside, f"{key}.{axis}", f"{where} lies outside {_arena_size(arena)}")
    gap_m = min(abs(x), abs(x - width), abs(y), abs(y - height))
    _check(
        gap_m <= WALL_TOLERANCE_M,
        key,
        f"{where} is not on a wall of {_arena_size(arena)} (bar-codes are mounted on walls)",
    )


def _validate_wall(key: str, wall: Sequence[float], arena: DictConfig) -> None:
    """An interior wall ``[x1, y1, x2, y2]`` lies inside the arena and has a length."""
    shape_ok = OmegaConf.is_list(wall) and len(wall) == 4
    numbers_ok = shape_ok and all(
        isinstance(v, (int, float)) and not isinstance(v, bool) for v in wall
    )
    _check(numbers_ok, key, f"a wall is [x1, y1, x2, y2] in metres, got {_plain(wall)!r}")
    sizes = (arena.width_m, arena.height_m) * 2
    for index, (value, size) in enumerate(zip(wall, sizes, strict=True)):
        problem = f"{value!r} lies outside {_arena_size(arena)}"
        _check(0 <= value <= size, f"{key}[{index}]", problem)
    _check(tuple(wall[:2]) != tuple(wall[2:]), key, "a wall needs two distinct end points")


def _plain(value: Any) -> Any:
    """A config node as builtin types, for messages."""
    return OmegaConf.to_container(value) if OmegaConf.is_config(value) else value


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
        _positive(f"robot.{name}", robot[name])
    _check(robot.radius_m < START_WALL_MARGIN_M, "robot.radius_m",
           f"must be less than {START_WALL_MARGIN_M:g} m (robots start with their centres "
           f"{START_WALL_MARGIN_M:g} m from the walls), got {robot.radius_m:g}")
    _check(robot.laser.n_rays >= MIN_LASER_RAYS, "robot.laser.n_rays",
           f"must be >= {MIN_LASER_RAYS} (a ray ahead to read bar-codes and rays to the sides to avoid robots "
           f"and follow walls), got {robot.laser.n_rays!r}")
    _angle("robot.laser.fov_deg", robot.laser.fov_deg, 360.0)
    _positive("robot.laser.range_m", robot.laser.range_m)
    _angle("robot.camera.fov_deg", robot.camera.fov_deg, 360.0)
    _positive("robot.camera.range_m", robot.camera.range_m)
    _angle("robot.camera.side_sector_deg", robot.camera.side_sector_deg, 180.0)
    for name, value in robot.odometry.items():
        _at_least(f"robot.odometry.{name}", value, 0)
    for name in ("avoid_dist_m", "arrive_dist_m", "wall_dist_m", "relocalise_dist_m", "stall_s", "escape_s",
                 "progress_m"):
        _positive(f"robot.behaviour.{name}", robot.behaviour[name])
    for name in ("stop_dist_m", "visible_margin_m"):
        _at_least(f"robot.behaviour.{name}", robot.behaviour[name], 0)
    _check(robot.behaviour.avoid_dist_m > robot.behaviour.stop_dist_m, "robot.behaviour.avoid_dist_m",
           f"must exceed robot.behaviour.stop_dist_m ({robot.behaviour.stop_dist_m:g}), "
           f"got {robot.behaviour.avoid_dist_m:g}")
    # the dock spot: the robot reads its code at arrive_dist_m from its centre, so its front
    # must stay clear of the wall there (a few cm at least) or it could never get that close
    clearance = robot.radius_m + MIN_DOCK_CLEARANCE_M
    _check(robot.behaviour.arrive_dist_m >= clearance, "robot.behaviour.arrive_dist_m",
           f"must be at least robot.radius_m + {MIN_DOCK_CLEARANCE_M:g} = {clearance:g} (the robot reads "
           f"its code from the dock spot in front of the wall), got {robot.behaviour.arrive_dist_m:g}")
    dock = robot.dock
    for name in ("lateral_tol_m", "approach_m", "backout_m", "occupied_m", "hold_margin_m", "patience_s"):
        _positive(f"robot.dock.{name}", dock[name])
    _at_least("robot.dock.dwell_s", dock.dwell_s, 0)
    _angle("robot.dock.heading_tol_deg", dock.heading_tol_deg, 90.0)
    # from the start of the final approach the robot must read its code to line up on it
    reach = robot.behaviour.arrive_dist_m + dock.approach_m
    _check(robot.laser.range_m >= reach, "robot.laser.range_m",
           f"must reach the start of the final approach, robot.behaviour.arrive_dist_m + robot.dock.approach_m "
           f"= {reach:g} m, got {robot.laser.range_m:g}")


def _validate_docks(arena: DictConfig, robot: DictConfig) -> None:
    """Each bar-code fits on its wall with room for a docked robot, and none overlap."""
    half = arena.barcode_width_m / 2
    body = robot.radius_m + MIN_DOCK_CLEARANCE_M
    need = max(half, body)
    placed: dict[str, list[tuple[float, int]]] = {}
    for index, target in enumerate(arena.targets):
        key, where = f"arena.targets[{index}]", f"target ({target.x!r}, {target.y!r})"
        wall, along, length = _wall_of(target.x, target.y, arena)
        gap = min(along, length - along)
        _check(gap >= need - WALL_TOLERANCE_M, key,
               f"{where} lies {gap:g} m from a corner; it needs {need:g} m for its bar-code "
               f"(arena.barcode_width_m / 2 = {half:g}) and a robot docked in front of it "
               f"(robot.radius_m + {MIN_DOCK_CLEARANCE_M:g} = {body:g})")
        for other_along, other in placed.get(wall, []):
            _check(abs(along - other_along) >= arena.barcode_width_m - WALL_TOLERANCE_M, key,
                   f"{where}'s bar-code overlaps that of arena.targets[{other}] on the {wall} wall: their centres "
                   f"must be at least arena.barcode_width_m = {arena.barcode_width_m:g} m apart, "
                   f"got {abs(along - other_along):g}")
        placed.setdefault(wall, []).append((along, index))


def _wall_of(x: float, y: float, arena: DictConfig) -> tuple[str, float, float]:
    """The outer wall nearest (x, y) as ``sim.arena`` picks it, the position along it, its length."""
    width, height = arena.width_m, arena.height_m
    walls = {"left": (x, y, height), "right": (width - x, y, height), "bottom": (y, x, width),
             "top": (height - y, x, width)}
    name = min(walls, key=lambda wall: walls[wall][0])
    _, along, length = walls[name]
    return name, along, length


def _validate_start(cfg: DictConfig) -> None:
    """Every trial's team can be placed where robots start: at random, apart, clear of the walls.

    Robots are placed one by one, each drawn uniformly in the start area (the arena less
    START_WALL_MARGIN_M all round) and kept if its centre is more than ``d = 2 radius +
    START_GAP_M`` from every placed one. With ``k`` placed, at most ``k pi d^2`` of the area is
    excluded, so a team with ``(n - 1) pi d^2 <= (1 - START_MIN_CHANCE) * area`` always fits. A
    larger team is placed here as the engine will place it, trial by trial, from each trial's seed.
    """
    arena, robot, n_robots = cfg.arena, cfg.robot, cfg.team.n_robots
    spacing = 2 * robot.radius_m + START_GAP_M
    area = (arena.width_m - 2 * START_WALL_MARGIN_M) * (arena.height_m - 2 * START_WALL_MARGIN_M)
    always = 1 + math.floor((1 - START_MIN_CHANCE) * area / (math.pi * spacing**2))
    if n_robots <= always:
        return
    # imported here: the engine loads numba, which `tavc config` need not wait for
    from tavc_cli.experiments.build import trial_specs
    from tavc_cli.experiments.engine import TrialState

    specs = trial_specs(OmegaConf.to_object(cfg))
    model = specs[0].build_arena()
    for spec in specs:
        try:
            TrialState(spec, model, 0)
        except TavcError:
            _fail("team.n_robots",
                  f"cannot place {n_robots} robots of robot.radius_m = {robot.radius_m:g} at random "
                  f"{START_GAP_M:g} m apart and {START_WALL_MARGIN_M:g} m from the walls of {_arena_size(arena)} "
                  f"(trial {spec.trial} of {spec.controller}, seed {cfg.seed}); {always} always fit")


def _validate_team(team: DictConfig) -> None:
    """Team size, and members matching it."""
    _at_least("team.n_robots", team.n_robots, 1)
    _check(
        len(team.members) == team.n_robots,
        "team.n_robots",
        f"{team.n_robots} does not match the {len(team.members)} robots listed in team.members",
    )
    for index, member in enumerate(team.members):
        _positive(f"team.members[{index}].speed_mps", member.speed_mps)
        _check(bool(member.group), f"team.members[{index}].group", "must not be empty")


def _validate_learner(learner: DictConfig, n_circuits: int, n_robots: int) -> None:
    """Learner name and Q-learning parameters."""
    _one_of("learner.name", learner.name, LEARNERS)
    _check(learner.name in AVAILABLE_LEARNERS, "learner.name",
           f"'{learner.name}' is not available in this version; use one of {', '.join(AVAILABLE_LEARNERS)}")
    for name in ("alpha", "gamma", "epsilon"):
        _unit(f"learner.{name}", learner[name])
    _positive("learner.tau", learner.tau)
    _positive("learner.decision_period_s", learner.decision_period_s)
    _finite("learner.q_init_low", learner.q_init_low)
    _finite("learner.q_init_high", learner.q_init_high)
    _check(
        math.isfinite(learner.q_init_high - learner.q_init_low),
        "learner.q_init_high",
        f"the range [{learner.q_init_low!r}, {learner.q_init_high!r}] is too wide to draw initial Q-values from",
    )
    _check(
        learner.q_init_low <= learner.q_init_high,
        "learner.q_init_low",
        f"must be <= learner.q_init_high ({learner.q_init_high!r}), got {learner.q_init_low!r}",
    )
    if learner.allocation is not None:
        _validate_allocation("learner.allocation", learner.allocation, n_circuits, n_robots)


def _validate_allocation(
    key: str, allocation: Sequence[int], n_circuits: int, n_robots: int
) -> None:
    """Robots per circuit: one non-negative count per circuit, summing to the team size."""
    _per_circuit(key, allocation, n_circuits, "robot count")
    for index, count in enumerate(allocation):
        _at_least(f"{key}[{index}]", count, 0)
    _check(
        sum(allocation) == n_robots,
        key,
        f"must sum to team.n_robots ({n_robots}), got {sum(allocation)}",
    )


def _validate_run(cfg: DictConfig) -> None:
    """Seed, trial counts, durations, baselines, output folder."""
    _at_least("seed", cfg.seed, 0)
    _at_least("trials", cfg.trials, 1)
    _at_least("baseline_trials", cfg.baseline_trials, 1)
    _positive("duration_s", cfg.duration_s)
    _check(
        0 <= cfg.convergence_s < cfg.duration_s,
        "convergence_s",
        f"must be in [0, duration_s = {cfg.duration_s:g}), got {cfg.convergence_s!r}",
    )
    for index, baseline in enumerate(cfg.baselines):
        _one_of(f"baselines[{index}]", baseline, BASELINES)
    _unique("baselines", list(cfg.baselines), "controller")
    _check(bool(cfg.output_dir), "output_dir", "must not be empty")


def _validate_tasks(tasks: DictConfig, n_circuits: int) -> None:
    """One learning value and one score value per circuit."""
    for name in ("values", "score_values"):
        key = f"tasks.{name}"
        _per_circuit(key, tasks[name], n_circuits, "value")
        for index, value in enumerate(tasks[name]):
            problem = f"must be a finite number, got {value!r}"
            _check(math.isfinite(value), f"{key}[{index}]", problem)
    _one_of("tasks.time_unit", tasks.time_unit, TIME_UNITS)


def _validate_events(cfg: DictConfig, n_circuits: int) -> None:
    """Scheduled breakdowns and value changes fall inside the simulated time."""
    n_robots = cfg.team.n_robots
    breakdowns = cfg.events.breakdowns
    _check(
        len(breakdowns) < n_robots,
        "events.breakdowns",
        f"{len(breakdowns)} breakdowns would leave none of the {n_robots} robots running",
    )
    for index, change in enumerate(cfg.events.value_changes):
        key = f"events.value_changes[{index}]"
        _validate_event_time(f"{key}.time_s", change.time_s, cfg)
        _per_circuit(f"{key}.values", change["values"], n_circuits, "value")
        for position, value in enumerate(change["values"]):
            _finite(f"{key}.values[{position}]", value)
    for index, breakdown in enumerate(breakdowns):
        key = f"events.breakdowns[{index}]"
        _validate_event_time(f"{key}.time_s", breakdown.time_s, cfg)
        _validate_breakdown_target(key, breakdown, n_robots, n_circuits)
        if breakdown.circuit in ("high", "low"):
            _validate_extreme_circuit(f"{key}.circuit", breakdown, cfg)
    robots = [breakdown.robot for breakdown in breakdowns if breakdown.robot is not None]
    _unique("events.breakdowns", robots, "robot")


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
    _check(values.count(extreme) == 1, key,
           f"{breakdown.circuit!r} names no single circuit: {source} tie at {extreme:g} ({values}); "
           "give a circuit index")


def _validate_event_time(key: str, time_s: float, cfg: DictConfig) -> None:
    """Events happen between the start of the warm-up (negative time) and the end of a trial."""
    start_s = 0.0 - cfg.sim.warmup_s  # not -warmup_s: that prints "-0" when there is none
    _check(
        start_s <= time_s < cfg.duration_s,
        key,
        f"{time_s:g} s (after scaling) is outside the simulated time "
        f"[-sim.warmup_s = {start_s:g}, duration_s = {cfg.duration_s:g})",
    )


def _validate_breakdown_target(
    key: str, breakdown: DictConfig, n_robots: int, n_circuits: int
) -> None:
    """A breakdown names a robot, a circuit (high, low or an index), or neither (random robot)."""
    if breakdown.robot is not None:
        _check(
            0 <= breakdown.robot < n_robots,
            f"{key}.robot",
            f"must be a robot index in [0, {n_robots}), got {breakdown.robot!r}",
        )
        _check(breakdown.circuit is None, key, "give robot or circuit, not both")
    circuit = breakdown.circuit
    if circuit is None or circuit in ("high", "low"):
        return
    _check(
        circuit.isdigit() and int(circuit) < n_circuits,
        f"{key}.circuit",
        f"must be null, high, low or a circuit index in [0, {n_circuits}), got {circuit!r}",
    )


def _validate_sim(sim: DictConfig) -> None:
    """Simulator timing."""
    _positive("sim.dt_s", sim.dt_s)
    _at_least("sim.physics_substeps", sim.physics_substeps, 1)
    _at_least("sim.solver_iterations", sim.solver_iterations, 1)
    _at_least("sim.q_snapshot_every_s", sim.q_snapshot_every_s, 0)
    _at_least("sim.pose_every_s", sim.pose_every_s, 0)
    _at_least("sim.warmup_s", sim.warmup_s, 0)


def _validate_control_period(cfg: DictConfig) -> None:
    """Trials and performance bins span a control period, in which no robot outruns its dock."""
    dt_s = cfg.sim.dt_s
    top_mps = max(member.speed_mps for member in cfg.team.members)
    tolerance_m = cfg.robot.dock.lateral_tol_m
    _check(top_mps * dt_s <= tolerance_m, "sim.dt_s",
           f"must be at most robot.dock.lateral_tol_m / top speed = {tolerance_m:g} m / {top_mps:g} m/s "
           f"= {tolerance_m / top_mps:g} s (no robot may move further than its docking tolerance in one "
           f"control period), got {dt_s:g}")
    for key, value in (("duration_s", cfg.duration_s), ("analysis.performance_bin_s", cfg.analysis.performance_bin_s)):
        _check(value >= dt_s, key, f"must be at least one control period (sim.dt_s = {dt_s:g} s), got {value:g}")


def _validate_executor(executor: DictConfig) -> None:
    """Backend and parallelism."""
    _one_of("executor.backend", executor.backend, BACKENDS)
    _check(executor.backend in AVAILABLE_BACKENDS, "executor.backend",
           f"'{executor.backend}' is not available in this version; use one of {', '.join(AVAILABLE_BACKENDS)}")
    module = BACKEND_MODULES.get(executor.backend)
    _check(module is None or importlib.util.find_spec(module) is not None, "executor.backend",
           f"'{executor.backend}' needs {module}, which is not installed: pip install 'tavc[{executor.backend}]'")
    _at_least("executor.n_jobs", executor.n_jobs, 1)
    _at_least("executor.batch_size", executor.batch_size, 1)
    _check(executor.batch_size <= 32, "executor.batch_size",
           f"must be at most 32 (one collision-filter bit per trial), got {executor.batch_size}")
