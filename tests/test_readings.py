"""The readings of what the chapter leaves unsaid: each a config group with today's world as its
default; arrival read at range, passing on one side, the reward's time from the source."""

import math

import numpy as np
import pytest

from tavc_cli.config import load_config, settings
from tavc_cli.errors import TavcError
from tavc_cli.experiments import trial
from tavc_cli.experiments.build import trial_specs
from tavc_cli.experiments.engine import BatchEngine, run_trials
from tavc_cli.vocabulary import SOURCE


def _specs(*overrides):
    cfg = settings(load_config(["scale=paper", "convergence_s=0", "learner=static", "sim.q_snapshot_every_s=0",
                                "robot.dock.dwell_s=0", *overrides]))
    return trial_specs(cfg)


def _with_starts(monkeypatch, poses):
    queue = [np.asarray(p, dtype=float) for p in poses]
    monkeypatch.setattr(trial, "start_poses", lambda arena, radii, rng: queue.pop(0))


def test_todays_world_is_every_readings_default():
    cfg = settings(load_config(["experiment=initial_distribution"]))
    assert (cfg.robot.behaviour.arrival, cfg.robot.behaviour.passing, cfg.tasks.time_from) == (
        "dock", "nearest", "choice")
    assert cfg.arena.name == "two_circuits"
    chosen = settings(load_config(["experiment=initial_distribution", "arrival=range", "passing=left",
                                   "reward_time=source", "arena=two_circuits_parallel"]))
    assert (chosen.robot.behaviour.arrival, chosen.robot.behaviour.passing, chosen.tasks.time_from) == (
        "range", "left", "source")
    # in the parallel layout each sink lies straight across from its source: x 4 and x 8
    xy = {t.name: (t.x, t.y) for t in chosen.arena.targets}
    assert (xy["source1"][0], xy["sink1"][0], xy["source2"][0], xy["sink2"][0]) == (4.0, 4.0, 8.0, 8.0)


@pytest.mark.parametrize(("override", "message"), [
    ("robot.behaviour.arrival=teleport", "robot.behaviour.arrival: must be one of dock, range; got 'teleport'"),
    ("robot.behaviour.passing=up", "robot.behaviour.passing: must be one of nearest, left, right; got 'up'"),
    ("tasks.time_from=sink", "tasks.time_from: must be one of choice, source; got 'sink'"),
    ("robot.behaviour.read_range_m=0", "robot.behaviour.read_range_m: must be > 0, got 0.0"),
])
def test_a_reading_that_does_not_exist_is_one_line(override, message):
    with pytest.raises(TavcError) as caught:
        load_config(["experiment=initial_distribution", override])
    assert str(caught.value) == message


def test_arrival_at_range_fires_where_the_code_is_read_not_at_the_dock_spot(monkeypatch):
    """one_circuit, the source's code at (0, 3) facing +x: a robot heading for it from (4, 3)
    arrives about 1.5 m out (the laser reads the code from the robot's centre), not at 0.45 m."""
    arrivals = {}
    for reading in ("dock", "range"):
        _with_starts(monkeypatch, [[[4.0, 3.0, math.pi]]])
        eng = BatchEngine(_specs("arena=one_circuit", "team.n_robots=1", "trials=1", "duration_s=60",
                                 f"arrival={reading}")[:1])
        seen = []
        eng.on_tick = lambda e, seen=seen: seen.extend(e.pose[g].copy() for g in np.flatnonzero(e.robots["arrived"]))
        eng.run()
        arrivals[reading] = seen[0]
    assert 1.35 <= arrivals["range"][0] <= 1.5 + 1e-9  # x of the robot's centre: the code read within 1.5 m
    assert arrivals["dock"][0] < 0.6


def test_the_reward_runs_from_the_loading_where_the_reading_says_so():
    """Every delivery's reward is w / t with t from the robot's last arrival at its source (in ms),
    computed by hand from the record's arrivals; the task time stays the whole task."""
    specs = _specs("arena=two_circuits", "team.n_robots=3", "trials=2", "duration_s=400", "reward_time=source",
                   "learner=tavc_egreedy")
    for rec in run_trials(specs):
        arrivals, deliveries = rec.table("arrivals"), rec.table("deliveries")
        assert len(deliveries["t_s"]) >= 6
        for t, robot, reward, value, task in zip(deliveries["t_s"], deliveries["robot"], deliveries["reward"],
                                                 deliveries["value"], deliveries["task_time_s"], strict=True):
            loaded = [a for a, r, k in zip(arrivals["t_s"], arrivals["robot"], arrivals["kind"], strict=True)
                      if r == robot and k == SOURCE and a < t]
            assert reward == pytest.approx(value / ((t - loaded[-1]) * 1000.0), rel=1e-9)
            assert task > t - loaded[-1]  # the empty leg is in the task's time, not in the reward's


def test_keeping_left_passes_an_oncoming_robot_on_the_left(monkeypatch):
    """Two robots meet head-on on one_circuit's line y = 3 (one from the source end, one from the
    sink end, each heading for the far code): keeping left, each swerves to its own left, so the
    one heading +x passes above the line and the one heading -x below it; keeping right, the reverse."""
    side = {}
    for reading in ("left", "right"):
        _with_starts(monkeypatch, [[[2.5, 3.0, 0.0], [5.5, 3.0, math.pi]]])
        specs = _specs("arena=one_circuit", "team.n_robots=2", "trials=1", "duration_s=25", f"passing={reading}")
        eng = BatchEngine(specs[:1])
        eng.robots["target"][:] = [1, 0]  # robot 0 to the sink (x = 8), robot 1 to the source (x = 0)
        ys = {0: [], 1: []}

        def watch(e, ys=ys):
            for g in (0, 1):
                ys[g].append(float(e.pose[g, 1]))

        eng.on_tick = watch
        eng.run()
        side[reading] = (max(ys[0], key=lambda y: abs(y - 3.0)) - 3.0, max(ys[1], key=lambda y: abs(y - 3.0)) - 3.0)
    assert side["left"][0] > 0.2 and side["left"][1] < -0.2
    assert side["right"][0] < -0.2 and side["right"][1] > 0.2
