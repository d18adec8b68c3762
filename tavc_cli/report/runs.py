"""The runs under a results folder, and several runs of one experiment in it (a sweep's jobs,
two runs side by side, a run in a folder of its own further down): every run folder at any
depth is found (`run_folders`); the claims are tested on one run per experiment, designated
by its folder's name, and each of the others gets a section of its own, titled with its
folder relative to the results folder: its state table, its figures under
`figures/runs/<folder>/`, and the settings in which it differs from the designated run. The
runs of the studies the report reads as a whole (`study_runs`) and every run's place in the
report are listed in *The runs in this folder* (`run_list_lines`)."""

from __future__ import annotations

import json
import math
import os
from collections.abc import Sequence
from pathlib import Path

import pandas as pd

from tavc_cli.analysis.claims import scale_shortfall
from tavc_cli.analysis.comparison import experiment_comparison
from tavc_cli.chapter import order_key, state_table_id
from tavc_cli.dotted import dotted, plain
from tavc_cli.ownership import (
    CALIBRATION,
    COMPARE,
    MODEL,
    READINGS,
    STUDY,
    SURROGATE,
    TASKS,
    TURN_TAKING_KIND,
    read,
)
from tavc_cli.readers import load_json
from tavc_cli.report.figures import experiment_figures
from tavc_cli.report.files import (
    READINGS_RUNS,
    SWEEPS,
    config_of,
    horizon_folders,
    is_horizon_folder,
    is_run_folder,
    natural,
    read_ladder,
    read_or_refuse,
    sweep_runs,
    there,
)
from tavc_cli.report.spatiotemporal import spatiotemporal_lines
from tavc_cli.report.text import performance, run_lines, state_table
from tavc_cli.run_checks import this_code
from tavc_cli.run_tables import rung_factor, rung_folders
from tavc_cli.settings import TavcConfig
from tavc_cli.table_cells import damaged

RUNS_DIR = "runs"  # under a horizon's figures/: one folder of figures per run beside the designated one
# folders directly under the results folder that the report reads otherwise than run by run:
# the longer horizons (`horizon_folders`, their runs found there in turn), the sweeps of the value
# ratio and the team size (`files.SWEEPS`) and the runs in other readings (`files.READINGS_RUNS`);
# under a horizon, the horizon ladder (`time_scale.ladder_lines`) and its readings
LADDER = "ladder"


def folder_kind(d: Path) -> str | None:
    """The kind of output tavc keeps in `d` (`ownership`: run, surrogate, surrogate-study, ...),
    or None where it recognises none."""
    owned = read(d)
    return owned.kind if owned is not None else None


def on_surrogate(d: Path) -> bool:
    """Whether the run in `d` was computed by the surrogate of the learning dynamics (its folder's
    kind, `tavc surrogate`), not the physical simulator."""
    return folder_kind(d) == SURROGATE


# what a link to a folder in a results folder is, where the report names it
LINK_LEFT_OUT = "a symbolic link, which the report does not follow (it reads each run where it lies)"


def run_folders(folder: Path, top: bool = True, links: list[Path] | None = None) -> list[Path]:
    """Every run folder under `folder` at any depth (`is_run_folder`), in natural order of
    their paths: a run's own folder is not searched further (its `trials/`, `model/`), nor
    `figures/`, hidden folders, or what the report reads otherwise (directly under the results
    folder, `top`: the longer horizons, the sweeps (`files.SWEEPS`) and the runs in other readings of
    the world, `readings/`; a `ladder/` with its `ladder.csv`). A link is not followed: each run
    is found once, where it lies, and a link that loops back leads nowhere; the links to folders
    passed over are added to `links`, where given (those that lead to a run within three levels),
    so that a run reached only through one is said to be left out."""
    out = []
    if links is not None:  # a link the search would have entered, to a run or a folder of runs
        links += sorted((p for p in folder.iterdir() if p.is_symlink() and p.is_dir() and not p.name.startswith(".")
                         and p.name != "figures" and _holds_runs(p)), key=lambda p: natural(p.name))
    for d in sorted((p for p in folder.iterdir() if p.is_dir() and not p.is_symlink()),
                    key=lambda p: natural(p.name)):
        read_otherwise = top and (d.name in (*SWEEPS, READINGS_RUNS) or is_horizon_folder(d))
        if d.name == "figures" or d.name.startswith(".") or read_otherwise \
                or (d.name == LADDER and (d / "ladder.csv").is_file()):
            continue
        if folder_kind(d) in (STUDY, TASKS, COMPARE, READINGS, MODEL, TURN_TAKING_KIND, CALIBRATION):  # read as a whole
            continue
        out += [d] if is_run_folder(d) else run_folders(d, top=False, links=links)
    return out


def _holds_runs(folder: Path, depth: int = 3) -> bool:
    """Whether `folder` is a run's folder or holds one within `depth` levels below it (looked into,
    never written; no link below it followed)."""
    if is_run_folder(folder):
        return True
    try:
        below = [d for d in folder.iterdir() if d.is_dir() and not d.is_symlink()] if depth else []
    except OSError:  # a folder that cannot be listed holds nothing the report could read
        return False
    return any(_holds_runs(d, depth - 1) for d in below)


def finished_runs(results_dir: Path, links: list[Path] | None = None) -> tuple[dict[str, list[Path]], list[Path]]:
    """experiment name -> the folders of its finished runs (their `provenance.json`, written
    last, is there) at any depth under results_dir (`run_folders`: not a longer horizon's nor a
    study's), the one its claims are tested on first (`designated_first`), in the chapter's
    order; and the folders of runs that did not finish (the links to folders passed over added to
    `links`, where given: `run_folders`)."""
    found: dict[str, list[Path]] = {}
    unfinished = []
    for d in run_folders(results_dir, links=links):
        if (d / "provenance.json").is_file():  # finished: its settings and states are files, whatever stands there
            odd = next((d / n for n in ("config.yaml", "state_time.csv")
                        if os.path.lexists(d / n) and not (d / n).is_file()), None)
            if odd is not None:
                raise damaged(odd, "not a regular file, where a finished run keeps one")
        if (d / "state_time.csv").is_file() and (d / "config.yaml").is_file() and (d / "provenance.json").is_file():
            found.setdefault(str(read_or_refuse(d / "config.yaml", config_of).experiment_name or d.name), []).append(d)
        else:
            unfinished.append(d)
    ordered = sorted(found.items(), key=lambda kv: order_key(kv[0]))
    return {name: designated_first(name, folders, results_dir) for name, folders in ordered}, unfinished


def study_runs(results_dir: Path) -> list[tuple[str, list[Path]]]:
    """(what reads them, run folders) for the studies the report reads as a whole: the
    horizon ladder's rungs, the runs in other readings, the sweeps' runs (`files.SWEEPS`)."""
    out = []
    for horizon in horizon_folders(results_dir):
        ladder = horizon / LADDER
        if (ladder / "ladder.csv").is_file() and (rungs := ladder_rungs(ladder)[0]):
            out.append(("the horizon ladder, in *The time scale*", rungs))
    for top in (results_dir, *horizon_folders(results_dir)):
        found = sorted((p for p in (top / READINGS_RUNS).rglob("config.yaml")), key=lambda p: natural(p.as_posix())) \
            if (top / READINGS_RUNS).is_dir() else []
        if found:
            out.append(("runs in other readings of the world, in *The readings* (the models' check points) and "
                        "*In other readings of the world* (the chapter's experiments)", [p.parent for p in found]))
    for folder, what in SWEEPS.items():
        found = sweep_runs(results_dir, folder)
        if found:
            out.append((what, found))
    return out


UNREADABLE_RUNG = "its config.yaml cannot be read"  # why `ladder_rungs` leaves a run out that could be any rung


def ladder_rungs(ladder: Path) -> tuple[list[Path], list[tuple[Path, str]]]:
    """A horizon ladder's folder (`ladder/`, with its `ladder.csv`): the rungs its table lists, in
    the order of their factors (`run_tables.rung_folders`), and the other runs beside them, each
    with why the report leaves it out: a rung at a factor the table does not list (an earlier
    ladder's, or one still running), a second run at a listed factor, a run whose config.yaml
    cannot be read, a link to a folder of runs."""
    factors = sorted({float(f) for f in read_ladder(ladder / "ladder.csv")["factor"]})
    found = rung_folders(ladder, factors)
    rungs = [found[f] for f in factors if f in found]
    read_at = {f"{f:.4f}": d for f, d in found.items()}
    others = []
    for d in sorted(ladder.iterdir(), key=lambda p: natural(p.name)):
        if d.name.startswith(".") or d in rungs or not d.is_dir():
            continue
        if d.is_symlink():
            others += [(d, LINK_LEFT_OUT)] if _holds_runs(d) else []
            continue
        if not is_run_folder(d):
            continue
        factor = rung_factor(d)
        others.append((d, UNREADABLE_RUNG if factor is None else
                       f"a second run at {float(factor):g} times the chapter's durations, beside the rung the "
                       f"ladder's table is held to, `{read_at[factor].name}`" if factor in read_at else
                       "not a rung the `ladder.csv` beside it lists (one of an earlier ladder, or one still "
                       "running); `tavc ladder` with its factor among the others reads it"))
    return rungs, others


def horizon_ladders(horizon_dirs: Sequence[Path]) -> dict[Path, list[Path]]:
    """Each horizon ladder's `ladder.csv` among `horizon_dirs` (anything at `<horizon>/ladder/ladder.csv`,
    read and checked: `files.read_ladder`) -> the runs beside it the report checks: the rungs it
    lists that have their tables, and those whose config.yaml cannot be read, which could be any
    rung (the run checks name what is wrong with it)."""
    tables = [d / LADDER / "ladder.csv" for d in horizon_dirs if there(d / LADDER / "ladder.csv")]
    out = {}
    for table in tables:
        rungs, others = ladder_rungs(table.parent)
        out[table] = [d for d in [*rungs, *(o for o, why in others if why == UNREADABLE_RUNG)]
                      if (d / "trial_stats.csv").is_file()]
    return out


def designated_first(name: str, folders: list[Path], results_dir: Path | None = None) -> list[Path]:
    """`folders`, every one a run of experiment `name`, in the report's order: first the run
    the claims are tested on (the folder named exactly after the experiment, the one nearest
    the results folder first, else the first by its path), then the others by path."""
    key = (lambda d: (len(d.relative_to(results_dir).parts), natural(d.relative_to(results_dir).as_posix()))) \
        if results_dir is not None else (lambda d: natural(d.as_posix()))
    folders = sorted(folders, key=lambda d: (on_surrogate(d), key(d)))  # the simulator's runs before the surrogate's
    named = [d for d in folders if d.name == name and not on_surrogate(d)][:1] or \
        [d for d in folders if d.name == name][:1]
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
    horizon's figures, its path relative to the horizon (`breakdown/1_seed=2`), so that no name
    collides with the designated run's nor with another sweep's job of the same name."""
    return horizon / "figures" / RUNS_DIR / d.relative_to(horizon)


def setting_differences(d: Path, base: Path, base_name: str | None = None) -> list[str]:
    """The settings in which run `d`'s config.yaml differs from run `base`'s, each as
    ``key value (`base`: value)`` (`base_name`, the folder's name unless given); where a run
    writes is no setting of it."""
    base_name = base_name or base.name
    ours, theirs = _settings(d), _settings(base)
    out = []
    for key in [*ours, *(k for k in theirs if k not in ours)]:
        if key == "output_dir" or ours.get(key, _UNSET) == theirs.get(key, _UNSET):
            continue
        out.append(f"{key} {_show(ours.get(key, _UNSET))} (`{base_name}`: {_show(theirs.get(key, _UNSET))})")
    return out


_UNSET = object()


def _settings(d: Path) -> dict:
    """Run `d`'s settings as today's tavc reads its config.yaml (`from_yaml`: a record written
    before a key existed reads with its default, and its learner's node as the learner declares
    it), as dotted keys."""
    return dotted(plain(config_of(d / "config.yaml")), keep_empty=False)


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
    prov = load_json(d / "provenance.json")
    diffs = setting_differences(d, base, rel(base, results_dir))
    if on_surrogate(d) and not on_surrogate(base):
        diffs = ["its engine: the surrogate of the learning dynamics (`tavc surrogate`), not the simulator", *diffs]
    engine = ", on the surrogate" if on_surrogate(d) else ""
    lines = [f"### {rel(d, results_dir)}: another run of {name}{engine}{horizon}", "",
             f"The claims about {name} are tested on `{rel(base, results_dir)}`, not on this run, which differs "
             "from it " + ("in " + "; ".join(diffs) if diffs else "in no setting but its folder") + ".", ""]
    lines += deliveries
    table = state_table_id(name)
    lines += ["% of the stable period in each state, mean ± std over trials"
              + (f"; the chapter's Table {table} beside ours:" if table else ":"), "",
              *state_table(state_time, experiment_comparison(name, state_time)), ""]
    if (d / "trial_stats.csv").is_file():
        lines += [performance(pd.read_csv(d / "trial_stats.csv")), ""]
    lines += figure_lines
    lines += run_lines(name, d, cfg, prov, pd.DataFrame({"claim_id": []}), {})
    return lines


def draw_figures(name: str, d: Path, cfg: TavcConfig, horizon: Path, results_dir: Path,
                 model_json: Path | None) -> list[str]:
    """The figures of a run beside the designated one, under `figure_dir`, with the markdown
    lines that show them from results_dir's REPORT.md (run in the report's figure pool)."""
    fig_dir = figure_dir(d, horizon)
    label = f"{name} ({rel(d, results_dir)})"
    if (d / "table_1_1.csv").is_file():
        return spatiotemporal_lines(name, d, cfg, results_dir, fig_dir, label)
    state_time = pd.read_csv(d / "state_time.csv", dtype={"state": str})
    return experiment_figures(name, d, cfg, state_time, results_dir, model_json, fig_dir, label)


def other_code_lines(other: dict[Path, str], results_dir: Path) -> list[str]:
    """The report's paragraph on the runs computed by other code than this tavc's (`other`: each
    with that code's digest, `RunFacts.other_code`), by folder; none where there are none."""
    if not other:
        return []
    groups: dict[Path, list[Path]] = {}
    for d in sorted(other, key=lambda d: natural(rel(d, results_dir))):
        groups.setdefault(d.parent, []).append(d)
    where = ", ".join(f"`{rel(parent, results_dir)}/` ({len(runs)} runs)" if len(runs) > 1 else
                      f"`{rel(runs[0], results_dir)}`" for parent, runs in groups.items())
    digests = ", ".join(f"`{c}`" for c in sorted(set(other.values())))
    return [f"**Runs of other code.** {len(other)} of the runs this report reads were computed by another version "
            f"of tavc's code (digest {digests}; this tavc's: {this_code()}): {where}. Their numbers are shown as "
            "that code made them, not as this code makes them; the command that made each, run again with this "
            "tavc, computes them anew (a trial is reused only under its key, which holds the code's digest).", ""]


def run_list_lines(results_dir: Path, horizons: list, linked: Sequence[Path] = ()) -> list[str]:
    """*The runs in this folder*: every run folder under results_dir, finished or not, with
    its experiment, scale and trials, and where the report uses it: the run a claim is tested
    on, a section of its own, a study read as a whole, or left out (and why). `horizons` are
    the report's (`horizons.Horizon`), the chapter's durations first; `linked`, the links to
    folders of runs its search passed over (`finished_runs`)."""
    rows = []
    for h in horizons:
        for name, d in h.experiments.items():
            rows.append((d, f"the claims about {name} {h.named} are tested on it"))
            rows += [(o, f"a section of its own, under {name}") for o in h.others.get(name, [])]
        rows += [(d, "left out: the run did not finish (no provenance.json)") for d in h.unfinished]
    linked = list(linked)
    for ladder in (h / LADDER for h in horizon_folders(results_dir) if (h / LADDER / "ladder.csv").is_file()):
        others = ladder_rungs(ladder)[1]
        rows += [(d, f"left out: {why}") for d, why in others if not d.is_symlink()]
        linked += [d for d, _ in others if d.is_symlink()]  # named, never read through
    lines = ["## The runs in this folder", "",
             "Every run under this folder, and where this report uses it.", "",
             "| run | experiment | scale | trials | in this report |", "|---|---|---|---|---|"]
    for d, use in sorted(rows, key=lambda r: natural(rel(r[0], results_dir))):
        lines.append(f"| `{rel(d, results_dir)}` | {_facts(d)} | {use} |")
    lines += [f"| `{rel(d, results_dir)}` | - | - | - | left out: {LINK_LEFT_OUT} |" for d in linked]
    for what, folders in study_runs(results_dir):
        groups: dict[Path, list[Path]] = {}
        for d in folders:
            groups.setdefault(d.parent, []).append(d)
        for parent, members in groups.items():
            names = ", ".join(f"`{d.name}`" for d in members)
            lines.append(f"| `{rel(parent, results_dir)}/`: {names} | {_facts(members[0], several=len(members))} | "
                         f"read as a whole: {what} |")
    return [*lines, ""]


def _facts(d: Path, several: int = 1) -> str:
    """A run's experiment, scale (and "not a verdict" where it is below the chapter's) and
    trials, as three table cells; for `several` runs of a study, the first one's experiment
    and scale and how many runs."""
    try:
        cfg = config_of(d / "config.yaml")
    except Exception:  # an unfinished run's settings may be missing or half-written: name what is known
        return " |  | "
    short = scale_shortfall(cfg)
    scale = str(cfg.scale.name) + (f" (not a verdict: {short})" if short else "")
    if on_surrogate(d):
        scale += " (on the surrogate)"
    if several > 1:  # a study's runs: no verdict is taken on them, but their scale is said all the same
        return f"{cfg.experiment_name} | {cfg.scale.name}{f' ({short})' if short else ''} | {several} runs"
    return f"{cfg.experiment_name} | {scale} | {cfg.trials}"
