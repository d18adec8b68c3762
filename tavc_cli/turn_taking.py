"""The model that knows turn-taking, run for one experiment in one world (`tavc model
--turn-taking`, and for each reading by `tavc stay-switch`).

Two runs of its own, each in a folder of the model's (`analysis.turn_taking` reads them):

- ``learners/``: the chapter's learning rule on the surrogate (`surrogate.run.run_surrogate`) at
  a longer horizon (`HORIZON`, 40 times the scale's durations: the chapter's at scale=paper,
  where today's world converges), its tasks measured by static robots in every make-up of this
  world at the scale's settings, or read from `tasks_dir` where they were measured before (the
  stay/switch study's);
- ``alternators/``: where those learners take turns, static robots that all alternate
  (`learner=alternate`, `learner.allocation=[0,0]`) in the simulator at the run's scale, whose
  order of circulation gives the modal state.

`turn_taking.json` records the prediction and where each part came from. Both runs are kept and
reused by a rerun of the same settings and code, as any run's trials are.
"""

from __future__ import annotations

import json
import math
from collections.abc import Callable, Sequence
from pathlib import Path

import pandas as pd

from tavc_cli.analysis.turn_taking import ALTERNATOR, HORIZON, TURN_TAKING, modal_state, prediction
from tavc_cli.errors import TavcError
from tavc_cli.io import claim_folder, owned_path, write_text_atomic
from tavc_cli.override_keys import setting, setting_key
from tavc_cli.ownership import TURN_TAKING_FILES, TURN_TAKING_KIND, take
from tavc_cli.report.mechanism import read_group
from tavc_cli.settings import TavcConfig

LEARNERS, ALTERNATORS = "learners", "alternators"
TURN_TAKING_FOLDER = "turn_taking"  # the model's folder in a reading's of the stay/switch study
PREDICTED = ("regime", "stayers", "alternators", "robots_high", "modal_state", "modal_share_pct", "modal_from",
             "learners_horizon", "learners_trials")  # a prediction's columns in a table
SET_HERE = ("learner", "output_dir", "surrogate.tasks_dir", "baseline_trials", "scale.time_factor",
            "scale.stable_window")

Compose = Callable[[list[str]], TavcConfig]


def check_overrides(overrides: Sequence[str]) -> None:
    """Refuse, in one line, a setting the model sets for its runs (`SET_HERE`)."""
    given = [k for k in map(setting_key, overrides) if k in SET_HERE]
    if given:
        raise TavcError(f"{given[0]}: set by the model that knows turn-taking for each of its runs (its "
                        f"learners on the surrogate at {HORIZON:g} times the scale's durations, static alternators at "
                        "the scale's own)")


def predict_turn_taking(overrides: Sequence[str], out: Path, compose: Compose, *, tasks_dir: Path | None = None,
                        horizon: float | None = None, progress: bool = False,
                        echo: Callable[[str], None] = print) -> dict:
    """The model's prediction for the experiment and world of `overrides` into `out`: its learners
    on the surrogate at `horizon` (default `HORIZON`) times the scale's durations, static
    alternators where they take turns, and `turn_taking.json`. The learners' tasks are measured
    at the scale's settings into `tasks_dir` (default `out/tasks`), or reused from there (the
    stay/switch study's). Returns the prediction (`analysis.turn_taking.prediction`) with the
    runs' folders."""
    # deferred: both load the simulator's compiled kernels
    from tavc_cli.pipeline import run_experiment
    from tavc_cli.surrogate.run import measure_tasks, run_surrogate

    check_overrides(overrides)
    out = Path(out)
    for below in (LEARNERS, ALTERNATORS, *([] if tasks_dir else ["tasks"])):  # its runs' folders: no link there
        owned_path(out, out / below, folder=True, what="output_dir")
    with claim_folder(out, within=out.parent):
        owned = take(out, TURN_TAKING_KIND, TURN_TAKING_FILES, "output_dir")
    here = compose(list(overrides))
    factor = HORIZON if horizon is None else float(horizon)
    tasks = setting("surrogate.tasks_dir", tasks_dir or out / "tasks")
    learners_cfg = compose([*overrides, f"scale.time_factor={factor * float(here.scale.time_factor)!r}",
                            "scale.stable_window=chapter", "baseline_trials=1",
                            tasks, setting("output_dir", out / LEARNERS)])
    echo(f"turn-taking model: the chapter's learners on the surrogate, {float(learners_cfg.scale.time_factor):g}x")
    times = measure_tasks(compose([*overrides, tasks]), progress=progress, echo=echo)
    run_surrogate(learners_cfg, times=times, progress=progress, echo=lambda _: None)
    learners = read_group(out / LEARNERS, learners_cfg)
    alternators, alternators_cfg = None, None
    if learners["regime"] == TURN_TAKING:
        alternators_cfg = compose([*overrides, "learner=alternate", "learner.allocation=[0,0]", "baseline_trials=1",
                                   setting("output_dir", out / ALTERNATORS)])
        echo("turn-taking model: every robot alternating, in the simulator")
        run_experiment(alternators_cfg, progress=progress)
        alternators = modal_state(pd.read_csv(out / ALTERNATORS / "state_time.csv"), ALTERNATOR)
    result = {**prediction(learners, alternators), "learners_run": LEARNERS,
              "learners_horizon": float(learners_cfg.scale.time_factor), "learners_trials": int(learners_cfg.trials),
              "alternators_run": ALTERNATORS if alternators_cfg is not None else None,
              "switches": str(learners_cfg.surrogate.switches), "overrides": list(overrides)}
    with claim_folder(out):
        owned.wrote(*TURN_TAKING_FILES)
        write_text_atomic(out / "turn_taking.json", json.dumps(result, indent=2, default=float))
    return result


def prediction_lines(result: dict) -> list[str]:
    """The prediction in a few lines, as `tavc model --turn-taking` prints it."""
    modal = (f"{result['modal_state']} ({result['modal_share_pct']:.1f} % of the stable period, "
             + ("every robot alternating in the simulator)" if result["modal_from"] == ALTERNATORS
                else "the learners on the surrogate)"))
    return [f"the model that knows turn-taking (the chapter's learners on measured tasks, "
            f"{result['learners_horizon']:g}x, {result['learners_trials']} trials):",
            f"  regime: {result['regime']} ({result['stayers']:.1f} stayers, {result['alternators']:.1f} alternators "
            "per trial)",
            *([f"  robots on the high-value circuit: {result['robots_high']:.2f}"]
              if math.isfinite(result["robots_high"]) else []),
            f"  modal state: {modal}"]
