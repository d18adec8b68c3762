"""Figures of fast and slow robots (section 1.6): f:s state shares as grids (Figure 1.12),
TAVC's difference from the theory row, absolute and relative (Figure 1.13), and each speed
group's share on the high-value circuit over time. Conventions as `figures`'."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import numpy as np
import pandas as pd

from tavc_cli.notation import counts_of
from tavc_cli.viz.figures import COLOURS, LABELS, clipped_band, finish_figure, n_text, plt, save_figure


def _grid(states: Sequence[str], values: Sequence[float]) -> np.ndarray:
    """f:s states and their numbers as a 2-D array: rows f (fast robots high), columns s (slow)."""
    pairs = [counts_of(s) for s in states]
    grid = np.full((max(f for f, _ in pairs) + 1, max(s for _, s in pairs) + 1), np.nan)
    for (f, s), v in zip(pairs, values, strict=True):
        grid[f, s] = v
    return grid


def _heat_panels(panels: Sequence[tuple[str, np.ndarray]], cmap: str, symmetric: bool, fmt: str, label: str,
                 title: str, out_stem: Path, limit: float | None = None) -> list[Path]:
    """Panels of f:s grids side by side, one colour scale (saturating at `limit` if given), each
    cell annotated with its number."""
    cols = max(1, min(2, len(panels)))
    rows_ = max(1, -(-len(panels) // cols))
    fig, axes = plt.subplots(rows_, cols, figsize=(4.4 * cols, 3.8 * rows_), squeeze=False, constrained_layout=True)
    finite = np.concatenate([g[np.isfinite(g)].ravel() for _, g in panels]) if panels else np.zeros(0)
    hi = float(np.max(np.abs(finite))) if len(finite) else 1.0
    hi = min(hi, limit) if limit is not None else hi
    hi = hi if hi > 0 else 1.0
    vmin, vmax = (-hi, hi) if symmetric else (0.0, hi)
    image = None
    for k, (name, grid) in enumerate(panels):
        ax = axes[k // cols][k % cols]
        image = ax.imshow(grid, origin="lower", cmap=cmap, vmin=vmin, vmax=vmax)
        for (f, s), v in np.ndenumerate(grid):
            if np.isfinite(v):
                ax.text(s, f, format(v, fmt), ha="center", va="center", fontsize=8)
        ax.set_xticks(range(grid.shape[1]))
        ax.set_yticks(range(grid.shape[0]))
        ax.set_xlabel("slow robots on the high-value circuit")
        ax.set_ylabel("fast robots on it")
        ax.set_title(name, fontsize=9)
    for k in range(len(panels), rows_ * cols):
        axes[k // cols][k % cols].set_visible(False)
    if image is not None:
        fig.colorbar(image, ax=axes.ravel().tolist(), shrink=0.8, label=label)
    fig.suptitle(title, fontsize=10)
    return save_figure(fig, out_stem)


def group_state_figure(state_time: pd.DataFrame, chapter: pd.DataFrame | None, title: str,
                       out_stem: Path) -> list[Path]:
    """Figure 1.12's kind: % of the stable period in each f:s state, TAVC and random, ours and the chapter's."""
    panels = []
    for ctrl in ("tavc", "random"):
        rows = state_time[state_time["controller"] == ctrl]
        if len(rows):
            panels.append((f"{LABELS.get(ctrl, ctrl)}, ours", _grid(rows["state"], rows["mean_pct"])))
        if chapter is not None and f"{ctrl}_mean_pct" in chapter:
            panels.append((f"{LABELS.get(ctrl, ctrl)}, the chapter", _grid(chapter["state"],
                                                                              chapter[f"{ctrl}_mean_pct"])))
    return _heat_panels(panels, "viridis", False, ".1f", "% of the stable period", title, out_stem)


def group_difference_figure(state_time: pd.DataFrame, chapter: pd.DataFrame | None, title: str,
                            out_stem: Path) -> list[Path]:
    """Figure 1.13's kind: TAVC's share minus the binomial theory row's per f:s state, and that
    difference over the theory row's share (what every row of the chapter's Table 1.6 prints,
    though its header names the random runs), ours and the chapter's from its means."""
    panels_abs, panels_rel = [], []
    means = state_time.pivot_table(index="state", columns="controller", values="mean_pct", sort=False)
    sources = []
    if {"tavc", "theory"} <= set(means.columns):
        sources.append(("ours", list(means.index), means["tavc"].to_numpy(float), means["theory"].to_numpy(float)))
    if chapter is not None and {"tavc_mean_pct", "theory_pct"} <= set(chapter.columns):
        sources.append(("the chapter", list(chapter["state"]), chapter["tavc_mean_pct"].to_numpy(float),
                        chapter["theory_pct"].to_numpy(float)))
    for name, states, vc, t in sources:
        panels_abs.append((f"TAVC - theory (% points), {name}", _grid(states, vc - t)))
        with np.errstate(invalid="ignore", divide="ignore"):
            panels_rel.append((f"(TAVC - theory) / theory, {name}", _grid(states, np.where(t > 0, (vc - t) / t,
                                                                                          np.nan))))
    stem = Path(out_stem)
    paths = _heat_panels(panels_abs, "coolwarm", True, ".1f", "% points", title + ": difference", stem)
    paths += _heat_panels(panels_rel, "coolwarm", True, ".2f", "relative difference (colours saturate at 1)",
                          title + ": relative difference", stem.with_name(stem.name + "_relative"), limit=1.0)
    return paths


def specialisation_figure(spec: pd.DataFrame, convergence_s: float, title: str, out_stem: Path) -> list[Path]:
    """Share of each speed group's robots on the high-value circuit over time, per controller."""
    fig, ax = plt.subplots(figsize=(7.5, 4.0))
    styles = ["-", "--", ":", "-."]
    for (ctrl, group), rows in spec.groupby(["controller", "group"], sort=False):
        t = rows["t_s"].to_numpy(float) / 1000.0
        m, s = rows["mean_share_high"].to_numpy(float), rows["std_share_high"].to_numpy(float)
        ls = styles[list(dict.fromkeys(spec["group"])).index(group) % len(styles)]
        n = f" (mean, band ± std over {n_text(rows['n_trials'])})" if "n_trials" in rows else ""
        ax.plot(t, m, color=COLOURS.get(ctrl), ls=ls, label=f"{LABELS.get(ctrl, ctrl)}, {group} robots{n}")
        ax.fill_between(t, *clipped_band(m, s, 0.0, 1.0), color=COLOURS.get(ctrl), alpha=0.10, lw=0)
    if convergence_s > 0:
        ax.axvline(convergence_s / 1000.0, color="k", ls="--", lw=1, label="end of convergence period")
    ax.axhline(0.5, color="0.6", lw=1)
    ax.set_ylim(0.0, 1.0)
    ax.set_xlabel("time (1000 s)")
    ax.set_ylabel("share of the group on the high-value circuit")
    return finish_figure(fig, ax, title, out_stem)
