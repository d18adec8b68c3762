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

from tavc_cli.behaviours.activities import (
    ACT_AVOID,
    ACT_DOCK,
    ACT_DRIVE,
    ACT_ESCAPE,
    ACT_IDLE,
    ACT_SEARCH,
    ACT_WAIT,
)
from tavc_cli.sim.sensors import (
    HIT_ROBOT,
    HIT_WALL,
    HIT_TARGET,
    camera_nearest,
    cast_laser,
    odometry_update,
    wrap_angle,
)

# columns of the integer robot state
(I_TRIAL, I_ALIVE, I_TARGET, I_MODE, I_SIDE, I_FORCED, I_ARRIVED, I_TVIS, I_LO, I_HI, I_TURN, I_LASTTGT,
 I_ACT) = range(13)
N_ISTATE = 13
# columns of the per-robot float state: best distance to the goal so far, seconds
# without progress, seconds of escape left, seconds left of the current dock phase
FS_BEST, FS_STALL, FS_ESCAPE, FS_TIMER, FS_WAITED = range(5)
N_FSTATE = 5
# columns of the per-robot float parameters
F_RADIUS, F_VMAX, F_WMAX, F_SIG_T, F_SIG_RM, F_SIG_RR = range(6)
N_FPARAM = 6
# global behaviour and sensor parameters
(G_AVOID, G_STOP, G_ARRIVE, G_WALLD, G_VISMARGIN, G_RELOC, G_RANGE,
 G_CAM_FOV_HALF, G_CAM_RANGE, G_SIDE_SECTOR, G_BARCODE_W, G_STALL_S, G_ESCAPE_S, G_PROGRESS_M, G_DT,
 G_DOCK_LAT, G_DOCK_HEAD, G_DOCK_APPROACH, G_DWELL, G_BACKOUT, G_OCCUPIED, G_HOLD) = range(22)
N_GPARAM = 22
# columns of the target table: bar-code centre x, y, inward normal x, y, bar-code id, outer wall index
T_X, T_Y, T_NX, T_NY, T_CODE, T_WALL = range(6)

MODE_APPROACH, MODE_WALLFOLLOW, MODE_ESCAPE, MODE_DOCK, MODE_SERVICE, MODE_UNDOCK = range(6)
BEH_AUTO, BEH_DIRECT, BEH_WALL, BEH_STOP = -1, 0, 1, 2
_CORRIDOR_MARGIN_M = 0.05
# the final approach runs along the code's normal toward a point this far ahead of the robot
_DOCK_LOOKAHEAD_M = 0.35
# slowest forward speed of the final approach and of backing out, as a fraction of top speed
_DOCK_CREEP = 0.2
_BACKOUT_SPEED = 0.5
# a robot counts another as nearer the dock only if it is nearer by this much (no ties)
_QUEUE_MARGIN_M = 0.1
# a waiting robot backs off at this fraction of top speed from a robot nearer than this to its front
_GIVEWAY_SPEED = 0.3
_GIVEWAY_GAP_M = 0.35
# a robot that has waited this long for a dock goes in anyway (its view of the queue may be wrong)
_PATIENCE_S = 90.0
# arrival: the code read at the reading distance, give or take this much
_READ_TOL_M = 0.02


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


@njit(cache=True, inline="always")
def to_frame(px, py, th, gx, gy):
    """Bearing (robot frame) and distance from pose (px, py, th) to the point (gx, gy)."""
    dx, dy = gx - px, gy - py
    return wrap_angle(math.atan2(dy, dx) - th), math.sqrt(dx * dx + dy * dy)


@njit(cache=True, inline="always")
def dock_frame(px, py, th, tinfo, tgt, standoff):
    """Pose relative to target tgt's dock spot, the point `standoff` out from the bar-code
    along its wall's normal: (along the normal, positive into the arena; along the wall;
    heading error from facing the wall)."""
    nx, ny = tinfo[tgt, T_NX], tinfo[tgt, T_NY]
    dx = px - (tinfo[tgt, T_X] + nx * standoff)
    dy = py - (tinfo[tgt, T_Y] + ny * standoff)
    return dx * nx + dy * ny, dy * nx - dx * ny, wrap_angle(th - math.atan2(-ny, -nx))


@njit(cache=True)
def dock_occupied(r, px, py, th, dock_x, dock_y, nx, ny, my_dist, my_lat, zone, ranges, kinds, ids, pts, radius):
    """Whether the laser shows another robot within `zone` of the dock spot, nearer to it than robot r.

    The rays that hit one robot form a blob; the shortest of them passes nearest its
    centre, which lies about a radius further along that ray (a glancing ray would put
    it up to a third of a metre off). Only a robot nearer the spot than r by a margin
    counts, so of several robots the nearest one never waits, and none wait for each
    other in a ring. Two robots about equally near (within the margin) go in the order
    of their position along the wall, which both see alike.
    """
    c, s = math.cos(th), math.sin(th)
    n = pts.shape[1]
    for j in range(n):
        if kinds[r, j] != HIT_ROBOT:
            continue
        nearest = True
        for k in range(n):
            if kinds[r, k] == HIT_ROBOT and ids[r, k] == ids[r, j] and (
                    ranges[r, k] < ranges[r, j] or (ranges[r, k] == ranges[r, j] and k < j)):
                nearest = False
                break
        if not nearest:
            continue
        rng = max(ranges[r, j], 1e-9)
        hx = pts[r, j, 0] * (1.0 + radius / rng)
        hy = pts[r, j, 1] * (1.0 + radius / rng)
        wx = px + c * hx - s * hy
        wy = py + s * hx + c * hy
        d = math.sqrt((wx - dock_x) ** 2 + (wy - dock_y) ** 2)
        if d >= zone:
            continue
        if d < my_dist - _QUEUE_MARGIN_M:
            return True
        lat = (wy - dock_y) * nx - (wx - dock_x) * ny
        if d <= my_dist + _QUEUE_MARGIN_M and lat > my_lat:
            return True
    return False


@njit(cache=True)
def robot_in_front(r, ranges, kinds, ray_ang, radius):
    """Whether a robot is within a give-way gap of robot r, anywhere in its laser's view."""
    for j in range(ray_ang.shape[0]):
        if kinds[r, j] == HIT_ROBOT and ranges[r, j] < radius + _GIVEWAY_GAP_M:
            return True
    return False


@njit(cache=True)
def dock_drive(r, along, lat, face, own_barcode, own_wall, kinds, ids, pts, fparam, gp, cmd):
    """The final approach: drive along the bar-code's normal up to the dock spot, facing the wall.

    The robot pursues a point on the normal a short look-ahead in front of it (this steers
    out its lateral offset as it closes in), slowing to a creep near the spot. The dock's
    own wall and bar-code are no obstacle here, other robots are.
    """
    radius, vmax, wmax = fparam[r, F_RADIUS], fparam[r, F_VMAX], fparam[r, F_WMAX]
    aim_along = max(along - _DOCK_LOOKAHEAD_M, -0.05)
    # the aim point relative to the robot, in the dock frame (x along the normal, y along the wall)
    ax, ay = aim_along - along, -lat
    # heading of the aim point relative to facing the wall: facing the wall is -x in this frame
    aim_dir = math.atan2(-ay, -ax)  # sign: lat grows toward +y, angles measured from -x
    err = wrap_angle(aim_dir - face)
    if abs(err) > math.pi / 3:
        cmd[r, 0] = 0.0
        cmd[r, 1] = wmax if err > 0 else -wmax
        return
    ahead = free_distance(r, 0.0, radius, pts, kinds, ids, own_barcode, own_wall)
    speed = vmax * min(1.0, max(_DOCK_CREEP, (along + 0.05) / max(gp[G_DOCK_APPROACH], 1e-9)))
    if ahead < gp[G_STOP]:
        speed = 0.0  # another robot in the way
    cmd[r, 0] = speed * math.cos(err) ** 2
    cmd[r, 1] = min(wmax, max(-wmax, 2.5 * err))


@njit(cache=True)
def dock_phase(r, istate, fstate, fparam, gp, cmd):
    """Standing at the dock (loading or unloading), then backing straight out, both timed:
    whatever is behind, the robot leaves the spot after `dwell` plus the back-out time."""
    fstate[r, FS_TIMER] -= gp[G_DT]
    istate[r, I_ACT] = ACT_DOCK
    cmd[r, 1] = 0.0
    if istate[r, I_MODE] == MODE_SERVICE:
        cmd[r, 0] = 0.0
        if fstate[r, FS_TIMER] <= 0.0:
            istate[r, I_MODE] = MODE_UNDOCK
            fstate[r, FS_TIMER] = gp[G_BACKOUT] / (_BACKOUT_SPEED * fparam[r, F_VMAX])
    else:
        cmd[r, 0] = -_BACKOUT_SPEED * fparam[r, F_VMAX]
        if fstate[r, FS_TIMER] <= 0.0:
            istate[r, I_MODE] = MODE_APPROACH
            fstate[r, FS_BEST] = np.inf
            fstate[r, FS_STALL] = 0.0


@njit(cache=True)
def behave(r, pose, est, istate, fstate, fparam, gp, ray_ang, tinfo, ranges, kinds, ids, pts, cmd):
    """Choose robot r's wheel command for this tick and flag arrival at its target.

    A target is served at its dock spot: the robot comes to the bar-code's normal, drives
    in facing the wall, and counts as arrived when it reads its code at `arrive_dist`
    from its centre, within the lateral and heading tolerances. It then stands for
    `dwell` seconds and backs out `backout` metres before heading for its next target. A
    robot that finds its dock spot taken by another robot holds back until it is free.
    """
    tgt = istate[r, I_TARGET]
    own_barcode = int(tinfo[tgt, T_CODE]) if tgt >= 0 else -999
    own_wall = int(tinfo[tgt, T_WALL]) if tgt >= 0 else -1
    n = ray_ang.shape[0]
    own_min, own_cnt = np.inf, 0
    near_min = np.inf
    for j in range(n):
        if kinds[r, j] != HIT_TARGET:
            continue
        near_min = min(near_min, ranges[r, j])
        if ids[r, j] == own_barcode:
            own_min = min(own_min, ranges[r, j])
            own_cnt += 1
    istate[r, I_TVIS] = 1 if own_cnt > 0 else 0
    istate[r, I_ARRIVED] = 0
    if near_min <= gp[G_RELOC]:
        # a bar-code close by gives range, bearing and orientation: localisation resets
        est[r, 0], est[r, 1], est[r, 2] = pose[r, 0], pose[r, 1], pose[r, 2]
        if istate[r, I_MODE] == MODE_WALLFOLLOW:
            istate[r, I_MODE] = MODE_APPROACH
    mode = istate[r, I_MODE]
    if mode == MODE_SERVICE or mode == MODE_UNDOCK:
        dock_phase(r, istate, fstate, fparam, gp, cmd)
        return
    forced = istate[r, I_FORCED]
    if forced == BEH_STOP or tgt < 0:
        cmd[r, 0] = 0.0
        cmd[r, 1] = 0.0
        istate[r, I_ACT] = ACT_IDLE
        return
    # where the dock spot is: from the bar-code reading while the code is in view (the
    # reader gives its range, bearing and orientation), else from the dead-reckoned pose
    if own_cnt > 0:
        gx, gy, gth = pose[r, 0], pose[r, 1], pose[r, 2]
    else:
        gx, gy, gth = est[r, 0], est[r, 1], est[r, 2]
    standoff = gp[G_ARRIVE]
    along, lat, face = dock_frame(gx, gy, gth, tinfo, tgt, standoff)
    dock_x = tinfo[tgt, T_X] + tinfo[tgt, T_NX] * standoff
    dock_y = tinfo[tgt, T_Y] + tinfo[tgt, T_NY] * standoff
    dock_dist = math.sqrt(along * along + lat * lat)
    # the funnel in front of the dock spot from which the final approach starts, and the
    # slightly wider one it keeps to (down to just past the spot, where arrival fires)
    enter_funnel = (0.05 < along <= gp[G_DOCK_APPROACH] + 0.3
                    and abs(lat) <= gp[G_DOCK_LAT] + 0.5 * along and abs(face) < 0.6 * math.pi)
    in_funnel = (-0.1 < along <= gp[G_DOCK_APPROACH] + 0.5
                 and abs(lat) <= gp[G_DOCK_LAT] + 0.5 * max(along, 0.0) + 0.1 and abs(face) < 0.6 * math.pi)
    nx, ny = tinfo[tgt, T_NX], tinfo[tgt, T_NY]
    funnel_m = gp[G_DOCK_APPROACH] + 0.5
    near = dock_dist <= max(gp[G_HOLD], funnel_m) + 0.5
    occupied = near and dock_occupied(r, gx, gy, gth, dock_x, dock_y, nx, ny, dock_dist, lat, gp[G_OCCUPIED],
                                      ranges, kinds, ids, pts, fparam[r, F_RADIUS])
    # two robots in the approach funnel at once would block each other: the one with priority goes
    if not occupied and dock_dist <= funnel_m and mode != MODE_DOCK or mode == MODE_DOCK and not occupied:
        occupied = dock_occupied(r, gx, gy, gth, dock_x, dock_y, nx, ny, dock_dist, lat,
                                 max(gp[G_OCCUPIED], funnel_m), ranges, kinds, ids, pts, fparam[r, F_RADIUS])
    if occupied and fstate[r, FS_WAITED] > _PATIENCE_S:
        occupied = False  # waited far longer than any dock visit takes: a misread, go anyway
    if not occupied or dock_dist > max(gp[G_HOLD], funnel_m):
        fstate[r, FS_WAITED] = 0.0

    if mode == MODE_DOCK:
        if occupied or not in_funnel:
            istate[r, I_MODE] = MODE_APPROACH  # lost the line or beaten to the spot: line up again
        elif (own_cnt > 0 and own_min <= gp[G_ARRIVE] + _READ_TOL_M and abs(lat) <= gp[G_DOCK_LAT]
              and abs(face) <= gp[G_DOCK_HEAD]):
            istate[r, I_ARRIVED] = 1
            istate[r, I_MODE] = MODE_SERVICE
            fstate[r, FS_TIMER] = gp[G_DWELL]
            cmd[r, 0] = 0.0
            cmd[r, 1] = 0.0
            istate[r, I_ACT] = ACT_DOCK
            return
        else:
            track_progress(r, dock_dist, lat, istate, fstate, gp)
            if istate[r, I_MODE] == MODE_ESCAPE:
                # no progress into the dock: back out and line up again
                istate[r, I_MODE] = MODE_UNDOCK
                fstate[r, FS_TIMER] = gp[G_BACKOUT] / (_BACKOUT_SPEED * fparam[r, F_VMAX])
                dock_phase(r, istate, fstate, fparam, gp, cmd)
                return
            dock_drive(r, along, lat, face, own_barcode, own_wall, kinds, ids, pts, fparam, gp, cmd)
            istate[r, I_ACT] = ACT_DOCK
            return

    if occupied and dock_dist <= max(gp[G_HOLD], funnel_m):
        # the spot is taken: wait here, facing the dock, without counting it as a stall; and
        # give way, backing off slowly, to a robot close in front (one leaving the dock)
        istate[r, I_ACT] = ACT_WAIT
        bearing, _ = to_frame(gx, gy, gth, dock_x, dock_y)
        cmd[r, 0] = -_GIVEWAY_SPEED * fparam[r, F_VMAX] if robot_in_front(r, ranges, kinds, ray_ang,
                                                                      fparam[r, F_RADIUS]) else 0.0
        cmd[r, 1] = 0.0 if abs(bearing) < 0.3 else min(fparam[r, F_WMAX], max(-fparam[r, F_WMAX], bearing))
        fstate[r, FS_STALL] = 0.0
        fstate[r, FS_WAITED] += gp[G_DT]
        return
    if enter_funnel and not occupied and (mode == MODE_APPROACH or own_cnt > 0):
        istate[r, I_MODE] = MODE_DOCK
        fstate[r, FS_BEST] = np.inf
        fstate[r, FS_STALL] = 0.0
        dock_drive(r, along, lat, face, own_barcode, own_wall, kinds, ids, pts, fparam, gp, cmd)
        istate[r, I_ACT] = ACT_DOCK
        return

    # on the way: head for the point `dock_approach` out along the code's normal
    pre_x = dock_x + tinfo[tgt, T_NX] * gp[G_DOCK_APPROACH]
    pre_y = dock_y + tinfo[tgt, T_NY] * gp[G_DOCK_APPROACH]
    bearing, pre_dist = to_frame(gx, gy, gth, pre_x, pre_y)
    if forced == BEH_AUTO:
        track_progress(r, dock_dist, bearing, istate, fstate, gp)
        if istate[r, I_MODE] == MODE_ESCAPE:
            wall_follow(r, istate[r, I_SIDE], ranges, kinds, ids, pts, ray_ang, fparam, gp, cmd)
            istate[r, I_ACT] = ACT_ESCAPE
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
            istate[r, I_ACT] = ACT_SEARCH
            return
    if own_cnt == 0 and forced == BEH_AUTO:
        tb, _ = to_frame(est[r, 0], est[r, 1], est[r, 2], tinfo[tgt, T_X], tinfo[tgt, T_Y])
        if should_see_target(r, est, tinfo[tgt, T_X], tinfo[tgt, T_Y], tinfo[tgt, T_NX], tinfo[tgt, T_NY],
                             ranges, kinds, ray_ang, gp):
            istate[r, I_MODE] = MODE_WALLFOLLOW
            # follow the wall on the side that leads round toward the expected target
            istate[r, I_SIDE] = -1 if tb > 0 else 1
            wall_follow(r, istate[r, I_SIDE], ranges, kinds, ids, pts, ray_ang, fparam, gp, cmd)
            istate[r, I_ACT] = ACT_SEARCH
            return
    steer_to(r, bearing, pre_dist, own_barcode, istate, ranges, kinds, ids, pts, ray_ang, fparam, gp, cmd)


@njit(cache=True)
def control_tick(pose, prev_pose, est, noise, istate, fstate, fparam, gp, ray_ang, ray_cs, walls, n_outer,
                 tsegs, target_wall, tinfo, barcodes, ranges, kinds, ids, pts, cam, cmd, act_s):
    """Sense and decide for every live robot: odometry, laser, camera, behaviours.

    Rows of `pose` are robots; robots of one trial occupy rows I_LO..I_HI and only
    see each other. `cmd` receives (forward speed m/s, turn rate rad/s); `act_s[r]`
    adds this tick's seconds to the robot's activity of the tick. Returns how many
    robots reached their target this tick.
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
        act_s[r, istate[r, I_ACT]] += gp[G_DT]
        n_arrived += istate[r, I_ARRIVED]
    return n_arrived
