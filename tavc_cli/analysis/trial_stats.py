"""One row per trial: what the claims are tested on.

The chapter tests its claims across trials (Student's t-tests at 90 %), so every test
needs per-trial numbers, not the means of `state_time.csv`: the share of the stable
period spent in each group state, and the score value delivered per second in the
stable period, in the convergence period and, when the trial ran a warm-up before an
event, in a window of the same length just before the event. `trial_stats.csv` keeps
them, so `tavc report` can test claims from saved results without the trial records.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping

import pandas as pd

from tavc_cli.analysis.performance import value_rate
from tavc_cli.analysis.states import alive_at_end, all_states, group_order, time_shares
from tavc_cli.experiments.records import TrialRecord

STATE_PREFIX = "pct_"


def trial_stats(records: Iterable[TrialRecord], cfg: Mapping) -> pd.DataFrame:
    """`controller,trial,value_rate_stable,value_rate_convergence,value_rate_before,pct_<state>...`.

    Stable period: [convergence_s, duration_s); convergence period: [0, convergence_s);
    before: [-w, 0) with w the stable period's length, capped by the warm-up (NaN without one).
    A state that never occurred in a trial's stable period has 0 %; a trial whose state was
    never defined in it has NaN in every state column.
    """
    records = list(records)
    t_conv, t_end = float(cfg["convergence_s"]), float(cfg["duration_s"])
    warm = float(cfg["sim"]["warmup_s"])
    before = min(warm, t_end - t_conv)
    scheme = cfg["analysis"]["state"]
    states: list[str] = []
    if records:
        first = records[0]
        alive = alive_at_end(first)
        groups = [g for g, a in zip(first.meta["groups"], alive, strict=True) if a]
        sizes = [groups.count(g) for g in group_order(first.meta["groups"], first.meta["speeds_mps"])]
        states = all_states(int(alive.sum()), int(first.meta["n_circuits"]), scheme, sizes)
    rows = []
    for rec in records:
        shares = time_shares(rec, t_conv, t_end, scheme)
        row = {
            "controller": rec.meta["controller"], "trial": int(rec.meta["trial"]),
            "value_rate_stable": value_rate(rec, t_conv, t_end),
            "value_rate_convergence": value_rate(rec, 0.0, t_conv) if t_conv > 0 else math.nan,
            "value_rate_before": value_rate(rec, -before, 0.0) if before > 0 else math.nan,
        }
        for s in states:
            row[STATE_PREFIX + s] = shares.get(s, 0.0) if shares else math.nan
        rows.append(row)
    columns = ["controller", "trial", "value_rate_stable", "value_rate_convergence", "value_rate_before",
               *(STATE_PREFIX + s for s in states)]
    return pd.DataFrame(rows, columns=columns)


def states_of(stats: pd.DataFrame) -> list[str]:
    """The state labels of a trial_stats table, in its column order."""
    return [c[len(STATE_PREFIX):] for c in stats.columns if c.startswith(STATE_PREFIX)]
