"""The horizon ladder: initial_distribution at several multiples of the chapter's durations,
side by side (`ladder.csv`), from each rung's saved tables only (read by `run_tables.read_rung`).

A rung is one folder of `tavc run` output whose `config.yaml` holds its factor
(`scale.time_factor`). The rungs' trials are prefixes of one another (the same seeds, the
same world and rule, only longer), so the ladder shows one set of groups at several ages.
Per rung and controller the table holds, as `quantity` rows:

- `pct_<state>`: % of the stable period in each state (mean, std over trials);
- `value_rate_stable`: score per second in the stable period;
- `claim<k>_statistic`, `claim<k>_p`, `claim<k>_reproduced` (claims 3 and 5 on TAVC's rows, 4 on
  random's, as
  the rung's own `claims.csv` tests them; 1 reproduced, 0 not, NaN inconclusive);
- the learner-side convergence measures (`analysis.convergence`): `q_drift` (median over
  trials), `policy_changed_share`, `alloc_drift` (mean |drift|), `td_error_rel` and `converged`
  (1 or 0, by the criteria fixed in that module before any long run was looked at);
- how the group is made in the stable period (`analysis.mechanism`): robots per trial that are
  `n_stayers_high`, `n_stayers_low`, `n_alternators`, `n_mixed`, the `switch_share` of tasks,
  the mean `task_s_stay` and `task_s_switch`, and `q_gap_stay_switch`.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import pandas as pd

from tavc_cli.analysis.convergence import convergence_verdict
from tavc_cli.notation import STATE_PREFIX

LADDER_COLUMNS = ["factor", "duration_s", "controller", "quantity", "mean", "std", "n_trials"]
LADDER_CLAIMS = (3, 4, 5)
CLAIM_CONTROLLER = {4: "random"}  # claim 4 is about random allocation; 3 and 5 about the learners
MECHANISM_QUANTITIES = ("n_stayers_high", "n_stayers_low", "n_alternators", "n_mixed", "switch_share",
                        "task_s_stay", "task_s_switch", "q_gap_stay_switch")


def _row(factor: float, duration: float, controller: str, quantity: str, mean: float, std: float = math.nan,
         n: int = 0) -> dict:
    return {"factor": factor, "duration_s": duration, "controller": controller, "quantity": quantity,
            "mean": mean, "std": std, "n_trials": n}


@dataclass(frozen=True)
class Rung:
    """One rung as its folder holds it: its multiple of the chapter's durations, its duration, and
    its tables by name (``state_time``, ``trial_stats``; ``claims``, ``convergence`` and
    ``mechanism`` where the run wrote them)."""

    factor: float
    duration_s: float
    tables: Mapping[str, pd.DataFrame]


def rung_rows(rung: Rung) -> list[dict]:
    """Every row of `ladder.csv` for one rung."""
    factor, duration, tables = rung.factor, rung.duration_s, rung.tables
    rows = []
    for r in tables["state_time"].itertuples():
        rows.append(_row(factor, duration, r.controller, f"{STATE_PREFIX}{r.state}", r.mean_pct, r.std_pct,
                         int(r.n_trials)))
    stats = tables["trial_stats"]
    for controller, group in stats.groupby("controller", sort=False):
        x = group["value_rate_stable"].dropna()
        rows.append(_row(factor, duration, str(controller), "value_rate_stable", x.mean(),
                         x.std(ddof=1) if len(x) > 1 else math.nan, len(x)))
    if "claims" in tables:
        claims = tables["claims"]
        for r in claims[claims["claim_id"].isin(LADDER_CLAIMS)].itertuples():
            who = CLAIM_CONTROLLER.get(int(r.claim_id), "tavc")  # whose trials the claim is about
            n = int((stats["controller"] == who).sum())
            verdict = {"reproduced": 1.0, "not_reproduced": 0.0}.get(r.verdict, math.nan)
            rows += [_row(factor, duration, who, f"claim{r.claim_id}_statistic", r.statistic, n=n),
                     _row(factor, duration, who, f"claim{r.claim_id}_p", r.p_value, n=n),
                     _row(factor, duration, who, f"claim{r.claim_id}_reproduced", verdict, n=n)]
    rows += _convergence_rows(tables.get("convergence"), factor, duration)
    rows += _mechanism_rows(tables.get("mechanism"), factor, duration)
    return rows


def _convergence_rows(table: pd.DataFrame | None, factor: float, duration: float) -> list[dict]:
    if table is None:
        return []
    rows = []
    for controller in dict.fromkeys(table["controller"]):
        v = convergence_verdict(table, controller=str(controller))
        n = int(v["n_trials"])
        rows += [_row(factor, duration, str(controller), q, float(v[q]), n=n)
                 for q in ("q_drift", "policy_changed_share", "alloc_drift", "td_error_rel")]
        rows.append(_row(factor, duration, str(controller), "converged", float(bool(v["converged"])), n=n))
    return rows


def _mechanism_rows(table: pd.DataFrame | None, factor: float, duration: float) -> list[dict]:
    if table is None:
        return []
    stable = table[table["window"] == "stable"]
    rows = []
    for controller, group in stable.groupby("controller", sort=False):
        for q in MECHANISM_QUANTITIES:
            x = group[q].dropna()
            rows.append(_row(factor, duration, str(controller), q, x.mean() if len(x) else math.nan,
                             x.std(ddof=1) if len(x) > 1 else math.nan, len(x)))
    return rows


def ladder_table(rungs: Sequence[Rung]) -> pd.DataFrame:
    """`ladder.csv` from the rungs, the shortest horizon first."""
    order = sorted(rungs, key=lambda rung: rung.factor)
    return pd.DataFrame([r for rung in order for r in rung_rows(rung)], columns=LADDER_COLUMNS)


def ladder_value(table: pd.DataFrame, controller: str, quantity: str) -> pd.Series:
    """One quantity of one controller against the factor (a Series indexed by factor)."""
    rows = table[(table["controller"] == controller) & (table["quantity"] == quantity)]
    return pd.Series(rows["mean"].to_numpy(float), index=rows["factor"].to_numpy(float))
