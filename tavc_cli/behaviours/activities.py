"""Where a robot's time goes: one activity per control tick, summed per task.

The kernel sets one of these per robot and tick; every delivery record carries the
seconds its task spent in each, so that slow-downs can be traced to their cause
(waiting at an occupied dock, detouring round robots, escaping a dead end).
"""

ACT_DRIVE, ACT_AVOID, ACT_WAIT, ACT_DOCK, ACT_SEARCH, ACT_ESCAPE, ACT_IDLE = range(7)
ACTIVITIES = ("drive", "avoid", "wait", "dock", "search", "escape", "idle")
N_ACT = len(ACTIVITIES)
