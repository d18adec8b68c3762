"""A state as the tables write it, read back: numbers joined by colons, the first for the
high-value circuit. For a team on circuits, robots per circuit, most valuable circuit first
(`3:2`, written by `vocabulary.split_label`); for a team of speed groups, each group's robots on
the high-value circuit, fastest group first (`2:1`); `model.csv`'s `split` column writes the
same notation in the circuits' own order.

Every layer that reads a label (the analysis, the model's files, the checks of a folder, the
report, the figures, the surrogate) reads it here, so a label is understood, and refused, the
same way wherever it comes from: only ASCII digits count as numbers, anything else is no state.
Like `vocabulary`, it imports nothing of tavc's, so any layer may import it.
"""

from __future__ import annotations

from collections.abc import Iterable
from functools import lru_cache

MAX_DIGITS = 9  # the most digits a count in a state may have
# a table's column of a state's share of the stable period (`trial_stats.csv`'s `pct_3:2`; `ladder.csv`'s quantities)
STATE_PREFIX = "pct_"


def state_counts(label: object) -> tuple[int, ...] | None:
    """The numbers of a state label (``"3:2"`` -> ``(3, 2)``), in the order written; None where
    `label` is not a string of ASCII digits joined by colons, each at most `MAX_DIGITS` long
    (``"3:-1"``, ``"3.0:2"``, ``" 3:2"``, ``"3:"``). One number alone (``"3"``) reads as a state
    of one count; whether that fits a team is the caller's to check."""
    return _parsed(label) if isinstance(label, str) else None


@lru_cache(maxsize=4096)
def _parsed(label: str) -> tuple[int, ...] | None:
    # a run's tables hold a few dozen states, each read once per interval of every trial
    parts = label.split(":")
    # a count of robots has a few digits; one past Python's limit for int() would raise
    if not all(p.isascii() and p.isdigit() and len(p) <= MAX_DIGITS for p in parts):
        return None
    return tuple(int(p) for p in parts)


def counts_of(label: str) -> tuple[int, ...]:
    """`state_counts`, with a ValueError naming the label where it is not a state."""
    counts = state_counts(label)
    if counts is None:
        raise ValueError(f"{label!r} is not a state (numbers joined by colons, like '3:2')")
    return counts


def high_of(label: str) -> int:
    """The first number of a state: robots on the high-value circuit (a team on circuits) or
    fast robots on it (a team of speed groups)."""
    return counts_of(label)[0]


def join_counts(counts: Iterable[int]) -> str:
    """Counts written as a state (``(3, 2)`` -> ``"3:2"``), in the order given."""
    return ":".join(str(int(c)) for c in counts)


def column_state(column: str) -> str | None:
    """The state a share column is for (``"pct_3:2"`` -> ``"3:2"``); None for any other column."""
    return column[len(STATE_PREFIX):] if column.startswith(STATE_PREFIX) else None
