"""The model's allocation as a pre-programmed controller (`learner=model`) and its informed variant
(`learner=informed`): the allocations read from a model file, the robots each moves at an event,
and both in the simulator."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from tavc_cli.errors import TavcError
from tavc_cli.learning.informed import InformedPolicy, ModelPolicy, ranked
from tavc_cli.model.allocations import model_allocations, model_differences
from tests.helpers import REPO, tavc, tavc_here


def write_model(path: Path, values: list[float], states: dict[str, str]) -> Path:
    path.write_text(json.dumps({"values": values,
                                "by_team_size": {n: {"predicted_state": s} for n, s in states.items()}}))
    return path


def test_allocations_are_read_most_valuable_circuit_first(tmp_path):
    # the model writes its states most valuable circuit first, whichever circuit that is: with
    # circuit 1 the more valuable, "3:2" is still 3 robots on the high circuit, 2 on the low one
    model = write_model(tmp_path / "model.json", [2000.0, 2200.0], {"5": "3:2", "6": "4:2"})
    assert model_allocations(model) == {"5": [3, 2], "6": [4, 2]}


def test_a_model_measured_with_other_settings_than_the_run_is_refused_in_one_line(tmp_path):
    """The model's allocations stand for a run only where its model.json records the run's arena,
    values, unit of t and robot speed (a setting it does not record is not compared)."""
    model = json.loads((REPO / "results/initial_distribution/model/model.json").read_text())
    world = {"arena": "two_circuits", "tasks.values": [2200.0, 2000.0], "tasks.time_unit": "ms",
             "robot.speed_mps": 0.25}  # the chapter's, as the committed model was measured
    assert model_differences(model, world) == []
    assert model_differences(model, {**world, "tasks.values": [4000.0, 2000.0], "robot.speed_mps": 0.3}) == [
        "tasks.values [2200.0, 2000.0] (the run: [4000.0, 2000.0])", "robot.speed_mps 0.25 (the run: 0.3)"]
    assert model_differences({"by_team_size": {}}, world) == []
    result = tavc("config", "experiment=initial_distribution", "learner=model", "scale=smoke",
                  f"learner.model_file={REPO / 'results/initial_distribution/model/model.json'}",
                  "arena=two_circuits_parallel")
    assert result.returncode != 0 and len(result.stderr.strip().splitlines()) == 1
    assert result.stderr.strip().endswith(
        "was measured with other settings than this run's (arena two_circuits (the run: two_circuits_parallel)); run "
        "`tavc model` at this run's settings and name its model.json"), result.stderr


def test_the_committed_model_gives_the_chapter_team_three_and_three():
    allocations = model_allocations(REPO / "results/initial_distribution/model/model.json")
    assert allocations["6"] == [3, 3] and allocations["5"] == [3, 2]


def test_a_missing_model_is_named(tmp_path):
    with pytest.raises(TavcError, match="no model at .*run `tavc model` first"):
        model_allocations(tmp_path / "nowhere.json")


def test_counts_follow_the_values_ranking():
    assert ranked([3, 2], np.array([2200.0, 2000.0])).tolist() == [3, 2]
    assert ranked([3, 2], np.array([2000.0, 2200.0])).tolist() == [2, 3]


def counts(policy, alive):
    return np.bincount(policy.assignment[alive], minlength=2).tolist()


def test_informed_moves_one_robot_into_the_vacancy_and_one_after_a_swap():
    policy = InformedPolicy({"6": [3, 3], "5": [3, 2]}, 6, 2, np.random.default_rng(1))
    alive = np.ones(6, dtype=bool)
    values = np.array([2200.0, 2000.0])
    policy.on_event(alive, values)
    assert counts(policy, alive) == [3, 3]
    before = policy.assignment.copy()
    # a robot on the high circuit (0) breaks down: 2 robots are left there, 3 on the low one;
    # the model wants 3:2 for five, so exactly one low robot moves up
    broken = int(np.flatnonzero(before == 0)[0])
    alive[broken] = False
    policy.on_event(alive, values)
    assert counts(policy, alive) == [3, 2]
    moved = np.flatnonzero((policy.assignment != before) & alive)
    assert len(moved) == 1 and before[moved[0]] == 1 and policy.assignment[moved[0]] == 0
    # the values swap: circuit 1 is now the valuable one and must hold 3: one robot moves down
    after_breakdown = policy.assignment.copy()
    policy.on_event(alive, values[::-1].copy())
    assert counts(policy, alive) == [2, 3]
    moved = np.flatnonzero((policy.assignment != after_breakdown) & alive)
    assert len(moved) == 1 and after_breakdown[moved[0]] == 0


def test_model_keeps_its_allocation_through_every_event():
    policy = ModelPolicy({"6": [3, 3], "5": [3, 2]}, 6, 2, np.random.default_rng(1))
    alive = np.ones(6, dtype=bool)
    policy.on_event(alive, np.array([2200.0, 2000.0]))
    start = policy.assignment.copy()
    alive[int(np.flatnonzero(start == 0)[0])] = False
    policy.on_event(alive, np.array([2200.0, 2000.0]))
    policy.on_event(alive, np.array([2000.0, 2200.0]))
    assert policy.assignment.tolist() == start.tolist()
    assert [policy.choose(r, 0) for r in range(6)] == start.tolist()


def test_robots_are_drawn_onto_the_allocation_not_taken_in_order():
    # a model that knows no robot from another: over seeds, robot 0 lands on each circuit
    firsts = set()
    for seed in range(20):
        policy = ModelPolicy({"6": [3, 3]}, 6, 2, np.random.default_rng(seed))
        policy.on_event(np.ones(6, dtype=bool), np.array([2200.0, 2000.0]))
        firsts.add(int(policy.assignment[0]))
    assert firsts == {0, 1}


def test_a_team_the_model_has_not_predicted_is_refused_in_one_line(tmp_path):
    result = tavc_here("run", "experiment=initial_distribution", "learner=model", "team.n_robots=4", "scale=smoke",
                       f"output_dir={tmp_path}/out")
    assert result.returncode != 0
    assert "learner.allocations: the model predicts nothing for a team of 4" in result.stderr
    assert "Traceback" not in result.stderr
    result = tavc_here("run", "experiment=initial_distribution", "learner=model",
                       f"learner.model_file={tmp_path}/x.json", "scale=smoke", f"output_dir={tmp_path}/out")
    assert result.returncode != 0 and "learner.model_file: no model at" in result.stderr
    assert len(result.stderr.strip().splitlines()) == 1
    # informed needs the model's allocation for the team a breakdown leaves, known before the warm-up
    six = write_model(tmp_path / "six.json", [2200.0, 2000.0], {"6": "3:3"})
    result = tavc_here("run", "experiment=breakdown", "learner=informed", f"learner.model_file={six}", "scale=smoke",
                       f"output_dir={tmp_path}/out")
    assert result.returncode != 0
    assert "the model predicts nothing for the 5 robots left after a breakdown" in result.stderr
    # the model's allocation kept through events needs only the starting team's
    result = tavc_here("config", "experiment=breakdown", "learner=model", f"learner.model_file={six}", "scale=smoke")
    assert result.returncode == 0, result.stderr


@pytest.mark.slow
def test_in_the_simulator_informed_fills_the_vacancy_and_model_leaves_it(tmp_path):
    for name in ("model", "informed"):
        result = tavc("run", "experiment=breakdown", f"learner={name}", "scale=quick", "trials=2", "baselines=[]",
                      f"output_dir={tmp_path}/{name}", "--no-progress")
        assert result.returncode == 0, result.stderr
    model = pd.read_csv(tmp_path / "model/state_time.csv").set_index(["controller", "state"])
    informed = pd.read_csv(tmp_path / "informed/state_time.csv").set_index(["controller", "state"])
    # after a high-circuit robot breaks down: the model's 3:3 becomes 2:3 and stays; informed
    # moves one robot up and holds the model's 3:2 for five
    assert model.loc[("model", "2:3"), "mean_pct"] == pytest.approx(100.0)
    assert informed.loc[("informed", "3:2"), "mean_pct"] == pytest.approx(100.0)
    vacancy = pd.read_csv(tmp_path / "informed/vacancy.csv")
    assert vacancy["filled"].all() and (vacancy["filler_from"] == 1).all()
    assert not pd.read_csv(tmp_path / "model/vacancy.csv")["filled"].any()


@pytest.mark.parametrize(("text", "said"), [
    ("[]", "has no `by_team_size`"),
    ('{"by_team_size": {}}', "has no `by_team_size`"),
    ('{"by_team_size": {"6": {}}}', "has no predicted state of counts for 6 robots"),
    ('{"by_team_size": {"6": {"predicted_state": "4:-2"}}}', "has no predicted state of counts for 6 robots"),
    # a digit to str.isdigit that int() refuses: one line, not a traceback
    ('{"by_team_size": {"6": {"predicted_state": "\u00b3:3"}}}', "has no predicted state of counts for 6 robots"),
    # a count past the digits int() reads
    ('{"by_team_size": {"6": {"predicted_state": "' + "9" * 5000 + ':3"}}}',
     "has no predicted state of counts for 6 robots"),
    ('{"by_team_size": {"6": {"predicted_state": "3:2"}}}', "predicts 3:2 for 6 robots: 5 robots, not 6"),
    ('{"by_team_size": {"6": {"predicted_state": "2:2:2"}}}', "2:2:2 for 6 robots: 3 circuits, where the arena has 2"),
    ('{"by_team_size": {"six": {"predicted_state": "3:3"}}}', "has a team size 'six'"),
    ('{"by_team_size": {"0": {"predicted_state": "0:0"}}}', "has a team size '0'"),
    ("[" * 100 + "]" * 100, "nested"),
    ("{", "is not a model.json"),
])
def test_a_malformed_model_file_is_one_line_before_anything_runs_and_the_fixed_file_runs(tmp_path, monkeypatch, text,
                                                                                          said):
    from typer.testing import CliRunner

    from tavc_cli.cli import app

    model = tmp_path / "model.json"
    model.write_text(text)
    monkeypatch.chdir(tmp_path)
    command = ["run", "experiment=initial_distribution", "scale=smoke", "learner=model", "baselines=[]", "trials=1",
               "duration_s=120", f"learner.model_file={model}", "output_dir=out", "--no-progress"]
    result = CliRunner().invoke(app, command)
    assert result.exit_code == 1
    line = result.output.strip().splitlines()[-1]
    assert line.startswith(f"error: learner.model_file: {model}") or line.startswith(f"error: {model}: cannot be read")
    assert said in line and "Traceback" not in result.output
    assert len(line) < 400  # the file's content is quoted short
    assert not (tmp_path / "out").exists()  # nothing written: the fixed file runs the same command
    write_model(model, [2200.0, 2000.0], {"5": "3:2", "6": "3:3"})
    assert CliRunner().invoke(app, command).exit_code == 0
