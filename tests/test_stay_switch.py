"""`tavc stay-switch`: what each reading does to staying and switching.

The table from a hand-made task table, every number worked out by hand; the grid's readings;
refusals in one line; one reading end to end at smoke scale (slow)."""

from __future__ import annotations

import math

import pandas as pd
import pytest
from typer.testing import CliRunner

from tavc_cli.analysis.stay_switch import stay_switch_table, thresholds
from tavc_cli.cli import app
from tavc_cli.surrogate.tasks import COLUMNS
from tavc_cli.vocabulary import ACTIVITIES


def _task(makeup: str, kind: str, circuit: int, t: float, source: float, drive: float = 0.0, wait: float = 0.0):
    row = {"team": "all:6@0.25", "makeup": makeup, "group": "all", "kind": kind, "circuit": circuit,
           "task_time_s": t, "source_s": source, **{f"{a}_s": 0.0 for a in ACTIVITIES}}
    row.update(drive_s=drive, wait_s=wait)
    return row


def test_the_thresholds_are_the_values_ratio():
    # (2200 + 2000) / (2 * 2000) = 1.05 on the low-value circuit, 4200 / 4400 = 0.9545... on the high one
    low, high, h, lo = thresholds([2200.0, 2000.0])
    assert (low, high, h, lo) == (pytest.approx(1.05), pytest.approx(4200 / 4400), 0, 1)
    assert thresholds([2000.0, 2200.0])[2:] == (1, 0)  # the high-value circuit is the one of the larger value


def test_stay_and_switch_times_and_whether_staying_pays_by_hand():
    tasks = pd.DataFrame([
        # make-up 2-2-2: stayers high (circuit 0) 80 s, stayers low (circuit 1) 80 and 90 s, switches 90 and 96 s
        _task("all:2-2-2", "stay", 0, 80.0, 30.0), _task("all:2-2-2", "stay", 1, 80.0, 30.0, drive=50.0),
        _task("all:2-2-2", "stay", 1, 90.0, 40.0, drive=60.0, wait=4.0),
        _task("all:2-2-2", "switch", 0, 90.0, 40.0, drive=70.0), _task("all:2-2-2", "switch", 1, 96.0, 36.0),
        # make-up 6-0-0: no low stayer, no alternator: no ratio
        _task("all:6-0-0", "stay", 0, 100.0, 50.0),
    ], columns=list(COLUMNS))
    table = stay_switch_table(tasks, [2200.0, 2000.0], "today").set_index("makeup")
    r = table.loc["all:2-2-2"]
    assert (r["high_stayers"], r["low_stayers"], r["alternators"]) == (2, 2, 2)
    assert (r["n_stay_low"], r["n_stay_high"], r["n_switch"]) == (2, 1, 2)
    assert (r["t_stay_low_s"], r["t_stay_high_s"], r["t_switch_s"]) == (85.0, 80.0, 93.0)
    assert (r["drive_stay_low_s"], r["wait_stay_low_s"], r["drive_switch_s"]) == (55.0, 2.0, 35.0)
    # whole task: 93 / 85 = 1.094 > 1.05 pays on the low circuit; 93 / 80 = 1.1625 > 0.9545 on the high one
    assert r["ratio_low"] == pytest.approx(93 / 85) and bool(r["stay_pays_low"])
    assert r["ratio_high"] == pytest.approx(93 / 80) and bool(r["stay_pays_high"])
    # from the source on: switches (50 + 60) / 2 = 55 s, low stayers (50 + 50) / 2 = 50 s: 1.10 > 1.05, pays
    assert r["ratio_low_source"] == pytest.approx(55 / 50) and bool(r["stay_pays_low_source"])
    assert r["ratio_high_source"] == pytest.approx(55 / 50)
    none = table.loc["all:6-0-0"]
    assert math.isnan(none["ratio_low"]) and not bool(none["stay_pays_low"])
    assert list(table.index) == ["all:6-0-0", "all:2-2-2"]  # by alternators, then low-value stayers


def test_a_switch_that_is_quicker_than_a_stay_does_not_pay():
    tasks = pd.DataFrame([_task("all:3-2-1", "stay", 1, 100.0, 40.0), _task("all:3-2-1", "switch", 0, 100.0, 40.0),
                          _task("all:3-2-1", "stay", 0, 100.0, 40.0)], columns=list(COLUMNS))
    r = stay_switch_table(tasks, [2200.0, 2000.0]).iloc[0]
    assert r["ratio_low"] == 1.0 and not bool(r["stay_pays_low"]) and bool(r["stay_pays_high"])  # 1 > 0.9545


def test_the_grid_is_every_combination_with_todays_world_first():
    from tavc_cli.analysis.stay_switch import parse_reading, reading_folder, reading_name, readings

    grid = readings()
    assert len(grid) == 8 and grid[0] == {"arrival": "dock", "passing": "nearest", "arena": "two_circuits"}
    assert len({reading_name(r) for r in grid}) == 8
    assert reading_name(grid[0]) == "arrival=dock passing=nearest arena=two_circuits"
    assert reading_folder(grid[-1]) == "range-left-two_circuits_parallel"
    assert all(parse_reading(reading_name(r)) == r for r in grid)


@pytest.mark.parametrize(("args", "message"), [
    (["arrival=range"], "error: arrival: set by the study for each reading"),
    (["experiment=heterogeneous", "scale=smoke"], "error: experiment=heterogeneous: stay and switch are measured on a "
                                                  "team of one group; this team has 2"),
    (["learner=random", "scale=smoke"], "error: learner=random: the drift model takes an epsilon-greedy learner's "
                                        "exploration"),
    (["seed=x"], "error: seed: expected an integer, got 'x'"),
])
def test_what_the_study_sets_or_cannot_measure_is_one_line(tmp_path, args, message):
    """Refused before anything is written: not even the folder's list of tavc's files (each
    reading's settings are composed and checked first; a learner without epsilon was refused
    only after the first reading's tasks were measured)."""
    result = CliRunner().invoke(app, ["stay-switch", *args, "--results", str(tmp_path / "out"), "--no-progress"])
    assert result.exit_code == 1
    lines = result.output.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith(message), result.output
    assert not (tmp_path / "out").exists()


@pytest.mark.slow
def test_the_study_end_to_end_at_smoke_scale_and_again_from_its_tasks(tmp_path):
    """Every reading measured, the table and figure written; the same command again measures
    nothing and writes the same table, byte for byte."""
    out = tmp_path / "study"
    args = ["stay-switch", "scale=smoke", "surrogate.trials_per_makeup=2", "team.n_robots=2", "--results", str(out),
            "--no-progress"]
    first = CliRunner().invoke(app, args)
    assert first.exit_code == 0, first.output
    table = pd.read_csv(out / "stay_switch.csv")
    # two robots make C(2 + 2, 2) = 6 make-ups of stayers high, stayers low and alternators
    assert table["reading"].nunique() == 8 and table.groupby("reading").size().max() <= 6
    tasks = pd.read_csv(out / "dock-nearest-two_circuits" / "tasks" / "task_times.csv")
    today = table[table["reading"] == "arrival=dock passing=nearest arena=two_circuits"].reset_index(drop=True)
    mine = stay_switch_table(tasks, [2200.0, 2000.0], today["reading"].iloc[0])  # the table is its tasks', read again
    pd.testing.assert_frame_equal(today, mine, check_dtype=False, atol=1e-3)
    assert (out / "stay_switch.png").is_file()
    before = (out / "stay_switch.csv").read_bytes()
    again = CliRunner().invoke(app, args)
    assert again.exit_code == 0 and "measuring" not in again.output
    assert (out / "stay_switch.csv").read_bytes() == before


def _write_study(results, tasks: pd.DataFrame, readings) -> None:
    """A study's `stay_switch.csv` under `results`: the table of `tasks` for each reading."""
    (results / "stay_switch").mkdir()
    pd.concat([stay_switch_table(tasks, [2200.0, 2000.0], r) for r in readings]).to_csv(
        results / "stay_switch" / "stay_switch.csv", index=False)


def test_the_reports_section_reads_the_studys_table(tmp_path):
    from tavc_cli.report.studies import stay_switch_lines

    assert stay_switch_lines(tmp_path) == []  # no study: no section
    tasks = pd.DataFrame([_task("all:2-2-2", "stay", 1, 80.0, 30.0), _task("all:2-2-2", "switch", 0, 92.0, 40.0),
                          _task("all:3-2-1", "stay", 1, 100.0, 30.0), _task("all:3-2-1", "switch", 0, 100.0, 40.0)],
                         columns=list(COLUMNS))
    _write_study(tmp_path, tasks, ["arrival=dock"])
    text = "\n".join(stay_switch_lines(tmp_path))
    # 92 / 80 = 1.15 pays, 100 / 100 = 1.0 does not: one of two; from the source 52 / 50 = 1.04 and 60 / 70: none
    assert "| arrival=dock | 2 | 1.000, 1.075, 1.150 | 1 | 0 |" in text
    assert "![stay and switch in each reading](stay_switch/stay_switch.png)" in text



@pytest.mark.parametrize(("name", "text", "says"), [
    ("stay_switch.csv", "reading,makeup\narrival=dock,all:2-2-2\n",
     "no column high_stayers, low_stayers, alternators, ratio_low, threshold_low, stay_pays_low, stay_pays_low_source"),
    ("stay_switch_model.csv", "reading,regime,basin,robots_high\narrival=dock,mixed,most,2\n",
     "column basin holds something other than numbers"),
    ("stay_switch_turn_taking.csv", 'reading,regime\n"arrival=dock\n', "Error tokenizing data. C error: EOF inside "
                                                                         "string starting at row 1"),
    ("stay_switch.json", '{"measurement": {"measure_s": "long"}}', "not a record of the study's measurement"),
])
def test_a_damaged_file_of_the_study_is_one_line_naming_it(tmp_path, name, text, says):
    from tavc_cli.errors import TavcError
    from tavc_cli.report.studies import stay_switch_lines

    tasks = pd.DataFrame([_task("all:2-2-2", "stay", 1, 80.0, 30.0), _task("all:2-2-2", "switch", 0, 92.0, 40.0)],
                         columns=list(COLUMNS))
    _write_study(tmp_path, tasks, ["arrival=dock"])
    (tmp_path / "stay_switch" / name).write_text(text)
    with pytest.raises(TavcError) as refused:
        stay_switch_lines(tmp_path)
    assert str(refused.value) == (f"{tmp_path / 'stay_switch' / name}: cannot be read ({says}); run its "
                                  "`tavc stay-switch` again to rewrite it")


def test_the_calibrated_study_is_a_second_table_with_the_settings_each_reading_was_measured_at(tmp_path):
    """A study at the calibrations' choices (`stay_switch_calibrated/`) beside the study at the
    readings' defaults: its own table after the first, each row with the settings from its
    record; the first table as it was without it."""
    import json

    from tavc_cli.report.studies import stay_switch_lines

    tasks = pd.DataFrame([_task("all:2-2-2", "stay", 1, 80.0, 30.0), _task("all:2-2-2", "switch", 0, 92.0, 40.0)],
                         columns=list(COLUMNS))
    _write_study(tmp_path, tasks, ["arrival=dock"])
    before = stay_switch_lines(tmp_path)
    slower = tasks.assign(task_time_s=[80.0, 70.0])  # a switch 70 / 80 = 0.875 of a stay: staying does not pay
    (tmp_path / "stay_switch_calibrated").mkdir()
    stay_switch_table(slower, [2200.0, 2000.0], "arrival=dock").to_csv(
        tmp_path / "stay_switch_calibrated" / "stay_switch.csv", index=False)
    (tmp_path / "stay_switch_calibrated" / "stay_switch.json").write_text(json.dumps(
        {"readings": {"arrival=dock": {"calibrated": ["robot.dock.dwell_s=5.0", "robot.laser.n_rays=31"]}}}))
    after = stay_switch_lines(tmp_path)
    assert after[:len(before) - 1] == before[:-1]  # the first table as it was
    rest = "\n".join(after[len(before) - 1:])
    assert "`tavc stay-switch --calibrated`" in rest and "(stay_switch_calibrated/stay_switch.png)" in rest
    assert "| arrival=dock | dwell_s 5.0, n_rays 31 | 1 | 0.875, 0.875, 0.875 | 0 |" in rest


def test_the_calibrated_settings_are_each_searchs_choice_or_one_line(tmp_path):
    """`calibrated_overrides` reads today's world's search in `calibration/world/` and another
    reading's in `readings/<reading>/calibration/world/`; a search that is missing, cannot be
    read or chose nothing is one line naming it."""
    import json

    from tavc_cli.errors import TavcError
    from tavc_cli.stay_switch import calibrated_overrides

    def search(where, record):
        (tmp_path / where).mkdir(parents=True, exist_ok=True)
        (tmp_path / where / "search.json").write_text(record if isinstance(record, str) else json.dumps(record))

    with pytest.raises(TavcError, match="no calibration search of dock-nearest-two_circuits at"):
        calibrated_overrides(tmp_path, "dock-nearest-two_circuits")
    search("calibration/world", {"chosen_overrides": ["robot.dock.dwell_s=0.0"]})
    search("readings/range-left-two_circuits/calibration/world", {"chosen_overrides": ["robot.dock.dwell_s=5.0"]})
    assert calibrated_overrides(tmp_path, "dock-nearest-two_circuits") == ["robot.dock.dwell_s=0.0"]
    assert calibrated_overrides(tmp_path, "range-left-two_circuits") == ["robot.dock.dwell_s=5.0"]
    search("readings/range-left-two_circuits/calibration/world", {"chosen": None, "chosen_overrides": []})
    with pytest.raises(TavcError, match="names no chosen point"):
        calibrated_overrides(tmp_path, "range-left-two_circuits")
    search("readings/range-left-two_circuits/calibration/world", "{not json")
    with pytest.raises(TavcError, match="cannot be read"):
        calibrated_overrides(tmp_path, "range-left-two_circuits")


def test_a_setting_the_calibrations_choose_is_refused_beside_calibrated_before_anything_is_written(tmp_path):
    import json

    for where in ["calibration/world", *(f"readings/{r}/calibration/world" for r in (
            "dock-left-two_circuits", "dock-nearest-two_circuits_parallel", "dock-left-two_circuits_parallel",
            "range-nearest-two_circuits", "range-nearest-two_circuits_parallel", "range-left-two_circuits",
            "range-left-two_circuits_parallel"))]:
        (tmp_path / where).mkdir(parents=True)
        (tmp_path / where / "search.json").write_text(json.dumps({"chosen_overrides": ["robot.dock.dwell_s=5.0"]}))
    result = CliRunner().invoke(app, ["stay-switch", "robot.dock.dwell_s=0", "--calibrated", str(tmp_path),
                                      "--results", str(tmp_path / "out"), "--no-progress"])
    assert result.exit_code == 1
    assert result.output.strip().splitlines()[-1] == \
        "error: robot.dock.dwell_s: set by each reading's calibration search (--calibrated)"
    assert not (tmp_path / "out").exists()


# ---- the drift model (analysis.makeup_model), on task times set by hand ------------------------

def _times(stay_high, stay_low, switch):
    """Times for every make-up of two robots: stay_high(h), stay_low(l) by robots on the circuit,
    switch a constant."""
    from tavc_cli.analysis.makeup_model import Times

    out = {}
    for h in range(3):
        for low in range(3 - h):
            out[(h, low, 2 - h - low)] = {"stay_high": stay_high(h) if h else math.nan,
                                          "stay_low": stay_low(low) if low else math.nan,
                                          "switch_high": switch if 2 - h - low else math.nan,
                                          "switch_low": switch if 2 - h - low else math.nan}
    return Times(out)


def test_the_start_is_multinomial_over_a_random_tables_greedy_policies():
    from tavc_cli.analysis.makeup_model import start_probability

    # 3/8 high, 3/8 low, 1/4 alternate: two robots both alternating 1/16, one high one low 2 * 9/64
    assert start_probability((0, 0, 2)) == pytest.approx(1 / 16)
    assert start_probability((1, 1, 0)) == pytest.approx(2 * 9 / 64)
    total = sum(start_probability((h, low, 6 - h - low)) for h in range(7) for low in range(7 - h))
    assert total == pytest.approx(1.0)


def test_a_switch_quicker_than_a_stay_makes_everyone_alternate():
    from tavc_cli.analysis.makeup_model import predict, predicted_regime, rate

    times = _times(lambda h: 100.0, lambda low: 100.0, 90.0)
    # epsilon 0: high 2200 / 100 = 22, low 20, alternate 2100 / 90 = 23.33 per second
    assert rate(times, (1, 1, 0), "high", (2200.0, 2000.0), 0.0) == pytest.approx(22.0)
    assert rate(times, (0, 0, 2), "alternate", (2200.0, 2000.0), 0.0) == pytest.approx(2100 / 90)
    prediction = predict(times, 2, (2200.0, 2000.0), 0.0)
    assert list(prediction["makeup"]) == ["0-0-2"] and prediction["basin"].iloc[0] == pytest.approx(1.0)
    assert predicted_regime(prediction) == ("turn-taking", pytest.approx(1.0))


def test_crowding_on_the_high_circuit_makes_one_robot_stay_low():
    from tavc_cli.analysis.makeup_model import best_change, expected_high, predict

    # two on the high circuit take 120 s a task (2200 / 120 = 18.3 < 2000 / 100 = 20 alone on the low one);
    # switching costs 130 s (2100 / 130 = 16.2): from every start the drift ends at one high, one low
    times = _times(lambda h: 100.0 * (1 + 0.2 * (h - 1)), lambda low: 100.0 * (1 + 0.2 * (low - 1)), 130.0)
    values = (2200.0, 2000.0)
    gain, where = best_change(times, (2, 0, 0), values, 0.0)
    assert where == (1, 1, 0) and gain == pytest.approx(20.0 / (2200 / 120) - 1)
    assert best_change(times, (1, 1, 0), values, 0.0) == (0.0, None)  # a rest point
    # from both alternating: to the high circuit gains 22 / 16.15 - 1, the most; then the other goes low
    assert best_change(times, (0, 0, 2), values, 0.0)[1] == (1, 0, 1)
    prediction = predict(times, 2, values, 0.0)
    assert list(prediction["makeup"]) == ["1-1-0"] and prediction["regime"].iloc[0] == "persistence"
    assert expected_high(prediction) == pytest.approx(1.0)


def test_exploration_mixes_the_other_task_into_a_strategys_rate():
    from tavc_cli.analysis.makeup_model import rate

    times = _times(lambda h: 100.0, lambda low: 110.0, 130.0)
    # a low stayer with epsilon 0.1: 95 % low tasks (2000, 110 s), 5 % switches to high (2200, 130 s)
    expected = (0.95 * 2000 + 0.05 * 2200) / (0.95 * 110 + 0.05 * 130)
    assert rate(times, (1, 1, 0), "low", (2200.0, 2000.0), 0.1) == pytest.approx(expected)


def test_the_reports_section_gives_the_make_up_models_regime(tmp_path):
    from tavc_cli.analysis.makeup_model import predict
    from tavc_cli.report.studies import stay_switch_lines

    tasks = pd.DataFrame([_task("all:1-0-1", "stay", 1, 80.0, 30.0), _task("all:1-0-1", "switch", 0, 92.0, 40.0),
                          _task("all:0-1-1", "stay", 1, 80.0, 30.0), _task("all:0-1-1", "switch", 0, 92.0, 40.0)],
                         columns=list(COLUMNS))
    _write_study(tmp_path, tasks, ["today"])
    model = predict(_times(lambda h: 100.0, lambda low: 100.0, 90.0), 2, (2200.0, 2000.0), 0.0).assign(reading="today")
    model.to_csv(tmp_path / "stay_switch" / "stay_switch_model.csv", index=False)
    text = "\n".join(stay_switch_lines(tmp_path))
    assert "| turn-taking (100 %), 1.00 |" in text  # both alternate: one robot's worth on each circuit


def test_the_learners_beside_the_models_say_whether_they_agree_and_whether_it_is_a_check(tmp_path):
    """The report's rows of learners beside the two models, on two committed 40x runs copied
    into a folder with the models' predictions written by hand: a converged run of turn-taking
    against a prediction of persistence is a disagreement; against one of turn-taking an
    agreement; the modal state is checked against the turn-taking model's; a run whose learners
    did not converge is no check, whatever the models say."""
    import shutil

    from tavc_cli.report.studies import stay_switch_lines
    from tests.helpers import REPO

    committed = REPO / "results" / "converged"
    today, other = committed / "initial_distribution", committed / "readings" / "range-left-two_circuits_parallel"
    if not (today / "mechanism.csv").is_file() or not (other / "mechanism.csv").is_file():
        pytest.skip("the committed 40x runs are not here")
    for src, dst in ((today, tmp_path / "converged" / "initial_distribution"),
                     (other, tmp_path / "converged" / "readings" / "range-left-two_circuits_parallel")):
        dst.mkdir(parents=True)
        for name in ("config.yaml", "mechanism.csv", "allocation.csv", "convergence.csv", "state_time.csv"):
            shutil.copy(src / name, dst / name)
    tasks = pd.DataFrame([_task("all:2-2-2", "stay", 1, 80.0, 30.0), _task("all:2-2-2", "switch", 0, 92.0, 40.0)],
                         columns=list(COLUMNS))
    readings = ("arrival=dock passing=nearest arena=two_circuits",
                "arrival=range passing=left arena=two_circuits_parallel")
    _write_study(tmp_path, tasks, readings)

    def rows(model_makeup: str) -> dict:
        h, low, a = (int(x) for x in model_makeup.split("-"))
        model = pd.DataFrame([{"reading": r, "makeup": model_makeup, "high_stayers": h, "low_stayers": low,
                               "alternators": a, "rest_point": True, "regime": regime, "robots_high": h + a / 2,
                               "basin": 1.0} for r, regime in zip(readings, [model_regime] * 2, strict=True)])
        model.to_csv(tmp_path / "stay_switch" / "stay_switch_model.csv", index=False)
        pd.DataFrame([{"reading": r, "regime": model_regime, "stayers": 6 - a, "alternators": a, "robots_high": 3.0,
                       "modal_state": modal, "modal_share_pct": 50.0, "modal_from": "alternators"} for r in readings]
                     ).to_csv(tmp_path / "stay_switch" / "stay_switch_turn_taking.csv", index=False)
        text = stay_switch_lines(tmp_path)
        tally[:] = [x for x in text if x.startswith("Where the learners converged")]
        lines = [x for x in text if x.startswith("| arrival=") and "` (" in x]
        return {x.split("|")[1].strip(): [c.strip() for c in x.strip("|").split("|")] for x in lines}

    tally: list[str] = []
    model_regime, modal = "persistence", "4:2"
    found = rows("3-3-0")
    # the converged run alone is a check: neither model names its regime, nor the turn-taking model its modal state
    assert tally == ["Where the learners converged (1 run): the turn-taking model names their modal state in 0 of 1 "
                     "and their regime in 0; the drift model their regime in 0 of 1."]
    assert found[readings[0]][2] == "yes" and found[readings[0]][3].startswith("turn-taking, 3.00, 3:3 (")  # converged
    assert found[readings[0]][5] == "persistence, 3.00, 4:2 (50 %)"
    assert found[readings[0]][6] == "**no**; **no**" and found[readings[0]][7].startswith("**no** (the learners: ")
    assert found[readings[1]][2].startswith("no (") and found[readings[1]][7].endswith("(not a check: the learners did "
                                                                                        "not converge)")
    model_regime, modal = "turn-taking", "3:3"
    found = rows("0-0-6")
    assert found[readings[0]][6] == "yes; yes" and found[readings[0]][7] == "yes"
    assert tally == ["Where the learners converged (1 run): the turn-taking model names their modal state in 1 of 1 "
                     "and their regime in 1; the drift model their regime in 1 of 1."]


def test_from_the_source_counts_only_tasks_whose_source_arrival_is_known():
    # two low stays: 100 s with 40 s to the source, 200 s with no source arrival recorded: 60 s from the source
    # (not 150 - 40 = 110); one switch of 90 s with 30 s to the source: 60 s; 60 / 60 = 1.0
    tasks = pd.DataFrame([_task("all:4-1-1", "stay", 1, 100.0, 40.0), _task("all:4-1-1", "stay", 1, 200.0, math.nan),
                          _task("all:4-1-1", "switch", 0, 90.0, 30.0)], columns=list(COLUMNS))
    r = stay_switch_table(tasks, [2200.0, 2000.0]).iloc[0]
    assert r["ratio_low_source"] == pytest.approx(1.0)
    assert r["ratio_low"] == pytest.approx(90 / 150)


def test_a_damaged_stay_switch_table_stops_the_report_before_it_writes(tmp_path):
    """The report checks the readings' table with every file it reads, before its first write."""
    import shutil

    from tavc_cli.errors import TavcError
    from tavc_cli.report import build_report
    from tests.helpers import REPO

    run = REPO / "results" / "initial_distribution"
    if not (run / "state_time.csv").is_file():
        pytest.skip("the committed run is not here")
    shutil.copytree(run, tmp_path / "initial_distribution", ignore=shutil.ignore_patterns("trials", "model"))
    (tmp_path / "stay_switch").mkdir()
    (tmp_path / "stay_switch" / "stay_switch.csv").write_bytes(b"\x00\xff not a table \"")
    with pytest.raises(TavcError, match="stay_switch.csv: cannot be read"):
        build_report(tmp_path)
    assert not (tmp_path / "REPORT.md").exists() and not (tmp_path / ".tavc.json").exists()
