"""The horizon ladder's figure, from `ladder.csv` only: time in each state against the
length of the run (log axis), with the chapter's Table 1.2, random allocation and the
binomial row drawn as references; below it, the learner-side convergence measures and how
the group is made (stayers, alternators) at each horizon."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd

from tavc_cli.chapter import base_case
from tavc_cli.notation import STATE_PREFIX, column_state
from tavc_cli.reference import chapter_table
from tavc_cli.viz.figures import clipped_err, n_text, plt, save_figure

STATE_COLOURS = {"2:4": "tab:green", "3:3": "tab:blue", "4:2": "tab:red"}


def _series(table: pd.DataFrame, controller: str, quantity: str) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    rows = table[(table["controller"] == controller) & (table["quantity"] == quantity)]
    return (rows["duration_s"].to_numpy(float) / 3600.0, rows["mean"].to_numpy(float),
            rows["std"].to_numpy(float))


def ladder_figure(table: pd.DataFrame, out_stem: Path, chapter: pd.DataFrame | None = None) -> list[Path]:
    """Two panels: (top) TAVC's % of the stable period in each state against the run's length
    in hours, log axis, one line per state (the three central ones coloured, error bars one std
    over trials), the chapter's Table 1.2 TAVC means as stars at the chapter's 5 h, random's
    and the binomial row's 3:3 as horizontal lines; (bottom) the convergence measures and the
    share of robots that are stayers and alternators."""
    if chapter is None:
        chapter = chapter_table("1.2")
    states = [s for s in map(column_state, dict.fromkeys(table.loc[table["controller"] == "tavc", "quantity"]))
              if s is not None]
    fig, (top, bottom) = plt.subplots(2, 1, figsize=(7.5, 8.0), sharex=True,
                                      gridspec_kw={"height_ratios": [3, 2]})
    other_labelled = False
    for state in states:
        h, m, s = _series(table, "tavc", STATE_PREFIX + state)
        central = state in STATE_COLOURS
        label = f"TAVC {state}" if central else (None if other_labelled else "TAVC, other states")
        other_labelled = other_labelled or not central
        top.errorbar(h, m, yerr=clipped_err(m, s, 0.0, 100.0), marker="o", color=STATE_COLOURS.get(state, "0.75"),
                     capsize=3, lw=2 if central else 1, label=label)
    chapter_hours = 5.0
    for r in chapter.itertuples():
        if r.state in STATE_COLOURS:
            top.plot([chapter_hours], [r.tavc_mean_pct], marker="*", ms=14, color=STATE_COLOURS[r.state],
                     markeredgecolor="k", ls="none",
                     label=f"the chapter's {r.state} (Table 1.2)")
    for controller, style in (("random", "--"), ("theory", ":")):
        h, m, _ = _series(table, controller, STATE_PREFIX + "3:3")
        if len(m):
            top.axhline(float(np.nanmean(m)), color="0.3", ls=style, lw=1,
                        label=f"{'random' if controller == 'random' else 'binomial'} 3:3")
    top.set_xscale("log")
    tavc = table[(table["controller"] == "tavc") & table["quantity"].str.startswith(STATE_PREFIX)]
    n = n_text(tavc["n_trials"]) if "n_trials" in tavc else "trials"
    top.set_ylabel(f"% of the stable period\n(mean ± std over {n}, cut at 0 and 100)")
    top.set_ylim(bottom=0.0)
    top.set_title(f"{base_case().name}: time in each state against the horizon")
    top.legend(fontsize=7, ncol=2)
    top.grid(alpha=0.3)
    for quantity, label, colour in (("q_drift", "Q drift over the last quarter (median)", "tab:purple"),
                                    ("policy_changed_share", "robots whose greedy policy changed, last quarter",
                                     "tab:brown")):
        h, m, _ = _series(table, "tavc", quantity)
        if len(m):
            bottom.plot(h, m, marker="s", color=colour, label=label)
    robots = _series(table, "tavc", "n_alternators")[1]
    if len(robots):
        h = _series(table, "tavc", "n_alternators")[0]
        total = sum(_series(table, "tavc", q)[1] for q in ("n_stayers_high", "n_stayers_low", "n_alternators",
                                                           "n_mixed"))
        with np.errstate(invalid="ignore", divide="ignore"):
            bottom.plot(h, robots / total, marker="^", color="tab:cyan", label="share of robots alternating")
            stayers = _series(table, "tavc", "n_stayers_high")[1] + _series(table, "tavc", "n_stayers_low")[1]
            bottom.plot(h, stayers / total, marker="v", color="tab:olive", label="share of robots staying")
    bottom.axhline(0.05, color="tab:purple", ls=":", lw=1)
    bottom.set_xscale("log")
    bottom.set_ylim(0, 1.05)
    bottom.set_xlabel("length of the run (h; the chapter's: 5 h)")
    bottom.set_ylabel("share")
    if bottom.get_legend_handles_labels()[0]:
        bottom.legend(fontsize=7)
    bottom.grid(alpha=0.3)
    fig.tight_layout()
    return save_figure(fig, out_stem)
