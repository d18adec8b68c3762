"""A trial's clock, in ticks: when something scheduled falls due, and when a trial ends.

A trial's clock reads `tick * dt` seconds since it started (its warm-up's start, if it has
one). The engine (`engine.BatchEngine`), the planner of shared history (`lineage`) and the
config's validation all count ticks with these two functions, so that they agree to the tick.
"""

from __future__ import annotations

import math


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
