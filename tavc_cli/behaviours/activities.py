"""Where a robot's time goes: one activity per control tick, summed per task.

The kernel sets one of these per robot and tick; every delivery record carries the
seconds its task spent in each, so that slow-downs can be traced to their cause
(waiting at an occupied dock, detouring round robots, escaping a dead end).
"""

ACT_DRIVE, ACT_AVOID, ACT_WAIT, ACT_DOCK, ACT_SEARCH, ACT_ESCAPE, ACT_IDLE = range(7)
ACTIVITIES = ("drive", "avoid", "wait", "dock", "search", "escape", "idle")
ACTIVITY_MEANING = {
    "drive": "driving or turning toward the goal on a free path",
    "avoid": "detouring round, or slowed by, an obstacle (mostly other robots)",
    "wait": "holding back from a dock spot another robot occupies",
    "dock": "the final aligned approach, standing at the dock, backing out",
    "search": "following a wall because localisation was judged wrong",
    "escape": "following a wall to get out of a dead end after a stall",
    "idle": "standing still by choice (the stop behaviour) or with no task",
}
N_ACT = len(ACTIVITIES)
