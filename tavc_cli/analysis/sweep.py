"""A sweep's jobs side by side: `sweep.csv` from each job's own tables (never simulates; read by
`run_tables.sweep_table`)."""

from __future__ import annotations

from collections.abc import Mapping

import pandas as pd


def job_rows(index: int, values: Mapping[str, str], folder: str, states: pd.DataFrame,
             stats: pd.DataFrame | None) -> list[dict]:
    """Job `index`'s rows, one per controller and state: the swept values, the job's folder, the mean
    and std % of the stable period in the state over trials (`states`: its state_time.csv), and the
    controller's mean score per second in the stable period (`stats`: its trial_stats.csv, if any)."""
    rate = (stats.groupby("controller")["value_rate_stable"].mean() if stats is not None
            else pd.Series(dtype=float))
    return [{"job": index, **values, "output_dir": folder, "controller": r.controller, "state": r.state,
             "mean_pct": r.mean_pct, "std_pct": r.std_pct,
             "value_rate_stable": float(rate.get(r.controller, float("nan")))} for r in states.itertuples(index=False)]
