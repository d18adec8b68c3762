"""Docking at the bar-codes: one robot at a dock spot at a time, the others wait, nobody
is left stuck, and every task's time is accounted for activity by activity."""

import math

import numpy as np
import pytest

from tavc_cli.config import load_config, settings
from tavc_cli.experiments import trial
from tavc_cli.experiments.build import trial_specs
from tavc_cli.experiments.engine import BatchEngine, run_trials
from tavc_cli.vocabulary import ACTIVITIES

ORIGINAL_START_POSES = trial.start_poses
RADIUS_M, READ_M, LATERAL_TOL_M, HEADING_TOL = 0.22, 0.30, 0.10, math.radians(20.0)


def _specs(*overrides):
    """Specs in a pinned dock world (the hand-computed geometry below is for it)."""
    cfg = settings(load_config(["scale=paper", "convergence_s=0", "learner=static",
                                    "sim.q_snapshot_every_s=0", "robot.behaviour.arrive_dist_m=0.30",
                                    "robot.dock.dwell_s=0", "robot.dock.occupied_m=0.6", *overrides]))
    return trial_specs(cfg)


def _with_starts(monkeypatch, poses):
    """Give the trials of the next batch these start poses, one (n_robots, 3) array each."""
    queue = [np.asarray(p, dtype=float) for p in poses]
    monkeypatch.setattr(trial, "start_poses", lambda arena, radii, rng: queue.pop(0))


def _arrival_poses(eng):
    """Run the engine; return its records and, per arrival, the true pose of the robot."""
    seen = []

    def watch(e):
        for g in np.flatnonzero(e.robots["arrived"]):  # arrivals of this tick
            seen.append((e.clock - e.dt, int(g), e.pose[g].copy()))  # no warm-up: the clock is t

    eng.on_tick = watch
    return eng.run(), seen


@pytest.fixture(scope="module")
def pair(request):
    """one_circuit, two robots side by side 1.6 m out from the source, both sent to it."""
    mp = pytest.MonkeyPatch()
    request.addfinalizer(mp.undo)
    _with_starts(mp, [[[1.9, 2.6, math.pi], [1.9, 3.4, math.pi]]])
    eng = BatchEngine(_specs("arena=one_circuit", "team.n_robots=2", "trials=1", "duration_s=200")[:1])
    (rec,), seen = _arrival_poses(eng)
    return rec, seen


def test_two_robots_at_one_dock_take_turns(pair):
    rec, _ = pair
    a = rec.table("arrivals")
    first_two = a["robot"][:2].tolist()
    # both reach the source (target 0) first, one after the other, each within a minute
    assert sorted(first_two) == [0, 1]
    assert a["target"][:2].tolist() == [0, 0]
    assert a["t_s"][1] < 60.0
    # the second cannot dock before the first has backed out (3.2 s) and cleared the spot
    assert a["t_s"][1] - a["t_s"][0] > 3.2
    # ... and it spent that time waiting, not pushing: its first task records seconds of waiting
    d = rec.table("deliveries")
    second = first_two[1]
    first_task = np.flatnonzero(d["robot"] == second)[0]
    assert d["wait_s"][first_task] > 1.0
    # both keep serving: each delivers several times in 200 s
    assert min(np.count_nonzero(d["robot"] == i) for i in (0, 1)) >= 2


def test_a_docked_robot_is_at_the_spot_facing_its_code(pair):
    _, seen = pair
    assert len(seen) >= 4
    for _, _, (x, y, th) in seen:
        # one_circuit's codes: source at x = 0 facing +x, sink at x = 8 facing -x, both at y = 3
        at_source = x < 4.0
        wall_gap = x if at_source else 8.0 - x
        facing = math.pi if at_source else 0.0
        assert READ_M - 0.05 <= wall_gap <= READ_M + 0.03
        assert abs(y - 3.0) <= LATERAL_TOL_M + 1e-9
        assert abs(math.remainder(th - facing, 2 * math.pi)) <= HEADING_TOL + 1e-9
        assert wall_gap > RADIUS_M  # standing free of the wall, not pressed into it


# Starts all over the two-circuit arena: open floor, corners, hugging the wall beside the
# target's own code and beside the other circuit's code, facing every way.
STARTS = [
    (6.0, 4.0, 0.0), (6.0, 4.0, math.pi), (0.7, 0.7, -2.4), (11.3, 7.3, 0.8), (0.7, 7.3, 2.4),
    (11.3, 0.7, -0.8), (4.9, 7.5, 0.0), (3.1, 7.5, math.pi), (4.0, 7.45, math.pi / 2),
    (8.0, 7.4, -math.pi / 2), (8.9, 0.6, -math.pi / 2), (2.0, 4.0, 1.0), (10.0, 4.0, -2.0),
    (4.0, 0.6, math.pi / 2), (7.6, 7.5, 2.0), (6.0, 0.6, 0.0),
]


@pytest.fixture(scope="module")
def lone_robots(request):
    """One robot per trial on circuit 1 (source at (4, 8)), from each of STARTS, 300 s."""
    mp = pytest.MonkeyPatch()
    request.addfinalizer(mp.undo)
    _with_starts(mp, [[s] for s in STARTS])
    specs = _specs("arena=two_circuits", "team.n_robots=1", "learner.allocation=[1,0]",
                   f"trials={len(STARTS)}", "duration_s=300")
    return run_trials(specs)


def test_a_lone_robot_docks_from_any_start_and_heading(lone_robots):
    for start, rec in zip(STARTS, lone_robots, strict=True):
        a = rec.table("arrivals")
        # the farthest start is about 8.5 m from the source's dock spot: 34 s at 0.25 m/s,
        # plus turning and the final approach; no start may take more than twice that
        assert len(a["t_s"]) > 0 and a["t_s"][0] < 75.0, f"start {start}: first arrival {a['t_s'][:1]}"
        assert a["target"][0] == 0


def test_no_lone_robot_goes_without_delivering(lone_robots):
    for start, rec in zip(STARTS, lone_robots, strict=True):
        d = rec.table("deliveries")
        # a cycle of two legs takes about 80 s: in 300 s at least 3 deliveries from anywhere
        assert len(d["t_s"]) >= 3, f"start {start}: {len(d['t_s'])} deliveries"
        assert np.all(d["escape_s"] == 0.0), f"start {start}: a lone robot should never need to escape"


def test_every_second_of_a_task_is_accounted_for(lone_robots, pair):
    for rec in [*lone_robots, pair[0]]:
        d = rec.table("deliveries")
        spent = sum(d[f"{a}_s"] for a in ACTIVITIES)
        np.testing.assert_allclose(spent, d["task_time_s"], atol=1e-6)


@pytest.mark.slow
@pytest.mark.parametrize("world", [
    (),
    ("robot.dock.dwell_s=5", "robot.dock.occupied_m=1.2"),
    ("robot.behaviour.arrive_dist_m=0.45", "robot.dock.occupied_m=1.5", "robot.laser.n_rays=61"),
])
def test_a_crowd_on_one_circuit_keeps_flowing(monkeypatch, world):
    """Six robots on the small one-circuit arena: waiting robots must not wall in a leaver.

    Nearest-first alone lets a robot lose the race for a dock again and again (one went
    940 s without arriving); the patience bound caps that. The bound is a liveness guard,
    not a prediction: 700 s is about fifteen lone legs, far beyond any fair turn in a queue
    of six, yet a jam at the start can still take a robot several minutes to get through.
    """
    monkeypatch.setattr(trial, "start_poses", ORIGINAL_START_POSES)
    (rec,) = run_trials(_specs("arena=one_circuit", "team.n_robots=6", "trials=1", "duration_s=1800", *world))
    a = rec.table("arrivals")
    for i in range(6):
        times = np.concatenate([[0.0], a["t_s"][a["robot"] == i], [1800.0]])
        assert np.diff(times).max() < 700.0, f"robot {i} stuck"
        assert np.count_nonzero(a["robot"] == i) >= 6
