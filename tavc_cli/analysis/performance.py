"""Group performance: score value delivered per second, over time and per period.

Pure functions of trial records (deliveries carry the score value of the circuit
they were made on at the moment of delivery).
"""

from __future__ import annotations

import math
from collections.abc import Iterable

import numpy as np
import pandas as pd

from tavc_cli.analysis.series import bin_edges, over_trials
from tavc_cli.experiments.records import TrialRecord


def value_rate_series(rec: TrialRecord, bin_s: float, t_from: float, t_to: float) -> tuple[np.ndarray, np.ndarray]:
    """(bin centres, score value delivered per second in each bin) for one trial.

    Bins are `bin_s` wide from `t_from`; time left over at the end forms a last, shorter bin
    (its rate is still per second), so no delivery before `t_to` goes uncounted. A trial that
    ended sooner (with its n-th delivery) has a rate over the part of a bin it ran, and NaN
    in the bins after its end; a trial that started late has NaN in the bins that begin
    before its start.
    """
    edges = bin_edges(t_from, t_to, bin_s)
    d = rec.table("deliveries")
    sums, _ = np.histogram(d["t_s"], bins=edges, weights=d["score"])
    centres, start, end = 0.5 * (edges[:-1] + edges[1:]), rec.start_s, rec.end_s
    if end >= edges[-1] and start <= edges[0]:
        return centres, sums / np.diff(edges)
    ran = np.minimum(edges[1:], end) - edges[:-1]
    with np.errstate(invalid="ignore", divide="ignore"):
        return centres, np.where((ran > 0) & (edges[:-1] >= start), sums / ran, np.nan)


def value_rate(rec: TrialRecord, t_from: float, t_to: float) -> float:
    """Mean score value delivered per second over [t_from, t_to), or over the part of it the
    trial ran before it ended (NaN if none, or if the trial started late, after t_from)."""
    t_to = min(t_to, rec.end_s)
    if t_to <= t_from or t_from < rec.start_s:
        return math.nan
    d = rec.table("deliveries")
    mask = (d["t_s"] >= t_from) & (d["t_s"] < t_to)
    return float(d["score"][mask].sum() / (t_to - t_from))


def performance_table(records: Iterable[TrialRecord], bin_s: float, t_from: float, t_to: float) -> pd.DataFrame:
    """`t_s,controller,mean,std,n_trials`: value per second in time bins, over trials."""
    by_ctrl: dict[str, list[np.ndarray]] = {}
    centres = None
    for rec in records:
        centres, rate = value_rate_series(rec, bin_s, t_from, t_to)
        by_ctrl.setdefault(rec.meta["controller"], []).append(rate)
    return over_trials(by_ctrl, centres, "mean", "std", std_of_one=0.0)
