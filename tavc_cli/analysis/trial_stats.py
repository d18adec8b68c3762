"""One row per trial: what the claims are tested on.

The chapter tests its claims across trials (Student's t-tests at 90 %), so every test
needs per-trial numbers, not the means of `state_time.csv`: the share of the stable
period spent in each group state, and the score value delivered per second in the
stable period, in the convergence period and, when the trial ran a warm-up before an
event, in a window of the same length just before the event. `trial_stats.csv` keeps
them, so `tavc report` can test claims from saved results without the trial records.
It also keeps `settle_s`, when the trial's allocation settled (`settle_time`), and
`policy_settle_s`, when its learners' greedy policies stopped changing (`analysis.qvalues`).
"""

from __future__ import annotations

import math
from collections.abc import Iterable

import numpy as np
import pandas as pd

from tavc_cli.analysis.performance import value_rate
from tavc_cli.analysis.qvalues import q_gaps, trial_policy_stats
from tavc_cli.analysis.states import alive_at_end, all_states, group_order, high_circuit_series, time_shares
from tavc_cli.analysis.table_schemas import Q_GAP_PREFIX
from tavc_cli.experiments.records import TrialRecord
from tavc_cli.notation import STATE_PREFIX, column_state
from tavc_cli.settings import TavcConfig

# a trial's allocation has settled from the first bin after which every bin's mean number of
# robots on the high-value circuit stays within this many robots of its stable-period mean
SETTLE_TOL = 0.5


def settle_time(centres, series, bin_s: float, t_conv: float) -> float:
    """Seconds from t = 0 to the start of the first bin from which the series stays within
    SETTLE_TOL of its mean over the stable period (bins centred at or after t_conv); NaN if
    the last bin is already off, or nothing was defined."""
    centres, series = np.asarray(centres, float), np.asarray(series, float)
    stable = series[(centres >= t_conv) & np.isfinite(series)]
    if not len(stable):
        return math.nan
    level = stable.mean()
    off = ~(np.abs(series - level) <= SETTLE_TOL)  # NaN (undefined) counts as off
    if off[-1]:
        return math.nan
    k = int(np.flatnonzero(off)[-1]) + 1 if off.any() else 0
    return max(float(centres[k] - bin_s / 2), 0.0)


def stable_from(cfg: TavcConfig) -> float:
    """The time of the record from which the stable period is measured: the end of the
    convergence period, or, with `scale.stable_window` = `chapter`, the start of the stable
    period's last stretch as long as the chapter's own stable period (when the stable period is
    longer), so that shares and rates, and their spread over trials, come from windows of the
    chapter's length at every horizon. Trials that end with a number of deliveries (section 1.4)
    have no stable window of the chapter's to match."""
    t_conv, t_end = float(cfg.convergence_s), float(cfg.duration_s)
    paper = cfg.paper
    if cfg.scale.stable_window != "chapter" or paper.deliveries is not None or not paper.duration_s:
        return t_conv
    length = float(paper.duration_s) - float(paper.convergence_s or 0.0)
    return max(t_conv, t_end - length)


def trial_stats(records: Iterable[TrialRecord], cfg: TavcConfig) -> pd.DataFrame:
    """`controller,trial,duration_s,value_rate_stable,value_rate_convergence,value_rate_before,pct_<state>...`
    (`duration_s`: the time of the record the trial ran to, its duration or its n-th delivery).

    Stable period: [convergence_s, duration_s) (to its end for a trial that ended sooner, with
    its n-th delivery), or its last stretch of the chapter's length (`stable_from`);
    convergence period: [0, convergence_s);
    before: [-w, 0) with w = analysis.before_s, or the stable period's length if that is null,
    capped by the warm-up (NaN without one, and for a baseline that started after -w:
    `baseline_lead_s`); a period that begins before a record's start has no rate (NaN).
    A state that never occurred in a trial's stable period has 0 %; a trial whose state was
    never defined in it has NaN in every state column.
    """
    records = list(records)
    t_conv, t_end = float(cfg.convergence_s), float(cfg.duration_s)
    t_stable = stable_from(cfg)
    warm = float(cfg.sim.warmup_s)
    before_s = cfg.analysis.before_s
    before = min(warm, float(before_s) if before_s is not None else t_end - t_stable)
    scheme = cfg.analysis.state
    bin_s = float(cfg.analysis.performance_bin_s)
    states: list[str] = []
    group_names: list[str] = []
    if records:
        first = records[0]
        alive = alive_at_end(first)
        groups = [g for g, a in zip(first.meta["groups"], alive, strict=True) if a]
        sizes = [groups.count(g) for g in group_order(first.meta["groups"], first.meta["speeds_mps"])]
        states = all_states(int(alive.sum()), int(first.meta["n_circuits"]), scheme, sizes)
        group_names = group_order(first.meta["groups"], first.meta["speeds_mps"])
    rows = []
    for rec in records:
        shares = time_shares(rec, t_stable, t_end, scheme)
        row = {
            "controller": rec.meta["controller"], "trial": int(rec.meta["trial"]),
            "duration_s": rec.end_s,
            "value_rate_stable": value_rate(rec, t_stable, t_end),
            "value_rate_convergence": value_rate(rec, 0.0, t_conv) if t_conv > 0 else math.nan,
            "value_rate_before": value_rate(rec, -before, 0.0) if before > 0 else math.nan,
            "settle_s": settle_time(*high_circuit_series(rec, bin_s, 0.0, t_end), bin_s, t_conv)
            if scheme == "circuits" and rec.start_s <= 0.0 else math.nan,  # not for a baseline started late
        }
        row["policy_settle_s"], row["policy_changes"] = trial_policy_stats(rec)
        if len(group_names) > 1:
            gaps = q_gaps(rec)
            row.update({Q_GAP_PREFIX + g: gaps.get(g, math.nan) for g in group_names})
        for s in states:
            row[STATE_PREFIX + s] = shares.get(s, 0.0) if shares else math.nan
        rows.append(row)
    columns = ["controller", "trial", "duration_s", "value_rate_stable", "value_rate_convergence", "value_rate_before",
               "settle_s", "policy_settle_s", "policy_changes",
               *(Q_GAP_PREFIX + g for g in (group_names if len(group_names) > 1 else [])),
               *(STATE_PREFIX + s for s in states)]
    return pd.DataFrame(rows, columns=columns)


def states_of(stats: pd.DataFrame) -> list[str]:
    """The state labels of a trial_stats table, in its column order."""
    return [s for s in map(column_state, stats.columns) if s is not None]
