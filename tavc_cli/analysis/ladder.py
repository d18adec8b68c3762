"""The horizon ladder: initial_distribution at several multiples of the chapter's durations,
side by side (`ladder.csv`), from each rung's saved tables only."""

from __future__ import annotations

from pathlib import Path

import pandas as pd

from tavc_cli.io import write_text_atomic
from tavc_cli.settings import from_yaml

LADDER_COLUMNS = ["factor", "duration_s", "controller", "quantity", "mean", "std", "n_trials"]


def ladder_table(folders: list[Path]) -> pd.DataFrame:
    """`factor,duration_s,controller,quantity,mean,std,n_trials`, one row per rung, controller
    and quantity: the time in each state (`pct_<state>`, % of the stable period) and the score
    per second in the stable period (`value_rate_stable`)."""
    rows = []
    for folder in folders:
        cfg = from_yaml(folder / "config.yaml")
        factor, duration = float(cfg.scale.time_factor), float(cfg.duration_s)
        states = pd.read_csv(folder / "state_time.csv", dtype={"state": str})
        for r in states.itertuples():
            rows.append({"factor": factor, "duration_s": duration, "controller": r.controller,
                         "quantity": f"pct_{r.state}", "mean": r.mean_pct, "std": r.std_pct, "n_trials": r.n_trials})
        stats = pd.read_csv(folder / "trial_stats.csv")
        for controller, group in stats.groupby("controller", sort=False):
            x = group["value_rate_stable"].dropna()
            rows.append({"factor": factor, "duration_s": duration, "controller": controller,
                         "quantity": "value_rate_stable", "mean": x.mean(), "std": x.std(ddof=1) if len(x) > 1 else 0.0,
                         "n_trials": len(x)})
    return pd.DataFrame(rows, columns=LADDER_COLUMNS)


def write_ladder(ladder_dir: Path, folders: list[Path]) -> Path:
    """Write `ladder.csv` into `ladder_dir` from the rungs' folders; return its path."""
    table = ladder_table(sorted(folders, key=lambda f: float(from_yaml(f / "config.yaml").scale.time_factor)))
    path = Path(ladder_dir) / "ladder.csv"
    write_text_atomic(path, table.to_csv(index=False, float_format="%.4f"))
    return path
