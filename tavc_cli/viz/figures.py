"""The chapter's kinds of figure, drawn from saved result tables only.

- state histograms (Figures 1.6, 1.8): % of the stable period in each state, TAVC and
  random with their standard deviations as error bars, the binomial theory row, and the
  chapter's own TAVC means as markers;
- performance over time (Figures 1.7, 1.9-1.11): score value delivered per second, mean
  and a band of one standard deviation over trials, per controller, with the event (a
  breakdown or a value change at t = 0) and the end of the convergence period marked;
- one the chapter lacks: robots on the high-value circuit over time, with the allocation
  the model predicts before and after the event drawn over it;
- the learners' Q-values over time, robot by robot, for one trial;
- the share of robots on the high-value circuit against the learning-value ratio, per
  horizon and reading, with the model's prediction;
- for fast and slow robots (section 1.6), in `groups`; section 1.4's target times and
  lanes, in `spatial`.

Every error bar and band says what it is and over how many trials (in its legend entry), and
is cut where the quantity ends: a share at 0 and at 100 % (or 1), a rate, a count or a time at
0, so that no bar shows a percentage below 0 that no trial had. Every heat map has a colour bar.
"""

from __future__ import annotations

import zlib
from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from contextvars import ContextVar
from pathlib import Path

import matplotlib

# every figure of tavc's is drawn through this module: off screen (Agg, in any process, on any
# machine) and with SVG ids that are the same on every run
matplotlib.use("Agg")
matplotlib.rcParams["svg.hashsalt"] = "tavc"
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pandas as pd  # noqa: E402

from tavc_cli.io import atomic_path  # noqa: E402
from tavc_cli.learning.registry import COLOURS as REGISTRY_COLOURS  # noqa: E402
from tavc_cli.learning.registry import TITLES  # noqa: E402


class _Colours(dict):
    """Each controller label's colour (`registry.COLOURS`); any other controller (a learner from
    outside tavc, `alternate`) its own, drawn from the colours they leave, the same for a label
    everywhere."""

    SPARE = ("tab:pink", "tab:red", "tab:gray", "gold", "teal", "navy", "maroon")

    def __missing__(self, label: str) -> str:
        return self.SPARE[zlib.crc32(str(label).encode()) % len(self.SPARE)]

    def get(self, label, default=None):
        return self[label]


COLOURS = _Colours(REGISTRY_COLOURS)
LABELS = TITLES


# what the figures drawn in this context are not: "not a verdict: scale=quick (...)" for runs below the
# chapter's scale (`marked`), stamped on each one `save_figure` writes; "" for none
_MARK: ContextVar[str] = ContextVar("figure_mark", default="")


@contextmanager
def marked(mark: str) -> Iterator[None]:
    """Every figure saved within the block carries `mark` in its lower right corner (nothing for "")."""
    token = _MARK.set(mark)
    try:
        yield
    finally:
        _MARK.reset(token)


def outside_legend(ax, fontsize: float = 8) -> None:
    """The axes' legend to their right, off the data (`tight_layout` keeps room for it)."""
    ax.legend(fontsize=fontsize, loc="upper left", bbox_to_anchor=(1.01, 1.0), borderaxespad=0.0)


def save_figure(fig, out_stem: Path) -> list[Path]:
    """Write the figure as PNG and SVG beside each other (`write_figure`) and close it; within
    `marked`, with its mark."""
    if _MARK.get():
        fig.text(0.995, 0.005, _MARK.get(), ha="right", va="bottom", fontsize=7, color="firebrick",
                 bbox={"facecolor": "white", "edgecolor": "firebrick", "boxstyle": "round,pad=0.2"})
    paths = [out_stem.with_suffix(f".{ext}") for ext in ("png", "svg")]
    try:
        for path in paths:
            # no date and fixed element ids in the SVG, so a figure redrawn from the same numbers is the same file
            write_figure(fig, path, dpi=110, metadata={"Date": None} if path.suffix == ".svg" else None)
    finally:
        plt.close(fig)
    return paths


def write_figure(fig, path: Path, **options) -> Path:
    """``fig.savefig(path, **options)``, through a temporary file renamed over `path` (`io.atomic_path`).

    A link, a pipe, a device or a folder at `path` is refused in one line, never written
    through. The format is the one `path`'s extension names, so the bytes are those `savefig`
    writes to `path` itself.
    """
    path = Path(path)
    with atomic_path(path) as tmp:
        fig.savefig(tmp, format=path.suffix.lstrip("."), **options)  # the temporary name has no extension to go by
    return path


def clipped_err(mean, std, lo: float | None = 0.0, hi: float | None = None) -> np.ndarray:
    """Asymmetric error bars (2, n) of one std around `mean`, cut at `lo` and `hi` (a share
    at 0 and 100 %): the bar ends where the quantity does; a missing std draws no bar."""
    mean, std = np.asarray(mean, float), np.nan_to_num(np.asarray(std, float))
    below = std if lo is None else np.minimum(std, np.maximum(mean - lo, 0.0))
    above = std if hi is None else np.minimum(std, np.maximum(hi - mean, 0.0))
    return np.vstack([np.nan_to_num(below), np.nan_to_num(above)])


def clipped_band(mean, std, lo: float | None = 0.0, hi: float | None = None) -> tuple[np.ndarray, np.ndarray]:
    """A one-std band's lower and upper edges, cut at `lo` and `hi`."""
    mean, std = np.asarray(mean, float), np.asarray(std, float)
    return np.clip(mean - std, lo, hi), np.clip(mean + std, lo, hi)


def n_text(n) -> str:
    """"n trials" for the trial counts of a bar or a band: one count, or their range (times
    with no trial, before a baseline starts, draw nothing and count for nothing)."""
    counts = sorted({int(v) for v in np.asarray(n, float) if np.isfinite(v) and v > 0})
    if not counts:
        return "trials"
    span = f"{counts[0]}" if len(counts) == 1 else f"{counts[0]}-{counts[-1]}"
    return f"{span} trial" + ("" if counts == [1] else "s")


def _label(ctrl: str, rows: pd.DataFrame, what: str = "mean ± std") -> str:
    """A legend entry naming what the bars or bands are: ``TAVC: mean ± std over 20 trials``."""
    name = LABELS.get(ctrl, ctrl)
    if ctrl == "theory":
        return f"{name} (binomial row)"
    if "n_trials" not in rows:
        return f"{name}: {what} over trials"
    return f"{name}: {what} over {n_text(rows['n_trials'])}"


def state_fig(state_time: pd.DataFrame, chapter: pd.DataFrame | None, title: str):
    """`state_figure`'s figure, unsaved."""
    states = list(dict.fromkeys(state_time["state"]))
    ctrls = [c for c in dict.fromkeys(state_time["controller"])]
    x = np.arange(len(states))
    width = 0.8 / max(len(ctrls), 1)
    fig, ax = plt.subplots(figsize=(10.5, 4.2))
    for k, ctrl in enumerate(ctrls):
        rows = state_time[state_time["controller"] == ctrl].set_index("state").reindex(states)
        mean = rows["mean_pct"].to_numpy(float)
        err = None if ctrl == "theory" else clipped_err(mean, rows["std_pct"], 0.0, 100.0)
        ax.bar(x + (k - (len(ctrls) - 1) / 2) * width, mean, width, yerr=err,
               capsize=2, color=COLOURS.get(ctrl), label=_label(ctrl, rows))
    if chapter is not None and "tavc_mean_pct" in chapter:
        ch = chapter.set_index("state").reindex(states)
        k = ctrls.index("tavc") if "tavc" in ctrls else 0
        ax.plot(x + (k - (len(ctrls) - 1) / 2) * width, ch["tavc_mean_pct"], "k*", ms=9,
                label="TAVC, the chapter's mean")
    _finish_states(fig, ax, x, states, title)
    return fig


def state_figure(state_time: pd.DataFrame, chapter: pd.DataFrame | None, title: str, out_stem: Path) -> list[Path]:
    """Bars per state: each controller's mean with its std over trials (cut at 0 and 100 %),
    theory as grey bars, the chapter's TAVC means as stars."""
    return save_figure(state_fig(state_time, chapter, title), out_stem)


def _finish_states(fig, ax, x: np.ndarray, states: Sequence[str], title: str) -> None:
    """A state histogram's axes, title and legend."""
    ax.set_xticks(x, states)
    ax.set_xlabel("state (robots on the high-value circuit : on the low-value circuit)")
    ax.set_ylabel("% of the stable period")
    ax.set_ylim(bottom=0.0)
    ax.set_title(title, fontsize=10)
    outside_legend(ax)
    fig.tight_layout()


def _over_time(frame: pd.DataFrame, mean: str, std: str, convergence_s: float, event: bool, ylabel: str,
               hi: float | None = None):
    """A figure of one quantity over time (ks): per controller its mean and a one-std band over
    trials (cut at 0 and at `hi`), the event at t = 0 and the end of the convergence period
    marked."""
    fig, ax = plt.subplots(figsize=(10.5, 4.2))
    for ctrl, rows in frame.groupby("controller", sort=False):
        t = rows["t_s"].to_numpy(float) / 1000.0
        m, s = rows[mean].to_numpy(float), rows[std].to_numpy(float)
        ax.plot(t, m, color=COLOURS.get(ctrl), label=_label(ctrl, rows, "mean, band ± std"))
        ax.fill_between(t, *clipped_band(m, s, 0.0, hi), color=COLOURS.get(ctrl), alpha=0.15, lw=0)
    if event:
        ax.axvline(0.0, color="r", lw=1, label="event")
    if convergence_s > 0:
        ax.axvline(convergence_s / 1000.0, color="k", ls="--", lw=1, label="end of convergence period")
    ax.set_xlabel("time (1000 s)")
    ax.set_ylabel(ylabel)
    return fig, ax


def finish_figure(fig, ax, title: str, out_stem: Path) -> list[Path]:
    """Title, legend and layout of a one-panel figure, then saved (`save_figure`)."""
    ax.set_title(title, fontsize=10)
    outside_legend(ax)
    fig.tight_layout()
    return save_figure(fig, out_stem)


def performance_figure(perf: pd.DataFrame, convergence_s: float, event: bool, title: str,
                       out_stem: Path) -> list[Path]:
    """Score per second over time (ks), mean and one-std band per controller."""
    fig, ax = _over_time(perf, "mean", "std", convergence_s, event, "score value delivered per second")
    ax.set_ylim(bottom=0.0)
    return finish_figure(fig, ax, title, out_stem)


def allocation_figure(alloc: pd.DataFrame, predicted: Sequence[tuple[float, float, str, float]],
                      convergence_s: float, event: bool, title: str, out_stem: Path) -> list[Path]:
    """Robots on the high-value circuit over time, mean and one-std band per controller, with
    the model's predicted count drawn as dotted lines: (from s, to s, label, robots) each."""
    fig, ax = _over_time(alloc, "mean_high", "std_high", convergence_s, event, "robots on the high-value circuit")
    ax.set_ylim(bottom=0.0)
    for k, (a, b, label, value) in enumerate(predicted):
        ax.hlines(value, a / 1000.0, b / 1000.0, colors="k", linestyles=":", lw=2,
                  label="the model's prediction" if k == 0 else None)
        ax.text(a / 1000.0, value + 0.05, label, fontsize=8)
    return finish_figure(fig, ax, title, out_stem)


def q_value_figure(q: pd.DataFrame, robots: pd.DataFrame | None, high: int, convergence_s: float,
                   title: str, out_stem: Path) -> list[Path]:
    """One trial's Q-tables over time, a panel per robot: Q(last served, next) for every pair,
    the action by colour (high-value circuit blue, low orange), the state by line style;
    each panel titled with the robot's kind from `robots.csv` if given."""
    states = sorted({int(c.split("_")[1]) for c in q.columns if c.startswith("q_")})
    n_robots = int(q["robot"].max()) + 1
    cols = min(3, n_robots)
    rows_ = -(-n_robots // cols)
    fig, axes = plt.subplots(rows_, cols, figsize=(3.6 * cols, 2.6 * rows_), sharex=True, sharey=True,
                             squeeze=False)
    name = {s: ("high" if s == high else "low") for s in states}
    kinds = {}
    if robots is not None:
        kinds = {int(r.robot): (r.kind if r.kind != "stayer" else f"stayer on {name.get(int(r.circuit), r.circuit)}")
                 for r in robots.itertuples()}
    for robot in range(n_robots):
        ax = axes[robot // cols][robot % cols]
        g = q[q["robot"] == robot].sort_values("t_s")
        t = g["t_s"].to_numpy(float) / 1000.0
        for s in states:
            for a in states:
                ax.plot(t, g[f"q_{s}_{a}"], color="tab:blue" if a == high else "tab:orange",
                        ls="-" if s == a else "--", lw=1.2,
                        label=f"after {name[s]}, take {name[a]}" if robot == 0 else None)
        if convergence_s > 0:
            ax.axvline(convergence_s / 1000.0, color="0.5", ls=":", lw=1)
        ax.set_title(f"robot {robot}" + (f": {kinds[robot]}" if robot in kinds else ""), fontsize=9)
        ax.grid(alpha=0.3)
    for ax in axes[-1]:
        ax.set_xlabel("time (ks)")
    for row in axes:
        row[0].set_ylabel("Q")
    for k in range(n_robots, rows_ * cols):
        axes[k // cols][k % cols].set_visible(False)
    fig.legend(loc="lower center", ncol=4, fontsize=8, frameon=False)
    fig.suptitle(title, fontsize=10)
    fig.tight_layout(rect=(0, 0.06, 1, 0.97))
    return save_figure(fig, out_stem)


def value_ratio_figure(points: pd.DataFrame, predicted: pd.DataFrame | None, chapter_ratio: float | None,
                       title: str, out_stem: Path) -> list[Path]:
    """Share of the stable period on the high-value circuit against w_high / w_low: one line per
    (reading, horizon) with one std over trials as error bars, the model's predicted share as a
    step line, and random choice's expected share (one half) as a grey line.

    points: `reading,horizon,ratio,mean,std,n_trials`; predicted: `ratio,share`."""
    fig, ax = plt.subplots(figsize=(9.0, 4.2))
    styles = {"5 h": "-", "50 h": "--"}
    markers = ["o", "s", "^", "D"]
    readings = list(dict.fromkeys(points["reading"]))
    lines = list(dict.fromkeys(zip(points["reading"], points["horizon"], strict=True)))
    for k, (reading, horizon) in enumerate(lines):  # each line its own colour and offset
        g = points[(points["reading"] == reading) & (points["horizon"] == horizon)].sort_values("ratio")
        n = f", n = {n_text(g['n_trials'])}" if "n_trials" in g else ""
        ax.errorbar(g["ratio"] + 0.008 * (k - (len(lines) - 1) / 2), g["mean"],
                    yerr=clipped_err(g["mean"], g["std"], 0.0, 1.0), capsize=3,
                    ls=styles.get(horizon, ":"), marker=markers[readings.index(reading) % len(markers)],
                    color=f"C{k % 10}", label=f"{reading}, {horizon}{n}")
    if predicted is not None and len(predicted):
        ax.step(predicted["ratio"], predicted["share"], where="mid", color="k", lw=2, ls=":",
                label="the model's prediction")
    ax.axhline(0.5, color="0.6", lw=1, label="random choice")
    if chapter_ratio is not None:
        ax.axvline(chapter_ratio, color="0.8", lw=6, zorder=0, label="the chapter's values (2200/2000)")
    ax.set_xlabel("learning value ratio w_high / w_low")
    ax.set_ylabel("share of robots on the high-value circuit\n(mean ± std over trials, cut at 0 and 1)")
    ax.set_ylim(0.0, 1.0)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=7, loc="upper left", bbox_to_anchor=(1.01, 1.0))
    ax.set_title(title, fontsize=10)
    fig.tight_layout()
    return save_figure(fig, out_stem)


def horizon_state_figure(base: pd.DataFrame, long: pd.DataFrame, chapter: pd.DataFrame | None, factor: float,
                         title: str, out_stem: Path) -> list[Path]:
    """Bars per state: the learners at the chapter's durations and at `factor` times them (mean,
    one std), random allocation and the theory row, with the chapter's TAVC means as stars."""
    states = list(dict.fromkeys(long["state"]))
    series = [("tavc", base, "TAVC, the chapter's durations", "tab:cyan"),
              ("tavc", long, f"TAVC, {factor:g}x", "tab:blue"),
              ("random", long, "random", COLOURS["random"]), ("theory", long, "theory", COLOURS["theory"])]
    series = [s for s in series if (s[1]["controller"] == s[0]).any()]
    x = np.arange(len(states))
    width = 0.8 / max(len(series), 1)
    fig, ax = plt.subplots(figsize=(10.5, 4.2))
    for k, (ctrl, table, label, colour) in enumerate(series):
        rows = table[table["controller"] == ctrl].set_index("state").reindex(states)
        mean = rows["mean_pct"].to_numpy(float)
        err = None if ctrl == "theory" else clipped_err(mean, rows["std_pct"], 0.0, 100.0)
        if ctrl != "theory" and "n_trials" in rows:
            label += f": mean ± std over {n_text(rows['n_trials'])}"
        ax.bar(x + (k - (len(series) - 1) / 2) * width, mean, width, yerr=err,
               capsize=2, color=colour, label=label)
    if chapter is not None and "tavc_mean_pct" in chapter:
        ch = chapter.set_index("state").reindex(states)
        ax.plot(x - (len(series) - 1) / 2 * width + width / 2, ch["tavc_mean_pct"], "k*", ms=9,
                label="TAVC, the chapter's mean")
    _finish_states(fig, ax, x, states, title)
    return save_figure(fig, out_stem)
