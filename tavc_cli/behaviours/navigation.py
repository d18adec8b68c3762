"""The robots' behaviours and the per-tick control kernel.

One compiled call senses and decides for every robot of every trial in a batch:
odometry, laser, camera, then the behaviours of sections 1.5.4 and 1.4.2, all on
top of obstacle avoidance:

- visible target approach: steer along the laser rays that read the target's
  bar-code;
- target location approach: steer toward the target's map position as seen from
  the dead-reckoned pose;
- wall following: when the target should be in view according to the estimated
  pose but the laser does not read it (and nothing stands in the way), the
  estimate is judged wrong and the robot follows the wall until it reads a
  bar-code close by, which resets its localisation (the bar-code reader gives
  range, bearing and orientation, as Stage's fiducial finder did);
- escape: a robot that has made no progress toward its goal for a while follows
  the wall for a while, which frees it from dead ends;
- stopping: stand still (a behaviour a learner may pick, section 1.4.2).

`forced` selects a behaviour from outside (a learner choosing behaviours,
section 1.4); `BEH_AUTO` lets the section 1.5.4 arbitration decide.
Nothing here knows about pymunk: the kernel reads true poses (for sensing only),
writes wheel commands (forward speed, turn rate) and event flags.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from tavc_cli.sim.sensors import (
    HIT_ROBOT,
    HIT_TARGET,
    camera_nearest,
    cast_laser,
    odometry_update,
    wrap_angle,
)

# columns of the integer robot state
I_TRIAL, I_ALIVE, I_TARGET, I_MODE, I_SIDE, I_FORCED, I_ARRIVED, I_TVIS, I_LO, I_HI, I_TURN, I_LASTTGT = range(12)
N_ISTATE = 12
# columns of the per-robot float state: best distance to the goal so far, seconds
# without progress, seconds of escape left
FS_BEST, FS_STALL, FS_ESCAPE = range(3)
N_FSTATE = 3
# columns of the per-robot float parameters
F_RADIUS, F_VMAX, F_WMAX, F_SIG_T, F_SIG_RM, F_SIG_RR = range(6)
N_FPARAM = 6
# global behaviour and sensor parameters
(G_AVOID, G_STOP, G_ARRIVE, G_WALLD, G_VISMARGIN, G_RELOC, G_RANGE,
 G_CAM_FOV_HALF, G_CAM_RANGE, G_SIDE_SECTOR, G_BARCODE_W, G_STALL_S, G_ESCAPE_S, G_PROGRESS_M, G_DT) = range(15)
N_GPARAM = 15

MODE_APPROACH, MODE_WALLFOLLOW, MODE_ESCAPE = 0, 1, 2
BEH_AUTO, BEH_DIRECT, BEH_WALL, BEH_STOP = -1, 0, 1, 2
_CORRIDOR_MARGIN_M = 0.05


@njit(cache=True)
def free_distance(r, heading, radius, pts, kinds, ids, skip_barcode):
    """How far robot r can drive along `heading` (robot frame) before its disc,
    widened by a small margin, touches a laser hit point (ignoring one bar-code)."""
    half = radius + _CORRIDOR_MARGIN_M
    ux, uy = math.cos(heading), math.sin(heading)
    best = np.inf
    for i in range(pts.shape[1]):
        if kinds[r, i] == HIT_TARGET and ids[r, i] == skip_barcode:
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
    shrinks toward `stop_dist`.
    """
    radius, vmax, wmax = fparam[r, F_RADIUS], fparam[r, F_VMAX], fparam[r, F_WMAX]
    avoid, stop = gp[G_AVOID], gp[G_STOP]
    n = ray_ang.shape[0]
    fov_half = max(abs(ray_ang[0]), abs(ray_ang[n - 1]))
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
    # the robot only has to get within reading range of its goal
    need = min(avoid, max(dist - gp[G_ARRIVE], stop))
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
        return
    istate[r, I_TURN] = 0
    ahead = free_distance(r, 0.0, radius, pts, kinds, ids, own_barcode)
    slow = min(1.0, max(0.0, (min(ahead, free) - stop) / max(avoid - stop, 1e-9)))
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


@njit(cache=True)
def behave(r, pose, est, istate, fstate, fparam, gp, ray_ang, tinfo, ranges, kinds, ids, pts, cmd):
    """Choose robot r's wheel command for this tick and flag arrival at its target."""
    tgt = istate[r, I_TARGET]
    own_barcode = int(tinfo[tgt, 4]) if tgt >= 0 else -999
    n = ray_ang.shape[0]
    own_min, own_sum, own_cnt = np.inf, 0.0, 0
    near_min = np.inf
    for j in range(n):
        if kinds[r, j] != HIT_TARGET:
            continue
        near_min = min(near_min, ranges[r, j])
        if ids[r, j] == own_barcode:
            own_min = min(own_min, ranges[r, j])
            own_sum += ray_ang[j]
            own_cnt += 1
    istate[r, I_TVIS] = 1 if own_cnt > 0 else 0
    istate[r, I_ARRIVED] = 1 if own_min <= gp[G_ARRIVE] else 0
    if near_min <= gp[G_RELOC]:
        # a bar-code close by gives range, bearing and orientation: localisation resets
        est[r, 0], est[r, 1], est[r, 2] = pose[r, 0], pose[r, 1], pose[r, 2]
        if istate[r, I_MODE] == MODE_WALLFOLLOW:
            istate[r, I_MODE] = MODE_APPROACH
    forced = istate[r, I_FORCED]
    if forced == BEH_STOP or tgt < 0:
        cmd[r, 0] = 0.0
        cmd[r, 1] = 0.0
        return
    tx, ty = tinfo[tgt, 0], tinfo[tgt, 1]
    dx, dy = tx - est[r, 0], ty - est[r, 1]
    bearing = wrap_angle(math.atan2(dy, dx) - est[r, 2])
    est_dist = math.sqrt(dx * dx + dy * dy)
    if forced == BEH_AUTO:
        track_progress(r, own_min if own_cnt > 0 else est_dist, bearing, istate, fstate, gp)
        if istate[r, I_MODE] == MODE_ESCAPE:
            wall_follow(r, istate[r, I_SIDE], ranges, kinds, ids, pts, ray_ang, fparam, gp, cmd)
            return
    if forced == BEH_WALL or (forced == BEH_AUTO and istate[r, I_MODE] == MODE_WALLFOLLOW):
        if istate[r, I_SIDE] == 0:  # chosen from outside: follow whatever is nearer, left or right
            left, right = np.inf, np.inf
            for j in range(n):
                if ray_ang[j] > 0:
                    left = min(left, ranges[r, j])
                else:
                    right = min(right, ranges[r, j])
            istate[r, I_SIDE] = 1 if left < right else -1
        if own_cnt > 0 and forced == BEH_AUTO:
            istate[r, I_MODE] = MODE_APPROACH  # the target came into view: approach it
        else:
            wall_follow(r, istate[r, I_SIDE], ranges, kinds, ids, pts, ray_ang, fparam, gp, cmd)
            return
    if own_cnt > 0:
        steer_to(r, own_sum / own_cnt, own_min, own_barcode, istate, ranges, kinds, ids, pts, ray_ang,
                 fparam, gp, cmd)
        return
    if forced == BEH_AUTO and should_see_target(r, est, tx, ty, tinfo[tgt, 2], tinfo[tgt, 3],
                                                ranges, kinds, ray_ang, gp):
        istate[r, I_MODE] = MODE_WALLFOLLOW
        # follow the wall on the side that leads round toward the expected target
        istate[r, I_SIDE] = -1 if bearing > 0 else 1
        wall_follow(r, istate[r, I_SIDE], ranges, kinds, ids, pts, ray_ang, fparam, gp, cmd)
        return
    steer_to(r, bearing, est_dist, own_barcode, istate, ranges, kinds, ids, pts, ray_ang, fparam, gp, cmd)


@njit(cache=True)
def control_tick(pose, prev_pose, est, noise, istate, fstate, fparam, gp, ray_ang, ray_cs, walls, n_outer,
                 tsegs, target_wall, tinfo, barcodes, ranges, kinds, ids, pts, cam, cmd):
    """Sense and decide for every live robot: odometry, laser, camera, behaviours.

    Rows of `pose` are robots; robots of one trial occupy rows I_LO..I_HI and only
    see each other. `cmd` receives (forward speed m/s, turn rate rad/s). Returns
    how many robots reached their target this tick.
    """
    alive = istate[:, I_ALIVE]
    radius = fparam[:, F_RADIUS]
    n_arrived = 0
    for r in range(pose.shape[0]):
        if alive[r] == 0:
            cmd[r, 0] = 0.0
            cmd[r, 1] = 0.0
            istate[r, I_ARRIVED] = 0
            continue
        lo, hi = istate[r, I_LO], istate[r, I_HI]
        odometry_update(r, prev_pose, pose, est, noise, fparam[r, F_SIG_T], fparam[r, F_SIG_RM],
                        fparam[r, F_SIG_RR])
        cast_laser(r, pose, radius, alive, lo, hi, ray_ang, ray_cs, gp[G_RANGE], walls, tsegs, target_wall, barcodes,
                   ranges, kinds, ids, pts)
        camera_nearest(r, pose, radius, alive, lo, hi, gp[G_CAM_FOV_HALF], gp[G_CAM_RANGE], walls,
                       n_outer, gp[G_SIDE_SECTOR], cam)
        behave(r, pose, est, istate, fstate, fparam, gp, ray_ang, tinfo, ranges, kinds, ids, pts, cmd)
        n_arrived += istate[r, I_ARRIVED]
    return n_arrived
