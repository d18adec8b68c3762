"""Sensing kernels (tavc_cli.sim.sensors) on small hand-made worlds.

The laser is checked against hand geometry and against pymunk's own segment
queries; the camera against the marking rule in the module docstring; odometry
against the random-walk growth of its error.
"""

import math

import numpy as np
import pymunk
import pytest
import yaml

from tavc_cli.behaviours.layout import PARAMS, ROBOT, ArenaGeometry, build_arena, empty_scan, laser_from_angles
from tavc_cli.config import find_conf_dir
from tavc_cli.settings import ArenaConfig, from_mapping
from tavc_cli.sim.arena import N_OUTER_WALLS, arena_from_config
from tavc_cli.sim.sensors import (
    HIT_NONE,
    HIT_ROBOT,
    HIT_TARGET,
    HIT_WALL,
    camera_nearest,
    cast_laser,
    markings_visible,
    odometry_update,
    ray_angles,
    wrap_angle,
)

RADIUS_M = 0.22
BOTTOM, RIGHT, TOP, LEFT = 0, 1, 2, 3  # outer wall indices as arena_from_config builds them


@pytest.fixture(scope="module")
def one_circuit():
    """The 8 x 6 m arena: source (bar-code 1) at (0, 3), sink (bar-code 2) at (8, 3)."""
    with open(find_conf_dir() / "arena" / "one_circuit.yaml") as fh:
        return arena_from_config(from_mapping(ArenaConfig, yaml.safe_load(fh)))


def _robots(poses, alive=None, lo=0, hi=None):
    """ROBOT records of robots at `poses`, rows lo..hi one trial."""
    n = len(poses)
    robots = np.zeros(n, dtype=ROBOT)
    robots["radius_m"] = RADIUS_M
    robots["alive"] = True if alive is None else np.asarray(alive, dtype=np.bool_)
    robots["first"], robots["last"] = lo, n if hi is None else hi
    return robots


def _params(**values):
    params = np.zeros((), dtype=PARAMS)
    for key, value in values.items():
        params[key] = value
    return params[()]


def _laser(arena, poses, ray_ang, *, r=0, lo=0, hi=None, alive=None, max_range=8.0, walls=None):
    """Cast robot r's rays; returns (range, kind, id, points in the robot's frame) of that robot."""
    pose = np.asarray(poses, dtype=np.float64)
    ray_ang = np.asarray(ray_ang, dtype=np.float64)
    laser = laser_from_angles(ray_ang)
    geometry = build_arena(arena)
    if walls is not None:
        geometry = geometry._replace(inner_walls=np.ascontiguousarray(np.asarray(walls)[N_OUTER_WALLS:]))
    scan = empty_scan(len(pose), len(ray_ang))
    params = _params(laser_range_m=max_range, arena_width_m=arena.width_m, arena_height_m=arena.height_m)
    cast_laser(r, _robots(pose, alive, lo, hi), pose, laser, geometry, params, scan)
    pts = scan.range_m[r][:, None] * np.column_stack([laser.cos, laser.sin])
    return scan.range_m[r], scan.kind[r], scan.hit_id[r], pts


# --- laser: hand geometry ----------------------------------------------------------------------

# ray_angles(180, 5) = -90, -45, 0, 45, 90 degrees
RAY_M90, RAY_M45, RAY_0, RAY_P45, RAY_P90 = range(5)


def test_ray_ahead_reads_the_sink_barcode_in_front_of_its_wall(one_circuit):
    rng, kind, ident, _ = _laser(one_circuit, [(2.0, 3.0, 0.0)], ray_angles(180.0, 5))
    # the bar-code hangs 1 mm in front of the wall at x = 8: range = 8 - 2 - 0.001
    assert kind[RAY_0] == HIT_TARGET
    assert ident[RAY_0] == 2
    assert rng[RAY_0] == pytest.approx(8.0 - 2.0 - 0.001, abs=1e-12)


def test_side_and_diagonal_rays_read_the_walls(one_circuit):
    rng, kind, ident, pts = _laser(one_circuit, [(2.0, 3.0, 0.0)], ray_angles(180.0, 5))
    # +90 deg: top wall y = 6, range 6 - 3 = 3; -90 deg: bottom wall y = 0, range 3
    assert (kind[RAY_P90], ident[RAY_P90]) == (HIT_WALL, TOP)
    assert rng[RAY_P90] == pytest.approx(3.0, abs=1e-12)
    assert (kind[RAY_M90], ident[RAY_M90]) == (HIT_WALL, BOTTOM)
    assert rng[RAY_M90] == pytest.approx(3.0, abs=1e-12)
    # +-45 deg: 3 m up (or down) and 3 m across, to (5, 6) / (5, 0): range 3 * sqrt(2)
    for j, wall in ((RAY_P45, TOP), (RAY_M45, BOTTOM)):
        assert (kind[j], ident[j]) == (HIT_WALL, wall)
        assert rng[j] == pytest.approx(3.0 * math.sqrt(2.0), abs=1e-12)
    # hit points are in the robot's frame: the +90 deg hit is 3 m to its left
    np.testing.assert_allclose(pts[RAY_P90], [0.0, 3.0], atol=1e-12)
    np.testing.assert_allclose(pts[RAY_P45], [3.0, 3.0], atol=1e-12)


def test_rays_turn_with_the_robot(one_circuit):
    # heading +90 deg: the straight-ahead ray now points at the top wall, 3 m away,
    # and the -90 deg ray points along +x at the sink bar-code, 8 - 2 - 0.001 away
    rng, kind, ident, _ = _laser(one_circuit, [(2.0, 3.0, math.pi / 2)], ray_angles(180.0, 5))
    assert (kind[RAY_0], ident[RAY_0]) == (HIT_WALL, TOP)
    assert rng[RAY_0] == pytest.approx(3.0, abs=1e-12)
    assert (kind[RAY_M90], ident[RAY_M90]) == (HIT_TARGET, 2)
    assert rng[RAY_M90] == pytest.approx(5.999, abs=1e-12)


def test_the_scan_keeps_the_frame_it_was_cast_in(one_circuit):
    # the wheel commands are turned into the world frame with these very numbers
    heading = 37.3  # a robot that has turned six times round
    laser = laser_from_angles(ray_angles(180.0, 5))
    pose = np.array([(2.0, 3.0, heading)])
    scan = empty_scan(1, 5)
    params = _params(laser_range_m=8.0, arena_width_m=one_circuit.width_m, arena_height_m=one_circuit.height_m)
    cast_laser(0, _robots(pose, None, 0, None), pose, laser, build_arena(one_circuit), params, scan)
    assert scan.heading_cs[0].tolist() == [math.cos(heading), math.sin(heading)]


@pytest.mark.parametrize(
    ("aim_y", "expected_kind", "expected_id"),
    [
        (3.29, HIT_TARGET, 2),  # inside the bar-code's stretch y in [2.7, 3.3]
        (3.305, HIT_WALL, RIGHT),  # just past its end (crosses x = 7.999 at y = 3.30495)
        (4.5, HIT_WALL, RIGHT),  # half-way between bar-code and corner
    ],
)
def test_ray_between_barcode_and_corner_reads_the_wall(
    one_circuit, aim_y, expected_kind, expected_id
):
    # one ray straight ahead, the robot at (2, 3) heading for the point (8, aim_y)
    heading = math.atan2(aim_y - 3.0, 6.0)
    rng, kind, ident, _ = _laser(one_circuit, [(2.0, 3.0, heading)], [0.0])
    assert (kind[0], ident[0]) == (expected_kind, expected_id)
    if expected_kind == HIT_WALL:
        # the wall x = 8 is 6 m across: range 6 / cos(heading) = hypot(6, aim_y - 3)
        assert rng[0] == pytest.approx(math.hypot(6.0, aim_y - 3.0), abs=1e-12)
    else:
        # the bar-code line x = 7.999 is 5.999 m across
        assert rng[0] == pytest.approx(5.999 / math.cos(heading), abs=1e-12)


def test_robot_in_the_way_is_read_with_its_index(one_circuit):
    poses = [(2.0, 3.0, 0.0), (4.0, 3.0, 1.0)]
    rng, kind, ident, pts = _laser(one_circuit, poses, ray_angles(180.0, 5))
    # the disc of radius 0.22 centred 2 m ahead: its near edge at 4 - 2 - 0.22 = 1.78 m
    assert (kind[RAY_0], ident[RAY_0]) == (HIT_ROBOT, 1)
    assert rng[RAY_0] == pytest.approx(4.0 - 2.0 - RADIUS_M, abs=1e-12)
    np.testing.assert_allclose(pts[RAY_0], [1.78, 0.0], atol=1e-12)
    # the side rays miss it and still read the walls
    assert (kind[RAY_P90], kind[RAY_M90]) == (HIT_WALL, HIT_WALL)


def test_robot_off_centre_is_hit_where_the_ray_meets_its_rim(one_circuit):
    # other robot at (4, 3.1): the ray along y = 3 passes 0.1 m from its centre and
    # enters the disc at x = 4 - sqrt(0.22^2 - 0.1^2) = 4 - sqrt(0.0384)
    rng, kind, ident, _ = _laser(one_circuit, [(2.0, 3.0, 0.0), (4.0, 3.1, 0.0)], [0.0])
    assert (kind[0], ident[0]) == (HIT_ROBOT, 1)
    assert rng[0] == pytest.approx(2.0 - math.sqrt(0.0384), abs=1e-12)


def test_broken_and_other_trials_robots_are_invisible(one_circuit):
    poses = [(2.0, 3.0, 0.0), (4.0, 3.0, 0.0)]
    # robot 1 broken down: the ray reads the bar-code behind where it stood
    _, kind, ident, _ = _laser(one_circuit, poses, [0.0], alive=[True, False])
    assert (kind[0], ident[0]) == (HIT_TARGET, 2)
    # robot 1 belongs to another trial (rows lo..hi-1 = 0..0 share robot 0's world)
    _, kind, ident, _ = _laser(one_circuit, poses, [0.0], lo=0, hi=1)
    assert (kind[0], ident[0]) == (HIT_TARGET, 2)


def test_nothing_within_max_range_reads_none_at_max_range(one_circuit):
    # max range 1 m from (2, 3): the nearest thing ahead is 5.999 m away, the side walls 3 m
    rng, kind, ident, pts = _laser(
        one_circuit, [(2.0, 3.0, 0.0), (4.0, 3.0, 0.0)], ray_angles(180.0, 5), max_range=1.0
    )
    assert np.all(kind == HIT_NONE)
    assert np.all(ident == -1)
    np.testing.assert_array_equal(rng, 1.0)
    np.testing.assert_allclose(pts[RAY_P90], [0.0, 1.0], atol=1e-12)


def test_interior_wall_blocks_the_barcode(one_circuit):
    # an interior wall (row 4) across the path at x = 5: range 5 - 2 = 3
    walls = np.vstack([one_circuit.walls, [[5.0, 2.0, 5.0, 4.0]]])
    rng, kind, ident, _ = _laser(one_circuit, [(2.0, 3.0, 0.0)], [0.0], walls=walls)
    assert (kind[0], ident[0]) == (HIT_WALL, 4)
    assert rng[0] == pytest.approx(3.0, abs=1e-12)


# --- laser: against pymunk's own segment queries ---------------------------------------------


def _random_world(rng, code_m=0.6):
    """An arena mapping with random size, targets (bar-codes `code_m` wide) and interior walls,
    and robot poses in it."""
    width, height = rng.uniform(4.0, 12.0), rng.uniform(4.0, 10.0)
    targets = []
    for k, side in enumerate(rng.permutation(4)):  # one per wall, so no two overlap
        # bar-codes (0.6 m wide) kept 0.5 m from the corners, as on a real arena
        along = rng.uniform(0.5, (width if side in (0, 2) else height) - 0.5)
        x, y = {0: (along, 0.0), 1: (width, along), 2: (along, height), 3: (0.0, along)}[side]
        targets.append(
            {
                "name": f"t{k}",
                "kind": "source" if k % 2 == 0 else "sink",
                "barcode": 10 + k,
                "x": float(x),
                "y": float(y),
            }
        )
    walls = []
    for _ in range(rng.integers(0, 3)):
        x1, x2 = rng.uniform(0.5, width - 0.5, 2)
        y1, y2 = rng.uniform(0.5, height - 0.5, 2)
        walls.append([float(x1), float(y1), float(x2), float(y2)])
    spec = {
        "name": "random",
        "width_m": float(width),
        "height_m": float(height),
        "barcode_width_m": float(code_m),
        "walls": walls,
        "targets": targets,
        "circuits": [{"name": "c", "source": "t0", "sink": "t1"}],
    }
    poses = []
    while len(poses) < 6:
        x, y = rng.uniform(0.3, width - 0.3), rng.uniform(0.3, height - 0.3)
        if all(math.hypot(x - p[0], y - p[1]) > 2 * RADIUS_M + 0.01 for p in poses):
            poses.append((x, y, rng.uniform(-math.pi, math.pi)))
    return arena_from_config(from_mapping(ArenaConfig, spec)), np.array(poses)


def _pymunk_space(arena, poses):
    """Walls and bar-codes as static segments, robots as discs, each robot in its own group."""
    space = pymunk.Space()
    labels = {}
    for w, (x1, y1, x2, y2) in enumerate(arena.walls):
        shape = pymunk.Segment(space.static_body, (x1, y1), (x2, y2), 0.0)
        space.add(shape)
        labels[shape] = (HIT_WALL, w)
    for seg, code in zip(arena.target_segments, arena.target_barcodes, strict=True):
        shape = pymunk.Segment(space.static_body, tuple(seg[:2]), tuple(seg[2:]), 0.0)
        space.add(shape)
        labels[shape] = (HIT_TARGET, int(code))
    for i, (x, y, _) in enumerate(poses):
        shape = pymunk.Circle(space.static_body, RADIUS_M, offset=(x, y))
        shape.filter = pymunk.ShapeFilter(group=i + 1)
        space.add(shape)
        labels[shape] = (HIT_ROBOT, i)
    return space, labels


def _near_a_code(rng, arena, poses):
    """The same robots, the first moved to within a metre of a random bar-code (clear of the others)."""
    t = arena.targets[rng.integers(len(arena.targets))]
    for _ in range(1000):
        d, lateral = rng.uniform(0.25, 1.0), rng.uniform(-0.8, 0.8)
        x = t.x + t.normal[0] * d - t.normal[1] * lateral
        y = t.y + t.normal[1] * d + t.normal[0] * lateral
        if (0.25 < x < arena.width_m - 0.25 and 0.25 < y < arena.height_m - 0.25
                and all(math.hypot(x - p[0], y - p[1]) > 2 * RADIUS_M + 0.01 for p in poses[1:])):
            poses = poses.copy()
            poses[0] = (x, y, rng.uniform(-math.pi, math.pi))
            return poses
    return poses


@pytest.mark.parametrize("fov_deg, n_rays, code_m", [
    (180.0, 31, 0.6), (360.0, 72, 0.6),
    # fans short of the full circle, whose windows must not wrap round at +-pi, and one whose
    # span plus a ray's spacing passes 360 degrees without being a full circle
    (270.0, 61, 0.6), (340.0, 69, 0.6), (358.0, 60, 0.6),
    (180.0, 31, 2.5),  # bar-codes wider than a robot is near them
])
def test_laser_agrees_with_pymunk_segment_queries(fov_deg, n_rays, code_m):
    """The angular-window and exit-wall shortcuts must not change what a ray hits."""
    rng = np.random.default_rng(7)
    ray_ang = ray_angles(fov_deg, n_rays)
    max_range = 8.0
    n_checked = {HIT_NONE: 0, HIT_WALL: 0, HIT_ROBOT: 0, HIT_TARGET: 0}
    for world in range(40):
        arena, poses = _random_world(rng, code_m)
        if world % 2:
            poses = _near_a_code(rng, arena, poses)
        space, labels = _pymunk_space(arena, poses)
        for r in range(len(poses)):
            got_range, got_kind, got_id, _ = _laser(arena, poses, ray_ang, r=r, max_range=max_range)
            px, py, th = poses[r]
            own = pymunk.ShapeFilter(group=r + 1)  # the ray starts inside the robot's own disc
            for j, a in enumerate(ray_ang):
                end = (px + max_range * math.cos(th + a), py + max_range * math.sin(th + a))
                hit = space.segment_query_first((px, py), end, 0.0, own)
                if hit is None:
                    expected = (max_range, HIT_NONE, -1)
                else:
                    expected = (hit.alpha * max_range, *labels[hit.shape])
                assert got_range[j] == pytest.approx(expected[0], abs=1e-9)
                assert (got_kind[j], got_id[j]) == expected[1:]
                n_checked[expected[1]] += 1
    # the random worlds exercise every kind of reading
    assert all(count > 20 for count in n_checked.values()), n_checked


# --- camera ------------------------------------------------------------------------------------

# Marking rule (sensors module docstring), a ship's lanterns: with the observer's bearing b in
# the observed robot's frame, red shows for 0 <= b <= S, green for -S <= b <= 0, yellow for
# |b| >= S, with S = robot.camera.side_sector_deg = 112.5 deg.
SIDE_SECTOR_DEG = 112.5


def _marks(obs_xy, o_pose=(0.0, 0.0, 0.0), sector_deg=SIDE_SECTOR_DEG):
    out = np.zeros((1, 4), dtype=np.int64)
    markings_visible(obs_xy[0], obs_xy[1], *o_pose, math.radians(sector_deg), out, 0)
    return tuple(int(v) for v in out[0, :3])  # (red = left, green = right, yellow = rear)


R2 = math.sqrt(2.0)


@pytest.mark.parametrize(
    ("where", "obs_xy", "expected"),
    [
        ("behind", (-2.0, 0.0), (0, 0, 1)),  # b = 180: only the rear sector
        ("left", (0.0, 2.0), (1, 0, 0)),  # b = 90: inside [0, 112.5], outside |b| >= 112.5
        ("right", (0.0, -2.0), (0, 1, 0)),  # b = -90
        ("ahead, a little left", (2.0, 0.1), (1, 0, 0)),  # b = 2.9
        ("dead ahead", (2.0, 0.0), (1, 1, 0)),  # b = 0: both side lights, no yellow
        ("rear-left", (-R2, R2), (0, 0, 1)),  # b = 135 >= 112.5: astern
        ("just abaft the left beam", (-0.5, 2.0), (1, 0, 0)),  # b = 104.0 <= 112.5
    ],
)
def test_markings_show_like_ship_lanterns(where, obs_xy, expected):
    assert _marks(obs_xy) == expected


def test_oncoming_robot_shows_no_yellow_and_a_leading_robot_only_yellow():
    # the distinction the section 1.4 learners use: a robot coming toward the observer
    # shows red and/or green but never yellow; one moving away shows yellow only
    for b_deg in np.linspace(-60.0, 60.0, 13):
        b = math.radians(b_deg)
        red, green, yellow = _marks((2 * math.cos(b), 2 * math.sin(b)))
        assert yellow == 0 and red + green >= 1
    for b_deg in np.linspace(120.0, 240.0, 13):
        b = math.radians(b_deg)
        assert _marks((2 * math.cos(b), 2 * math.sin(b))) == (0, 0, 1)


def test_markings_turn_with_the_observed_robot():
    # observed robot heading +90 deg: its rear now faces -y, its left faces -x
    assert _marks((0.0, -2.0), o_pose=(0.0, 0.0, math.pi / 2)) == (0, 0, 1)
    assert _marks((-2.0, 0.0), o_pose=(0.0, 0.0, math.pi / 2)) == (1, 0, 0)


def _camera(poses, alive=None, walls=None, fov_deg=80.0, range_m=6.0, sector_deg=SIDE_SECTOR_DEG):
    pose = np.asarray(poses, dtype=np.float64)
    n = len(pose)
    alive = np.ones(n, dtype=np.bool_) if alive is None else np.asarray(alive, dtype=np.bool_)
    walls = (
        np.array(
            [[-10, -10, 10, -10], [10, -10, 10, 10], [10, 10, -10, 10], [-10, 10, -10, -10]],
            dtype=np.float64,
        )
        if walls is None
        else np.asarray(walls, dtype=np.float64)
    )
    geometry = ArenaGeometry(np.zeros(0), np.ascontiguousarray(walls[N_OUTER_WALLS:]))
    params = _params(camera_on=True, camera_half_fov_rad=math.radians(fov_deg) / 2, camera_range_m=range_m,
                     marking_sector_rad=math.radians(sector_deg))
    scan = empty_scan(n, 1)
    camera_nearest(0, _robots(pose, alive), pose, geometry, params, scan)
    out = scan.camera
    return tuple(int(v) for v in out[0])


def test_camera_sees_the_nearest_robot_in_its_field_of_view():
    poses = [
        (0.0, 0.0, 0.0),  # the observer, looking along +x with a 80 deg (+-40) field of view
        (3.0, 0.5, math.pi),  # 3.04 m at 9.5 deg: in view, facing the observer
        (1.0, 1.5, 0.0),  # 1.80 m but at 56.3 deg: outside the field of view
        (5.0, 0.0, 0.0),  # 5 m straight ahead, behind robot 1
    ]
    red, green, yellow, seen = _camera(poses)
    assert seen == 1
    # robot 1 heads back toward the observer: in its frame the camera bears
    # atan2(-0.5, -3) - 180 deg = 9.46 deg, in the red sector [0, 112.5] only
    assert (red, green, yellow) == (1, 0, 0)


def test_camera_ignores_robots_out_of_range_broken_or_behind_walls():
    poses = [(0.0, 0.0, 0.0), (3.0, 0.0, 0.0), (5.0, 0.0, 0.0)]
    # robot 1 shows the observer its rear: yellow
    assert _camera(poses) == (0, 0, 1, 1)
    # robot 1 broken down: robot 2 is the nearest in view
    assert _camera(poses, alive=[True, False, True])[3] == 2
    # range 2.5 m: nothing in range
    assert _camera(poses, range_m=2.5) == (0, 0, 0, -1)
    # an interior wall at x = 2 hides both
    walls = [
        [-10, -10, 10, -10],
        [10, -10, 10, 10],
        [10, 10, -10, 10],
        [-10, 10, -10, -10],
        [2.0, -1.0, 2.0, 1.0],
    ]
    assert _camera(poses, walls=walls) == (0, 0, 0, -1)


# --- odometry ----------------------------------------------------------------------------------


def _drive(truth_steps, sigmas, n_rows, seed=0):
    """Feed each row the same true motion (a list of poses) with independent noise.

    Returns (true final pose, (n_rows, 3) estimates).
    """
    rng = np.random.default_rng(seed)
    start = np.asarray(truth_steps[0], dtype=np.float64)
    robots = np.zeros(n_rows, dtype=ROBOT)
    robots["odo_trans_per_sqrt_m"], robots["odo_rot_per_sqrt_m"], robots["odo_rot_per_sqrt_rad"] = sigmas
    for i, name in enumerate(("x_m", "y_m", "heading_rad")):
        robots[f"est_{name}"] = robots[f"prev_{name}"] = start[i]
    pose = np.tile(start, (n_rows, 1))
    for step in truth_steps[1:]:
        pose[:] = step
        noise = rng.standard_normal((n_rows, 3))
        for r in range(n_rows):
            odometry_update(r, robots, pose, noise)
    est = np.column_stack([robots["est_x_m"], robots["est_y_m"], robots["est_heading_rad"]])
    return pose[0], est


N_ROWS = 4000
D_M = 25  # 25 steps of 1 m
# A sample std of N normal draws has relative standard error ~ 1 / sqrt(2 (N - 1)):
# 1 / sqrt(7998) = 1.12 %. Five standard errors: 5.6 %.
STD_RTOL = 5.0 / math.sqrt(2 * (N_ROWS - 1))


def test_std_tolerance_by_hand():
    assert STD_RTOL == pytest.approx(0.0559, abs=1e-4)


def test_distance_error_grows_with_the_square_root_of_distance():
    straight = [(float(k), 0.0, 0.0) for k in range(D_M + 1)]
    truth, est = _drive(straight, (0.05, 0.0, 0.0), N_ROWS)
    along = est[:, 0] - truth[0]
    # per metre: N(0, 0.05^2); after 25 m: std 0.05 * sqrt(25) = 0.25 m
    assert along.std(ddof=1) == pytest.approx(0.25, rel=STD_RTOL)
    assert abs(along.mean()) < 4 * 0.25 / math.sqrt(N_ROWS)  # unbiased: 4 standard errors
    # no heading noise: the estimate stays on the line and keeps its heading
    np.testing.assert_array_equal(est[:, 1], 0.0)
    np.testing.assert_array_equal(est[:, 2], 0.0)


def test_heading_error_grows_with_the_square_root_of_distance():
    straight = [(float(k), 0.0, 0.0) for k in range(D_M + 1)]
    _, est = _drive(straight, (0.0, 0.02, 0.0), N_ROWS)
    # heading error std 0.02 rad per sqrt(m): after 25 m, 0.02 * 5 = 0.1 rad
    assert est[:, 2].std(ddof=1) == pytest.approx(0.1, rel=STD_RTOL)


def test_heading_error_grows_with_the_square_root_of_angle_turned():
    # 20 quarter-radian turns on the spot: 5 rad turned in all
    turning = [(1.0, 1.0, 0.25 * k) for k in range(21)]
    truth, est = _drive(turning, (0.0, 0.0, 0.04), N_ROWS)
    err = (est[:, 2] - truth[2] + math.pi) % (2 * math.pi) - math.pi
    # std 0.04 rad per sqrt(rad): after 5 rad, 0.04 * sqrt(5) = 0.08944 rad
    assert err.std(ddof=1) == pytest.approx(0.04 * math.sqrt(5.0), rel=STD_RTOL)
    # turning on the spot measures no distance
    np.testing.assert_array_equal(est[:, :2], 1.0)


def test_noiseless_odometry_tracks_the_truth_exactly():
    # an arc: 20 steps, each 0.3 m forward while turning 0.1 rad (chord along the mean heading)
    poses = [(0.5, 0.5, 0.2)]
    for _ in range(20):
        x, y, th = poses[-1]
        mid = th + 0.05
        poses.append((x + 0.3 * math.cos(mid), y + 0.3 * math.sin(mid), th + 0.1))
    truth, est = _drive(poses, (0.0, 0.0, 0.0), 3)
    np.testing.assert_allclose(est, np.tile(truth, (3, 1)), atol=1e-12)


def test_sideways_shove_goes_unmeasured():
    # heading 0, pushed 1 m along +y: wheels measure ds = 0, so the estimate stays put
    # (and with |ds| = 0 no noise is added either)
    _, est = _drive([(2.0, 2.0, 0.0), (2.0, 3.0, 0.0)], (0.05, 0.05, 0.05), 10)
    np.testing.assert_array_equal(est, np.tile([2.0, 2.0, 0.0], (10, 1)))


# --- the angular windows' arctangent -----------------------------------------------------------


def test_fast_atan2_stays_well_inside_the_window_margin():
    from tavc_cli.sim.sensors import _WINDOW_MARGIN_RAD, _fast_atan2

    for (y, x), expected in {(0.0, 1.0): 0.0, (1.0, 0.0): math.pi / 2, (0.0, -1.0): math.pi,
                             (-1.0, 0.0): -math.pi / 2, (1.0, 1.0): math.pi / 4}.items():
        assert _fast_atan2(y, x) == pytest.approx(expected, abs=_WINDOW_MARGIN_RAD / 4)
    ys, xs = np.random.default_rng(0).normal(size=(2, 20_000))
    worst = max(abs(_fast_atan2(y, x) - math.atan2(y, x)) for y, x in zip(ys, xs, strict=True))
    assert worst < _WINDOW_MARGIN_RAD / 4


def test_wrap_angle_is_the_remainder_formula_to_the_last_bit():
    """The wrap skips the remainder for angles already in range; it must give, bit for bit,
    what (a + pi) % 2 pi - pi gives, on both sides of every boundary and far outside."""
    rng = np.random.default_rng(3)
    edges = [0.0, -0.0, math.pi, -math.pi, 2 * math.pi, -2 * math.pi, 3 * math.pi, -3 * math.pi, 5 * math.pi,
             1e-300, -1e-300]
    near = [np.nextafter(e, d) for e in edges for d in (-np.inf, np.inf)]
    # headings that have turned many times: a hair either side of whole turns (less pi), where a
    # quotient rounded to the next integer would give the wrong multiple of 2 pi, and beyond 1e6
    turns = np.concatenate([np.arange(-300, 300), rng.integers(-150_000, 150_000, 2000)]) * 2 * math.pi - math.pi
    around = [np.nextafter(np.nextafter(t, d), d) for t in turns for d in (-np.inf, np.inf)]
    angles = np.concatenate([edges, near, turns, np.nextafter(turns, np.inf), np.nextafter(turns, -np.inf), around,
                             rng.uniform(-4 * math.pi, 4 * math.pi, 20000), rng.uniform(-1e6, 1e6, 20000),
                             rng.uniform(-1e9, 1e9, 1000), [np.inf, -np.inf, np.nan]])
    for a in angles.tolist():
        expected = (a + math.pi) % (2.0 * math.pi) - math.pi  # Python's float remainder
        got = wrap_angle(a)
        same = np.array([got]).tobytes() == np.array([expected]).tobytes()
        assert same or (math.isnan(got) and math.isnan(expected)), a
        if math.isfinite(a):
            assert -math.pi <= got <= math.pi  # pi itself where x just below 2 pi rounds up, as before
