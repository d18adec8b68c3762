"""The ``tavc`` command line.

Each command parses its arguments and hands them to one function: a keyword-only one of
`tavc_cli.commands`, or the Python API's (`tavc_cli.api`, which `tavc model` and `tavc calibrate`
share with notebooks); those functions load the config, call the library, and print. There is no
domain logic here. A ``TavcError`` or an ``OSError`` anywhere becomes one ``error: ...`` line on
stderr and exit status 1; Ctrl-C becomes exit status 130 (`console.user_errors`). Any other
exception is a bug and keeps its traceback.

Modules that load the simulator are imported only by the commands that need them: ``tavc list`` starts fast.
"""

import os
from pathlib import Path
from typing import Annotated, Optional

import typer

from tavc_cli import __version__, commands, config, options
from tavc_cli.compare import CONTROLLERS, SCENARIOS
from tavc_cli.console import user_errors as _user_errors
from tavc_cli.errors import TavcError
from tavc_cli.learning.plugins import CONFIG_DIRS_ENV
from tavc_cli.user_configs import extended_config_dirs

app = typer.Typer(
    name="tavc",
    cls=options.UntypedGroup,
    help="Reproduce task allocation through vacancy chains in multi-robot transportation.",
    no_args_is_help=True,
    add_completion=False,
    # A bug's traceback is for developers; the locals (whole configs) would drown it.
    pretty_exceptions_show_locals=False,
)


def _show_version(value: bool) -> None:
    if value:
        typer.echo(f"tavc {__version__}")
        raise typer.Exit()


@app.callback()
def main(
    version: Annotated[
        bool, typer.Option("--version", help="Print the version and exit.", callback=_show_version, is_eager=True),
    ] = False,
    config_dir: Annotated[
        Optional[list[str]],  # as typed: an empty name is refused, not taken for the working folder
        typer.Option("--config-dir", help="A folder of your own configs (learner/, experiment/, team/ ...) and "
                                          "learners' files, searched besides tavc's; repeatable.",
                     show_default=False),
    ] = None,
) -> None:
    """Reproduce task allocation through vacancy chains in multi-robot transportation."""
    if config_dir:
        try:
            os.environ[CONFIG_DIRS_ENV] = extended_config_dirs(config_dir)
        except TavcError as error:
            typer.echo(f"error: {error}", err=True)
            raise typer.Exit(code=1) from None


# --------------------------------------------------------------------------------------------
# Commands
# --------------------------------------------------------------------------------------------


@app.command("config")
def config_command(overrides: options.Overrides = None) -> None:
    """Print the composed, validated config as YAML and exit."""
    with _user_errors():
        commands.print_config(overrides=overrides or [])


@app.command("list")
def list_command() -> None:
    """List the experiments: name, chapter section, what the chapter reports of each."""
    with _user_errors():
        commands.print_experiments()


@app.command()
def run(
    overrides: options.Overrides = None,
    multirun: Annotated[
        bool,
        typer.Option(
            "--multirun",
            "-m",
            help="Sweep comma lists, range() and choice(); one output folder per job.",
        ),
    ] = False,
    progress: options.ProgressFlag = None,
) -> None:
    """Run every trial and controller an experiment needs and write its results."""
    with _user_errors(folder=lambda: config.load_config(overrides or []).output_dir):
        commands.run(
            overrides=overrides or [],
            multirun=multirun,
            progress=options.shown(progress),
        )


@app.command()
def reproduce(
    overrides: options.overrides_of("scale=paper seed=3, for every experiment") = None,
    experiments: Annotated[
        Optional[str],
        typer.Option("--experiments", help="Comma-separated experiment names (default: every one).",
                     show_default=False),
    ] = None,
    results: Annotated[Optional[Path], options.results("Folder that gets one folder per experiment (default: "
                                                       "runs/<scale>).")] = None,
    ladder: Annotated[
        Optional[str],
        typer.Option("--ladder", help="Also the horizon ladder at these multiples of the chapter's durations "
                                      "(e.g. 1,4,10,20,40), into RESULTS/ladder/.", show_default=False),
    ] = None,
    progress: options.ProgressFlag = None,
) -> None:
    """Run several experiments at once, the history their trials share simulated once."""
    with _user_errors(folder=lambda: results):
        commands.reproduce(
            overrides=overrides or [],
            names=experiments,
            results=results,
            progress=options.shown(progress),
            ladder=config.parse_factors(ladder),
        )


@app.command("ladder")
def ladder_command(
    overrides: options.overrides_of("seed=3 trials=8") = None,
    factors: Annotated[
        str, typer.Option("--factors", help="Multiples of the chapter's durations, comma-separated.")
    ] = "1,4,10,20,40",
    results: Annotated[Optional[Path], options.results("Folder whose ladder/ gets one folder per rung (default: "
                                                       "runs/<scale>, runs/converged unless a scale is given).")
                       ] = None,
    progress: options.ProgressFlag = None,
) -> None:
    """initial_distribution at several multiples of the chapter's durations, history shared; ladder.csv."""
    with _user_errors(folder=lambda: results):
        commands.reproduce(overrides=overrides or [], names="", results=results, progress=options.shown(progress),
                   ladder=config.parse_factors(factors))


@app.command("stay-switch")
def stay_switch_command(
    overrides: options.overrides_of("seed=3 surrogate.trials_per_makeup=8") = None,
    results: Annotated[Path, options.results("The study's folder: one folder per reading with its measured tasks, "
                                             "stay_switch.csv and its figure beside them.", show_default=True)
                       ] = Path("runs/stay_switch"),
    calibrated: options.CalibratedFrom = None,
    progress: options.ProgressFlag = None,
) -> None:
    """What each reading of the world (arrival, passing, layout) does to staying and switching.

    Static robots in every make-up of the team, per reading: stay_switch.csv and its figure, and
    the turn-taking model's prediction per reading."""
    with _user_errors(folder=lambda: results):
        commands.stay_switch(results, overrides or [], options.shown(progress), calibrated)


@app.command()
def model(
    overrides: options.Overrides = None,
    save_calibration: Annotated[bool, typer.Option(
        "--save-calibration", help="Record the calibrated values as the config option tasks=calibrated (conf/tasks/).",
    )] = False,
    turn_taking: Annotated[bool, typer.Option(
        "--turn-taking", help="Beside it, the model that knows turn-taking (docs/model.md): the chapter's learners on "
                              "measured tasks at 40 times the scale's durations, into OUTPUT_DIR/turn_taking.",
    )] = False,
    progress: options.ProgressFlag = None,
) -> None:
    """Measure c_i(n) in the simulator and apply the TAVC model; --turn-taking adds its rival.

    The chapter's model: slot values, predicted allocation, constraints (1.3)/(1.4), calibrated task
    values; with --turn-taking, the model that knows turn-taking beside it."""
    with _user_errors(folder=lambda: config.load_config(overrides or []).output_dir):
        # deferred: loads pandas
        from tavc_cli.api import model as run_model

        run_model(overrides or [], save_calibration=save_calibration, turn_taking=turn_taking,
                  progress=options.shown(progress), echo=typer.echo)


@app.command()
def surrogate(
    overrides: options.overrides_of("experiment=breakdown scale=converged surrogate.calibration=stayers") = None,
    study: Annotated[
        bool, typer.Option("--study", help="Check the surrogate against the simulator's runs and map what it "
                                            "answers: comparison, ladder, phase diagram, convergence horizon, speed.")
    ] = False,
    results: Annotated[Optional[Path], options.results("The study's folder (default: runs/surrogate-study).")] = None,
    simulator: Annotated[
        Optional[Path], typer.Option("--simulator", help="The simulator's runs the study compares with (their results "
                                                         "root; default: results).", show_default=False)
    ] = None,
    parts: Annotated[
        Optional[str],
        typer.Option("--parts", help="Only these parts of the study: compare,ladder,phase,horizon,speed.",
                     show_default=False),
    ] = None,
    progress: options.ProgressFlag = None,
) -> None:
    """Run an experiment on the surrogate of the learning dynamics; --study checks it.

    The same learners, seeds, events and tables, each task drawn from tasks measured in the simulator
    by the group's make-up (default output: runs/<scale>/surrogate/<experiment>); with --study, the
    surrogate checked against the simulator and what it answers beyond it."""
    with _user_errors(folder=lambda: results):
        if study:
            # deferred: loads pandas
            from tavc_cli.surrogate.study import run_study, summary_lines

            out = results if results is not None else Path("runs") / "surrogate-study"  # both horizons: no one scale
            chosen = None if parts is None else [p.strip() for p in parts.split(",") if p.strip()]
            if chosen == []:
                raise TavcError("--parts: names no part; give one or more of compare, ladder, phase, horizon, speed")
            run_study(out, simulator if simulator is not None else Path("results"), overrides or [],
                      lambda o: config.settings(config.load_config(o)), parts=chosen,
                      progress=options.shown(progress), echo=typer.echo)
            for line in summary_lines(out):
                typer.echo(line)
            return
        given = [name for name, value in (("--results", results), ("--simulator", simulator), ("--parts", parts))
                 if value is not None]
        if given:
            raise TavcError(f"{given[0]}: belongs to --study; a surrogate run writes into output_dir")
        # deferred: loads pandas
        from tavc_cli.api import surrogate_summary

        commands.print_summary(surrogate_summary(overrides or [], progress=options.shown(progress), echo=typer.echo))


@app.command()
def compare(
    overrides: options.overrides_of("scale=converged scale.trials=8") = None,
    learners: Annotated[
        str, typer.Option("--learners", help="Comma-separated learner configs to compare (tavc: each scenario's "
                                             "own; a learner of your own: its config's name, with --config-dir); "
                                             f"by default {', '.join(CONTROLLERS)}.", show_default=False)
    ] = ",".join(CONTROLLERS),
    experiments: Annotated[
        Optional[str], typer.Option("--experiments", help="Comma-separated scenarios; by default "
                                    f"{', '.join(SCENARIOS)}, and your own that compare serves.", show_default=False)
    ] = None,
    results: Annotated[Optional[Path], options.results("The comparison's folder (default: runs/<scale>/compare).")
                       ] = None,
    reuse: Annotated[
        Optional[list[str]],
        typer.Option("--reuse", help="CONTROLLER=FOLDER: take a controller's runs from a folder holding one per "
                                     "scenario (e.g. tavc=results/converged) instead of running them; each must "
                                     "be a finished run at the comparison's settings, checked as tavc report does.",
                     show_default=False),
    ] = None,
    progress: options.ProgressFlag = None,
) -> None:
    """Learners side by side on the chapter's scenarios, each tested against TAVC and random.

    Score per second, time in the model's predicted state, time to fill a vacancy, fast robots on the
    valuable circuit (compare.csv, compare.md, compare.png)."""
    with _user_errors(folder=lambda: results):
        # deferred: loads pandas
        from tavc_cli.api import compare_summary
        from tavc_cli.compare.run import parse_reuse

        written = compare_summary(overrides or [], learners=[n for n in learners.split(",") if n],
                                  experiments=None if experiments is None else [n for n in experiments.split(",") if n],
                                  results_dir=results, reuse=parse_reuse(reuse or []), progress=options.shown(progress))
        for name in ("compare.csv", "compare.md", "compare_trials.csv"):
            typer.echo(f"{name}: {Path(written['results']) / name}")
        for path in written["figures"]:
            typer.echo(f"figure: {path}")


@app.command()
def calibrate(
    overrides: options.Overrides = None,
    save: Annotated[bool, typer.Option(
        "--save", help="Record the chosen world as the config option world=calibrated (conf/world/).")] = False,
    progress: options.ProgressFlag = None,
) -> None:
    """Search the world's settings (calibration.grid) under which the chapter's facts hold.

    Static allocations only: the settings under which the chapter's task values meet its
    constraints (1.3)/(1.4)."""
    with _user_errors():
        # deferred: loads pandas
        from tavc_cli.api import calibrate as search_world

        search_world(overrides or [], save=save, progress=options.shown(progress), echo=typer.echo)


@app.command()
def bench(
    json_output: Annotated[
        bool, typer.Option("--json", help="Print one JSON object and nothing else.")
    ] = False,
    scenario: Annotated[str, typer.Option(help="Arena to simulate.")] = "two_circuits",
    n_robots: Annotated[int, typer.Option("--n-robots", min=1, help="Robots in the arena.")] = 6,
    duration_s: Annotated[
        float, typer.Option("--duration-s", help="Simulated seconds per repeat.")
    ] = 600.0,
    repeats: Annotated[int, typer.Option(min=1, help="Timed repeats; their median counts.")] = 3,
    batch: Annotated[Optional[int], typer.Option(
        min=1, help="Trials advanced together (default: the simulator's choice).", show_default=False)] = None,
    n_rays: Annotated[
        Optional[int],
        typer.Option("--n-rays", min=1, help="Laser rays (default: the configured world's).", show_default=False),
    ] = None,
    scaling: Annotated[
        bool, typer.Option(help="Also measure 2, 6, 12, 24 robots and 1, 2, all processes.")
    ] = True,
    against: Annotated[
        Optional[str],
        typer.Option(help="Run the same scenario in a reference simulator beside it: enki.", show_default=False),
    ] = None,
    profile: Annotated[
        bool, typer.Option(help="Instead, where one batch's time goes, by kernel and library (needs Linux's "
                                "perf; at least 5,000 simulated s per trial).")
    ] = False,
    force: Annotated[
        bool, typer.Option("--force", help="Run it even if estimated to take over a day.")
    ] = False,
) -> None:
    """Measure simulator throughput (simulated seconds per wall second, one core)."""
    with _user_errors():
        commands.bench(
            json_output=json_output,
            scenario=scenario,
            n_robots=n_robots,
            duration_s=duration_s,
            repeats=repeats,
            batch=batch,
            n_rays=n_rays,
            scaling=scaling,
            against=against,
            profile=profile,
            force=force,
        )


@app.command()
def animate(
    overrides: options.Overrides = None,
    out: Annotated[
        Optional[Path],
        typer.Option(
            "--out", help="File to write (default: in the run's output_dir).", show_default=False
        ),
    ] = None,
    duration_s: Annotated[
        float, typer.Option("--duration-s", help="Simulated seconds to render.")
    ] = 300.0,
    fps: Annotated[int, typer.Option(min=1, help="Frames per second of the animation.")] = 10,
    mp4: Annotated[
        bool, typer.Option("--mp4/--no-mp4", help="Also write an MP4 (needs ffmpeg).")
    ] = False,
) -> None:
    """Render one run (robots, markings, targets, trails) to GIF or MP4."""
    with _user_errors():
        commands.animate(overrides=overrides or [], out=out, duration_s=duration_s, fps=fps, mp4=mp4)


@app.command()
def report(
    results_dir: Annotated[
        Path, typer.Argument(help="Folder holding one folder per experiment run.", parser=options.folder)
    ] = Path("results"),
    progress: Annotated[
        Optional[bool],
        typer.Option("--progress/--no-progress", help="A line at each stage while it works (reading, drawing, "
                                                      "written); by default on a terminal only.",
                     show_default=False),
    ] = None,
    html: Annotated[
        bool, typer.Option("--html", help="Also write RESULTS_DIR/REPORT.html: the report as a web page with a table "
                                          "of contents, readable offline.")
    ] = False,
) -> None:
    """Write RESULTS_DIR/REPORT.md and claims.csv from saved results (never simulates).

    Each run's own claims.csv and comparison.csv are made again from its tables by this tavc's rules,
    and rewritten where they differ."""
    with _user_errors(folder=lambda: results_dir):
        commands.report(results_dir, progress, html)


options.untyped_help(app)

