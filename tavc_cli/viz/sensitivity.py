"""How much the predicted allocation rests on the docking reconstruction: a figure of the
world search (a pure function of its saved table, `search.csv`)."""

from __future__ import annotations

import json
from pathlib import Path

import pandas as pd

from tavc_cli.viz.figures import plt, save_figure

ZONE, DWELL, READ, RAYS = "robot.dock.occupied_m", "robot.dock.dwell_s", "robot.behaviour.arrive_dist_m", \
    "robot.laser.n_rays"


def sensitivity_figure(search_csv: Path, out_stem: Path) -> list[Path]:
    """Crowding ratio t(4 on a circuit) / t(3 on the other) and arrivals per 5 h against the
    dock zone, one line per dwell, one column of panels per reading distance and laser
    resolution; the chapter's w_high / w_low drawn as the line (1.3) must clear."""
    frame = pd.read_csv(search_csv)
    needed = {ZONE, DWELL, READ, RAYS}
    if not needed <= set(frame.columns):
        return []
    panels = sorted({(r, n) for r, n in zip(frame[READ], frame[RAYS], strict=True)})
    fig, axes = plt.subplots(2, len(panels), figsize=(3.2 * len(panels), 5.6), sharex=True, sharey="row",
                             squeeze=False)
    rho = float(frame["chapter_ratio"].iloc[0])
    for col, (read, rays) in enumerate(panels):
        sub = frame[(frame[READ] == read) & (frame[RAYS] == rays)]
        for dwell, rows in sub.groupby(DWELL):
            rows = rows.sort_values(ZONE)
            line, = axes[0, col].plot(rows[ZONE], rows["crowding_ratio_6"], marker="o", label=f"dwell {dwell:g} s")
            robust = rows[rows["robust"]]
            axes[0, col].plot(robust[ZONE], robust["crowding_ratio_6"], "o", ms=10, mfc="none", color=line.get_color())
            axes[1, col].plot(rows[ZONE], rows["arrivals_per_5h"], marker="o", color=line.get_color())
        chosen = sub[sub["chosen"]]
        if len(chosen):
            axes[0, col].plot(chosen[ZONE], chosen["crowding_ratio_6"], "*", ms=16, color="k", label="chosen")
        axes[0, col].axhline(rho, color="grey", ls="--", lw=1)
        axes[1, col].axhline(3000, color="grey", ls="--", lw=1)
        axes[0, col].set_title(f"reading {read:g} m, {rays:g} rays", fontsize=9)
        axes[1, col].set_xlabel("dock zone held by one robot (m)")
    axes[0, 0].set_ylabel("t(4 on a circuit) / t(3 on the other)")
    axes[1, 0].set_ylabel("target arrivals per 5 h, six robots")
    axes[0, 0].legend(fontsize=7)
    fig.suptitle("Docking reconstruction: crowding needed by (1.3) (dashed: w_high / w_low = "
                 f"{rho:.2f}; circles: robust) and arrivals (dashed: the chapter's 3000)", fontsize=9)
    fig.tight_layout()
    return save_figure(fig, out_stem)


def task_time_figure(sensitivity_csv: Path, sensitivity_json: Path, out_stem: Path) -> list[Path]:
    """t_i(n) on the high-value circuit for n = 1..N (the rest of the team on the other),
    one panel per grid axis: the chosen world in black, the worlds that differ from it on
    that axis alone in colour, each labelled with its crowding ratio and the allocations
    the model predicts for N and N-1 robots with the chapter's values."""
    frame = pd.read_csv(sensitivity_csv)
    worlds = {w["world"]: w for w in json.loads(Path(sensitivity_json).read_text())["worlds"]}
    axes_varied = [v for v in dict.fromkeys(frame["varied"]) if v != "chosen"]
    if not axes_varied or "chosen" not in worlds:
        return []
    n_team = int(frame["n_on_circuit"].max())
    high = int(frame.loc[frame["value"].idxmax(), "circuit"])
    fig, axes = plt.subplots(1, len(axes_varied), figsize=(3.6 * len(axes_varied), 4.0), sharey=True, squeeze=False)

    def label(name: str) -> str:
        w = worlds[name]
        ratio = w.get("crowding_ratio_6")
        return (f"{name}: t4/t3 {'-' if ratio is None else format(ratio, '.2f')}, "
                f"{n_team}\u2192{w[f'predicted_{n_team}']}, {n_team - 1}\u2192{w[f'predicted_{n_team - 1}']}")

    for ax, varied in zip(axes[0], axes_varied, strict=True):
        others = dict.fromkeys(frame["world"][frame["varied"] == varied])
        for name, color in [("chosen", "k")] + [(w, None) for w in others]:
            rows = frame[(frame["world"] == name) & (frame["circuit"] == high)].sort_values("n_on_circuit")
            # a task time is never below 0: an interval over few trials that reaches below it is cut there
            err = [rows["task_time_s"] - rows["t_lo"].clip(lower=0.0), rows["t_hi"] - rows["task_time_s"]]
            ax.errorbar(rows["n_on_circuit"], rows["task_time_s"], yerr=err, marker="o", ms=4, capsize=2,
                        color=color, lw=2 if name == "chosen" else 1, label=label(name))
        ax.set_title(f"varying {varied.rsplit('.', 1)[1]}", fontsize=9)
        ax.set_xlabel(f"robots on the high-value circuit (of {n_team})")
        ax.legend(fontsize=6.5, loc="upper left")
        ax.set_xticks(range(1, n_team + 1))
    per_split = json.loads(Path(sensitivity_json).read_text()).get("measurement", {}).get("trials_per_split")
    over = f" over {per_split} trials per split" if per_split else ""
    axes[0, 0].set_ylabel(f"task time t(n) on the high-value circuit (s),\nmean and 90 % interval{over}")
    fig.suptitle("How the task times and the predicted allocation rest on the docking reconstruction "
                 "(one setting changed at a time)", fontsize=9)
    fig.tight_layout()
    return save_figure(fig, out_stem)
