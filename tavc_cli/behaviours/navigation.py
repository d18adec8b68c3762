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

from tavc_cli.behaviours.activities import ACT_DOCK, ACT_ESCAPE, ACT_IDLE, ACT_SEARCH, ACT_WAIT
from tavc_cli.behaviours.docking import (
    BACKOUT_SPEED,
    GIVEWAY_SPEED,
    READ_TOL_M,
    dock_drive,
    dock_frame,
    dock_occupied,
    dock_phase,
    robot_in_front,
    to_frame,
)
from tavc_cli.behaviours.layout import *  # noqa: F403  (the layout is part of this module's interface)
from tavc_cli.behaviours.motion import should_see_target, steer_to, track_progress, wall_follow
from tavc_cli.sim.sensors import HIT_TARGET, camera_nearest, cast_laser, odometry_update


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
    if not near:
        fstate[r, FS_WAITED] = 0.0  # away from the dock: any wait there starts afresh
    if fstate[r, FS_WAITED] > gp[G_PATIENCE]:
        # waited long: stop deferring to robots that are merely nearer, and yield only to one
        # at the spot or backing out of it (so a robot can't lose the race for a dock forever)
        occupied = near and dock_occupied(r, gx, gy, gth, dock_x, dock_y, nx, ny, dock_dist, lat,
                                          gp[G_BACKOUT] + fparam[r, F_RADIUS], ranges, kinds, ids, pts,
                                          fparam[r, F_RADIUS])
    else:
        occupied = near and dock_occupied(r, gx, gy, gth, dock_x, dock_y, nx, ny, dock_dist, lat,
                                          gp[G_OCCUPIED], ranges, kinds, ids, pts, fparam[r, F_RADIUS])
        # two robots in the approach funnel at once would block each other: the one with priority goes
        if not occupied and (dock_dist <= funnel_m or mode == MODE_DOCK):
            occupied = dock_occupied(r, gx, gy, gth, dock_x, dock_y, nx, ny, dock_dist, lat,
                                     max(gp[G_OCCUPIED], funnel_m), ranges, kinds, ids, pts, fparam[r, F_RADIUS])

    if mode == MODE_DOCK:
        if occupied or not in_funnel:
            istate[r, I_MODE] = MODE_APPROACH  # lost the line or beaten to the spot: line up again
        elif (own_cnt > 0 and own_min <= gp[G_ARRIVE] + READ_TOL_M and abs(lat) <= gp[G_DOCK_LAT]
              and abs(face) <= gp[G_DOCK_HEAD]):
            istate[r, I_ARRIVED] = 1
            istate[r, I_MODE] = MODE_SERVICE
            fstate[r, FS_TIMER] = gp[G_DWELL]
            fstate[r, FS_WAITED] = 0.0
            cmd[r, 0] = 0.0
            cmd[r, 1] = 0.0
            istate[r, I_ACT] = ACT_DOCK
            return
        else:
            track_progress(r, dock_dist, lat, istate, fstate, gp)
            if istate[r, I_MODE] == MODE_ESCAPE:
                # no progress into the dock: back out and line up again
                istate[r, I_MODE] = MODE_UNDOCK
                fstate[r, FS_TIMER] = gp[G_BACKOUT] / (BACKOUT_SPEED * fparam[r, F_VMAX])
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
        cmd[r, 0] = -GIVEWAY_SPEED * fparam[r, F_VMAX] if robot_in_front(r, ranges, kinds, ray_ang,
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
