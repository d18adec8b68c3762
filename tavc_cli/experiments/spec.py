"""What one trial needs, as plain data: built from a resolved config, no Hydra here.

A `TrialSpec` fixes a trial completely together with its seed. Specs of one
experiment differ only in their index, seed and controller, so trials can be
advanced side by side in one process.
"""

from __future__ import annotations

import hashlib
import json
from collections.abc import Mapping
from dataclasses import asdict, dataclass
from functools import cache
from pathlib import Path

import numpy as np

from tavc_cli import meaning_digest
from tavc_cli.learning.parameters import LearnerSettings, PluginSettings
from tavc_cli.learning.plugins import target_digest
from tavc_cli.settings import ArenaConfig, RobotConfig
from tavc_cli.sim.arena import Arena, arena_from_config


@dataclass(frozen=True)
class Breakdown:
    """A robot fails at `time_s`: a given robot, or one picked at random among those
    whose last target was on `circuit` ('high', 'low', an index, or None for any)."""

    time_s: float
    robot: int | None = None
    circuit: str | int | None = None


@dataclass(frozen=True)
class ValueChange:
    """The circuits' learning values become `values` at `time_s`."""
    time_s: float
    values: tuple[float, ...]


@dataclass(frozen=True)
class TrialSpec:
    """Everything that determines one trial, given its seed."""

    arena: ArenaConfig
    robot: RobotConfig
    speeds_mps: tuple[float, ...]
    groups: tuple[str, ...]
    policy: LearnerSettings
    values: tuple[float, ...]
    score_values: tuple[float, ...]
    time_unit_s: float
    duration_s: float
    warmup_s: float = 0.0
    start_s: float = 0.0  # a trial that starts late starts at this time of the record (then without warm-up)
    deliveries: int | None = None  # the trial ends with the tick of its n-th delivery after the warm-up
    dt_s: float = 0.1
    physics_substeps: int = 1
    solver_iterations: int = 10
    breakdowns: tuple[Breakdown, ...] = ()
    value_changes: tuple[ValueChange, ...] = ()
    q_snapshot_every_s: float = 600.0
    pose_every_s: float = 0.0
    # the time t of r = w / t runs from the robot's choice at the sink (the empty leg counts) or,
    # where true, from its loading at the source (`tasks.time_from`)
    time_from_source: bool = False
    controller: str = "main"
    trial: int = 0
    seed: tuple[int, ...] = (0,)
    # what computes the trial: the physical simulator, or the surrogate of the learning dynamics
    # and the measured tasks it draws from (`tavc_cli.surrogate`)
    engine: str = "physics"

    @property
    def n_robots(self) -> int:
        """The team's size: one robot per speed."""
        return len(self.speeds_mps)

    @property
    def t0_s(self) -> float:
        """The time of the record at the trial's first tick: before t = 0 by its warm-up, or
        after it for a trial that starts late (nothing before its start is simulated)."""
        return self.start_s - self.warmup_s

    @property
    def span_s(self) -> float:
        """Seconds the trial runs from its first tick to its duration (at most, for a trial
        that ends with a number of deliveries)."""
        return self.duration_s - self.t0_s

    def build_arena(self) -> Arena:
        """The arena the trial runs in, built from its config."""
        return arena_from_config(self.arena)

    def key(self) -> str:
        """A digest of everything that fixes the trial's outcome, the simulator's own code and a
        learner from outside tavc's own (`plugins.target_digest`) included, so a rerun reuses a
        trial only if it would come out the same."""
        blob = json.dumps(asdict(self), sort_keys=True, default=_jsonable) + code_digest()
        if isinstance(self.policy, PluginSettings):
            blob += target_digest(str(self.policy.target))
        return hashlib.sha256(blob.encode()).hexdigest()[:20]


_OUTCOME_CODE = ("kernel.py", "vocabulary.py", "sim", "behaviours", "learning", "experiments/engine.py",
                 "experiments/arrivals.py", "experiments/clock.py", "experiments/spec.py", "experiments/tick.py",
                 "experiments/trial.py", "experiments/records.py")


@cache
def code_digest() -> str:
    """Digest of the code that decides a trial's outcome (`meaning_digest`: what it computes,
    not its docstrings, comments or layout, which decide nothing)."""
    return meaning_digest(Path(__file__).resolve().parent.parent, _OUTCOME_CODE)


def _jsonable(obj):
    if isinstance(obj, np.generic):
        return obj.item()
    if isinstance(obj, np.ndarray):
        return obj.tolist()
    if isinstance(obj, Mapping):
        return dict(obj)
    return str(obj)
