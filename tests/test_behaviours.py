"""The section 1.4.2 behaviours a behaviour-choosing learner selects: stop, wall following,
direct target approach. Each is forced on one robot and its effect checked."""

import math

import numpy as np

from tavc_cli.behaviours import layout
from tavc_cli.config import load_config, settings
from tavc_cli.experiments.build import trial_specs
from tavc_cli.experiments.engine import BatchEngine


def _engine(behaviour: int, duration_s: float = 120.0) -> BatchEngine:
    cfg = settings(load_config(["arena=one_circuit", "learner=static", "team.n_robots=1", "trials=1",
                                    f"duration_s={duration_s}", "convergence_s=0", "scale=paper"]))
    eng = BatchEngine(trial_specs(cfg))
    eng.robots["forced"] = behaviour
    return eng


def _trace(eng: BatchEngine) -> np.ndarray:
    poses = []
    eng.on_tick = lambda e: poses.append(e.pose[0].copy())
    rec = eng.run()[0]
    return np.array(poses), rec


def test_stopping_freezes_the_robot():
    poses, rec = _trace(_engine(layout.BEH_STOP))
    # 120 s standing still: the robot is where it started, to the millimetre
    assert np.abs(poses[:, :2] - poses[0, :2]).max() < 1e-3
    assert len(rec.table("arrivals")["t_s"]) == 0


def test_wall_following_keeps_to_the_boundary_and_passes_targets():
    poses, rec = _trace(_engine(layout.BEH_WALL, duration_s=400.0))
    later = poses[len(poses) // 4:]  # after it has found a wall
    gap = np.minimum.reduce([later[:, 0], 8.0 - later[:, 0], later[:, 1], 6.0 - later[:, 1]])
    # it runs along the walls: its centre mostly within radius + 2 x wall distance of one
    # (0.22 + 2 * 0.5 = 1.22 m), far from the middle of the 8 x 6 m arena
    assert np.mean(gap < 1.22) > 0.8
    # and it goes round: over 400 s at 0.25 m/s it covers most of the 28 m perimeter, so it
    # passes close by the bar-codes in the middle of the short walls and reads them
    assert len(rec.table("arrivals")["t_s"]) >= 1


def test_direct_approach_drives_straight_at_the_target():
    poses, rec = _trace(_engine(layout.BEH_DIRECT, duration_s=200.0))
    arrivals = rec.table("arrivals")
    assert len(arrivals["t_s"]) >= 2  # source and then sink, at least
    # its first leg is nearly straight: path length within 25 % of the start-to-arrival distance
    first = int(round(arrivals["t_s"][0] / 0.1))
    path = np.sum(np.hypot(*np.diff(poses[:first + 1, :2], axis=0).T))
    straight = math.dist(poses[0, :2], poses[first, :2])
    assert path <= 1.25 * straight + 1.0  # + 1 m for turning toward it first


def test_free_distance_is_exact_below_its_reach():
    """Points too far to matter within `reach` are skipped: below reach the answer is the one a
    scan of every point gives, bit for bit, and at or beyond it so is the full answer."""
    from tavc_cli.behaviours.layout import Work, empty_scan, laser_from_angles
    from tavc_cli.behaviours.motion import free_distance
    from tavc_cli.sim.sensors import HIT_NONE, HIT_ROBOT, HIT_WALL

    rng = np.random.default_rng(3)
    laser = laser_from_angles(np.linspace(-math.pi / 2, math.pi / 2, 61))
    work = Work(np.empty(61), np.empty(61), np.empty(61, dtype=np.bool_), np.empty(1, dtype=np.int64))
    below = 0
    for _ in range(300):
        scan = empty_scan(1, 61)
        scan.range_m[0] = rng.uniform(0.25, 3.0, 61)
        scan.kind[0] = rng.choice([HIT_NONE, HIT_WALL, HIT_ROBOT], 61)
        heading = rng.uniform(-1.5, 1.5)
        everything = free_distance(0, heading, 0.22, scan, laser, -999, -1, 1e9, work)
        for reach in (0.25, 0.5, 0.7):
            near = free_distance(0, heading, 0.22, scan, laser, -999, -1, reach, work)
            if everything < reach:
                assert near == everything
                below += 1
            else:
                assert near >= reach
    assert below > 50  # the exact branch was exercised
