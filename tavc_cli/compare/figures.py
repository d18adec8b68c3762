"""The comparison's figure: one panel per number, scenarios along x, a bar per controller."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd

from tavc_cli.compare.metrics import METRICS

CEILING = {"predicted_state_pct": 100.0, "filled_pct": 100.0, "fast_high_share": 1.0}  # what a share cannot pass


def comparison_figure(table: pd.DataFrame, out_stem: Path) -> list[Path]:
    """Bars of each controller's mean with its standard deviation (cut at 0), a panel per metric."""
    # deferred: loads matplotlib
    from tavc_cli.viz.figures import COLOURS, LABELS, plt, save_figure

    metrics = [m for m in METRICS if m in set(table["metric"])]
    controllers = list(dict.fromkeys(table["controller"]))
    fig, axes = plt.subplots(len(metrics), 1, figsize=(9, 2.8 * len(metrics)), squeeze=False)
    for ax, metric in zip(axes[:, 0], metrics, strict=True):
        rows = table[table["metric"] == metric]
        experiments = list(dict.fromkeys(rows["experiment"]))
        width = 0.8 / max(1, len(controllers))
        for k, controller in enumerate(controllers):
            mine = rows[rows["controller"] == controller].set_index("experiment").reindex(experiments)
            x = np.arange(len(experiments)) + (k - (len(controllers) - 1) / 2) * width
            mean, std = mine["mean"].to_numpy(float), np.nan_to_num(mine["std"].to_numpy(float))
            lower = np.minimum(std, np.where(np.isfinite(mean), mean, 0.0))  # bars cut at 0 ...
            top = CEILING.get(metric)
            upper = std if top is None else np.minimum(std, np.where(np.isfinite(mean), top - mean, 0.0))  # and 100 %
            n = mine["n_trials"].dropna()
            ax.bar(x, mean, width, yerr=[lower, upper], capsize=2, color=COLOURS[controller],
                   label=f"{LABELS.get(controller, controller)} (n {int(n.max()) if len(n) else 0})")
        ax.set_xticks(np.arange(len(experiments)), [e.replace("_", " ") for e in experiments])
        ax.set_ylabel(METRICS[metric], fontsize=8)
        ax.set_ylim(bottom=0)
    handles, labels = axes[0, 0].get_legend_handles_labels()
    fig.suptitle("mean ± std over trials (n), per controller and scenario; cut at 0 and 100 %", fontsize=9, y=0.998)
    fig.legend(handles, labels, loc="upper center", bbox_to_anchor=(0.5, 0.985), ncol=min(3, len(labels)),
               fontsize=7, frameon=False)
    fig.tight_layout(rect=(0, 0, 1, 0.95))
    return save_figure(fig, out_stem)
