"""What each robot did in a trial's stable period, from its task choices.

A robot is a *stayer* on a circuit if at least STAYER_SHARE of its choices in the
period were that circuit; an *alternator* if at least ALTERNATOR_RATE of its choices
switched circuit; otherwise *mixed*. A robot that made fewer than MIN_CHOICES choices
in the period (broken down, or stuck) is *idle*. The thresholds were fixed before any
trial was classified: with the chapter's epsilon = 0.1 a robot that always prefers one
circuit still explores about one choice in twenty away from it.
"""

from __future__ import annotations

from collections.abc import Iterable

import numpy as np
import pandas as pd

from tavc_cli.experiments.records import TrialRecord

STAYER_SHARE = 0.9
ALTERNATOR_RATE = 0.5
MIN_CHOICES = 5
COLUMNS = ["controller", "trial", "robot", "kind", "circuit", "n_choices", "share_main", "switch_rate"]


def robot_rows(rec: TrialRecord, t_from: float, t_to: float) -> list[dict]:
    """One row per robot of `rec` (`COLUMNS`) over its choices in [t_from, t_to): how many, the
    share of the circuit it chose most, how often its choice left the circuit it had served, and its
    kind (idle below `MIN_CHOICES` choices, else stayer, alternator or mixed; a stayer's
    circuit)."""
    c = rec.table("choices")
    rows = []
    for robot in range(int(rec.meta["n_robots"])):
        m = (c["robot"] == robot) & (c["t_s"] >= t_from) & (c["t_s"] < t_to)
        chosen, last = c["circuit"][m], c["state"][m]
        n = int(m.sum())
        row = {"controller": rec.meta["controller"], "trial": int(rec.meta["trial"]), "robot": robot,
               "n_choices": n, "circuit": -1, "share_main": np.nan, "switch_rate": np.nan}
        if n < MIN_CHOICES:
            rows.append({**row, "kind": "idle"})
            continue
        counts = np.bincount(chosen, minlength=int(rec.meta["n_circuits"]))
        main = int(np.argmax(counts))
        share = counts[main] / n
        rate = float(np.mean(chosen != last))
        kind = "stayer" if share >= STAYER_SHARE else ("alternator" if rate >= ALTERNATOR_RATE else "mixed")
        rows.append({**row, "kind": kind, "circuit": main if kind == "stayer" else -1, "share_main": share,
                     "switch_rate": rate})
    return rows


def robot_table(records: Iterable[TrialRecord], t_from: float, t_to: float) -> pd.DataFrame:
    """`robots.csv`: one row per robot and trial."""
    return pd.DataFrame([r for rec in records for r in robot_rows(rec, t_from, t_to)], columns=COLUMNS)


def robot_summary(table: pd.DataFrame) -> dict[str, dict[str, float]]:
    """controller -> mean number of robots per trial of each kind."""
    out = {}
    for ctrl, g in table.groupby("controller", sort=False):
        n_trials = g["trial"].nunique()
        out[str(ctrl)] = {k: float((g["kind"] == k).sum()) / n_trials
                          for k in ("stayer", "alternator", "mixed", "idle")}
    return out
