"""Section 1.4's figures: the target time over the run (Figure 1.4's measure) and the lanes the
robots keep, as occupancy of the arena. Conventions as `figures`'."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd

from tavc_cli.viz.figures import COLOURS, clipped_band, finish_figure, n_text, plt, save_figure


def target_time_figure(curve: pd.DataFrame, chapter: pd.DataFrame | None, title: str, out_stem: Path) -> list[Path]:
    """Figure 1.4's kind: the group's target time, smoothed over 10 arrivals, against arrivals,
    mean and one-std band over trials; the chapter's Table 1.1 target-time means as stars."""
    fig, ax = plt.subplots(figsize=(7.5, 4.0))
    m, mu, sd = (curve[c].to_numpy(float) for c in ("m_arrivals", "mean_target_s", "std_target_s"))
    n = n_text(curve["n_trials"]) if "n_trials" in curve else "trials"
    ax.plot(m, mu, color=COLOURS["tavc"], label=f"TAVC: mean, band ± std over {n}")
    ax.fill_between(m, *clipped_band(mu, sd, 0.0), color=COLOURS["tavc"], alpha=0.15, lw=0)
    if chapter is not None:
        ax.plot(chapter["m_arrivals"], chapter["mean_target_s"], "k*", ms=9, label="the chapter (Table 1.1)")
    ax.set_xlabel("target arrivals of the group, m")
    ax.set_ylabel("target time (s), mean of 10")
    ax.set_ylim(bottom=0.0)
    return finish_figure(fig, ax, title, out_stem)


def lane_figure(occupancy: pd.DataFrame, source_xy, sink_xy, title: str, out_stem: Path) -> list[Path]:
    """Where the robots drive: pose frames per cell (log scale), heading toward the sink and
    toward the source, early and late in the run, each panel scaled to its own maximum and
    given its own colour bar (`lane_fig`)."""
    return save_figure(lane_fig(occupancy, source_xy, sink_xy, title), out_stem)


def lane_fig(occupancy: pd.DataFrame, source_xy, sink_xy, title: str):
    """`lane_figure`'s figure, unsaved: a panel per window and direction, each with its colour bar."""
    windows = list(dict.fromkeys(occupancy["window"]))
    directions = [("to_sink", "heading to the sink"), ("to_source", "heading to the source")]
    fig, axes = plt.subplots(len(windows), 2, figsize=(9.5, 3.4 * len(windows)), squeeze=False,
                             constrained_layout=True)
    for i, w in enumerate(windows):
        for j, (d, label) in enumerate(directions):
            g = occupancy[(occupancy["window"] == w) & (occupancy["direction"] == d)]
            xs, ys = np.sort(g["x_m"].unique()), np.sort(g["y_m"].unique())
            grid = g.pivot_table(index="y_m", columns="x_m", values="count").reindex(index=ys, columns=xs)
            cell = float(xs[1] - xs[0]) if len(xs) > 1 else 1.0
            ax = axes[i][j]
            # log scale: robots standing still pile up frames in one cell
            image = ax.imshow(np.log1p(grid.to_numpy(float)), origin="lower", cmap="magma", aspect="equal",
                              extent=(xs[0] - cell / 2, xs[-1] + cell / 2, ys[0] - cell / 2, ys[-1] + cell / 2))
            # each panel has its own scale, so each has its own bar
            fig.colorbar(image, ax=ax, shrink=0.85, label="ln(1 + pose frames in the cell)")
            ax.plot([source_xy[0], sink_xy[0]], [source_xy[1], sink_xy[1]], color="c", ls=":", lw=1)
            ax.annotate("", xy=(0.9, 0.08), xytext=(0.6, 0.08), xycoords="axes fraction",
                        arrowprops={"arrowstyle": "->", "color": "w"} if d == "to_sink" else
                        {"arrowstyle": "<-", "color": "w"})
            ax.set_title(f"{w} tenth of the run, {label}", fontsize=9)
            ax.set_xlabel("x (m)")
            ax.set_ylabel("y (m)")
    fig.suptitle(title, fontsize=10)
    return fig
