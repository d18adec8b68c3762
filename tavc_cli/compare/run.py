"""Run the comparison's controllers on the scenarios and write its outputs.

A controller is a learner's config name (``learner=<name>``; ``tavc`` is each scenario's own
TAVC learner, e-greedy or softmax as the chapter has it). Its runs go, every scenario together
(their shared history simulated once), into ``RESULTS/runs/<controller>/<scenario>`` with no
baselines beside it (random is a controller of the comparison like the others). A rerun reuses
every finished trial; runs of another configuration in those folders are refused as ``tavc run``
refuses them. ``reuse`` takes a controller's runs from a folder that already holds them (one
folder per scenario, e.g. ``results/converged`` for TAVC at 40 times the chapter's durations)
instead of running them. Each is checked before its tables are read or anything is written
(`check_reused`): a finished run, its files whole and unchanged as `tavc report` checks them, of
the scenario, of the controller, at the settings the comparison would run it at, with at least
as many trials.

Outputs in RESULTS: ``compare.csv`` (`metrics.TABLE_COLUMNS`), ``compare_trials.csv`` (every
trial's four numbers), ``compare.md`` (the table as a reader reads it) and ``compare.png/.svg``.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path

import pandas as pd

from tavc_cli.analysis.claims import not_a_verdict
from tavc_cli.compare.figures import comparison_figure
from tavc_cli.compare.metrics import METRICS, TABLE_COLUMNS, comparison_table, cut_fill_delays, order, trial_metrics
from tavc_cli.errors import TavcError
from tavc_cli.io import claim_folder, write_text_atomic
from tavc_cli.learning.parameters import PluginSettings
from tavc_cli.learning.plugins import target_digest
from tavc_cli.learning.registry import LEARNS_NOTHING, controller_label
from tavc_cli.model.allocations import model_allocations
from tavc_cli.ownership import COMPARE, COMPARE_FILES, config_differences, take
from tavc_cli.readers import load_yaml
from tavc_cli.run_checks import check_run, this_code
from tavc_cli.settings import TavcConfig, to_yaml


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


# what a reused run may differ in from the comparison's own: its baselines (not read) and how
# many trials it ran (a trial's seed does not depend on how many there are: `trials_short` asks
# only for enough of them)
REUSE_MAY_DIFFER = ("baselines", "trials", "scale.trials", "baseline_trials", "static_trials")
REUSE_ADVICE = ("name a folder holding this controller's finished runs at the comparison's settings, or leave it "
                "out of --reuse to run them")


def check_reused(folder: Path, planned: TavcConfig, label: str) -> None:
    """Refuse, in one line (``--reuse: <folder>: <what is wrong>; <what to do>``), a folder the
    comparison would read instead of running `planned` (the run it would make of one scenario
    for the controller whose trials are labelled `label`), unless it holds a finished run
    (its `provenance.json` there) whose files are whole and unchanged (`run_checks.check_run`,
    as `tavc report` checks a run), computed by this tavc's code, of that scenario, of
    that learner with trials of `label` (of a learner from outside tavc, by its code as it is now),
    at `planned`'s settings but `REUSE_MAY_DIFFER`, and with at least `planned`'s trials."""
    experiment = str(planned.experiment_name)
    _refuse_unfinished(folder, experiment)
    try:
        facts = check_run(folder)
    except TavcError as error:
        raise TavcError(f"--reuse: {error}") from None
    if facts.other_code is not None:
        raise _refused(folder, f"computed by another version of tavc's code ({facts.other_code}; this tavc's: "
                       f"{this_code()})")
    if isinstance(planned.learner, PluginSettings):  # a learner from outside tavc: its code as it is now
        ours = target_digest(str(planned.learner.target))
        theirs = sorted({str(d.get("digest")) for d in facts.learner_code.values() if isinstance(d, dict)})
        if ours not in theirs:
            raise _refused(folder, f"computed by other code of the learner ({', '.join(theirs) or 'none recorded'}; "
                           f"its code now: {ours})")
    recorded = load_yaml(folder / "config.yaml")
    if recorded.get("experiment_name") != experiment:
        raise _refused(folder, f"a run of {recorded.get('experiment_name')}, not of {experiment}")
    learner = (recorded.get("learner") or {}).get("name")
    if learner != planned.learner.name:
        raise _refused(folder, f"a run of learner {learner}, not of {planned.learner.name}")
    differ = config_differences(folder / "config.yaml", to_yaml(planned), ignore=REUSE_MAY_DIFFER)
    if differ:
        raise _refused(folder, f"a run at other settings than the comparison's ({'; '.join(differ)})")
    short = trials_short(facts.trials or frozenset(), label, int(planned.trials))
    if short:
        raise _refused(folder, short)


def refuse_reuse(reuse: Mapping[str, Path], controllers: Sequence[str], experiments: Sequence[str]) -> None:
    """What `check_reused` can tell before any run is planned, so that it is said before the
    settings of every controller are composed: a controller in `reuse` that is not compared, and a
    scenario's folder there that holds no finished run."""
    unknown = [name for name in reuse if name not in controllers]
    if unknown:
        raise TavcError(f"--reuse: {unknown[0]} is not one of the controllers compared ({', '.join(controllers)})")
    for folder in reuse.values():
        for experiment in experiments:
            _refuse_unfinished(Path(folder) / experiment, experiment)


def _refuse_unfinished(folder: Path, experiment: str) -> None:
    for name in ("provenance.json", "trial_stats.csv"):
        if not (folder / name).is_file():
            raise _refused(folder, f"holds no finished run of {experiment} (no {name})")


def trials_short(trials: frozenset[tuple[str, int]], label: str, wanted: int) -> str:
    """What is missing of the trials ``0..wanted-1`` labelled `label` among `trials` ((label,
    trial) pairs, as a run's provenance.json lists them); empty where none is."""
    missing = [k for k in range(wanted) if (label, k) not in trials]
    if not missing:
        return ""
    return f"no trial {missing[0]} of {label} among those its provenance.json lists; the comparison runs {wanted}"


def _refused(folder: Path, what: str) -> TavcError:
    return TavcError(f"--reuse: {folder}: {what}; {REUSE_ADVICE}")


def run_compare(plans: Mapping[str, Sequence[TavcConfig]], results: Path, *, controllers: Sequence[str],
                experiments: Sequence[str], reuse: Mapping[str, Path], model_file: str, scale_name: str,
                progress: bool = False) -> dict:
    """Run what is missing of `plans` (each controller's experiments, composed at the front door
    into ``results/runs/<controller>``) but the controllers in `reuse`, whose folders are checked
    against their plans first (`check_reused`), then write the comparison (module docstring).
    Returns where each output went and the table."""
    # deferred: loads the simulator's compiled kernels
    from tavc_cli.pipeline import run_experiments

    refuse_reuse(reuse, controllers, experiments)
    allocations = model_allocations(model_file)  # the predicted states: known before anything runs
    for name, folder in reuse.items():
        planned = {str(cfg.experiment_name): cfg for cfg in plans[name]}
        for experiment in experiments:
            check_reused(folder / experiment, planned[experiment], controller_label(name))
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
    # runs below the chapter's scale make a comparison that is no verdict: its figure says so
    mark = next((m for runs in plans.values() for cfg in runs if (m := not_a_verdict(cfg))), "")
    return write(results, table, trials_frame, folders, scale_name=scale_name, mark=mark)


def _time_factor(folder: Path) -> float:
    return float(load_yaml(folder / "config.yaml")["scale"]["time_factor"])


def write(results: Path, table: pd.DataFrame, trials: pd.DataFrame, folders: Mapping[str, Path], *,
          scale_name: str, mark: str = "") -> dict:
    """The comparison's files in `results` (tavc's own only, `ownership`); `mark` on its figure
    (`viz.figures.marked`)."""
    # deferred: loads matplotlib
    from tavc_cli.viz.figures import marked

    results.mkdir(parents=True, exist_ok=True)
    with claim_folder(results):
        owned = take(results, COMPARE, COMPARE_FILES, "--results")
        write_text_atomic(results / "compare.csv", table[TABLE_COLUMNS].to_csv(index=False, float_format="%.6g"))
        write_text_atomic(results / "compare_trials.csv", trials.to_csv(index=False, float_format="%.6g"))
        write_text_atomic(results / "compare.md", markdown(table, folders, scale_name))
        with marked(mark):
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
