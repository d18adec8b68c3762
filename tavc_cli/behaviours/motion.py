"""Moving toward a goal among obstacles: free-path tests on the laser's hit points, steering
with detours, wall following, the "target should be visible" check, and the escape rule
for dead ends. Compiled with numba; everything works on one robot's rows of the arrays.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from tavc_cli.behaviours.activities import ACT_AVOID, ACT_DRIVE
from tavc_cli.behaviours.layout import (
    F_RADIUS,
    F_VMAX,
    F_WMAX,
    FS_BEST,
    FS_ESCAPE,
    FS_STALL,
    G_AVOID,
    G_BARCODE_W,
    G_DT,
    G_ESCAPE_S,
    G_PROGRESS_M,
    G_RANGE,
    G_STALL_S,
    G_STOP,
    G_VISMARGIN,
    G_WALLD,
    I_ACT,
    I_LASTTGT,
    I_MODE,
    I_SIDE,
    I_TARGET,
    I_TURN,
    MODE_APPROACH,
    MODE_ESCAPE,
)
from tavc_cli.sim.sensors import HIT_ROBOT, HIT_TARGET, HIT_WALL, wrap_angle

_CORRIDOR_MARGIN_M = 0.05


@njit(cache=True)
def free_distance(r, heading, radius, pts, kinds, ids, skip_barcode, skip_wall=-1):
    """How far robot r can drive along `heading` (robot frame) before its disc,
    widened by a small margin, touches a laser hit point (ignoring one bar-code, and
    the outer wall `skip_wall` that a docking robot drives up to on purpose)."""
    half = radius + _CORRIDOR_MARGIN_M
    ux, uy = math.cos(heading), math.sin(heading)
    best = np.inf
    for i in range(pts.shape[1]):
        if kinds[r, i] == HIT_TARGET and ids[r, i] == skip_barcode:
            continue
        if kinds[r, i] == HIT_WALL and ids[r, i] == skip_wall:
            continue
        px = pts[r, i, 0]
        py = pts[r, i, 1]
        along = px * ux + py * uy
        if along <= 0.0:
            continue
        lateral = abs(px * uy - py * ux)
        if lateral >= half:
            continue
        best = min(best, along - math.sqrt(half * half - lateral * lateral))
    return best


@njit(cache=True)
def steer_to(r, bearing, dist, own_barcode, istate, ranges, kinds, ids, pts, ray_ang, fparam, gp, cmd):
    """Head for `bearing` (robot frame), detouring around whatever the laser sees.

    The heading taken is the free direction nearest the goal's: candidates are
    tried outward from the goal bearing, and the first along which the robot's
    disc can travel `need` metres wins. Speed falls as the free distance ahead
    shrinks toward `stop_dist`. Sets the tick's activity to avoiding whenever an
    obstacle bends the path or slows the robot.
    """
    radius, vmax, wmax = fparam[r, F_RADIUS], fparam[r, F_VMAX], fparam[r, F_WMAX]
    avoid, stop = gp[G_AVOID], gp[G_STOP]
    n = ray_ang.shape[0]
    fov_half = max(abs(ray_ang[0]), abs(ray_ang[n - 1]))
    istate[r, I_ACT] = ACT_DRIVE
    if abs(bearing) > fov_half:
        # the goal is behind: turn on the spot until it is in view, keeping the
        # direction already chosen while the goal is nearly straight behind (the
        # sign of the bearing flips there from one tick to the next)
        if istate[r, I_TURN] == 0 or abs(bearing) < math.pi - 0.5:
            istate[r, I_TURN] = 1 if bearing > 0 else -1
        cmd[r, 0] = 0.0
        cmd[r, 1] = istate[r, I_TURN] * wmax
        return
    spacing = (ray_ang[n - 1] - ray_ang[0]) / max(n - 1, 1)
    # the robot only has to get to its goal point
    need = min(avoid, max(dist, stop))
    heading = np.nan
    free = free_distance(r, bearing, radius, pts, kinds, ids, own_barcode)
    if free >= need:
        heading = bearing
    else:
        j0 = int(round((bearing - ray_ang[0]) / max(spacing, 1e-9)))
        for step in range(1, 2 * n):
            off = (step + 1) // 2 if step % 2 == 1 else -(step // 2)
            j = j0 + off
            if j < 0 or j >= n:
                continue
            f = free_distance(r, ray_ang[j], radius, pts, kinds, ids, own_barcode)
            if f >= need:
                heading, free = ray_ang[j], f
                break
    if np.isnan(heading):
        # boxed in: turn toward the more open side, and keep turning that way
        if istate[r, I_TURN] == 0:
            left, right = 0.0, 0.0
            for j in range(n):
                if ray_ang[j] > 0:
                    left += ranges[r, j]
                else:
                    right += ranges[r, j]
            istate[r, I_TURN] = 1 if left >= right else -1
        cmd[r, 0] = 0.0
        cmd[r, 1] = 0.5 * wmax * istate[r, I_TURN]
        istate[r, I_ACT] = ACT_AVOID
        return
    istate[r, I_TURN] = 0
    ahead = free_distance(r, 0.0, radius, pts, kinds, ids, own_barcode)
    slow = min(1.0, max(0.0, (min(ahead, free) - stop) / max(avoid - stop, 1e-9)))
    if heading != bearing or slow < 1.0:
        istate[r, I_ACT] = ACT_AVOID
    cmd[r, 0] = vmax * slow * max(0.0, math.cos(heading)) ** 2
    cmd[r, 1] = min(wmax, max(-wmax, 2.0 * heading))


@njit(cache=True)
def wall_follow(r, side, ranges, kinds, ids, pts, ray_ang, fparam, gp, cmd):
    """Keep a wall at `wall_dist` on `side` (+1 left, -1 right) and move along it."""
    radius, vmax, wmax = fparam[r, F_RADIUS], fparam[r, F_VMAX], fparam[r, F_WMAX]
    wall_d, stop = gp[G_WALLD], gp[G_STOP]
    gap = free_distance(r, 0.0, radius, pts, kinds, ids, -999)
    side_d = np.inf
    for j in range(ray_ang.shape[0]):
        a = side * ray_ang[j]
        if math.pi / 4 <= a <= 3 * math.pi / 4:
            side_d = min(side_d, ranges[r, j] - radius)
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


@njit(cache=True)
def should_see_target(r, est, tx, ty, nx, ny, ranges, kinds, ray_ang, gp):
    """Whether the estimated pose says the target's bar-code must be in the laser's view.

    True only where the code would be wide enough to be hit by at least two rays
    and the ray toward it is not blocked by a nearer robot.
    """
    dx, dy = tx - est[r, 0], ty - est[r, 1]
    d = math.sqrt(dx * dx + dy * dy)
    margin = gp[G_VISMARGIN]
    if d < 1e-6 or d > gp[G_RANGE] - margin:
        return False
    n = ray_ang.shape[0]
    spacing = (ray_ang[n - 1] - ray_ang[0]) / max(n - 1, 1)
    b = wrap_angle(math.atan2(dy, dx) - est[r, 2])
    if abs(b) > max(abs(ray_ang[0]), abs(ray_ang[n - 1])) - spacing:
        return False
    facing = -(dx * nx + dy * ny) / d  # cosine of the incidence on the bar-code
    if facing < 0.25 or gp[G_BARCODE_W] * facing / d < 2.0 * spacing:
        return False
    j = int(round((b - ray_ang[0]) / max(spacing, 1e-9)))
    j = min(n - 1, max(0, j))
    if kinds[r, j] == HIT_ROBOT and ranges[r, j] < d - margin:
        return False  # something is in the way: no evidence against the estimate
    return True


@njit(cache=True)
def track_progress(r, goal_dist, bearing, istate, fstate, gp):
    """Escape from dead ends: after `stall` seconds without getting `progress` metres
    closer to the goal, follow the wall (on the side toward the goal) for `escape`
    seconds. Behaviour-based robots need such a rule: approach and avoidance alone
    can trap a robot in a corner by its goal or two robots in each other's way."""
    if istate[r, I_TARGET] != istate[r, I_LASTTGT]:  # a new goal: start afresh
        istate[r, I_LASTTGT] = istate[r, I_TARGET]
        fstate[r, FS_BEST] = np.inf
        fstate[r, FS_STALL] = 0.0
        if istate[r, I_MODE] == MODE_ESCAPE:
            istate[r, I_MODE] = MODE_APPROACH
            fstate[r, FS_ESCAPE] = 0.0
    if goal_dist < fstate[r, FS_BEST] - gp[G_PROGRESS_M]:
        fstate[r, FS_BEST] = goal_dist
        fstate[r, FS_STALL] = 0.0
    else:
        fstate[r, FS_STALL] += gp[G_DT]
    if istate[r, I_MODE] == MODE_ESCAPE:
        fstate[r, FS_ESCAPE] -= gp[G_DT]
        if fstate[r, FS_ESCAPE] <= 0.0:
            istate[r, I_MODE] = MODE_APPROACH
            fstate[r, FS_BEST] = goal_dist
            fstate[r, FS_STALL] = 0.0
    elif fstate[r, FS_STALL] > gp[G_STALL_S]:
        istate[r, I_MODE] = MODE_ESCAPE
        istate[r, I_SIDE] = -1 if bearing > 0 else 1
        fstate[r, FS_ESCAPE] = gp[G_ESCAPE_S]
        fstate[r, FS_STALL] = 0.0
