"""The report's sections for the studies beside the chapter's state tables: the value-ratio
sweep (`make value-ratio`) and the readings' stay/switch studies, with the models set beside the
learners' runs (`report.beside`)."""

from __future__ import annotations

from pathlib import Path

import pandas as pd

from tavc_cli.analysis.makeup_model import readings_summary
from tavc_cli.analysis.value_ratio import predicted_shares
from tavc_cli.chapter import base_case
from tavc_cli.io import write_text_atomic
from tavc_cli.ownership import VALUE_RATIO_DIR, read
from tavc_cli.readers import load_json
from tavc_cli.report.beside import learners_beside_the_models, turn_taking_check_lines, turn_words
from tavc_cli.report.files import read_stay_switch, there
from tavc_cli.report.text import fmt
from tavc_cli.run_tables import model_rows, ratio_points


def check_value_ratio(results_dir: Path) -> None:
    """Refuse a value-ratio sweep (`run_tables.ratio_points`) with two runs in a cell of its table,
    or a column of runs made otherwise in what the column's label does not name."""
    if (results_dir / VALUE_RATIO_DIR).is_dir():
        ratio_points(results_dir / VALUE_RATIO_DIR)


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
        owned = read(root)  # an earlier report's table, of runs no longer there: not left as this one's
        if owned is not None:
            owned.remove("value_ratio.csv")
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
                  *learners_beside_the_models(results_dir, model, turn), *turn_taking_check_lines(results_dir)]
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
        lines.append(line + f" {turn_words(turn, r.reading)} |")
    return lines
