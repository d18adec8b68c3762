"""The pymunk world (tavc_cli.sim.world): driving, contacts, removal, trial slots and their spaces."""

import math

import numpy as np
import pymunk
import pytest
import yaml

from tavc_cli.config import find_conf_dir
from tavc_cli.settings import ArenaConfig, from_mapping
from tavc_cli.sim.arena import arena_from_config
from tavc_cli.sim.world import COLLISION_SLOP_M, PhysicsWorld

DT_S = 0.1  # the configured control period (conf/config.yaml sim.dt_s)


@pytest.fixture(scope="module")
def arena():
    """one_circuit: an 8 x 6 m box."""
    with open(find_conf_dir() / "arena" / "one_circuit.yaml") as fh:
        return arena_from_config(from_mapping(ArenaConfig, yaml.safe_load(fh)))


@pytest.fixture(scope="module")
def robot():
    with open(find_conf_dir() / "robot" / "pioneer2dx.yaml") as fh:
        return yaml.safe_load(fh)


def _world(arena, robot, slots, substeps=1):
    return PhysicsWorld(
        arena,
        [np.asarray(s, dtype=np.float64) for s in slots],
        robot["radius_m"],
        robot["mass_kg"],
        robot["drive_force_n"],
        robot["drive_torque_nm"],
        DT_S,
        substeps,
    )


def _run(world, cmd, seconds):
    """Drive with a fixed command; return the poses after every tick, (ticks, n, 3)."""
    cmd = np.asarray(cmd, dtype=np.float64)
    out = []
    for _ in range(int(round(seconds / DT_S))):
        world.poses()
        world.drive(cmd)
        world.step()
        out.append(world.poses().copy())
    return np.array(out)


def test_robot_drives_at_its_commanded_speed_and_turn_rate(arena, robot):
    world = _world(arena, robot, [[(1.0, 1.0, 0.0), (4.0, 3.0, 0.0)]])
    trace = _run(world, [[0.25, 0.0], [0.0, 0.5]], 10.0)
    # steady state (after the first tick): 0.25 m/s * 5 s = 1.25 m; 0.5 rad/s * 5 s = 2.5 rad
    assert trace[-1, 0, 0] - trace[49, 0, 0] == pytest.approx(1.25, abs=1e-6)
    assert trace[-1, 0, 1] == pytest.approx(1.0, abs=1e-6)
    assert trace[-1, 1, 2] - trace[49, 1, 2] == pytest.approx(2.5, abs=1e-6)
    np.testing.assert_allclose(trace[-1, 1, :2], [4.0, 3.0], atol=1e-6)  # turning on the spot


# Discrete time steps let a body move v * dt / substeps into a wall or another body before the
# contact is found; the solver then pushes it back to within the collision slop.


@pytest.mark.parametrize("substeps", [1, 4])
@pytest.mark.parametrize("speed", [0.25, 0.30])
def test_wall_overlap_is_bounded_by_one_step_and_settles(arena, robot, speed, substeps):
    r = robot["radius_m"]
    world = _world(arena, robot, [[(7.0, 3.0, 0.0)]], substeps)
    trace = _run(world, [[speed, 0.0]], 20.0)
    gap = 8.0 - trace[:, 0, 0]
    # never deeper than one physics step's travel plus the slop: 0.25 * 0.1 / 1 + 0.002 = 2.7 cm
    # with one substep, 0.25 * 0.1 / 4 + 0.002 = 0.825 cm with four
    assert gap.min() >= r - (speed * DT_S / substeps + COLLISION_SLOP_M) - 1e-9
    # pressed against the wall for the last 10 s: held within the slop, never through
    assert np.all(gap[-100:] >= r - COLLISION_SLOP_M - 1e-6)
    assert np.all(np.abs(trace[:, 0, 1] - 3.0) < 1e-6)  # a square hit does not slide sideways


@pytest.mark.parametrize("substeps", [1, 4])
def test_head_on_overlap_is_bounded_by_one_step_and_settles(arena, robot, substeps):
    r, v = robot["radius_m"], robot["speed_mps"]
    world = _world(arena, robot, [[(3.0, 3.0, 0.0), (5.0, 3.0, math.pi)]], substeps)
    trace = _run(world, [[v, 0.0], [v, 0.0]], 20.0)
    dist = np.hypot(*(trace[:, 0, :2] - trace[:, 1, :2]).T)
    # closing at 2 * 0.25 = 0.5 m/s: at most 0.5 * 0.1 / substeps + 0.002 deep
    assert dist.min() >= 2 * r - (2 * v * DT_S / substeps + COLLISION_SLOP_M) - 1e-9
    assert np.all(dist[-100:] >= 2 * r - COLLISION_SLOP_M - 1e-6)
    # equal and opposite pushes: they meet in the middle, x = 4, neither gets through
    assert np.all(trace[:, 0, 0] < trace[:, 1, 0])
    assert (trace[-1, 0, 0] + trace[-1, 1, 0]) / 2 == pytest.approx(4.0, abs=1e-6)


def test_removed_robot_no_longer_blocks_and_others_keep_their_poses(arena, robot):
    r = robot["radius_m"]
    # robot 0 drives along y = 3 toward robot 1 (standing at x = 3); robot 2 turns on the spot
    world = _world(arena, robot, [[(2.0, 3.0, 0.0), (3.0, 3.0, 0.0), (6.0, 1.0, 0.0)]])
    cmd = [[0.25, 0.0], [0.0, 0.0], [0.0, 0.5]]
    before = _run(world, cmd, 2.0)[-1]
    assert before[0, 0] < 3.0 - 2 * r + 0.03  # blocked (within one step's overlap)
    world.remove(1)
    assert not world.alive[1]
    after = _run(world, cmd, 8.0)
    # free to drive through where robot 1 stood: 8 s at 0.25 m/s = 2 m further on
    assert after[-1, 0, 0] == pytest.approx(before[0, 0] + 2.0, abs=1e-6)
    assert after[-1, 0, 1] == pytest.approx(3.0, abs=1e-6)
    # robot 2 is still robot 2 after the bodies are re-indexed: 8 s at 0.5 rad/s = 4 rad more
    assert after[-1, 2, 2] - before[2, 2] == pytest.approx(4.0, abs=1e-6)
    np.testing.assert_allclose(after[-1, 2, :2], [6.0, 1.0], atol=1e-6)
    # the removed robot keeps its last pose
    np.testing.assert_array_equal(after[-1, 1], before[1])
    world.remove(1)  # removing twice is harmless
    assert world.n_robots == 3


def test_poses_are_in_each_trials_own_arena_frame(arena, robot):
    r = robot["radius_m"]
    starts = [[(7.0, 3.0, 0.0)], [(7.0, 3.0, 0.0), (2.0, 1.0, 0.0)], [(1.0, 2.0, math.pi)]]
    world = _world(arena, robot, starts)
    np.testing.assert_array_equal(world.slot_of, [0, 1, 1, 2])
    np.testing.assert_allclose(world.poses(), np.concatenate(starts), atol=1e-12)
    # everyone drives forward for 10 s: into their own arena's right wall (slots 0 and 1,
    # and robot 2 only 2.5 m on) or left wall (slot 2), never into a neighbour's
    trace = _run(world, [[0.25, 0.0]] * 4, 10.0)
    end = trace[-1]
    assert end[0, 0] == pytest.approx(8.0 - r, abs=COLLISION_SLOP_M + 1e-6)
    assert end[1, 0] == pytest.approx(8.0 - r, abs=COLLISION_SLOP_M + 1e-6)
    assert end[2, 0] == pytest.approx(2.0 + 0.25 * 9.9, abs=1e-6)  # 99 moving steps (one-tick lag)
    assert end[3, 0] == pytest.approx(r, abs=COLLISION_SLOP_M + 1e-6)
    # identical starts in different slots give the same trajectory
    np.testing.assert_allclose(trace[:, 0], trace[:, 1], atol=1e-9)


def _jostle(arena, robot, seeds, ticks, error_bias=None):
    """Six robots per trial packed into the box and driven by random commands (each trial's own
    draws, from its seed), so they bump into each other and the walls all the time; returns the
    first trial's poses after every tick."""
    starts = []
    for seed in seeds:
        headings = np.random.default_rng(seed).uniform(-math.pi, math.pi, 6)
        starts.append([(1.0 + 1.2 * (k // 2), 1.5 + 1.5 * (k % 2), th) for k, th in enumerate(headings)])
    world = _world(arena, robot, starts)
    if error_bias is not None:
        for _, _, _, pivot, gear in world._parts:
            pivot.error_bias = gear.error_bias = error_bias
    rngs = [np.random.default_rng(100 + seed) for seed in seeds]
    out = []
    for _ in range(ticks):
        world.poses()
        world.drive(np.concatenate([np.column_stack([r.uniform(-0.1, 0.5, 6), r.uniform(-1.0, 1.0, 6)])
                                    for r in rngs]))
        world.step()
        out.append(world.poses()[:6].copy())
    return np.array(out)


def test_a_trial_moves_the_same_alone_or_beside_other_trials(arena, robot):
    # each trial has a space of its own: the other trials' robots, crowded the same way at the
    # same coordinates, change nothing in its contacts, to the last bit (in one shared space,
    # kept apart by collision filters, this trial departed from itself alone within 200 ticks)
    alone = _jostle(arena, robot, [1], 1000)
    moved = np.abs(alone[-1, :, :2] - alone[0, :, :2]).max()
    assert moved > 0.5  # it is not standing still
    np.testing.assert_array_equal(_jostle(arena, robot, [1, 2, 3], 1000), alone)


def test_the_drive_joints_error_bias_changes_nothing(arena, robot):
    # the joints may not correct position error at all (max_bias 0), so how fast they would
    # (error_bias) cannot matter: the world's 0, which Chipmunk computes faster, moves the robots
    # exactly as Chipmunk's own default does, contacts and all
    default = pymunk.PivotJoint(pymunk.Body(), pymunk.Body(), (0, 0)).error_bias
    assert default == pytest.approx(0.9 ** 60, rel=1e-5)  # 90 % corrected each 1/60 s (in float)
    ours = _jostle(arena, robot, [1], 600)
    assert all(joint.error_bias == 0.0 for part in _world(arena, robot, [[(1.0, 1.0, 0.0)]])._parts
               for joint in part[3:])
    np.testing.assert_array_equal(_jostle(arena, robot, [1], 600, error_bias=default), ours)


def test_wall_distance_by_hand():
    from tavc_cli.sim.arena import wall_distance

    walls = np.array([[6.0, 0.0, 6.0, 7.0], [0.0, 4.0, 4.0, 4.0]])
    x = np.array([6.0, 5.0, 2.0, 7.0, 0.0])
    y = np.array([7.5, 3.0, 5.0, 7.0 + 1.0, 4.0])
    # past the end (0.5), beside the first (1.0), above the second (1.0), off the end at 45 degrees (sqrt 2), on it
    np.testing.assert_allclose(wall_distance(walls, x, y), [0.5, 1.0, 1.0, np.sqrt(2.0), 0.0])
    assert np.isinf(wall_distance(np.zeros((0, 4)), np.array(1.0), np.array(1.0)))
