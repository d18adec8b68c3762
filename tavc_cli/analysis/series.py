"""Time series over trials: the bins they share and their mean and spread per controller."""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np
import pandas as pd


def bin_edges(t_from: float, t_to: float, bin_s: float) -> np.ndarray:
    """Edges of `bin_s`-wide bins from t_from; time left over at the end forms a last, shorter bin."""
    n_full = int(np.floor((t_to - t_from) / bin_s + 1e-9))
    edges = t_from + bin_s * np.arange(n_full + 1)
    if t_to - edges[-1] > 1e-9 * max(1.0, abs(t_to)):
        edges = np.append(edges, t_to)
    if len(edges) < 2:
        edges = np.array([t_from, t_to])
    return edges


def over_trials(series: Mapping[str, Sequence[np.ndarray]], centres: np.ndarray, mean: str, std: str,
                std_of_one: float) -> pd.DataFrame:
    """`t_s,controller,<mean>,<std>,n_trials`: per controller and bin, the mean and sample std
    over its trials' series, NaN entries (undefined there) left out; `std_of_one` where a bin
    has a single trial, NaN where it has none."""
    rows = []
    for ctrl, runs in series.items():
        m = np.vstack(runs)
        for k, t in enumerate(centres):
            col = m[:, k][np.isfinite(m[:, k])]
            spread = float(col.std(ddof=1)) if len(col) > 1 else std_of_one if len(col) else np.nan
            rows.append({"t_s": float(t), "controller": ctrl, mean: float(col.mean()) if len(col) else np.nan,
                         std: spread, "n_trials": len(col)})
    return pd.DataFrame(rows, columns=["t_s", "controller", mean, std, "n_trials"])
