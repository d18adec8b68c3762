"""The surrogate of the learning dynamics: tasks measured by make-up in the simulator, trials drawn
from them with the simulator's own learners, seeds and records."""

from __future__ import annotations

import json
from dataclasses import replace

import numpy as np
import pandas as pd
import pytest

from tavc_cli import config
from tavc_cli.errors import TavcError
from tavc_cli.experiments.build import trial_specs
from tavc_cli.learning.policies import AlternatePolicy, alternate_roles
from tavc_cli.surrogate.engine import SurrogateTrial, run_trial
from tavc_cli.surrogate.tasks import COLUMNS, STAY, SWITCH, TaskTimes, Team, makeup_name, makeups, teams_needed
from tavc_cli.vocabulary import ACTIVITIES
from tests.helpers import REPO

TEAM2 = Team.of(["all", "all"], [0.25, 0.25])
# by hand: a stay on circuit 0 takes 100 s, on circuit 1 50 s; a switch to 0 takes 200 s, to 1 100 s
FIXED = {(STAY, 0): 100.0, (STAY, 1): 50.0, (SWITCH, 0): 200.0, (SWITCH, 1): 100.0}


def fixed_times(team: Team = TEAM2, times: dict = FIXED) -> TaskTimes:
    """One task per cell of every make-up of `team`, of the time `times` gives its kind and circuit."""
    rows = []
    for m in makeups(team):
        (s0, s1, a), = m
        cells = [(STAY, 0)] * (s0 > 0) + [(STAY, 1)] * (s1 > 0) + [(SWITCH, 0), (SWITCH, 1)] * (a > 0)
        for kind, c in cells:
            t = times[(kind, c)]
            rows.append({"team": team.name, "makeup": makeup_name(team, m), "group": "all", "kind": kind,
                         "circuit": c, "task_time_s": t, "source_s": t / 2,
                         **{f"{x}_s": (t if x == ACTIVITIES[0] else 0.0) for x in ACTIVITIES}})
    return TaskTimes(pd.DataFrame(rows, columns=list(COLUMNS)))


def two_robot_spec(**learner):
    cfg = config.settings(config.load_config([
        "experiment=initial_distribution", "team.n_robots=2", "learner=tavc_egreedy", "learner.epsilon=0",
        "learner.alpha=0.5", "learner.gamma=0", "learner.q_init_low=0", "learner.q_init_high=0",
        "tasks.values=[2.0,1.0]", "tasks.time_unit=s", "baselines=[]", "trials=1", "duration_s=500",
        "convergence_s=100", "sim.warmup_s=0", "sim.q_snapshot_every_s=0", "scale=paper",
        *[f"learner.{k}={v}" for k, v in learner.items()]]))
    return trial_specs(cfg)[0]


def test_makeups_and_teams_by_hand():
    assert makeups(TEAM2) == [((0, 0, 2),), ((0, 1, 1),), ((0, 2, 0),), ((1, 0, 1),), ((1, 1, 0),), ((2, 0, 0),)]
    assert len(makeups(Team.of(["all"] * 6, [0.25] * 6))) == 28  # (6+2 choose 2)
    mixed = Team.of(["fast", "fast", "slow"], [0.3, 0.3, 0.2])
    assert mixed.name == "fast:2@0.3,slow:1@0.2" and len(makeups(mixed)) == 6 * 3
    assert [t.name for t in teams_needed(mixed, 1)] == ["fast:2@0.3,slow:1@0.2", "fast:1@0.3,slow:1@0.2",
                                                        "fast:2@0.3"]
    with pytest.raises(TavcError, match="one speed per group"):
        Team.of(["all", "all"], [0.25, 0.3])


def test_alternate_controller_holds_each_role():
    policy = AlternatePolicy(alternate_roles([1, 0], 3), 2)  # robot 0 stays on circuit 0; robots 1, 2 alternate
    assert [policy.choose(0, s) for s in (0, 1)] == [0, 0]
    assert [policy.choose(1, s) for s in (0, 1)] == [1, 0]
    assert policy.q_tables() is None


def test_two_robots_every_choice_and_reward_by_hand():
    """Greedy learners (epsilon 0), alpha 0.5, gamma 0, Q starting at 0, values 2 and 1, r = w / t in
    seconds: replayed by hand from the initial classes, the only choices left to chance being
    ties between equal Q-values (broken at random, as the simulator's learners do)."""
    spec = two_robot_spec()
    rec = run_trial(spec, fixed_times())
    d, ch = rec.table("deliveries"), rec.table("choices")
    values = [2.0, 1.0]
    for i in range(2):
        q = np.zeros((2, 2))
        my_choices = list(zip(ch["t_s"][ch["robot"] == i].tolist(), ch["state"][ch["robot"] == i].tolist(),
                              ch["circuit"][ch["robot"] == i].tolist(), strict=True))
        t, expected = 0.0, []
        for k, (t_choice, state, circuit) in enumerate(my_choices):
            assert t_choice == pytest.approx(t)
            if q[state, 0] != q[state, 1]:
                assert circuit == int(np.argmax(q[state]))  # greedy where the values differ
            task = FIXED[(STAY if circuit == state else SWITCH, circuit)]
            if t + task >= 500:  # the trial ends at 500 s: this task is not delivered
                assert k == len(my_choices) - 1
                break
            t += task
            reward = values[circuit] / task
            q[state, circuit] += 0.5 * (reward - q[state, circuit])
            expected.append((t, circuit, task, reward))
            if k + 1 < len(my_choices):
                assert my_choices[k + 1][1] == circuit  # the next choice is from the circuit just served
        mine = d["robot"] == i
        got = list(zip(d["t_s"][mine].tolist(), d["circuit"][mine].tolist(), d["task_time_s"][mine].tolist(),
                       d["reward"][mine].tolist(), strict=True))
        assert np.allclose(np.array(got), np.array(expected)) and len(got) == len(expected) >= 2
    assert rec.meta["key"] == spec.key() and rec.meta["duration_s"] == 500.0
    arrivals = rec.table("arrivals")
    assert (arrivals["kind"] == 1).sum() == len(d["t_s"])  # a sink arrival per delivery


def test_the_same_spec_draws_the_same_trial_and_the_seed_is_the_simulators():
    spec = two_robot_spec(epsilon=0.3)
    a, b = run_trial(spec, fixed_times()), run_trial(spec, fixed_times())
    assert a.tables["choices"]["circuit"].tolist() == b.tables["choices"]["circuit"].tolist()
    from tavc_cli.experiments.trial import TrialState

    state = TrialState(spec, spec.build_arena(), 0)  # the simulator's book-keeping draws the same initial classes
    assert a.table("choices")["state"][:2].tolist() == state.state.tolist()


def test_makeup_counts_stayers_and_alternators_of_the_live_robots():
    spec = two_robot_spec()
    trial = SurrogateTrial(spec, fixed_times())
    tr = trial.tr
    tr.task[:] = [1, 0]
    trial.switching[:] = [False, True]
    assert trial.makeup() == (TEAM2.name, "all:0-1-1")
    tr.alive[1] = False
    assert trial.makeup() == ("all:1@0.25", "all:0-1-0")
    stayers = SurrogateTrial(spec, fixed_times(), stayers=True)
    stayers.tr.task[:] = [1, 0]
    stayers.switching[:] = [False, True]
    assert stayers.makeup() == (TEAM2.name, "all:1-1-0")  # by robots per circuit only


def test_a_cell_never_measured_borrows_the_nearest_makeup():
    frame = fixed_times().frame
    frame = frame[~((frame["makeup"] == "all:1-0-1") & (frame["kind"] == SWITCH))]
    times = TaskTimes(frame)
    row = times.draw(TEAM2.name, "all:1-0-1", "all", SWITCH, 1, np.random.default_rng(0))
    assert row[0] == 100.0 and len(times.borrowed) == 1
    with pytest.raises(TavcError, match="no measured"):
        times.draw("all:3@0.25", "all:3-0-0", "all", STAY, 0, np.random.default_rng(0))


def test_measured_tasks_come_from_static_runs_of_every_makeup(tmp_path):
    from tavc_cli.surrogate.run import measure_tasks

    cfg = config.settings(config.load_config([
        "experiment=initial_distribution", "scale=smoke", "team.n_robots=3", f"surrogate.tasks_dir={tmp_path}",
        "surrogate.measure_s=3000"]))
    said: list[str] = []
    times = measure_tasks(cfg, echo=said.append)
    frame = times.frame
    assert len(said) == 1 and "10 make-ups" in said[0]
    assert set(frame["makeup"]) <= {makeup_name(Team.of(["all"] * 3, [0.25] * 3), m)
                                    for m in makeups(Team.of(["all"] * 3, [0.25] * 3))}
    no_alternators = frame["makeup"].str.endswith("-0")
    assert (frame.loc[no_alternators, "kind"] == STAY).all()  # without alternators every task stays
    assert (frame["source_s"] <= frame["task_time_s"] + 1e-9).all()
    spent = frame[[f"{a}_s" for a in ACTIVITIES]].sum(axis=1)
    assert np.allclose(spent, frame["task_time_s"], atol=0.2)
    again: list[str] = []
    measure_tasks(cfg, echo=again.append)
    assert again == []  # measured once, then read
    other = replace(cfg, surrogate=replace(cfg.surrogate, measure_s=2000.0))
    with pytest.raises(TavcError, match="other settings"):
        measure_tasks(other, echo=again.append)


# --- the study: the side-by-side comparison on synthetic runs ------------------------------------

def _run_folder(folder, shares: dict, rate: float, alternators: int, verdict: str, *overrides: str):
    """A run's folder with just the tables the comparison reads, of one controller `tavc`, and the
    settings of initial_distribution at 40x (and `overrides`)."""
    from tavc_cli.config import load_config
    from tavc_cli.config import settings as to_settings
    from tavc_cli.settings import to_yaml

    folder.mkdir(parents=True)
    (folder / "config.yaml").write_text(to_yaml(to_settings(load_config(
        ["experiment=initial_distribution", "scale=converged", *overrides]))))
    pd.DataFrame({"state": list(shares), "controller": "tavc", "mean_pct": list(shares.values()), "std_pct": 0.0,
                  "n_trials": 2}).to_csv(folder / "state_time.csv", index=False)
    pd.DataFrame({"controller": "tavc", "trial": [0, 1], "value_rate_stable": [rate - 0.01, rate + 0.01]}).to_csv(
        folder / "trial_stats.csv", index=False)
    pd.DataFrame({"claim_id": [3], "verdict": [verdict]}).to_csv(folder / "claims.csv", index=False)
    from tavc_cli.analysis.mechanism import COLUMNS as MECH

    rows = [{c: 0.0 for c in MECH} | {"controller": "tavc", "trial": t, "window": "stable",
                                      "n_alternators": alternators, "n_stayers_high": 6 - alternators}
            for t in (0, 1)]
    pd.DataFrame(rows, columns=MECH).to_csv(folder / "mechanism.csv", index=False)
    return folder


def test_the_comparison_reads_each_engine_against_the_simulator(tmp_path):
    from tavc_cli.surrogate.compare import comparison_rows, high_share

    sim = _run_folder(tmp_path / "sim", {"2:4": 20.0, "3:3": 60.0, "4:2": 20.0}, 0.41, 6, "reproduced")
    sur = _run_folder(tmp_path / "sur", {"2:4": 30.0, "3:3": 38.0, "4:2": 32.0}, 0.40, 6, "not_reproduced")
    rows = comparison_rows("initial_distribution", "40x", sim, {"surrogate_makeup": sur,
                                                               "surrogate_stayers": tmp_path / "none"})
    assert [r["engine"] for r in rows] == ["simulator", "surrogate_makeup"]  # a missing run is left out
    simulator, surrogate = rows
    # by hand: |38 - 60| = 22 points in 3:3, against 10 and 12 in 2:4 and 4:2
    assert surrogate["largest_diff_pts"] == pytest.approx(22.0) and surrogate["at_state"] == "3:3"
    assert simulator["largest_diff_pts"] == 0.0 and simulator["at_state"] == ""
    assert surrogate["modal_state"] == "3:3" and surrogate["pct_modal"] == 38.0
    assert surrogate["n_alternators"] == 6 and surrogate["regime"] == "turn-taking"
    assert surrogate["value_rate_stable"] == pytest.approx(0.40)
    assert simulator["claims"] == "3:yes" and surrogate["claims"] == "3:no"
    # share of robot-time on the high-value circuit, by hand: (0.2 * 2 + 0.6 * 3 + 0.2 * 4) / 6
    assert high_share({"2:4": 20.0, "3:3": 60.0, "4:2": 20.0}, 6) == pytest.approx(0.5)
    # a simulator's run is set beside the surrogate's only where it was made alike, on the same seed
    for override, why in (("seed=3", "ran with another seed (3; the surrogate's: 0)"),
                          ("learner.epsilon=0.2", "ran with other settings (learner.epsilon 0.2 (the surrogate's: "
                                                  "0.1))"),
                          ("experiment=breakdown", "is a run of breakdown (the surrogate's: initial_distribution)")):
        other = _run_folder(tmp_path / override, {"3:3": 100.0}, 0.41, 6, "reproduced", override)
        with pytest.raises(TavcError) as info:
            comparison_rows("initial_distribution", "40x", other, {"surrogate_makeup": sur})
        assert str(info.value) == (f"{other}: is no simulator's run of the surrogate's {sur}: it {why}; name the "
                                   "results folder that holds the runs the study compares with (--simulator)")


def test_the_models_prediction_from_the_stay_tasks_by_hand():
    from tavc_cli.surrogate.compare import predicted_state

    # two robots: a stay task on circuit 0 takes 100 s alone and 200 s with another robot there;
    # on circuit 1 100 s alone. With values 2 and 1, by the model each robot earns its circuit's
    # value over its time: 2:0 gives 2/200 = 0.01 each, 1:1 gives 2/100 and 1/100: a robot on
    # circuit 1 would earn 2/200 = 0.01 by moving, no more than its 0.01: 1:1 holds; in 2:0 a robot
    # earns 0.01 and would earn 1/100 on circuit 1, no more: both are equilibria. With value 3 on
    # circuit 0 instead, 2:0 gives 3/200 = 0.015 > 1/100: the robots crowd circuit 0.
    times = fixed_times(TEAM2, {(STAY, 0): 100.0, (STAY, 1): 100.0, (SWITCH, 0): 100.0, (SWITCH, 1): 100.0})
    frame = times.frame.copy()
    frame.loc[(frame["makeup"] == "all:2-0-0") & (frame["circuit"] == 0), "task_time_s"] = 200.0
    frame.loc[(frame["makeup"] == "all:0-2-0") & (frame["circuit"] == 1), "task_time_s"] = 200.0
    assert predicted_state(TaskTimes(frame), TEAM2.name, 2, [3.0, 1.0]) == "2:0"


def test_the_study_refuses_what_it_sets_for_each_run(tmp_path):
    from tavc_cli.surrogate.study import run_study

    def compose(overrides):
        return config.settings(config.load_config(overrides))

    with pytest.raises(TavcError, match="scale: set by the study"):
        run_study(tmp_path / "study", tmp_path, ["scale=smoke"], compose)
    with pytest.raises(TavcError, match="no part 'phases'"):
        run_study(tmp_path / "study", tmp_path, [], compose, parts=["phases"])
    with pytest.raises(TavcError, match="^seed: expected an integer, got 'x'$"):  # before the folder is taken
        run_study(tmp_path / "study", tmp_path, ["seed=x"], compose)
    assert not (tmp_path / "study").exists()


def test_the_study_checks_its_overrides_as_its_runs_compose_them(tmp_path, monkeypatch):
    """Checked before its folder is taken, at the chapter's scale its runs use: 5000 s of
    convergence is past the end of a quick run (4500 s), not of the study's."""
    from tavc_cli.surrogate import study

    class Taken(Exception):
        pass

    def take(*args, **kwargs):
        raise Taken

    monkeypatch.setattr(study, "take", take)
    with pytest.raises(Taken):
        study.run_study(tmp_path / "study", REPO / "results", ["convergence_s=5000"],
                        lambda overrides: config.settings(config.load_config(overrides)))


@pytest.mark.parametrize(("parts", "such_as"), [
    (None, "initial_distribution"), (["ladder"], "converged/ladder/x1"), (["phase"], "initial_distribution"),
    (["horizon"], "converged/ladder")])
def test_the_study_refuses_a_simulator_folder_without_the_runs_it_compares_with_before_anything_runs(
        tmp_path, parts, such_as):
    """Without one of the simulator's runs its parts compare with, every comparison would stand
    without its reference: refused in one line before the study's folder is made."""
    from tavc_cli.surrogate.study import run_study

    def compose(overrides):
        return config.settings(config.load_config(overrides))

    mine = tmp_path / "mine"
    mine.mkdir()
    (mine / "notes.txt").write_text("somebody's notes\n")
    none = f"holds none of the simulator's runs the study compares with (such as {mine / such_as})"
    for given, says in ((tmp_path / "missing", "is not a folder"), (mine, none)):
        with pytest.raises(TavcError) as refused:
            run_study(tmp_path / "study", given, [], compose, parts=parts)
        assert str(refused.value) == (f"--simulator: {given} {says}; name the folder of the simulator's committed "
                                      "runs (results, as make reproduce-all writes it)")
    assert not (tmp_path / "study").exists()


@pytest.mark.parametrize("part", ["ladder", "phase", "horizon"])
def test_the_study_refuses_a_simulators_run_of_other_settings_before_its_own_runs(tmp_path, monkeypatch, part):
    """The ladder's rung, the phase diagram's chapter point and a rung behind the horizon's
    ladder.csv are each compared with the settings the study's run beside it will have, before
    any run is made: a rung of another seed is one line naming it, and nothing runs."""
    from tavc_cli.surrogate import study

    def ran(*args, **kwargs):
        raise AssertionError("a run was made before the check")

    monkeypatch.setattr(study.Study, "surrogate", ran)
    monkeypatch.setattr(study.Study, "simulator", ran)
    results = tmp_path / "results"
    where = {"ladder": results / "converged" / "ladder" / "x4", "horizon": results / "converged" / "ladder" / "x4",
             "phase": results / "converged" / "initial_distribution"}[part]
    factor = "4.0" if part != "phase" else "40.0"
    other = _run_folder(where, {"3:3": 100.0}, 0.41, 6, "reproduced", f"scale.time_factor={factor}", "seed=3")
    (results / "converged" / "ladder" / "ladder.csv").parent.mkdir(parents=True, exist_ok=True)
    (results / "converged" / "ladder" / "ladder.csv").write_text("factor\n")
    with pytest.raises(TavcError) as info:
        study.run_study(tmp_path / "study", results, [], lambda o: config.settings(config.load_config(o)),
                        parts=[part])
    assert str(info.value).startswith(f"{other}: is no simulator's run of the surrogate's {tmp_path / 'study'}")
    assert "it ran with another seed (3; the surrogate's: 0)" in str(info.value)


def test_a_part_of_other_settings_is_refused_beside_the_studys_tables_or_replaces_them(tmp_path, monkeypatch):
    """A study run a part at a time: a part of another seed beside a table of the first is refused in
    one line; with overwrite=true the earlier part's table goes; where and how fast the runs go is
    no other setting."""
    import pandas as pd

    from tavc_cli.surrogate import study

    def stamped(self):  # a part's table, stamped with the overrides it was made with
        return pd.DataFrame({"overrides": [" ".join(self.overrides)]})

    monkeypatch.setattr(study.Study, "compare", stamped)
    monkeypatch.setattr(study.Study, "speeds", stamped)
    monkeypatch.setattr(study.Study, "check_simulator", lambda self, parts: None)
    monkeypatch.setattr(study.Study, "check_beside", lambda self, parts: None)
    monkeypatch.setattr("tavc_cli.viz.surrogate.study_figures", lambda folder: [])
    out = tmp_path / "study"

    def run(*overrides, part):
        return study.run_study(out, tmp_path, list(overrides), lambda o: config.settings(config.load_config(o)),
                               parts=[part], echo=lambda line: None)

    run("seed=1", part="compare")
    with pytest.raises(TavcError) as refused:
        run("seed=3", part="speed")
    assert str(refused.value) == (f"--results: {out} holds a study made with other settings (settings.seed: 1 -> 3); "
                                  "add overwrite=true to replace its tables, or choose another folder")
    assert not (out / "speed.csv").exists()
    run("seed=3", "overwrite=true", part="speed")
    assert not (out / "comparison.csv").exists() and (out / "speed.csv").is_file()
    run("executor.n_jobs=1", "seed=3", part="compare")  # the same study, spelled and run another way
    assert pd.read_csv(out / "comparison.csv")["overrides"].tolist() == ["executor.n_jobs=1 seed=3"]
    assert (out / "speed.csv").is_file()
    record = json.loads((out / "study.json").read_text())
    assert record["settings"]["seed"] == 3 and "executor" not in record["settings"]
    assert record["simulator"] == str(tmp_path.resolve())
