"""How the group is made (tavc_cli.analysis.mechanism), on hand-made records."""

import math
from functools import partial

import numpy as np
import pandas as pd
import pytest

from tavc_cli.analysis.mechanism import (
    COLUMNS,
    kind_counts,
    mechanism_rows,
    mechanism_summary,
    mechanism_table,
    q_gap_stay_switch,
    regime,
    switch_share,
    task_kinds,
    task_means,
)
from tests.records import record

_record = partial(record, n_robots=3)  # three robots unless a test says otherwise


# --- stay and switch tasks -----------------------------------------------------------------------

# (t, robot, circuit, task time, avoid, wait), in time order as the record keeps them
TASKS = [(10.0, 0, 0, 10.0, 1.0, 0.0),   # robot 0's first: no kind
         (12.0, 1, 1, 12.0, 9.0, 9.0),   # robot 1's first: no kind
         (20.0, 0, 0, 10.0, 2.0, 1.0),   # stay (0 after 0)
         (30.0, 1, 0, 18.0, 5.0, 6.0),   # switch (0 after 1)
         (35.0, 0, 1, 15.0, 3.0, 4.0),   # switch (1 after 0)
         (45.0, 0, 1, 10.0, 0.0, 2.0)]   # stay (1 after 1)


def _task_record():
    return _record(deliveries=[{"t_s": t, "robot": r, "circuit": c, "task_time_s": s, "avoid_s": a, "wait_s": w}
                               for t, r, c, s, a, w in TASKS])


def test_tasks_are_stay_or_switch_by_the_robots_previous_delivery():
    assert task_kinds(_task_record()).tolist() == [-1, -1, 1, 0, 0, 1]


def test_task_means_by_kind_by_hand():
    rec = _task_record()
    # [0, 50): stay tasks at 20 and 45 s: task (10 + 10) / 2 = 10, avoid (2 + 0) / 2 = 1, wait (1 + 2) / 2 = 1.5;
    # switch tasks at 30 and 35 s: task (18 + 15) / 2 = 16.5, avoid (5 + 3) / 2 = 4, wait (6 + 4) / 2 = 5
    assert task_means(rec, 0.0, 50.0) == pytest.approx(
        {"task_s_stay": 10.0, "task_s_switch": 16.5, "avoid_s_stay": 1.0, "avoid_s_switch": 4.0,
         "wait_s_stay": 1.5, "wait_s_switch": 5.0})
    # [0, 25): one stay task (20 s), no switch task: NaN
    early = task_means(rec, 0.0, 25.0)
    assert early["task_s_stay"] == 10.0 and math.isnan(early["task_s_switch"]) and math.isnan(early["wait_s_switch"])
    # [30, 40): the switch tasks at 30 s (robot 1's, though its previous delivery, at 12 s, is
    # outside the window) and at 35 s: (18 + 15) / 2; no stay task
    mid = task_means(rec, 30.0, 40.0)
    assert mid["task_s_switch"] == pytest.approx(16.5) and math.isnan(mid["task_s_stay"])
    assert task_means(rec, 20.0, 45.0)["task_s_stay"] == 10.0  # 45 s left out: only the task at 20 s


# --- choices: switch share and robot kinds -------------------------------------------------------


def _kinds_record():
    """Three robots choosing once a second for 100 s; circuit 0 high until 50 s, then circuit 1.
    robot 0 always circuit 0; robot 1 always circuit 1; robot 2 alternates 0, 1, 0, ... until 49 s,
    then stays on circuit 1 (its state at 50 s is 1, its choice at 49 s)."""
    choices = []
    for t in range(100):
        choices.append((float(t), 0, 0, 0))
        choices.append((float(t), 1, 1, 1))
        if t < 50:
            choices.append((float(t), 2, 1 - t % 2, t % 2))
        else:
            choices.append((float(t), 2, 1, 1))
    return _record(choices=choices, value_changes=[(50.0, (1.0, 3.0))])


def test_robot_kinds_by_window_follow_the_values_in_force():
    rec = _kinds_record()
    # [0, 50): circuit 0 high (the change at 50 s comes after the half-open window):
    # robot 0 stays high, robot 1 low, robot 2 alternates
    assert kind_counts(rec, 0.0, 50.0) == {"n_stayers_high": 1, "n_stayers_low": 1, "n_alternators": 1,
                                           "n_mixed": 0, "n_idle": 0}
    # [50, 100): circuit 1 high: robots 1 and 2 stay high, robot 0 low
    assert kind_counts(rec, 50.0, 100.0) == {"n_stayers_high": 2, "n_stayers_low": 1, "n_alternators": 0,
                                             "n_mixed": 0, "n_idle": 0}
    # [40, 60): robot 2 chose circuit 1 at 15 of its 20 choices (share 0.75 < 0.9: no stayer) and
    # switched at 10 of them, 40-49 s (rate 0.5 >= 0.5): an alternator
    assert kind_counts(rec, 40.0, 60.0)["n_alternators"] == 1
    # nobody chose anything: all idle
    assert kind_counts(rec, 200.0, 300.0)["n_idle"] == 3


def test_switch_share_by_hand():
    rec = _kinds_record()
    # [0, 50): 150 choices, robot 2's 50 all switch -> 1/3; [50, 100): none switches
    assert switch_share(rec, 0.0, 50.0) == pytest.approx(1 / 3)
    assert switch_share(rec, 50.0, 100.0) == 0.0
    assert math.isnan(switch_share(rec, 200.0, 300.0))


def test_mechanism_rows_stable_then_eight_windows():
    rec = _kinds_record()
    rows = mechanism_rows(rec, 50.0)
    assert [r["window"] for r in rows] == ["stable", *(f"w{k}" for k in range(1, 9))]
    assert (rows[0]["t_from_s"], rows[0]["t_to_s"]) == (50.0, 100.0)
    assert [(r["t_from_s"], r["t_to_s"]) for r in rows[1:3]] == [(0.0, 12.5), (12.5, 25.0)]
    assert rows[-1]["t_to_s"] == 100.0
    # stable: as [50, 100) above; w1 [0, 12.5): robot 2 alternating, circuit 0 high
    assert (rows[0]["n_stayers_high"], rows[0]["n_stayers_low"], rows[0]["n_alternators"]) == (2, 1, 0)
    assert (rows[1]["n_stayers_high"], rows[1]["n_stayers_low"], rows[1]["n_alternators"]) == (1, 1, 1)
    # no deliveries: no task means; no Q-tables: no gap
    assert math.isnan(rows[0]["task_s_stay"]) and math.isnan(rows[0]["q_gap_stay_switch"])
    table = mechanism_table([rec, _record(controller="random", trial=1)], 50.0)
    assert table.columns.tolist() == COLUMNS and len(table) == 18
    # a record without a choices table has no rows
    del rec.tables["choices"]
    assert len(mechanism_table([rec], 50.0)) == 0


# --- Q gap between staying and switching ---------------------------------------------------------


def test_q_gap_stay_switch_by_hand():
    # two circuits, snapshot at 50 s; robot 2 broke down (left out)
    # robot 0 [[3, 1], [1, 3]]: state 0: 3 - 1 = 2, state 1: 3 - 1 = 2
    # robot 1 [[1, 2], [0, 4]]: state 0: 1 - 2 = -1, state 1: 4 - 0 = 4
    # mean over robots and states: (2 + 2 - 1 + 4) / 4 = 1.75
    q = np.zeros((2, 3, 2, 2))
    q[0, 0] = [[3, 1], [1, 3]]
    q[0, 1] = [[1, 2], [0, 4]]
    q[0, 2] = [[100, 0], [0, 100]]
    q[1] = -5.0  # the snapshot at 100 s, after the window's end
    rec = _record(breakdowns=[(20.0, 2)], q_t=[50.0, 100.0], q=q)
    assert q_gap_stay_switch(rec, 60.0) == pytest.approx(1.75)
    assert q_gap_stay_switch(rec, 100.0) == pytest.approx(0.0)  # -5 everywhere
    assert math.isnan(q_gap_stay_switch(rec, 40.0))  # no snapshot by then
    # three circuits: Q[s, s] minus the mean of the other two
    # [[3, 1, 2], [0, 0, 0], [1, 1, 1]]: 3 - 1.5 = 1.5, 0 - 0 = 0, 1 - 1 = 0 -> 0.5
    q3 = np.array([[[[3, 1, 2], [0, 0, 0], [1, 1, 1]]]], dtype=float)
    rec3 = _record(n_robots=1, values=(3.0, 2.0, 1.0), q_t=[10.0], q=q3)
    assert q_gap_stay_switch(rec3, 10.0) == pytest.approx(0.5)
    # a behaviour learner's tables (32 states, 3 behaviours) are not circuit by circuit
    beh = _record(n_robots=1, q_t=[10.0], q=np.ones((1, 1, 32, 3)))
    assert math.isnan(q_gap_stay_switch(beh, 10.0))


# --- the regime ----------------------------------------------------------------------------------


def test_regime_rule():
    # 6 working robots: 3 stayers is half -> persistence; 2 stayers and 3 alternators -> turn-taking;
    # 2 stayers, 2 alternators, 2 mixed -> mixed
    assert regime(3.0, 0.0, 6.0) == "persistence"
    assert regime(2.0, 3.0, 6.0) == "turn-taking"
    assert regime(2.0, 2.0, 6.0) == "mixed"
    assert regime(0.0, 0.0, 0.0) == "undefined"


def test_mechanism_summary_over_stable_rows():
    base = {c: 0.0 for c in COLUMNS[5:]}
    rows = [
        # two tavc trials: stayers (2 + 1) + (1 + 1) = 5 -> 2.5 per trial; alternators 1 and 2 -> 1.5;
        # mixed 1 and 0 -> 0.5; working 2.5 + 1.5 + 0.5 = 4.5, half 2.25 <= 2.5 stayers: persistence
        {**base, "controller": "tavc", "trial": 0, "window": "stable", "n_stayers_high": 2, "n_stayers_low": 1,
         "n_alternators": 1, "n_mixed": 1, "n_idle": 1, "switch_share": 0.2, "task_s_stay": 100.0,
         "task_s_switch": 150.0, "q_gap_stay_switch": 0.5},
        {**base, "controller": "tavc", "trial": 1, "window": "stable", "n_stayers_high": 1, "n_stayers_low": 1,
         "n_alternators": 2, "n_mixed": 0, "n_idle": 0, "switch_share": 0.4, "task_s_stay": np.nan,
         "task_s_switch": 130.0, "q_gap_stay_switch": 1.5},
        # windows over time and other controllers do not count
        {**base, "controller": "tavc", "trial": 0, "window": "w1", "n_alternators": 6},
        {**base, "controller": "random", "trial": 0, "window": "stable", "n_alternators": 6},
    ]
    table = pd.DataFrame(rows, columns=COLUMNS)
    s = mechanism_summary(table)
    assert s["n_trials"] == 2 and s["regime"] == "persistence"
    assert (s["n_stayers_high"], s["n_stayers_low"], s["n_alternators"], s["n_mixed"], s["n_idle"]) == (
        1.5, 1.0, 1.5, 0.5, 0.5)
    # means over trials; a NaN (no stay task) is left out
    assert s["switch_share"] == pytest.approx(0.3) and s["task_s_stay"] == 100.0
    assert s["task_s_switch"] == 140.0 and s["q_gap_stay_switch"] == 1.0
    assert mechanism_summary(table, controller="random")["regime"] == "turn-taking"
