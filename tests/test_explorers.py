"""Switching tasks measured from robots that stay and explore (`surrogate.switches=explorers`)."""

from __future__ import annotations

import json

import numpy as np
import pandas as pd
import pytest

from tavc_cli import config
from tavc_cli.errors import TavcError
from tavc_cli.experiments.build import trial_specs
from tavc_cli.experiments.records import TrialRecord
from tavc_cli.report.tally import switches_line, switches_of
from tavc_cli.surrogate import run
from tavc_cli.surrogate.engine import SurrogateTrial
from tavc_cli.surrogate.explorers import (
    ExplorerPolicy,
    choice_makeups,
    explorer_specs,
    one_switcher,
    stayers_makeups,
    with_explorers,
)
from tavc_cli.surrogate.run import measure_tasks
from tavc_cli.surrogate.tasks import COLUMNS, STAY, SWITCH, TaskTimes, Team, makeup_name, makeups
from tavc_cli.vocabulary import ACTIVITIES

TEAM3 = Team.of(["all"] * 3, [0.25] * 3)


def test_an_explorer_goes_home_but_at_epsilon_draws_a_circuit():
    never = ExplorerPolicy(3, 2, np.random.default_rng(1), homes=[0, 1, 1], epsilon=0.0)
    assert [never.choose(i, s) for i in range(3) for s in (0, 1)] == [0, 0, 1, 1, 1, 1]
    # epsilon 0.5 over two circuits: home with 0.5 + 0.5 / 2 = 0.75, from either state
    half = ExplorerPolicy(1, 2, np.random.default_rng(2), homes=[1], epsilon=0.5)
    home = np.mean([half.choose(0, k % 2) == 1 for k in range(20000)])
    assert home == pytest.approx(0.75, abs=0.01)  # 0.003 is one standard error


def _record():
    """Three robots homed 0, 0, 1. At 0 s all choose home (robot 2 switching in from circuit 0);
    robot 2 explores to circuit 0 at 100 s and comes back at 190 s; robot 0 stays at 120 s."""
    choices = [(0.0, 0, 0, 0), (0.0, 1, 0, 0), (0.0, 2, 0, 1), (100.0, 2, 1, 0), (120.0, 0, 0, 0),
               (190.0, 2, 0, 1)]
    deliveries = [(100.0, 2, 1, 100.0), (120.0, 0, 0, 120.0), (190.0, 2, 0, 90.0), (250.0, 0, 0, 130.0),
                  (280.0, 2, 1, 90.0)]
    col = lambda rows, k, t: np.array([r[k] for r in rows], dtype=t)  # noqa: E731
    tables = {"choices": {"t_s": col(choices, 0, float), "robot": col(choices, 1, int),
                          "state": col(choices, 2, int), "circuit": col(choices, 3, int)},
              "deliveries": {"t_s": col(deliveries, 0, float), "robot": col(deliveries, 1, int),
                             "circuit": col(deliveries, 2, int), "task_time_s": col(deliveries, 3, float)}}
    return TrialRecord(meta={"n_robots": 3, "groups": ["all"] * 3, "duration_s": 300.0, "warmup_s": 0.0},
                       tables=tables)


def test_each_task_takes_the_make_up_at_its_choice():
    makeup, kind = choice_makeups(_record(), TEAM3)
    # deliveries in the record's order: robot 2's first task (chosen at 0 s: two stay on 0, robot 2
    # switches in to 1), robot 0's first (chosen at 0 s), robot 2's excursion (chosen at 100 s: two
    # on 0, robot 2 switching to 0), robot 0's second (chosen at 120 s, robot 2 still away), robot
    # 2's return (chosen at 190 s: switching back to 1)
    assert makeup.tolist() == ["all:2-0-1", "all:2-0-1", "all:2-0-1", "all:2-0-1", "all:2-0-1"]
    assert kind.tolist() == ["switch", "stay", "switch", "stay", "switch"]
    # robot 2 counts as switching until its next choice: robot 0's choice at 250 s still sees 2-0-1;
    # robot 2's own choice to stay, at 280 s, and robot 0's at 380 s see 2-1-0 (deliveries appended
    # in that order: robot 0's at 380 s, robot 2's at 370 s, robot 0's at 500 s)
    rec = _record()
    for t, robot, state, circuit, done, took in ((250.0, 0, 0, 0, 380.0, 130.0), (280.0, 2, 1, 1, 370.0, 90.0),
                                                 (380.0, 0, 0, 0, 500.0, 120.0)):
        for k, v in {"t_s": t, "robot": robot, "state": state, "circuit": circuit}.items():
            rec.tables["choices"][k] = np.append(rec.tables["choices"][k], v)
        for k, v in {"t_s": done, "robot": robot, "circuit": circuit, "task_time_s": took}.items():
            rec.tables["deliveries"][k] = np.append(rec.tables["deliveries"][k], v)
    makeup, kind = choice_makeups(rec, TEAM3)
    assert makeup[-3:].tolist() == ["all:2-0-1", "all:2-1-0", "all:2-1-0"]
    assert kind[-3:].tolist() == ["stay", "stay", "stay"]


def test_the_make_ups_are_those_the_surrogate_draws_from_ties_included():
    """A surrogate trial of three learners exploring half the time on tasks of one length, so that
    robots deliver at the same tick again and again: each delivered task's make-up and kind, as
    `choice_makeups` reads them from the record, are those the engine drew it from."""
    cfg = config.settings(config.load_config([
        "experiment=initial_distribution", "team.n_robots=3", "learner=tavc_egreedy", "learner.epsilon=0.5",
        "baselines=[]", "trials=1", "duration_s=3000", "convergence_s=100", "sim.warmup_s=0",
        "sim.q_snapshot_every_s=0", "scale=paper"]))
    spec = trial_specs(cfg)[0]
    rows = [{"team": TEAM3.name, "makeup": makeup_name(TEAM3, m), "group": "all", "kind": kind, "circuit": c,
             "task_time_s": 100.0, "source_s": 50.0, **{f"{a}_s": 0.0 for a in ACTIVITIES}}
            for m in makeups(TEAM3) for kind in (STAY, SWITCH) for c in (0, 1)]
    drawn: dict[int, list] = {}

    class Spy(SurrogateTrial):
        def draw(self, i: int, tick: int) -> None:
            drawn.setdefault(i, []).append((self.makeup()[1], SWITCH if self.switching[i] else STAY))
            super().draw(i, tick)

    record = Spy(spec, TaskTimes(pd.DataFrame(rows, columns=list(COLUMNS)))).run()
    makeup, kind = choice_makeups(record, TEAM3)
    d = record.table("deliveries")
    ties = len(d["t_s"]) - len(np.unique(d["t_s"]))
    assert ties > 20  # many robots deliver at one tick
    for robot, seen in drawn.items():
        mine = np.flatnonzero(d["robot"] == robot)
        mine = mine[np.argsort(d["t_s"][mine], kind="stable")]
        assert list(zip(makeup[mine], kind[mine], strict=True)) == seen[:len(mine)]
    assert {k for _, k in drawn[0]} == {STAY, SWITCH}


def _cells(makeup: str, kind: str, circuit: int, times: list[float]) -> pd.DataFrame:
    return pd.DataFrame([{"team": TEAM3.name, "makeup": makeup, "group": "all", "kind": kind, "circuit": circuit,
                          "task_time_s": t, "source_s": t / 2, **{f"{a}_s": 0.0 for a in ACTIVITIES}}
                         for t in times], columns=list(COLUMNS))


def test_only_well_filled_cells_of_one_switcher_make_ups_are_taken():
    alternating = pd.concat([_cells("all:2-0-1", "switch", 0, [80.0, 81.0]), _cells("all:2-0-1", "stay", 0, [76.0]),
                             _cells("all:1-0-2", "switch", 0, [70.0]), _cells("all:3-0-0", "stay", 0, [77.0])])
    exploring = pd.concat([_cells("all:2-0-1", "switch", 0, [85.0] * 3),   # three tasks: taken
                           _cells("all:2-0-1", "stay", 0, [90.0] * 2),     # two: too few, kept
                           _cells("all:1-0-2", "switch", 0, [60.0] * 5),   # two switchers: never taken
                           _cells("all:3-0-0", "stay", 0, [99.0] * 5),     # no switcher: never taken
                           _cells("all:2-0-1", "switch", 1, [72.0] * 4)])  # a cell only the explorers filled
    out = with_explorers(alternating, exploring, min_tasks=3)
    got = out.groupby(["makeup", "kind", "circuit"])["task_time_s"].agg(list).to_dict()
    assert got == {("all:2-0-1", "switch", 0): [85.0] * 3, ("all:2-0-1", "stay", 0): [76.0],
                   ("all:1-0-2", "switch", 0): [70.0], ("all:3-0-0", "stay", 0): [77.0],
                   ("all:2-0-1", "switch", 1): [72.0] * 4}
    assert list(out.columns) == list(COLUMNS)
    assert with_explorers(alternating, exploring, min_tasks=6).equals(alternating.reset_index(drop=True))
    # explorers that completed no task leave the alternators' table as it is
    assert with_explorers(alternating, exploring.iloc[:0], min_tasks=1).equals(alternating.reset_index(drop=True))
    assert one_switcher("fast:1-0-1 slow:2-0-0") and not one_switcher("fast:1-0-1 slow:1-0-1")


def _cfg(*overrides: str):
    return config.settings(config.load_config(["experiment=initial_distribution", "scale=smoke", "team.n_robots=3",
                                               *overrides]))


def test_explorers_are_homed_on_every_allocation_of_stayers_with_the_learners_epsilon():
    cfg = _cfg("surrogate.switches=explorers", "surrogate.explore_trials=3", "learner.epsilon=0.2")
    specs = explorer_specs(cfg, [TEAM3])
    assert [m for _, m in specs] == stayers_makeups(TEAM3) == [((0, 3, 0),), ((1, 2, 0),), ((2, 1, 0),), ((3, 0, 0),)]
    first = specs[(TEAM3.name, ((2, 1, 0),))]
    assert len(first) == 2 and len({s.seed for s in first}) == 2  # 3 capped by the smoke scale's 2 trials
    assert first[0].policy.params == {"homes": [0, 0, 1], "epsilon": 0.2}
    assert first[0].controller == "explore_all-2-1-0_n3" and first[0].policy.target.endswith(".ExplorerPolicy")


def test_bad_explorer_settings_are_one_line():
    with pytest.raises(TavcError, match="surrogate.switches"):
        _cfg("surrogate.switches=sometimes")
    with pytest.raises(TavcError, match="surrogate.explore_epsilon"):
        _cfg("surrogate.switches=explorers", "surrogate.explore_epsilon=1.5")
    with pytest.raises(TavcError, match="surrogate.calibration=stayers never draws"):
        _cfg("surrogate.switches=explorers", "surrogate.calibration=stayers")
    softmax = _cfg("surrogate.switches=explorers", "learner=tavc_softmax")
    with pytest.raises(TavcError, match="explores by no epsilon"):
        explorer_specs(softmax, [TEAM3])


def test_the_explorers_change_only_one_switcher_make_ups_and_are_recorded(tmp_path):
    def measure(switches: str):
        said: list[str] = []
        cfg = _cfg(f"surrogate.tasks_dir={tmp_path / switches}", f"surrogate.switches={switches}",
                   "surrogate.explore_epsilon=1", "surrogate.explore_min_tasks=1", "executor.n_jobs=1")
        return cfg, measure_tasks(cfg, echo=said.append).frame, said

    _, alternating, _ = measure("alternators")
    cfg, exploring, said = measure("explorers")
    assert len(said) == 1 and "and 4 allocations of stayers with explorers, 2 trials each" in said[0]

    record = json.loads((tmp_path / "explorers" / "task_times.json").read_text())["measurement"]
    assert record["switches"] == "explorers" and record["explore_epsilon"] == 1.0 and record["explore_min_tasks"] == 1
    assert "switches" not in json.loads((tmp_path / "alternators" / "task_times.json").read_text())["measurement"]
    one = exploring["makeup"].map(one_switcher)
    # make-ups without exactly one switcher keep the alternators' tasks, row for row
    pd.testing.assert_frame_equal(exploring[~one].reset_index(drop=True),
                                  alternating[~alternating["makeup"].map(one_switcher)].reset_index(drop=True))
    assert not exploring[one].reset_index(drop=True).equals(
        alternating[alternating["makeup"].map(one_switcher)].reset_index(drop=True))
    # a table of either kind is refused, in one line, to a request for the other
    with pytest.raises(TavcError, match="measurement.switches: explorers -> alternators"):
        measure_tasks(_cfg(f"surrogate.tasks_dir={tmp_path / 'explorers'}"), echo=print)
    with pytest.raises(TavcError, match="measurement.switches: alternators -> explorers"):
        measure_tasks(_cfg(f"surrogate.tasks_dir={tmp_path / 'alternators'}", "surrogate.switches=explorers",
                           "surrogate.explore_epsilon=1", "surrogate.explore_min_tasks=1"), echo=print)


def test_an_explorers_table_of_other_code_is_measured_again(tmp_path, monkeypatch):
    cfg = _cfg(f"surrogate.tasks_dir={tmp_path}", "surrogate.switches=explorers", "surrogate.explore_epsilon=1",
               "surrogate.explore_min_tasks=1", "executor.n_jobs=1")
    said: list[str] = []
    measure_tasks(cfg, echo=said.append)
    assert json.loads((tmp_path / "task_times.json").read_text())["explorers_code"] == run.explorers_code()
    again: list[str] = []
    measure_tasks(cfg, echo=again.append)
    assert again == []
    monkeypatch.setattr(run, "explorers_code", lambda: "0" * 16)
    measure_tasks(cfg, echo=again.append)
    assert again[0].startswith("note:") and "another explorers_code" in again[0] and "measuring" in again[1]


def test_predictions_with_explorers_are_tallied_apart_beside_the_model_as_it_is():
    """A prediction names its way of measuring a lone switcher in `turn_taking.json` (none
    recorded: alternators). The explorers' tally counts their converged runs and, at those same
    runs, the model as it is. By hand: runs a, b converged, c not; the explorers hit a (modal
    state and regime) and b (regime); the model as it is hits b's modal state and b's regime."""
    assert switches_of({"overrides": ["surrogate.switches=explorers"]}) == "alternators"
    assert switches_of({"switches": "explorers"}) == "explorers"
    main = [{"check": True, "run": "a", "modal": False, "regime": False},
            {"check": True, "run": "b", "modal": True, "regime": True},
            {"check": False, "run": "c", "modal": True, "regime": True}]
    explored = [{"check": True, "run": "a", "modal": True, "regime": True},
                {"check": True, "run": "b", "modal": False, "regime": True},
                {"check": False, "run": "c", "modal": True, "regime": True}]
    line = switches_line(explored, main)[-1]
    assert line.endswith("where the learners converged (2 runs): the turn-taking model names their modal state in "
                         "1 of 2 and their regime in 2; the model as it is, at 2 of the same runs, their modal state "
                         "in 1 and their regime in 1.")
    assert switches_line([], main) == []
    assert switches_line(explored[2:], main)[-1].endswith("no run beside them converged (1 in all).")
