"""Moving toward a goal among obstacles: free-path tests on the laser's hit points, steering
with detours, wall following, the "target should be visible" check, and the escape rule
for dead ends. Compiled with numba; everything works on one robot's row of the bundles
of `behaviours.layout` (`robots`, `scan`, `laser`, `params`).
"""

from __future__ import annotations

import math

import numpy as np

from tavc_cli.behaviours.layout import MODE_APPROACH, MODE_ESCAPE, PASS_NEAREST
from tavc_cli.kernel import kernel
from tavc_cli.sim.sensors import HIT_ROBOT, HIT_TARGET, HIT_WALL, wrap_angle
from tavc_cli.vocabulary import ACT_AVOID, ACT_DRIVE

_CORRIDOR_MARGIN_M = 0.05
# a robot in view within this angle of the goal's bearing, and within reach, is one to pass
_AHEAD_RAD = math.pi / 4


@kernel
def near_points(r, reach, half, scan, laser, skip_barcode, skip_wall, xs, ys):
    """Robot r's laser hit points (robot frame) that could stop its disc, widened to half-width
    `half`, within `reach` metres along any heading: into xs, ys; returns how many.

    A point at range rho >= reach + 3 half blocks no heading before reach + half (the
    disc's gap to it is at least sqrt(rho^2 - half^2) - half), so it is left out; so are
    one bar-code and one outer wall that a robot drives up to on purpose.
    """
    kinds, ids, ranges = scan.kind, scan.hit_id, scan.range_m
    limit = reach + 3.0 * half
    m = 0
    for i in range(ranges.shape[1]):
        kind, ident = kinds[r, i], ids[r, i]
        if ranges[r, i] >= limit or (kind == HIT_TARGET and ident == skip_barcode) or (
                kind == HIT_WALL and ident == skip_wall):
            continue
        xs[m] = ranges[r, i] * laser.cos[i]
        ys[m] = ranges[r, i] * laser.sin[i]
        m += 1
    return m


@kernel(inline="always")
def _gap(x, y, ux, uy, half):
    """How far a disc of half-width `half` travels along (ux, uy) before it touches the point
    (x, y) (robot frame), or inf if it never does."""
    along = x * ux + y * uy
    lateral = abs(x * uy - y * ux)
    if along > 0.0 and lateral < half:
        return along - math.sqrt(half * half - lateral * lateral)
    return np.inf


@kernel
def free_along(ux, uy, half, xs, ys, m):
    """How far a disc of half-width `half` can travel along the heading (ux, uy) (robot frame)
    before it touches one of the first m points of xs, ys. With points from `near_points`:
    exact below the reach they were gathered for, at least reach + half beyond it (inf when
    nothing is near)."""
    best = np.inf
    for i in range(m):
        best = min(best, _gap(xs[i], ys[i], ux, uy, half))
    return best


@kernel
def blocked_before(ux, uy, half, xs, ys, m, need):
    """Whether `free_along` would be below `need`: stops at the first point that makes it so."""
    for i in range(m):
        if _gap(xs[i], ys[i], ux, uy, half) < need:
            return True
    return False


@kernel
def free_distance(r, heading, radius, scan, laser, skip_barcode, skip_wall, reach, work):
    """How far robot r can drive along `heading` (robot frame) before its disc, widened by a
    small margin, touches a laser hit point (ignoring one bar-code, and the outer wall
    `skip_wall` that a docking robot drives up to on purpose): exact below `reach`,
    at least `reach` beyond."""
    half = radius + _CORRIDOR_MARGIN_M
    m = near_points(r, reach, half, scan, laser, skip_barcode, skip_wall, work.xs, work.ys)
    return free_along(math.cos(heading), math.sin(heading), half, work.xs, work.ys, m)


@kernel
def robot_ahead(r, bearing, reach, scan, laser):
    """Whether robot r's laser shows another robot within `reach` metres and `_AHEAD_RAD` of the
    bearing `bearing` (robot frame)."""
    for j in range(scan.range_m.shape[1]):
        if (scan.kind[r, j] == HIT_ROBOT and scan.range_m[r, j] < reach
                and abs(wrap_angle(laser.angle_rad[j] - bearing)) < _AHEAD_RAD):
            return True
    return False


@kernel
def steer_to(r, bearing, dist, own_barcode, robots, scan, laser, params, cmd, work):
    """Head for `bearing` (robot frame), detouring around whatever the laser sees.

    The heading taken is the free direction nearest the goal's: candidates are
    tried outward from the goal bearing, and the first along which the robot's
    disc can travel `need` metres wins. Where the passing reading keeps to one side
    (`pass_side`) and a robot stands ahead, the candidates on that side are tried
    first, all of them, then the other side's. Speed falls as the free distance ahead
    shrinks toward `stop_dist`. Sets the tick's activity to avoiding whenever an
    obstacle bends the path or slows the robot.
    """
    rob = robots[r]
    radius, vmax, wmax = rob.radius_m, rob.top_speed_mps, rob.turn_rate_radps
    avoid, stop = params.avoid_dist_m, params.stop_dist_m
    ray_ang = laser.angle_rad
    n = ray_ang.shape[0]
    fov_half = max(abs(ray_ang[0]), abs(ray_ang[n - 1]))
    rob.activity = ACT_DRIVE
    if abs(bearing) > fov_half:
        # the goal is behind: turn on the spot until it is in view, keeping the
        # direction already chosen while the goal is nearly straight behind (the
        # sign of the bearing flips there from one tick to the next)
        if rob.turn == 0 or abs(bearing) < math.pi - 0.5:
            rob.turn = 1 if bearing > 0 else -1
        cmd[r, 0] = 0.0
        cmd[r, 1] = rob.turn * wmax
        return
    spacing = (ray_ang[n - 1] - ray_ang[0]) / max(n - 1, 1)
    # the robot only has to get to its goal point
    need = min(avoid, max(dist, stop))
    # the free distances below only matter up to max(avoid, stop): beyond, the robot goes full speed
    half = radius + _CORRIDOR_MARGIN_M
    xs, ys = work.xs, work.ys
    m = near_points(r, max(avoid, stop), half, scan, laser, own_barcode, -1, xs, ys)
    heading = np.nan
    cos_bearing = math.cos(bearing)
    heading_cos = cos_bearing  # cos of the heading taken, for the speed below (the same number either way)
    free = free_along(cos_bearing, math.sin(bearing), half, xs, ys, m)
    if free >= need:
        heading = bearing
    else:
        j0 = int(round((bearing - ray_ang[0]) / max(spacing, 1e-9)))
        side = params.pass_side
        if side != PASS_NEAREST and not robot_ahead(r, bearing, avoid + radius, scan, laser):
            side = PASS_NEAREST
        for step in range(1, 2 * n):
            if side == PASS_NEAREST:
                off = (step + 1) // 2 if step % 2 == 1 else -(step // 2)
            else:
                off = side * step if step < n else -side * (step - n + 1)
            j = j0 + off
            if j < 0 or j >= n:
                continue
            ux, uy = laser.heading_cos[j], laser.heading_sin[j]
            if not blocked_before(ux, uy, half, xs, ys, m, need):
                heading, free = ray_ang[j], free_along(ux, uy, half, xs, ys, m)
                heading_cos = ux  # the C library's cos of ray_ang[j] (`layout.laser_from_angles`)
                break
    if np.isnan(heading):
        # boxed in: turn toward the more open side, and keep turning that way
        if rob.turn == 0:
            left, right = 0.0, 0.0
            for j in range(n):
                if ray_ang[j] > 0:
                    left += scan.range_m[r, j]
                else:
                    right += scan.range_m[r, j]
            rob.turn = 1 if left >= right else -1
        cmd[r, 0] = 0.0
        cmd[r, 1] = 0.5 * wmax * rob.turn
        rob.activity = ACT_AVOID
        return
    rob.turn = 0
    ahead = free_along(1.0, 0.0, half, xs, ys, m)  # cos 0, sin 0
    slow = min(1.0, max(0.0, (min(ahead, free) - stop) / max(avoid - stop, 1e-9)))
    if heading != bearing or slow < 1.0:
        rob.activity = ACT_AVOID
    cmd[r, 0] = vmax * slow * max(0.0, heading_cos) ** 2
    cmd[r, 1] = min(wmax, max(-wmax, 2.0 * heading))


@kernel
def wall_follow(r, side, robots, scan, laser, params, cmd, work):
    """Keep a wall at `wall_dist` on `side` (+1 left, -1 right) and move along it."""
    rob = robots[r]
    radius, vmax, wmax = rob.radius_m, rob.top_speed_mps, rob.turn_rate_radps
    wall_d, stop = params.wall_dist_m, params.stop_dist_m
    gap = free_distance(r, 0.0, radius, scan, laser, -999, -1, max(wall_d, stop), work)
    side_d = np.inf
    for j in range(laser.angle_rad.shape[0]):
        a = side * laser.angle_rad[j]
        if math.pi / 4 <= a <= 3 * math.pi / 4:
            side_d = min(side_d, scan.range_m[r, j] - radius)
    if gap < wall_d:
        cmd[r, 0] = 0.0 if gap < stop else 0.3 * vmax
        cmd[r, 1] = -side * wmax
    elif side_d > 2.0 * wall_d:
        # no wall on that side: drive on, curving gently toward it (a 2 m radius), until
        # a wall comes up ahead or alongside
        cmd[r, 0] = vmax
        cmd[r, 1] = side * min(wmax, vmax / 2.0)
    else:
        cmd[r, 0] = vmax
        cmd[r, 1] = min(wmax, max(-wmax, side * 2.0 * (side_d - wall_d)))


@kernel
def should_see_target(r, robots, target, scan, laser, params):
    """Whether the estimated pose says the target's bar-code must be in the laser's view.

    True only where the code would be wide enough to be hit by at least two rays
    and the ray toward it is not blocked by a nearer robot.
    """
    rob = robots[r]
    nx, ny = target.nx, target.ny
    dx, dy = target.x_m - rob.est_x_m, target.y_m - rob.est_y_m
    d = math.sqrt(dx * dx + dy * dy)
    margin = params.visible_margin_m
    if d < 1e-6 or d > params.laser_range_m - margin:
        return False
    ray_ang = laser.angle_rad
    n = ray_ang.shape[0]
    spacing = (ray_ang[n - 1] - ray_ang[0]) / max(n - 1, 1)
    b = wrap_angle(math.atan2(dy, dx) - rob.est_heading_rad)
    if abs(b) > max(abs(ray_ang[0]), abs(ray_ang[n - 1])) - spacing:
        return False
    facing = -(dx * nx + dy * ny) / d  # cosine of the incidence on the bar-code
    if facing < 0.25 or params.barcode_width_m * facing / d < 2.0 * spacing:
        return False
    j = int(round((b - ray_ang[0]) / max(spacing, 1e-9)))
    j = min(n - 1, max(0, j))
    if scan.kind[r, j] == HIT_ROBOT and scan.range_m[r, j] < d - margin:
        return False  # something is in the way: no evidence against the estimate
    return True


@kernel
def track_progress(r, goal_dist, bearing, robots, params):
    """Escape from dead ends: after `stall` seconds without getting `progress` metres
    closer to the goal, follow the wall (on the side toward the goal) for `escape`
    seconds. Behaviour-based robots need such a rule: approach and avoidance alone
    can trap a robot in a corner by its goal or two robots in each other's way."""
    rob = robots[r]
    if rob.target != rob.last_target:  # a new goal: start afresh
        rob.last_target = rob.target
        rob.best_dist_m = np.inf
        rob.stall_s = 0.0
        if rob.mode == MODE_ESCAPE:
            rob.mode = MODE_APPROACH
            rob.escape_s = 0.0
    if goal_dist < rob.best_dist_m - params.progress_m:
        rob.best_dist_m = goal_dist
        rob.stall_s = 0.0
    else:
        rob.stall_s += params.dt_s
    if rob.mode == MODE_ESCAPE:
        rob.escape_s -= params.dt_s
        if rob.escape_s <= 0.0:
            rob.mode = MODE_APPROACH
            rob.best_dist_m = goal_dist
            rob.stall_s = 0.0
    elif rob.stall_s > params.stall_limit_s:
        rob.mode = MODE_ESCAPE
        rob.side = -1 if bearing > 0 else 1
        rob.escape_s = params.escape_duration_s
        rob.stall_s = 0.0
