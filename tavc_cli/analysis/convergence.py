"""Have the learners converged by the end of a trial? Per-trial measures and a verdict.

A run that is too short for its learners shows it in their Q-tables before it shows it in the
group's states: with alpha = 0.1 and gamma = 0.95 a Q-value moves toward its target by
alpha (1 - gamma) = 0.005 of the gap per task in the long run, so a table still climbing
changes by tens of per cent over the last quarter of a short run, and by well under 5 % once
settled. `convergence.csv` keeps, for every trial whose controller has Q-tables (two
snapshots at least), measures over the run's last quarter [0.75 end, end] (the run is the
record after t = 0; end = `TrialRecord.end_s`), counting the robots alive at the end only:

- `q_drift`: per robot, max |Q_end - Q_ref| / max |Q_end| over (state, action), Q_end the
  last snapshot and Q_ref the last one at or before the quarter's start (the first if none);
  the median over robots.
- `policy_changed_share`: the share of robots whose greedy policy changed at a snapshot in
  the quarter (after its start, up to its end).
- `alloc_first_half`, `alloc_second_half`, `alloc_drift`: the time-weighted mean number of
  robots on the high-value circuit in the two halves of the stable period
  [convergence_s, end), read from the `circuits` states whatever the analysis' scheme (they
  count every robot working at the time), and second - first.
- `td_error_rel`: the mean signed TD error of the quarter's deliveries,
  reward + gamma max_a Q[c, a] - Q[s, c] (c the delivered circuit, s the state it was chosen
  from, Q the robot's table at the last snapshot at or before the delivery), over the mean
  |Q| of the final tables: near 0 when the values are where the rewards hold them, positive
  while they still climb. NaN where the tables are not circuit by circuit (behaviour learners).

`convergence_verdict` applies three thresholds, fixed before any long run was looked at:
Q_DRIFT_MAX on the median drift, POLICY_CHANGED_MAX on the mean share of changed policies
and ALLOC_DRIFT_MAX on the mean |alloc_drift|.
"""

from __future__ import annotations

import math
from collections.abc import Iterable

import numpy as np
import pandas as pd

from tavc_cli.analysis.qvalues import policy_changes
from tavc_cli.analysis.states import alive_at_end, state_intervals
from tavc_cli.experiments.records import TrialRecord
from tavc_cli.notation import high_of

Q_DRIFT_MAX = 0.05
POLICY_CHANGED_MAX = 0.10
ALLOC_DRIFT_MAX = 0.25
# the last quarter of the run: [LAST_SHARE * end, end]
LAST_SHARE = 0.75
# record times are sums of ticks (t0 + k dt): "at or before" allows for their rounding
EPS_S = 1e-6
COLUMNS = ["controller", "trial", "t_from_s", "t_to_s", "q_drift", "policy_changed_share", "alloc_first_half",
           "alloc_second_half", "alloc_drift", "td_error_rel"]
CRITERIA = ("q_drift", "policy_changed_share", "alloc_drift")


def has_q(rec: TrialRecord, min_snapshots: int = 1) -> bool:
    """Whether the record holds at least `min_snapshots` Q-table snapshots."""
    q = np.asarray(rec.q)
    return q.ndim == 4 and len(q) >= min_snapshots


def circuit_tables(rec: TrialRecord) -> bool:
    """Whether the record's Q-tables are circuit by circuit (state: circuit last served, action:
    circuit taken next), as the task learners' are; a behaviour learner's are not."""
    n_c = int(rec.meta["n_circuits"])
    return has_q(rec) and np.asarray(rec.q).shape[2:] == (n_c, n_c)


def snapshot_at(q_t: np.ndarray, t: float) -> int:
    """Index of the last snapshot at or before t; -1 if there is none."""
    return int(np.searchsorted(np.asarray(q_t, float), t + EPS_S, side="right")) - 1


def q_drift(rec: TrialRecord, t_from: float, live: np.ndarray) -> float:
    """Median over the `live` robots of max |Q_end - Q_ref| / max |Q_end| (module docstring)."""
    q = np.asarray(rec.q)
    ref = q[max(snapshot_at(rec.q_t, t_from), 0)][live]
    end = q[-1][live]
    scale = np.abs(end).max(axis=(1, 2))
    with np.errstate(invalid="ignore", divide="ignore"):
        drift = np.abs(end - ref).max(axis=(1, 2)) / scale
    drift = drift[np.isfinite(drift)]  # a table of zeros has no relative drift
    return float(np.median(drift)) if len(drift) else math.nan


def policy_changed_share(rec: TrialRecord, t_from: float, t_to: float, live: np.ndarray) -> float:
    """Share of the `live` robots whose greedy policy changed at a snapshot in (t_from, t_to]."""
    if not live.any():
        return math.nan
    t, changed = policy_changes(rec.q_t, rec.q)
    inside = (t > t_from + EPS_S) & (t <= t_to + EPS_S)
    return float(changed[inside][:, live].any(axis=0).mean())


def high_count_mean(rec: TrialRecord, t_from: float, t_to: float) -> float:
    """Time-weighted mean number of robots whose last target was on the high-value circuit over
    [t_from, t_to), from the `circuits` states; NaN if no state was defined in it."""
    weighted = covered = 0.0
    for a, b, s in state_intervals(rec, "circuits"):
        lo, hi = max(a, t_from), min(b, t_to)
        if hi > lo and s is not None:
            weighted += high_of(s) * (hi - lo)  # robots on the high circuit
            covered += hi - lo
    return weighted / covered if covered > 0 else math.nan


def alloc_halves(rec: TrialRecord, convergence_s: float) -> tuple[float, float]:
    """`high_count_mean` over the first and the second half of [convergence_s, end)."""
    end = rec.end_s
    if end <= convergence_s:
        return math.nan, math.nan
    mid = 0.5 * (convergence_s + end)
    return high_count_mean(rec, convergence_s, mid), high_count_mean(rec, mid, end)


def td_errors(rec: TrialRecord, t_from: float, t_to: float, gamma: float, live: np.ndarray) -> np.ndarray:
    """Signed TD errors of the deliveries in [t_from, t_to] by `live` robots (module docstring), in
    robot and circuit order; a delivery without the choice that started it, or before the first
    snapshot, is left out."""
    d, c = rec.table("deliveries"), rec.table("choices")
    q = np.asarray(rec.q)
    robots, circuits = d["robot"].astype(int), d["circuit"].astype(int)
    pick = (d["t_s"] >= t_from - EPS_S) & (d["t_s"] <= t_to + EPS_S) & live[robots]
    out = []
    for robot, circuit in sorted(set(zip(robots[pick].tolist(), circuits[pick].tolist(), strict=True))):
        k = np.flatnonzero(pick & (robots == robot) & (circuits == circuit))
        # the choice that sent the robot on each task: its latest choice of this circuit by the task's start
        mine = np.flatnonzero((c["robot"] == robot) & (c["circuit"] == circuit))
        mine = mine[np.argsort(c["t_s"][mine], kind="stable")]
        start = d["t_s"][k] - d["task_time_s"][k]
        chose = np.searchsorted(c["t_s"][mine], start + EPS_S, side="right") - 1
        snap = np.searchsorted(np.asarray(rec.q_t, float), d["t_s"][k] + EPS_S, side="right") - 1
        ok = (chose >= 0) & (snap >= 0)
        k, snap, state = k[ok], snap[ok], c["state"][mine[chose[ok]]].astype(int)
        tables = q[snap, robot]  # (n, n_states, n_actions)
        n = np.arange(len(k))
        out.append(d["reward"][k] + gamma * tables[n, circuit].max(axis=1) - tables[n, state, circuit])
    return np.concatenate(out) if out else np.zeros(0)


def td_error_rel(rec: TrialRecord, t_from: float, t_to: float, gamma: float, live: np.ndarray) -> float:
    """Mean TD error of the quarter's deliveries over the mean |Q| of the live robots' last tables."""
    if not circuit_tables(rec) or "choices" not in rec.tables:
        return math.nan
    delta = td_errors(rec, t_from, t_to, gamma, live)
    scale = float(np.abs(np.asarray(rec.q)[-1][live]).mean()) if live.any() else 0.0
    return float(delta.mean()) / scale if len(delta) and scale > 0 else math.nan


def convergence_row(rec: TrialRecord, convergence_s: float, gamma: float) -> dict:
    """One trial's row of `convergence.csv` (the record has two Q snapshots at least)."""
    t_to = rec.end_s
    t_from = LAST_SHARE * t_to
    live = alive_at_end(rec)
    first, second = alloc_halves(rec, convergence_s)
    return {"controller": rec.meta["controller"], "trial": int(rec.meta["trial"]), "t_from_s": t_from,
            "t_to_s": t_to, "q_drift": q_drift(rec, t_from, live) if live.any() else math.nan,
            "policy_changed_share": policy_changed_share(rec, t_from, t_to, live),
            "alloc_first_half": first, "alloc_second_half": second, "alloc_drift": second - first,
            "td_error_rel": td_error_rel(rec, t_from, t_to, gamma, live)}


def convergence_table(records: Iterable[TrialRecord], convergence_s: float, gamma: float) -> pd.DataFrame:
    """`convergence.csv`: one row per trial with two Q snapshots or more (the learners')."""
    rows = [convergence_row(rec, convergence_s, gamma) for rec in records if has_q(rec, 2)]
    return pd.DataFrame(rows, columns=COLUMNS)


def convergence_verdict(table: pd.DataFrame, controller: str = "tavc") -> dict:
    """Whether `controller`'s trials have converged by the three criteria (module docstring).

    Returns n_trials, the median q_drift, the mean policy_changed_share, the mean |alloc_drift|,
    the mean td_error_rel, `converged` (all three met) and `failed` (the names of those not met).
    An alloc_drift that is NaN in every trial (no state defined) counts as met; a NaN q_drift
    or policy share does not.
    """
    mine = table[table["controller"] == controller]
    out = {"n_trials": int(len(mine)),
           "q_drift": float(mine["q_drift"].median()),
           "policy_changed_share": float(mine["policy_changed_share"].mean()),
           "alloc_drift": float(mine["alloc_drift"].abs().mean()),
           "td_error_rel": float(mine["td_error_rel"].mean())}
    met = {"q_drift": out["q_drift"] < Q_DRIFT_MAX,
           "policy_changed_share": out["policy_changed_share"] <= POLICY_CHANGED_MAX,
           # pandas' mean skips NaN: it is NaN only when every trial's drift is
           "alloc_drift": math.isnan(out["alloc_drift"]) or out["alloc_drift"] < ALLOC_DRIFT_MAX}
    failed = [name for name in CRITERIA if not met[name]]
    return {**out, "converged": not failed, "failed": failed}
