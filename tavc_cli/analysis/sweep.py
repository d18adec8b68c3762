"""A sweep's jobs side by side: `sweep.csv` from each job's own tables (never simulates)."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path

import pandas as pd


def sweep_table(jobs: Sequence[tuple[Mapping[str, str], Path]]) -> pd.DataFrame:
    """One row per job, controller and state: the swept values, the job's folder, the mean and std
    % of the stable period in the state over trials, and the controller's mean score per second
    in the stable period. Jobs without a state table (one-circuit runs) give no rows."""
    rows = []
    for index, (values, folder) in enumerate(jobs):
        states, stats = Path(folder) / "state_time.csv", Path(folder) / "trial_stats.csv"
        if not states.is_file():
            continue
        rate = (pd.read_csv(stats).groupby("controller")["value_rate_stable"].mean()
                if stats.is_file() else pd.Series(dtype=float))
        for r in pd.read_csv(states).itertuples(index=False):
            rows.append({"job": index, **values, "output_dir": str(folder), "controller": r.controller,
                         "state": r.state, "mean_pct": r.mean_pct, "std_pct": r.std_pct,
                         "value_rate_stable": float(rate.get(r.controller, float("nan")))})
    return pd.DataFrame(rows)
