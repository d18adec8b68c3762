"""tavc from Python: run an experiment from overrides, and read any results folder as pandas
DataFrames, for notebooks and scripts.

    from tavc_cli import api

    run = api.run(["experiment=breakdown", "scale=smoke"], output_dir="/tmp/tavc-demo")
    run.state_time                     # % of the stable period in each state, per controller
    run.events("deliveries")           # every delivery of every trial, one row each
    api.load("results/initial_distribution").claims

`run` takes the same overrides as `tavc run` and writes the same folder; `reproduce` runs
several experiments together as `tavc reproduce` does; `model` and `calibrate` measure the
model and search the docking world as `tavc model` and `tavc calibrate` do; `load` and
`load_sweep` only read (`tavc_cli.reading`). The command line runs through the same functions (`run_summary`,
`reproduce_summaries`, `model`, `calibrate`).
Errors a user can make (a bad override, a folder without results) raise `TavcError` with one
line that names the problem.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import replace
from pathlib import Path

import pandas as pd

from tavc_cli import config
from tavc_cli.analysis import tasks_seen
from tavc_cli.arguments import (
    echo_of,
    factors_of,
    folder_of,
    folder_setting,
    mapping_of,
    names_of,
    overrides_of,
    share_of,
)
from tavc_cli.chapter import base_case
from tavc_cli.compare import CONTROLLERS, scenarios
from tavc_cli.errors import TavcError
from tavc_cli.io import default_root, owned_path, path_of, refuse_folder_problem
from tavc_cli.learning.parameters import PluginSettings
from tavc_cli.learning.registry import MODEL_LEARNERS
from tavc_cli.model.allocations import model_allocations, model_world
from tavc_cli.model.report import measurement_shortfall, model_text
from tavc_cli.override_keys import setting, setting_key
from tavc_cli.ownership import COMPARE, LADDER, RESULTS, expect, refuse_other_settings
from tavc_cli.reading import Results, Sweep, load, load_sweep  # noqa: F401 - the API reads through these
from tavc_cli.settings import from_yaml
from tavc_cli.turn_taking import LEARNERS
from tavc_cli.user_configs import using_config_dirs

ConfigDirs = str | Path | Sequence[str | Path] | None  # a folder of the user's configs, or several


def run(overrides: Sequence[str] = (), *, output_dir: str | Path | None = None, progress: bool = False,
        config_dir: ConfigDirs = None) -> Results:
    """Run an experiment as `tavc run` does (finished trials in the folder are reused) and open its results.

    Args:
        overrides: Hydra overrides, e.g. ``["experiment=breakdown", "scale=quick", "seed=3"]``.
        output_dir: Where to write; by default the config's (``runs/<scale>/<experiment>``).
        progress: Show a progress bar.
        config_dir: A folder of your own configs and learners (or several), searched besides
            tavc's as ``--config-dir`` makes them (docs/plugins.md).
    """
    overrides = [*overrides_of(overrides), *folder_setting(output_dir)]
    with using_config_dirs(config_dir):
        return Results(run_summary(overrides, progress=progress)["output_dir"])


def reproduce(overrides: Sequence[str] = (), *, experiments: Sequence[str] | None = None,
              results_dir: str | Path | None = None, progress: bool = False,
              config_dir: ConfigDirs = None) -> dict[str, Results]:
    """Run several experiments together as `tavc reproduce` does (the history their trials share
    simulated once) and open each one's results, by experiment name.

    Args:
        overrides: Hydra overrides for every experiment, e.g. ``["scale=quick"]``.
        experiments: Experiment names; by default every one.
        results_dir: The folder that gets one folder per experiment; by default ``runs/<scale>``.
        progress: Show a progress bar.
        config_dir: A folder of your own configs and learners (or several), searched besides
            tavc's as ``--config-dir`` makes them (docs/plugins.md).
    """
    overrides = overrides_of(overrides)
    with using_config_dirs(config_dir):
        return {name: Results(summary["output_dir"])
                for name, summary in reproduce_summaries(overrides, experiments=experiments,
                                                         results_dir=results_dir, progress=progress)}


def surrogate(overrides: Sequence[str] = (), *, output_dir: str | Path | None = None,
              progress: bool = False, config_dir: ConfigDirs = None) -> Results:
    """Run an experiment on the surrogate of the learning dynamics as `tavc surrogate` does and
    open its results (the same tables as `run`'s).

    Args:
        overrides: Hydra overrides, e.g. ``["experiment=breakdown", "scale=converged"]``.
        output_dir: Where to write; by default ``runs/<scale>/surrogate/<experiment>``.
        progress: Show progress while the tasks are measured.
        config_dir: A folder of your own configs and learners (or several), searched besides
            tavc's as ``--config-dir`` makes them (docs/plugins.md).
    """
    overrides = [*overrides_of(overrides), *folder_setting(output_dir)]
    with using_config_dirs(config_dir):
        return Results(surrogate_summary(overrides, progress=progress, echo=lambda _: None)["output_dir"])


def surrogate_summary(overrides: Sequence[str] = (), *, progress: bool = False,
                      echo: Callable[[str], None] = print) -> dict:
    """`surrogate`'s work, returning the run's summary as `tavc surrogate` prints it."""
    overrides = overrides_of(overrides)
    # deferred: loads the simulator's compiled kernels
    from tavc_cli.surrogate.run import run_surrogate

    cfg = config.load_config(overrides)
    if not any(setting_key(o) == "output_dir" for o in overrides):
        overrides.append(setting("output_dir", default_root(cfg.scale.name) / "surrogate" / cfg.experiment_name))
        cfg = config.load_config(overrides)
    return run_surrogate(config.settings(cfg), progress=progress, echo=echo)


def run_summary(overrides: Sequence[str] = (), *, progress: bool = False) -> dict:
    """`run`'s work, returning the run's summary (where it went, its tables and claims) as
    `tavc run` prints it."""
    overrides = overrides_of(overrides)
    # deferred: loads the simulator's compiled kernels
    from tavc_cli.pipeline import run_experiment

    return run_experiment(config.settings(config.load_config(list(overrides))), progress=progress)


def seen_tasks(run_dir: str | Path, *, controller: str = "tavc", from_share: float = 0.5) -> pd.DataFrame:
    """The tasks `controller`'s learners made in the finished run in `run_dir` (the trials its
    provenance lists, each checked to be its own: `Results.records`), by the robots on circuit 0
    once the chooser had chosen, the kind of task and its circuit, from `from_share` of each
    trial on (`analysis.tasks_seen.seen_tasks`)."""
    share = share_of(from_share, "from_share")
    return tasks_seen.seen_tasks(load(run_dir).records(controller), share)


def surrogate_seen_switches(prediction: str | Path, learners_run: str | Path, *, output_dir: str | Path) -> Results:
    """A diagnostic of the turn-taking model: its learners on the surrogate as the prediction in
    `prediction` ran them (`tavc model --turn-taking`'s `turn_taking/` folder: its learners'
    settings, the tasks it measured), every switching task of a make-up with one switcher
    shifted to the mean the learners of `learners_run` met in the state it makes
    (`analysis.tasks_seen.seen_switches`), into `output_dir`. Tasks measured by other code or
    settings, or edited since, are refused in one line, as the surrogate refuses them. The folder
    is read as data: its learners must be tavc's own (a learner from outside tavc it names is
    refused, not run), and the trials run where this machine's settings run them, not where its
    `executor` says."""
    # deferred: loads the simulator's compiled kernels
    from tavc_cli.experiments.build import trial_specs
    from tavc_cli.surrogate.run import kept_tasks, measurement_record, run_surrogate
    from tavc_cli.surrogate.tasks import TaskTimes

    prediction, output_dir = path_of(prediction, "prediction"), path_of(output_dir, "output_dir")
    path_of(learners_run, "learners_run")
    own = prediction / LEARNERS / "config.yaml"
    if not own.is_file():
        raise TavcError(f"{prediction}: not a turn-taking prediction's folder (no {LEARNERS}/config.yaml in it)")
    here = config.settings(config.load_config([]))
    cfg = replace(from_yaml(own), output_dir=str(output_dir), executor=here.executor)
    if any(isinstance(spec.policy, PluginSettings) for spec in trial_specs(cfg)):
        raise TavcError(f"{own}: its learners are from outside tavc (learner.target), code a folder cannot vouch "
                        "for; a prediction's learners are tavc's own (rerun tavc model --turn-taking)")
    # the tasks are drawn only where the surrogate itself would draw them (this code, these settings)
    why: list[str] = []
    frame = kept_tasks(prediction / "tasks", measurement_record(cfg), overwrite=False, echo=why.append)
    if not len(frame):
        said = why[0].removeprefix("note: ").removesuffix("; measuring the tasks again") if why else ""
        raise TavcError(f"{prediction / 'tasks'}: no measured tasks of this code and these settings to draw from"
                        + (f" ({said})" if said else "") + "; rerun tavc model --turn-taking")
    shifted = TaskTimes(tasks_seen.seen_switches(frame, seen_tasks(learners_run)))
    return Results(run_surrogate(cfg, times=shifted, echo=lambda _: None)["output_dir"])


def reproduce_summaries(overrides: Sequence[str] = (), *, experiments: Sequence[str] | None = None,
                        results_dir: str | Path | None = None, progress: bool = False,
                        ladder: Sequence[float] | None = None) -> list[tuple[str, dict]]:
    """`reproduce`'s work, returning (name, summary) per experiment as `tavc reproduce` prints
    them. With `ladder` (multiples of the chapter's durations), the horizon ladder's rungs run
    in the same job, their history shared with the experiments' trials (`config.load_ladder`),
    and follow the experiments as ``ladder x<factor>``; ``experiments=[]`` runs the ladder alone."""
    overrides = overrides_of(overrides)
    # deferred: loads the simulator's compiled kernels
    from tavc_cli.pipeline import run_experiments

    names = names_of(experiments, "experiments")
    ladder = factors_of(ladder)
    folder_of(results_dir, "results_dir")
    if results_dir is None:  # runs/<scale>: the ladder's scale is converged unless one is given
        results_dir = config.results_root(overrides, None if names != [] else "converged")
    cfgs = config.load_experiments(names, list(overrides), results_dir) if names != [] else []
    rungs = config.load_ladder(ladder, list(overrides), results_dir) if ladder else []
    if not cfgs and not rungs:
        raise TavcError("--experiments: no experiment and no ladder to run")
    expect(Path(results_dir), RESULTS, "--results")  # the report goes there at the end: checked before hours of runs
    if rungs:
        expect(Path(results_dir) / "ladder", LADDER, "--results")
    summaries = run_experiments([config.settings(cfg) for cfg in [*cfgs, *rungs]], progress=progress)
    for summary in summaries:
        summary["together"] = len(summaries) > 1  # one wall time, the invocation's
    out = [(str(cfg.experiment_name), summary) for cfg, summary in zip(cfgs, summaries, strict=False)]
    if rungs:
        # deferred: loads the simulator's compiled kernels
        from tavc_cli.pipeline import write_ladder

        write_ladder(Path(results_dir) / "ladder", [Path(str(cfg.output_dir)) for cfg in rungs])
        out += [(f"ladder x{float(cfg.scale.time_factor):g}", summary)
                for cfg, summary in zip(rungs, summaries[len(cfgs):], strict=True)]
    return out


def compare(overrides: Sequence[str] = (), *, learners: Sequence[str] | None = None,
            experiments: Sequence[str] | None = None, results_dir: str | Path | None = None,
            reuse: Mapping[str, str | Path] | None = None, progress: bool = False,
            config_dir: ConfigDirs = None) -> pd.DataFrame:
    """Learners side by side on the chapter's scenarios as `tavc compare` does; returns compare.csv's table.

    Args:
        overrides: Hydra overrides for every run, e.g. ``["scale=quick"]``.
        learners: Learner configs to compare (``tavc``: each scenario's own); by default
            tavc, random, model, informed, wolf_phc and threshold.
        experiments: Scenarios; by default the chapter's five task-allocation ones.
        results_dir: The comparison's folder; by default ``runs/<scale>/compare``.
        reuse: Controller name -> a folder holding its runs, one per scenario, to read instead of running.
        progress: Show progress while simulating.
        config_dir: A folder of your own configs and learners (or several), searched besides
            tavc's as ``--config-dir`` makes them (docs/plugins.md).
    """
    overrides = overrides_of(overrides)
    with using_config_dirs(config_dir):
        return compare_summary(overrides, learners=learners, experiments=experiments, results_dir=results_dir,
                               reuse=reuse, progress=progress)["table"]


def compare_summary(overrides: Sequence[str] = (), *, learners: Sequence[str] | None = None,
                    experiments: Sequence[str] | None = None, results_dir: str | Path | None = None,
                    reuse: Mapping[str, str | Path] | None = None, progress: bool = False) -> dict:
    """`compare`'s work: each controller's runs composed here (the config stays at the front
    doors), run and read by `compare.run.run_compare`; returns its summary."""
    overrides = overrides_of(overrides)
    learners, experiments = names_of(learners, "learners"), names_of(experiments, "experiments")
    folder_of(results_dir, "results_dir")
    mapping_of(reuse, "reuse")
    # deferred: loads scipy
    from tavc_cli.compare.run import controller_overrides, refuse_reuse, run_compare

    config.refuse_deletions(overrides)
    # learner.model_file is the comparison's: the model its predicted states come from, and the one the
    # model's controllers follow; every other controller's learner has no such key
    model_keys = [o for o in overrides if setting_key(o) == "learner.model_file"]
    overrides = [o for o in overrides if o not in model_keys]
    config.parse_overrides(model_keys)  # a slip in one is named as itself
    learners = list(CONTROLLERS if learners is None else learners)
    if experiments is None:
        experiments = scenarios()
        files = config.experiment_names()
        if missing := [name for name in experiments if name not in files]:
            raise TavcError(f"chapter: {missing[0]}'s registry entry says compare serves it, but no "
                            f"experiment/{missing[0]}.yaml is in tavc's configs or a --config-dir folder")
    experiments = list(experiments)
    if not experiments:
        raise TavcError("--experiments: no scenario given")
    if len(set(experiments)) != len(experiments):
        raise TavcError(f"--experiments: name each scenario once ({', '.join(experiments)})")
    served = scenarios()
    if other := next((name for name in experiments if name not in served), None):  # before any run
        raise TavcError(f"--experiments: {other!r} is not a scenario compare serves (it serves {', '.join(served)}; "
                        "an experiment of your own, where its registry entry says compare=True)")
    if not learners or len(set(learners)) != len(learners):
        raise TavcError(f"--learners: name each learner once ({', '.join(learners) or 'none given'})")
    options = config.group_options("learner")
    if other := next((name for name in learners if name != "tavc" and name not in options), None):
        raise TavcError(f"--learners: {other}: learner={other}: no such option; choose tavc (each scenario's own) or "
                        f"one of {', '.join(options)}")
    if results_dir is not None:
        refuse_folder_problem(results_dir, "--results", in_setting=True)
    results = Path(results_dir) if results_dir is not None else config.results_root(overrides) / "compare"
    expect(results, COMPARE, "--results")  # checked before hours of runs
    for name in learners:  # its runs' folders are named below it: a link there is refused, not followed
        owned_path(results, results / "runs" / name, folder=True, what="--results")
    reuse = {name: path_of(folder, f"reuse[{name!r}]") for name, folder in (reuse or {}).items()}
    refuse_reuse(reuse, learners, experiments)  # what needs no settings, before composing them
    base = config.load_config([f"experiment={experiments[0]}", *overrides])
    # read as a model learner's run reads it (its grammar and interpolations), then the file itself and
    # the world it was measured in, the comparison's (`model.allocations.model_world`); the teams it
    # predicts for are the model's controllers' own to check, where they are compared
    model_file = config.setting_of(["learner=model", *model_keys[-1:]], "learner.model_file")
    model_allocations(model_file, len(base.arena.circuits), model_world(base))
    scale = config.to_container(base.scale)
    plans = {}
    for name in learners:  # a reused controller's too: its folder is checked against them
        try:
            own = [*overrides, *controller_overrides(name, scale), *(model_keys if name in MODEL_LEARNERS else [])]
            cfgs = config.load_experiments(experiments, own, results / "runs" / name)
        except TavcError as error:
            raise TavcError(f"--learners: {name}: {error}") from None
        plans[name] = [config.settings(cfg) for cfg in cfgs]
    return run_compare(plans, results, controllers=learners, experiments=experiments, reuse=reuse,
                       model_file=str(model_file), scale_name=str(scale["name"]), progress=progress)


def model(overrides: Sequence[str] = (), *, save_calibration: bool = False, turn_taking: bool = False,
          progress: bool = False, echo: Callable[[str], None] = print, config_dir: ConfigDirs = None) -> dict:
    """Measure c_i(n) and apply the TAVC model as `tavc model` does, printing its summary through
    `echo`; with `save_calibration`, record the calibrated values as tasks=calibrated; with
    `turn_taking`, the model that knows turn-taking beside it (its prediction under the result's
    ``turn_taking`` key, its runs in ``<output_dir>/turn_taking``). Returns the model's result.
    `config_dir`: folders of your own configs, as ``--config-dir``."""
    overrides = overrides_of(overrides)
    echo_of(echo)
    with using_config_dirs(config_dir):
        if turn_taking:
            # deferred: pandas and the model's modules, only with turn_taking
            from tavc_cli.turn_taking import TURN_TAKING_FOLDER, check_overrides

            check_overrides([o for o in overrides if setting_key(o) != "output_dir"])
            folder = Path(config.load_config(list(overrides)).output_dir)  # its folder checked before the model runs
            owned_path(folder, folder / TURN_TAKING_FOLDER, folder=True, what="output_dir")
        result = _model(overrides, save_calibration, progress, echo)
        if turn_taking:
            result["turn_taking"] = _turn_taking(overrides, progress, echo)
        return result


def _turn_taking(overrides: Sequence[str], progress: bool, echo: Callable[[str], None]) -> dict:
    # deferred: loads the surrogate and the simulator's compiled kernels
    from tavc_cli.turn_taking import TURN_TAKING_FOLDER, predict_turn_taking, prediction_lines

    out = Path(config.load_config(list(overrides)).output_dir) / TURN_TAKING_FOLDER
    mine = [o for o in overrides if setting_key(o) != "output_dir"]
    result = predict_turn_taking(mine, out, lambda o: config.settings(config.load_config(o)), progress=progress,
                                 echo=echo)
    echo("\n".join(prediction_lines(result)))
    return result


def _model(overrides: Sequence[str], save_calibration: bool, progress: bool, echo: Callable[[str], None]) -> dict:
    # deferred: loads the simulator's compiled kernels
    from tavc_cli.model.api import calibration_record, model_identity, run_model
    from tavc_cli.model.api import save_calibration as save

    config.check_measurement(list(overrides), "model")  # its time on this machine, before anything runs
    cfg = config.settings(config.load_config(list(overrides)))
    tasks_dir = config.find_conf_dir() / "tasks"
    if save_calibration:  # the values in conf/ are replaced only by a model of the same settings, or when told
        refuse_other_settings(calibration_record(cfg, tasks_dir), model_identity(cfg), "--save-calibration",
                              cfg.overwrite, allow=f"add overwrite=true to replace {tasks_dir / 'calibrated.yaml'} "
                                                   "with this model's values, or leave out --save-calibration")
    result = run_model(cfg, progress=progress)
    echo(model_text(result, measurement_shortfall(result["model"]["measurement"], cfg.model.trials_per_split,
                                                  cfg.model.measure_s, cfg.scale.name)))
    if save_calibration:
        echo(f"calibrated values saved as {save(result, tasks_dir)}")
    return result


def calibrate(overrides: Sequence[str] = (), *, save: bool = False, progress: bool = False,
              echo: Callable[[str], None] = print, config_dir: ConfigDirs = None) -> None:
    """Search the reconstructed docking world over `calibration.grid` as `tavc calibrate` does
    (initial_distribution's six robots and the chapter's values unless an experiment is
    given), printing through `echo`, into ``<output_dir>/calibration/world/`` (``output_dir``
    ``runs/<scale>`` unless given); with `save`, record the choice as world=calibrated.
    `config_dir`: folders of your own configs, as ``--config-dir``."""
    overrides = overrides_of(overrides)
    echo_of(echo)
    with using_config_dirs(config_dir):
        _calibrate(overrides, save, progress, echo)


def _calibrate(overrides: Sequence[str], save: bool, progress: bool, echo: Callable[[str], None]) -> None:
    # deferred: loads the simulator's compiled kernels
    from tavc_cli.model.calibrate import calibrate_world, plan_search
    from tavc_cli.model.world_search import grid_points, point_overrides

    overrides = list(overrides)
    config.check_measurement(overrides, "calibration")  # its time on this machine, before anything runs
    if not any(setting_key(o) == "experiment" for o in overrides):
        overrides = [f"experiment={base_case().name}", *overrides]  # six robots, the chapter's values
    base = config.settings(config.load_config(overrides))
    if not any(setting_key(o) == "output_dir" for o in overrides):  # the scale's folder, not an experiment's
        overrides.append(setting("output_dir", default_root(base.scale.name)))
        base = config.settings(config.load_config(overrides))
    if not base.calibration.grid:
        raise TavcError("calibration.grid: empty; nothing to search")
    world_dir = config.find_conf_dir() / "world"
    grid = grid_points(base.calibration.grid)
    plan = plan_search(base, len(grid), world_dir, save=save, progress=progress)  # checked before the points compose
    points = [(p, config.settings(config.load_config([*overrides, *point_overrides(p)]))) for p in grid]
    calibrate_world(base, points, plan, world_dir, save=save, echo=echo)
