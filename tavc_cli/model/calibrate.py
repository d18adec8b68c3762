"""`tavc calibrate`: compose one config per point of `calibration.grid`, search them, record
the chosen world if asked, then measure the chosen world and every world one setting away
from it (`world_search` has the rules; this module only wires config, runs and outputs)."""

from __future__ import annotations

from collections.abc import Callable, Sequence
from pathlib import Path

from tavc_cli import config
from tavc_cli.errors import TavcError
from tavc_cli.experiments.store import Executor
from tavc_cli.model.report import search_text, sensitivity_text
from tavc_cli.model.world_search import (
    grid_points,
    one_axis_variants,
    point_id,
    point_overrides,
    run_search,
    run_sensitivity,
    save_world,
)


def calibrate_world(overrides: Sequence[str], *, save: bool, progress: bool, echo: Callable[[str], None]) -> None:
    """Run the search and the sensitivity step, printing through `echo` as each finishes."""
    from tavc_cli.viz.sensitivity import sensitivity_figure, task_time_figure

    if not any(o.split("=", 1)[0].lstrip("+~") == "experiment" for o in overrides):
        overrides = ["experiment=initial_distribution", *overrides]  # six robots, the chapter's values
    base = config.to_container(config.load_config(overrides))
    axes = base["calibration"]["grid"]
    if not axes:
        raise TavcError("calibration.grid: empty; nothing to search")
    points = [(p, config.to_container(config.load_config([*overrides, *point_overrides(p)])))
              for p in grid_points(axes)]
    cal, factor = base["calibration"], float(base["scale"]["time_factor"])
    trials = int(cal["trials_per_split"])
    if base["scale"].get("trials"):
        trials = max(2, min(trials, int(base["scale"]["trials"])))
    out_dir = Path(base["output_dir"]).parent / "calibration" / "world"
    measurement = dict(
        n_robots=int(base["team"]["n_robots"]), trials=trials, warmup_s=float(cal["warmup_s"]) * factor,
        measure_s=float(cal["measure_s"]) * factor, confidence=float(base["model"]["confidence"]),
        executor=Executor.from_mapping(base["executor"]), progress=progress,
    )
    search = run_search(points, out_dir, **measurement)
    echo(search_text(search))
    if save:
        path = save_world(search, config.find_conf_dir() / "world", [a["key"] for a in axes])
        echo(f"chosen world saved as {path}")
    figures = sensitivity_figure(out_dir / "search.csv", out_dir / "sensitivity")
    chosen = search["result"]["chosen"]
    if chosen is not None:
        # the chosen world and its one-setting-changed neighbours (all grid points, composed above),
        # every split of N and N-1 robots
        composed = {point_id(p): cfg for p, cfg in points}
        variants = [(varied, p, composed[point_id(p)])
                    for varied, p in one_axis_variants(axes, {a["key"]: chosen[a["key"]] for a in axes})]
        sens = run_sensitivity(variants, out_dir, **measurement)
        echo(sensitivity_text(sens))
        figures += task_time_figure(out_dir / "sensitivity.csv", out_dir / "sensitivity.json", out_dir / "task_times")
    for path in figures:
        echo(f"figure: {path}")
