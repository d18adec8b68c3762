"""The figure of `tavc stay-switch`, from `stay_switch.csv` only: for each reading, a low-value
stayer's t_switch / t_stay in every make-up that has both a low-value stayer and an
alternator, with the task timed whole (left) and from the source on (right), against the ratio
above which staying pays."""

from __future__ import annotations

from pathlib import Path

import pandas as pd

from tavc_cli.analysis.stay_switch import parse_reading
from tavc_cli.viz.figures import plt, save_figure

KIND = {"arrival=dock": "-", "arrival=range": "--"}  # line style by arrival, colour by passing and layout


def _style(reading: str, i: int) -> dict:
    parts = parse_reading(reading)
    return {"linestyle": KIND.get(f"arrival={parts.get('arrival', 'dock')}", "-"), "color": f"C{i % 10}",
            "marker": "o" if parts.get("arena", "two_circuits") == "two_circuits" else "s"}


def stay_switch_figure(table: pd.DataFrame, out_stem: Path) -> list[Path]:
    """Two panels side by side, one line per reading over the make-ups (labelled
    high stayers-low stayers-alternators), the threshold dashed in black."""
    both = table.dropna(subset=["ratio_low"])
    label = (both["high_stayers"].astype(int).astype(str) + "-" + both["low_stayers"].astype(int).astype(str) + "-"
             + both["alternators"].astype(int).astype(str))
    both = both.assign(label=label).sort_values(["alternators", "low_stayers"], kind="stable")
    makeups = list(dict.fromkeys(both["label"]))  # by alternators, then low-value stayers
    x = {m: i for i, m in enumerate(makeups)}
    fig, axes = plt.subplots(1, 2, figsize=(12.0, 5.0), sharey=True)
    colours = {}
    for ax, column, title in ((axes[0], "ratio_low", "t the whole task (from the choice at the sink)"),
                              (axes[1], "ratio_low_source", "t from the source to the sink")):
        for reading, rows in both.groupby("reading", sort=False):
            i = colours.setdefault(reading, len(colours))
            ax.plot([x[m] for m in rows["label"]], rows[column], label=reading, linewidth=1.2, markersize=4,
                    **_style(str(reading), i))
        threshold = float(both["threshold_low"].iloc[0]) if len(both) else float("nan")
        ax.axhline(threshold, color="black", linestyle=":", linewidth=1.0,
                   label=f"staying pays above {threshold:.3f}")
        ax.set_xticks(range(len(makeups)), makeups, rotation=90, fontsize=7)
        ax.set_xlabel("make-up: high-value stayers - low-value stayers - alternators")
        ax.set_title(title, fontsize=9)
        ax.grid(alpha=0.3)
    axes[0].set_ylabel("t_switch / t_stay of a low-value stayer")
    handles, labels = axes[0].get_legend_handles_labels()
    fig.legend(handles, labels, loc="lower center", ncol=3, fontsize=7, frameon=False)
    fig.suptitle("What each reading does to staying and switching (static robots held to their roles)", fontsize=10)
    fig.tight_layout(rect=(0, 0.16, 1, 0.97))
    return save_figure(fig, out_stem)
