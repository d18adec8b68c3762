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

A robot's `forced` field selects a behaviour from outside (a learner choosing
behaviours, section 1.4); `BEH_AUTO` lets the section 1.5.4 arbitration decide.
Nothing here knows about pymunk: `control_tick` reads true poses (for sensing only)
and the bundles of `behaviours.layout` (robots, shared parameters, arena, laser),
and writes the scan, the robots' state, wheel commands (forward speed, turn rate)
and arrival flags.
"""

from __future__ import annotations

import math

import numba
import numpy as np

from tavc_cli.behaviours.docking import (
    BACKOUT_SPEED,
    GIVEWAY_SPEED,
    READ_TOL_M,
    dock_drive,
    dock_frame,
    dock_occupied,
    dock_phase,
    nearest_rays,
    robot_in_front,
    to_frame,
)
from tavc_cli.behaviours.layout import (
    ARRIVE_RANGE,
    BEH_AUTO,
    BEH_STOP,
    BEH_WALL,
    MODE_APPROACH,
    MODE_DOCK,
    MODE_ESCAPE,
    MODE_SERVICE,
    MODE_UNDOCK,
    MODE_WALLFOLLOW,
)
from tavc_cli.behaviours.motion import should_see_target, steer_to, track_progress, wall_follow
from tavc_cli.kernel import kernel
from tavc_cli.sim.sensors import HIT_TARGET, camera_nearest, cast_laser, odometry_update
from tavc_cli.vocabulary import ACT_DOCK, ACT_ESCAPE, ACT_IDLE, ACT_SEARCH, ACT_WAIT


@kernel
def behave(r, robots, pose, params, arena, laser, scan, cmd, work):
    """Choose robot r's wheel command for this tick and flag arrival at its target.

    A target is served at its dock spot: the robot comes to the bar-code's normal, drives
    in facing the wall, and counts as arrived when it reads its code at `arrive_dist`
    from its centre, within the lateral and heading tolerances. It then stands for
    `dwell` seconds and backs out `backout` metres before heading for its next target. A
    robot that finds its dock spot taken by another robot holds back until it is free.
    Where arrival is read at range (`ARRIVE_RANGE`), a robot arrives as soon as it reads its
    code within `read_range`, wherever it stands, and heads on (after its dwell, if any).
    """
    rob = robots[r]
    tgt = rob.target
    target = arena.targets[max(tgt, 0)]
    own_barcode = target.barcode if tgt >= 0 else -999
    own_wall = target.wall if tgt >= 0 else -1
    ranges, kinds, ids = scan.range_m, scan.kind, scan.hit_id
    ray_ang = laser.angle_rad
    n = ray_ang.shape[0]
    radius, vmax, wmax = rob.radius_m, rob.top_speed_mps, rob.turn_rate_radps
    own_min, own_cnt = np.inf, 0
    near_min = np.inf
    for j in range(n):
        if kinds[r, j] != HIT_TARGET:
            continue
        near_min = min(near_min, ranges[r, j])
        if ids[r, j] == own_barcode:
            own_min = min(own_min, ranges[r, j])
            own_cnt += 1
    rob.target_visible = own_cnt > 0
    rob.code_in_view = near_min < np.inf
    rob.arrived = False
    if near_min <= params.relocalise_dist_m:
        # a bar-code close by gives range, bearing and orientation: localisation resets
        rob.est_x_m, rob.est_y_m, rob.est_heading_rad = pose[r, 0], pose[r, 1], pose[r, 2]
        if rob.mode == MODE_WALLFOLLOW:
            rob.mode = MODE_APPROACH
    mode = rob.mode
    if mode == MODE_SERVICE or mode == MODE_UNDOCK:
        dock_phase(r, robots, params, cmd)
        return
    forced = rob.forced
    if forced == BEH_STOP or tgt < 0:
        cmd[r, 0] = 0.0
        cmd[r, 1] = 0.0
        rob.activity = ACT_IDLE
        return
    if params.arrival == ARRIVE_RANGE and own_cnt > 0 and own_min <= params.read_range_m:
        # the code read within range: arrived wherever the robot stands, no dock spot to take
        rob.arrived = True
        rob.waited_s = 0.0
        if params.dwell_s > 0.0:  # it stands for the loading or unloading, then backs away as from a dock
            rob.mode = MODE_SERVICE
            rob.timer_s = params.dwell_s
        cmd[r, 0] = 0.0
        cmd[r, 1] = 0.0
        rob.activity = ACT_DOCK
        return
    # where the dock spot is: from the bar-code reading while the code is in view (the
    # reader gives its range, bearing and orientation), else from the dead-reckoned pose
    if own_cnt > 0:
        gx, gy, gth = pose[r, 0], pose[r, 1], pose[r, 2]
    else:
        gx, gy, gth = rob.est_x_m, rob.est_y_m, rob.est_heading_rad
    standoff = params.arrive_dist_m
    approach = params.dock_approach_m
    along, lat, face = dock_frame(gx, gy, gth, target, standoff)
    nx, ny = target.nx, target.ny
    dock_x = target.x_m + nx * standoff
    dock_y = target.y_m + ny * standoff
    dock_dist = math.sqrt(along * along + lat * lat)
    # the funnel in front of the dock spot from which the final approach starts, and the
    # slightly wider one it keeps to (down to just past the spot, where arrival fires)
    enter_funnel = (0.05 < along <= approach + 0.3
                    and abs(lat) <= params.dock_lateral_tol_m + 0.5 * along and abs(face) < 0.6 * math.pi)
    in_funnel = (-0.1 < along <= approach + 0.5
                 and abs(lat) <= params.dock_lateral_tol_m + 0.5 * max(along, 0.0) + 0.1
                 and abs(face) < 0.6 * math.pi)
    funnel_m = approach + 0.5
    near = dock_dist <= max(params.hold_m, funnel_m) + 0.5
    if not near:
        rob.waited_s = 0.0  # away from the dock: any wait there starts afresh
    patient = rob.waited_s <= params.patience_s
    in_line = dock_dist <= funnel_m or mode == MODE_DOCK
    occupied = False
    if near or (patient and in_line):
        nearest = work.flags  # one ray per robot in view
        nearest_rays(r, rob.first, rob.last, scan, nearest, work.rows)
        # the frame of the pose judged from: while the code is read, the true one the laser was cast at
        if own_cnt > 0:
            gcos, gsin = scan.heading_cs[r, 0], scan.heading_cs[r, 1]
        else:
            gcos, gsin = math.cos(gth), math.sin(gth)
        if near:
            # waited long: stop deferring to robots that are merely nearer, and yield only to one
            # at the spot or backing out of it (so a robot can't lose the race for a dock forever)
            zone = params.occupied_m if patient else params.backout_m + radius
            occupied = dock_occupied(r, gx, gy, gcos, gsin, dock_x, dock_y, nx, ny, dock_dist, lat, zone,
                                     scan, laser, nearest, radius)
        if not occupied and patient and in_line:
            # two robots in the approach funnel at once would block each other: the one with priority goes
            occupied = dock_occupied(r, gx, gy, gcos, gsin, dock_x, dock_y, nx, ny, dock_dist, lat,
                                     max(params.occupied_m, funnel_m), scan, laser, nearest, radius)

    if mode == MODE_DOCK:
        if occupied or not in_funnel:
            rob.mode = MODE_APPROACH  # lost the line or beaten to the spot: line up again
        elif (own_cnt > 0 and own_min <= params.arrive_dist_m + READ_TOL_M and abs(lat) <= params.dock_lateral_tol_m
              and abs(face) <= params.dock_heading_tol_rad):
            rob.arrived = True
            rob.mode = MODE_SERVICE
            rob.timer_s = params.dwell_s
            rob.waited_s = 0.0
            cmd[r, 0] = 0.0
            cmd[r, 1] = 0.0
            rob.activity = ACT_DOCK
            return
        else:
            track_progress(r, dock_dist, lat, robots, params)
            if rob.mode == MODE_ESCAPE:
                # no progress into the dock: back out and line up again
                rob.mode = MODE_UNDOCK
                rob.timer_s = params.backout_m / (BACKOUT_SPEED * vmax)
                dock_phase(r, robots, params, cmd)
                return
            dock_drive(r, along, lat, face, own_barcode, own_wall, robots, scan, laser, params, cmd, work)
            rob.activity = ACT_DOCK
            return

    if occupied and dock_dist <= max(params.hold_m, funnel_m):
        # the spot is taken: wait here, facing the dock, without counting it as a stall; and
        # give way, backing off slowly, to a robot close in front (one leaving the dock)
        rob.activity = ACT_WAIT
        bearing, _ = to_frame(gx, gy, gth, dock_x, dock_y)
        cmd[r, 0] = -GIVEWAY_SPEED * vmax if robot_in_front(r, scan, radius) else 0.0
        cmd[r, 1] = 0.0 if abs(bearing) < 0.3 else min(wmax, max(-wmax, bearing))
        rob.stall_s = 0.0
        rob.waited_s += params.dt_s
        return
    if enter_funnel and not occupied and (mode == MODE_APPROACH or own_cnt > 0):
        rob.mode = MODE_DOCK
        rob.best_dist_m = np.inf
        rob.stall_s = 0.0
        dock_drive(r, along, lat, face, own_barcode, own_wall, robots, scan, laser, params, cmd, work)
        rob.activity = ACT_DOCK
        return

    # on the way: head for the point `dock_approach` out along the code's normal
    pre_x = dock_x + nx * approach
    pre_y = dock_y + ny * approach
    bearing, pre_dist = to_frame(gx, gy, gth, pre_x, pre_y)
    if forced == BEH_AUTO:
        track_progress(r, dock_dist, bearing, robots, params)
        if rob.mode == MODE_ESCAPE:
            wall_follow(r, rob.side, robots, scan, laser, params, cmd, work)
            rob.activity = ACT_ESCAPE
            return
    if forced == BEH_WALL or (forced == BEH_AUTO and rob.mode == MODE_WALLFOLLOW):
        if rob.side == 0:  # chosen from outside: follow whatever is nearer, left or right
            left, right = np.inf, np.inf
            for j in range(n):
                if ray_ang[j] > 0:
                    left = min(left, ranges[r, j])
                else:
                    right = min(right, ranges[r, j])
            rob.side = 1 if left < right else -1
        if own_cnt > 0 and forced == BEH_AUTO:
            rob.mode = MODE_APPROACH  # the target came into view: approach it
        else:
            wall_follow(r, rob.side, robots, scan, laser, params, cmd, work)
            rob.activity = ACT_SEARCH
            return
    if own_cnt == 0 and forced == BEH_AUTO and should_see_target(r, robots, target, scan, laser, params):
        tb, _ = to_frame(rob.est_x_m, rob.est_y_m, rob.est_heading_rad, target.x_m, target.y_m)
        rob.mode = MODE_WALLFOLLOW
        # follow the wall on the side that leads round toward the expected target
        rob.side = -1 if tb > 0 else 1
        wall_follow(r, rob.side, robots, scan, laser, params, cmd, work)
        rob.activity = ACT_SEARCH
        return
    steer_to(r, bearing, pre_dist, own_barcode, robots, scan, laser, params, cmd, work)


@kernel
def control_tick(robots, pose, noise, params, arena, laser, scan, cmd, act_s, work):
    """One control tick for every live robot of every trial in a batch.

    Reads the true poses `pose` (n, 3: x m, y m, heading rad, for sensing only) and
    this tick's odometry noise (n, 3 standard normal draws); for each live robot:
    odometry, laser, camera (when anyone reads it), behaviour. Writes the scan, the
    wheel commands `cmd` (n, 2: forward m/s, turn rad/s), the robots' state and
    `act_s` (seconds per activity, this tick's added), using `work` (a `layout.Work` for
    the batch) as scratch. Returns how many robots reached their target this tick (their
    `arrived` flag is set).
    """
    n_arrived = 0
    for r in range(robots.shape[0]):
        rob = robots[r]
        if not rob.alive:
            cmd[r, 0] = 0.0
            cmd[r, 1] = 0.0
            rob.arrived = False
            continue
        odometry_update(r, robots, pose, noise)
        cast_laser(r, robots, pose, laser, arena, params, scan)
        if params.camera_on:
            camera_nearest(r, robots, pose, arena, params, scan)
        behave(r, robots, pose, params, arena, laser, scan, cmd, work)
        act_s[r, rob.activity] += params.dt_s
        n_arrived += rob.arrived
    return n_arrived


def compiled(kernel, *args):
    """The compiled specialisation of an njit `kernel` for these arguments' types.

    Calling it skips numba's per-call type dispatch, which for bundles of arrays costs
    several microseconds a call; nothing is checked at call time, so the arguments it is
    later called with must have exactly these types (dtypes, dimensions and C-contiguous
    memory, as the engine's arrays, fixed at its construction, have).
    """
    return kernel.compile(tuple(numba.typeof(a) for a in args))
