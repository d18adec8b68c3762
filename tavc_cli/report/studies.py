"""The report's sections for the studies beside the chapter's state tables: the value-ratio
sweep (`make value-ratio`), the readings' stay/switch studies and the turn-taking model's checks
against the learners."""

from __future__ import annotations

import math
from pathlib import Path

import pandas as pd

from tavc_cli.analysis.makeup_model import expected_high, predicted_regime, readings_summary
from tavc_cli.analysis.stay_switch import parse_reading, reading_folder, readings
from tavc_cli.analysis.turn_taking import RESAMPLES, state_shares
from tavc_cli.analysis.value_ratio import predicted_shares
from tavc_cli.chapter import base_case
from tavc_cli.io import write_text_atomic
from tavc_cli.ownership import READINGS_DIR, VALUE_RATIO_DIR
from tavc_cli.readers import load_json
from tavc_cli.report import files
from tavc_cli.report.files import (
    TURN_TAKING_RUNS,
    config_of,
    horizon_folders,
    model_learners,
    prediction_files,
    read_or_refuse,
    read_prediction,
    read_stay_switch,
    run_in,
    sweep_runs,
    there,
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
from tavc_cli.run_tables import model_rows, ratio_points
from tavc_cli.settings_studies import EXPLORERS


def value_ratio_lines(results_dir: Path, model_json: Path | None) -> list[str]:
    """The value-ratio sweep (`make value-ratio`), if it was run into results_dir/value_ratio:
    its table (also written as value_ratio.csv there), a figure, and the model's prediction."""
    root = results_dir / VALUE_RATIO_DIR
    if not root.is_dir():
        return []
    # deferred: loads matplotlib
    from tavc_cli.viz.figures import value_ratio_figure

    points = ratio_points(root)
    if not len(points):
        return []
    write_text_atomic(root / "value_ratio.csv", points.to_csv(index=False, float_format="%.4f"))
    predicted = None
    model_csv = model_json.parent / "model.csv" if model_json is not None else None
    rows = model_rows(model_csv) if model_csv is not None and there(model_csv) else None
    if rows is not None and set(rows["circuit"]) == {0, 1}:  # a model of two circuits' values
        n_robots = int(load_json(model_json)["n_robots"])  # checked with its run (`files.check_model`)
        fine = [round(1.0 + 0.01 * k, 2) for k in range(101)]
        predicted = predicted_shares(rows, n_robots, fine)
    value_ratio_figure(points, predicted, 1.1, "share of robots on the high-value circuit in the stable period",
                       results_dir / "figures" / "value_ratio")
    columns = list(dict.fromkeys(zip(points["reading"], points["horizon"], strict=True)))
    lines = ["## Learning values and time", "",
             "The chapter's learning values differ by 10 %. How far does the group move towards the high-value "
             "circuit as the difference grows, at the chapter's trial length and at longer ones? "
             f"(`make value-ratio`, 5 h and 50 h, and `make value-ratio-converged`, 200 h: {base_case().name} "
             "with w_low = 2000 and w_high = 2000 x ratio, TAVC only, "
             "each reading and horizon on the same seeds; share of robots on the high-value circuit over the "
             "stable period, mean ± std over trials; runs under `value_ratio/`, table in "
             "`value_ratio/value_ratio.csv`.)", "",
             "| ratio | model predicts | " + " | ".join(f"{r}, {h}" for r, h in columns) + " |",
             "|---|---|" + "---|" * len(columns)]
    for ratio in sorted(set(points["ratio"])):
        pred = ""
        if predicted is not None:
            hit = predicted[(predicted["ratio"] - ratio).abs() < 1e-9]
            pred = f"{hit['state'].iloc[0]} ({hit['share'].iloc[0]:.2f})" if len(hit) else ""
        cells = []
        for r, h in columns:
            g = points[(points["reading"] == r) & (points["horizon"] == h) & ((points["ratio"] - ratio).abs() < 1e-9)]
            cells.append(f"{g['mean'].iloc[0]:.2f} ± {fmt(g['std'].iloc[0], '.2f')} (n = {g['n_trials'].iloc[0]}"
                         + (f", {g['policy_changes_per_trial'].iloc[0]:.1f} policy changes per trial)"
                            if pd.notna(g["policy_changes_per_trial"].iloc[0]) else ")") if len(g) else "")
        lines.append(f"| {ratio:.2f} | {pred} | " + " | ".join(cells) + " |")
    lines += ["", "![share on the high-value circuit against the value ratio](figures/value_ratio.png)", "",
              "With epsilon-greedy selection the unit of t only rescales every reward, and with it the Q-values, "
              "against the fixed initial range [-0.1, 0.1]: with t in seconds the initial values are negligible "
              "beside the first reward, with t in milliseconds they are of its order. The two units of t therefore "
              "differ only in how strongly the initial table decides each robot's first preference.", ""]
    if points["reading"].str.contains("arrival=").any():
        lines += ["Columns naming a reading of the world (`arrival=...`) are the learners in that reading (`make "
                  "value-ratio-checks`); the model's column is today's world's, and the turn-taking model's "
                  "predictions for those runs are set beside them in *The readings*.", ""]
    if points["reading"].str.contains("diagnostic").any():
        lines += ["Rows marked diagnostic are not the chapter's rule: with gamma = 0 a Q-value is a running mean "
                  "of its own task's reward and no longer bootstraps from the state the robot would switch to, so "
                  "a robot compares running means of the circuits' rewards; its estimate for the circuit it does "
                  "not serve still moves only on the exploratory choices. They separate the two brakes on "
                  "learning; the verdicts use the chapter's gamma = 0.95.",
                  ""]
    return lines


STAY_SWITCH_DIR = "stay_switch"  # `make stay-switch`: each reading at its defaults
STAY_SWITCH_CALIBRATED_DIR = "stay_switch_calibrated"  # `make stay-switch-calibrated`: at its calibration's choice
STAY_SWITCH_DIRS = (STAY_SWITCH_DIR, STAY_SWITCH_CALIBRATED_DIR)


def stay_switch_lines(results_dir: Path) -> list[str]:
    """What each reading does to staying and switching (`tavc stay-switch`, `make stay-switch`),
    if it was run into results_dir/stay_switch: per reading, a low-value stayer's t_switch /
    t_stay over the make-ups that have both, and in how many of them staying pays; the figure;
    the same at each reading's calibrated settings where that study was run too
    (`stay_switch_calibrated/`); the models beside the learners."""
    study = _study(results_dir, STAY_SWITCH_DIR)
    if study is None:
        return []
    table, model, turn, record = study
    rel = STAY_SWITCH_DIR
    threshold = float(table.dropna(subset=["ratio_low"])["threshold_low"].iloc[0])
    m = record.get("measurement", {})
    how = (f" Each make-up: {m['trials_per_makeup']} static trials, {m['measure_s']:g} s measured after "
           f"{m['warmup_s']:g} s (scale={record.get('scale', '?')})." if {"trials_per_makeup", "measure_s", "warmup_s"}
           <= set(m) else "")
    n = int((table["high_stayers"] + table["low_stayers"] + table["alternators"]).max())
    lines = ["## The readings: what staying and switching cost", "",
             "Static robots held to their roles (staying on the high-value circuit, staying on the low-value one, "
             f"alternating) in every make-up of the team of {n}, in each reading of the world the chapter leaves "
             f"unsaid (`tavc stay-switch`, `{rel}/stay_switch.csv`). A robot on the low-value circuit gains by staying "
             f"there where a switching task takes more than {threshold:.3f} times a staying one (the values' "
             "(w_h + w_l) / 2 w_l); the vacancy chains the chapter describes need it to. No learner and no claim "
             "enters: this is what the world offers the learners, measured." + how, "",
             f"![stay and switch in each reading]({rel}/stay_switch.png)", "", *_study_rows(table, model, turn)]
    calibrated = _study(results_dir, STAY_SWITCH_CALIBRATED_DIR)
    if calibrated is not None:
        rel = STAY_SWITCH_CALIBRATED_DIR
        lines += ["", "The same study with each reading at the settings its own calibration search chose against the "
                  "chapter's facts (`tavc stay-switch --calibrated`, `make stay-switch-calibrated`, "
                  f"`{rel}/stay_switch.csv`; *The readings calibrated against the chapter's facts*), measured alike:",
                  "", f"![stay and switch in each reading, as calibrated]({rel}/stay_switch.png)", "",
                  *_study_rows(*calibrated)]
    if model is not None:
        lines += ["", "Two models of where the learners settle, neither fitted to anything the learners did. The drift "
                  "model (`analysis/makeup_model.py`, `stay_switch_model.csv`) gives each robot one of the strategies "
                  "a two-state Q-learner holds greedily (stay high, stay low, alternate), rates each by the measured "
                  "tasks of its make-up with epsilon-greedy exploration, and follows the make-up from random initial "
                  "tables, one robot's most gainful change at a time, to where no robot gains. The turn-taking model "
                  "(`turn_taking.py`, `stay_switch_turn_taking.csv`) runs the chapter's learners themselves on the "
                  "same measured tasks (the surrogate, 40 times the chapter's durations, the chapter's trial count) "
                  "for the regime and the robots on the high-value circuit; where they take turns, the modal state is "
                  "that of static robots all alternating in the simulator, which keep their order of circulation.",
                  *_learners_beside_the_models(results_dir, model, turn), *turn_taking_check_lines(results_dir)]
    return [*lines, ""]


def _study(results_dir: Path, folder: str) -> tuple | None:
    """A stay/switch study in results_dir/folder: its table, drift model and turn-taking model
    (None where not written) and its record ({} where none); None where it was not run or no
    make-up has both a low-value stayer and an alternator."""
    study = read_stay_switch(results_dir / folder)
    if study is None or study[0].dropna(subset=["ratio_low"]).empty:
        return None
    table, model, turn, record = study
    return table, model, turn.set_index("reading") if turn is not None else None, record


def _study_rows(table: pd.DataFrame, model: pd.DataFrame | None, turn: pd.DataFrame | None,
                record: dict | None = None) -> list[str]:
    """A stay/switch study's table, a row per reading; with `record`, the settings each reading
    was measured at beside its name (`calibrated` in the study's record)."""
    settings = {k: v.get("calibrated") for k, v in record.get("readings", {}).items() if isinstance(v, dict)} \
        if record else {}
    lines = ["| reading | " + ("settings | " if settings else "") + "make-ups with both | t_switch / t_stay (min, "
             "median, max) | staying pays in | timed from the source: pays in | the drift model: regime (share of "
             "starts), robots high | the turn-taking model: regime, robots high, modal state |",
             "|---|" + ("---|" if settings else "") + "---|---|---|---|---|---|"]
    for r in readings_summary(table, model).itertuples():
        chosen = settings.get(r.reading) or []
        words = ", ".join(f"{k.rsplit('.', 1)[-1]} {v}" for k, _, v in (o.partition("=") for o in chosen))
        line = f"| {r.reading} |" + (f" {words or '?'} |" if settings else "")
        line += f" {r.n} | {r.ratio_min:.3f}, {r.ratio_median:.3f}, {r.ratio_max:.3f} | {r.pays} | {r.pays_source} |"
        line += f" {r.regime} ({100 * r.basin:.0f} %), {r.robots_high:.2f} |" if r.regime is not None else "  |"
        lines.append(line + f" {_turn_words(turn, r.reading)} |")
    return lines


def turn_taking_check_lines(results_dir: Path) -> list[str]:
    """The turn-taking model beside the learners at the chapter's scenarios and value ratios in
    today's world, and in worlds of their own: for each prediction
    `turn_taking/<name>/turn_taking/turn_taking.json` (`tavc model --turn-taking`), the learners'
    runs it predicts (`_learners_runs`), read as in `_beside`."""
    found = prediction_files(results_dir)
    rows, tallies = [], []
    for path in found:
        predicted = read_prediction(path)
        name = path.parent.parent.name
        runs = [d for d in _learners_runs(results_dir, name, predicted, path.parent)
                if all((d / f"{t}.csv").is_file() for t in ("mechanism", "state_time"))]
        if not runs:
            continue
        state, switches, post_hoc = str(predicted["modal_state"]), switches_of(predicted), name.endswith(POST_HOC)
        words = _prediction_words(predicted, model_support(path.parent, predicted))  # once for all its runs
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


def _learners_runs(results_dir: Path, name: str, predicted: dict, where: Path) -> list[Path]:
    """The learners' runs a prediction named `name` (its folder `where`) is for, each once, where
    `<name>` is the prediction's name without its way's and post hoc's suffixes (`tally.base_name`):
    `<horizon>/<name>` and `<horizon>/readings/<name>` (a world of its own, e.g. a reading as
    calibrated; `files.run_in`) at every longer horizon; and every run of a sweep (`SWEEPS`) or
    in a reading (`<horizon>/readings/`) at scale=converged of the prediction's experiment in the
    world its own learners ran in (`WORLD`: the same arena, robots, team, tasks and events)."""
    own_dir = model_learners(where, predicted)
    own_path = own_dir / "config.yaml" if own_dir is not None else None
    own = read_or_refuse(own_path, config_of) if own_path is not None and own_path.is_file() else None
    name = base_name(name)
    runs = [run_in(d, own.experiment_name if own else base_case().name) for h in horizon_folders(results_dir)
            for d in (h / name, h / READINGS_RUNS / name)]
    if own is None:
        return runs
    for d in [*(d for f in SWEEPS for d in sweep_runs(results_dir, f)),
              *(d for h in horizon_folders(results_dir) for d in sweep_runs(h, READINGS_RUNS))]:
        cfg = read_or_refuse(d / "config.yaml", config_of)
        if d not in runs and cfg.scale.name == "converged" and cfg.experiment_name == own.experiment_name and \
                all(getattr(cfg, k) == getattr(own, k) for k in WORLD):
            runs.append(d)
    return runs


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


def _prediction_words(p, own: float = math.nan) -> str:
    """A turn-taking prediction (`turn_taking.json`, or a row of the study's table) in a few words;
    with `own` (`tally.model_support`), how firmly the static alternators it reads name its state."""
    firm = f"; the alternators' modal state in {100 * own:.0f} % of resamples" if math.isfinite(own) else ""
    return (f"{p['regime']}, {fmt(float(p['robots_high']), '.2f') or '-'}, {p['modal_state']} "
            f"({float(p['modal_share_pct']):.0f} %{firm})")


def _turn_words(turn: pd.DataFrame | None, reading: str) -> str:
    """The turn-taking model's prediction for `reading` in a few words, or nothing."""
    return _prediction_words(turn.loc[reading]) if turn is not None and reading in turn.index else ""


FIRMNESS = (f"Beside each predicted modal state, the share of {RESAMPLES:,} resamples of the learners' trials (drawn "
            "with replacement) in which it is their modal state: where each trial settles in a state of its own, a "
            "few trials decide which state is modal, and the share says how firmly they do.")
MODEL_FIRMNESS = (" Where the model takes its modal state from static alternators, the share of resamples of "
                  "their trials in which it is theirs says how firmly they name it.")
SEED_FOR_SEED = (" The last column sets the model's own learners (the surrogate's, same seeds) beside the "
                 "learners' run robot by robot: those of the same kind at the end in both, of those matched by their "
                 "first Q-tables, and in brackets the number chance would give (as in *In other readings of the "
                 "world*); far above it, the make-up is the initial tables' rather than the world's.")
TEAM_SIZE_DIR = "team_size"  # under the results folder: the learners at other team sizes (`make team-size-checks`)
# the sweeps under the results folder the report reads as studies, not run by run, each with where
# it is read: a prediction of the turn-taking model is set beside their runs at 40x in its world
SWEEPS = {VALUE_RATIO_DIR: "the value-ratio sweep, in *Learning values and time*",
          TEAM_SIZE_DIR: "the team-size sweep, in *The readings* (the turn-taking model's check points)"}
WORLD = ("arena", "robot", "team", "tasks", "events")  # the settings that make a run's world and its task
READINGS_RUNS = READINGS_DIR  # under a results or horizon folder: runs in a reading, <arrival>-<passing>-<arena>


def _learners_beside_the_models(results_dir: Path, model: pd.DataFrame, turn: pd.DataFrame | None) -> list[str]:
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
             f"({100 * basin:.0f} %), {expected_high(mine):.2f} | {_turn_words(turn, reading)} | {regimes} | "
             f"{modal}{learners['no_check']} |", tally)]
