"""Several runs of one experiment in a results folder (a sweep's jobs, two runs side by side):
the claims are tested on one of them, designated by its folder's name, and each of the
others gets a section of its own: its state table, its figures under
`figures/runs/<folder>/`, and the settings in which it differs from the designated run."""

from __future__ import annotations

import json
import math
from pathlib import Path

import pandas as pd
import yaml

from tavc_cli.analysis.comparison import experiment_comparison
from tavc_cli.reference import TABLES
from tavc_cli.report.text import performance, run_lines, state_table
from tavc_cli.settings import TavcConfig

RUNS_DIR = "runs"  # under a horizon's figures/: one folder of figures per run beside the designated one


def designated_first(name: str, folders: list[Path]) -> list[Path]:
    """`folders`, every one a run of experiment `name`, in the report's order: first the run
    the claims are tested on (the folder named exactly after the experiment, else the first
    by name), then the others by name."""
    folders = sorted(folders)
    named = [d for d in folders if d.name == name]
    return [*named, *(d for d in folders if d not in named)]


def choice_lines(name: str, folders: list[Path], results_dir: Path) -> list[str]:
    """Where an experiment has several runs: which one its claims are tested on, and why."""
    if len(folders) < 2:
        return []
    first, others = folders[0], folders[1:]
    why = "the folder named after the experiment" if first.name == name else "the first by name; none is named after it"
    return [f"There are {len(folders)} runs of {name} here. The claims are tested on `{rel(first, results_dir)}` "
            f"({why}); the others each have a section of their own below: "
            + ", ".join(f"`{rel(d, results_dir)}`" for d in others) + ".", ""]


def rel(d: Path, results_dir: Path) -> str:
    """A run's folder as the report names it: relative to the results folder."""
    return d.relative_to(results_dir).as_posix()


def figure_dir(d: Path, horizon: Path) -> Path:
    """Where the figures of a run beside the designated one go: its own folder under the
    horizon's figures, so that no name collides with the designated run's."""
    return horizon / "figures" / RUNS_DIR / d.name


def setting_differences(d: Path, base: Path) -> list[str]:
    """The settings in which run `d`'s config.yaml differs from run `base`'s, each as
    ``key value (`base`: value)``; where a run writes is no setting of it."""
    ours, theirs = _flat(yaml.safe_load((d / "config.yaml").read_text())), _flat(
        yaml.safe_load((base / "config.yaml").read_text()))
    out = []
    for key in [*ours, *(k for k in theirs if k not in ours)]:
        if key == "output_dir" or ours.get(key, _UNSET) == theirs.get(key, _UNSET):
            continue
        out.append(f"{key} {_show(ours.get(key, _UNSET))} (`{base.name}`: {_show(theirs.get(key, _UNSET))})")
    return out


_UNSET = object()


def _flat(data, prefix: str = "") -> dict:
    """A nested mapping as dotted keys (lists stay whole: `tasks.values`)."""
    if not isinstance(data, dict):
        return {prefix.rstrip("."): data}
    out: dict = {}
    for key, value in data.items():
        out.update(_flat(value, f"{prefix}{key}.") if isinstance(value, dict) else {f"{prefix}{key}": value})
    return out


def _show(value) -> str:
    if value is _UNSET:
        return "not set"
    if isinstance(value, float) and math.isfinite(value):
        return f"{value:g}"
    return json.dumps(value) if isinstance(value, (list, dict, str)) or value is None else str(value)


def other_run_lines(name: str, d: Path, cfg: TavcConfig, base: Path, results_dir: Path, figure_lines: list[str],
                    deliveries: list[str], horizon: str = "") -> list[str]:
    """The section of a run beside the designated one (`base`): titled with its folder, the
    settings in which it differs, what was delivered where nothing was (`deliveries`), its
    state table beside the chapter's, its performance, its figures (`figure_lines`, drawn by
    the caller) and the command and provenance of the run. `horizon` names the horizon
    after the title."""
    state_time = pd.read_csv(d / "state_time.csv", dtype={"state": str})
    prov = json.loads((d / "provenance.json").read_text())
    diffs = setting_differences(d, base)
    lines = [f"### {rel(d, results_dir)}: another run of {name}{horizon}", "",
             f"The claims about {name} are tested on `{rel(base, results_dir)}`, not on this run, which differs "
             "from it " + ("in " + "; ".join(diffs) if diffs else "in no setting but its folder") + ".", ""]
    lines += deliveries
    table = TABLES.get(name)
    lines += ["% of the stable period in each state, mean ± std over trials"
              + (f"; the chapter's Table {table} beside ours:" if table else ":"), "",
              *state_table(state_time, experiment_comparison(name, state_time)), ""]
    if (d / "trial_stats.csv").is_file():
        lines += [performance(pd.read_csv(d / "trial_stats.csv")), ""]
    lines += figure_lines
    lines += run_lines(name, cfg, prov, pd.DataFrame({"claim_id": []}), {})
    return lines


def draw_figures(name: str, d: Path, cfg: TavcConfig, horizon: Path, results_dir: Path,
                 model_json: Path | None) -> list[str]:
    """The figures of a run beside the designated one, under `figure_dir`, with the markdown
    lines that show them from results_dir's REPORT.md (run in the report's figure pool)."""
    from tavc_cli.report.figures import experiment_figures
    from tavc_cli.report.studies import spatiotemporal_lines

    fig_dir = figure_dir(d, horizon)
    label = f"{name} ({rel(d, results_dir)})"
    if (d / "table_1_1.csv").is_file():
        return spatiotemporal_lines(name, d, cfg, results_dir, fig_dir, label)
    state_time = pd.read_csv(d / "state_time.csv", dtype={"state": str})
    return experiment_figures(name, d, cfg, state_time, results_dir, model_json, fig_dir, label)
