"""Vacancy chains, trial by trial: after an event opens a vacancy on a circuit (a robot
serving it breaks down, or it becomes the high-value circuit), which robot fills it,
from which circuit, how long after the event, and what moves came first.

A *move* is a task choice of a circuit other than the one the robot served last (the
`choices` table: state = the circuit last served, circuit = the one chosen). A move is
*settled* when the robot then chooses the new circuit for the next SETTLE_TASKS - 1
choices as well (so it serves it at least SETTLE_TASKS tasks running); exploratory
one-task visits are not settled. The vacancy is *filled* by the first settled move into
the vacancy circuit after the event. The chain is the list of settled moves from the event
up to and including that one. Both rules were fixed before any trial was looked at.
"""

from __future__ import annotations

import math
from collections.abc import Iterable

import numpy as np
import pandas as pd

from tavc_cli.experiments.records import TrialRecord

SETTLE_TASKS = 3
COLUMNS = ["controller", "trial", "event", "event_t_s", "vacancy_circuit", "filled", "filler", "filler_from",
           "fill_delay_s", "moves_before_fill", "chain"]


def settled_moves(rec: TrialRecord, t_from: float) -> list[tuple[float, int, int, int]]:
    """(t_s, robot, from circuit, to circuit) of every settled move at or after t_from, in time order."""
    c = rec.table("choices")
    out = []
    for robot in np.unique(c["robot"]):
        mask = c["robot"] == robot
        t, last, chosen = c["t_s"][mask], c["state"][mask], c["circuit"][mask]
        order = np.argsort(t, kind="stable")
        t, last, chosen = t[order], last[order], chosen[order]
        for k in range(len(t)):
            if t[k] < t_from or last[k] < 0 or chosen[k] == last[k]:
                continue
            follow = chosen[k:k + SETTLE_TASKS]
            if len(follow) == SETTLE_TASKS and np.all(follow == chosen[k]):
                out.append((float(t[k]), int(robot), int(last[k]), int(chosen[k])))
    return sorted(out)


def _event(rec: TrialRecord) -> tuple[str, float, int] | None:
    """(kind, time, vacancy circuit) of the trial's first event at or after t = 0."""
    b = rec.table("breakdowns")
    after = np.flatnonzero(b["t_s"] >= 0.0)
    vc_t = [t for t in rec.value_changes_t if t >= 0.0]
    if len(after) and (not vc_t or b["t_s"][after[0]] <= vc_t[0]):
        t, robot = float(b["t_s"][after[0]]), int(b["robot"][after[0]])
        a = rec.table("arrivals")
        mine = (a["robot"] == robot) & (a["t_s"] <= t)
        if not np.any(mine):
            return None
        # the circuit of its last target, as the breakdown event chose the robot
        return "breakdown", t, int(a["circuit"][mine][np.argmax(a["t_s"][mine])])
    if vc_t:
        k = list(rec.value_changes_t).index(vc_t[0])
        return "value_change", float(vc_t[0]), int(np.argmax(rec.value_changes[k]))
    return None


def vacancy_row(rec: TrialRecord) -> dict | None:
    """One trial's vacancy chain, or None if the trial has no event."""
    ev = _event(rec)
    if ev is None:
        return None
    kind, t0, vac = ev
    chain, filler = [], None
    for t, robot, frm, to in settled_moves(rec, t0):
        chain.append((t, robot, frm, to))
        if to == vac:
            filler = (t, robot, frm)
            break
    return {
        "controller": rec.meta["controller"], "trial": int(rec.meta["trial"]), "event": kind, "event_t_s": t0,
        "vacancy_circuit": vac, "filled": filler is not None,
        "filler": filler[1] if filler else -1, "filler_from": filler[2] if filler else -1,
        "fill_delay_s": filler[0] - t0 if filler else math.nan,
        "moves_before_fill": len(chain) - 1 if filler else len(chain),
        "chain": "; ".join(f"robot {r} {a}->{b} at +{t - t0:.0f} s" for t, r, a, b in chain),
    }


def vacancy_table(records: Iterable[TrialRecord]) -> pd.DataFrame:
    """`vacancy.csv`: one row per trial that has an event at or after t = 0."""
    rows = [r for r in (vacancy_row(rec) for rec in records) if r is not None]
    return pd.DataFrame(rows, columns=COLUMNS)


def vacancy_summary(table: pd.DataFrame, controller: str = "tavc") -> str:
    """One sentence: how often, how fast and from where the vacancy was filled."""
    t = table[table["controller"] == controller]
    if not len(t):
        return ""
    filled = t[t["filled"].astype(bool)]
    text = f"{controller}: a robot moved onto the short circuit in {len(filled)} of {len(t)} trials"
    if len(filled):
        delays = filled["fill_delay_s"].to_numpy(float)
        text += (f", a median {np.median(delays):.0f} s after the event (range {delays.min():.0f}-{delays.max():.0f} s)"
                 f", with a median of {np.median(filled['moves_before_fill']):.0f} settled moves before the fill")
    return text + "."
