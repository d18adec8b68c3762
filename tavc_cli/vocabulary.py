"""The words every layer shares, defined once: what a robot's time is spent on, the kinds of
event that change a group's state, the kinds of target, and how a split of robots over circuits
is written.

Any module of tavc may import this one; it imports nothing of tavc's, so the simulator, the
learners, the analysis and the report read the same numbering and notation.
"""

from __future__ import annotations

from collections.abc import Sequence
from enum import IntEnum

import numpy as np

# Where a robot's time goes: one activity per control tick, summed per task. The kernel sets one
# per robot and tick; every delivery record carries the seconds its task spent in each, so that
# slow-downs can be traced to their cause (waiting at an occupied dock, detouring round robots,
# escaping a dead end).
ACT_DRIVE, ACT_AVOID, ACT_WAIT, ACT_DOCK, ACT_SEARCH, ACT_ESCAPE, ACT_IDLE = range(7)
ACTIVITIES = ("drive", "avoid", "wait", "dock", "search", "escape", "idle")
N_ACT = len(ACTIVITIES)

# a target's kind: a robot loads at a source and delivers at a sink
SOURCE, SINK = 0, 1

# readings of what the chapter leaves unsaid (docs/readings.md), today's world first:
# how a robot arrives at a target (`robot.behaviour.arrival`): into its dock spot, or on reading its code at range
ARRIVALS = ("dock", "range")
# how it passes a robot ahead (`robot.behaviour.passing`): the free heading nearest its goal's, or one side first
PASSINGS = ("nearest", "left", "right")
# where the time t of r = w / t starts (`tasks.time_from`): the choice at the sink, or the loading at the source
TIME_FROM = ("choice", "source")


class EventKind(IntEnum):
    """An event's kind, one numbering for the simulator and the analysis, in the order the events
    of one instant apply."""

    BREAKDOWN = 0     # a robot is removed
    VALUE_CHANGE = 1  # the circuits' learning values change
    ARRIVAL = 2       # a robot reaches a source or sink (its last circuit changes)


def split_label(counts: Sequence[int], values: Sequence[float]) -> str:
    """Robots per circuit in the tables' notation: most valuable circuit first (`3:2`)."""
    rank = np.argsort(-np.asarray(values, dtype=np.float64), kind="stable")
    return ":".join(str(int(counts[c])) for c in rank)
