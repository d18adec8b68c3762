"""The learners' Q-tables over time, and when their greedy policies stop changing.

A TAVC robot's table Q[s, a] has one row per state (the circuit it last served) and one
column per action (the circuit it takes next). The trial records keep every robot's table
on a grid (`sim.q_snapshot_every_s`) and once more at the end. `q_values.csv` keeps them
in a wide form, one row per snapshot and robot (`q_<state>_<action>`), so figures can be
drawn without the trial records. A long run takes its snapshots on the chapter's grid, so it
has time_factor times as many: `q_value_table(records, every_s)` then keeps only those at
whole multiples of `every_s` (within THIN_TOL_S of one; times from t = 0) and the record's
last one. `experiment._analyse` passes the snapshot period times `scale.time_factor`, which
leaves about as many rows per trial as a chapter-length run has. With `every_s` None or not
longer than the record's own snapshot period, the table is every snapshot, unchanged.

Policy settling (`policy_settle_s`): the greedy policy of a robot is its best action in every
state. A trial's policies have settled at the first snapshot from which no live robot's greedy
policy changes again; counted from t = 0 (an event, when the run has a warm-up), NaN when a
policy still changed between the last two snapshots. The resolution is the snapshot period.
A settling time of 0 means no greedy policy changed at all: the allocation is the one the
initial tables (or the warm-up) gave. `policy_changes` counts the changes, robot by robot.
"""

from __future__ import annotations

import math
from collections.abc import Iterable

import numpy as np
import pandas as pd

from tavc_cli.analysis.states import alive_at_end
from tavc_cli.experiments.records import TrialRecord

# snapshot times are sums of ticks (t0 + k dt): "a multiple of every_s" allows for their rounding
THIN_TOL_S = 1e-6


def q_columns(n_states: int, n_actions: int) -> list[str]:
    """The Q-value columns of `q_value_table`, `q_<state>_<action>`, state by state."""
    return [f"q_{s}_{a}" for s in range(n_states) for a in range(n_actions)]


def q_value_table(records: Iterable[TrialRecord], every_s: float | None = None) -> pd.DataFrame | None:
    """`controller,trial,robot,t_s,q_<s>_<a>...` for every record with Q snapshots; None if none has.

    With `every_s` longer than a record's snapshot period, only its snapshots at multiples of
    `every_s` (within THIN_TOL_S) and its last one are kept.
    """
    frames = []
    for rec in records:
        q = np.asarray(rec.q)
        if q.ndim != 4 or not len(q):
            continue
        q_t = np.asarray(rec.q_t, float)
        keep = thinned(q_t, every_s)
        if keep is not None:
            q, q_t = q[keep], q_t[keep]
        n_snap, n_robots, n_s, n_a = q.shape
        frame = pd.DataFrame(q.reshape(n_snap * n_robots, n_s * n_a), columns=q_columns(n_s, n_a))
        frame.insert(0, "t_s", np.repeat(q_t, n_robots))
        frame.insert(0, "robot", np.tile(np.arange(n_robots), n_snap))
        frame.insert(0, "trial", int(rec.meta["trial"]))
        frame.insert(0, "controller", rec.meta["controller"])
        frames.append(frame)
    return pd.concat(frames, ignore_index=True) if frames else None


def thinned(q_t: np.ndarray, every_s: float | None) -> np.ndarray | None:
    """The snapshots to keep (bool per snapshot) at one per `every_s`, or None to keep all: when
    every_s is None or not longer than the record's period (its longest gap between snapshots:
    the one to the final snapshot, at the end of the run, may be shorter)."""
    if every_s is None or len(q_t) < 2 or every_s <= float(np.diff(q_t).max()) + THIN_TOL_S:
        return None
    keep = np.abs(q_t - np.round(q_t / every_s) * every_s) <= THIN_TOL_S
    keep[-1] = True
    return keep


def policy_changes(q_t, q) -> tuple[np.ndarray, np.ndarray]:
    """(snapshot times, (n_snap, n_robots) bool: robot's greedy policy differs from the previous
    snapshot's); the first snapshot has no change."""
    q = np.asarray(q)
    greedy = np.argmax(q, axis=3)  # (n_snap, n_robots, n_states)
    changed = np.zeros(greedy.shape[:2], dtype=bool)
    changed[1:] = (greedy[1:] != greedy[:-1]).any(axis=2)
    return np.asarray(q_t, float), changed


def policy_settle_time(q_t, q, robots: np.ndarray | None = None, t0: float = 0.0) -> float:
    """Seconds from t0 to the first snapshot from which the greedy policies of `robots` (all if
    None) never change again; NaN if they changed at the last snapshot or there are fewer than
    two snapshots from t0 on (the last snapshot at or before t0 is the reference)."""
    t, changed = policy_changes(q_t, q)
    if robots is not None:
        changed = changed[:, robots]
    start = int(np.searchsorted(t, t0, side="right")) - 1  # the reference: last snapshot at or before t0
    start = max(start, 0)
    t, changed = t[start:], changed[start:].any(axis=1)
    changed[0] = False
    if len(t) < 2 or changed[-1]:
        return math.nan
    if not changed.any():
        return max(float(t[0]) - t0, 0.0)
    k = int(np.flatnonzero(changed)[-1])
    return float(t[k]) - t0


def trial_policy_stats(rec: TrialRecord, t0: float = 0.0) -> tuple[float, float]:
    """(`policy_settle_s`, `policy_changes`) of one trial, over the robots alive at its end:
    when their greedy policies stopped changing, and how many times one of them changed
    (robot-snapshots) from t0 on; NaN for both without Q snapshots."""
    q = np.asarray(rec.q)
    if q.ndim != 4 or len(q) < 2:
        return math.nan, math.nan
    robots = np.flatnonzero(alive_at_end(rec))
    t, changed = policy_changes(rec.q_t, q)
    n_changes = float(changed[t > t0][:, robots].sum())
    return policy_settle_time(rec.q_t, q, robots, t0), n_changes


def final_values(rec: TrialRecord) -> np.ndarray:
    """The learning values in force at the end of the trial (after any value change)."""
    changes = np.asarray(rec.value_changes)
    return changes[-1] if changes.ndim == 2 and len(changes) else np.asarray(rec.meta["values"], float)


def q_gaps(rec: TrialRecord) -> dict[str, float]:
    """Per group of robots: the mean over its robots alive at the end of Q(s, high) - Q(s, low),
    averaged over states s, in the final tables (high/low: the circuits of the highest and lowest
    value at the end); empty without Q snapshots or with fewer than two circuits."""
    q = np.asarray(rec.q)
    values = final_values(rec)
    if q.ndim != 4 or not len(q) or len(values) < 2:
        return {}
    high, low = int(np.argmax(values)), int(np.argmin(values))
    gap = (q[-1][:, :, high] - q[-1][:, :, low]).mean(axis=1)  # per robot
    alive = alive_at_end(rec)
    groups = np.asarray(rec.meta["groups"])
    return {str(g): float(gap[(groups == g) & alive].mean()) for g in dict.fromkeys(rec.meta["groups"])
            if ((groups == g) & alive).any()}
