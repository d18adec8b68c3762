"""A trial's clock, in ticks: when something scheduled falls due, and when a trial ends;
and a batch's schedule of what falls due next.

A trial's clock reads `tick * dt` seconds since it started (its warm-up's start, if it has
one). The engine (`engine.BatchEngine`), the planner of shared history (`lineage`) and the
config's validation all count ticks with these two functions, so that they agree to the tick.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any, Protocol


class Scheduled(Protocol):
    """What the schedule reads of a trial (`trial.TrialState`): its spec's snapshot and pose
    periods and the time of its next scheduled event."""

    spec: Any

    def next_event_time(self) -> float:
        """Seconds on the trial's clock of its next scheduled event (inf: none)."""


def due_tick(clock_s: float, dt_s: float) -> int:
    """The first tick k whose time k * dt is at or after `clock_s`: the tick at which whatever
    is scheduled for that time falls due (the engine compares exactly this product)."""
    if clock_s <= 0:
        return 0
    k = max(0, math.ceil(clock_s / dt_s))
    while k > 0 and (k - 1) * dt_s >= clock_s:
        k -= 1
    while k * dt_s < clock_s:
        k += 1
    return k


def end_tick(t0_s: float, duration_s: float, dt_s: float) -> int:
    """The tick at which a trial ends that starts at time `t0_s` of its record (minus its warm-up,
    or its late start) and runs to `duration_s` (the ticks before it run)."""
    return int(round((duration_s - t0_s) / dt_s))


def next_multiple(tick: int, every: int) -> int:
    """The first multiple of `every` after `tick`."""
    return (tick // every + 1) * every


class Schedule:
    """When each trial of a batch next takes a Q-table snapshot or a pose frame, and when
    anything next falls due in the batch (those, or a scheduled event)."""

    def __init__(self, trials: Sequence[Scheduled]) -> None:
        """The first snapshot and pose frame of each trial that takes them, due at 0 on its clock;
        `next_due` is set by `update`."""
        # on the trials' clock, which starts at 0 with the warm-up
        self.next_q = [0.0 if tr.spec.q_snapshot_every_s > 0 else math.inf for tr in trials]
        self.next_pose = [0.0 if tr.spec.pose_every_s > 0 else math.inf for tr in trials]
        self.next_due = -math.inf

    def update(self, trials: Sequence[Scheduled]) -> None:
        """Set `next_due` to the earliest of the trials' next snapshots, pose frames and events."""
        self.next_due = min(min(self.next_q), min(self.next_pose), min(tr.next_event_time() for tr in trials))
