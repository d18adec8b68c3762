"""Validation of where things are: the arena, its walls and targets, room to dock at each
bar-code (and robots slow enough to stop there, with a drive strong enough to get going), every
target within reach, and room for the team where it starts (``sim.arena`` holds the start rules)."""

import math
from collections.abc import Sequence

import numpy as np
from omegaconf import DictConfig, OmegaConf

from tavc_cli.config.checks import at_least, check, fail, one_of, plain, positive, unique
from tavc_cli.errors import TavcError
from tavc_cli.experiments.build import stand_in, trial_specs
from tavc_cli.experiments.trial import TrialState
from tavc_cli.settings import MIN_DOCK_CLEARANCE_M, TARGET_KINDS, WALL_TOLERANCE_M, RobotConfig, SimConfig
from tavc_cli.sim.arena import (
    N_OUTER_WALLS,
    START_GAP_M,
    START_WALL_MARGIN_M,
    arena_from_config,
    most_robots,
    nearest_wall,
    wall_distance,
)

# A team always fits if, with all but one robot placed, a draw still succeeds with at least this
# chance wherever the others stand: a robot then fails all its draws with a chance below
# 0.99 ** 10 000, about 1e-44. A larger team is placed by the engine's own code to check it.
START_MIN_CHANCE = 0.01
# The reach check's grid: cells of at most this side (and a quarter of the robot's radius), and
# no more than this many cells (a very large arena gets coarser cells).
REACH_CELL_M = 0.02
REACH_MAX_CELLS = 2_000_000
# The longest side an arena may have (1,000 km): there a double still tells positions 1.2e-10 m
# apart, far below anything the simulator resolves; far longer sides overflow the areas the start
# checks compute (1e200 m does), and robots started that far from the targets deliver nothing.
MAX_ARENA_M = 1e6
# pymunk's contact solver passes per step (its default 10); the estimate of a run's time assumes the default.
MAX_SOLVER_ITERATIONS = 100


def validate_arena(arena: DictConfig) -> None:
    """Walls, targets on walls, circuits between existing sources and sinks."""
    for name in ("width_m", "height_m"):
        positive(f"arena.{name}", arena[name])
        low = 2 * START_WALL_MARGIN_M
        check(arena[name] >= low, f"arena.{name}",
              f"must be at least {low:g} m (robots start at least {START_WALL_MARGIN_M:g} m from every wall), "
              f"got {arena[name]:g}")
        check(arena[name] <= MAX_ARENA_M, f"arena.{name}",
              f"must be at most {MAX_ARENA_M:,.0f} m (1,000 km), got {_exact(arena[name])}")
    positive("arena.barcode_width_m", arena.barcode_width_m)
    for index, wall in enumerate(arena.walls):
        _validate_wall(f"arena.walls[{index}]", wall, arena)
    for index, target in enumerate(arena.targets):
        _validate_target(f"arena.targets[{index}]", target, arena)
    unique("arena.targets", [target.name for target in arena.targets], "name")
    unique("arena.targets", [target.barcode for target in arena.targets], "barcode")
    check(len(arena.circuits) >= 1, "arena.circuits", "needs at least one circuit")
    unique("arena.circuits", [circuit.name for circuit in arena.circuits], "name")
    kinds = {target.name: target.kind for target in arena.targets}
    for index, circuit in enumerate(arena.circuits):
        for end in ("source", "sink"):
            key, name = f"arena.circuits[{index}].{end}", circuit[end]
            check(name in kinds, key, f"no target named {name!r} in arena.targets")
            check(kinds[name] == end, key, f"target {name!r} is a {kinds[name]}, not a {end}")


def _exact(value: float) -> str:
    """`value` with every digit that tells it from a bound: 1,000,001, or 1000000.0000001."""
    value = float(value)
    return f"{value:,.0f}" if value.is_integer() and abs(value) < 1e15 else repr(value)


def _arena_size(arena: DictConfig) -> str:
    return f"the {arena.width_m:g} x {arena.height_m:g} m arena"


def _validate_target(key: str, target: DictConfig, arena: DictConfig) -> None:
    """A target lies on one of the four walls: its bar-code is mounted there."""
    one_of(f"{key}.kind", target.kind, TARGET_KINDS)
    at_least(f"{key}.barcode", target.barcode, 0)
    x, y, width, height = target.x, target.y, arena.width_m, arena.height_m
    where = f"target ({x!r}, {y!r})"
    for axis, value, size in (("x", x, width), ("y", y, height)):
        inside = -WALL_TOLERANCE_M <= value <= size + WALL_TOLERANCE_M
        check(inside, f"{key}.{axis}", f"{where} lies outside {_arena_size(arena)}")
    gap_m = min(abs(x), abs(x - width), abs(y), abs(y - height))
    check(
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
    check(numbers_ok, key, f"a wall is [x1, y1, x2, y2] in metres, got {plain(wall)!r}")
    sizes = (arena.width_m, arena.height_m) * 2
    for index, (value, size) in enumerate(zip(wall, sizes, strict=True)):
        problem = f"{value!r} lies outside {_arena_size(arena)}"
        check(0 <= value <= size, f"{key}[{index}]", problem)
    check(tuple(wall[:2]) != tuple(wall[2:]), key, "a wall needs two distinct end points")


def validate_docks(arena: DictConfig, robot: DictConfig) -> None:
    """Each bar-code fits on its wall with room for a docked robot, and none overlap."""
    half = arena.barcode_width_m / 2
    body = robot.radius_m + MIN_DOCK_CLEARANCE_M
    need = max(half, body)
    placed: dict[str, list[tuple[float, int]]] = {}
    for index, target in enumerate(arena.targets):
        key, where = f"arena.targets[{index}]", f"target ({target.x!r}, {target.y!r})"
        wall, _, along, length = nearest_wall(target.x, target.y, arena.width_m, arena.height_m)
        gap = min(along, length - along)
        check(gap >= need - WALL_TOLERANCE_M, key,
              f"{where} lies {gap:g} m from a corner; it needs {need:g} m for its bar-code "
              f"(arena.barcode_width_m / 2 = {half:g}) and a robot docked in front of it "
              f"(robot.radius_m + {MIN_DOCK_CLEARANCE_M:g} = {body:g})")
        for other_along, other in placed.get(wall, []):
            check(abs(along - other_along) >= arena.barcode_width_m - WALL_TOLERANCE_M, key,
                  f"{where}'s bar-code overlaps that of arena.targets[{other}] on the {wall} wall: their centres "
                  f"must be at least arena.barcode_width_m = {arena.barcode_width_m:g} m apart, "
                  f"got {abs(along - other_along):g}")
        placed.setdefault(wall, []).append((along, index))


def validate_dock_speed(cfg: DictConfig) -> None:
    """No robot moves further than its docking tolerance in a control period, or it could overshoot
    every dock. A robot too fast even at the usual period is the speed's fault (its member's key in
    a team that lists them), else the period's."""
    dt_s = cfg.sim.dt_s
    members = cfg.team.members
    fastest = max(range(len(members)), key=lambda index: members[index].speed_mps)
    top_mps = members[fastest].speed_mps
    tolerance_m = cfg.robot.dock.lateral_tol_m
    if top_mps * min(dt_s, SimConfig.dt_s) > tolerance_m:
        same = all(member.speed_mps == cfg.robot.speed_mps for member in members)
        fail("robot.speed_mps" if same else f"team.members[{fastest}].speed_mps",
             f"{top_mps:g} m/s would carry the robot {top_mps * dt_s:g} m in one control period (sim.dt_s = "
             f"{dt_s:g} s), past its docking tolerance robot.dock.lateral_tol_m = {tolerance_m:g} m, so it could "
             f"overshoot every dock; at most {tolerance_m / dt_s:g} m/s at this period")
    check(top_mps * dt_s <= tolerance_m, "sim.dt_s",
          f"must be at most robot.dock.lateral_tol_m / top speed = {tolerance_m:g} m / {top_mps:g} m/s "
          f"= {tolerance_m / top_mps:g} s (no robot may move further than its docking tolerance in one "
          f"control period), got {dt_s:g}")


def validate_drive(cfg: DictConfig) -> None:
    """Every robot gets up to its speed and its turn rate within a trial. The drive pushes a disc
    of robot.mass_kg with at most robot.drive_force_n and turns it with at most
    robot.drive_torque_nm (the simulator's body and joints), so from rest it needs mass x speed /
    force seconds to reach its speed, moment x turn rate / torque to reach its turn rate. A robot
    needing longer than a whole trial, warm-up included, never once moves as its settings say.
    Named: the drive's key where even the usual mass would be too slow with it, else the mass."""
    robot = cfg.robot
    span_s = float(cfg.sim.warmup_s) + float(cfg.duration_s)
    top_mps = max(member.speed_mps for member in cfg.team.members)
    disc = robot.radius_m ** 2 / 2  # a uniform disc's moment of inertia per kg
    for what, rate, unit, per_kg, drive_key, drive, drive_unit in (
            ("speed", top_mps, "m/s", 1.0, "drive_force_n", robot.drive_force_n, "N"),
            ("turn rate", robot.turn_rate_radps, "rad/s", disc, "drive_torque_nm", robot.drive_torque_nm, "N m")):
        needs_s = robot.mass_kg * per_kg * rate / drive
        if needs_s <= span_s:
            continue
        usual_mass_too_slow = RobotConfig.mass_kg * per_kg * rate / drive > span_s
        fail(f"robot.{drive_key}" if usual_mass_too_slow else "robot.mass_kg",
             f"a robot of robot.mass_kg = {robot.mass_kg:g} kg driven with at most robot.{drive_key} = {drive:g} "
             f"{drive_unit} would need {needs_s:.3g} s from rest to reach its {what} of {rate:g} {unit}, longer than "
             f"a whole trial (sim.warmup_s + duration_s = {span_s:g} s); it would never move as its settings say")


def validate_periods(cfg: DictConfig) -> None:
    """No robot outruns its dock in a control period, or needs longer than a trial to get going;
    trials and performance bins span a control period."""
    validate_dock_speed(cfg)
    dt_s = cfg.sim.dt_s
    for key, value in (("duration_s", cfg.duration_s), ("analysis.performance_bin_s", cfg.analysis.performance_bin_s)):
        check(value >= dt_s, key, f"must be at least one control period (sim.dt_s = {dt_s:g} s), got {value:g}")
    validate_drive(cfg)


def validate_reachable(arena: DictConfig, robot: DictConfig) -> None:
    """With interior walls, a robot can get from where robots start to every target.

    The robot's centre moves in the free space: points more than a radius from every wall. On
    a grid of cells (``REACH_CELL_M``), that space must hold the whole start area (the
    arena less START_WALL_MARGIN_M from every wall) in one connected piece, and the spot in
    front of each bar-code where a docked robot's centre sits must lie in that piece. Without
    interior walls the arena is an open rectangle and nothing is checked.
    """
    if not arena.walls:
        return
    model = arena_from_config(arena)
    width, height, radius = model.width_m, model.height_m, float(robot.radius_m)
    cell = max(min(REACH_CELL_M, radius / 4), math.sqrt(width * height / REACH_MAX_CELLS),
               max(width, height) / REACH_MAX_CELLS)  # however long and thin: at most REACH_MAX_CELLS a side
    xs, ys = np.arange(cell / 2, width, cell), np.arange(cell / 2, height, cell)
    x, y = np.meshgrid(xs, ys)
    free = wall_distance(model.walls, x, y) > radius
    # deferred: loads scipy
    from scipy import ndimage

    pieces, _ = ndimage.label(free)
    margin = START_WALL_MARGIN_M
    start = ((x >= margin) & (x <= width - margin) & (y >= margin) & (y <= height - margin)
             & (wall_distance(model.walls[N_OUTER_WALLS:], x, y) >= margin))
    where = np.unique(pieces[start & free])
    where = where[where > 0]
    who = f"a robot of robot.radius_m = {radius:g}"
    check(len(where) > 0, "arena.walls", f"the walls leave no room for {who} to start "
          f"({margin:g} m from every wall)")
    check(len(where) == 1, "arena.walls", f"the walls split the area where robots start into {len(where)} "
          f"parts that {who} cannot pass between")
    for index, target in enumerate(model.targets):
        reach = radius + MIN_DOCK_CLEARANCE_M
        px, py = target.x + target.normal[0] * reach, target.y + target.normal[1] * reach
        i = min(int(py / cell), len(ys) - 1)
        j = min(int(px / cell), len(xs) - 1)
        check(pieces[i, j] == where[0], f"arena.targets[{index}]",
              f"target {target.name!r} cannot be reached by {who} from where robots start: "
              "arena.walls close it off or leave no room to dock in front of it")


def validate_model_team(cfg: DictConfig) -> None:
    """`tavc model` measures teams of up to model.max_robots: they must fit in the arena."""
    arena, radius = cfg.arena, float(cfg.robot.radius_m)
    most = most_robots(float(arena.width_m), float(arena.height_m), radius)
    if cfg.model.max_robots is not None:
        check(cfg.model.max_robots <= most, "model.max_robots",
              f"{cfg.model.max_robots} robots of robot.radius_m = {radius:g} cannot start in the "
              f"{arena.width_m:g} x {arena.height_m:g} m arena; at most {most} would fit")


def validate_start(cfg: DictConfig) -> None:
    """Every trial's team can be placed where robots start: at random, apart, clear of the walls.

    Robots are placed one by one, each drawn uniformly in the start area (the arena less
    START_WALL_MARGIN_M all round) and kept if its centre is more than ``d = 2 radius +
    START_GAP_M`` from every placed one. With ``k`` placed, at most ``k pi d^2`` of the area is
    excluded, so a team with ``(n - 1) pi d^2 <= (1 - START_MIN_CHANCE) * area`` always fits. A
    larger team, or any team in an arena with interior walls, is placed here as the engine will
    place it, trial by trial, from each trial's seed.
    """
    arena, robot, n_robots = cfg.arena, cfg.robot, cfg.team.n_robots
    spacing = 2 * robot.radius_m + START_GAP_M
    area = (arena.width_m - 2 * START_WALL_MARGIN_M) * (arena.height_m - 2 * START_WALL_MARGIN_M)
    always = 1 + math.floor((1 - START_MIN_CHANCE) * area / (math.pi * spacing**2))
    if n_robots <= always and not arena.walls:  # interior walls take start area the bound does not count
        return
    specs = trial_specs(OmegaConf.to_object(cfg))
    model = specs[0].build_arena()
    for spec in specs:
        try:
            TrialState(stand_in(spec), model, 0)  # placed from its seed; a learner from outside tavc is not run here
        except TavcError:
            fail("team.n_robots",
                 f"cannot place {n_robots} robots of robot.radius_m = {robot.radius_m:g} at random "
                 f"{START_GAP_M:g} m apart and {START_WALL_MARGIN_M:g} m from the walls of {_arena_size(arena)} "
                 f"(trial {spec.trial} of {spec.controller}, seed {cfg.seed}); {always} always fit")


def validate_sim(sim: DictConfig) -> None:
    """Simulator timing."""
    positive("sim.dt_s", sim.dt_s)
    at_least("sim.physics_substeps", sim.physics_substeps, 1)
    at_least("sim.solver_iterations", sim.solver_iterations, 1)
    check(sim.solver_iterations <= MAX_SOLVER_ITERATIONS, "sim.solver_iterations",
          f"must be at most {MAX_SOLVER_ITERATIONS} (pymunk's default is 10; each step solves every contact this "
          f"many times, a cost the estimate of a run's time does not count), got {sim.solver_iterations}")
    at_least("sim.q_snapshot_every_s", sim.q_snapshot_every_s, 0)
    at_least("sim.pose_every_s", sim.pose_every_s, 0)
    at_least("sim.warmup_s", sim.warmup_s, 0)
