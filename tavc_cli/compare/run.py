"""Run the comparison's controllers on the scenarios and write its outputs.

A controller is a learner's config name (``learner=<name>``; ``tavc`` is each scenario's own
TAVC learner, e-greedy or softmax as the chapter has it). Its runs go, every scenario together
(their shared history simulated once), into ``RESULTS/runs/<controller>/<scenario>`` with no
baselines beside it (random is a controller of the comparison like the others). A rerun reuses
every finished trial; runs of another configuration in those folders are refused as ``tavc run``
refuses them. ``reuse`` takes a controller's runs from a folder that already holds them (one
folder per scenario, e.g. ``results/converged`` for TAVC at 40 times the chapter's durations)
instead of running them.

Outputs in RESULTS: ``compare.csv`` (`metrics.TABLE_COLUMNS`), ``compare_trials.csv`` (every
trial's four numbers), ``compare.md`` (the table as a reader reads it) and ``compare.png/.svg``.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path

import pandas as pd

from tavc_cli.compare.metrics import METRICS, TABLE_COLUMNS, comparison_table, cut_fill_delays, order, trial_metrics
from tavc_cli.config.model_file import model_allocations
from tavc_cli.errors import TavcError
from tavc_cli.io import claim_folder, write_text_atomic
from tavc_cli.learning.registry import LEARNS_NOTHING, controller_label
from tavc_cli.readers import load_yaml
from tavc_cli.settings import TavcConfig


def controller_overrides(name: str, scale: Mapping) -> list[str]:
    """What a controller's runs add to the user's overrides: its learner, no baselines, and
    for a controller that learns nothing at a scale with a baselines' schedule, that schedule."""
    extra = [] if name == "tavc" else [f"learner={name}"]
    extra.append("baselines=[]")
    theirs = scale.get("baseline_time_factor")
    if name in LEARNS_NOTHING and theirs is not None and float(theirs) != float(scale["time_factor"]):
        extra.append(f"scale.time_factor={float(theirs)!r}")
    return extra


def parse_reuse(items: Sequence[str]) -> dict[str, Path]:
    """``NAME=FOLDER`` pairs (``--reuse``), each folder holding one run folder per scenario."""
    out = {}
    for item in items:
        name, sep, folder = item.partition("=")
        if not sep or not name or not folder:
            raise TavcError(f"--reuse: {item!r} is not CONTROLLER=FOLDER (e.g. tavc=results/converged)")
        if not Path(folder).is_dir():
            raise TavcError(f"--reuse: no folder {folder}")
        out[name] = Path(folder)
    return out


def run_compare(plans: Mapping[str, Sequence[TavcConfig]], results: Path, *, controllers: Sequence[str],
                experiments: Sequence[str], reuse: Mapping[str, Path], model_file: str, scale_name: str,
                progress: bool = False) -> dict:
    """Run what is missing of `plans` (each controller's experiments, composed at the front door
    into ``results/runs/<controller>``), then write the comparison (module docstring). Returns
    where each output went and the table."""
    from tavc_cli.ownership import COMPARE, COMPARE_FILES, take
    from tavc_cli.pipeline import run_experiments

    unknown = [name for name in reuse if name not in controllers]
    if unknown:
        raise TavcError(f"--reuse: {unknown[0]} is not one of the controllers compared ({', '.join(controllers)})")
    allocations = model_allocations(model_file)  # the predicted states: known before anything runs
    for folder in reuse.values():
        missing = [e for e in experiments if not (folder / e / "trial_stats.csv").is_file()]
        if missing:
            raise TavcError(f"--reuse: {folder / missing[0]} holds no finished run of {missing[0]} "
                            "(no trial_stats.csv)")
    results = Path(results)
    results.mkdir(parents=True, exist_ok=True)
    with claim_folder(results):  # a comparison's from the start: its runs/ are not runs of their own
        take(results, COMPARE, COMPARE_FILES, "--results")
    cfgs = [cfg for name in controllers if name not in reuse for cfg in plans[name]]
    if cfgs:
        run_experiments(list(cfgs), progress=progress)
    folders = {name: reuse.get(name, results / "runs" / name) for name in controllers}
    trials, factors = [], {}
    for name in controllers:
        for experiment in experiments:
            folder = folders[name] / experiment
            trials.append(trial_metrics(folder, experiment, name, controller_label(name), allocations))
            factors.setdefault(name, _time_factor(folder))
    trials_frame = cut_fill_delays(pd.concat(trials, ignore_index=True))
    table = order(comparison_table(trials_frame, factors), experiments, controllers)
    return write(results, table, trials_frame, folders, scale_name=scale_name)


def _time_factor(folder: Path) -> float:
    return float(load_yaml(folder / "config.yaml")["scale"]["time_factor"])


def write(results: Path, table: pd.DataFrame, trials: pd.DataFrame, folders: Mapping[str, Path], *,
          scale_name: str) -> dict:
    """The comparison's files in `results` (tavc's own only, `ownership`)."""
    from tavc_cli.compare.figures import comparison_figure
    from tavc_cli.ownership import COMPARE, COMPARE_FILES, take

    results.mkdir(parents=True, exist_ok=True)
    with claim_folder(results):
        owned = take(results, COMPARE, COMPARE_FILES, "--results")
        write_text_atomic(results / "compare.csv", table[TABLE_COLUMNS].to_csv(index=False, float_format="%.6g"))
        write_text_atomic(results / "compare_trials.csv", trials.to_csv(index=False, float_format="%.6g"))
        write_text_atomic(results / "compare.md", markdown(table, folders, scale_name))
        figures = comparison_figure(table, results / "compare")
        for name in COMPARE_FILES:
            owned.wrote(name)
    return {"results": str(results), "table": table, "figures": [str(p) for p in figures]}


def markdown(table: pd.DataFrame, folders: Mapping[str, Path], scale_name: str) -> str:
    """The table as a reader reads it: one block per scenario, a row per controller, a column
    per number (mean ± std, n), then the tests."""
    factors = table.groupby("controller", sort=False)["time_factor"].first()
    lines = [f"# Learners compared on the chapter's scenarios (scale={scale_name})", "",
             "Mean ± standard deviation over trials (n); p: two-sided Mann-Whitney U against TAVC and against "
             "random allocation. Multiple of the chapter's durations each controller ran at: "
             + ", ".join(f"{c} {f:g}x" for c, f in factors.items())
             + ".", ""]
    for experiment, rows in table.groupby("experiment", sort=False):
        lines += [f"## {experiment}", "", "| controller | " + " | ".join(METRICS[m] for m in rows["metric"].unique())
                  + " |", "|---" * (1 + rows["metric"].nunique()) + "|"]
        for controller, mine in rows.groupby("controller", sort=False):
            cells = [_cell(r) for r in mine.to_dict("records")]
            lines.append(f"| {controller} | " + " | ".join(cells) + " |")
        lines.append("")
    lines += ["Runs: " + "; ".join(f"{c}: {f}" for c, f in folders.items()), ""]
    return "\n".join(lines)


def _cell(row: Mapping) -> str:
    def p(x: float) -> str:
        return "" if pd.isna(x) else f"{x:.2g}"

    tests = ", ".join(t for t in (f"p_TAVC {p(row['p_vs_tavc'])}" if p(row["p_vs_tavc"]) else "",
                                  f"p_random {p(row['p_vs_random'])}" if p(row["p_vs_random"]) else "") if t)
    spread = "" if pd.isna(row["std"]) else f" ± {row['std']:.3g}"
    return f"{row['mean']:.3g}{spread} (n {row['n_trials']}{'; ' + tests if tests else ''})"
