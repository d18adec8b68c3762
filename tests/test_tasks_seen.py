"""The tasks the learners made, by make-up at their choice (`analysis.tasks_seen`), worked by hand."""

import numpy as np
import pandas as pd
import pytest

from tavc_cli.analysis.tasks_seen import SEEN_COLUMNS, seen_switches, seen_tasks
from tavc_cli.experiments.records import TrialRecord


def _record():
    """Three robots over 400 s. Robot 0 stays on circuit 0, then switches to 1; robot 1 switches
    from 1 to 0 and stays; robot 2 takes circuit 0 at the start and breaks down at 50 s."""
    choices = [(0.0, 0, 0, 0), (0.0, 1, 1, 1), (0.0, 2, 0, 0), (100.0, 0, 0, 0), (150.0, 1, 1, 0),
               (210.0, 0, 0, 1), (290.0, 1, 0, 0), (330.0, 0, 1, 1)]
    deliveries = [(100.0, 0, 0, 100.0, 0.0), (150.0, 1, 1, 150.0, 0.0), (210.0, 0, 0, 110.0, 4.0),
                  (290.0, 1, 0, 140.0, 10.0), (330.0, 0, 1, 120.0, 6.0)]
    col = lambda rows, k, t: np.array([r[k] for r in rows], dtype=t)  # noqa: E731
    tables = {"choices": {"t_s": col(choices, 0, float), "robot": col(choices, 1, int),
                          "state": col(choices, 2, int), "circuit": col(choices, 3, int)},
              "deliveries": {"t_s": col(deliveries, 0, float), "robot": col(deliveries, 1, int),
                             "circuit": col(deliveries, 2, int), "task_time_s": col(deliveries, 3, float),
                             "wait_s": col(deliveries, 4, float), "avoid_s": np.zeros(len(deliveries))},
              "breakdowns": {"t_s": np.array([50.0]), "robot": np.array([2])}}
    return TrialRecord(meta={"n_robots": 3, "duration_s": 400.0, "warmup_s": 0.0}, tables=tables)


def test_seen_tasks_by_the_make_up_at_each_choice():
    # from 200 s on: robot 0's task chosen at 100 s (stays on 0; on circuit 0 then: robot 0 only,
    # robot 2 having broken down at 50 s), its task chosen at 210 s (switches to 1; robot 1 on 0),
    # and robot 1's chosen at 150 s (switches to 0; robots 0 and 1 on 0)
    seen = seen_tasks([_record()])
    assert list(seen.columns) == SEEN_COLUMNS
    assert seen[["on_0", "kind", "circuit", "n", "task_s", "wait_s"]].values.tolist() == [
        [1, "stay", 0, 1, 110.0, 4.0], [1, "switch", 1, 1, 120.0, 6.0], [2, "switch", 0, 1, 140.0, 10.0]]
    # from the start: the first tasks too, chosen together at 0 s with robots 0 and 2 on circuit 0
    whole = seen_tasks([_record(), _record()], from_share=0.0).set_index(["on_0", "kind", "circuit"])
    assert whole.loc[(2, "stay", 0), "n"] == 2 and whole.loc[(2, "stay", 0), "task_s"] == 100.0
    assert whole.loc[(2, "stay", 1), "task_s"] == 150.0 and whole["n"].sum() == 10


def test_seen_switches_move_only_one_switcher_make_ups():
    frame = pd.DataFrame({
        "team": "all:2@0.25", "group": "all",
        "makeup": ["all:1-0-1", "all:1-0-1", "all:1-0-1", "all:1-0-1", "all:0-0-2"],
        "kind": ["switch", "switch", "switch", "stay", "switch"], "circuit": [0, 0, 1, 0, 0],
        "task_time_s": [100.0, 102.0, 90.0, 70.0, 80.0]})
    seen = seen_tasks([_record()])
    out = seen_switches(frame, seen)
    # one on circuit 0 staying and one switching to 0 make two on 0: the learners' 140 s against
    # the cell's mean 101 s, +39 s to each; switching to 1 leaves one on 0: 120 s against 90 s;
    # the stay and the make-up with two switchers are kept
    assert out["task_time_s"].tolist() == pytest.approx([139.0, 141.0, 120.0, 70.0, 80.0])
    assert frame["task_time_s"].tolist() == [100.0, 102.0, 90.0, 70.0, 80.0]  # the input is not changed


BREAKDOWN = ["experiment=breakdown", "scale=smoke", "executor.n_jobs=1", "trials=2", "baseline_trials=2",
             "static_trials=1"]


def test_the_api_reads_a_runs_own_learners(finished_run, tmp_path):
    from tavc_cli import api
    from tavc_cli.errors import TavcError

    folder = finished_run(*BREAKDOWN, name="breakdown")
    seen = api.seen_tasks(folder)
    records = [r for r in api.load(folder).records() if r.meta["controller"] == "tavc"]
    # every tavc delivery in the second half of its trial, and no other, counted once; never more
    # robots on circuit 0 than the team's six
    half = [(r.table("deliveries")["t_s"] >= r.start_s + 0.5 * (r.end_s - r.start_s)).sum() for r in records]
    assert seen["n"].sum() == sum(half) > 0
    assert seen["on_0"].between(0, 6).all() and set(seen["kind"]) <= {"stay", "switch"}
    with pytest.raises(TavcError, match="no trials of nobody to read"):
        api.seen_tasks(folder, controller="nobody")
    with pytest.raises(TavcError, match="not a turn-taking prediction's folder"):
        api.surrogate_seen_switches(tmp_path, folder, output_dir=tmp_path / "out")


def test_a_predictions_folder_naming_a_learner_from_outside_tavc_is_refused_not_run(tmp_path):
    """The diagnostic reads a prediction's folder as data: a learner its settings name (code the
    folder cannot vouch for, which would run with the folder's own executor settings) is one line,
    and nothing is run or written."""
    from tavc_cli import api, config
    from tavc_cli.errors import TavcError
    from tavc_cli.settings import to_yaml

    marker = tmp_path / "ran"
    (tmp_path / "mine.py").write_text(f"open({str(marker)!r}, 'w').close()\n"
                                      "class Mine:\n    def __init__(self, n_robots, n_circuits, rng):\n"
                                      "        pass\n    def choose(self, robot, state):\n        return 0\n"
                                      "    def learn(self, *args):\n        pass\n")
    theirs = config.settings(config.load_config([*BREAKDOWN, "learner=plugin", "learner.name=mine",
                                                 f"learner.target={tmp_path / 'mine.py'}:Mine",
                                                 "executor.confine=off"]))
    prediction = tmp_path / "prediction"
    (prediction / "learners").mkdir(parents=True)
    (prediction / "learners" / "config.yaml").write_text(to_yaml(theirs))
    marker.unlink(missing_ok=True)  # composing their settings here rehearsed the learner, unconfined as they say
    with pytest.raises(TavcError, match="learners are from outside tavc"):
        api.surrogate_seen_switches(prediction, tmp_path, output_dir=tmp_path / "out")
    assert not marker.exists() and not (tmp_path / "out").exists()
