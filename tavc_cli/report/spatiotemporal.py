"""The report's lines for section 1.4's experiment: Table 1.1 beside the chapter's, the
group's target time (Figure 1.4's kind), the learned policies, the lanes, and how long trials
that end with a number of deliveries ran."""

from __future__ import annotations

from pathlib import Path

import pandas as pd
from scipy import stats

from tavc_cli.reference import chapter_table
from tavc_cli.report.figures import figure_link
from tavc_cli.report.text import fmt
from tavc_cli.settings import TavcConfig


def spatiotemporal_lines(name: str, d: Path, cfg: TavcConfig, results_dir: Path, fig_dir: Path | None = None,
                         label: str | None = None) -> list[str]:
    """Section 1.4: Table 1.1 beside the chapter's, Figure 1.4's kind, the learned policies, the
    lanes; the figures under `fig_dir` (results_dir/figures unless given), their titles naming
    `label` (the experiment's name unless given)."""
    # deferred: loads the simulator's compiled kernels; loads matplotlib
    from tavc_cli.analysis.spatiotemporal import target_time_curve
    from tavc_cli.viz.spatial import lane_figure, target_time_figure

    ours = pd.read_csv(d / "table_1_1.csv")
    chapter = chapter_table("1.1")
    lines = ["Individual traversal time after n traversals (mean ± std over robots) and the group's target time "
             "after m arrivals (mean ± std over trials), the chapter's Table 1.1 beside ours. Both as the chapter "
             "defines them: a traversal runs from a sink via the source back to a sink, a target time lies "
             "between two arrivals at either a source or a sink. (The chapter's own last row, a target time a "
             "fifth of the traversal time with five robots, fits one arrival per traversal rather than two.)", "",
             "| n | chapter | ours (robots) | m | chapter | ours (trials) |", "|---|---|---|---|---|---|"]
    for o, c in zip(ours.itertuples(), chapter.itertuples(), strict=True):
        lines.append(f"| {o.n_traversals} | {c.mean_traversal_s:.1f} ± {c.std_traversal_s:.1f} | "
                     f"{fmt(o.mean_traversal_s)} ± {fmt(o.std_traversal_s)} ({o.n_robots}) | {o.m_arrivals} | "
                     f"{c.mean_target_s:.1f} ± {c.std_target_s:.1f} | {fmt(o.mean_target_s)} ± "
                     f"{fmt(o.std_target_s)} ({o.n_trials}) |")
    lines.append("")
    lines += trial_length_lines(d, cfg)
    fig_dir = fig_dir or results_dir / "figures"
    link, label = figure_link(results_dir, fig_dir), label or name
    if (d / "target_times.csv").is_file():
        target_time_figure(target_time_curve(pd.read_csv(d / "target_times.csv")), chapter,
                           f"{label}: the group's target time over arrivals (Figure 1.4's kind)", fig_dir / "fig_1_4")
        lines += [f"![Figure 1.4, tavc]({link}/fig_1_4.png)", ""]
    if (d / "policy.csv").is_file():
        pol = pd.read_csv(d / "policy.csv")
        shares = ", ".join(f"{c[len('share_'):]} {pol[c].mean():.2f}" for c in pol.columns if c.startswith("share_"))
        rates = ", ".join(f"{c[len('stop_rate_'):]} {pol[c].mean():.2f}" for c in pol.columns
                          if c.startswith("stop_rate_"))
        learned = f", {pol['n_states'].mean():.1f} of the 32 states on average" if "n_states" in pol else ""
        lines += [f"Learned policies ({len(pol)} robots, final Q-tables, over the states each robot learned in"
                  f"{learned}): share whose best behaviour is each behaviour: {shares}. Stop-rates (share of those "
                  f"states with that marking in view, and no yellow for red, green and front, whose best behaviour "
                  f"is stop): {rates}.", ""]
    if (d / "lanes.csv").is_file():
        lanes = pd.read_csv(d / "lanes.csv")
        parts = [f"{w} {g['mean_left_m'].mean():+.3f} ± {fmt(g['mean_left_m'].std(ddof=1), '.3f')} m"
                 for w, g in lanes.groupby("window", sort=False)]
        text = ("Lanes: mean offset to the left of the direction of travel, robots driving along the source-sink "
                "axis away from its ends, per trial (mean ± std over trials): " + "; ".join(parts) + ".")
        wide = lanes.pivot_table(index="trial", columns="window", values="mean_left_m")
        if {"early", "late"} <= set(wide.columns) and len(wide.dropna()) >= 2:
            both = wide.dropna()
            res = stats.ttest_rel(both["late"], both["early"])
            text += (f" Late against early, paired two-sided over {len(both)} trials (reported, not part of a "
                     f"verdict): t = {res.statistic:.2f}, p = {res.pvalue:.3g}.")
        lines += [text, ""]
    if (d / "occupancy.csv").is_file():
        arena = cfg.arena
        xy = {t.name: (float(t.x), float(t.y)) for t in arena.targets}
        lane_figure(pd.read_csv(d / "occupancy.csv"), xy[arena.circuits[0].source],
                    xy[arena.circuits[0].sink], f"{label}: where the robots drive", fig_dir / f"lanes_{name}")
        lines += [f"![lanes, {label}]({link}/lanes_{name}.png)", ""]
    return lines


def trial_length_lines(d: Path, cfg: TavcConfig) -> list[str]:
    """How long the trials ran, where they end with a number of deliveries (traversals)."""
    if cfg.deliveries is None or not (d / "trial_stats.csv").is_file():
        return []
    stats = pd.read_csv(d / "trial_stats.csv")
    if "duration_s" not in stats:
        return []
    x = stats["duration_s"].to_numpy(float)
    capped = int((x >= float(cfg.duration_s)).sum())
    return [f"Each trial ran until its robots had made {cfg.deliveries} traversals together (the chapter: "
            f"{cfg.paper.deliveries}), at most {float(cfg.duration_s):,.0f} s: its trials ran "
            f"{x.min():,.0f} to {x.max():,.0f} s (mean {x.mean():,.0f} s)"
            + (f"; {capped} of {len(x)} reached the limit first" if capped else "") + ".", ""]
