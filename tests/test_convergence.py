"""Convergence measures (tavc_cli.analysis.convergence) and q_values thinning, on hand-made records."""

import math

import numpy as np
import pandas as pd
import pytest

from tavc_cli.analysis.convergence import (
    COLUMNS,
    alloc_halves,
    convergence_table,
    convergence_verdict,
    policy_changed_share,
    q_drift,
    td_error_rel,
)
from tavc_cli.analysis.qvalues import q_value_table
from tavc_cli.analysis.states import alive_at_end
from tests.records import greedy_snapshots, record

# --- Q drift -------------------------------------------------------------------------------------


def test_q_drift_is_the_median_over_live_robots_of_the_relative_change_over_the_last_quarter():
    # 100 s run: the last quarter is [75, 100]; snapshots every 25 s, the reference the one at 75 s.
    # robot 0: [[1, .5], [.5, 1]] until 75 s, then 10 % higher at 100 s: max |diff| = 0.1 (the 1s),
    #          max |Q_end| = 1.1 -> 0.1 / 1.1 = 0.090909
    # robot 1: never changes -> 0
    # robot 2: broken down at 50 s, its table doubles (drift 0.5) -> not counted
    # median over robots 0 and 1: (0.090909 + 0) / 2 = 0.045455
    base = np.array([[1.0, 0.5], [0.5, 1.0]])
    q = np.stack([np.stack([base, 2 * base, base]) for _ in range(5)])
    q[-1, 0] = 1.1 * base
    q[-1, 2] = 2 * base
    q[1, 0] = 0.2 * base  # a change before the quarter does not count
    rec = record(n_robots=3, breakdowns=[(50.0, 2)], q_t=[0, 25, 50, 75, 100], q=q)
    live = alive_at_end(rec)
    assert q_drift(rec, 75.0, live) == pytest.approx(0.5 * 0.1 / 1.1)
    assert q_drift(rec, 75.0, np.array([True, False, False])) == pytest.approx(0.1 / 1.1)
    table = convergence_table([rec], 20.0, 0.95)
    assert table.columns.tolist() == COLUMNS
    row = table.iloc[0]
    assert (row["t_from_s"], row["t_to_s"]) == (75.0, 100.0)
    assert row["q_drift"] == pytest.approx(0.5 * 0.1 / 1.1)
    # snapshot times are sums of ticks: one a hair after 75 s is still "at" 75 s
    rec.q_t = np.array([0, 25, 50, 75 + 1e-9, 100])
    assert q_drift(rec, 75.0, live) == pytest.approx(0.5 * 0.1 / 1.1)


def test_q_drift_without_a_snapshot_before_the_quarter_starts_from_the_first():
    # snapshots at 80 and 100 only: robot 0 goes from 1 to 1.25 -> 0.25 / 1.25 = 0.2
    q = np.ones((2, 1, 2, 2))
    q[1] *= 1.25
    rec = record(n_robots=1, q_t=[80.0, 100.0], q=q)
    assert q_drift(rec, 75.0, alive_at_end(rec)) == pytest.approx(0.2)


# --- greedy policies -----------------------------------------------------------------------------


def test_policy_changed_share_counts_flips_inside_the_quarter_only():
    # robots 0, 1, 2; snapshots 0, 25, 50, 75, 100; last quarter (75, 100]
    # robot 0 flips between 50 and 75 s (before the quarter: the change shows at 75 s, not in it)
    # robot 1 flips between 75 and 100 s (inside)
    # robot 2 flips inside too, but has broken down: not counted
    # -> 1 of the 2 live robots: 0.5
    snaps = [[(0, 1), (0, 1), (0, 1)]] * 3 + [[(1, 1), (0, 1), (0, 1)], [(1, 1), (1, 1), (1, 1)]]
    rec = record(n_robots=3, breakdowns=[(10.0, 2)], q_t=[0, 25, 50, 75, 100], q=greedy_snapshots(snaps))
    live = alive_at_end(rec)
    assert policy_changed_share(rec, 75.0, 100.0, live) == 0.5
    # the whole run from 0: both live robots changed
    assert policy_changed_share(rec, 0.0, 100.0, live) == 1.0
    # nobody alive: no share
    assert math.isnan(policy_changed_share(rec, 75.0, 100.0, np.zeros(3, dtype=bool)))


# --- TD error ------------------------------------------------------------------------------------


def test_td_error_of_one_delivery_by_hand():
    # robot 0: delivers circuit 0 at 30 s and chooses circuit 1 from state 0; delivers that at 60 s
    # (before the quarter, [75, 100]) and chooses circuit 0 from state 1; delivers it at 90 s (task
    # 30 s, reward 2). Its choice of circuit 0 at 0 s and at 90 s are not the one that started it.
    # Its table at the last snapshot by 90 s (80 s): Q = [[1.0, 0.5], [0.8, 0.2]].
    # delta = r + gamma max_a Q[0, a] - Q[1, 0] = 2 + 0.9 * 1.0 - 0.8 = 2.1
    # robot 1 broke down at 50 s: its delivery at 95 s and its table are left out.
    # mean |Q| of the live robots' last tables: robot 0's [[1, 2], [3, 4]] -> 2.5
    # td_error_rel = 2.1 / 2.5 = 0.84
    q = np.zeros((3, 2, 2, 2))
    q[1, 0] = [[1.0, 0.5], [0.8, 0.2]]
    q[2, 0] = [[1.0, 2.0], [3.0, 4.0]]
    q[2, 1] = 100.0
    rec = record(
        breakdowns=[(50.0, 1)],
        choices=[(0.0, 0, 0, 0), (30.0, 0, 0, 1), (60.0, 0, 1, 0), (90.0, 0, 0, 0), (65.0, 1, 0, 0)],
        deliveries=[{"t_s": 30.0, "robot": 0, "circuit": 0, "task_time_s": 30.0, "reward": 1.0},
                    {"t_s": 60.0, "robot": 0, "circuit": 1, "task_time_s": 30.0, "reward": 5.0},
                    {"t_s": 90.0, "robot": 0, "circuit": 0, "task_time_s": 30.0, "reward": 2.0},
                    {"t_s": 95.0, "robot": 1, "circuit": 0, "task_time_s": 30.0, "reward": 9.0}],
        q_t=[0.0, 80.0, 100.0], q=q)
    live = alive_at_end(rec)
    assert td_error_rel(rec, 75.0, 100.0, 0.9, live) == pytest.approx(2.1 / 2.5)
    assert convergence_table([rec], 20.0, 0.9).iloc[0]["td_error_rel"] == pytest.approx(0.84)
    # the delivery's choice is found by its start, 90 - 30 = 60 s, even a hair off it
    rec.tables["deliveries"]["task_time_s"][2] = 30.0 + 1e-9
    assert td_error_rel(rec, 75.0, 100.0, 0.9, live) == pytest.approx(0.84)
    # the last snapshot taken at 90 s instead, the delivery's own time: it is the delivery's table,
    # [[1, 2], [3, 4]]: 2 + 0.9 * 2 - 3 = 0.8
    rec.q_t = np.array([0.0, 80.0, 90.0])
    assert td_error_rel(rec, 75.0, 100.0, 0.9, live) == pytest.approx(0.8 / 2.5)
    # no delivery in the window: NaN
    assert math.isnan(td_error_rel(rec, 91.0, 94.0, 0.9, live))


# --- allocation halves ---------------------------------------------------------------------------


def test_allocation_halves_by_hand():
    # two robots, circuit 0 the high one; stable period [20, 100): halves [20, 60) and [60, 100)
    #   t=0  robot 0 reaches circuit 0 (robot 1 nowhere yet: no state until 30 s)
    #   t=30 robot 1 reaches circuit 1   -> 1:1
    #   t=50 robot 1 reaches circuit 0   -> 2:0
    #   t=80 robot 0 reaches circuit 1   -> 1:1
    # first half: 1 for 20 s (30-50), 2 for 10 s (50-60), 30 s defined: 40 / 30 = 1.3333
    # second half: 2 for 20 s (60-80), 1 for 20 s (80-100): 60 / 40 = 1.5; drift 0.16667
    arrivals = [(0.0, 0, 0), (30.0, 1, 1), (50.0, 1, 0), (80.0, 0, 1)]
    rec = record(arrivals=arrivals)
    assert alloc_halves(rec, 20.0) == pytest.approx((40 / 30, 1.5))
    # a heterogeneous team (analysed in the groups scheme) gets the same from the circuits states
    mixed = record(arrivals=arrivals, groups=["fast", "slow"], q_t=[0.0, 100.0], q=np.ones((2, 2, 2, 2)))
    row = convergence_table([mixed], 20.0, 0.95).iloc[0]
    assert (row["alloc_first_half"], row["alloc_second_half"]) == pytest.approx((40 / 30, 1.5))
    assert row["alloc_drift"] == pytest.approx(1.5 - 40 / 30)
    # no stable period, or no defined state in a half: NaN
    assert all(math.isnan(x) for x in alloc_halves(rec, 100.0))
    assert math.isnan(alloc_halves(record(arrivals=[(0.0, 0, 0)]), 20.0)[0])


def test_convergence_table_keeps_only_records_with_two_snapshots():
    one = record(q_t=[100.0], q=np.ones((1, 2, 2, 2)))
    none = record(controller="random")
    two = record(q_t=[0.0, 100.0], q=np.ones((2, 2, 2, 2)), trial=4)
    table = convergence_table([one, none, two], 20.0, 0.95)
    assert table["trial"].tolist() == [4]
    assert convergence_table([one, none], 20.0, 0.95).columns.tolist() == COLUMNS


# --- the verdict ---------------------------------------------------------------------------------


def _verdict_table(q_drift=(0.01, 0.02, 0.03), changed=(0.0, 0.0, 1 / 6), alloc=(0.1, -0.1, 0.2),
                   td=(0.01, 0.02, 0.03)):
    rows = {"controller": ["tavc"] * 3, "trial": [0, 1, 2], "q_drift": q_drift, "policy_changed_share": changed,
            "alloc_drift": alloc, "td_error_rel": td}
    table = pd.DataFrame(rows)
    # another controller's trials, far from converged, must not count
    other = pd.DataFrame({**{k: [v[0]] for k, v in rows.items()}, "controller": ["softmax"], "q_drift": [1.0],
                          "policy_changed_share": [1.0], "alloc_drift": [3.0]})
    return pd.concat([table, other], ignore_index=True)


def test_verdict_converged_by_hand():
    # median q_drift 0.02 < 0.05; mean changed share 1/18 = 0.0556 <= 0.10;
    # mean |alloc drift| (0.1 + 0.1 + 0.2) / 3 = 0.1333 < 0.25; mean TD 0.02
    v = convergence_verdict(_verdict_table())
    assert v["n_trials"] == 3 and v["converged"] and v["failed"] == []
    assert v["q_drift"] == pytest.approx(0.02) and v["policy_changed_share"] == pytest.approx(1 / 18)
    assert v["alloc_drift"] == pytest.approx(0.4 / 3) and v["td_error_rel"] == pytest.approx(0.02)


@pytest.mark.parametrize("changes, failed", [
    # median of 0.01, 0.06, 0.30 = 0.06, not below 0.05
    ({"q_drift": (0.01, 0.06, 0.30)}, ["q_drift"]),
    # mean of 0, 1/6, 1/6 = 0.111 > 0.10
    ({"changed": (0.0, 1 / 6, 1 / 6)}, ["policy_changed_share"]),
    # mean |.| of 0.3, -0.3, 0.2 = 0.2667, not below 0.25 (signs do not cancel)
    ({"alloc": (0.3, -0.3, 0.2)}, ["alloc_drift"]),
])
def test_verdict_each_criterion_failing_alone(changes, failed):
    v = convergence_verdict(_verdict_table(**changes))
    assert not v["converged"] and v["failed"] == failed


def test_verdict_nan_allocation_drift():
    # no defined state in any trial: the allocation criterion has nothing against it
    v = convergence_verdict(_verdict_table(alloc=(np.nan, np.nan, np.nan)))
    assert v["converged"] and math.isnan(v["alloc_drift"])
    # NaN in one trial only: the others' mean, (0.3 + 0.3) / 2 = 0.3, decides
    v = convergence_verdict(_verdict_table(alloc=(np.nan, 0.3, -0.3)))
    assert v["failed"] == ["alloc_drift"] and v["alloc_drift"] == pytest.approx(0.3)
    # a controller without trials fails on what it cannot show
    v = convergence_verdict(_verdict_table(), controller="nobody")
    assert v["n_trials"] == 0 and v["failed"] == ["q_drift", "policy_changed_share"]


# --- q_values.csv thinning -----------------------------------------------------------------------


def _snapshot_record(q_t):
    rng = np.random.default_rng(0)
    return record(q_t=q_t, q=rng.uniform(-1, 1, (len(q_t), 2, 2, 2)), trial=1)


def test_q_value_table_thinning_keeps_multiples_and_the_last_snapshot():
    # snapshots every 600 s (one a hair off its grid point) and a final one at 3700 s (the
    # trial's end); one per 1200 s: 0, 1200, 2400, 3600 and the final 3700
    q_t = [0.0, 600.0, 1200.0 + 1e-9, 1800.0, 2400.0, 3000.0, 3600.0, 3700.0]
    rec = _snapshot_record(q_t)
    table = q_value_table([rec], every_s=1200.0)
    assert sorted(set(table["t_s"])) == pytest.approx([0.0, 1200.0, 2400.0, 3600.0, 3700.0])
    assert len(table) == 5 * 2
    full = q_value_table([rec])
    kept = full[full["t_s"].isin(table["t_s"])].reset_index(drop=True)
    pd.testing.assert_frame_equal(table, kept)  # the same rows, values untouched


def test_q_value_table_unchanged_at_or_below_the_record_period():
    rec = _snapshot_record([0.0, 600.0, 1200.0, 1800.0, 2000.0])
    text = q_value_table([rec]).to_csv(index=False, float_format="%.6g")
    for every_s in (None, 600.0, 150.0, 600.0 + 1e-9):
        assert q_value_table([rec], every_s=every_s).to_csv(index=False, float_format="%.6g") == text
    # a record with a single snapshot has nothing to thin
    single = _snapshot_record([100.0])
    assert len(q_value_table([single], every_s=1200.0)) == 2
