"""Serving a target at its dock spot: where the robot stands relative to the spot, whether
another robot holds the spot, the aligned final approach, and the timed stand and back-out.
Compiled with numba; everything works on one robot's row of the bundles of `behaviours.layout`.
"""

from __future__ import annotations

import math

import numpy as np

from tavc_cli.behaviours.layout import MODE_APPROACH, MODE_SERVICE, MODE_UNDOCK
from tavc_cli.behaviours.motion import free_distance
from tavc_cli.kernel import kernel
from tavc_cli.sim.sensors import HIT_ROBOT, wrap_angle
from tavc_cli.vocabulary import ACT_DOCK

# the final approach runs along the code's normal toward a point this far ahead of the robot
DOCK_LOOKAHEAD_M = 0.35
# slowest forward speed of the final approach and of backing out, as a fraction of top speed
DOCK_CREEP = 0.2
BACKOUT_SPEED = 0.5
# a robot counts another as nearer the dock only if it is nearer by this much (no ties)
QUEUE_MARGIN_M = 0.1
# a waiting robot backs off at this fraction of top speed from a robot nearer than this to its front
GIVEWAY_SPEED = 0.3
GIVEWAY_GAP_M = 0.35
# arrival: the code read at the reading distance, give or take this much
READ_TOL_M = 0.02


@kernel(inline="always")
def to_frame(px, py, th, gx, gy):
    """Bearing (robot frame) and distance from pose (px, py, th) to the point (gx, gy)."""
    dx, dy = gx - px, gy - py
    return wrap_angle(math.atan2(dy, dx) - th), math.sqrt(dx * dx + dy * dy)


@kernel(inline="always")
def dock_frame(px, py, th, target, standoff):
    """Pose relative to `target`'s dock spot (a TARGET record), the point `standoff` out from the bar-code
    along its wall's normal: (along the normal, positive into the arena; along the wall;
    heading error from facing the wall)."""
    nx, ny = target.nx, target.ny
    dx = px - (target.x_m + nx * standoff)
    dy = py - (target.y_m + ny * standoff)
    return dx * nx + dy * ny, dy * nx - dx * ny, wrap_angle(th - target.facing_rad)


@kernel
def dock_occupied(r, px, py, c, s, dock_x, dock_y, nx, ny, my_dist, my_lat, zone, scan, laser, nearest, radius):
    """Whether the laser shows another robot within `zone` of the dock spot, nearer to it than robot r,
    seen from the pose (px, py) with heading cosine and sine (c, s).

    The rays that hit one robot form a blob; the shortest of them passes nearest its
    centre, which lies about a radius further along that ray (a glancing ray would put
    it up to a third of a metre off). Only a robot nearer the spot than r by a margin
    counts, so of several robots the nearest one never waits, and none wait for each
    other in a ring. Two robots about equally near (within the margin) go in the order
    of their position along the wall, which both see alike.
    """
    ranges = scan.range_m
    for j in range(ranges.shape[1]):
        if not nearest[j]:
            continue
        rng = max(ranges[r, j], 1e-9)
        hx = (ranges[r, j] * laser.cos[j]) * (1.0 + radius / rng)
        hy = (ranges[r, j] * laser.sin[j]) * (1.0 + radius / rng)
        wx = px + c * hx - s * hy
        wy = py + s * hx + c * hy
        d = math.sqrt((wx - dock_x) ** 2 + (wy - dock_y) ** 2)
        if d >= zone:
            continue
        if d < my_dist - QUEUE_MARGIN_M:
            return True
        lat = (wy - dock_y) * nx - (wx - dock_x) * ny
        if d <= my_dist + QUEUE_MARGIN_M and lat > my_lat:
            return True
    return False


@kernel
def nearest_rays(r, first, last, scan, out, best):
    """out[j] = whether ray j of robot r is the shortest of the rays that hit the same robot
    (the first of equals): one ray per robot in view (rows first..last-1), the one passing
    nearest its centre. `best` is scratch of at least last - first rows."""
    kinds, ids, ranges = scan.kind, scan.hit_id, scan.range_m
    n = ranges.shape[1]
    for o in range(last - first):
        best[o] = -1
    for j in range(n):
        out[j] = False
        if kinds[r, j] == HIT_ROBOT:
            o = ids[r, j] - first
            if best[o] < 0 or ranges[r, j] < ranges[r, best[o]]:
                best[o] = j
    for o in range(last - first):
        if best[o] >= 0:
            out[best[o]] = True


@kernel
def robot_in_front(r, scan, radius):
    """Whether a robot is within a give-way gap of robot r, anywhere in its laser's view."""
    for j in range(scan.range_m.shape[1]):
        if scan.kind[r, j] == HIT_ROBOT and scan.range_m[r, j] < radius + GIVEWAY_GAP_M:
            return True
    return False


@kernel
def dock_drive(r, along, lat, face, own_barcode, own_wall, robots, scan, laser, params, cmd, work):
    """The final approach: drive along the bar-code's normal up to the dock spot, facing the wall.

    The robot pursues a point on the normal a short look-ahead in front of it (this steers
    out its lateral offset as it closes in), slowing to a creep near the spot. The dock's
    own wall and bar-code are no obstacle here, other robots are.
    """
    rob = robots[r]
    radius, vmax, wmax = rob.radius_m, rob.top_speed_mps, rob.turn_rate_radps
    aim_along = max(along - DOCK_LOOKAHEAD_M, -0.05)
    # the aim point relative to the robot, in the dock frame (x along the normal, y along the wall)
    ax, ay = aim_along - along, -lat
    # heading of the aim point relative to facing the wall: facing the wall is -x in this frame
    aim_dir = math.atan2(-ay, -ax)  # sign: lat grows toward +y, angles measured from -x
    err = wrap_angle(aim_dir - face)
    if abs(err) > math.pi / 3:
        cmd[r, 0] = 0.0
        cmd[r, 1] = wmax if err > 0 else -wmax
        return
    ahead = free_distance(r, 0.0, radius, scan, laser, own_barcode, own_wall, params.stop_dist_m, work)
    speed = vmax * min(1.0, max(DOCK_CREEP, (along + 0.05) / max(params.dock_approach_m, 1e-9)))
    if ahead < params.stop_dist_m:
        speed = 0.0  # another robot in the way
    cmd[r, 0] = speed * math.cos(err) ** 2
    cmd[r, 1] = min(wmax, max(-wmax, 2.5 * err))


@kernel
def dock_phase(r, robots, params, cmd):
    """Standing at the dock (loading or unloading), then backing straight out, both timed:
    whatever is behind, the robot leaves the spot after `dwell` plus the back-out time."""
    rob = robots[r]
    rob.timer_s -= params.dt_s
    rob.activity = ACT_DOCK
    cmd[r, 1] = 0.0
    if rob.mode == MODE_SERVICE:
        cmd[r, 0] = 0.0
        if rob.timer_s <= 0.0:
            rob.mode = MODE_UNDOCK
            rob.timer_s = params.backout_m / (BACKOUT_SPEED * rob.top_speed_mps)
    else:
        cmd[r, 0] = -BACKOUT_SPEED * rob.top_speed_mps
        if rob.timer_s <= 0.0:
            rob.mode = MODE_APPROACH
            rob.best_dist_m = np.inf
            rob.stall_s = 0.0
