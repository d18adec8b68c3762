"""The section 1.4.2 behaviours a behaviour-choosing learner selects: stop, wall following,
direct target approach. Each is forced on one robot and its effect checked."""

import math

import numpy as np

from tavc_cli.behaviours import layout
from tavc_cli.config import load_config, to_container
from tavc_cli.experiments.build import trial_specs
from tavc_cli.experiments.engine import BatchEngine


def _engine(behaviour: int, duration_s: float = 120.0) -> BatchEngine:
    cfg = to_container(load_config(["arena=one_circuit", "learner=static", "team.n_robots=1", "trials=1",
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
