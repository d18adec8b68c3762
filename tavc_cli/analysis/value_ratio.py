"""Where the learners go as the high circuit's learning value grows, and how fast.

`make value-ratio` runs initial_distribution at several learning-value ratios
w_high / w_low, at the chapter's 5 h and at ten times that, under two readings of the
unit of t in r = w / t, and, as a diagnostic that is not the chapter's rule, with no
discounting (gamma = 0: each Q-value a running mean of its task's reward). This module
makes those runs (`run_tables.ratio_points` reads every finished run below a root) one table:
per reading, horizon and ratio, the mean share of robots on the high-value circuit over
the stable period, from `trial_stats.csv` (each state's share
of the period weighted by the fraction of robots it puts on the high circuit). A run in another
reading of the world (`make value-ratio-checks READING=...`) is a reading of its own there, and a variant of
a reading its folder names after the reading's own name (``range-left-two_circuits_parallel-calibrated/``:
the reading at the settings its calibration chose) is named so in brackets. The model's
prediction for the same ratios comes from a `model.csv` measured in the same world.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from pathlib import Path

import numpy as np
import pandas as pd

from tavc_cli.analysis.stay_switch import reading_name, reading_of, readings, split_folder
from tavc_cli.learning.parameters import CHAPTER_GAMMA, settings_mapping
from tavc_cli.model import core
from tavc_cli.notation import column_state, counts_of
from tavc_cli.settings import TavcConfig

POINT_COLUMNS = ["reading", "horizon", "ratio", "values", "mean", "std", "n_trials", "policy_changes_per_trial",
                 "run"]
READINGS = {"ms": "t in ms (the default)", "s": "t in s"}


def high_share(stats: pd.DataFrame) -> np.ndarray:
    """Per trial: the mean fraction of robots on the high-value circuit in the stable period."""
    share = np.zeros(len(stats))
    for col in (c for c in stats.columns if column_state(c) is not None):
        high, low = counts_of(column_state(col))
        share += stats[col].to_numpy(float) / 100.0 * high / (high + low)
    return share


def horizon_label(duration_s: float) -> str:
    """A duration in hours as the tables label a horizon (`18000` -> ``5 h``)."""
    return f"{duration_s / 3600.0:g} h"


def ratio_point(cfg: TavcConfig, stats: pd.DataFrame, run: str, controller: str = "tavc") -> dict | None:
    """A run's row of the table (`POINT_COLUMNS`), from its settings, `trial_stats.csv` and `run`, its
    folder relative to the sweep's (whose first part may name a variant of the run's reading); None
    for a run without two circuits or without a finite share of `controller`'s trials."""
    values = cfg.tasks.values
    if not values or len(values) != 2:
        return None
    stats = stats[stats["controller"] == controller]
    share = high_share(stats)
    share = share[np.isfinite(share)]
    if not len(share):
        return None
    unit = str(cfg.tasks.time_unit)
    reading = READINGS.get(unit, f"t in {unit}")
    gamma = float(getattr(cfg.learner, "gamma", CHAPTER_GAMMA))
    if gamma != CHAPTER_GAMMA:
        reading += f", gamma {gamma:g} (diagnostic)"
    world = reading_of(cfg)
    # a variant of the run's reading, named as its folder under the sweep's is (the calibrated range world)
    split = split_folder(Path(run).parts[0]) if run else None
    variant = split[1] if split is not None and split[0] == world else ""
    if world != readings()[0] or variant:  # a reading of the world other than today's (docs/readings.md)
        reading += f", {reading_name(world)}" + (f" ({variant})" if variant else "")
    changes = stats["policy_changes"].to_numpy(float) if "policy_changes" in stats else np.full(len(stats), np.nan)
    return {"reading": reading, "horizon": horizon_label(float(cfg.duration_s)),
            "ratio": max(values) / min(values), "values": "/".join(f"{float(v):g}" for v in values),
            "mean": float(share.mean()), "std": float(share.std(ddof=1)) if len(share) > 1 else math.nan,
            "n_trials": len(share),
            "policy_changes_per_trial": float(np.nanmean(changes)) if np.isfinite(changes).any() else math.nan,
            "run": run}


def unnamed_settings(cfg: TavcConfig) -> dict[str, object]:
    """What a run's row of the table does not name but its column presumes alike (`ratio_point`
    names the unit of t, a discount other than the chapter's, the reading and the horizon): the
    experiment, the team, the learner (but its discount), the robot and the time factor."""
    learner = {k: v for k, v in settings_mapping(cfg.learner).items() if k != "gamma"}
    return {"experiment_name": cfg.experiment_name, "team": cfg.team, "learner": learner, "robot": cfg.robot,
            "scale.time_factor": float(cfg.scale.time_factor)}


def points_table(rows: Sequence[dict]) -> pd.DataFrame:
    """The runs' rows (`ratio_point`) as one table: the default reading first, then shorter horizons
    first, then by ratio."""
    out = pd.DataFrame(list(rows), columns=POINT_COLUMNS)
    key = [(r != READINGS["ms"], r, float(h.split()[0]), x) for r, h, x in zip(out["reading"], out["horizon"],
                                                                           out["ratio"], strict=True)]
    return out.iloc[sorted(range(len(out)), key=key.__getitem__)].reset_index(drop=True)


def predicted_shares(model_rows: pd.DataFrame, n_robots: int, ratios: Sequence[float],
                     low_value: float = 2000.0) -> pd.DataFrame:
    """`ratio,share,state`: the model's predicted split (the individual equilibrium) of n_robots at
    each ratio, as the share of robots on the high-value circuit (circuit 0 gets the high value);
    `model_rows` is a `model.csv` as read (`run_tables.model_rows`)."""
    # deferred: loads the simulator's compiled kernels
    from tavc_cli.model.api import table_from_rows

    table = table_from_rows(model_rows)
    rows = []
    for r in ratios:
        values = [low_value * float(r), low_value]
        n = core.predicted_split(table, n_robots, values)
        rows.append({"ratio": float(r), "share": n[0] / n_robots, "state": core.state_label(n, values)})
    return pd.DataFrame(rows)
