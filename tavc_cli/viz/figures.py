"""The chapter's kinds of figure, drawn from saved result tables only.

- state histograms (Figures 1.6, 1.8): % of the stable period in each state, TAVC and
  random with their standard deviations as error bars, the binomial theory row, and the
  chapter's own TAVC means as markers;
- performance over time (Figures 1.7, 1.9-1.11): score value delivered per second, mean
  and a band of one standard deviation over trials, per controller, with the event (a
  breakdown or a value change at t = 0) and the end of the convergence period marked;
- one the chapter lacks: robots on the high-value circuit over time, with the allocation
  the model predicts before and after the event drawn over it.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
matplotlib.rcParams["svg.hashsalt"] = "tavc"
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pandas as pd  # noqa: E402

# the chapter's figure numbers per experiment: (state histogram, performance)
FIGURES = {
    "initial_distribution": ("1.6", "1.7"),
    "breakdown": ("1.8", "1.9"),
    "breakdown_no_vacancy": (None, "1.10"),
    "value_change": (None, "1.11"),
}
COLOURS = {"tavc": "tab:blue", "random": "tab:orange", "static": "tab:green", "theory": "0.4"}
LABELS = {"tavc": "TAVC", "random": "random", "static": "static", "theory": "theory"}


def save_figure(fig, out_stem: Path) -> list[Path]:
    """Write the figure as PNG and SVG beside each other and close it."""
    out_stem.parent.mkdir(parents=True, exist_ok=True)
    paths = []
    for ext in ("png", "svg"):
        path = out_stem.with_suffix(f".{ext}")
        # no date and fixed element ids in the SVG, so a figure redrawn from the same numbers is the same file
        fig.savefig(path, dpi=110, metadata={"Date": None} if ext == "svg" else None)
        paths.append(path)
    plt.close(fig)
    return paths


def state_figure(state_time: pd.DataFrame, chapter: pd.DataFrame | None, title: str, out_stem: Path) -> list[Path]:
    """Bars per state: each controller's mean with its std, theory as grey bars, the chapter's TAVC means as stars."""
    states = list(dict.fromkeys(state_time["state"]))
    ctrls = [c for c in dict.fromkeys(state_time["controller"])]
    x = np.arange(len(states))
    width = 0.8 / max(len(ctrls), 1)
    fig, ax = plt.subplots(figsize=(7.5, 4.0))
    for k, ctrl in enumerate(ctrls):
        rows = state_time[state_time["controller"] == ctrl].set_index("state").reindex(states)
        err = None if ctrl == "theory" else rows["std_pct"].to_numpy(float)
        ax.bar(x + (k - (len(ctrls) - 1) / 2) * width, rows["mean_pct"].to_numpy(float), width, yerr=err,
               capsize=2, color=COLOURS.get(ctrl), label=LABELS.get(ctrl, ctrl))
    if chapter is not None and "tavc_mean_pct" in chapter:
        ch = chapter.set_index("state").reindex(states)
        k = ctrls.index("tavc") if "tavc" in ctrls else 0
        ax.plot(x + (k - (len(ctrls) - 1) / 2) * width, ch["tavc_mean_pct"], "k*", ms=9, label="TAVC, the chapter")
    ax.set_xticks(x, states)
    ax.set_xlabel("state (robots on the high-value circuit : on the low-value circuit)")
    ax.set_ylabel("% of the stable period")
    ax.set_title(title, fontsize=10)
    ax.legend(fontsize=8)
    fig.tight_layout()
    return save_figure(fig, out_stem)


def _over_time(frame: pd.DataFrame, mean: str, std: str, convergence_s: float, event: bool, ylabel: str):
    """A figure of one quantity over time (ks): per controller its mean and a one-std band, the
    event at t = 0 and the end of the convergence period marked."""
    fig, ax = plt.subplots(figsize=(7.5, 4.0))
    for ctrl, rows in frame.groupby("controller", sort=False):
        t = rows["t_s"].to_numpy(float) / 1000.0
        m, s = rows[mean].to_numpy(float), rows[std].to_numpy(float)
        ax.plot(t, m, color=COLOURS.get(ctrl), label=LABELS.get(ctrl, ctrl))
        ax.fill_between(t, m - s, m + s, color=COLOURS.get(ctrl), alpha=0.15, lw=0)
    if event:
        ax.axvline(0.0, color="r", lw=1, label="event")
    if convergence_s > 0:
        ax.axvline(convergence_s / 1000.0, color="k", ls="--", lw=1, label="end of convergence period")
    ax.set_xlabel("time (1000 s)")
    ax.set_ylabel(ylabel)
    return fig, ax


def _finish(fig, ax, title: str, out_stem: Path) -> list[Path]:
    ax.set_title(title, fontsize=10)
    ax.legend(fontsize=8)
    fig.tight_layout()
    return save_figure(fig, out_stem)


def performance_figure(perf: pd.DataFrame, convergence_s: float, event: bool, title: str,
                       out_stem: Path) -> list[Path]:
    """Score per second over time (ks), mean and one-std band per controller."""
    fig, ax = _over_time(perf, "mean", "std", convergence_s, event, "score value delivered per second")
    return _finish(fig, ax, title, out_stem)


def allocation_figure(alloc: pd.DataFrame, predicted: Sequence[tuple[float, float, str, float]],
                      convergence_s: float, event: bool, title: str, out_stem: Path) -> list[Path]:
    """Robots on the high-value circuit over time, mean and one-std band per controller, with
    the model's predicted count drawn as dotted lines: (from s, to s, label, robots) each."""
    fig, ax = _over_time(alloc, "mean_high", "std_high", convergence_s, event, "robots on the high-value circuit")
    for k, (a, b, label, value) in enumerate(predicted):
        ax.hlines(value, a / 1000.0, b / 1000.0, colors="k", linestyles=":", lw=2,
                  label="the model's prediction" if k == 0 else None)
        ax.text(a / 1000.0, value + 0.05, label, fontsize=8)
    return _finish(fig, ax, title, out_stem)
