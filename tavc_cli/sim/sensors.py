"""Simulated sensors: a bar-code reading laser, a colour-marking camera, odometry.

Everything here is compiled with numba and works on plain arrays so the control
loop can sense for every robot of every trial in one call. Geometry is exact:
rays are intersected analytically with wall segments, bar-code segments and the
other robots' discs (the same shapes the pymunk world collides).

Laser: each ray returns its range and what it hit (`HIT_*`) with an id (the
bar-code number for a target, the robot's index for a robot).

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
from numba import njit

HIT_NONE, HIT_WALL, HIT_ROBOT, HIT_TARGET = 0, 1, 2, 3
MARK_LEFT, MARK_RIGHT, MARK_REAR = 0, 1, 2  # red, green, yellow
MARKING_ANGLES = np.array([math.pi / 2, -math.pi / 2, math.pi])


@njit(cache=True, inline="always")
def wrap_angle(a: float) -> float:
    """Wrap an angle to [-pi, pi)."""
    return (a + math.pi) % (2.0 * math.pi) - math.pi


@njit(cache=True, inline="always")
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


@njit(cache=True, inline="always")
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


@njit(cache=True, inline="always")
def _ray_window(rel, half, a0, spacing, n, full_circle):
    """Indices k (to be taken mod n when full_circle) of rays within `half` of angle `rel`."""
    lo = int(math.ceil((rel - half - a0) / spacing - 1e-9))
    hi = int(math.floor((rel + half - a0) / spacing + 1e-9))
    if not full_circle:
        lo = max(lo, 0)
        hi = min(hi, n - 1)
    elif hi - lo >= n:
        lo, hi = 0, n - 1
    return lo, hi


@njit(cache=True)
def cast_laser(
    r, pose, radius, alive, lo, hi, ray_ang, ray_cs, max_range, walls, tsegs, target_wall, barcodes,
    out_range, out_kind, out_id, out_pts,
):
    """Cast every ray of robot `r` (rows lo..hi of `pose` share its world).

    Rays are evenly spaced (`ray_ang`, with their cos and sin in `ray_cs`). Every
    ray is tested against every wall; a bar-code (on outer wall `target_wall[k]`)
    only by the rays that leave through that wall, and a robot only by the rays
    inside its angular extent, which gives the same answer for less work.
    Writes range, hit kind, hit id and the hit point in the robot's frame into
    row `r` of the outputs.
    """
    n = ray_ang.shape[0]
    a0 = ray_ang[0]
    spacing = (ray_ang[n - 1] - a0) / (n - 1) if n > 1 else 1.0
    full_circle = n > 1 and (ray_ang[n - 1] - a0 + spacing) >= 2.0 * math.pi - 1e-9
    px, py, th = pose[r, 0], pose[r, 1], pose[r, 2]
    c, s = math.cos(th), math.sin(th)
    half_fov = max(abs(ray_ang[0]), abs(ray_ang[n - 1]))
    # rows 0-3 of `walls` are the outer rectangle (bottom, right, top, left, as the
    # arena builds them): a ray from inside leaves it through exactly one side, found
    # with two divisions; further rows are interior walls, tested in general
    width, height = walls[0, 2], walls[1, 3]
    for j in range(n):
        dx = c * ray_cs[j, 0] - s * ray_cs[j, 1]
        dy = s * ray_cs[j, 0] + c * ray_cs[j, 1]
        tx, wx = np.inf, -1
        if dx > 1e-12:
            tx, wx = (width - px) / dx, 1
        elif dx < -1e-12:
            tx, wx = -px / dx, 3
        ty, wy = np.inf, -1
        if dy > 1e-12:
            ty, wy = (height - py) / dy, 2
        elif dy < -1e-12:
            ty, wy = -py / dy, 0
        t, w = (tx, wx) if tx < ty else (ty, wy)
        best, kind, ident = max_range, HIT_NONE, -1
        if t < best:
            best, kind, ident = t, HIT_WALL, w
            # bar-codes hang on the outer walls, a hair in front of them: the ray
            # reads one if it leaves the arena through that code's stretch of wall
            for k in range(tsegs.shape[0]):
                if target_wall[k] != w:
                    continue
                tk = ray_segment(px, py, dx, dy, tsegs[k, 0], tsegs[k, 1], tsegs[k, 2], tsegs[k, 3])
                if tk < best:
                    best, kind, ident = tk, HIT_TARGET, barcodes[k]
        for w in range(4, walls.shape[0]):
            t = ray_segment(px, py, dx, dy, walls[w, 0], walls[w, 1], walls[w, 2], walls[w, 3])
            if t < best:
                best, kind, ident = t, HIT_WALL, w
        out_range[r, j] = best
        out_kind[r, j] = kind
        out_id[r, j] = ident
    for o in range(lo, hi):
        if o == r or not alive[o]:
            continue
        ox, oy = pose[o, 0] - px, pose[o, 1] - py
        d = math.sqrt(ox * ox + oy * oy)
        if d - radius[o] > max_range or d <= radius[o]:
            continue
        if not full_circle and half_fov <= math.pi / 2 and ox * c + oy * s < -radius[o]:
            continue  # wholly behind a laser that sees no further back than its sides
        rel = wrap_angle(math.atan2(oy, ox) - th)
        jlo, jhi = _ray_window(rel, math.asin(radius[o] / d), a0, spacing, n, full_circle)
        for jj in range(jlo, jhi + 1):
            j = jj % n
            dx = c * ray_cs[j, 0] - s * ray_cs[j, 1]
            dy = s * ray_cs[j, 0] + c * ray_cs[j, 1]
            t = ray_disc(px, py, dx, dy, pose[o, 0], pose[o, 1], radius[o])
            if t < out_range[r, j]:
                out_range[r, j] = t
                out_kind[r, j] = HIT_ROBOT
                out_id[r, j] = o
    for j in range(n):
        out_pts[r, j, 0] = out_range[r, j] * ray_cs[j, 0]
        out_pts[r, j, 1] = out_range[r, j] * ray_cs[j, 1]


@njit(cache=True)
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


@njit(cache=True)
def camera_nearest(r, pose, radius, alive, lo, hi, fov_half, max_range, walls, n_outer, side_sector, out):
    """Nearest robot in robot r's camera view and its visible markings.

    out[r] = (red, green, yellow, index of the seen robot or -1). Interior walls
    (rows n_outer.. of `walls`) block the view; the outer walls cannot.
    """
    px, py, th = pose[r, 0], pose[r, 1], pose[r, 2]
    best, best_o = max_range, -1
    for o in range(lo, hi):
        if o == r or not alive[o]:
            continue
        dx, dy = pose[o, 0] - px, pose[o, 1] - py
        d = math.sqrt(dx * dx + dy * dy)
        if d >= best or d == 0.0:
            continue
        # inside the field of view iff the angle to the heading is at most fov_half
        if (dx * math.cos(th) + dy * math.sin(th)) < d * math.cos(fov_half):
            continue
        blocked = False
        for w in range(n_outer, walls.shape[0]):
            t = ray_segment(px, py, dx / d, dy / d, walls[w, 0], walls[w, 1], walls[w, 2], walls[w, 3])
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
        markings_visible(px, py, pose[best_o, 0], pose[best_o, 1], pose[best_o, 2], side_sector, out, r)


@njit(cache=True)
def odometry_update(r, prev_pose, pose, est, noise, sigma_trans, sigma_rot_m, sigma_rot_rad):
    """Advance robot r's dead-reckoned pose `est` by its measured motion since `prev_pose`.

    `noise[r]` holds three standard normal draws for this tick.
    """
    dth = wrap_angle(pose[r, 2] - prev_pose[r, 2])
    mid = prev_pose[r, 2] + 0.5 * dth
    # wheel encoders only measure motion along the heading
    ds = (pose[r, 0] - prev_pose[r, 0]) * math.cos(mid) + (pose[r, 1] - prev_pose[r, 1]) * math.sin(mid)
    ads, adth = abs(ds), abs(dth)
    ds_m = ds + sigma_trans * math.sqrt(ads) * noise[r, 0]
    dth_m = dth + sigma_rot_m * math.sqrt(ads) * noise[r, 1] + sigma_rot_rad * math.sqrt(adth) * noise[r, 2]
    emid = est[r, 2] + 0.5 * dth_m
    est[r, 0] += ds_m * math.cos(emid)
    est[r, 1] += ds_m * math.sin(emid)
    est[r, 2] = wrap_angle(est[r, 2] + dth_m)


def ray_angles(fov_deg: float, n_rays: int) -> np.ndarray:
    """Ray directions relative to the heading, evenly over the field of view."""
    half = math.radians(fov_deg) / 2
    if n_rays == 1:
        return np.zeros(1)
    if fov_deg >= 360.0:
        return np.linspace(-math.pi, math.pi, n_rays, endpoint=False)
    return np.linspace(-half, half, n_rays)
