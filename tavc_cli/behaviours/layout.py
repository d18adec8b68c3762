"""The kernel's data: what one control tick reads and writes, in named bundles.

The compiled kernel (`navigation.control_tick`) works on plain numpy data, so its
inputs are laid out here once, with names and units:

- `ROBOT`, a record per robot: which trial it belongs to, its own model (radius,
  speeds, odometry noise), its dead-reckoned pose and the true pose of the last
  tick, and its behaviour state (target, mode, timers);
- `PARAMS`, one record of parameters every robot shares: the behaviours', the
  sensors', the dock's and the arena's size;
- `ArenaGeometry`: the targets (`TARGET` records: bar-code centre, inward normal, code,
  the outer wall it hangs on, and the bar-code segment the laser reads) and the
  interior walls (the outer rectangle is `PARAMS.arena_width_m` x `arena_height_m`);
- `Laser`: the rays' directions relative to the heading;
- `Scan`, what the sensors wrote this tick: per ray range, kind of hit and hit id;
  per robot what the camera saw;
- `Work`, scratch space the behaviours reuse robot after robot (the kernels allocate
  nothing: see `sim.kernel`).

`build_robots`, `build_params`, `build_arena`, `build_laser` and `empty_scan` fill
them from the config and the arena.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, NamedTuple

import numpy as np

from tavc_cli.sim.arena import N_OUTER_WALLS, Arena
from tavc_cli.sim.sensors import ray_angles
from tavc_cli.vocabulary import ARRIVALS, PASSINGS

if TYPE_CHECKING:  # the settings are read, never imported, by the simulator's lowest layers
    from tavc_cli.settings import RobotConfig

ROBOT = np.dtype([
    # robots of one trial are rows first..last-1 of every per-robot array, and see only each other
    ("trial", np.int64), ("first", np.int64), ("last", np.int64),
    ("alive", np.bool_),
    # the robot's own model
    ("radius_m", np.float64), ("top_speed_mps", np.float64), ("turn_rate_radps", np.float64),
    ("odo_trans_per_sqrt_m", np.float64),   # std of distance error per sqrt(m) travelled
    ("odo_rot_per_sqrt_m", np.float64),     # std of heading error (rad) per sqrt(m) travelled
    ("odo_rot_per_sqrt_rad", np.float64),   # std of heading error (rad) per sqrt(rad) turned
    # where the robot believes it is (odometry), and where it truly was last tick
    ("est_x_m", np.float64), ("est_y_m", np.float64), ("est_heading_rad", np.float64),
    ("prev_x_m", np.float64), ("prev_y_m", np.float64), ("prev_heading_rad", np.float64),
    # behaviour state: the target it heads for (-1: none) and the last one progress was tracked to
    ("target", np.int64), ("last_target", np.int64),
    ("mode", np.int64),          # MODE_*
    ("forced", np.int64),        # BEH_*: a behaviour chosen from outside, or BEH_AUTO
    ("side", np.int64),          # wall-following side: +1 left, -1 right, 0 not chosen
    ("turn", np.int64),          # turn-in-place direction kept while boxed in or turning round
    ("activity", np.int64),      # this tick's activity (behaviours.activities)
    ("arrived", np.bool_),       # reached its target this tick
    ("target_visible", np.bool_),  # the laser reads its target's bar-code this tick
    ("code_in_view", np.bool_),    # the laser reads some bar-code this tick
    ("best_dist_m", np.float64),  # nearest it has come to its goal since progress was last made
    ("stall_s", np.float64),      # seconds without progress
    ("escape_s", np.float64),     # seconds of escape left
    ("timer_s", np.float64),      # seconds left of the current dock phase
    ("waited_s", np.float64),     # seconds spent waiting near an occupied dock
], align=True)

PARAMS = np.dtype([
    ("dt_s", np.float64),
    ("arena_width_m", np.float64), ("arena_height_m", np.float64),
    # behaviours
    ("avoid_dist_m", np.float64), ("stop_dist_m", np.float64), ("arrive_dist_m", np.float64),
    ("wall_dist_m", np.float64), ("visible_margin_m", np.float64), ("relocalise_dist_m", np.float64),
    ("arrival", np.int64),             # ARRIVE_DOCK or ARRIVE_RANGE (`robot.behaviour.arrival`)
    ("read_range_m", np.float64),      # ARRIVE_RANGE: a robot arrives on reading its code this near
    ("pass_side", np.int64),           # PASS_NEAREST, PASS_LEFT or PASS_RIGHT (`robot.behaviour.passing`)
    ("stall_limit_s", np.float64),     # this long without getting progress_m closer: escape ...
    ("escape_duration_s", np.float64),  # ... by following the wall this long
    ("progress_m", np.float64),
    # sensors
    ("laser_range_m", np.float64), ("barcode_width_m", np.float64),
    ("camera_on", np.bool_),     # whether anyone reads the camera (section 1.4's learners)
    ("camera_half_fov_rad", np.float64), ("camera_range_m", np.float64), ("marking_sector_rad", np.float64),
    # docking
    ("dock_lateral_tol_m", np.float64), ("dock_heading_tol_rad", np.float64), ("dock_approach_m", np.float64),
    ("dwell_s", np.float64), ("backout_m", np.float64), ("occupied_m", np.float64),
    ("hold_m", np.float64), ("patience_s", np.float64),
], align=True)

TARGET = np.dtype([
    ("x_m", np.float64), ("y_m", np.float64),    # bar-code centre, on its wall
    ("nx", np.float64), ("ny", np.float64),      # the wall's inward unit normal
    ("barcode", np.int64),
    ("wall", np.int64),                          # outer wall: 0 bottom, 1 right, 2 top, 3 left
    # the bar-code segment the laser reads, a hair in front of the wall
    ("x1_m", np.float64), ("y1_m", np.float64), ("x2_m", np.float64), ("y2_m", np.float64),
    ("half_width_m", np.float64),
    ("facing_rad", np.float64),                  # heading of a robot squarely facing the wall: atan2(-ny, -nx)
], align=True)


class ArenaGeometry(NamedTuple):
    """What the sensors and behaviours know of the arena besides its outer rectangle."""

    targets: np.ndarray       # (n_targets,) TARGET
    inner_walls: np.ndarray   # (n, 4) x1, y1, x2, y2 m; a laser hit on row w reports id N_OUTER_WALLS + w


class Laser(NamedTuple):
    """Ray directions relative to the heading, evenly spaced over the field of view."""

    angle_rad: np.ndarray
    cos: np.ndarray
    sin: np.ndarray
    # the same directions as candidate headings for steering, with the C library's cos and sin
    # (the kernel's own), so a heading's free distance is the same computed either way
    heading_cos: np.ndarray
    heading_sin: np.ndarray
    # the fan as the laser's angular windows need it (`sensors.cast_laser`)
    inv_spacing: float      # rays per radian (1 for a single ray)
    half_fov_rad: float     # the largest ray angle either side of the heading
    full_circle: bool       # the rays go evenly round the whole circle


class Scan(NamedTuple):
    """This tick's readings, one row per robot."""

    range_m: np.ndarray   # (n, n_rays) distance to what the ray hit, or the laser's range
    kind: np.ndarray      # (n, n_rays) HIT_* (sensors)
    hit_id: np.ndarray    # (n, n_rays) bar-code, robot row or wall index of the hit; -1 for none
    camera: np.ndarray    # (n, 4) red, green, yellow markings of the nearest robot seen, its row (-1: none)
    heading_cs: np.ndarray  # (n, 2) cos and sin of the heading the laser was cast at (the scan's frame)


class Work(NamedTuple):
    """Scratch space the behaviours reuse robot after robot, tick after tick: nothing in it
    outlives one robot's turn."""

    xs: np.ndarray        # (n_rays,) hit points that can block a path, robot frame
    ys: np.ndarray
    flags: np.ndarray     # (n_rays,) bool: the ray passing nearest each robot in view
    rows: np.ndarray      # (n_robots,) int: that ray, per robot of the trial (row - first)


MODE_APPROACH, MODE_WALLFOLLOW, MODE_ESCAPE, MODE_DOCK, MODE_SERVICE, MODE_UNDOCK = range(6)
# how a robot arrives at a target (`robot.behaviour.arrival`): into the dock spot, reading the code
# at `arrive_dist_m` (dock); or wherever it stands when it reads its code within `read_range_m` (range)
ARRIVE_DOCK, ARRIVE_RANGE = 0, 1
ARRIVAL_CODES = dict(zip(ARRIVALS, (ARRIVE_DOCK, ARRIVE_RANGE), strict=True))
# how a robot passes a robot ahead (`robot.behaviour.passing`): by the free heading nearest its goal's,
# either side (nearest); or by the free heading nearest its goal's on its left (right) side first
PASS_NEAREST, PASS_LEFT, PASS_RIGHT = 0, 1, -1
PASS_CODES = dict(zip(PASSINGS, (PASS_NEAREST, PASS_LEFT, PASS_RIGHT), strict=True))
BEH_AUTO, BEH_DIRECT, BEH_WALL, BEH_STOP = -1, 0, 1, 2


def build_robots(robot: RobotConfig, speeds_mps: np.ndarray, trial_rows: list[tuple[int, int]],
                 start_poses: np.ndarray) -> np.ndarray:
    """ROBOT records for the robots of trials whose rows are `trial_rows` [(first, last), ...]."""
    odo = robot.odometry
    robots = np.zeros(len(start_poses), dtype=ROBOT)
    robots["radius_m"] = robot.radius_m
    robots["top_speed_mps"] = speeds_mps
    robots["turn_rate_radps"] = robot.turn_rate_radps
    robots["odo_trans_per_sqrt_m"] = odo.trans_noise_per_sqrt_m
    robots["odo_rot_per_sqrt_m"] = odo.rot_noise_per_sqrt_m
    robots["odo_rot_per_sqrt_rad"] = odo.rot_noise_per_sqrt_rad
    for b, (first, last) in enumerate(trial_rows):
        robots["trial"][first:last] = b
        robots["first"][first:last] = first
        robots["last"][first:last] = last
    robots["alive"] = True
    robots["forced"] = BEH_AUTO
    robots["target"] = -1
    robots["last_target"] = -1
    robots["best_dist_m"] = np.inf
    for i, name in enumerate(("x_m", "y_m", "heading_rad")):
        robots[f"est_{name}"] = start_poses[:, i]  # robots start localised
        robots[f"prev_{name}"] = start_poses[:, i]
    return robots


def build_params(robot: RobotConfig, arena: Arena, dt_s: float, camera_on: bool) -> np.void:
    """The PARAMS record from the robot's settings, the arena and the control period."""
    laser, cam, beh, dock = robot.laser, robot.camera, robot.behaviour, robot.dock
    p = np.zeros((), dtype=PARAMS)
    p["dt_s"] = dt_s
    p["arena_width_m"], p["arena_height_m"] = arena.width_m, arena.height_m
    for key in ("avoid_dist_m", "stop_dist_m", "arrive_dist_m", "wall_dist_m", "visible_margin_m",
                "relocalise_dist_m", "progress_m"):
        p[key] = getattr(beh, key)
    p["arrival"] = ARRIVAL_CODES[beh.arrival]
    p["read_range_m"] = beh.read_range_m
    p["pass_side"] = PASS_CODES[beh.passing]
    p["stall_limit_s"], p["escape_duration_s"] = beh.stall_s, beh.escape_s
    p["laser_range_m"] = laser.range_m
    p["barcode_width_m"] = arena.barcode_width_m
    p["camera_on"] = camera_on
    p["camera_half_fov_rad"] = math.radians(float(cam.fov_deg)) / 2
    p["camera_range_m"] = cam.range_m
    p["marking_sector_rad"] = math.radians(float(cam.side_sector_deg))
    p["dock_lateral_tol_m"] = dock.lateral_tol_m
    p["dock_heading_tol_rad"] = math.radians(float(dock.heading_tol_deg))
    p["dock_approach_m"] = dock.approach_m
    p["dwell_s"] = dock.dwell_s
    p["backout_m"] = dock.backout_m
    p["occupied_m"] = dock.occupied_m
    p["hold_m"] = dock.occupied_m + dock.hold_margin_m
    p["patience_s"] = dock.patience_s
    return p[()]


def build_arena(arena: Arena) -> ArenaGeometry:
    """The kernel's view of an arena: target records and interior walls."""
    targets = np.zeros(len(arena.targets), dtype=TARGET)
    targets["x_m"], targets["y_m"] = arena.target_xy.T
    targets["nx"], targets["ny"] = arena.target_normals.T
    targets["barcode"] = arena.target_barcodes
    targets["wall"] = arena.target_wall
    seg = arena.target_segments
    for i, name in enumerate(("x1_m", "y1_m", "x2_m", "y2_m")):
        targets[name] = seg[:, i]
    targets["half_width_m"] = 0.5 * np.hypot(seg[:, 2] - seg[:, 0], seg[:, 3] - seg[:, 1])
    # Python's math.atan2 is the C library's, as the kernels' is: the same number to the last bit
    targets["facing_rad"] = [math.atan2(-t["ny"], -t["nx"]) for t in targets]
    return ArenaGeometry(targets, np.ascontiguousarray(arena.walls[N_OUTER_WALLS:]))


def build_laser(fov_deg: float, n_rays: int) -> Laser:
    """Rays evenly over the field of view, with their cosines and sines."""
    return laser_from_angles(ray_angles(fov_deg, n_rays))


def laser_from_angles(angle_rad: np.ndarray) -> Laser:
    """A `Laser` with rays at `angle_rad` (relative to the heading, evenly spaced, ascending): their
    cosines and sines, both numpy's and the C library's, and the fan's spacing, half-width and
    whether it closes round the robot."""
    ang = np.asarray(angle_rad, dtype=np.float64)
    n = len(ang)
    spacing = float(ang[n - 1] - ang[0]) / (n - 1) if n > 1 else 1.0
    return Laser(ang, np.cos(ang), np.sin(ang), np.array([math.cos(a) for a in ang]),
                 np.array([math.sin(a) for a in ang]), 1.0 / spacing,
                 float(max(abs(ang[0]), abs(ang[n - 1]))),
                 n > 1 and abs(n * spacing - 2.0 * math.pi) < 1e-9)  # evenly round, as ray_angles makes it


def empty_scan(n_robots: int, n_rays: int) -> Scan:
    """The readings before the first scan, one row per robot: ranges and kinds 0, no hit id, no
    robot in view."""
    return Scan(np.zeros((n_robots, n_rays)), np.zeros((n_robots, n_rays), dtype=np.int8),
                np.full((n_robots, n_rays), -1, dtype=np.int32), np.tile(np.array([0, 0, 0, -1]), (n_robots, 1)),
                np.zeros((n_robots, 2)))


def empty_work(n_robots: int, n_rays: int) -> Work:
    """Scratch space for a batch of `n_robots` robots with `n_rays` rays each."""
    return Work(np.zeros(n_rays), np.zeros(n_rays), np.zeros(n_rays, dtype=np.bool_),
                np.zeros(n_robots, dtype=np.int64))
