"""The chapter's state tables beside ours, cell by cell.

Our `state_time.csv` has one row per state and controller (`tavc`, `random`, `theory`);
the chapter's tables have one column per controller and statistic (`tavc_mean_pct`,
`random_std_pct`, `theory_pct`, ...). Every cell the chapter printed gets one row of
`comparison.csv`: `table,state,quantity,chapter,ours,difference` (ours minus the chapter's;
empty where we have no such number, e.g. a controller the run did not include).
Columns the chapter derived from others are compared too, from our own means: Table 1.6's
differences are the learners' share over the binomial theory row (TAVC - theory and
(TAVC - theory) / theory), which is what every one of its rows gives to rounding.
"""

from __future__ import annotations

import math

import pandas as pd

from tavc_cli.chapter import state_table_id
from tavc_cli.reference import chapter_table

COLUMNS = ["table", "state", "quantity", "chapter", "ours", "difference"]


def _ours(state_time: pd.DataFrame) -> dict[tuple[str, str], float]:
    """(state, quantity) -> our number, in the chapter's column names."""
    out: dict[tuple[str, str], float] = {}
    for r in state_time.itertuples():
        if r.controller == "theory":
            out[(r.state, "theory_pct")] = float(r.mean_pct)
        else:
            out[(r.state, f"{r.controller}_mean_pct")] = float(r.mean_pct)
            out[(r.state, f"{r.controller}_std_pct")] = float(r.std_pct)
    for state in {s for s, _ in out}:
        tavc, theory = out.get((state, "tavc_mean_pct")), out.get((state, "theory_pct"))
        if tavc is not None and theory is not None:
            out[(state, "diff_pct")] = tavc - theory
            out[(state, "rel_diff")] = (tavc - theory) / theory if theory > 0 else math.nan
    return out


def compare(state_time: pd.DataFrame, table_id: str) -> pd.DataFrame:
    """Every cell of chapter table `table_id` beside ours."""
    chapter = chapter_table(table_id)
    ours = _ours(state_time)
    rows = []
    for r in chapter.itertuples(index=False):
        for quantity in chapter.columns[1:]:
            ch = float(getattr(r, quantity))
            our = ours.get((r.state, quantity), math.nan)
            rows.append({"table": table_id, "state": r.state, "quantity": quantity, "chapter": ch, "ours": our,
                         "difference": our - ch})
    return pd.DataFrame(rows, columns=COLUMNS)


def experiment_comparison(experiment: str, state_time: pd.DataFrame) -> pd.DataFrame | None:
    """The comparison for an experiment the chapter reports in a state table, else None."""
    table_id = state_table_id(experiment)
    return None if table_id is None else compare(state_time, table_id)
