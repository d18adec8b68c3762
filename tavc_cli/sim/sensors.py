"""Simulated sensors: a bar-code reading laser, a colour-marking camera, odometry.

Everything here is compiled with numba and works on plain arrays so the control
loop can sense for every robot of every trial in one call. Geometry is exact:
rays are intersected analytically with wall segments, bar-code segments and the
other robots' discs (the same shapes the pymunk world collides).

Laser: each ray returns its range and what it hit (`HIT_*`) with an id (the
bar-code number for a target, the robot's index for a robot). The kernels read
and write the bundles of `behaviours.layout`.

Camera: reports which colour markings of the nearest robot in its field of view
can be seen: red on its left, green on its right, yellow at its rear, each seen
over a sector of bearings around the robot as a ship's lanterns are (the
chapter's inspiration for them), so a robot seen from ahead shows red and green,
from behind yellow, from the side its side colour.

Odometry: integrates the robot's true motion as its wheel encoders would see it
(only the component along its heading: a sideways shove goes unnoticed), with
zero-mean noise whose variance grows linearly with distance travelled and angle
turned, so the estimate drifts like a random walk.
"""

from __future__ import annotations

import math

import numpy as np

from tavc_cli.kernel import fma, kernel
from tavc_cli.sim.arena import N_OUTER_WALLS

HIT_NONE, HIT_WALL, HIT_ROBOT, HIT_TARGET = 0, 1, 2, 3
# rays this much outside an object's angular extent (as `_fast_atan2` bounds it) are not
# tested against it: the approximation is good to 2e-6 rad, rounding errors are some ten
# orders of magnitude smaller
_WINDOW_MARGIN_RAD = 1e-5
MARK_LEFT, MARK_RIGHT, MARK_REAR = 0, 1, 2  # red, green, yellow
MARKING_ANGLES = np.array([math.pi / 2, -math.pi / 2, math.pi])


@kernel(inline="always")
def wrap_angle(a: float) -> float:
    """Wrap an angle to [-pi, pi): (a + pi) mod 2 pi, less pi.

    Most angles need no wrapping, and for 0 <= x < 2 pi the remainder x mod 2 pi is x itself
    (floating-point remainders are exact), so those skip the remainder's library call and
    division. So do x one turn either side, the sum of a heading that has turned a while and a
    bearing: for 2 pi <= x < 4 pi the remainder is x - 2 pi, which is exact (the operands are
    within a factor two), and for -2 pi <= x < 0 Python's remainder is x + 2 pi, rounded as it
    rounds it. The result is the same number either way.
    """
    x = a + math.pi
    turn = 2.0 * math.pi
    if 0.0 <= x < turn:
        return x - math.pi
    if turn <= x < 2.0 * turn:
        return (x - turn) - math.pi
    if -turn <= x < 0.0:
        return (x + turn) - math.pi
    return _turns_remainder(x) - math.pi


@kernel(inline="always")
def _turns_remainder(x: float) -> float:
    """x % 2 pi, as Python computes it, for x outside [-2 pi, 4 pi) (headings that have turned
    many times), without the C library's fmod where |x| < 1e6.

    Python's remainder is fmod's exact one, moved into [0, 2 pi) by adding 2 pi to a negative
    one; that sum is exact too, since the result is x - k 2 pi for the integer k = floor(x / 2 pi)
    exactly, and every such number in [0, 2 pi) is a double: x (|x| >= 4) and 2 pi are multiples
    of 2^-50, so it is one too, below 8 = 2^53 2^-50. So one fused multiply-add gives it for the
    right k; the k from a rounded x / 2 pi may be one off, which the result's range shows.
    """
    turn = 2.0 * math.pi
    if not -1e6 < x < 1e6:
        return x % turn
    k = np.floor(x / turn)
    r = fma(-k, turn, x)
    if r < 0.0:
        return fma(-(k - 1.0), turn, x)
    if r >= turn:
        return fma(-(k + 1.0), turn, x)
    return r


@kernel(inline="always")
def ray_segment(px, py, dx, dy, x1, y1, x2, y2) -> float:
    """Distance along the unit ray (p, d) to segment (x1,y1)-(x2,y2), or inf."""
    sx, sy = x2 - x1, y2 - y1
    denom = dx * sy - dy * sx
    if abs(denom) < 1e-12:
        return np.inf
    inv = 1.0 / denom
    qx, qy = x1 - px, y1 - py
    t = (qx * sy - qy * sx) * inv
    if t < 0.0:
        return np.inf
    u = (qx * dy - qy * dx) * inv
    if 0.0 <= u <= 1.0:
        return t
    return np.inf


@kernel(inline="always")
def ray_disc(px, py, dx, dy, cx, cy, r) -> float:
    """Distance along the unit ray (p, d) to the disc (c, r), or inf (ray starts outside)."""
    ox, oy = cx - px, cy - py
    tca = ox * dx + oy * dy
    d2 = ox * ox + oy * oy - tca * tca
    r2 = r * r
    if d2 > r2:
        return np.inf
    t0 = tca - math.sqrt(r2 - d2)
    if t0 < 0.0:
        return np.inf
    return t0


@kernel(inline="always", error_model="numpy")
def _exit_wall(px, py, dx, dy, width, height):
    """Distance along the unit ray (p, d) from inside the width x height rectangle to its
    boundary, and the side it leaves through (0 bottom, 1 right, 2 top, 3 left)."""
    tx = (width - px if dx > 0.0 else -px) / dx
    ty = (height - py if dy > 0.0 else -py) / dy
    if abs(dx) <= 1e-12:
        tx = np.inf
    if abs(dy) <= 1e-12:
        ty = np.inf
    if tx < ty:
        return tx, 1 if dx > 0.0 else 3
    return ty, 2 if dy > 0.0 else 0


@kernel(inline="always")
def _fast_atan2(y, x):
    """atan2 to within 2e-6 rad (an odd polynomial for atan on [-1, 1]), for choosing which
    rays to test, never for a reading."""
    ay, ax = abs(y), abs(x)
    if ax == 0.0 and ay == 0.0:
        return 0.0
    z = min(ax, ay) / max(ax, ay)
    z2 = z * z
    a = z * (0.99997726 + z2 * (-0.33262347 + z2 * (0.19354346 + z2 * (-0.11643287
                                                                     + z2 * (0.05265332 + z2 * -0.01172120)))))
    if ay > ax:
        a = 0.5 * math.pi - a
    if x < 0.0:
        a = math.pi - a
    return -a if y < 0.0 else a


@kernel(inline="always")
def _ray_window(rel, half, a0, inv_spacing, n, full_circle):
    """Indices k (to be taken mod n when full_circle) of the rays within `half` of angle `rel`
    (and a few more: never fewer). A fan of rays short of the full circle does not wrap round
    at +-pi: a window that crosses it takes every ray."""
    lo = int(math.ceil((rel - half - a0) * inv_spacing - 1e-9))
    hi = int(math.floor((rel + half - a0) * inv_spacing + 1e-9))
    if full_circle:
        if hi - lo >= n:
            lo, hi = 0, n - 1
    elif rel - half < -math.pi or rel + half > math.pi:
        lo, hi = 0, n - 1
    else:
        lo = max(lo, 0)
        hi = min(hi, n - 1)
    return lo, hi


@kernel(inline="always")
def _ray_index(jj, n):
    """Ray jj of a window, as a ray of the fan of n: jj mod n (round a full circle), without the
    integer division, one of the slowest instructions, for the indices already within the fan."""
    return jj if 0 <= jj < n else jj % n


@kernel(error_model="numpy")
def cast_laser(r, robots, pose, laser, arena, params, scan):
    """Cast every ray of robot `r`; write range, kind of hit and hit id into row `r` of `scan`.

    For each ray, in this order, the nearest of: the outer wall it leaves through,
    a bar-code on that wall, an interior wall, a robot of the same trial (ties keep
    the first). Bar-codes and robots are tested only by the rays within their angular
    extent, which gives the same answer for less work. Hit ids: the bar-code for a
    target, the wall's row in `Arena.walls` for a wall, the robot's row for a robot,
    -1 for nothing within range.
    """
    angle, ray_cos, ray_sin = laser.angle_rad, laser.cos, laser.sin
    targets, inner = arena.targets, arena.inner_walls
    out_range, out_kind, out_id = scan.range_m, scan.kind, scan.hit_id
    n = angle.shape[0]
    a0 = angle[0]
    full_circle, inv_spacing, half_fov = laser.full_circle, laser.inv_spacing, laser.half_fov_rad
    max_range = params.laser_range_m
    width, height = params.arena_width_m, params.arena_height_m
    px, py, th = pose[r, 0], pose[r, 1], pose[r, 2]
    c, s = math.cos(th), math.sin(th)
    scan.heading_cs[r, 0], scan.heading_cs[r, 1] = c, s  # for whoever needs the robot's frame this tick
    # 1. the outer rectangle: every ray leaves it through one side
    for j in range(n):
        t, w = _exit_wall(px, py, c * ray_cos[j] - s * ray_sin[j], s * ray_cos[j] + c * ray_sin[j], width, height)
        hit = t < max_range
        out_range[r, j] = t if hit else max_range
        out_kind[r, j] = HIT_WALL if hit else HIT_NONE
        out_id[r, j] = w if hit else -1
    # 2. bar-codes, a hair in front of the outer walls: a ray reads one if it leaves the
    # arena within range through that code's stretch of wall. A code lies within half its
    # width h of its centre, at distance d: only rays within asin(h / d) <= h / sqrt(d^2 - h^2)
    # of the centre's bearing (and a hair more, against rounding) can reach it, and none if
    # d - h is beyond the laser's range; the others are skipped.
    for k in range(targets.shape[0]):
        tgt = targets[k]
        cx, cy = 0.5 * (tgt.x1_m + tgt.x2_m) - px, 0.5 * (tgt.y1_m + tgt.y2_m) - py
        half_w = tgt.half_width_m
        ahead = cx * c + cy * s  # the centre in the robot's frame
        if not full_circle and half_fov <= math.pi / 2 and ahead < -half_w:
            continue  # wholly behind a laser that sees no further back than its sides
        d2 = cx * cx + cy * cy
        if d2 > (max_range + half_w + 1e-6) ** 2:
            continue  # out of range
        half = half_w / math.sqrt(d2 - half_w * half_w) if d2 > 4.0 * half_w * half_w else math.pi
        rel = _fast_atan2(cy * c - cx * s, ahead)
        jlo, jhi = _ray_window(rel, half + _WINDOW_MARGIN_RAD, a0, inv_spacing, n, full_circle)
        for jj in range(jlo, jhi + 1):
            j = _ray_index(jj, n)
            kind = out_kind[r, j]
            if kind == HIT_NONE or (kind == HIT_WALL and out_id[r, j] != tgt.wall):
                continue
            dx = c * ray_cos[j] - s * ray_sin[j]
            dy = s * ray_cos[j] + c * ray_sin[j]
            if kind == HIT_TARGET:  # read another code already: through which wall does it leave?
                t, w = _exit_wall(px, py, dx, dy, width, height)
                if w != tgt.wall:
                    continue
            tk = ray_segment(px, py, dx, dy, tgt.x1_m, tgt.y1_m, tgt.x2_m, tgt.y2_m)
            if tk < out_range[r, j]:
                out_range[r, j] = tk
                out_kind[r, j] = HIT_TARGET
                out_id[r, j] = tgt.barcode
    # 3. interior walls, by every ray
    if inner.shape[0] > 0:
        for j in range(n):
            dx = c * ray_cos[j] - s * ray_sin[j]
            dy = s * ray_cos[j] + c * ray_sin[j]
            for w in range(inner.shape[0]):
                t = ray_segment(px, py, dx, dy, inner[w, 0], inner[w, 1], inner[w, 2], inner[w, 3])
                if t < out_range[r, j]:
                    out_range[r, j] = t
                    out_kind[r, j] = HIT_WALL
                    out_id[r, j] = N_OUTER_WALLS + w
    # 4. the other robots of the trial, by the rays within their angular extent
    for o in range(robots[r].first, robots[r].last):
        if o == r or not robots[o].alive:
            continue
        radius = robots[o].radius_m
        ox, oy = pose[o, 0] - px, pose[o, 1] - py
        d = math.sqrt(ox * ox + oy * oy)
        if d - radius > max_range or d <= radius:
            continue
        ahead = ox * c + oy * s  # its centre in the robot's frame
        if not full_circle and half_fov <= math.pi / 2 and ahead < -radius:
            continue  # wholly behind a laser that sees no further back than its sides
        # within asin(radius / d) <= radius / sqrt(d^2 - radius^2) of its centre's bearing
        half = radius / math.sqrt(d * d - radius * radius) if d * d > 2.0 * radius * radius else math.pi
        rel = _fast_atan2(oy * c - ox * s, ahead)
        jlo, jhi = _ray_window(rel, half + _WINDOW_MARGIN_RAD, a0, inv_spacing, n, full_circle)
        for jj in range(jlo, jhi + 1):
            j = _ray_index(jj, n)
            dx = c * ray_cos[j] - s * ray_sin[j]
            dy = s * ray_cos[j] + c * ray_sin[j]
            t = ray_disc(px, py, dx, dy, pose[o, 0], pose[o, 1], radius)
            if t < out_range[r, j]:
                out_range[r, j] = t
                out_kind[r, j] = HIT_ROBOT
                out_id[r, j] = o


@kernel
def markings_visible(obs_x, obs_y, ox, oy, oth, side_sector, out, k):
    """Set out[k, 0..2] to whether the observed robot's red (left), green (right) and
    yellow (rear) markings can be seen from the observer's position.

    As with a ship's lanterns, which inspired the markings: red shows from dead ahead
    round the left side to `side_sector` off the bow, green likewise on the right,
    yellow over the rest of the circle astern.
    """
    beta = wrap_angle(math.atan2(obs_y - oy, obs_x - ox) - oth)  # observer's bearing, observed robot's frame
    out[k, 0] = 1 if 0.0 <= beta <= side_sector else 0
    out[k, 1] = 1 if -side_sector <= beta <= 0.0 else 0
    out[k, 2] = 1 if abs(beta) >= side_sector else 0


@kernel
def camera_nearest(r, robots, pose, arena, params, scan):
    """Nearest robot in robot r's camera view and its visible markings.

    scan.camera[r] = (red, green, yellow, row of the seen robot or -1). Interior
    walls block the view; the outer walls cannot.
    """
    out, inner = scan.camera, arena.inner_walls
    px, py, th = pose[r, 0], pose[r, 1], pose[r, 2]
    best, best_o = params.camera_range_m, -1
    for o in range(robots[r].first, robots[r].last):
        if o == r or not robots[o].alive:
            continue
        dx, dy = pose[o, 0] - px, pose[o, 1] - py
        d = math.sqrt(dx * dx + dy * dy)
        if d >= best or d == 0.0:
            continue
        # inside the field of view iff the angle to the heading is at most its half
        if (dx * math.cos(th) + dy * math.sin(th)) < d * math.cos(params.camera_half_fov_rad):
            continue
        blocked = False
        for w in range(inner.shape[0]):
            t = ray_segment(px, py, dx / d, dy / d, inner[w, 0], inner[w, 1], inner[w, 2], inner[w, 3])
            if t < d:
                blocked = True
        if not blocked:
            best, best_o = d, o
    out[r, 3] = best_o
    if best_o < 0:
        out[r, 0] = 0
        out[r, 1] = 0
        out[r, 2] = 0
    else:
        markings_visible(px, py, pose[best_o, 0], pose[best_o, 1], pose[best_o, 2], params.marking_sector_rad,
                         out, r)


@kernel
def odometry_update(r, robots, pose, noise):
    """Advance robot r's dead-reckoned pose by its measured motion since last tick's true pose,
    then remember this tick's true pose. `noise[r]` holds three standard normal draws.
    """
    rob = robots[r]
    dth = wrap_angle(pose[r, 2] - rob.prev_heading_rad)
    mid = rob.prev_heading_rad + 0.5 * dth
    # wheel encoders only measure motion along the heading
    ds = (pose[r, 0] - rob.prev_x_m) * math.cos(mid) + (pose[r, 1] - rob.prev_y_m) * math.sin(mid)
    ads, adth = abs(ds), abs(dth)
    ds_m = ds + rob.odo_trans_per_sqrt_m * math.sqrt(ads) * noise[r, 0]
    dth_m = (dth + rob.odo_rot_per_sqrt_m * math.sqrt(ads) * noise[r, 1]
             + rob.odo_rot_per_sqrt_rad * math.sqrt(adth) * noise[r, 2])
    emid = rob.est_heading_rad + 0.5 * dth_m
    rob.est_x_m += ds_m * math.cos(emid)
    rob.est_y_m += ds_m * math.sin(emid)
    rob.est_heading_rad = wrap_angle(rob.est_heading_rad + dth_m)
    rob.prev_x_m, rob.prev_y_m, rob.prev_heading_rad = pose[r, 0], pose[r, 1], pose[r, 2]


def ray_angles(fov_deg: float, n_rays: int) -> np.ndarray:
    """Ray directions relative to the heading, evenly over the field of view."""
    half = math.radians(fov_deg) / 2
    if n_rays == 1:
        return np.zeros(1)
    if fov_deg >= 360.0:
        return np.linspace(-math.pi, math.pi, n_rays, endpoint=False)
    return np.linspace(-half, half, n_rays)
