"""Figures of the surrogate's study (`surrogate.study`), drawn from its tables only."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pandas as pd

from tavc_cli.chapter import base_case
from tavc_cli.viz.figures import plt, save_figure

ENGINES = {"simulator": ("physical simulator", "0.25"), "surrogate_makeup": ("surrogate, by make-up", "tab:blue"),
           "surrogate_stayers": ("surrogate, by stayers alone", "tab:orange")}


def study_figures(out: Path) -> list[Path]:
    """Every figure whose table the study has written."""
    out = Path(out)
    written: list[Path] = []
    if (out / "comparison.csv").is_file():
        written += comparison_figure(pd.read_csv(out / "comparison.csv"), out / "comparison")
    if (out / "phase.csv").is_file():
        written += phase_figure(pd.read_csv(out / "phase.csv"), out / "phase")
    if (out / "horizon.csv").is_file():
        written += horizon_figure(pd.read_csv(out / "horizon.csv"), out / "horizon")
    return written


def comparison_figure(table: pd.DataFrame, stem: Path) -> list[Path]:
    """Per experiment and horizon: the largest difference from the simulator in any state's share
    (left), and the alternators per trial of each engine (right)."""
    horizons = list(dict.fromkeys(table["horizon"]))
    experiments = list(dict.fromkeys(table["experiment"]))
    fig, axes = plt.subplots(len(horizons), 2, figsize=(11, 3.2 * len(horizons)), squeeze=False)
    x = np.arange(len(experiments))
    for row, horizon in enumerate(horizons):
        here = table[table["horizon"] == horizon]
        for col, (quantity, label) in enumerate((("largest_diff_pts", "largest difference in a state's share (points)"),
                                                  ("n_alternators", "alternators per trial"))):
            ax = axes[row][col]
            engines = [e for e in ENGINES if e in set(here["engine"]) and not (col == 0 and e == "simulator")]
            width = 0.8 / max(1, len(engines))
            for k, engine in enumerate(engines):
                values = [here.loc[(here["experiment"] == e) & (here["engine"] == engine), quantity].mean()
                          for e in experiments]
                name, colour = ENGINES[engine]
                ax.bar(x + (k - (len(engines) - 1) / 2) * width, np.nan_to_num(values), width, label=name,
                       color=colour)
            ax.set_xticks(x, [e.replace("_", "\n") for e in experiments], fontsize=8)
            ax.set_ylabel(label, fontsize=8)
            ax.set_title(f"{horizon} the chapter's durations", fontsize=9)
            ax.set_ylim(bottom=0)
            if row == 0:
                ax.legend(fontsize=7)
    fig.suptitle("The surrogate beside the physical simulator (means over each run's trials, the same trial counts)",
                 fontsize=10)
    fig.tight_layout()
    return save_figure(fig, stem)


def phase_figure(table: pd.DataFrame, stem: Path) -> list[Path]:
    """Per horizon: the learners' share of robot-time on the high-value circuit (left; the model's
    predicted share written in each cell) and the share of alternators among the robots (right),
    over team size and value ratio; the simulator's checked points circled, their value beside."""
    sur = table[table["engine"] == "surrogate"]
    sim = table[table["engine"] == "simulator"]
    horizons = list(dict.fromkeys(sur["horizon"]))
    teams, ratios = sorted(sur["n_robots"].unique()), sorted(sur["ratio"].unique())
    fig, axes = plt.subplots(len(horizons), 2, figsize=(11, 4.2 * len(horizons)), squeeze=False)
    for row, horizon in enumerate(horizons):
        here = sur[sur["horizon"] == horizon]
        share = _grid(here, teams, ratios, "high_share")
        alternators = _grid(here.assign(alt=here["n_alternators"] / here["n_robots"]), teams, ratios, "alt")
        model = _grid(here, teams, ratios, "model_high_share")
        for col, (grid, title, cmap) in enumerate(((share, "share of robot-time on the high-value circuit", "viridis"),
                                                   (alternators, "alternators among the robots", "magma"))):
            ax = axes[row][col]
            image = ax.imshow(grid, origin="lower", aspect="auto", vmin=0, vmax=1, cmap=cmap)
            fig.colorbar(image, ax=ax, fraction=0.046, pad=0.04)
            ax.set_xticks(range(len(ratios)), [f"{r:g}" for r in ratios], fontsize=8)
            ax.set_yticks(range(len(teams)), [str(n) for n in teams], fontsize=8)
            ax.set_xlabel("value ratio w_high / w_low", fontsize=8)
            ax.set_ylabel("robots", fontsize=8)
            ax.set_title(f"{title}, {horizon}", fontsize=9)
            if col == 0:
                for i in range(len(teams)):
                    for j in range(len(ratios)):
                        if not math.isnan(model[i, j]):
                            ax.text(j, i, f"{model[i, j]:.2f}", ha="center", va="center", fontsize=6, color="w")
            checked = sim[sim["horizon"] == horizon]
            for r in checked.itertuples():
                if r.n_robots in teams and r.ratio in ratios:
                    i, j = teams.index(r.n_robots), ratios.index(r.ratio)
                    value = r.high_share if col == 0 else r.n_alternators / r.n_robots
                    ax.scatter([j], [i], s=220, facecolors="none", edgecolors="red", linewidths=1.5)
                    ax.annotate(f"sim {value:.2f}", (j, i), xytext=(6, 8), textcoords="offset points", fontsize=7,
                                color="red")
    n = int(sur["n_trials"].max()) if len(sur) else 0
    fig.suptitle(f"Phase diagram on the surrogate (means over {n} trials a cell; white numbers: the model's "
                 "predicted share; red circles: the physical simulator)", fontsize=10)
    fig.tight_layout()
    return save_figure(fig, stem)


def _grid(frame: pd.DataFrame, teams, ratios, column: str) -> np.ndarray:
    grid = np.full((len(teams), len(ratios)), np.nan)
    for r in frame.itertuples():
        grid[teams.index(r.n_robots), ratios.index(r.ratio)] = getattr(r, column)
    return grid


def horizon_figure(table: pd.DataFrame, stem: Path) -> list[Path]:
    """The first multiple of the chapter's duration at which the learners converge, against
    epsilon, alpha and gamma (the others at the chapter's values); above the ladder's top: not
    within it."""
    engine = table["engine"] if "engine" in table else pd.Series("surrogate", index=table.index)
    checked = table[(engine == "simulator") & (table["parameter"] == "chapter")]
    table = table[engine != "simulator"]
    chapter = table[table["parameter"] == "chapter"]
    top = float(table["factor"].max())
    fig, axes = plt.subplots(1, 3, figsize=(11, 3.2), sharey=True)
    base = {"epsilon": 0.1, "alpha": 0.1, "gamma": 0.95}
    for ax, name in zip(axes, ("epsilon", "alpha", "gamma"), strict=True):
        rows = table[table["parameter"] == name].drop_duplicates("value")[["value", "horizon"]]
        if len(chapter):
            rows = pd.concat([rows, pd.DataFrame({"value": [base[name]], "horizon": [chapter["horizon"].iloc[0]]})])
        rows = rows.sort_values("value")
        shown = np.where(np.isfinite(rows["horizon"]), rows["horizon"], top * 2)
        ax.plot(rows["value"], shown, "o-", color="tab:blue")
        ax.axhline(top, color="0.6", lw=0.8, ls="--")
        if len(checked):
            first = float(checked["horizon"].iloc[0])
            ax.scatter([base[name]], [first if math.isfinite(first) else top * 2], s=160, facecolors="none",
                       edgecolors="red", linewidths=1.5, label="physical simulator", zorder=3)
            ax.legend(fontsize=7)
        ax.set_xlabel(name)
        ax.set_yscale("log")
        ax.set_title(f"the chapter's {name} = {base[name]:g}", fontsize=9)
    axes[0].set_ylabel("converged from (x the chapter's duration)")
    fig.suptitle(f"Convergence horizon on the surrogate ({base_case().name}, {int(table['factor'].nunique())} "
                 f"horizons, {int(table['n_trials'].max()) if 'n_trials' in table else 8} trials each; above the "
                 f"dashed line: not within {top:g}x; red: the simulator's ladder)", fontsize=10)
    fig.tight_layout()
    return save_figure(fig, stem)
