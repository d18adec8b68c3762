"""The kernel's data layout: columns of the per-robot state and parameter arrays, the
global parameter vector (and how a robot config fills it), the target table, the
behaviour modes.

The compiled kernel works on plain arrays; these names say what each column holds.
"""

import math
from collections.abc import Mapping

import numpy as np

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
 G_DOCK_LAT, G_DOCK_HEAD, G_DOCK_APPROACH, G_DWELL, G_BACKOUT, G_OCCUPIED, G_HOLD, G_PATIENCE) = range(23)
N_GPARAM = 23
# columns of the target table: bar-code centre x, y, inward normal x, y, bar-code id, outer wall index
T_X, T_Y, T_NX, T_NY, T_CODE, T_WALL = range(6)

MODE_APPROACH, MODE_WALLFOLLOW, MODE_ESCAPE, MODE_DOCK, MODE_SERVICE, MODE_UNDOCK = range(6)
BEH_AUTO, BEH_DIRECT, BEH_WALL, BEH_STOP = -1, 0, 1, 2

def behaviour_params(robot: Mapping, barcode_width_m: float, dt_s: float) -> np.ndarray:
    """The kernel's global sensor and behaviour parameters, from a robot config mapping."""
    laser, cam, beh = robot["laser"], robot["camera"], robot["behaviour"]
    gp = np.zeros(N_GPARAM)
    gp[G_AVOID] = beh["avoid_dist_m"]
    gp[G_STOP] = beh["stop_dist_m"]
    gp[G_ARRIVE] = beh["arrive_dist_m"]
    gp[G_WALLD] = beh["wall_dist_m"]
    gp[G_VISMARGIN] = beh["visible_margin_m"]
    gp[G_RELOC] = beh["relocalise_dist_m"]
    gp[G_STALL_S] = beh["stall_s"]
    gp[G_ESCAPE_S] = beh["escape_s"]
    gp[G_PROGRESS_M] = beh["progress_m"]
    gp[G_RANGE] = laser["range_m"]
    gp[G_CAM_FOV_HALF] = math.radians(float(cam["fov_deg"])) / 2
    gp[G_CAM_RANGE] = cam["range_m"]
    gp[G_SIDE_SECTOR] = math.radians(float(cam["side_sector_deg"]))
    gp[G_BARCODE_W] = barcode_width_m
    gp[G_DT] = dt_s
    dock = robot["dock"]
    gp[G_DOCK_LAT] = dock["lateral_tol_m"]
    gp[G_DOCK_HEAD] = math.radians(float(dock["heading_tol_deg"]))
    gp[G_DOCK_APPROACH] = dock["approach_m"]
    gp[G_DWELL] = dock["dwell_s"]
    gp[G_BACKOUT] = dock["backout_m"]
    gp[G_OCCUPIED] = dock["occupied_m"]
    gp[G_HOLD] = dock["occupied_m"] + dock["hold_margin_m"]
    gp[G_PATIENCE] = dock["patience_s"]
    return gp



__all__ = [
    "behaviour_params",
    "BEH_AUTO",
    "BEH_DIRECT",
    "BEH_STOP",
    "BEH_WALL",
    "FS_BEST",
    "FS_ESCAPE",
    "FS_STALL",
    "FS_TIMER",
    "FS_WAITED",
    "F_RADIUS",
    "F_SIG_RM",
    "F_SIG_RR",
    "F_SIG_T",
    "F_VMAX",
    "F_WMAX",
    "G_ARRIVE",
    "G_AVOID",
    "G_BACKOUT",
    "G_BARCODE_W",
    "G_CAM_FOV_HALF",
    "G_CAM_RANGE",
    "G_DOCK_APPROACH",
    "G_DOCK_HEAD",
    "G_DOCK_LAT",
    "G_DT",
    "G_DWELL",
    "G_ESCAPE_S",
    "G_HOLD",
    "G_OCCUPIED",
    "G_PATIENCE",
    "G_PROGRESS_M",
    "G_RANGE",
    "G_RELOC",
    "G_SIDE_SECTOR",
    "G_STALL_S",
    "G_STOP",
    "G_VISMARGIN",
    "G_WALLD",
    "I_ACT",
    "I_ALIVE",
    "I_ARRIVED",
    "I_FORCED",
    "I_HI",
    "I_LASTTGT",
    "I_LO",
    "I_MODE",
    "I_SIDE",
    "I_TARGET",
    "I_TRIAL",
    "I_TURN",
    "I_TVIS",
    "MODE_APPROACH",
    "MODE_DOCK",
    "MODE_ESCAPE",
    "MODE_SERVICE",
    "MODE_UNDOCK",
    "MODE_WALLFOLLOW",
    "N_FPARAM",
    "N_FSTATE",
    "N_GPARAM",
    "N_ISTATE",
    "T_CODE",
    "T_NX",
    "T_NY",
    "T_WALL",
    "T_X",
    "T_Y",
]
