"""The model that knows turn-taking: how a group is read from a run's tables (modal state,
robots on the high-value circuit over the measured stretch, regime), where its prediction takes
the modal state from, its refusals in one line, and its two runs end to end at smoke scale
(slow)."""

from __future__ import annotations

import json
import math

import pandas as pd
import pytest
from typer.testing import CliRunner

from tavc_cli import config
from tavc_cli.analysis.trial_stats import stable_from
from tavc_cli.analysis.turn_taking import group_reading, modal_state, modal_support, prediction, robots_high
from tavc_cli.cli import app
from tavc_cli.errors import TavcError
from tavc_cli.report.tally import (
    base_name,
    middle_line,
    middle_states,
    no_check_note,
    tally_line,
    trials_words,
    turn_tally,
)
from tavc_cli.turn_taking import check_overrides, predict_turn_taking
from tests.helpers import KINDS_A, KINDS_B, q_table, robots_table

STATES = ("0:6", "1:5", "2:4", "3:3", "4:2", "5:1", "6:0")


def _state_time(shares: dict[str, list[float]]) -> pd.DataFrame:
    return pd.DataFrame([{"state": s, "controller": c, "mean_pct": p, "std_pct": 0.0, "n_trials": 4}
                         for c, pcts in shares.items() for s, p in zip(STATES, pcts, strict=True)])


def _mechanism(rows: list[tuple[str, str, float, float, float, float]]) -> pd.DataFrame:
    """(controller, window, stayers high, stayers low, alternators, mixed) per trial."""
    cols = {"switch_share": 0.5, "task_s_stay": 90.0, "task_s_switch": 80.0, "avoid_s_stay": 5.0,
            "avoid_s_switch": 1.0, "wait_s_stay": 9.0, "wait_s_switch": 1.0, "q_gap_stay_switch": 0.0, "n_idle": 0}
    return pd.DataFrame([{"controller": c, "trial": i, "window": w, "n_stayers_high": h, "n_stayers_low": lo,
                          "n_alternators": a, "n_mixed": m, **cols} for i, (c, w, h, lo, a, m) in enumerate(rows)])


def test_the_modal_state_is_the_largest_share_and_the_first_on_a_tie():
    table = _state_time({"tavc": [1, 5, 20, 30, 30, 10, 4], "random": [2, 9, 23, 31, 23, 9, 2]})
    assert modal_state(table, "tavc") == ("3:3", 30.0)  # 3:3 and 4:2 tie at 30: the first in the table's order
    assert modal_state(table, "random") == ("3:3", 31.0)
    state, share = modal_state(table, "alternate")
    assert state == "" and math.isnan(share)


def _trial_stats(*trials: dict[str, float], controller: str = "tavc") -> pd.DataFrame:
    return pd.DataFrame([{"controller": controller, "trial": i, **{f"pct_{k}": v for k, v in t.items()}}
                         for i, t in enumerate(trials)])


def test_a_modal_states_firmness_is_its_share_of_resampled_trials():
    # one trial: every resample is that trial, so its modal state is modal in all of them
    one = _trial_stats({"3:2": 70.0, "2:3": 30.0})
    assert modal_support(one, "3:2") == 1.0 and modal_support(one, "2:3") == 0.0
    # two trials, one wholly in y and one wholly in x: of the four equally likely pairs, yy names y, xx names x
    # and the two mixed ones tie, which goes to y, first in the table's order (not the alphabet's): y in 3/4
    two = _trial_stats({"y": 100.0, "x": 0.0}, {"y": 0.0, "x": 100.0})
    assert modal_support(two, "y") == pytest.approx(0.75, abs=0.03)
    assert modal_support(two, "x") == pytest.approx(0.25, abs=0.03)
    assert modal_support(two, "x") + modal_support(two, "y") == 1.0
    # other controllers' trials are not the learners': three random trials wholly in x change nothing
    mixed = pd.concat([two, _trial_stats(*[{"y": 0.0, "x": 100.0}] * 3, controller="random")], ignore_index=True)
    assert modal_support(mixed, "y") == modal_support(two, "y")
    # a trial without shares (no defined state in its window) is left out: the one left decides alone
    gap = _trial_stats({"y": 100.0, "x": 0.0}, {"y": math.nan, "x": math.nan})
    assert modal_support(gap, "y") == 1.0
    # a state only another controller's trials have is no column of the learners': it leaves theirs alone
    other = pd.concat([one, _trial_stats({"3:2": 0.0, "2:3": 0.0, "9:9": 100.0}, controller="random")],
                      ignore_index=True)
    assert modal_support(other, "3:2") == 1.0 and math.isnan(modal_support(other, "9:9"))
    # a state the table does not have, or no trials of the controller: no share
    assert math.isnan(modal_support(two, "z")) and math.isnan(modal_support(two, "x", controller="static"))


def test_robots_high_are_averaged_over_the_measured_stretch_only():
    alloc = pd.DataFrame({"t_s": [100.0, 200.0, 300.0, 400.0, 200.0], "controller": ["tavc"] * 4 + ["random"],
                          "mean_high": [1.0, 2.0, 4.0, 8.0, 100.0]})
    assert robots_high(alloc, "tavc", 150.0, 400.0) == pytest.approx(3.0)  # 200 and 300: (2 + 4) / 2
    assert math.isnan(robots_high(alloc, "tavc", 500.0, 600.0))


def test_a_group_is_read_from_its_stable_windows():
    mech = _mechanism([("tavc", "stable", 0, 0, 6, 0), ("tavc", "stable", 0, 1, 5, 0), ("tavc", "w1", 3, 3, 0, 0)])
    alloc = pd.DataFrame({"t_s": [50.0, 150.0], "controller": ["tavc", "tavc"], "mean_high": [4.0, 3.0]})
    got = group_reading(mech, alloc, _state_time({"tavc": [0, 2, 20, 60, 15, 3, 0]}), 100.0, 200.0)
    # per trial 0.5 stayers and 5.5 alternators: 5.5 of 6 working robots alternate, at least half
    assert got == {"regime": "turn-taking", "stayers": 0.5, "alternators": 5.5, "robots_high": 3.0,
                   "modal_state": "3:3", "modal_share_pct": 60.0}


def test_turn_taking_takes_its_modal_state_from_the_alternators_and_the_rest_from_the_learners():
    learners = {"regime": "turn-taking", "stayers": 0.0, "alternators": 6.0, "robots_high": 3.0,
                "modal_state": "2:4", "modal_share_pct": 35.0}
    got = prediction(learners, ("3:3", 61.0))
    assert (got["modal_state"], got["modal_share_pct"], got["modal_from"]) == ("3:3", 61.0, "alternators")
    assert got["robots_high"] == 3.0 and got["regime"] == "turn-taking"
    held = prediction({**learners, "regime": "persistence"}, ("3:3", 61.0))
    assert (held["modal_state"], held["modal_from"]) == ("2:4", "learners")
    with pytest.raises(ValueError, match="static alternators"):
        prediction(learners, None)


@pytest.mark.parametrize("override", ["learner=random", "output_dir=/tmp/x", "scale.time_factor=3",
                                      "+surrogate.tasks_dir=/tmp/y", "baseline_trials=4"])
def test_what_the_model_sets_for_its_runs_is_refused(override):
    with pytest.raises(TavcError, match=f"^{override.split('=')[0].lstrip('+')}: set by the model"):
        check_overrides([override])
    check_overrides(["experiment=breakdown", "scale=smoke", "arrival=range"])  # the user's to set


def test_tavc_model_refuses_such_a_setting_in_one_line_before_it_measures(tmp_path):
    result = CliRunner().invoke(app, ["model", "--turn-taking", "learner=random", "scale=smoke",
                                      f"output_dir={tmp_path / 'm'}", "--no-progress"])
    assert result.exit_code != 0
    assert result.output.strip().splitlines() == [
        "error: learner: set by the model that knows turn-taking for each of its runs (its learners on the surrogate "
        "at 40 times the scale's durations, static alternators at the scale's own)"]
    assert not (tmp_path / "m" / "model").exists()


@pytest.mark.slow
def test_the_model_end_to_end_at_smoke_scale_and_again_from_its_runs(tmp_path):
    """Its tasks measured, its learners run at 40 times the scale's durations, its prediction
    written as its learners' tables give it; the same call again reuses every trial and writes
    the same prediction."""
    compose = lambda o: config.settings(config.load_config(o))  # noqa: E731
    out = tmp_path / "tt"
    args = ["experiment=initial_distribution", "scale=smoke"]
    first = predict_turn_taking(args, out, compose, echo=lambda _: None)
    learners = compose([*args, f"scale.time_factor={40 * 0.02!r}", "scale.stable_window=chapter"])
    assert first["learners_horizon"] == pytest.approx(40 * 0.02) and first["learners_trials"] == 2
    tables = {n: pd.read_csv(out / "learners" / f"{n}.csv") for n in ("mechanism", "allocation", "state_time")}
    again = group_reading(tables["mechanism"], tables["allocation"], tables["state_time"], stable_from(learners),
                          float(learners.duration_s))
    assert first["regime"] == again["regime"] and first["robots_high"] == pytest.approx(again["robots_high"])
    assert (first["alternators_run"] is not None) == (first["regime"] == "turn-taking")
    written = (out / "turn_taking.json").read_bytes()
    assert json.loads(written)["modal_state"] == first["modal_state"]
    stamps = {p: p.stat().st_mtime_ns for p in (out / "learners" / "trials").rglob("*") if p.is_file()}
    second = predict_turn_taking(args, out, compose, echo=lambda _: None)
    assert second == first and (out / "turn_taking.json").read_bytes() == written
    assert {p: p.stat().st_mtime_ns for p in stamps} == stamps  # no trial drawn again


def test_the_report_sets_a_scenarios_prediction_beside_its_learners_at_each_horizon(tmp_path):
    """A prediction written by hand for breakdown beside the committed 40x run of breakdown (its
    learners take turns; 3:2 42.08 % of the measured stretch, 2:3 41.99 %): the same regime and
    modal state is two yeses; another modal state is a no, with the learners' share of it
    beside; without the learners' run there is no row."""
    import shutil

    from tavc_cli.report.beside import turn_taking_check_lines
    from tests.helpers import REPO

    run = REPO / "results" / "converged" / "breakdown"
    if not (run / "mechanism.csv").is_file():
        pytest.skip("the committed 40x runs are not here")
    assert turn_taking_check_lines(tmp_path) == []
    (tmp_path / "converged" / "breakdown").mkdir(parents=True)
    for name in ("config.yaml", "mechanism.csv", "allocation.csv", "state_time.csv", "convergence.csv"):
        shutil.copy(run / name, tmp_path / "converged" / "breakdown" / name)
    where = tmp_path / "turn_taking" / "breakdown" / "turn_taking"
    where.mkdir(parents=True)

    def row(modal: str, **more) -> list[str]:
        (where / "turn_taking.json").write_text(json.dumps({"regime": "turn-taking", "robots_high": 2.5,
                                                            "modal_state": modal, "modal_share_pct": 40.0, **more}))
        text = turn_taking_check_lines(tmp_path)
        lines = [x for x in text if x.startswith("| breakdown |")]
        assert len(lines) == 1
        tally.append(next(x for x in text if x.startswith("Where the learners converged (")))
        middle.append(next(x for x in text if x.startswith("Where the learners converged to turn-taking")))
        return [c.strip() for c in lines[0].strip("|").split("|")]

    tally: list[str] = []
    middle: list[str] = []

    cells = row("3:2")
    assert cells[1] == "`converged/breakdown` (20 trials)" and cells[2] == "yes"
    assert cells[3].startswith("turn-taking, ") and cells[3].split(", ")[2] == "3:2 (42 %)"
    assert cells[4] == "turn-taking, 2.50, 3:2 (40 %)" and cells[5] == "yes; yes"
    assert row("2:3")[5] == "yes; **no** (the learners: 42.0 % in 2:3)"
    assert tally == ["Where the learners converged (1 run): the turn-taking model names their modal state in 1 of 1 "
                     "and their regime in 1.", "Where the learners converged (1 run): the turn-taking model names "
                     "their modal state in 0 of 1 and their regime in 1."]
    # five robots taking turns, modal in 3:2: the two middle states, 3:2 and 2:3, are a near tie (42.1 and 42.0 %
    # of the committed run; no table of its trials, no alternators' run here)
    assert middle[-1] == ("Where the learners converged to turn-taking in a team of odd size, modal in one of its two "
                          "middle states (1 run), they spend at least 42.0 % of the stable period in each of the two, "
                          "whose shares differ by 0.1 points: their modal state is a near tie, and the model names it "
                          "at 0 of 1.")
    # with the table of its trials, one trial wholly in 3:2: the predicted state's share of resamples beside it
    _trial_stats({"3:2": 100.0, "2:3": 0.0}).to_csv(tmp_path / "converged" / "breakdown" / "trial_stats.csv",
                                                    index=False)
    assert row("3:2")[5] == "yes; yes (modal in 100 % of resamples of the trials)"
    assert row("2:3")[5] == "yes; **no** (the learners: 42.0 % in 2:3; modal in 0 % of resamples of the trials)"
    said = "Where the learners converged (1 run): the turn-taking model names their modal state in {} of 1 (over " \
           "resamples of the learners' trials, in {}.0 of the 1 on average, where a prediction of each run's own " \
           "modal state would be right in 1.0; at the 1 whose trials name their own modal state firmly, modal in at " \
           "least 90 % of resamples, in {}) and their regime in 1."
    # the learners' own modal state, 3:2, is the one state of that trial: every resample makes it modal, so the
    # point is a firm one, and the model names its modal state there or not as it does at all
    assert tally[-2:] == [said.format(1, 1, 1), said.format(0, 0, 0)]
    # the model's own learners beside these, seed for seed (tests.helpers' KINDS_A and KINDS_B, one trial: 3 of
    # 4, and 3 by chance, each robot's chance being whether it is the same); nothing there without both tables
    assert row("3:2")[6] == ""
    for folder, kinds in ((tmp_path / "converged" / "breakdown", KINDS_A), (where / "learners", KINDS_B)):
        folder.mkdir(exist_ok=True)
        robots_table(kinds).to_csv(folder / "robots.csv", index=False)
        q_table([0.1, -0.05, 0.02, 0.07]).to_csv(folder / "q_values.csv", index=False)
    assert row("3:2")[6] == "3 of 4 (3)"
    # a modal state read from static alternators: how firmly their trials name it, from their own rows alone (one
    # alternators' trial wholly in 3:2; three random trials wholly in 2:3 beside it, which would make 2:3 modal in
    # most resamples were they counted); a state the surrogate's learners name, or no table: nothing more
    (where / "alternators").mkdir()
    pd.concat([_trial_stats({"3:2": 100.0, "2:3": 0.0}, controller="alternate"),
               _trial_stats(*[{"3:2": 0.0, "2:3": 100.0}] * 3, controller="random")], ignore_index=True) \
        .to_csv(where / "alternators" / "trial_stats.csv", index=False)
    alternators = {"modal_from": "alternators", "alternators_run": "alternators"}
    assert row("3:2", **alternators)[4] == "turn-taking, 2.50, 3:2 (40 %; the alternators' modal state in 100 % " \
                                          "of resamples)"
    assert row("2:3", **alternators)[4] == "turn-taking, 2.50, 2:3 (40 %; the alternators' modal state in 0 % " \
                                          "of resamples)"
    assert row("3:2", modal_from="learners", alternators_run="alternators")[4] == "turn-taking, 2.50, 3:2 (40 %)"
    assert row("3:2", modal_from="alternators", alternators_run="elsewhere")[4] == "turn-taking, 2.50, 3:2 (40 %)"
    assert row("3:2", modal_from="alternators", alternators_run="..")[4] == "turn-taking, 2.50, 3:2 (40 %)"
    # two alternators' trials, one wholly in each state: resampled, not the means' argmax (a tie, which would
    # name 3:2 always): 3:2 when both draws are the first or one of each (a tie goes to the table's first), 3/4
    pd.concat([_trial_stats({"3:2": 100.0, "2:3": 0.0}, {"3:2": 0.0, "2:3": 100.0}, controller="alternate"),
               _trial_stats({"3:2": 0.0, "2:3": 100.0}, controller="random")], ignore_index=True) \
        .to_csv(where / "alternators" / "trial_stats.csv", index=False)
    assert row("3:2", **alternators)[4] == "turn-taking, 2.50, 3:2 (40 %; the alternators' modal state in 75 % " \
                                          "of resamples)"
    # their shares of the two middle states beside the learners': |46.9 - 45.9| = 1.0, their own rows alone
    pd.DataFrame({"state": ["3:2", "2:3", "3:2"], "controller": ["alternate", "alternate", "random"],
                  "mean_pct": [46.9, 45.9, 10.0]}).to_csv(where / "alternators" / "state_time.csv", index=False)
    row("3:2", **alternators)
    assert middle[-1].endswith("at 1 of 1 (over resamples of their trials, in 1.0 of the 1 on average); the static "
                               "alternators' shares of the same two states, which the model reads its modal state "
                               "from, differ by 1.0 (median 1.0).")
    (where / "alternators" / "state_time.csv").write_text("state,controller\n3:2,alternate\n")
    with pytest.raises(TavcError, match="alternators/state_time.csv: cannot be read"):
        row("3:2", **alternators)
    (where / "alternators" / "state_time.csv").unlink()
    # a table without its columns is one line naming it, not a traceback
    (where / "alternators" / "trial_stats.csv").write_text("trial,pct_3:2\n0,100\n")
    with pytest.raises(TavcError, match="alternators/trial_stats.csv: cannot be read"):
        row("3:2", **alternators)


def test_a_post_hoc_prediction_stands_beside_its_scenarios_run_and_is_tallied_apart_from_every_check(tmp_path):
    """A prediction folder named after its scenario with the way's and post hoc's suffixes
    (`breakdown-explorers-post_hoc`) is set beside the scenario's own run, marked as no check; the
    checks' tally counts only the prediction made before (`breakdown`: 3:2, the learners' modal
    state, 1 of 1), and a line of its own counts the post hoc one (2:3, a miss: 0 of 1) beside
    the model as it is at the same run (1 of 1)."""
    import shutil

    from tavc_cli.report.beside import turn_taking_check_lines
    from tests.helpers import REPO

    assert base_name("team_size_3-explorers-post_hoc") == base_name("team_size_3-explorers") == "team_size_3"
    assert base_name("team_size_3-post_hoc") == "team_size_3" and base_name("post_hoc-x") == "post_hoc-x"
    run = REPO / "results" / "converged" / "breakdown"
    if not (run / "mechanism.csv").is_file():
        pytest.skip("the committed 40x runs are not here")
    (tmp_path / "converged" / "breakdown").mkdir(parents=True)
    for name in ("config.yaml", "mechanism.csv", "allocation.csv", "state_time.csv", "convergence.csv"):
        shutil.copy(run / name, tmp_path / "converged" / "breakdown" / name)
    for name, modal, more in (("breakdown", "3:2", {}), ("breakdown-explorers-post_hoc", "2:3",
                                                          {"switches": "explorers"})):
        where = tmp_path / "turn_taking" / name / "turn_taking"
        where.mkdir(parents=True)
        (where / "turn_taking.json").write_text(json.dumps({"regime": "turn-taking", "robots_high": 2.5,
                                                            "modal_state": modal, "modal_share_pct": 40.0, **more}))
    text = turn_taking_check_lines(tmp_path)
    rows = {x.split("|")[1].strip(): [c.strip() for c in x.strip("|").split("|")] for x in text
            if x.startswith("| breakdown")}
    assert set(rows) == {"breakdown", "breakdown-explorers-post_hoc"}
    assert rows["breakdown"][5] == "yes; yes"
    assert rows["breakdown-explorers-post_hoc"][1] == "`converged/breakdown` (20 trials)"
    assert rows["breakdown-explorers-post_hoc"][5] == "yes; **no** (the learners: 42.0 % in 2:3) (post hoc: not a " \
                                                      "check)"
    assert "Where the learners converged (1 run): the turn-taking model names their modal state in 1 of 1 and " \
           "their regime in 1." in text
    assert text[-1].startswith("Made after the learners' runs beside them were read (predictions `*-post_hoc`")
    assert text[-1].endswith("where the learners converged (1 run): the turn-taking model names their modal state "
                             "in 0 of 1 and their regime in 1; the model as it is, at 1 of the same runs, their "
                             "modal state in 1 and their regime in 1.")
    assert not [x for x in text if x.startswith("With lone switchers measured from explorers")]


def test_a_prediction_finds_its_learners_among_a_readings_experiments(tmp_path):
    """A reading's folder at 40x that holds the chapter's experiments, as `tavc reproduce
    --results` writes them, rather than being one run: the prediction named after the reading is
    set beside the base case's run inside it; a folder with neither gives no row."""
    import shutil

    from tavc_cli.report.beside import turn_taking_check_lines
    from tests.helpers import REPO

    run = REPO / "results" / "converged" / "initial_distribution"
    if not (run / "mechanism.csv").is_file():
        pytest.skip("the committed 40x runs are not here")
    name = "range-left-two_circuits_parallel-calibrated"
    where = tmp_path / "turn_taking" / name / "turn_taking"
    where.mkdir(parents=True)
    (where / "turn_taking.json").write_text(json.dumps({"regime": "turn-taking", "robots_high": 3.0,
                                                        "modal_state": "3:3", "modal_share_pct": 70.0}))
    folder = tmp_path / "converged" / "readings" / name
    (folder / "breakdown").mkdir(parents=True)
    assert not [x for x in turn_taking_check_lines(tmp_path) if x.startswith(f"| {name} |")]
    (folder / "initial_distribution").mkdir()
    for f in ("config.yaml", "mechanism.csv", "allocation.csv", "state_time.csv", "convergence.csv"):
        shutil.copy(run / f, folder / "initial_distribution" / f)
    rows = [x for x in turn_taking_check_lines(tmp_path) if x.startswith(f"| {name} |")]
    assert len(rows) == 1
    cells = [c.strip() for c in rows[0].strip("|").split("|")]
    assert cells[1] == f"`converged/readings/{name}/initial_distribution` (20 trials)" and cells[5] == "yes; yes"


def test_a_team_of_two_groups_is_read_without_robots_on_the_high_circuit(tmp_path):
    """A run of a team of several groups writes no allocation.csv (its states count each group):
    its group is read all the same, the robots on the high-value circuit NaN, and the report's
    words show a dash for them."""
    from tavc_cli.report.beside import prediction_words
    from tavc_cli.report.mechanism import read_group

    mech = _mechanism([("tavc", "stable", 3, 2, 1, 0)])
    mech.to_csv(tmp_path / "mechanism.csv", index=False)
    _state_time({"tavc": [1, 5, 20, 30, 31, 10, 3]}).to_csv(tmp_path / "state_time.csv", index=False)
    cfg = config.settings(config.load_config(["experiment=heterogeneous", "scale=smoke"]))
    got = read_group(tmp_path, cfg)
    assert got["regime"] == "persistence" and got["modal_state"] == "4:2" and math.isnan(got["robots_high"])
    assert prediction_words(got) == "persistence, -, 4:2 (31 %)"


def test_a_prediction_at_other_values_is_set_beside_the_value_ratio_sweeps_run_at_those_values(tmp_path):
    """A prediction with ``tasks.values=[3000,2000]`` among its overrides is set beside the
    committed 40x run of the value-ratio sweep at those values, and beside no other."""
    import shutil

    from tavc_cli.report.beside import turn_taking_check_lines
    from tests.helpers import REPO

    sweep = REPO / "results" / "value_ratio" / "converged"
    jobs = {w: sweep / f"{k}_tasks.values=_{w},2000_" for k, w in ((2, 3000), (3, 4000))}
    if not all((d / "mechanism.csv").is_file() for d in jobs.values()):
        pytest.skip("the committed value-ratio sweep is not here")
    for d in jobs.values():
        (tmp_path / "value_ratio" / "converged" / d.name).mkdir(parents=True)
        for name in ("config.yaml", "mechanism.csv", "allocation.csv", "state_time.csv", "convergence.csv"):
            shutil.copy(d / name, tmp_path / "value_ratio" / "converged" / d.name / name)
    where = tmp_path / "turn_taking" / "value_ratio_3000" / "turn_taking"
    (where / "learners").mkdir(parents=True)
    (where / "turn_taking.json").write_text(json.dumps({
        "regime": "persistence", "robots_high": 4.0, "modal_state": "4:2", "modal_share_pct": 50.0,
        "learners_run": "learners"}))
    # the prediction's own learners ran in the world of the sweep's job at 3000
    shutil.copy(jobs[3000] / "config.yaml", where / "learners" / "config.yaml")
    rows = [x for x in turn_taking_check_lines(tmp_path) if x.startswith("| value_ratio_3000 |")]
    assert len(rows) == 1 and "`value_ratio/converged/2_tasks.values=_3000,2000_` (8 trials)" in rows[0]


def test_a_readings_folder_name_in_words():
    from tavc_cli.report.counterfactuals import reading_words

    assert reading_words("range-left-two_circuits_parallel") == \
        "arrival=range passing=left arena=two_circuits_parallel"
    assert reading_words("range-left-two_circuits_parallel-calibrated") == \
        "arrival=range passing=left arena=two_circuits_parallel (calibrated)"
    assert reading_words("mine") == "mine"  # a folder not named after a reading keeps its name


def test_a_prediction_at_another_team_size_is_set_beside_the_team_size_sweeps_run_in_its_world(tmp_path):
    """A prediction whose learners ran four robots is set beside the team-size sweep's 40x run
    of four robots, not beside one of five nor the value-ratio sweep's run of six at the same
    values; one of four robots at other values is set beside none of them; the sweeps' runs are
    no runs of the chapter's horizon."""
    import shutil

    from tavc_cli.report.beside import turn_taking_check_lines
    from tavc_cli.report.runs import run_folders
    from tests.helpers import REPO

    job = REPO / "results" / "value_ratio" / "converged" / "1_tasks.values=_2200,2000_"
    if not (job / "mechanism.csv").is_file():
        pytest.skip("the committed value-ratio sweep is not here")

    def config(size: int, values: str = "2200.0") -> str:
        text = (job / "config.yaml").read_text()
        assert "n_robots: 6\n" in text and "- 2200.0\n" in text
        return text.replace("n_robots: 6\n", f"n_robots: {size}\n").replace("- 2200.0\n", f"- {values}\n")

    for sweep, size in (("value_ratio", 6), ("team_size", 4), ("team_size", 5)):
        d = tmp_path / sweep / "converged" / f"0_team.n_robots={size}"
        d.mkdir(parents=True)
        for name in ("mechanism.csv", "allocation.csv", "state_time.csv", "convergence.csv"):
            shutil.copy(job / name, d / name)
        (d / "config.yaml").write_text(config(size))
    assert run_folders(tmp_path) == []
    for name, learners in (("team_size_4", config(4)), ("team_size_4_at_3000", config(4, "3000.0"))):
        where = tmp_path / "turn_taking" / name / "turn_taking"
        (where / "learners").mkdir(parents=True)
        (where / "learners" / "config.yaml").write_text(learners)
        (where / "turn_taking.json").write_text(json.dumps({
            "regime": "turn-taking", "robots_high": 2.0, "modal_state": "2:2", "modal_share_pct": 50.0,
            "learners_run": "learners"}))
    lines = turn_taking_check_lines(tmp_path)
    rows = [x for x in lines if x.startswith("| team_size_4 |")]
    assert len(rows) == 1 and "`team_size/converged/0_team.n_robots=4` (8 trials)" in rows[0]
    assert not [x for x in lines if x.startswith("| team_size_4_at_3000 |")]


def test_each_readings_calibration_search_is_a_row_with_the_world_asked_judged_and_the_rules_choice(tmp_path):
    """Searches by hand: today's world first; a reading whose world as asked (`configured`: code
    read at 1.5 m, no dwell, 61 rays) fails the chapter's facts while another point meets them
    robustly and is chosen; one asked about a point off its grid; one that recorded nothing
    ("?"); a table without the columns a search writes is refused in one line."""
    from tavc_cli.report.counterfactuals import calibration_lines

    cols = ["point", "robot.behaviour.read_range_m", "robot.dock.dwell_s", "robot.laser.n_rays", "lone_leg_s",
            "arrivals_per_5h", "crowding_ratio_6", "feasible", "robust", "chosen"]
    rows = [["a", 1.5, 0.0, 61, 30.0, 3500, 1.02, False, False, False],
            ["b", 2.0, 5.0, 31, 33.0, 3919, 1.2049, True, True, True],
            ["c", 2.0, 10.0, 31, 35.0, 3100, 1.30, True, False, False]]
    assert calibration_lines(tmp_path) == []
    asked = {"robot.behaviour.read_range_m": 1.5, "robot.dock.dwell_s": 0.0, "robot.laser.n_rays": 61}
    for where, record in (
            ("calibration/world", {"configured": {"robot.behaviour.read_range_m": 2.0, "robot.dock.dwell_s": 10.0,
                                                  "robot.laser.n_rays": 31},
                                   "measurement": {"confidence": 0.9}}),
            ("readings/range-left-two_circuits_parallel/calibration/world",
             {"configured": asked, "measurement": {"confidence": 0.9}}),
            ("readings/range-left-two_circuits/calibration/world",
             {"configured": {**asked, "robot.dock.dwell_s": 2.5}}),
            ("readings/range-nearest-two_circuits_parallel/calibration/world", {})):
        (tmp_path / where).mkdir(parents=True)
        pd.DataFrame(rows, columns=cols).to_csv(tmp_path / where / "search.csv", index=False)
        (tmp_path / where / "search.json").write_text(json.dumps(record))
    lines = calibration_lines(tmp_path)
    table = [x.split(" | ")[0].lstrip("| ") + " | " + x.split(" | ")[3] for x in lines if x.startswith("| ")][1:]
    assert table == ["today's world | meets the chapter's facts, not robustly",
                     "arrival=range passing=left arena=two_circuits | is not on its grid",
                     "arrival=range passing=left arena=two_circuits_parallel | does not meet the chapter's facts",
                     "arrival=range passing=nearest arena=two_circuits_parallel | ?"]
    row = [x for x in lines if x.startswith("| arrival=range passing=left arena=two_circuits_parallel |")][0]
    assert row == ("| arrival=range passing=left arena=two_circuits_parallel | read_range_m 1.5, 2; dwell_s 0, 5, "
                   "10; n_rays 31, 61 | 1 / 2 of 3 | does not meet the chapter's facts | read_range_m 2, dwell_s 5, "
                   "n_rays 31; 3919 arrivals per 5 h, t(4 on a circuit) / t(3) 1.20 |")
    assert "robustly to the intervals of its measurement" in lines[2]  # the searches did not all say their level
    pd.DataFrame([r[:5] for r in rows], columns=cols[:5]).to_csv(tmp_path / "calibration" / "world" / "search.csv",
                                                               index=False)
    with pytest.raises(TavcError, match=r"calibration/world/search.csv: cannot be read \(no column arrivals_per_5h"):
        calibration_lines(tmp_path)


def test_the_tally_counts_hits_at_firm_points_apart():
    """Of the converged points, those whose own modal state is modal in at least 90 % of the
    resamples of their trials (0.9 counts) are counted apart, with the model's hits there; a point
    that is no check counts nowhere. By hand: hits 1 of 3, support 1.0 + 0.3 + 0.0 = 1.3, the
    learners' own 1.0 + 0.6 + 0.9 = 2.5, firm points 2 (1.0 and 0.9), hits there 1; regime 2."""
    tallies = [{"check": True, "regime": True, "modal": True, "support": 1.0, "ceiling": 1.0},
               {"check": True, "regime": True, "modal": False, "support": 0.3, "ceiling": 0.6},
               {"check": True, "regime": False, "modal": False, "support": 0.0, "ceiling": 0.9},
               {"check": False, "regime": True, "modal": True, "support": 1.0, "ceiling": 1.0}]
    assert tally_line(tallies) == ["", "Where the learners converged (3 runs): the turn-taking model names their "
                                   "modal state in 1 of 3 (over resamples of the learners' trials, in 1.3 of the 3 on "
                                   "average, where a prediction of each run's own modal state would be right in 2.5; "
                                   "at the 2 whose trials name their own modal state firmly, modal in at least 90 % "
                                   "of resamples, in 1) and their regime in 2."]
    assert tally_line([{**tallies[1], "ceiling": 0.89}])[-1].count("at the 0 whose trials") == 1
    # a firm point whose predicted state has no support (a state outside the trials' table) still counts, as a miss
    odd = tally_line([tallies[0], {**tallies[2], "support": math.nan}])[-1]
    assert "in 1.0 of the 1 with a table of their trials" in odd and "at the 2 whose trials" in odd and \
        "resamples, in 1)" in odd


def test_the_middle_states_of_an_odd_team_are_read_and_their_gaps_tallied():
    """A team of 3 has the middle states 2:1 and 1:2, whichever of its states names it; an even team,
    or a state of another form, has none. A turn-taking group modal in one of them gets both shares,
    its own and the alternators' (None without both); one modal elsewhere, none. By hand over two
    converged odd-team runs (a third no check, a fourth without the shares): the learners' gaps
    |38.1 - 38.3| = 0.2 and |44.0 - 41.0| = 3.0, lowest share 38.1; the alternators' gap 0.0 at
    the one run with their table; hits 1 of 2, support 0.3 + 1.0 = 1.3."""
    assert middle_states("1:2") == middle_states("3:0") == ("2:1", "1:2")
    assert middle_states("4:3") == ("4:3", "3:4")
    assert middle_states("1:1") is None and middle_states("all") is None and middle_states("1:1:1") is None
    learners = {"regime": "turn-taking", "modal_state": "1:2", "trial_stats": pd.DataFrame(),
                "shares": {"0:3": 10.0, "1:2": 38.3, "2:1": 38.1, "3:0": 13.6}}
    tally = turn_tally("turn-taking", "2:1", 0.3, learners, {"2:1": 43.4, "1:2": 43.4})
    assert tally["middle"] == (38.1, 38.3) and tally["alternators"] == (43.4, 43.4) and not tally["modal"]
    assert turn_tally("turn-taking", "2:1", 0.3, learners, {"2:1": 43.4})["alternators"] is None
    assert "middle" not in turn_tally("persistence", "2:1", 0.3, {**learners, "regime": "persistence"})
    assert "middle" not in turn_tally("turn-taking", "2:1", 0.3, {**learners, "modal_state": "3:0"})
    tallies = [{**tally, "check": True},
               {"check": True, "modal": True, "support": 1.0, "middle": (44.0, 41.0), "alternators": None},
               {**tally, "check": False}, {"check": True, "modal": True, "support": 1.0}]
    assert middle_line(tallies) == [
        "", "Where the learners converged to turn-taking in a team of odd size, modal in one of its two middle states "
        "(2 runs), they spend at least 38.1 % of the stable period in each of the two, whose shares differ by 0.2 to "
        "3.0 points: their modal state is a near tie, and the model names it at 1 of 2 (over resamples of their "
        "trials, in 1.3 of the 2 on average); the static alternators' shares of the same two states, which the model "
        "reads its modal state from, differ by 0.0 (median 0.0; at the 1 with their table)."]
    assert middle_line(tallies[2:]) == []


def test_only_converged_learners_at_the_checks_horizon_are_a_check():
    """The checks are at 40x (`analysis.turn_taking.HORIZON`): a converged run at 80x stands beside its
    prediction labelled with its horizon and is no check; a run that did not converge is none
    at any horizon."""
    assert no_check_note(True, 40.0) == ""
    assert no_check_note(True, 80.0) == " (not a check: at 80x; the checks are at 40x)"
    assert no_check_note(False, 80.0) == no_check_note(False, 40.0) == " (not a check: the learners did not converge)"
    assert trials_words({"trials": 20, "factor": 40.0}) == "20 trials"
    assert trials_words({"trials": 8, "factor": 80.0}) == "8 trials, 80x"


def test_a_run_a_prediction_finds_by_its_name_must_be_of_its_own_learners_world(tmp_path):
    """A prediction reads the learners' run at `<horizon>/<name>` as its check: one of another world
    than the prediction's own learners (another arena, here) is refused in one line, before the
    report writes anything."""
    import shutil

    from tavc_cli.errors import TavcError
    from tavc_cli.report.beside import check_named_runs
    from tests.helpers import REPO

    today = REPO / "results" / "converged" / "breakdown" / "config.yaml"
    parallel = REPO / "results" / "converged" / "readings" / "dock-nearest-two_circuits_parallel" / "breakdown"
    where = tmp_path / "turn_taking" / "breakdown" / "turn_taking"
    (where / "learners").mkdir(parents=True)
    (where / "turn_taking.json").write_text(json.dumps({"regime": "turn-taking", "robots_high": 2.5,
                                                        "modal_state": "3:2", "modal_share_pct": 40.0}))
    shutil.copy(today, where / "learners" / "config.yaml")
    run = tmp_path / "converged" / "breakdown"
    run.mkdir(parents=True)
    shutil.copy(today, run / "config.yaml")
    check_named_runs(tmp_path)  # the same world: read as its check
    shutil.copy(parallel / "config.yaml", run / "config.yaml")
    with pytest.raises(TavcError) as info:
        check_named_runs(tmp_path)
    assert str(info.value) == (f"{run}: its arena settings are not those of the learners of the prediction "
                               "turn_taking/breakdown that reads it by its name as its check; move it, or run it "
                               "again in that world")
