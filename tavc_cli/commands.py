"""What each command of ``tavc`` does once its arguments are parsed (`cli`): load the config,
call the library, print. Modules that pull in the simulator are imported inside the functions
that need them, so that ``tavc config`` and ``tavc list`` start fast."""

import functools
import sys
from collections.abc import Sequence
from pathlib import Path
from typing import Any, Optional

import typer

from tavc_cli import config
from tavc_cli.config.launch import launch_sweep
from tavc_cli.console import summary_text


def print_config(*, overrides: Sequence[str]) -> None:
    """Print the resolved config as YAML."""
    typer.echo(config.to_yaml(config.load_config(overrides)), nl=False)


def print_experiments() -> None:
    """Print one aligned line per experiment: its name, its section of the chapter, and what the
    chapter reports of it, as the chapter's report rather than as a fact (`tavc report` tests it).
    The words come from each experiment file's `description`, which a run also records in its
    config.yaml: rewording them there would make every saved run another configuration. The
    experiments are tavc's files and those the chapter's registry adds from the user's config
    folders (`config.describe_experiments`)."""
    items = config.describe_experiments()
    name_width = max((len(item["name"]) for item in items), default=0)
    section_width = max((len(item["section"]) for item in items), default=0)
    for item in items:
        said = str(item["description"])
        said = said if said[1:2].isupper() else said[:1].lower() + said[1:]  # an acronym keeps its capital
        typer.echo(f"{item['name']:<{name_width}}  {item['section']:<{section_width}}  "
                   f"the chapter reports that {said}")


def run(*, overrides: Sequence[str], multirun: bool, progress: bool) -> None:
    """Run one experiment, or every job of a sweep (all validated first) through a Hydra launcher."""
    if not multirun:
        # deferred: loads pandas
        from tavc_cli.api import run_summary

        return print_summary(run_summary(overrides, progress=progress))

    ours = [o for o in overrides if not config.is_hydra_override(o)]
    launch_sweep(overrides, functools.partial(sweep_job, progress=progress),
                 lambda done: write_sweep(config.swept_values(ours), [Path(f) for f in done]))


def reproduce(*, overrides: Sequence[str], names: str | None, results: Optional[Path], progress: bool,
               ladder: list[float] | None = None) -> None:
    """Compose every experiment with the same overrides (and the ladder's rungs), run them
    together, print each summary."""
    # deferred: loads pandas
    from tavc_cli.api import reproduce_summaries

    experiments = None if names is None else [n for n in names.split(",") if n]
    if results is None:  # runs/<scale>; the ladder alone runs at scale=converged unless told
        results = config.results_root(overrides, "converged" if experiments == [] else None)
    for name, summary in reproduce_summaries(overrides, experiments=experiments, results_dir=results,
                                             progress=progress, ladder=ladder):
        if name.startswith("ladder"):
            typer.echo(f"{name}:")
        print_summary(summary)
        typer.echo("")
    if ladder:
        typer.echo(f"ladder: {results / 'ladder' / 'ladder.csv'}")
        for folder in config.runs_beside(results, ladder):
            typer.echo(f"note: {folder} is no rung of this ladder; kept, and named by the report as left out")


def sweep_job(cfg: Any, *, progress: bool) -> str:
    """One job of a sweep, wherever the launcher runs it: run, print its summary, return its folder."""
    # deferred: loads the simulator's compiled kernels
    from tavc_cli.pipeline import run_experiment

    typer.echo(f"job: {cfg.output_dir}")
    summary = run_experiment(config.settings(cfg), progress=progress)
    print_summary(summary)
    return summary["output_dir"]


def write_sweep(values: list[dict[str, str]], folders: list[Path]) -> None:
    """sweep.csv and its figure beside the jobs' folders (`pipeline.write_sweep`); print where."""
    # deferred: loads the simulator's compiled kernels
    from tavc_cli.pipeline import write_sweep

    written = write_sweep(values, folders)
    if written:
        typer.echo(f"\nsweep: {written[0]}")
        for path in written[1:]:
            typer.echo(f"figure: {path}")


def print_summary(summary: dict[str, Any]) -> None:
    """Print where results went, how many trials ran, the state and performance summary, and
    whether anything was delivered (`console.summary_text`)."""
    typer.echo(summary_text(summary))


def bench(*, scenario: str, n_robots: int, n_rays: Optional[int] = None, **options: Any) -> None:
    """Run the benchmark and print its result as JSON or as aligned lines (`bench.bench_text`)."""
    # deferred: loads the simulator's compiled kernels
    from tavc_cli.bench import bench_overrides, bench_text

    def settings_for(n: int, duration: float) -> Any:
        return config.settings(config.load_config(bench_overrides(scenario, n, duration, n_rays)))

    typer.echo(bench_text(settings_for, scenario=scenario, n_robots=n_robots, n_rays=n_rays, **options))


def animate(
    *, overrides: Sequence[str], out: Optional[Path], duration_s: float, fps: int, mp4: bool
) -> None:
    """Render a run and print the files written."""
    settings = config.settings(config.load_config(overrides))
    # deferred: loads the simulator's compiled kernels and matplotlib
    from tavc_cli.viz.animate import animate_run

    paths = animate_run(settings, out=out, duration_s=duration_s, fps=fps, mp4=mp4)
    for path in paths:
        typer.echo(str(path))


def report(results_dir: Path, progress: bool | None = None, page: bool = False) -> None:
    """Build the report (with `page`, its web page too) and print its summary line and where it
    went; with `progress` (by default on a terminal), a line on stderr at each stage while it works."""
    # deferred: loads scipy and pandas
    from tavc_cli.report import build_report, summary_lines

    show = sys.stderr.isatty() if progress is None else progress
    say = (lambda line: typer.echo(line, err=True)) if show else None
    typer.echo("\n".join(summary_lines(build_report(results_dir, say, page))))


def stay_switch(results: Path, overrides: list[str], progress: bool, calibrated: Path | None = None) -> None:
    """Run the readings' stay/switch study into `results` (each reading at its calibrated
    settings with `calibrated`, `stay_switch.calibrated_overrides`) and print its summary and files."""
    # deferred: loads pandas
    import pandas as pd

    from tavc_cli.stay_switch import run_stay_switch, summary_lines

    written = run_stay_switch(results, overrides, lambda o: config.settings(config.load_config(o)), progress=progress,
                              echo=typer.echo, calibrated=calibrated)
    for line in summary_lines(pd.read_csv(written[0]), pd.read_csv(written[1])):
        typer.echo(line)
    for path in written:
        typer.echo(f"written: {path}")
