"""Group states and performance (tavc_cli.analysis) on hand-made trial records."""

import math

import numpy as np
import pytest

from tavc_cli.analysis.performance import performance_table, value_rate, value_rate_series
from tavc_cli.analysis.states import (
    all_states,
    state_intervals,
    state_time_table,
    theory_pct,
    time_shares,
)
from tavc_cli.experiments.records import TrialRecord
from tests.records import greedy_snapshots


def _record(
    arrivals=(),
    breakdowns=(),
    value_changes=(),
    deliveries=(),
    *,
    n_robots=3,
    values=(2.0, 1.0),
    groups=("fast", "slow", "fast"),
    speeds=(0.3, 0.2, 0.3),
    duration_s=100.0,
    warmup_s=0.0,
    controller="tavc",
    t0_s=None,
):
    """A TrialRecord from rows: arrivals (t, robot, circuit), breakdowns (t, robot),
    value changes (t, values), deliveries (t, score)."""
    arrivals = list(arrivals)
    tables = {
        "arrivals": {
            "t_s": np.array([a[0] for a in arrivals], dtype=float),
            "robot": np.array([a[1] for a in arrivals], dtype=np.int64),
            "target": np.zeros(len(arrivals), dtype=np.int64),
            "circuit": np.array([a[2] for a in arrivals], dtype=np.int64),
            "kind": np.zeros(len(arrivals), dtype=np.int64),
        },
        "breakdowns": {
            "t_s": np.array([b[0] for b in breakdowns], dtype=float),
            "robot": np.array([b[1] for b in breakdowns], dtype=np.int64),
        },
        "deliveries": {
            "t_s": np.array([d[0] for d in deliveries], dtype=float),
            "score": np.array([d[1] for d in deliveries], dtype=float),
        },
    }
    rec = TrialRecord(
        meta={
            "n_robots": n_robots,
            "n_circuits": len(values),
            "groups": list(groups),
            "speeds_mps": list(speeds),
            "values": list(values),
            "duration_s": duration_s,
            "warmup_s": warmup_s,
            "controller": controller,
            **({} if t0_s is None else {"t0_s": t0_s}),
        },
        tables=tables,
    )
    rec.value_changes_t = np.array([v[0] for v in value_changes], dtype=float)
    rec.value_changes = np.array([v[1] for v in value_changes], dtype=float).reshape(
        len(value_changes), len(values)
    )
    return rec


def _merged(intervals):
    """Join neighbouring pieces with the same state (the split points carry no meaning)."""
    out = []
    for a, b, s in intervals:
        if out and out[-1][2] == s and out[-1][1] == a:
            out[-1] = (out[-1][0], b, s)
        else:
            out.append((a, b, s))
    return out


# Three robots (0 fast, 1 slow, 2 fast), two circuits, circuit 0 worth more at first.
#   t=10 robot 0 reaches circuit 0          -> robots 1, 2 have no target yet: no state
#   t=20 robot 1 reaches circuit 1
#   t=30 robot 2 reaches circuit 0          -> high:low = 2:1
#   t=50 robot 1 reaches circuit 0          -> 3:0
#   t=60 robot 2 breaks down                -> two robots left, both on circuit 0: 2:0
#   t=80 values swap, circuit 1 now "high"  -> 0 on high, 2 on low: 0:2
#   t=100 end
STORY = {
    "arrivals": [(10.0, 0, 0), (20.0, 1, 1), (30.0, 2, 0), (50.0, 1, 0)],
    "breakdowns": [(60.0, 2)],
    "value_changes": [(80.0, (1.0, 3.0))],
}


@pytest.fixture
def story():
    return _record(**STORY)


def test_state_intervals_follow_the_story(story):
    assert _merged(state_intervals(story)) == [
        (0.0, 30.0, None),
        (30.0, 50.0, "2:1"),
        (50.0, 60.0, "3:0"),
        (60.0, 80.0, "2:0"),
        (80.0, 100.0, "0:2"),
    ]


def test_state_intervals_in_group_notation(story):
    # "fast:slow" robots whose last target was on the high-value circuit
    #   t=30: fast 0, 2 on circuit 0 (high), slow 1 on circuit 1     -> 2:0
    #   t=50: slow 1 joins circuit 0                                 -> 2:1
    #   t=60: fast 2 broken                                          -> 1:1
    #   t=80: circuit 1 becomes high, nobody there                   -> 0:0
    assert _merged(state_intervals(story, "groups")) == [
        (0.0, 30.0, None),
        (30.0, 50.0, "2:0"),
        (50.0, 60.0, "2:1"),
        (60.0, 80.0, "1:1"),
        (80.0, 100.0, "0:0"),
    ]


def test_time_shares_leave_out_undefined_time(story):
    # defined from 30 to 100 s = 70 s: 2:1 for 20 s, 3:0 for 10, 2:0 for 20, 0:2 for 20
    shares = time_shares(story, 0.0, 100.0)
    assert shares == pytest.approx(
        {"2:1": 100 * 20 / 70, "3:0": 100 * 10 / 70, "2:0": 100 * 20 / 70, "0:2": 100 * 20 / 70}
    )
    assert shares["2:1"] == pytest.approx(28.5714, abs=1e-4)


def test_time_shares_within_a_window(story):
    # [40, 90]: 2:1 40-50 (10 s), 3:0 50-60 (10), 2:0 60-80 (20), 0:2 80-90 (10); 50 s in all
    assert time_shares(story, 40.0, 90.0) == pytest.approx(
        {"2:1": 20.0, "3:0": 20.0, "2:0": 40.0, "0:2": 20.0}
    )
    # a window with no defined time has no shares
    assert time_shares(story, 0.0, 25.0) == {}


def test_simultaneous_events_apply_breakdown_first():
    # at t=20 robot 1 breaks down and robot 0 arrives: the state right away counts robot 0 only
    rec = _record(
        arrivals=[(10.0, 0, 1), (10.0, 1, 0), (20.0, 0, 0)],
        breakdowns=[(20.0, 1)],
        n_robots=2,
        groups=("all", "all"),
        speeds=(0.25, 0.25),
        duration_s=40.0,
    )
    assert _merged(state_intervals(rec)) == [
        (0.0, 10.0, None),
        (10.0, 20.0, "1:1"),
        (20.0, 40.0, "1:0"),
    ]


def test_warmup_time_is_covered_from_its_negative_start():
    rec = _record(
        arrivals=[(-50.0, 0, 0), (-40.0, 1, 1), (-30.0, 2, 1)], warmup_s=100.0, duration_s=50.0
    )
    assert _merged(state_intervals(rec)) == [(-100.0, -30.0, None), (-30.0, 50.0, "1:2")]
    assert time_shares(rec, 0.0, 50.0) == pytest.approx({"1:2": 100.0})


# --- theory --------------------------------------------------------------------------------------


def test_theory_circuits_is_binomial_for_two_circuits():
    # 6 robots, each on either circuit with p = 1/2: P(n on high) = C(6, n) / 2^6 = C(6, n) / 64
    # C(6, n) = 1, 6, 15, 20, 15, 6, 1 -> 1.5625, 9.375, 23.4375, 31.25, 23.4375, 9.375, 1.5625 %
    th = theory_pct(6, 2, "circuits")
    assert list(th) == ["0:6", "1:5", "2:4", "3:3", "4:2", "5:1", "6:0"]
    np.testing.assert_allclose(
        list(th.values()), [1.5625, 9.375, 23.4375, 31.25, 23.4375, 9.375, 1.5625]
    )


def test_theory_circuits_is_multinomial_for_three():
    # 3 robots on 3 circuits: 3^3 = 27 outcomes; 1:1:1 in 3! = 6 ways, 3:0:0 in 1, 2:1:0 in 3
    th = theory_pct(3, 3, "circuits")
    assert len(th) == 10
    assert th["1:1:1"] == pytest.approx(100 * 6 / 27)
    assert th["3:0:0"] == pytest.approx(100 / 27)
    assert th["2:1:0"] == pytest.approx(100 * 3 / 27)
    assert sum(th.values()) == pytest.approx(100.0)


def test_theory_groups_is_a_product_of_binomials():
    # 3 fast and 3 slow, each on the high circuit with p = 1/2: P(f:s) = C(3,f) C(3,s) / 64
    th = theory_pct(6, 2, "groups", (3, 3))
    assert len(th) == 16
    c3 = [1, 3, 3, 1]
    for f in range(4):
        for s in range(4):
            assert th[f"{f}:{s}"] == pytest.approx(100 * c3[f] * c3[s] / 64)
    assert th["1:2"] == pytest.approx(14.0625)  # 3 * 3 / 64
    assert sum(th.values()) == pytest.approx(100.0)


def test_all_states_in_the_chapters_order():
    assert all_states(3, 2, "circuits") == ["0:3", "1:2", "2:1", "3:0"]
    assert all_states(3, 2, "groups", (2, 1)) == ["0:0", "0:1", "1:0", "1:1", "2:0", "2:1"]


# --- tables over trials --------------------------------------------------------------------------


def _two_state_record(first_state_robots_on_high, switch_t, controller="tavc"):
    """3 robots defined from t=0: `first` robots on circuit 0 until switch_t, then 2 of them."""
    k = first_state_robots_on_high
    arrivals = [(0.0, i, 0 if i < k else 1) for i in range(3)]
    arrivals += [(switch_t, i, 0 if i < 2 else 1) for i in range(3)]
    return _record(
        arrivals=arrivals, groups=("all",) * 3, speeds=(0.25,) * 3, controller=controller
    )


def test_state_time_table_mean_and_std_by_hand():
    # record A: 3:0 for 75 s, then 2:1 for 25 s; record B: 1:2 for 25 s, then 2:1 for 75 s
    a = _two_state_record(3, 75.0)
    b = _two_state_record(1, 25.0)
    table = state_time_table([a, b], 0.0, 100.0)
    tavc = table[table.controller == "tavc"].set_index("state")
    assert list(tavc.index) == ["0:3", "1:2", "2:1", "3:0"]
    # 2:1: A 25 %, B 75 % -> mean 50, sample std sqrt(((25-50)^2 + (75-50)^2) / 1) = 35.3553
    # 3:0: A 75, B 0 -> mean 37.5, std 75 / sqrt(2) = 53.0330
    # 1:2: A 0, B 25 -> mean 12.5, std 25 / sqrt(2) = 17.6777; 0:3 never: 0, 0
    np.testing.assert_allclose(tavc["mean_pct"], [0.0, 12.5, 50.0, 37.5])
    np.testing.assert_allclose(tavc["std_pct"], [0.0, 17.6777, 35.3553, 53.0330], atol=1e-4)
    assert set(tavc["n_trials"]) == {2}
    # theory rows for 3 robots: C(3, n) / 8 = 12.5, 37.5, 37.5, 12.5 %
    theory = table[table.controller == "theory"].set_index("state")
    np.testing.assert_allclose(
        theory.loc[["0:3", "1:2", "2:1", "3:0"], "mean_pct"], [12.5, 37.5, 37.5, 12.5]
    )
    assert list(table.columns) == ["state", "controller", "mean_pct", "std_pct", "n_trials"]


def test_state_time_table_keeps_controllers_apart():
    table = state_time_table(
        [_two_state_record(3, 75.0), _two_state_record(1, 25.0, controller="random")],
        0.0,
        100.0,
        with_theory=False,
    )
    assert set(table.controller) == {"tavc", "random"}
    one = table[(table.controller == "random") & (table.state == "2:1")].iloc[0]
    assert (one.mean_pct, one.n_trials) == (75.0, 1) and math.isnan(one.std_pct)  # one trial: no spread


def test_state_time_table_after_a_breakdown_lists_the_smaller_teams_states():
    # the story ends with 2 robots working: states of 2 robots, 3-robot states as extras
    rec = _record(**STORY)
    table = state_time_table([rec], 0.0, 100.0)
    states = list(table[table.controller == "tavc"].state)
    assert states[:3] == ["0:2", "1:1", "2:0"]
    assert set(states[3:]) == {"2:1", "3:0"}
    theory = table[table.controller == "theory"]
    np.testing.assert_allclose(theory.mean_pct, [25.0, 50.0, 25.0])  # C(2, n) / 4


# --- performance ---------------------------------------------------------------------------------


def test_performance_table_bins_by_hand():
    # bins [0, 50) and [50, 100]; value per second = summed score / 50 s
    a = _record(
        deliveries=[(10.0, 10.0), (40.0, 1.0), (60.0, 10.0)]
    )  # 11 / 50 = 0.22, 10 / 50 = 0.2
    b = _record(deliveries=[(49.9, 10.0), (99.0, 1.0)])  # 10 / 50 = 0.2, 1 / 50 = 0.02
    table = performance_table([a, b], 50.0, 0.0, 100.0)
    assert list(table.columns) == ["t_s", "controller", "mean", "std", "n_trials"]
    np.testing.assert_allclose(table.t_s, [25.0, 75.0])
    # means (0.22 + 0.2) / 2 = 0.21 and (0.2 + 0.02) / 2 = 0.11;
    # sample std |x1 - x2| / sqrt(2): 0.02 / sqrt(2) = 0.0141421, 0.18 / sqrt(2) = 0.1272792
    np.testing.assert_allclose(table["mean"], [0.21, 0.11])
    np.testing.assert_allclose(table["std"], [0.02 / math.sqrt(2), 0.18 / math.sqrt(2)])
    assert set(table.n_trials) == {2}


def test_performance_counts_a_trailing_partial_bin():
    # 100 s in 30 s bins: [0, 30), [30, 60), [60, 90), and the 10 s left over, [90, 100]
    rec = _record(deliveries=[(5.0, 3.0), (95.0, 2.0)])
    centres, rate = value_rate_series(rec, 30.0, 0.0, 100.0)
    np.testing.assert_allclose(centres, [15.0, 45.0, 75.0, 95.0])
    np.testing.assert_allclose(rate, [3.0 / 30, 0.0, 0.0, 2.0 / 10])


def test_a_trial_that_ended_sooner_has_rates_over_the_time_it_ran():
    # a trial counted in deliveries that ended at 75 s, analysed over [0, 100) in 30 s bins:
    # [0, 30) 3 points / 30 s; [30, 60) none; [60, 90) ran 15 s, 1.5 points; [90, 100) not at all
    rec = _record(deliveries=[(5.0, 3.0), (70.0, 1.5)], duration_s=75.0)
    centres, rate = value_rate_series(rec, 30.0, 0.0, 100.0)
    np.testing.assert_allclose(centres, [15.0, 45.0, 75.0, 95.0])
    np.testing.assert_allclose(rate, [0.1, 0.0, 0.1, np.nan])
    assert value_rate(rec, 0.0, 100.0) == pytest.approx(4.5 / 75.0)  # its 75 s, not 100
    assert value_rate(rec, 60.0, 100.0) == pytest.approx(1.5 / 15.0)
    assert math.isnan(value_rate(rec, 80.0, 100.0))
    # over trials, a bin counts only the trials that ran in it
    table = performance_table([rec, _record(deliveries=[(95.0, 2.0)])], 30.0, 0.0, 100.0)
    assert table["n_trials"].tolist() == [2, 2, 2, 1] and table["mean"].iloc[-1] == pytest.approx(0.2)


def test_a_trial_that_started_late_has_rates_only_from_its_start():
    # a baseline that started at 40 s, analysed over [0, 100) in 30 s bins: [0, 30) and
    # [30, 60) began before it ran (NaN, not a rate over the part it ran); [60, 90) 3 points
    # / 30 s; [90, 100) 1 point / 10 s. A period from before its start has no rate either.
    rec = _record(deliveries=[(50.0, 2.0), (70.0, 3.0), (95.0, 1.0)], t0_s=40.0)
    centres, rate = value_rate_series(rec, 30.0, 0.0, 100.0)
    np.testing.assert_allclose(centres, [15.0, 45.0, 75.0, 95.0])
    np.testing.assert_allclose(rate, [np.nan, np.nan, 0.1, 0.1])
    assert math.isnan(value_rate(rec, 0.0, 100.0)) and math.isnan(value_rate(rec, 30.0, 60.0))
    assert value_rate(rec, 40.0, 100.0) == pytest.approx(6.0 / 60.0)
    assert value_rate(rec, 60.0, 100.0) == pytest.approx(4.0 / 40.0)
    table = performance_table([rec, _record(deliveries=[(10.0, 3.0)])], 30.0, 0.0, 100.0)
    assert table["n_trials"].tolist() == [1, 1, 2, 2] and table["mean"].iloc[0] == pytest.approx(0.1)
    # a baseline whose warm-up was cut to 30 s of a learner's 100 s: no rate before -30 s
    warm = _record(deliveries=[(-20.0, 3.0), (10.0, 1.0)], warmup_s=30.0, t0_s=-30.0)
    assert math.isnan(value_rate(warm, -100.0, 0.0))
    assert value_rate(warm, -30.0, 0.0) == pytest.approx(0.1)


def test_a_trial_that_started_late_is_covered_from_its_start():
    # robots 0-2 of a baseline that started at 40 s: nothing is known before 40 s, the state
    # is undefined until all three have a circuit (at 60 s), then 1:2 (robot 1 and 2 low)
    rec = _record(arrivals=[(45.0, 0, 0), (50.0, 1, 1), (60.0, 2, 1)], t0_s=40.0)
    assert _merged(state_intervals(rec)) == [(40.0, 60.0, None), (60.0, 100.0, "1:2")]
    assert time_shares(rec, 50.0, 100.0) == pytest.approx({"1:2": 100.0})
    assert (rec.start_s, rec.end_s) == (40.0, 100.0)
    # over time, in 30 s bins from 0, a bin that begins before the start has no value, as the
    # trial's performance has none there: [30, 60) though the state is known from 60 s on in
    # this record, and from 43 s in one whose robots all arrive by then
    early = _record(arrivals=[(41.0, 0, 0), (42.0, 1, 1), (43.0, 2, 1)], t0_s=40.0)
    from tavc_cli.analysis.states import group_high_series, high_circuit_series

    for r in (rec, early):
        centres, high = high_circuit_series(r, 30.0, 0.0, 100.0)
        np.testing.assert_allclose(centres, [15.0, 45.0, 75.0, 95.0])
        np.testing.assert_allclose(high, [np.nan, np.nan, 1.0, 1.0])
    _, order, shares = group_high_series(early, 30.0, 0.0, 100.0)  # robots 0 and 2 fast, 1 slow
    assert order == ["fast", "slow"]
    np.testing.assert_allclose(shares, [[np.nan, np.nan, 0.5, 0.5], [np.nan, np.nan, 0.0, 0.0]])
    # a record saved before `t0_s` was kept starts at minus its warm-up
    assert _record(warmup_s=30.0).start_s == -30.0


def test_value_rate_over_a_period():
    rec = _record(deliveries=[(10.0, 10.0), (40.0, 1.0), (60.0, 10.0)])
    # [0, 50): 11 points in 50 s = 0.22 per second; [50, 100): 10 / 50 = 0.2
    assert value_rate(rec, 0.0, 50.0) == pytest.approx(0.22)
    assert value_rate(rec, 50.0, 100.0) == pytest.approx(0.2)


def test_robots_on_the_high_circuit_over_time_by_hand():
    from tavc_cli.analysis.states import allocation_table, high_circuit_series

    # record A: 3 on the high circuit for 0-75 s, then 2; in 50 s bins: 3, then (25*3 + 25*2)/50 = 2.5
    a = _two_state_record(3, 75.0)
    centres, series = high_circuit_series(a, 50.0, 0.0, 100.0)
    np.testing.assert_allclose(centres, [25.0, 75.0])
    np.testing.assert_allclose(series, [3.0, 2.5])
    # record B: 1 until 25 s, then 2: bins (25*1 + 25*2)/50 = 1.5 and 2; over A and B:
    # means 2.25 and 2.25, sample stds |3 - 1.5| / sqrt(2) = 1.0607 and 0.5 / sqrt(2) = 0.3536
    b = _two_state_record(1, 25.0)
    table = allocation_table([a, b], 50.0, 0.0, 100.0)
    np.testing.assert_allclose(table["mean_high"], [2.25, 2.25])
    np.testing.assert_allclose(table["std_high"], [1.0607, 0.3536], atol=1e-4)
    # before any robot has reached a target the count is undefined, not zero
    _, early = high_circuit_series(a, 10.0, -20.0, 0.0)
    assert np.isnan(early).all()


# --- vacancy chains -----------------------------------------------------------------------------


def _with_choices(rec, choices, trial=0):
    """Add a choices table (t, robot, state = circuit last served, circuit chosen)."""
    rec.tables["choices"] = {
        "t_s": np.array([c[0] for c in choices], dtype=float),
        "robot": np.array([c[1] for c in choices], dtype=np.int64),
        "state": np.array([c[2] for c in choices], dtype=np.int64),
        "circuit": np.array([c[3] for c in choices], dtype=np.int64),
    }
    rec.meta["trial"] = trial
    return rec


def test_vacancy_chain_on_a_hand_made_event_log():
    from tavc_cli.analysis.vacancy import settled_moves, vacancy_row

    # robot 0 serves circuit 0 (high) and breaks down at t = 0, opening a vacancy there.
    # robot 1 visits circuit 0 once at +10 s and goes back: exploration, not a settled move.
    # robot 2 moves 0 -> 1 at +20 s and stays (settled); robot 1 then moves 1 -> 0 at +50 s
    # and stays three tasks: it fills the vacancy 50 s after the event, one settled move first.
    choices = [(-10.0, 0, 0, 0), (-5.0, 1, 1, 1), (-5.0, 2, 0, 0),
               (10.0, 1, 1, 0), (15.0, 1, 0, 1),
               (20.0, 2, 0, 1), (30.0, 2, 1, 1), (40.0, 2, 1, 1),
               (50.0, 1, 1, 0), (60.0, 1, 0, 0), (70.0, 1, 0, 0)]
    rec = _with_choices(_record(arrivals=[(-8.0, 0, 0)], breakdowns=[(0.0, 0)]), choices)
    assert settled_moves(rec, 0.0) == [(20.0, 2, 0, 1), (50.0, 1, 1, 0)]
    row = vacancy_row(rec)
    assert row["event"] == "breakdown" and row["vacancy_circuit"] == 0
    assert row["filled"] and row["filler"] == 1 and row["filler_from"] == 1
    assert row["fill_delay_s"] == pytest.approx(50.0) and row["moves_before_fill"] == 1
    assert row["chain"] == "robot 2 0->1 at +20 s; robot 1 1->0 at +50 s"


def test_vacancy_after_a_value_change_is_on_the_new_high_circuit_and_may_stay_open():
    from tavc_cli.analysis.vacancy import vacancy_row

    # values swap at t = 0: circuit 1 becomes the high one; only a two-task visit follows
    choices = [(-5.0, 0, 0, 0), (10.0, 0, 0, 1), (20.0, 0, 1, 1), (30.0, 0, 1, 0)]
    rec = _with_choices(_record(value_changes=[(0.0, (1.0, 3.0))]), choices)
    row = vacancy_row(rec)
    assert row["event"] == "value_change" and row["vacancy_circuit"] == 1
    assert not row["filled"] and math.isnan(row["fill_delay_s"]) and row["chain"] == ""
    # a trial without any event has no row
    assert vacancy_row(_with_choices(_record(), choices)) is None


def test_robots_are_classified_from_their_choices_by_hand():
    from tavc_cli.analysis.robots import robot_rows

    # robot 0: 10 choices, 9 of circuit 0 -> share 0.9: a stayer on circuit 0
    # robot 1: 0,1,0,1,... 8 choices each switching -> rate 1.0: an alternator
    # robot 2: 1,1,0,0,1,1,0,0 from state 1: switches at 3 of 8 choices, share 0.5: mixed
    choices = [(float(k), 0, 0, 1 if k == 4 else 0) for k in range(10)]
    choices[5] = (5.0, 0, 1, 0)  # after the one visit to circuit 1 its state is 1
    choices += [(float(k), 1, k % 2, 1 - k % 2) for k in range(8)]
    seq = [1, 1, 0, 0, 1, 1, 0, 0]
    choices += [(float(k), 2, ([1] + seq)[k], seq[k]) for k in range(8)]
    rec = _with_choices(_record(), choices)
    rows = {r["robot"]: r for r in robot_rows(rec, 0.0, 100.0)}
    assert rows[0]["kind"] == "stayer" and rows[0]["circuit"] == 0 and rows[0]["share_main"] == pytest.approx(0.9)
    assert rows[1]["kind"] == "alternator" and rows[1]["switch_rate"] == pytest.approx(1.0)
    assert rows[2]["kind"] == "mixed" and rows[2]["switch_rate"] == pytest.approx(3 / 8)
    # outside the window nobody chose anything: idle
    assert {r["kind"] for r in robot_rows(rec, 200.0, 300.0)} == {"idle"}


def test_settle_time_by_hand():
    from tavc_cli.analysis.trial_stats import settle_time

    # 100 s bins from 0; stable period from 300 s: mean of 3.0, 3.2, 2.8 = 3.0.
    # Bins: 1.0, 3.6 (off by 0.6), 2.7, 3.0, 3.2, 2.8 -> the last off bin is the second (100-200 s),
    # so the allocation settles at 200 s
    centres = [50, 150, 250, 350, 450, 550]
    assert settle_time(centres, [1.0, 3.6, 2.7, 3.0, 3.2, 2.8], 100.0, 300.0) == pytest.approx(200.0)
    # never off: settled from the start; the last bin off: never settled
    assert settle_time(centres, [3.0] * 6, 100.0, 300.0) == 0.0
    # stable mean (3 + 3 + 1) / 3 = 2.33, the last bin 1.33 below it
    assert math.isnan(settle_time(centres, [3.0, 3.0, 3.0, 3.0, 3.0, 1.0], 100.0, 300.0))




def test_policy_settling_by_hand():
    from tavc_cli.analysis.qvalues import policy_settle_time

    t = [0.0, 600.0, 1200.0, 1800.0, 2400.0]
    # robot 1 changes its best action after circuit 1 between 600 and 1200 s; then nothing changes
    q = greedy_snapshots([[(0, 0), (1, 1)], [(0, 0), (1, 1)], [(0, 0), (1, 0)], [(0, 0), (1, 0)], [(0, 0), (1, 0)]])
    assert policy_settle_time(t, q) == 1200.0
    # only robot 0 counted: it never changed, so settled from the start
    assert policy_settle_time(t, q, robots=np.array([0])) == 0.0
    # a change between the last two snapshots: not settled
    q_late = greedy_snapshots([[(0, 0)], [(0, 0)], [(0, 0)], [(0, 0)], [(1, 0)]])
    assert math.isnan(policy_settle_time(t, q_late))
    # counted from an event at 1000 s: the snapshot at 600 s is the reference, the change shows at 1200 s
    assert policy_settle_time(t, q, t0=1000.0) == pytest.approx(200.0)
    # an event after the change: nothing changes from it on
    assert policy_settle_time(t, q, t0=1500.0) == 0.0


def test_q_value_table_and_policy_stats_of_a_record():
    from tavc_cli.analysis.qvalues import q_value_table, trial_policy_stats

    rec = _record(n_robots=2, groups=("a", "a"), speeds=(0.25, 0.25))
    rec.q_t = np.array([0.0, 600.0, 1200.0])
    rec.q = greedy_snapshots([[(0, 0), (1, 1)], [(1, 0), (1, 1)], [(1, 1), (1, 1)]])
    rec.meta["trial"] = 3
    table = q_value_table([rec])
    assert table.columns.tolist() == ["controller", "trial", "robot", "t_s", "q_0_0", "q_0_1", "q_1_0", "q_1_1"]
    assert len(table) == 3 * 2 and set(table["trial"]) == {3}
    # robot 0 at 600 s prefers circuit 1 after circuit 0, and circuit 0 after circuit 1
    row = table[(table["robot"] == 0) & (table["t_s"] == 600.0)].iloc[0]
    assert (row["q_0_1"], row["q_0_0"], row["q_1_0"], row["q_1_1"]) == (1.0, 0.0, 1.0, 0.0)
    # robot 0 changed at 600 and at 1200 s: two changes, the last at the last snapshot -> not settled
    settle, changes = trial_policy_stats(rec)
    assert changes == 2 and math.isnan(settle)
    # a learner without tables (random) has neither
    rec.q = np.zeros(0)
    assert all(math.isnan(x) for x in trial_policy_stats(rec))
    assert q_value_table([rec]) is None


def test_high_share_weights_each_state_by_its_robots_on_the_high_circuit():
    import pandas as pd

    from tavc_cli.analysis.value_ratio import high_share

    # 50 % in 3:3 (half the robots high), 25 % in 6:0 (all), 25 % in 0:6 (none): 0.25 + 0.25 = 0.5;
    # all the time in 4:2: 4/6
    stats = pd.DataFrame({"pct_0:6": [25.0, 0.0], "pct_3:3": [50.0, 0.0], "pct_4:2": [0.0, 100.0],
                          "pct_6:0": [25.0, 0.0]})
    assert high_share(stats) == pytest.approx([0.5, 4 / 6])


def test_model_prediction_against_the_value_ratio_by_hand(tmp_path):
    import pandas as pd

    from tavc_cli.analysis.value_ratio import predicted_shares
    from tavc_cli.run_tables import model_rows

    # two robots; alone on a circuit a task takes 100 s, two on one circuit 150 s each.
    # In 1:1 the low robot earns 2000/100 = 20 per s; moving to the high circuit it would earn
    # 2000 r / 150, better only for r > 1.5: below that 1:1 (half the robots high), above it 2:0.
    inf = float("inf")
    rows = [("1:0", 0, 0.01, 100.0), ("1:0", 1, 0.0, inf), ("0:1", 0, 0.0, inf), ("0:1", 1, 0.01, 100.0),
            ("2:0", 0, 2 / 150, 150.0), ("2:0", 1, 0.0, inf), ("1:1", 0, 0.01, 100.0), ("1:1", 1, 0.01, 100.0),
            ("0:2", 0, 0.0, inf), ("0:2", 1, 2 / 150, 150.0)]
    pd.DataFrame(rows, columns=["split", "circuit", "c_per_s", "task_time_s"]).to_csv(tmp_path / "model.csv",
                                                                                     index=False)
    pred = predicted_shares(model_rows(tmp_path / "model.csv"), 2, [1.0, 1.4, 1.6, 2.0])
    assert pred["share"].tolist() == [0.5, 0.5, 1.0, 1.0]
    assert pred["state"].tolist() == ["1:1", "1:1", "2:0", "2:0"]


def test_ratio_points_gather_a_sweep_from_its_run_folders(tmp_path):
    import pandas as pd

    from tavc_cli.config import load_config, settings
    from tavc_cli.run_tables import ratio_points
    from tavc_cli.settings import to_yaml

    reading = ["arrival=dock", "passing=left", "arena=two_circuits_parallel"]
    for sub, unit, values, duration, shares, world in (
            ("paper/0", "ms", [2000, 2000], 18000.0, (0.0, 50.0), []),
            ("paper/1", "ms", [4000, 2000], 18000.0, (50.0, 100.0), []),
            ("long/0", "s", [3000, 2000], 180000.0, (100.0, 100.0), []),
            ("dock-left-two_circuits_parallel/0", "ms", [3000, 2000], 18000.0, (0.0, 0.0), reading),
            # a variant of that reading, named by its folder; a folder naming another reading names no variant
            ("dock-left-two_circuits_parallel-calibrated/0", "ms", [3000, 2000], 18000.0, (0.0, 0.0), reading),
            ("range-left-two_circuits_parallel-calibrated/0", "ms", [4000, 2000], 18000.0, (0.0, 0.0), reading),
            # a run that did not finish (no provenance.json): its tables may be an earlier run's, no row
            ("paper/2", "ms", [3000, 2000], 18000.0, (0.0, 0.0), [])):
        d = tmp_path / sub
        d.mkdir(parents=True)
        run = load_config(["experiment=initial_distribution", f"tasks.values={values}", f"tasks.time_unit={unit}",
                           f"duration_s={duration}", *world])
        (d / "config.yaml").write_text(to_yaml(settings(run)))
        # two robots; share of the period in 2:0 per trial (the rest in 0:2); a random trial to leave out
        pd.DataFrame({"controller": ["tavc", "tavc", "random"], "trial": [0, 1, 0], "policy_changes": [1, 3, 0],
                      "pct_0:2": [100 - shares[0], 100 - shares[1], 0.0], "pct_2:0": [*shares, 100.0]}
                     ).to_csv(d / "trial_stats.csv", index=False)
        if sub != "paper/2":
            (d / "provenance.json").write_text("{}")
    points = ratio_points(tmp_path)
    assert points[["reading", "horizon", "ratio"]].values.tolist() == [
        ["t in ms (the default)", "5 h", 1.0, ], ["t in ms (the default)", "5 h", 2.0],
        # a run in another reading of the world is a reading of its own, after the default's
        ["t in ms (the default), " + " ".join(reading), "5 h", 1.5],
        ["t in ms (the default), " + " ".join(reading), "5 h", 2.0],
        ["t in ms (the default), " + " ".join(reading) + " (calibrated)", "5 h", 1.5], ["t in s", "50 h", 1.5]]
    # trials with 0 % and 50 % of the period in 2:0: mean share 0.25, std of (0, 0.5) = 0.3536
    first = points.iloc[0]
    assert first["mean"] == pytest.approx(0.25) and first["std"] == pytest.approx(math.sqrt(0.125))
    assert first["n_trials"] == 2 and first["policy_changes_per_trial"] == 2.0
    assert points.iloc[1]["mean"] == pytest.approx(0.75) and points.iloc[2]["mean"] == 0.0
    assert points.iloc[5]["mean"] == 1.0


def test_specialisation_by_speed_group_by_hand():
    from tavc_cli.analysis.states import specialisation_table

    # robots 0 and 2 fast, 1 slow; circuit 0 is the high-value one (values 2, 1). At t = 0 robot 0 is
    # on the high circuit, 1 and 2 on the low; at 50 s robot 2 moves to the high one.
    # 50 s bins: fast share 1/2 then 2/2; slow share 0 then 0.
    rec = _record([(0.0, 0, 0), (0.0, 1, 1), (0.0, 2, 1), (50.0, 2, 0)], duration_s=100.0)
    table = specialisation_table([rec], 50.0, 0.0, 100.0)
    fast = table[table["group"] == "fast"]
    slow = table[table["group"] == "slow"]
    assert fast["t_s"].tolist() == [25.0, 75.0]
    assert fast["mean_share_high"].tolist() == [0.5, 1.0]
    assert slow["mean_share_high"].tolist() == [0.0, 0.0]
    # a robot moving mid-bin counts for the time it spent: one 100 s bin gives fast (0.5 * 50 + 1 * 50) / 100
    assert specialisation_table([rec], 100.0, 0.0, 100.0).query("group == 'fast'")["mean_share_high"].tolist() == [
        0.75]


def test_specialisation_counts_live_robots_and_survives_a_trial_without_states():
    from tavc_cli.analysis.states import specialisation_table

    # both fast robots on the high circuit; fast robot 2 breaks down at 50 s: the share stays 1, not 2 or 1/2
    rec = _record([(0.0, 0, 0), (0.0, 1, 1), (0.0, 2, 0)], breakdowns=[(50.0, 2)], duration_s=100.0)
    fast = specialisation_table([rec], 50.0, 0.0, 100.0).query("group == 'fast'")
    assert fast["mean_share_high"].tolist() == [1.0, 1.0]
    # a trial in which nobody ever reached a target: no state, NaN shares, no error
    silent = _record([], duration_s=100.0)
    table = specialisation_table([silent], 50.0, 0.0, 100.0)
    assert len(table) == 4 and table["mean_share_high"].isna().all()


def test_specialisation_share_follows_a_breakdown_that_leaves_the_state_unchanged():
    from tavc_cli.analysis.states import specialisation_table

    # fast robot 0 on the high circuit, fast robot 2 on the low one; robot 2 breaks down at 50 s.
    # The state stays "1:0" (one fast robot on the high circuit), but the fast group shrinks
    # from two to one: its share goes from 1/2 to 1/1.
    rec = _record([(0.0, 0, 0), (0.0, 1, 1), (0.0, 2, 1)], breakdowns=[(50.0, 2)], duration_s=100.0)
    fast = specialisation_table([rec], 50.0, 0.0, 100.0).query("group == 'fast'")
    assert fast["mean_share_high"].tolist() == [0.5, 1.0]


def test_binned_means_are_a_plain_loops_bit_for_bit():
    from tavc_cli.analysis.states import _binned_mean

    rng = np.random.default_rng(3)
    cuts = np.sort(np.concatenate([rng.uniform(-50.0, 1050.0, 400), np.arange(0.0, 1001.0, 100.0)[::3]]))
    states = [None, "0:3", "1:2", "2:1", "3:0"]
    intervals = [(a, b, states[rng.integers(len(states))]) for a, b in zip(cuts[:-1], cuts[1:], strict=True)]
    intervals += [(-40.0, 990.0, "2:1")]  # one interval over every bin
    edges = np.arange(0.0, 1001.0, 100.0)

    def value(s, start):
        return np.array([float(x) for x in s.split(":")]) * (1.0 + start / 7.0)

    weighted, covered = np.zeros((len(edges) - 1, 2)), np.zeros(len(edges) - 1)
    for a, b, s in intervals:
        if s is None:
            continue
        first = max(int(np.searchsorted(edges, a, side="right")) - 1, 0)
        last = min(int(np.searchsorted(edges, b, side="left")), len(edges) - 1)
        for k in range(first, last):
            lo, hi = max(a, edges[k]), min(b, edges[k + 1])
            if hi > lo:
                weighted[k] += value(s, a) * (hi - lo)
                covered[k] += hi - lo
    expected = weighted / covered[:, None]
    got = _binned_mean(intervals, value, edges, 2)
    assert got.tobytes() == expected.tobytes()
    # nothing defined anywhere: NaN in every bin
    assert np.isnan(_binned_mean([(0.0, 1000.0, None)], value, edges, 2)).all()


@pytest.mark.parametrize("scheme", ["circuits", "groups"])
def test_state_intervals_are_a_recount_after_every_event(scheme):
    """The intervals, kept by counts updated event by event, are exactly those of labelling
    the whole team anew after every event (`state_label`), on logs with simultaneous
    events, repeated and late arrivals, arrivals and breakdowns of robots already broken
    down, and value changes that swap the circuits' ranking."""
    from tavc_cli.analysis.states import _events, group_order, state_label

    rng = np.random.default_rng(11)
    groups, speeds = ("fast", "slow", "fast", "slow", "slow"), (0.3, 0.2, 0.3, 0.2, 0.2)
    for _ in range(40):
        times = np.round(rng.uniform(-20.0, 100.0, 30))  # whole seconds: many ties
        arrivals = [(float(t), int(rng.integers(5)), int(rng.integers(2))) for t in times]
        breakdowns = [(float(t), int(rng.integers(5))) for t in np.round(rng.uniform(0.0, 100.0, 3))]
        changes = [(float(t), tuple(rng.permutation([2.0, 1.0]))) for t in np.round(rng.uniform(0.0, 100.0, 2))]
        rec = _record(arrivals, breakdowns, changes, n_robots=5, groups=groups, speeds=speeds,
                      warmup_s=20.0)
        last, alive, values = np.full(5, -1), np.ones(5, dtype=bool), [2.0, 1.0]
        order = group_order(groups, speeds)
        t_prev, state, expected = -20.0, None, []
        for t, kind, payload in _events(rec):
            if t > t_prev:
                expected.append((t_prev, min(t, 100.0), state))
                t_prev = t
            if kind == 2:
                last[payload[0]] = payload[1]
            elif kind == 0:
                alive[payload] = False
            else:
                values = list(payload)
            state = state_label(last, alive, values, scheme, groups, order)
        if t_prev < 100.0:
            expected.append((t_prev, 100.0, state))
        expected = [(a, b, s) for a, b, s in expected if b > a]
        assert state_intervals(rec, scheme) == expected


def test_events_are_ordered_by_time_then_kind_then_as_recorded():
    from tavc_cli.analysis.states import _events

    rec = _record(arrivals=[(5.0, 1, 0), (3.0, 0, 1), (5.0, 0, 1)], breakdowns=[(5.0, 2)],
                  value_changes=[(5.0, (1.0, 2.0))])
    # kinds: breakdown 0, value change 1, arrival 2
    assert _events(rec) == [(3.0, 2, (0, 1)), (5.0, 0, 2), (5.0, 1, (1.0, 2.0)), (5.0, 2, (1, 0)), (5.0, 2, (0, 1))]
