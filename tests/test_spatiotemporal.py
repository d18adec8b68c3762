"""Section 1.4: the five-bit state from hand-placed robots, the behaviour learner, and the
measures of Table 1.1, the policies and the lanes on hand-made records."""

import math

import numpy as np
import pandas as pd
import pytest

from tavc_cli.analysis import spatiotemporal as st
from tavc_cli.config import load_config, settings
from tavc_cli.experiments import engine, trial
from tavc_cli.experiments.build import trial_specs
from tavc_cli.experiments.records import TrialRecord
from tavc_cli.learning import behaviour
from tavc_cli.learning.behaviour import BehaviourPolicy, sensed_states, state_bits, state_index
from tavc_cli.vocabulary import SINK, SOURCE


def test_sensed_states_are_the_five_bits_and_pick_the_changed_live_robots():
    from tavc_cli.behaviours.layout import ROBOT

    rng = np.random.default_rng(5)
    robots = np.zeros(9, dtype=ROBOT)
    robots["code_in_view"] = rng.integers(0, 2, 9).astype(bool)
    robots["alive"] = True
    robots["alive"][5] = False
    camera = np.column_stack([rng.integers(0, 2, (9, 3)), np.full(9, -1)]).astype(np.int64)
    random_bit = rng.integers(0, 2, 9).astype(np.int64)
    deciding = np.zeros(9, dtype=bool)
    deciding[3:9] = True  # one trial's rows; rows 0-2 belong to a trial that does not learn behaviours
    expected = state_index(robots["code_in_view"], random_bit, camera[:, 0], camera[:, 1], camera[:, 2])
    last_state = expected.copy()
    last_state[[0, 3, 5, 7]] += 1  # rows 3, 5, 7 sense something new (and row 0, not deciding); 5 is broken
    states, due = np.full(9, -7, dtype=np.int64), np.zeros(9, dtype=np.int64)
    every_time = np.zeros(9, dtype=bool)
    m = sensed_states(robots, camera, deciding, random_bit, last_state, every_time, states, due)
    np.testing.assert_array_equal(states[3:], expected[3:])
    assert list(states[:3]) == [-7, -7, -7]  # rows not deciding are left alone
    assert list(due[:m]) == [3, 7]
    every_time[3:9] = True
    m = sensed_states(robots, camera, deciding, random_bit, last_state, every_time, states, due)
    assert list(due[:m]) == [3, 4, 6, 7, 8]  # every live robot, deciding every time


def test_state_index_packs_the_five_bits():
    assert state_index(0, 0, 0, 0, 0) == 0
    assert state_index(1, 0, 0, 0, 0) == 1
    assert state_index(0, 1, 0, 0, 0) == 2
    assert state_index(0, 0, 1, 1, 0) == 4 + 8
    assert state_index(1, 1, 1, 1, 1) == 31
    assert state_bits(16) == {"target": 0, "random": 0, "red": 0, "green": 0, "yellow": 1}


def test_states_from_hand_placed_robots(monkeypatch):
    # one_circuit: source bar-code at (0, 3), sink at (8, 3); every robot first heads for the source.
    # 0 at (5, 3) facing the sink, robot 1 ahead of it facing the same way: 0 sees 1's rear (yellow: 16);
    # 1 at (6, 3) facing robot 3, which faces it at (7.2, 3): each sees the other's bow, red and green (12);
    # 2 at (2, 3) facing the source 2 m away, nothing in front: a bar-code in view (1); robots 0 and 1
    # have the sink's code ahead but hidden by the robot in front of them.
    poses = np.array([[5.0, 3.0, 0.0], [6.0, 3.0, 0.0], [2.0, 3.0, math.pi], [7.2, 3.0, math.pi]])
    monkeypatch.setattr(trial, "start_poses", lambda arena, radii, rng: poses.copy())
    seen = {}
    decide = BehaviourPolicy.decide

    def record(self, robot, state):
        seen.setdefault(robot, []).append(state)
        decide(self, robot, state)
        return behaviour.ACTIONS[2]  # everyone stops, so nothing moves

    monkeypatch.setattr(BehaviourPolicy, "decide", record)
    cfg = load_config(["experiment=spatiotemporal", "scale=paper", "team.n_robots=4", "trials=1", "duration_s=0.5",
                       "learner.decision_period_s=0.1", "sim.pose_every_s=0"])
    engine.BatchEngine(trial_specs(settings(cfg))).run()
    # tick 0 decides before anything was sensed (state 0); tick 1 on what tick 0 sensed; then, with
    # nothing moving and the random bits off for their first second, the states stay and nobody decides
    assert all(states[0] == 0 and len(states) == 2 for states in seen.values())
    first = {robot: states[1] for robot, states in seen.items()}
    assert first[0] == 16 and first[1] == 12 and first[2] == 1
    assert first[3] & ~1 == 12  # a code may be in view between the robots; the markings are certain


def test_behaviour_learner_credits_arrivals_to_the_last_choice():
    rng = np.random.default_rng(0)
    pol = BehaviourPolicy(1, 1, alpha=0.5, gamma=0.9, tau=1e-6, q_init=(0.0, 0.0), decision_period_s=1.0, rng=rng)
    pol.q[0, 3] = [0.0, 1.0, 0.0]  # in state 3 wall following is best: with a tiny tau it is chosen
    assert pol.decide(0, 3) == behaviour.ACTIONS[1]
    pol.arrived(0, 0.2)
    pol.arrived(0, 0.3)
    pol.q[0, 5] = [0.4, 0.0, 0.0]
    pol.decide(0, 5)
    # Q(3, wall) += 0.5 * (0.2 + 0.3 + 0.9 * 0.4 - 1.0) = 1.0 - 0.07 = 0.93; the reward is spent
    assert pol.q[0, 3, 1] == pytest.approx(0.93)
    assert pol.reward[0] == 0.0


def test_random_bit_switches_at_interval_ends():
    pol = BehaviourPolicy(2, 1, alpha=0.1, gamma=0.9, tau=0.1, q_init=(0.0, 0.0), decision_period_s=1.0,
                          rng=np.random.default_rng(1))
    first = pol.random_until.copy()
    assert ((first >= 1.0) & (first <= 30.0)).all()
    assert pol.random_bits(0.5).tolist() == [0, 0]
    bits = pol.random_bits(float(first[0]) + 1e-9).copy()
    assert bits[0] == 1 and pol.random_until[0] - first[0] >= 1.0


def _record(arrivals, n_robots=2, q=None, poses=None, pose_t=None, controller="behaviour"):
    a = list(arrivals)
    rec = TrialRecord(meta={"n_robots": n_robots, "controller": controller, "trial": 0, "n_circuits": 1,
                            "values": [1.0], "groups": ["a"] * n_robots, "speeds_mps": [0.25] * n_robots,
                            "duration_s": 1000.0, "warmup_s": 0.0},
                      tables={"arrivals": {"t_s": np.array([x[0] for x in a], float),
                                           "robot": np.array([x[1] for x in a], np.int64),
                                           "target": np.zeros(len(a), np.int64),
                                           "circuit": np.zeros(len(a), np.int64),
                                           "kind": np.array([x[2] for x in a], np.int64)},
                              "breakdowns": {"t_s": np.zeros(0), "robot": np.zeros(0, np.int64)}})
    if q is not None:
        rec.q_t, rec.q = np.array([0.0]), q
    if poses is not None:
        rec.pose_t, rec.poses = np.asarray(pose_t, float), np.asarray(poses, float)
        rec.pose_alive = np.ones(rec.poses.shape[:2], bool)
    return rec


def test_traversals_and_target_times_by_hand():
    # robot 0: source 20, sink 50, source 90, sink 130 -> traversals 50 (from t = 0) and 80
    # robot 1: source 30, sink 70 -> one traversal of 70
    rec = _record([(20, 0, SOURCE), (30, 1, SOURCE), (50, 0, SINK), (70, 1, SINK), (90, 0, SOURCE), (130, 0, SINK)])
    assert [t.tolist() for t in st.traversal_times(rec)] == [[50.0, 80.0], [70.0]]
    # the group's arrivals 20, 30, 50, 70, 90, 130 -> intervals 20, 10, 20, 20, 20, 40
    assert st.target_times(rec).tolist() == [20.0, 10.0, 20.0, 20.0, 20.0, 40.0]
    table = st.table_1_1([rec])
    first = table.iloc[0]
    # after 0 traversals: 50 and 70 -> mean 60, std sqrt(200) = 14.14; after 0 arrivals: one trial, 20 s
    assert (first["mean_traversal_s"], first["n_robots"]) == (60.0, 2)
    assert first["std_traversal_s"] == pytest.approx(math.sqrt(200.0))
    assert (first["mean_target_s"], first["n_trials"]) == (20.0, 1)
    assert math.isnan(table.iloc[1]["mean_traversal_s"])  # nobody made 26 traversals
    # Figure 1.4: a window of 2 over 20, 10, 20, 20, 20, 40 -> 15, 15, 20, 20, 30
    curve = st.target_time_curve(st.target_time_table([rec]), window=2)
    assert curve["mean_target_s"].tolist() == [15.0, 15.0, 20.0, 20.0, 30.0]


def test_policy_shares_and_stop_rates_by_hand():
    q = np.zeros((1, 1, 32, 3))
    q[0, 0, :, 0] = 1.0  # direct approach best everywhere...
    for s in range(32):
        b = state_bits(s)
        if b["yellow"] and b["target"]:
            q[0, 0, s, 2] = 2.0  # ...but stop when a rear marking is in view and the target is too (8 of 16)
        if (b["red"] and not b["yellow"]) and not b["random"]:
            q[0, 0, s, 1] = 2.0  # wall following facing a red marking without the random bit (4 of 8)
    # every state learned: the first snapshot all zeros, the last as set above
    [row] = st.policy_rows(_record([], n_robots=1, q=np.concatenate([np.zeros_like(q), q])))
    assert row["n_states"] == 32
    assert row["share_stop"] == 8 / 32 and row["share_wall"] == 4 / 32 and row["share_direct"] == 20 / 32
    assert row["stop_rate_yellow"] == 0.5 and row["stop_rate_red"] == 0.0 and row["stop_rate_green"] == 0.0
    # only the 16 states without the random bit learned: of them 4 stop (yellow, target), 4 wall
    # (red, no yellow, no random bit), 8 direct; of their 8 yellow states 4 stop
    first = q.copy()
    first[0, 0, [s for s in range(32) if not state_bits(s)["random"]]] = 0.0
    [row] = st.policy_rows(_record([], n_robots=1, q=np.concatenate([first, q])))
    assert row["n_states"] == 16
    assert (row["share_stop"], row["share_wall"], row["share_direct"]) == (4 / 16, 4 / 16, 8 / 16)
    assert row["stop_rate_yellow"] == 0.5


def test_lane_offsets_are_left_of_the_direction_of_travel():
    # axis from (0, 3) to (8, 3); frames at t = 0 and 10 s. Robot 0 heads to the sink 0.4 m above the
    # axis (its left); robot 1 heads to the source 0.4 m below it (also its left); robot 2 is near the
    # sink's end (left out) and robot 3 drives across the axis (left out).
    frame = [[4.0, 3.4, 0.0], [3.0, 2.6, math.pi], [7.0, 3.0, 0.0], [4.0, 2.0, math.pi / 2]]
    rec = _record([], n_robots=4, poses=[frame, frame], pose_t=[0.0, 10.0])
    x = st.lane_offsets(rec, (0.0, 3.0), (8.0, 3.0), 0.0, 20.0)
    assert sorted(x.round(6).tolist()) == [0.4, 0.4, 0.4, 0.4]
    lanes = st.lane_table([rec], (0.0, 3.0), (8.0, 3.0), {"late": (5.0, 20.0)})
    assert lanes["mean_left_m"].tolist() == [pytest.approx(0.4)] and lanes["n_frames"].tolist() == [2]
    occ = st.occupancy_table([rec], (0.0, 3.0), (8.0, 3.0), 8.0, 6.0, {"all": (0.0, 20.0)}, cell_m=1.0)
    to_sink = occ[(occ["direction"] == "to_sink") & (occ["count"] > 0)]
    # robot 0 twice in cell (4..5, 3..4), robot 2 twice in (7..8, 3..4)
    assert sorted(zip(to_sink["x_m"], to_sink["y_m"], to_sink["count"], strict=True)) == [(4.5, 3.5, 2), (7.5, 3.5, 2)]


def test_lanes_are_read_in_each_trials_own_first_and_last_tenth():
    # two trials, one that ran 1000 s and one that ended with its n-th delivery at 400 s: frames
    # every 20 s; the robot drives to the sink 0.4 m left of the axis until 300 s, then 0.2 m right
    t = np.arange(0.0, 1000.0, 20.0)
    frames = [[[4.0, 3.4 if x < 300.0 else 2.8, 0.0]] for x in t]
    long_run = _record([], n_robots=1, poses=frames, pose_t=t)
    short = _record([], n_robots=1, poses=[f for f, x in zip(frames, t, strict=True) if x < 400.0],
                    pose_t=t[t < 400.0])
    short.meta["duration_s"] = 400.0
    assert st.lane_windows(short) == {"early": (0.0, 40.0), "late": (360.0, 400.0)}
    lanes = st.lane_table([long_run, short], (0.0, 3.0), (8.0, 3.0), st.lane_windows)
    # early: 0-100 s and 0-40 s, both left (+0.4); late: 900-1000 s and 360-400 s, both right (-0.2)
    assert lanes["window"].tolist() == ["early", "late", "early", "late"]
    np.testing.assert_allclose(lanes["mean_left_m"], [0.4, -0.2, 0.4, -0.2])
    assert lanes["n_frames"].tolist() == [5, 5, 2, 2]
    occ = st.occupancy_table([long_run, short], (0.0, 3.0), (8.0, 3.0), 8.0, 6.0, st.lane_windows, cell_m=1.0)
    assert occ.groupby("window")["count"].sum().to_dict() == {"early": 7, "late": 7}


def test_claims_1_and_2_on_hand_made_tables():
    from tavc_cli.analysis.claims import claim_rows

    rng = np.random.default_rng(0)
    trav = pd.DataFrame([("behaviour", t, r, k, 1000.0 / (1 + k / 20) + rng.normal(0, 20))
                         for t in range(5) for r in range(5) for k in range(201)],
                        columns=["controller", "trial", "robot", "traversal", "time_s"])
    targ = pd.DataFrame([("behaviour", t, k, 250.0 / (1 + k / 100) + rng.normal(0, 10))
                         for t in range(5) for k in range(1001)], columns=["controller", "trial", "arrival", "time_s"])
    pol = pd.DataFrame({"share_direct": 0.6 + 0.01 * rng.random(25), "share_wall": 0.3 + 0.01 * rng.random(25),
                        "share_stop": 0.1 + 0.01 * rng.random(25), "stop_rate_yellow": 0.1 * rng.random(25),
                        "stop_rate_red": 0.5 + 0.1 * rng.random(25), "stop_rate_green": 0.5 + 0.1 * rng.random(25),
                        "stop_rate_front": 0.5 + 0.1 * rng.random(25)})
    lanes = pd.DataFrame({"window": ["late"] * 5, "mean_left_m": 0.3 + 0.05 * rng.random(5)})
    runs = {"spatiotemporal": pd.DataFrame(), "spatiotemporal/traversals": trav, "spatiotemporal/target_times": targ,
            "spatiotemporal/policy": pol, "spatiotemporal/lanes": lanes}
    rows = claim_rows(runs, "spatiotemporal").set_index("claim_id")
    assert rows.loc[1, "verdict"] == "reproduced" and rows.loc[2, "verdict"] == "reproduced"
    # no lanes: robots spread on both sides, the offset's mean near zero
    runs["spatiotemporal/lanes"] = lanes.assign(mean_left_m=[0.1, -0.1, 0.05, -0.05, 0.0])
    assert claim_rows(runs, "spatiotemporal").set_index("claim_id").loc[2, "verdict"] == "not_reproduced"
    # learning that does not speed the robots up
    runs["spatiotemporal/traversals"] = trav.assign(time_s=1000.0 + rng.normal(0, 20, len(trav)))
    assert claim_rows(runs, "spatiotemporal").set_index("claim_id").loc[1, "verdict"] == "not_reproduced"
