"""`tavc calibrate`: search the settings of every point of `calibration.grid`, record the
chosen world if asked, then measure the chosen world and every world one setting away from it
(`world_search` has the rules; this module only wires settings, runs and outputs). The CLI
composes the points' settings."""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from operator import attrgetter
from pathlib import Path

from tavc_cli.errors import TavcError
from tavc_cli.experiments.store import Executor
from tavc_cli.io import claim_folder, owned_path, refuse_folder_problem
from tavc_cli.model.report import search_text, sensitivity_text
from tavc_cli.model.world_search import Point, one_axis_variants, point_id, run_search, run_sensitivity, save_world
from tavc_cli.ownership import (
    CALIBRATION,
    CALIBRATION_FILES,
    RESULTS,
    WORLD_SEARCH_DIR,
    describe,
    refuse_other_settings,
    take,
)
from tavc_cli.ownership import read as read_owned
from tavc_cli.settings import TavcConfig


@dataclass(frozen=True)
class SearchPlan:
    """Where a search writes (`out_dir`, below `holder`, the folder its user named), how it
    measures each split (`measurement`, `run_search`'s keywords) and the settings it records
    (`identity`), checked against what stands there already."""

    holder: Path
    out_dir: Path
    measurement: dict
    identity: dict


def plan_search(base: TavcConfig, n_points: int, world_dir: Path, *, save: bool, progress: bool) -> SearchPlan:
    """The search of `n_points` grid points `base` asks for, once every check that needs no
    point's settings has passed: the folder its user named is no run's nor the file system's
    root, nothing between it and the search's folder is a link or a file, the executor can run,
    and with `save`, the world recorded in `world_dir` (conf/world/) was searched with the same
    settings or `overwrite` is set. Cheap: a command plans before it composes the grid's points."""
    cal, factor = base.calibration, float(base.scale.time_factor)
    trials = int(cal.trials_per_split)
    if base.scale.trials:
        trials = max(2, min(trials, int(base.scale.trials)))
    holder = Path(base.output_dir)
    owned = read_owned(holder) if holder.is_dir() else None
    if owned is not None and owned.kind != RESULTS:  # a run's folder: the search would nest inside it
        raise TavcError(f"output_dir: {holder} is {describe(owned.kind)}; the search goes into "
                        f"{holder / WORLD_SEARCH_DIR}: name the folder that holds it ({holder.resolve().parent}), "
                        "or another")
    refuse_folder_problem(holder, "output_dir")
    out_dir = owned_path(holder, holder / WORLD_SEARCH_DIR, folder=True, what="output_dir")
    refuse_folder_problem(out_dir, "output_dir")  # a file on the way: refused before the grid is composed
    measurement = dict(
        n_robots=int(base.team.n_robots), trials=trials, warmup_s=float(cal.warmup_s) * factor,
        measure_s=float(cal.measure_s) * factor, confidence=float(base.model.confidence),
        executor=Executor.from_config(base.executor), progress=progress,
    )
    measurement["executor"].check()
    identity = {"n_points": n_points, "values": [float(v) for v in base.tasks.values],
                "measurement": {"trials_per_split": trials, "warmup_s": measurement["warmup_s"],
                                "measure_s": measurement["measure_s"], "confidence": measurement["confidence"],
                                "n_robots": measurement["n_robots"]}}
    if save:  # conf/world/calibrated.yaml is replaced only by a search of the same settings, or when told
        refuse_other_settings(world_dir / "calibration" / "search.json", identity, "--save", base.overwrite,
                              allow=f"add overwrite=true to replace {world_dir / 'calibrated.yaml'} with this "
                                    "search's choice, or leave out --save")
    return SearchPlan(holder, out_dir, measurement, identity)


def calibrate_world(base: TavcConfig, points: Sequence[tuple[Point, TavcConfig]], plan: SearchPlan, world_dir: Path,
                    *, save: bool, echo: Callable[[str], None]) -> None:
    """Run the search `plan` planned (`plan_search`) over `points` (each grid point with its
    settings; `base` holds the search's own settings) and the sensitivity step, printing through
    `echo` as each finishes. With `save`, the chosen world is recorded in `world_dir` (conf/world/)."""
    out_dir = plan.out_dir
    with claim_folder(out_dir, within=plan.holder):
        owned = take(out_dir, CALIBRATION, CALIBRATION_FILES, save=False)  # nothing written until the checks pass
        if owned.owns("search.json"):
            refuse_other_settings(out_dir / "search.json", plan.identity, "output_dir", base.overwrite)
        owned.wrote(*CALIBRATION_FILES)  # listed before they are written, so a stopped search's are tavc's
        owned.remove_temporaries()
        written = _search_and_measure(base, points, out_dir, world_dir, plan.measurement, save=save, echo=echo)
        # an earlier search's tables and figures this one did not write go (no world chosen: no sensitivity
        # step; a grid without the docking's four settings: no sensitivity figure), only once it is done
        for name in sorted(set(CALIBRATION_FILES) - written):
            owned.remove(name)


def _search_and_measure(base: TavcConfig, points, out_dir: Path, world_dir: Path, measurement: dict, *, save: bool,
                        echo: Callable[[str], None]) -> set[str]:
    # deferred: loads matplotlib
    from tavc_cli.viz.sensitivity import sensitivity_figure, task_time_figure

    axes = base.calibration.grid
    configured = {a.key: attrgetter(a.key)(base) for a in axes}  # the world as asked, before the grid's settings
    search = run_search(points, out_dir, configured=configured, **measurement)
    echo(search_text(search))
    if save:
        path = save_world(search, world_dir, [a.key for a in axes])
        echo(f"chosen world saved as {path}")
    figures = sensitivity_figure(out_dir / "search.csv", out_dir / "sensitivity")
    chosen = search["result"]["chosen"]
    if chosen is not None:
        # the chosen world and its one-setting-changed neighbours (all grid points, composed above),
        # every split of N and N-1 robots
        composed = {point_id(p): cfg for p, cfg in points}
        variants = [(varied, p, composed[point_id(p)])
                    for varied, p in one_axis_variants(axes, {a.key: chosen[a.key] for a in axes})]
        sens = run_sensitivity(variants, out_dir, **measurement)
        echo(sensitivity_text(sens))
        figures += task_time_figure(out_dir / "sensitivity.csv", out_dir / "sensitivity.json", out_dir / "task_times")
    for path in figures:
        echo(f"figure: {path}")
    return {"search.csv", "search.json", *(["sensitivity.csv", "sensitivity.json"] if chosen is not None else []),
            *(Path(path).name for path in figures)}
