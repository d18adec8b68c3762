"""The models set beside the learners' runs: where learners ran the base case in a reading the
stay/switch studies measured (`learners_beside_the_models`), and every prediction of the turn-taking
model beside the learners' runs it is for (`turn_taking_check_lines`), each with whether the model
names their regime and modal state, and how firmly."""

from __future__ import annotations

import math
from pathlib import Path

import pandas as pd

from tavc_cli.analysis.makeup_model import expected_high, predicted_regime
from tavc_cli.analysis.stay_switch import parse_reading, reading_folder, readings
from tavc_cli.analysis.turn_taking import RESAMPLES, state_shares
from tavc_cli.chapter import base_case
from tavc_cli.errors import TavcError
from tavc_cli.report import files
from tavc_cli.report.files import (
    READINGS_RUNS,
    SWEEPS,
    TEAM_SIZE_DIR,
    TURN_TAKING_RUNS,
    config_of,
    horizon_folders,
    model_learners,
    prediction_files,
    read_or_refuse,
    read_prediction,
    run_in,
    sweep_runs,
)
from tavc_cli.report.mechanism import convergence, mechanism, read_group
from tavc_cli.report.tally import (
    EXPLORED,
    POST_HOC,
    alternator_shares,
    base_name,
    middle_line,
    model_support,
    no_check_note,
    post_hoc_line,
    support_of,
    switches_line,
    switches_of,
    tally_line,
    trials_words,
    turn_tally,
)
from tavc_cli.report.text import fmt
from tavc_cli.settings import TavcConfig
from tavc_cli.settings_studies import EXPLORERS

WORLD = ("arena", "robot", "team", "tasks", "events")  # the settings that make a run's world and its task


def turn_taking_check_lines(results_dir: Path) -> list[str]:
    """The turn-taking model beside the learners at the chapter's scenarios and value ratios in
    today's world, and in worlds of their own: for each prediction
    `turn_taking/<name>/turn_taking/turn_taking.json` (`tavc model --turn-taking`), the learners'
    runs it predicts (`_learners_runs`), read as in `_beside`."""
    found = prediction_files(results_dir)
    rows, tallies = [], []
    swept = _swept_runs(results_dir) if found else []
    for path in found:
        predicted = read_prediction(path)
        name = path.parent.parent.name
        runs = [d for d in _learners_runs(results_dir, name, predicted, path.parent, swept)
                if all((d / f"{t}.csv").is_file() for t in ("mechanism", "state_time"))]
        if not runs:
            continue
        state, switches, post_hoc = str(predicted["modal_state"]), switches_of(predicted), name.endswith(POST_HOC)
        words = prediction_words(predicted, model_support(path.parent, predicted))  # once for all its runs
        alternators = alternator_shares(path.parent, predicted)
        for d in runs:
            learners = _learners(d)
            support = support_of(learners, state)
            same = f"{_same(predicted['regime'], learners['regime'])}; " \
                   f"{_same_state(state, learners, support)}{learners['no_check']}" + \
                   (" (post hoc: not a check)" if post_hoc and not learners["no_check"] else "")
            own = files.seed_for_seed_cell(model_learners(path.parent, predicted), d)
            rows.append(f"| {name} | `{d.relative_to(results_dir).as_posix()}` ({trials_words(learners)}) | "
                        f"{learners['converged']} | {learners['words']} | {words} | {same} | {own} |")
            tallies.append({"check": not learners["no_check"], "switches": switches, "run": d, "post_hoc": post_hoc,
                            **turn_tally(str(predicted["regime"]), state, support, learners, alternators)})
    if not rows:
        return []
    post = [t for t in tallies if t["post_hoc"]]
    main = [t for t in tallies if t["switches"] != EXPLORERS and not t["post_hoc"]]
    explored = [t for t in tallies if t["switches"] == EXPLORERS and not t["post_hoc"]]
    return ["", "The turn-taking model at the chapter's other scenarios and at other values in today's world (`make "
            f"turn-taking-checks`: `tavc model --turn-taking ... scale=paper`, into `{TURN_TAKING_RUNS}/<name>/`), and "
            "in the readings of the world (as configured or as calibrated), beside the learners' runs at the longer "
            f"horizons (`<horizon>/<name>`, `<horizon>/{READINGS_RUNS}/<name>`) and the value-ratio sweep's at 40x. "
            "The model was fixed before it was set beside any of these runs; the chapter's scenarios in today's world, "
            "the sweep and some of a reading's scenarios were run before their predictions were made, the rest after "
            "their predictions were committed (which is which: docs/readings.md). " + FIRMNESS + MODEL_FIRMNESS
            + SEED_FOR_SEED + (
                f" At other team sizes, `make team-size-checks` predicts (`{TURN_TAKING_RUNS}/team_size_<n>/`; in a "
                f"reading `<reading>-team_size_<n>/`) and then runs the learners at 40x (`{TEAM_SIZE_DIR}/`)."
                if (results_dir / TEAM_SIZE_DIR).is_dir()
                else "") + (f" Predictions whose folder ends in `{EXPLORED}` draw a lone switcher's tasks from robots "
                            "that stay and explore (`surrogate.switches=explorers`, docs/surrogate.md); they are "
                            "tallied apart." if explored else "") + (
                f" Predictions whose folder ends in `{POST_HOC}` were made after the learners' runs beside them were "
                "read, by a way of the model built after those runs: diagnostics, tallied apart from every check."
                if post else ""), "",
            "| prediction | the learners' run | converged | their regime, robots high, modal state | the turn-taking "
            "model | the same regime; modal state | the model's learners and these, seed for seed |",
            "|---|---|---|---|---|---|---|", *rows, *tally_line(main), *middle_line(main),
            *switches_line(explored, main), *post_hoc_line(post, main)]


def _swept_runs(results_dir: Path) -> list[tuple[Path, TavcConfig]]:
    """Every run of a sweep (`SWEEPS`) or in a reading (`<horizon>/readings/`), with its settings:
    the runs `_learners_runs` looks among for each prediction, read once for all of them."""
    found = [*(d for f in SWEEPS for d in sweep_runs(results_dir, f)),
             *(d for h in horizon_folders(results_dir) for d in sweep_runs(h, READINGS_RUNS))]
    return [(d, read_or_refuse(d / "config.yaml", config_of)) for d in found]


def _learners_runs(results_dir: Path, name: str, predicted: dict, where: Path,
                   swept: list[tuple[Path, TavcConfig]]) -> list[Path]:
    """The learners' runs a prediction named `name` (its folder `where`) is for, each once, where
    `<name>` is the prediction's name without its way's and post hoc's suffixes (`tally.base_name`):
    `<horizon>/<name>` and `<horizon>/readings/<name>` (a world of its own, e.g. a reading as
    calibrated; `files.run_in`) at every longer horizon; and every run of a sweep or in a reading
    (`swept`, `_swept_runs`) at scale=converged of the prediction's experiment in the world its own
    learners ran in (`WORLD`: the same arena, robots, team, tasks and events)."""
    own_dir = model_learners(where, predicted)
    own_path = own_dir / "config.yaml" if own_dir is not None else None
    own = read_or_refuse(own_path, config_of) if own_path is not None and own_path.is_file() else None
    name = base_name(name)
    runs = [run_in(d, own.experiment_name if own else base_case().name) for h in horizon_folders(results_dir)
            for d in (h / name, h / READINGS_RUNS / name)]
    if own is None:
        return runs
    for d, cfg in swept:
        if d not in runs and cfg.scale.name == "converged" and cfg.experiment_name == own.experiment_name and \
                all(getattr(cfg, k) == getattr(own, k) for k in WORLD):
            runs.append(d)
    return runs


def check_named_runs(results_dir: Path) -> None:
    """Refuse a run where a prediction looks for its learners by name (`<horizon>/<name>`,
    `<horizon>/readings/<name>`) that was not made in the world the prediction's own learners ran
    in (`WORLD`), before the report writes anything: it would be set beside the prediction as its
    check."""
    for path in prediction_files(results_dir):
        predicted = read_prediction(path)
        own_dir = model_learners(path.parent, predicted)
        if own_dir is None or not (own_dir / "config.yaml").is_file():
            continue
        own = read_or_refuse(own_dir / "config.yaml", config_of)
        name = base_name(path.parent.parent.name)
        for h in horizon_folders(results_dir):
            for d in (run_in(h / name, own.experiment_name), run_in(h / READINGS_RUNS / name, own.experiment_name)):
                if not (d / "config.yaml").is_file():
                    continue
                cfg = read_or_refuse(d / "config.yaml", config_of)
                differ = next((k for k in WORLD if getattr(cfg, k) != getattr(own, k)), None)
                if differ is not None:
                    raise TavcError(f"{d}: its {differ} settings are not those of the learners of the prediction "
                                    f"{path.parent.parent.relative_to(results_dir).as_posix()} that reads it by its "
                                    "name as its check; move it, or run it again in that world")


def _learners(d: Path) -> dict:
    """The learners' group in the run in `d` (`report.mechanism.read_group`), in words, with its
    trial count, whether they converged, and the note that makes a row no check where not."""
    cfg = config_of(d / "config.yaml")
    group = read_group(d, cfg)
    v = convergence(d)
    converged = "?" if v is None else ("yes" if v["converged"] else f"no ({', '.join(v['failed'])})")
    trials = pd.read_csv(d / "trial_stats.csv") if (d / "trial_stats.csv").is_file() else pd.DataFrame()
    factor = float(cfg.scale.time_factor)
    shares = state_shares(pd.read_csv(d / "state_time.csv", dtype={"state": str}), "tavc")
    return {**group, "shares": shares, "trials": cfg.trials,
            "trial_stats": trials, "factor": factor, "converged": converged,
            "no_check": no_check_note(v is not None and v["converged"], factor),
            "words": f"{group['regime']}, {fmt(group['robots_high'], '.2f') or '-'}, {group['modal_state']} "
                     f"({group['modal_share_pct']:.0f} %)"}


def _same(predicted: str, found: str) -> str:
    return "yes" if predicted == found else "**no**"


def _same_state(predicted: str, learners: dict, support: float) -> str:
    """Whether a predicted modal state is the learners' modal state; where not, the learners'
    share of the predicted state beside (two states can be nearly tied); and in what share of
    resamples of the learners' trials the predicted state is their modal state (`support`,
    `tally.support_of`)."""
    firm = f"modal in {100 * support:.0f} % of resamples of the trials" if math.isfinite(support) else ""
    if predicted == learners["modal_state"]:
        return "yes" + (f" ({firm})" if firm else "")
    share = learners["shares"].get(predicted)
    notes = [f"the learners: {share:.1f} % in {predicted}"] if share is not None else []
    notes += [firm] if firm else []
    return "**no**" + (f" ({'; '.join(notes)})" if notes else "")


def prediction_words(p, own: float = math.nan) -> str:
    """A turn-taking prediction (`turn_taking.json`, or a row of the study's table) in a few words;
    with `own` (`tally.model_support`), how firmly the static alternators it reads name its state."""
    firm = f"; the alternators' modal state in {100 * own:.0f} % of resamples" if math.isfinite(own) else ""
    return (f"{p['regime']}, {fmt(float(p['robots_high']), '.2f') or '-'}, {p['modal_state']} "
            f"({float(p['modal_share_pct']):.0f} %{firm})")


def turn_words(turn: pd.DataFrame | None, reading: str) -> str:
    """The turn-taking model's prediction for `reading` in a few words, or nothing."""
    return prediction_words(turn.loc[reading]) if turn is not None and reading in turn.index else ""


FIRMNESS = (f"Beside each predicted modal state, the share of {RESAMPLES:,} resamples of the learners' trials (drawn "
            "with replacement) in which it is their modal state: where each trial settles in a state of its own, a "
            "few trials decide which state is modal, and the share says how firmly they do.")
MODEL_FIRMNESS = (" Where the model takes its modal state from static alternators, the share of resamples of "
                  "their trials in which it is theirs says how firmly they name it.")
SEED_FOR_SEED = (" The last column sets the model's own learners (the surrogate's, same seeds) beside the "
                 "learners' run robot by robot: those of the same kind at the end in both, of those matched by their "
                 "first Q-tables, and in brackets the number chance would give (as in *In other readings of the "
                 "world*); far above it, the make-up is the initial tables' rather than the world's.")
def learners_beside_the_models(results_dir: Path, model: pd.DataFrame, turn: pd.DataFrame | None) -> list[str]:
    """Where learners ran the base case at a longer horizon in a reading the models were measured
    in (today's world: `<horizon>/<the base case>`; any other:
    `<horizon>/readings/<arrival>-<passing>-<arena>` or its base case's run, for every horizon folder), how their group
    was made beside what each model predicts for that world: the regime, the robots on the
    high-value circuit and the modal state over the run's measured stretch of its stable period
    (`report.mechanism.read_group`), whether its learners converged, and whether each model
    names their regime and the turn-taking model their modal state (a run whose learners did not
    converge is no check of where they settle)."""
    rows = []
    for reading, mine in model.groupby("reading", sort=False):
        folder = reading_folder(parse_reading(str(reading)))
        today = folder == reading_folder(readings()[0])
        for horizon in horizon_folders(results_dir):
            d = run_in(horizon / (base_case().name if today else f"{READINGS_RUNS}/{folder}"), base_case().name)
            rows += _beside(str(reading), mine, turn, d, results_dir)
    if not rows:
        return []
    rows, tallies = [r for r, _ in rows], [t for _, t in rows]
    return ["", "Beside the learners, where they ran the base case in a reading: whether they converged (by the "
            "measures of *The time scale*), how their group was made over the measured stretch of the stable period "
            "(regime, robots on the high-value circuit, modal state), against each model's prediction. " + FIRMNESS, "",
            "| reading | the learners' run | converged | their regime, robots high, modal state | the drift model | "
            "the turn-taking model | the same regime (drift; turn-taking) | the same modal state (turn-taking) |",
            "|---|---|---|---|---|---|---|---|", *rows, *tally_line(tallies)]


def _beside(reading: str, mine: pd.DataFrame, turn: pd.DataFrame | None, d: Path,
            results_dir: Path) -> list[tuple[str, dict]]:
    """The row of `_learners_beside_the_models` for the run in `d`, if it holds one, with its
    tally (`tally.tally_line`)."""
    if not all((d / f"{name}.csv").is_file() for name in ("mechanism", "allocation", "state_time")) \
            or mechanism(d) is None:
        return []
    learners = _learners(d)
    regime, basin = predicted_regime(mine)
    regimes, modal = _same(regime, learners["regime"]), ""
    tally = {"check": not learners["no_check"], "drift": regime == learners["regime"]}
    if turn is not None and reading in turn.index:
        predicted = turn.loc[reading]
        regimes += f"; {_same(str(predicted['regime']), learners['regime'])}"
        state = str(predicted["modal_state"])
        support = support_of(learners, state)
        modal = _same_state(state, learners, support)
        tally.update(turn_tally(str(predicted["regime"]), state, support, learners))
    return [(f"| {reading} | `{d.relative_to(results_dir).as_posix()}` ({learners['trials']} trials, "
             f"{learners['factor']:g}x) | {learners['converged']} | {learners['words']} | {regime} "
             f"({100 * basin:.0f} %), {expected_high(mine):.2f} | {turn_words(turn, reading)} | {regimes} | "
             f"{modal}{learners['no_check']} |", tally)]
