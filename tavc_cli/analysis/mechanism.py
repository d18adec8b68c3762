"""How the group's allocation is made, trial by trial and over time: by robots that stay on
one circuit (persistence) or by robots that take turns between circuits (turn-taking).

`mechanism.csv` has, for every trial with a `choices` table, one row for the stable period
[convergence_s, end) (window `stable`) and one for each of eight equal windows `w1`..`w8`
over the whole record [start, end), with:

- the robots of each kind in the window (`analysis.robots`), the stayers split into those on
  the circuit of the highest learning value in force at the window's end (`high`) and the
  others (`low`);
- `switch_share`: the share of the window's choices of a circuit other than the one last served;
- per kind of task, *stay* (the same circuit as the robot's previous delivery) or *switch*
  (another one), the mean task time and the mean seconds of it spent avoiding robots and
  waiting (a robot's first delivery has no kind; NaN where a kind has no task);
- `q_gap_stay_switch`: in the last Q snapshot at or before the window's end, the mean over
  the robots alive at the end of the trial and over states s of Q[s, s] - mean_{a != s} Q[s, a];
  positive when staying is preferred (NaN without circuit-by-circuit Q-tables).

`mechanism_summary` names the regime of a controller's stable periods with a rule fixed
before any long run was looked at: *persistence* when stayers make at least REGIME_SHARE
of the working robots (stayers, alternators and mixed), *turn-taking* when alternators do,
else *mixed*.
"""

from __future__ import annotations

import math
from collections.abc import Iterable

import numpy as np
import pandas as pd

from tavc_cli.analysis.convergence import circuit_tables, snapshot_at
from tavc_cli.analysis.robots import robot_rows
from tavc_cli.analysis.states import alive_at_end
from tavc_cli.experiments.records import TrialRecord

N_WINDOWS = 8
PERSISTENCE, TURN_TAKING, MIXED, UNDEFINED = "persistence", "turn-taking", "mixed", "undefined"  # the regimes
REGIME_SHARE = 0.5
COLUMNS = ["controller", "trial", "window", "t_from_s", "t_to_s", "n_stayers_high", "n_stayers_low",
           "n_alternators", "n_mixed", "n_idle", "switch_share", "task_s_stay", "task_s_switch", "avoid_s_stay",
           "avoid_s_switch", "wait_s_stay", "wait_s_switch", "q_gap_stay_switch"]
# the delivery columns averaged per kind of task, and their names in the table
TASK_COLUMNS = {"task_time_s": "task_s", "avoid_s": "avoid_s", "wait_s": "wait_s"}
KIND_COUNTS = ("n_stayers_high", "n_stayers_low", "n_alternators", "n_mixed", "n_idle")


def values_at(rec: TrialRecord, t: float) -> np.ndarray:
    """The learning values in force just before t: the last change before t, else the initial
    values (a change exactly at a window's end comes after the half-open window)."""
    changes_t = np.asarray(rec.value_changes_t, float)
    k = int(np.searchsorted(changes_t, t, side="left")) - 1
    return np.asarray(rec.value_changes, float)[k] if k >= 0 else np.asarray(rec.meta["values"], float)


def kind_counts(rec: TrialRecord, t_from: float, t_to: float) -> dict[str, int]:
    """Robots of each kind in [t_from, t_to), the stayers split by the circuit they stay on."""
    high = int(np.argmax(values_at(rec, t_to)))
    kinds = [(r["kind"], r["circuit"]) for r in robot_rows(rec, t_from, t_to)]
    return {"n_stayers_high": sum(k == "stayer" and c == high for k, c in kinds),
            "n_stayers_low": sum(k == "stayer" and c != high for k, c in kinds),
            "n_alternators": sum(k == "alternator" for k, _ in kinds),
            "n_mixed": sum(k == "mixed" for k, _ in kinds),
            "n_idle": sum(k == "idle" for k, _ in kinds)}


def switch_share(rec: TrialRecord, t_from: float, t_to: float) -> float:
    """Share of the choices in [t_from, t_to) of another circuit than the one last served."""
    c = rec.table("choices")
    m = (c["t_s"] >= t_from) & (c["t_s"] < t_to)
    return float(np.mean(c["circuit"][m] != c["state"][m])) if m.any() else math.nan


def task_kinds(rec: TrialRecord) -> np.ndarray:
    """Per delivery: 1 if a stay task (the circuit of the robot's previous delivery), 0 if a
    switch task, -1 for a robot's first delivery."""
    d = rec.table("deliveries")
    kind = np.full(len(d["t_s"]), -1, dtype=np.int64)
    for robot in np.unique(d["robot"]):
        mine = np.flatnonzero(d["robot"] == robot)
        mine = mine[np.argsort(d["t_s"][mine], kind="stable")]
        kind[mine[1:]] = d["circuit"][mine[1:]] == d["circuit"][mine[:-1]]
    return kind


def task_means(rec: TrialRecord, t_from: float, t_to: float) -> dict[str, float]:
    """Mean task time, avoiding and waiting seconds of the stay and the switch tasks delivered
    in [t_from, t_to) (NaN for a kind without a task, or a column the record lacks)."""
    d = rec.table("deliveries")
    kind = rec.derived.get("task_kinds")
    if kind is None:
        kind = rec.derived["task_kinds"] = task_kinds(rec)
    inside = (d["t_s"] >= t_from) & (d["t_s"] < t_to)
    out = {}
    for col, name in TASK_COLUMNS.items():
        for label, k in (("stay", 1), ("switch", 0)):
            m = inside & (kind == k)
            out[f"{name}_{label}"] = float(d[col][m].mean()) if col in d and m.any() else math.nan
    return out


def q_gap_stay_switch(rec: TrialRecord, t_to: float) -> float:
    """Mean over the robots alive at the end and over states s of Q[s, s] - mean_{a != s} Q[s, a]
    in the last snapshot at or before t_to; NaN without circuit-by-circuit tables or snapshot."""
    snap = snapshot_at(rec.q_t, t_to) if circuit_tables(rec) else -1
    live = alive_at_end(rec)
    q = np.asarray(rec.q)
    if snap < 0 or not live.any() or q.shape[3] < 2:
        return math.nan
    table = q[snap][live]  # (n_live, n, n)
    n = table.shape[1]
    stay = np.einsum("rss->rs", table)
    switch = (table.sum(axis=2) - stay) / (n - 1)
    return float((stay - switch).mean())


def mechanism_rows(rec: TrialRecord, convergence_s: float) -> list[dict]:
    """One trial's rows: the stable period, then the eight windows over the whole record."""
    end = rec.end_s
    edges = np.linspace(rec.start_s, end, N_WINDOWS + 1)
    windows = [("stable", convergence_s, end)]
    windows += [(f"w{k + 1}", float(edges[k]), float(edges[k + 1])) for k in range(N_WINDOWS)]
    rows = []
    for name, t_from, t_to in windows:
        rows.append({"controller": rec.meta["controller"], "trial": int(rec.meta["trial"]), "window": name,
                     "t_from_s": t_from, "t_to_s": t_to, **kind_counts(rec, t_from, t_to),
                     "switch_share": switch_share(rec, t_from, t_to), **task_means(rec, t_from, t_to),
                     "q_gap_stay_switch": q_gap_stay_switch(rec, t_to)})
    return rows


def mechanism_table(records: Iterable[TrialRecord], convergence_s: float) -> pd.DataFrame:
    """`mechanism.csv`: nine rows per trial with a `choices` table."""
    rows = [r for rec in records if "choices" in rec.tables for r in mechanism_rows(rec, convergence_s)]
    return pd.DataFrame(rows, columns=COLUMNS)


def regime(stayers: float, alternators: float, working: float) -> str:
    """`persistence`, `turn-taking` or `mixed` by the REGIME_SHARE rule ("undefined" without
    working robots)."""
    if not working > 0:
        return UNDEFINED
    if stayers >= REGIME_SHARE * working:
        return PERSISTENCE
    return TURN_TAKING if alternators >= REGIME_SHARE * working else MIXED


def mechanism_summary(table: pd.DataFrame, controller: str = "tavc") -> dict:
    """Over `controller`'s stable periods: the mean number of robots of each kind per trial, the
    mean switch share, stay and switch task times (and their seconds avoiding other robots and
    waiting for a dock), the stay-switch Q gap, and the regime."""
    mine = table[(table["controller"] == controller) & (table["window"] == "stable")]
    out: dict = {"n_trials": int(len(mine))}
    for col in (*KIND_COUNTS, "switch_share", "task_s_stay", "task_s_switch", "avoid_s_stay", "avoid_s_switch",
                "wait_s_stay", "wait_s_switch", "q_gap_stay_switch"):
        out[col] = float(mine[col].mean())
    stayers = out["n_stayers_high"] + out["n_stayers_low"]
    out["regime"] = regime(stayers, out["n_alternators"], stayers + out["n_alternators"] + out["n_mixed"])
    return out
