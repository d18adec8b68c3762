"""The figure of a sweep: time share of each state against the swept value, per controller."""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import pandas as pd  # noqa: E402


def sweep_figure(table: pd.DataFrame, key: str, out: Path) -> list[Path]:
    """% of the stable period in each state against `key`'s values, one panel per controller."""
    controllers = list(dict.fromkeys(table["controller"]))
    fig, axes = plt.subplots(1, len(controllers), figsize=(5.0 * len(controllers), 3.6), squeeze=False)
    numeric = pd.to_numeric(table[key], errors="coerce")
    x = numeric if numeric.notna().all() else table[key].astype(str)
    for ax, ctrl in zip(axes[0], controllers, strict=True):
        rows = table[table["controller"] == ctrl].assign(x=x)
        for state, group in rows.groupby("state", sort=False):
            group = group.sort_values("x")
            ax.errorbar(group["x"], group["mean_pct"], yerr=group["std_pct"], marker="o", capsize=3, label=state)
        ax.set_title(ctrl)
        ax.set_xlabel(key)
        ax.set_ylabel("% of the stable period")
        ax.legend(fontsize=7, ncol=2, title="state")
    fig.tight_layout()
    paths = [out.with_suffix(".png"), out.with_suffix(".svg")]
    for path in paths:
        fig.savefig(path, dpi=120)
    plt.close(fig)
    return paths
