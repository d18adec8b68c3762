"""Arenas as data: a rectangle of walls, bar-coded targets mounted on them, circuits.

An arena knows nothing of robots or physics. It turns the arena's settings into the
arrays the sensing kernels and the physics world need: wall segments, target bar-code
segments (set a millimetre in front of their wall so a laser ray meets the bar-code before
the wall behind it) and, per target, the inward normal of the wall it hangs on. It also
holds where robots may start.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from tavc_cli.vocabulary import SINK, SOURCE

if TYPE_CHECKING:  # the settings are read, never imported, by the simulator's lowest layers
    from tavc_cli.settings import ArenaConfig

_BARCODE_INSET_M = 1e-3
# the outer rectangle is always the first rows of `Arena.walls`: bottom, right, top, left
N_OUTER_WALLS = 4
_INWARD_NORMALS = {"left": (1.0, 0.0), "right": (-1.0, 0.0), "bottom": (0.0, 1.0), "top": (0.0, -1.0)}
# Where a team starts: each centre at random at least START_WALL_MARGIN_M from every wall and
# more than two radii plus START_GAP_M from every other robot (the engine places them; the config
# layer checks a team can be placed).
START_WALL_MARGIN_M = 0.6
START_GAP_M = 0.3


def most_robots(width_m: float, height_m: float, radius_m: float) -> int:
    """More robots than this can never start in the arena: their centres, each more than
    ``d = 2 radius + START_GAP_M`` from the others, lie in the start area, so discs of diameter
    d around them lie in that area grown by d / 2 all round, and no packing of equal discs is
    denser than the hexagonal one (pi / (2 sqrt 3)): n <= 2 area / (sqrt 3 d^2)."""
    spacing = 2 * radius_m + START_GAP_M
    grown = (width_m - 2 * START_WALL_MARGIN_M + spacing) * (height_m - 2 * START_WALL_MARGIN_M + spacing)
    return math.floor(2 * max(grown, 0.0) / (math.sqrt(3) * spacing**2))


@dataclass(frozen=True)
class Target:
    """A source or sink: a bar-code of known id on a wall."""

    name: str
    kind: int  # SOURCE or SINK
    barcode: int
    x: float
    y: float
    normal: tuple[float, float]  # unit vector pointing into the arena


@dataclass(frozen=True)
class Circuit:
    """A transport task class: fetch at `source`, deliver at `sink` (target indices)."""

    name: str
    source: int
    sink: int


@dataclass(frozen=True)
class Arena:
    """Walls, targets and circuits of one arena; all lengths in metres."""

    name: str
    width_m: float
    height_m: float
    walls: np.ndarray  # (n_walls, 4): x1, y1, x2, y2; the outer rectangle first (N_OUTER_WALLS rows)
    targets: tuple[Target, ...]
    circuits: tuple[Circuit, ...]
    barcode_width_m: float

    @property
    def n_circuits(self) -> int:
        """How many circuits the arena has."""
        return len(self.circuits)

    @property
    def target_xy(self) -> np.ndarray:
        """(n_targets, 2) bar-code centres."""
        return np.array([[t.x, t.y] for t in self.targets], dtype=np.float64)

    @property
    def target_normals(self) -> np.ndarray:
        """(n_targets, 2) unit normals of the targets, pointing into the arena."""
        return np.array([t.normal for t in self.targets], dtype=np.float64)

    @property
    def target_barcodes(self) -> np.ndarray:
        """(n_targets,) each target's bar code."""
        return np.array([t.barcode for t in self.targets], dtype=np.int64)

    @property
    def target_segments(self) -> np.ndarray:
        """(n_targets, 4) bar-code segments, inset a millimetre into the arena."""
        segs = np.empty((len(self.targets), 4))
        half = self.barcode_width_m / 2
        for i, t in enumerate(self.targets):
            nx, ny = t.normal
            tx, ty = -ny, nx  # along the wall
            cx, cy = t.x + nx * _BARCODE_INSET_M, t.y + ny * _BARCODE_INSET_M
            segs[i] = (cx - tx * half, cy - ty * half, cx + tx * half, cy + ty * half)
        return segs

    @property
    def target_wall(self) -> np.ndarray:
        """Index of the outer wall (0 bottom, 1 right, 2 top, 3 left) each target hangs on."""
        side = {(0.0, 1.0): 0, (-1.0, 0.0): 1, (0.0, -1.0): 2, (1.0, 0.0): 3}
        return np.array([side[t.normal] for t in self.targets], dtype=np.int64)

    @property
    def target_circuit(self) -> np.ndarray:
        """Circuit index of each target (-1 for a target no circuit uses)."""
        out = np.full(len(self.targets), -1, dtype=np.int64)
        for c, circ in enumerate(self.circuits):
            out[circ.source] = c
            out[circ.sink] = c
        return out



def nearest_wall(x: float, y: float, width: float, height: float) -> tuple[str, tuple[float, float], float, float]:
    """The outer wall nearest to (x, y): its name, inward normal, the position along it and its
    length (ties go to the first of left, right, bottom, top)."""
    walls = {"left": (x, y, height), "right": (width - x, y, height), "bottom": (y, x, width),
             "top": (height - y, x, width)}
    name = min(walls, key=lambda wall: walls[wall][0])
    _, along, length = walls[name]
    return name, _INWARD_NORMALS[name], along, length


def wall_distance(walls: np.ndarray, x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """Distance from each point (x, y: arrays of one shape) to the nearest of `walls` (rows
    x1, y1, x2, y2); infinite with no walls."""
    x, y = np.asarray(x, dtype=np.float64), np.asarray(y, dtype=np.float64)
    best = np.full(np.broadcast(x, y).shape, np.inf)
    for x1, y1, x2, y2 in np.asarray(walls, dtype=np.float64).reshape(-1, 4):
        dx, dy = x2 - x1, y2 - y1
        u = np.clip(((x - x1) * dx + (y - y1) * dy) / (dx * dx + dy * dy), 0.0, 1.0)
        np.minimum(best, np.hypot(x - (x1 + u * dx), y - (y1 + u * dy)), out=best)
    return best


def clear_to_start(arena: Arena, x: float, y: float) -> bool:
    """Whether a robot may start centred at (x, y) as far as interior walls go: at least
    START_WALL_MARGIN_M from each (the start area already keeps that from the outer walls)."""
    inner = arena.walls[N_OUTER_WALLS:]
    return len(inner) == 0 or float(wall_distance(inner, np.array(x), np.array(y))) >= START_WALL_MARGIN_M


def arena_from_config(spec: ArenaConfig) -> Arena:
    """Build an Arena from its settings (an `ArenaConfig`, or the config layer's node of it).

    Bar-codes hang on the outer walls; each target's facing is the inward normal of
    the wall nearest to it. Validation of the numbers is the config layer's job.
    """
    width, height = float(spec.width_m), float(spec.height_m)
    outer = [(0, 0, width, 0), (width, 0, width, height), (width, height, 0, height), (0, height, 0, 0)]
    extra = [tuple(float(v) for v in w) for w in (spec.walls or [])]
    targets = tuple(
        Target(
            name=str(t.name),
            kind=SOURCE if t.kind == "source" else SINK,
            barcode=int(t.barcode),
            x=float(t.x),
            y=float(t.y),
            normal=nearest_wall(float(t.x), float(t.y), width, height)[1],
        )
        for t in spec.targets
    )
    index = {t.name: i for i, t in enumerate(targets)}
    circuits = tuple(Circuit(name=str(c.name), source=index[c.source], sink=index[c.sink]) for c in spec.circuits)
    return Arena(
        name=str(spec.name),
        width_m=width,
        height_m=height,
        walls=np.array(outer + extra, dtype=np.float64),
        targets=targets,
        circuits=circuits,
        barcode_width_m=float(spec.barcode_width_m),
    )
