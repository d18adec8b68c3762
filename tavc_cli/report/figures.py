"""An experiment's figures for REPORT.md, drawn from its saved tables under the results
folder's `figures/`, with the markdown lines that show them."""

from __future__ import annotations

import json
from pathlib import Path
from urllib.parse import quote

import pandas as pd

from tavc_cli.analysis.claims import not_a_verdict
from tavc_cli.chapter import EXPERIMENTS, base_case, state_table_id
from tavc_cli.experiments.plan import RunPlan, read_plan
from tavc_cli.notation import state_counts
from tavc_cli.reference import chapter_table
from tavc_cli.report.files import config_of, model_misfit
from tavc_cli.settings import TavcConfig


def find_model(experiments: dict[str, Path]) -> Path | None:
    """The model's output to draw predictions from: the chapter's base case's (`make model` measures
    it there), else any run's; only a model of the run it sits in (`files.model_misfit`)."""
    base = base_case().name
    folders = sorted(experiments.items(), key=lambda kv: kv[0] != base)
    for _, d in folders:
        path = d / "model" / "model.json"
        if path.is_file() and not model_misfit(path, config_of(d / "config.yaml")):
            return path
    return None


def predicted_segments(cfg: TavcConfig, model_json: Path | None) -> list[tuple[float, float, str, float]]:
    """(from s, to s, label, robots on the high circuit) the model predicts between breakdowns."""
    if model_json is None or len(cfg.arena.circuits) != 2 or model_misfit(model_json, cfg):
        return []
    by_size = json.loads(model_json.read_text()).get("by_team_size", {})
    start, end = -float(cfg.sim.warmup_s), float(cfg.duration_s)
    times = sorted(float(b.time_s) for b in cfg.events.breakdowns
                   if start < float(b.time_s) < end)
    n = int(cfg.team.n_robots) - sum(1 for b in cfg.events.breakdowns if float(b.time_s) <= start)
    out = []
    for a, b in zip([start, *times], [*times, end], strict=True):
        entry = by_size.get(str(n)) if isinstance(by_size, dict) else None
        state = entry.get("predicted_state") if isinstance(entry, dict) else None
        counts = state_counts(state)
        if counts is not None:  # a state the model file does not give is not drawn
            out.append((a, b, f"{n} robots: {state}", float(counts[0])))
        n -= 1
    return out


def baseline_levels(frame: pd.DataFrame, cfg: TavcConfig, plan: RunPlan, mean: str, std: str) -> pd.DataFrame:
    """`frame` (a table over time) with each baseline that ran another schedule than the learner
    (`scale.baseline_time_factor`) drawn as its stable-period level: its mean and std over its
    own stable period (the std: its bins' mean spread over trials), at every time of the
    learner's stable period (each controller's periods: the run's `plan`). A time series of the
    chapter's length would otherwise sit in the first per cent of a long run's axis."""
    if plan.shared_schedule:
        return frame
    learner = frame["controller"] == "tavc"
    mine = frame[learner]
    times = mine.loc[mine["t_s"] >= float(cfg.convergence_s), "t_s"].drop_duplicates()
    parts = [mine]
    for controller, rows in frame[~learner].groupby("controller", sort=False):
        own = plan.controller(str(controller)).schedule
        stable = rows[(rows["t_s"] >= own.convergence_s) & (rows["t_s"] < own.duration_s)]
        level = pd.DataFrame({"t_s": times.to_numpy(float), "controller": controller,
                              mean: stable[mean].mean(), std: stable[std].mean()})
        if "n_trials" in rows:
            level["n_trials"] = rows["n_trials"].max()
        parts.append(level)
    return pd.concat(parts, ignore_index=True)


def experiment_figures(name: str, d: Path, cfg: TavcConfig, state_time: pd.DataFrame, results_dir: Path,
                       model_json: Path | None, fig_dir: Path | None = None, label: str | None = None) -> list[str]:
    """Draw this experiment's figures under `fig_dir` (results_dir/figures unless given), their
    titles naming `label` (the experiment's name unless given); markdown lines that show them
    (baselines on another schedule than the learner's drawn as levels: `baseline_levels`). A run
    below the chapter's scale marks each of its figures "not a verdict" (`viz.figures.marked`)."""
    # deferred: loads matplotlib
    from tavc_cli.viz.figures import marked

    with marked(not_a_verdict(cfg)):
        return _experiment_figures(name, d, cfg, state_time, results_dir, model_json, fig_dir, label)


def _experiment_figures(name: str, d: Path, cfg: TavcConfig, state_time: pd.DataFrame, results_dir: Path,
                        model_json: Path | None, fig_dir: Path | None, label: str | None) -> list[str]:
    # deferred: loads matplotlib
    from tavc_cli.viz.figures import allocation_figure, performance_figure, state_figure

    fig_dir = fig_dir or results_dir / "figures"
    link, label = figure_link(results_dir, fig_dir), label or name
    experiment = EXPERIMENTS.get(name)
    state_fig, perf_fig = (experiment.state_figure, experiment.performance_figure) if experiment else (None, None)
    conv = float(cfg.convergence_s or 0.0)
    event = float(cfg.sim.warmup_s) > 0
    plan = read_plan(d, cfg)
    lines = []
    if cfg.analysis.state == "groups":
        return group_figures(name, d, cfg, state_time, fig_dir, link, label)
    if state_fig is not None:
        table = state_table_id(name)
        stem = f"fig_{state_fig.replace('.', '_')}"
        state_figure(state_time, chapter_table(table) if table else None,
                     f"{label}: % of the stable period in each state (the chapter's Figure {state_fig})",
                     fig_dir / stem)
        lines.append(f"![Figure {state_fig}, tavc]({link}/{stem}.png)")
    if perf_fig is not None and (d / "performance.csv").is_file():
        stem = f"fig_{perf_fig.replace('.', '_')}"
        performance_figure(baseline_levels(pd.read_csv(d / "performance.csv"), cfg, plan, "mean", "std"), conv, event,
                           f"{label}: performance over time (the chapter's Figure {perf_fig})", fig_dir / stem)
        lines.append(f"![Figure {perf_fig}, tavc]({link}/{stem}.png)")
    if (d / "allocation.csv").is_file():
        allocation_figure(baseline_levels(pd.read_csv(d / "allocation.csv"), cfg, plan, "mean_high", "std_high"),
                          predicted_segments(cfg, model_json), conv, event,
                          f"{label}: robots on the high-value circuit over time", fig_dir / f"allocation_{name}")
        lines.append(f"![robots on the high-value circuit, {label}]({link}/allocation_{name}.png)")
    lines += q_figure(name, d, cfg, fig_dir, link, label)
    return [*lines, ""] if lines else []


def figure_link(results_dir: Path, fig_dir: Path) -> str:
    """`fig_dir` as a markdown link from REPORT.md in results_dir (each part URL-quoted: a
    run's folder may be named `1_tasks.values=_2200,2000_`)."""
    return "/".join(quote(part) for part in fig_dir.relative_to(results_dir).parts)


def group_figures(name: str, d: Path, cfg: TavcConfig, state_time: pd.DataFrame, fig_dir: Path,
                  link: str = "figures", label: str | None = None) -> list[str]:
    """Fast and slow robots: the f:s grids (Figure 1.12's kind), TAVC against the theory row (1.13's),
    each speed group on the high-value circuit over time, and the Q-values of trial 0."""
    # deferred: loads matplotlib
    from tavc_cli.viz.groups import group_difference_figure, group_state_figure, specialisation_figure

    label = label or name
    table = state_table_id(name)
    chapter = chapter_table(table) if table else None
    group_state_figure(state_time, chapter, f"{label}: % of the stable period in each state f:s (Figure 1.12's kind)",
                       fig_dir / "fig_1_12")
    group_difference_figure(state_time, chapter, f"{label}: TAVC against the theory row (Figure 1.13's kind)",
                            fig_dir / "fig_1_13")
    lines = [f"![Figure 1.12, tavc]({link}/fig_1_12.png)", f"![Figure 1.13, tavc]({link}/fig_1_13.png)",
             f"![Figure 1.13, relative, tavc]({link}/fig_1_13_relative.png)"]
    if (d / "specialisation.csv").is_file():
        specialisation_figure(_group_levels(pd.read_csv(d / "specialisation.csv"), cfg, read_plan(d, cfg)),
                              float(cfg.convergence_s or 0.0),
                              f"{label}: each speed group's share on the high-value circuit",
                              fig_dir / f"specialisation_{name}")
        lines.append(f"![specialisation, {label}]({link}/specialisation_{name}.png)")
    lines += q_figure(name, d, cfg, fig_dir, link, label)
    return [*lines, ""]


def _group_levels(spec: pd.DataFrame, cfg: TavcConfig, plan: RunPlan) -> pd.DataFrame:
    """`baseline_levels` for each speed group's share on the high-value circuit."""
    if plan.shared_schedule:
        return spec
    parts = [baseline_levels(rows, cfg, plan, "mean_share_high", "std_share_high").assign(group=group)
             for group, rows in spec.groupby("group", sort=False)]
    return pd.concat(parts, ignore_index=True)[list(spec.columns)] if parts else spec


def final_high_circuit(cfg: TavcConfig) -> int:
    """The circuit with the highest learning value at the end of the run (after any value change)."""
    values = cfg.tasks.values
    changes = cfg.events.value_changes
    if changes:
        values = sorted(changes, key=lambda c: float(c.time_s))[-1].values
    return int(max(range(len(values)), key=lambda i: float(values[i]))) if values else 0


def q_figure(name: str, d: Path, cfg: TavcConfig, fig_dir: Path, link: str = "figures",
             label: str | None = None) -> list[str]:
    """The Q-tables of the first TAVC trial (trial 0, fixed before looking), robot by robot."""
    path = d / "q_values.csv"
    if not path.is_file():
        return []
    # deferred: loads matplotlib
    from tavc_cli.viz.figures import q_value_figure

    q = pd.read_csv(path)
    q = q[(q["controller"] == "tavc") & (q["trial"] == 0)]
    if not len(q):
        return []
    robots = None
    if (d / "robots.csv").is_file():
        r = pd.read_csv(d / "robots.csv")
        robots = r[(r["controller"] == "tavc") & (r["trial"] == 0)]
    label = label or name
    q_value_figure(q, robots, final_high_circuit(cfg), float(cfg.convergence_s or 0.0),
                   f"{label}: Q-values of TAVC trial 0, robot by robot", fig_dir / f"q_values_{name}")
    return [f"![Q-values of trial 0, {label}]({link}/q_values_{name}.png)"]
