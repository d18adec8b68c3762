"""The kinds of event that change a group's state, one numbering for the simulator and the
analysis. When several fall on the same instant they apply in this order."""

from enum import IntEnum


class EventKind(IntEnum):
    """An event's kind, numbered in the order events of one instant apply."""
    BREAKDOWN = 0     # a robot is removed
    VALUE_CHANGE = 1  # the circuits' learning values change
    ARRIVAL = 2       # a robot reaches a source or sink (its last circuit changes)
