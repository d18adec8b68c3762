"""Every bad input is refused before anything is written; every accepted config runs.

Property-based (hypothesis) over the config space, plus one example per refusal rule.
"""

import math
import re
from types import SimpleNamespace

import numpy as np
import pytest
from hydra.core.override_parser.overrides_parser import OverridesParser
from hypothesis import HealthCheck, assume, event, given, settings
from hypothesis import strategies as st
from typer.testing import CliRunner

from tavc_cli import api
from tavc_cli.cli import app
from tavc_cli.config import load_config
from tavc_cli.errors import TavcError
from tavc_cli.learning.registry import controller_label
from tavc_cli.override_keys import setting

runner = CliRunner()
# one line `error: <key>: <rule>`, the key a dotted path with optional [index] parts
ERROR_LINE = re.compile(r"^error: [A-Za-z_][\w.\[\]=]*: \S.*$")
TOP_KEYS = {"arena", "robot", "team", "learner", "scale", "executor", "experiment_name", "seed", "trials",
            "baseline_trials", "duration_s", "convergence_s", "output_dir", "paper", "baselines",
            "static_allocation", "tasks", "events", "sim", "analysis", "model", "calibration"}
# every run is as short as the config space allows: one trial of each controller, one process
FIXED = ["scale=smoke", "trials=1", "baseline_trials=1", "executor.n_jobs=1"]


# ------------------------------------------------------------------------------- strategies


def _num(value: float) -> str:
    """A float as Hydra's override grammar reads it."""
    return repr(float(value))


def _list(values) -> str:
    return "[" + ",".join(str(v) for v in values) + "]"


@st.composite
def _pick(draw, good, bad, bad_percent: int):
    """``good``, or ``bad`` with the given chance (shrinks toward good)."""
    return draw(bad) if draw(st.integers(0, 99)) < bad_percent else draw(good)


@st.composite
def _split(draw, total: int, parts: int) -> list[int]:
    """``parts`` non-negative counts summing to ``total``."""
    cuts = sorted(draw(st.lists(st.integers(0, total), min_size=parts - 1, max_size=parts - 1)))
    return [b - a for a, b in zip([0, *cuts], [*cuts, total], strict=True)]


_BAD_UNIT = st.one_of(st.floats(-2, -0.01), st.floats(1.01, 5), st.just(math.nan))


@st.composite
def configs(draw, bad_percent: int) -> list[str]:
    """Overrides over arenas, teams, learners, task values, events and sensors, each key bad
    with ``bad_percent`` % chance (bad types, ranges, lengths, sums, times, geometry)."""
    bad = bad_percent

    def pick(good, wrong, percent: int = bad):
        return draw(_pick(good, wrong, percent))

    arena = draw(st.sampled_from(["one_circuit", "two_circuits"]))
    n_circuits = 1 if arena == "one_circuit" else 2
    n_robots = pick(st.integers(1, 8), st.sampled_from([0, -1, 60]))
    duration_s = pick(st.floats(20, 40), st.sampled_from([0.0, -5.0, 0.05, math.nan]))
    # an unknown learner fails at composition, before any other check: rarer, so as not to hide them
    learner = pick(st.sampled_from(["random", "static", "tavc_egreedy", "tavc_softmax", "behaviour_softmax"]),
                   st.just("greedy"), bad // 3)
    out = [*FIXED, f"arena={arena}", f"team.n_robots={n_robots}", f"duration_s={_num(duration_s)}",
           f"learner={learner}"]
    for name in ("epsilon", "alpha", "gamma"):
        out.append(f"learner.{name}={_num(pick(st.floats(0, 1), _BAD_UNIT))}")
    team = max(n_robots, 0)
    if learner == "static" and draw(st.booleans()):
        good = _split(team, n_circuits)
        wrong = st.one_of(_split(team + 1, n_circuits), _split(team, n_circuits + 1), st.just([-1] * n_circuits))
        out.append(f"learner.allocation={_list(pick(good, wrong))}")
    if draw(st.booleans()):
        out.append("baselines=[static]")
        if draw(st.booleans()):
            wrong = st.one_of(_split(team + 2, n_circuits), _split(team, n_circuits + 1))
            out.append(f"static_allocation={_list(pick(_split(team, n_circuits), wrong))}")
    else:
        out.append("baselines=[]")
    if draw(st.booleans()):
        values = st.lists(st.floats(1, 3000), min_size=n_circuits, max_size=n_circuits)
        wrong = st.one_of(st.lists(st.floats(1, 3000), min_size=n_circuits + 1, max_size=n_circuits + 1),
                          st.lists(st.sampled_from([math.nan, math.inf]), min_size=n_circuits, max_size=n_circuits))
        out.append(f"tasks.values={_list(_num(v) for v in pick(values, wrong))}")
    if draw(st.booleans()):
        out.append("team=heterogeneous")  # its members, unless a list of our own follows
        if draw(st.booleans()):
            speed = pick(st.floats(0.1, 0.5), st.sampled_from([0.0, -0.1, 5.0]))
            size = pick(st.just(team), st.sampled_from([team + 1, max(team - 1, 0)]))
            members = [f"{{speed_mps:{_num(speed)},group:g{i % 2}}}" for i in range(size)]
            out.append(f"team.members={_list(members)}")
    # event times are scaled by scale.time_factor (0.02 at smoke): user seconds are 50 of these
    horizon = 50 * (duration_s if math.isfinite(duration_s) and duration_s > 0 else 20.0)
    breakdowns = []
    for _ in range(draw(st.integers(0, 2))):
        time_s = pick(st.floats(0, 0.95 * horizon), st.sampled_from([-100.0, 2 * horizon, math.nan]))
        target = pick(st.one_of(st.just("robot:null"), st.integers(0, max(team - 1, 0)).map(lambda r: f"robot:{r}"),
                                st.sampled_from(["circuit:high", "circuit:low"]),
                                st.integers(0, n_circuits - 1).map(lambda c: f"circuit:'{c}'")),
                      st.sampled_from([f"robot:{team}", f"circuit:'{n_circuits}'", "circuit:middle"]))
        breakdowns.append(f"{{time_s:{_num(time_s)},{target}}}")
    if breakdowns:
        out.append(f"events.breakdowns={_list(breakdowns)}")
    if draw(st.integers(0, 3)) == 0:  # interior walls: inside the arena, or outside it / of no length
        width, height = (8.0, 6.0) if arena == "one_circuit" else (12.0, 8.0)
        walls = []
        for _ in range(draw(st.integers(1, 2))):
            x1, x2 = draw(st.floats(0, width)), draw(st.floats(0, width))
            y1, y2 = draw(st.floats(0, height)), draw(st.floats(0, height))
            wall = pick(st.just([x1, y1, x2, y2]), st.sampled_from([[x1, y1, x1, y1], [x1, -1.0, x2, y2],
                                                                    [x1, y1, width + 1.0, y2]]))
            walls.append(_list(_num(v) for v in wall))
        out.append(f"arena.walls={_list(walls)}")
    if draw(st.booleans()):
        out.append(f"robot.laser.n_rays={pick(st.integers(3, 64), st.integers(-1, 2))}")
    if draw(st.booleans()):
        out.append(f"robot.speed_mps={_num(pick(st.floats(0.05, 1.0), st.sampled_from([0.0, -0.1, 2.0])))}")
    if draw(st.booleans()):
        out.append(f"sim.dt_s={_num(pick(st.sampled_from([0.05, 0.1, 0.2]), st.sampled_from([0.0, -0.1, 1000.0])))}")
    if draw(st.booleans()):
        out.append(f"executor.batch_size={pick(st.integers(1, 32), st.sampled_from([0, 33]))}")
    return out


# ------------------------------------------------------------------------------- properties


@pytest.mark.slow
@settings(max_examples=8, deadline=None, database=None,
          suppress_health_check=[HealthCheck.too_slow, HealthCheck.filter_too_much])
@given(overrides=configs(bad_percent=0))
def test_every_accepted_config_runs_a_short_trial(overrides, tmp_path_factory):
    out = tmp_path_factory.mktemp("accepted") / "out"
    try:
        results = api.run(overrides, output_dir=out)
    except TavcError as error:
        assert not out.exists(), f"refused after writing into {out}"
        event(f"refused: {str(error).split(':')[0]}")
        assume(False)  # refused up front: property B's business
    cfg = results.config  # the resolved config the run wrote
    records = results.records()
    # one trial per controller; a baseline that is the learner itself runs once
    assert sorted(r.meta["controller"] for r in records) == sorted({controller_label(cfg["learner"]["name"]),
                                                                   *cfg["baselines"]})
    for record in records:
        assert record.meta["n_robots"] == cfg["team"]["n_robots"]
        deliveries = record.table("deliveries")
        t_s = deliveries["t_s"]
        assert np.all((t_s >= -cfg["sim"]["warmup_s"]) & (t_s < cfg["duration_s"]))
        assert np.all(np.isfinite(deliveries["reward"]))
        assert len(record.table("breakdowns")["t_s"]) <= len(cfg["events"]["breakdowns"])
    assert (out / "state_time.csv").is_file() and (out / "config.yaml").is_file()


@pytest.mark.slow
@settings(max_examples=30, deadline=None, database=None,
          suppress_health_check=[HealthCheck.too_slow, HealthCheck.filter_too_much])
@given(overrides=configs(bad_percent=15))
def test_every_refused_config_is_one_line_and_writes_nothing(overrides, tmp_path_factory):
    out = tmp_path_factory.mktemp("refused") / "out"
    result = runner.invoke(app, ["run", *overrides, f"output_dir={out}"])
    assume(result.exit_code != 0)  # accepted (and run in a second): property A's business
    assert result.exception is None or isinstance(result.exception, SystemExit), repr(result.exception)
    assert result.exit_code == 1, result.output
    lines = [line for line in result.output.splitlines() if line.strip()]
    assert len(lines) == 1 and lines == [result.stderr.strip()], result.output
    assert ERROR_LINE.match(lines[0]), lines[0]
    key = lines[0].removeprefix("error: ").split(": ")[0]
    assert re.split(r"[.\[=]", key)[0] in TOP_KEYS, lines[0]
    event(f"refused: {key}")
    assert not out.exists()


# --------------------------------------------------------------------------- each rule, once

# By hand, for the rows below: the default world (conf/world/calibrated.yaml) has a 0.22 m
# radius robot at 0.25 m/s, arrive_dist_m 0.45, approach_m 0.8 and lateral_tol_m 0.1; bar-codes
# are 0.6 m wide; smoke scales times by 0.02.
REFUSED = [
    (["learner=tavc_egreedy", "learner.q_init_high=inf"], "learner.q_init_high: must be a finite number, got inf"),
    (["learner=tavc_egreedy", "learner.q_init_low=-1e308", "learner.q_init_high=1e308"],
     "learner.q_init_high: the range [-1e+308, 1e+308] is too wide (the initial Q-values are drawn from "
     "[q_init_low, q_init_high])"),
    # a learner's node holds its own parameters only: random has none
    (["learner=random", "+learner.alpha=0.2"],
     "learner.alpha: the learner random takes no parameter alpha (it takes no parameters)"),
    (["learner=random", "learner.alpha=0.2"], "learner.alpha: the learner random takes no parameter alpha (it takes "
                                              "no parameters)"),
    # a near miss of a parameter the learner takes is named, and every one it takes
    (["learner=tavc_egreedy", "learner.epsilonn=0.1"],
     "learner.epsilonn: the learner tavc_egreedy takes no parameter epsilonn (did you mean 'epsilon'? it takes alpha, "
     "gamma, epsilon, q_init_low, q_init_high)"),
    # a learner from a file takes its own parameters under learner.params
    (["learner=plugin", "learner.name=mine", "learner.target=x.py:C", "learner.alpha=0.1"],
     "learner.alpha: the learner mine comes from learner.target and takes its parameters as learner.params.<key>"),
    # its trials' records are files named after it: a name longer than a file name may be is refused up front
    (["learner=plugin", f"learner.name={'a' * 129}", "learner.target=x.py:C"],
     "learner.name: at most 128 bytes (its trials' records are files named after it), got 129"),
    (["learner=random", "+learner.params.a=1"],
     "learner.params: only a learner from learner.target takes params; set random's parameters as learner.<name>"),
    # the warm-up is checked as written (before smoke's 0.02 would make it -0.1)
    (["sim.warmup_s=-5"], "sim.warmup_s: must be >= 0, got -5.0"),
    (["arena.width_m=1"],
     "arena.width_m: must be at least 1.2 m (robots start at least 0.6 m from every wall), got 1"),
    (["arena=one_circuit", "arena.height_m=1", "arena.targets.0.y=0.5", "arena.targets.1.y=0.5"],
     "arena.height_m: must be at least 1.2 m (robots start at least 0.6 m from every wall), got 1"),
    (["robot.radius_m=0.65", "robot.behaviour.arrive_dist_m=0.7"],
     "robot.radius_m: must be less than 0.6 m (robots start with their centres 0.6 m from the walls), got 0.65"),
    (["robot.laser.n_rays=2"],
     "robot.laser.n_rays: must be >= 3 (a ray ahead to read bar-codes and rays to the sides to avoid robots "
     "and follow walls), got 2"),
    # 0.45 + 0.8 = 1.25 m
    (["robot.laser.range_m=1"],
     "robot.laser.range_m: must reach the start of the final approach, robot.behaviour.arrive_dist_m + "
     "robot.dock.approach_m = 1.25 m, got 1"),
    # max(0.6 / 2, 0.22 + 0.03) = 0.3 m from either end of the wall
    (["arena.targets.0.x=0", "arena.targets.0.y=0"],
     "arena.targets[0]: target (0.0, 0.0) lies 0 m from a corner; it needs 0.3 m for its bar-code "
     "(arena.barcode_width_m / 2 = 0.3) and a robot docked in front of it (robot.radius_m + 0.03 = 0.25)"),
    (["arena=one_circuit", "arena.targets.1.y=5.9"],
     "arena.targets[1]: target (8.0, 5.9) lies 0.1 m from a corner; it needs 0.3 m for its bar-code "
     "(arena.barcode_width_m / 2 = 0.3) and a robot docked in front of it (robot.radius_m + 0.03 = 0.25)"),
    (["arena.targets.1.x=4.2"],
     "arena.targets[1]: target (4.2, 8.0)'s bar-code overlaps that of arena.targets[0] on the top wall: their "
     "centres must be at least arena.barcode_width_m = 0.6 m apart, got 0.2"),
    # 80 discs 0.74 m across cover 80 * pi * 0.37^2 = 34.4 m^2 of the (8 - 1.2 + 0.74) x (6 - 1.2 + 0.74)
    # = 41.8 m^2 their centres may reach: far beyond random packing (about 0.55 of it), so trial 0 fails;
    # start area (8 - 1.2) x (6 - 1.2) = 32.64 m^2, d = 2 * 0.22 + 0.3 = 0.74 m, pi d^2 = 1.7203 m^2:
    # 1 + floor(0.99 * 32.64 / 1.7203) = 1 + floor(18.78) = 19 always fit
    (["arena=one_circuit", "team.n_robots=80"],
     "team.n_robots: cannot place 80 robots of robot.radius_m = 0.22 at random 0.3 m apart and 0.6 m from the "
     "walls of the 8 x 6 m arena (trial 0 of random, seed 0); 19 always fit"),
    # too fast even at the usual period: 2 m/s x 0.1 s = 0.2 m, at most 0.1 m / 0.1 s = 1 m/s
    (["robot.speed_mps=2"],
     "robot.speed_mps: 2 m/s would carry the robot 0.2 m in one control period (sim.dt_s = 0.1 s), past its "
     "docking tolerance robot.dock.lateral_tol_m = 0.1 m, so it could overshoot every dock; at most 1 m/s at "
     "this period"),
    # a member of a heterogeneous team likewise, named by its own key
    (["experiment=heterogeneous", "team.members.4.speed_mps=1000"],
     "team.members[4].speed_mps: 1000 m/s would carry the robot 100 m in one control period (sim.dt_s = 0.1 s), "
     "past its docking tolerance robot.dock.lateral_tol_m = 0.1 m, so it could overshoot every dock; at most 1 m/s "
     "at this period"),
    # 0.1 m / 0.25 m/s = 0.4 s: the period is what is out of line
    (["sim.dt_s=0.5"],
     "sim.dt_s: must be at most robot.dock.lateral_tol_m / top speed = 0.1 m / 0.25 m/s = 0.4 s (no robot may "
     "move further than its docking tolerance in one control period), got 0.5"),
    # the fast members (0.3 m/s) set the limit: 0.1 / 0.3 = 0.333333 s
    (["experiment=heterogeneous", "sim.dt_s=0.4"],
     "sim.dt_s: must be at most robot.dock.lateral_tol_m / top speed = 0.1 m / 0.3 m/s = 0.333333 s (no robot "
     "may move further than its docking tolerance in one control period), got 0.4"),
    # a robot that could not get going within a trial (smoke: 18,000 s x 0.02 = 360 s, no warm-up):
    # 1e9 kg x 0.25 m/s / 60 N = 4.17e6 s; the usual 15 kg would take 0.0625 s, so the mass is named
    (["robot.mass_kg=1e9"],
     "robot.mass_kg: a robot of robot.mass_kg = 1e+09 kg driven with at most robot.drive_force_n = 60 N would "
     "need 4.17e+06 s from rest to reach its speed of 0.25 m/s, longer than a whole trial (sim.warmup_s + "
     "duration_s = 360 s); it would never move as its settings say"),
    # 15 kg x 0.25 m/s / 0.001 N = 3,750 s: even the usual mass is too heavy for that drive, so it is named
    (["robot.drive_force_n=0.001"],
     "robot.drive_force_n: a robot of robot.mass_kg = 15 kg driven with at most robot.drive_force_n = 0.001 N "
     "would need 3.75e+03 s from rest to reach its speed of 0.25 m/s, longer than a whole trial (sim.warmup_s + "
     "duration_s = 360 s); it would never move as its settings say"),
    # a disc's moment 15 kg x 0.22^2 m^2 / 2 = 0.363 kg m^2, x 1.2 rad/s / 1e-6 N m = 435,600 s
    (["robot.drive_torque_nm=1e-6"],
     "robot.drive_torque_nm: a robot of robot.mass_kg = 15 kg driven with at most robot.drive_torque_nm = 1e-06 "
     "N m would need 4.36e+05 s from rest to reach its turn rate of 1.2 rad/s, longer than a whole trial "
     "(sim.warmup_s + duration_s = 360 s); it would never move as its settings say"),
    (["duration_s=0.05"], "duration_s: must be at least one control period (sim.dt_s = 0.1 s), got 0.05"),
    # narrower bins only cost memory: 1e-6 s bins over a 30 s run took 4 GB
    (["analysis.performance_bin_s=0.01"],
     "analysis.performance_bin_s: must be at least one control period (sim.dt_s = 0.1 s), got 0.01"),
    (["events.value_changes=[{time_s:10,values:[nan,1]}]"],
     "events.value_changes[0].values[0]: must be a finite number, got nan"),
    (["events.value_changes=[{time_s:10,values:[1,inf]}]"],
     "events.value_changes[0].values[1]: must be a finite number, got inf"),
    (["experiment=breakdown", "tasks.values=[2000,2000]"],
     "events.breakdowns[0].circuit: 'high' names no single circuit: tasks.values tie at 2000 ([2000.0, 2000.0]); "
     "give a circuit index"),
    (["experiment=breakdown_no_vacancy", "tasks.values=[2000,2000]"],
     "events.breakdowns[0].circuit: 'low' names no single circuit: tasks.values tie at 2000 ([2000.0, 2000.0]); "
     "give a circuit index"),
    # the values changed at 5 * 0.02 = 0.1 s tie when the robot breaks down at 10 * 0.02 = 0.2 s
    (["tasks.values=[1,2]", "events.value_changes=[{time_s:5,values:[3,3]}]",
      "events.breakdowns=[{time_s:10,circuit:high}]"],
     "events.breakdowns[0].circuit: 'high' names no single circuit: the values from the value change at 0.1 s "
     "tie at 3 ([3.0, 3.0]); give a circuit index"),
    # refusals that held before, now also shown to write nothing
    (["events.breakdowns=[{time_s:10,robot:6}]"],
     "events.breakdowns[0].robot: must be a robot index in [0, 6), got 6"),
    (["events.breakdowns=[{time_s:10,circuit:'2'}]"],
     "events.breakdowns[0].circuit: must be null, high, low or a circuit index in [0, 2), got '2'"),
    (["experiment=breakdown", "events.breakdowns.0.time_s=30000"],
     "events.breakdowns[0].time_s: 600 s (after scaling) is outside the simulated time "
     "[-sim.warmup_s = -360, duration_s = 540)"),
    # at smoke scale (x 0.02) the trial runs (360 + 540) / 0.1 = 9000 periods, ticks 0-8999; 539.99 s is
    # 899.99 s on its clock, which only tick 9000 (900 s) reaches
    (["experiment=breakdown", "events.breakdowns.0.time_s=26999.5"],
     "events.breakdowns[0].time_s: 539.99 s (after scaling) would fall due at tick 9000, after the trial's last "
     "tick, 8999 (its 9000 periods of sim.dt_s = 0.1 s from the start of the warm-up), so it would never happen"),
    # in decimals 22792.0 + 4835.9 = 27627.9 = 92093 x 0.3 s, the last of round(27628.3 / 0.3) = 92094 ticks;
    # in binary floating point 92093 x 0.3 falls short of the sum, which the engine compares it with
    (["experiment=breakdown", "scale=paper", "sim.dt_s=0.3", "sim.warmup_s=4835.9", "duration_s=22792.4",
      "events.breakdowns.0.time_s=22792.0"],
     "events.breakdowns[0].time_s: 22792 s (after scaling) would fall due at tick 92094, after the trial's last "
     "tick, 92093 (its 92094 periods of sim.dt_s = 0.3 s from the start of the warm-up), so it would never happen"),
    (["learner=static", "learner.allocation=[4,1]"], "learner.allocation: must sum to team.n_robots (6), got 5"),
    (["baselines=[static]", "static_allocation=[6]"],
     "static_allocation: needs one robot count per circuit (2), got 1"),
    (["tasks.values=[1,2,3]"], "tasks.values: needs one value per circuit (2), got 3"),
    # a learning value is positive (the reward is value / time), a score value not negative
    (["tasks.values=[0,2000]"], "tasks.values[0]: must be > 0 (the reward is the value over the task time), got 0.0"),
    (["events.value_changes=[{time_s:10,values:[2000,-1]}]"],
     "events.value_changes[0].values[1]: must be > 0 (the reward is the value over the task time), got -1.0"),
    (["tasks.score_values=[-1,1]"], "tasks.score_values[0]: must be >= 0, got -1.0"),
    # 6 robots x 360 s / 0.1 s = 21,600 deliveries at most; sqrt(1.797e308) = 1.341e154, / 21,600 = 6.21e149
    (["tasks.score_values=[1e300,1]"],
     "tasks.score_values[0]: 1e+300 is more than 6.21e+149: scores are summed over a trial's deliveries (at most "
     "21,600, one per robot and control period) and squared in the spread over trials, and that must stay a "
     "finite number"),
    # the score values left unset follow the learning values: the key set is named
    (["tasks.score_values=null", "tasks.values=[1e300,1]"],
     "tasks.values[0]: 1e+300 is more than 6.21e+149: scores are summed over a trial's deliveries (at most 21,600, "
     "one per robot and control period) and squared in the spread over trials, and that must stay a finite number "
     "(tasks.score_values follows it)"),
    # packed hexagonally, discs of 2 x 0.22 + 0.3 = 0.74 m round centres in the 10.8 x 6.8 m start area fill
    # at most 2 (10.8 + 0.74)(6.8 + 0.74) / (sqrt 3 x 0.74^2) = 183.5 of the arena: refused at once
    (["team.n_robots=100000"], "team.n_robots: 100000 robots of robot.radius_m = 0.22 cannot start 0.3 m apart in "
     "the 12 x 8 m arena: at most 183 would fit even packed as closely as discs can be"),
    (["duration_s=inf"], "duration_s: must be a finite number > 0, got inf"),
    # config groups take an option's name; a list element needs a list
    (["robot=null"], "robot: a config group takes the name of one of its options, got null"),
    (["scale=123"], "scale: a config group takes the name of one of its options, got 123"),
    (["=5"], "=5: an override needs a key (key=value)"),
    (["team.members.0.speed_mps=0.3"],
     "team.members.0.speed_mps: team.members is null in this config, so it has no element 0; "
     "give the whole list (team.members=[...])"),
    # interior walls (the arena is 12 x 8 m, sink2's bar-code at (4, 0), robots 0.22 m in radius):
    # a wall across the arena, or one leaving a 0.4 m gap (< 2 x 0.22), cuts it in two ...
    (["arena=two_circuits", "arena.walls=[[6,0,6,8]]"],
     "arena.walls: the walls split the area where robots start into 2 parts that a robot of robot.radius_m = 0.22 "
     "cannot pass between"),
    (["arena=two_circuits", "arena.walls=[[6,0,6,7.6]]"],
     "arena.walls: the walls split the area where robots start into 2 parts that a robot of robot.radius_m = 0.22 "
     "cannot pass between"),
    # ... a box around sink2 closes it off, a wall through its dock leaves no room to dock
    (["arena=two_circuits", "arena.walls=[[0,1.2,5,1.2],[5,1.2,5,0]]"],
     "arena.targets[2]: target 'sink2' cannot be reached by a robot of robot.radius_m = 0.22 from where robots "
     "start: arena.walls close it off or leave no room to dock in front of it"),
    (["arena=two_circuits", "arena.walls=[[4,0,4,2]]"],
     "arena.targets[2]: target 'sink2' cannot be reached by a robot of robot.radius_m = 0.22 from where robots "
     "start: arena.walls close it off or leave no room to dock in front of it"),
    (["executor.batch_size=0"], "executor.batch_size: must be >= 1, got 0"),
    (["executor.n_jobs=0"], "executor.n_jobs: must be >= 1, got 0"),
    (["sim.dt_s=0"], "sim.dt_s: must be > 0, got 0.0"),
    (["team.members=[{speed_mps:0.3}]"], "team.n_robots: 6 does not match the 1 robots listed in team.members"),
    (["learner=tavc_egreedy", "learner.epsilon=1.5"], "learner.epsilon: must be in [0, 1], got 1.5"),
]


@pytest.mark.parametrize(("overrides", "message"), REFUSED, ids=[" ".join(o) for o, _ in REFUSED])
def test_a_bad_input_is_refused_in_one_line_before_anything_is_written(overrides, message, tmp_path):
    out = tmp_path / "out"
    result = runner.invoke(app, ["run", "scale=smoke", *overrides, f"output_dir={out}"])
    assert isinstance(result.exception, SystemExit), repr(result.exception)
    assert result.exit_code == 1, result.output
    assert result.stderr.strip() == f"error: {message}"
    assert result.stdout == ""
    assert not out.exists()


@pytest.mark.parametrize(
    "overrides",
    [
        # 1 + floor(0.99 * 10.8 * 6.8 / 1.7203) = 43 robots always fit the 12 x 8 m arena; 60 are placed
        # trial by trial (at its seeds), as is the benchmark's largest team on one circuit
        ["team.n_robots=43"],
        ["team.n_robots=60"],
        ["arena=one_circuit", "team.n_robots=24"],
        ["arena=one_circuit", "arena.targets.1.y=5.7"],  # 0.3 m from the corner: just fits
        ["arena.targets.1.x=4.6"],  # bar-codes edge to edge (0.6 m apart, up to rounding)
        ["robot.laser.n_rays=3", "robot.laser.range_m=1.25"],
        ["robot.speed_mps=1", "sim.dt_s=0.1"],  # 0.1 m per control period: the tolerance itself
        # a breakdown at the instant of a value change comes first, under the old values
        ["tasks.values=[1,2]", "events.value_changes=[{time_s:5,values:[3,3]}]",
         "events.breakdowns=[{time_s:5,circuit:high}]"],
        ["arena=one_circuit", "events.breakdowns=[{time_s:0,circuit:high}]"],  # one circuit: no tie
        # 26995 x 0.02 = 539.9 s, 899.9 s on the clock: the trial's last tick, 8999 (of 9000), reaches it
        ["experiment=breakdown", "events.breakdowns.0.time_s=26995"],
        # interior walls that leave a way round: a 1 m gap (> 2 x 0.22 m), a 1.2 m corridor to the sinks
        ["arena=two_circuits", "arena.walls=[[6,0,6,7]]"],
        ["arena=two_circuits", "arena.walls=[[0,1.2,10,1.2]]"],
    ],
)
def test_inputs_at_the_limits_are_accepted(overrides):
    load_config(["scale=smoke", *overrides])


@pytest.mark.parametrize(("width_m", "height_m", "always"), [(12.0, 8.0, 43), (8.0, 6.0, 19)])
def test_a_team_that_always_fits_is_placed_at_every_seed(width_m, height_m, always):
    from tavc_cli.experiments.trial import start_poses

    arena = SimpleNamespace(width_m=width_m, height_m=height_m, walls=np.zeros((4, 4)))  # the outer ones only
    for seed in range(20):
        assert len(start_poses(arena, np.full(always, 0.22), np.random.default_rng(seed))) == always


@settings(max_examples=300, deadline=None, database=None)
@given(text=st.text().filter(lambda t: "${" not in t))
def test_a_value_set_to_the_letter_is_read_back_as_written(text):
    """A folder tavc names in an override it writes (a run's under a results folder the user chose)
    reads back as the same text, whatever its characters: a comma is no sweep, a backslash is one."""
    assert OverridesParser.create().parse_override(setting("output_dir", text)).value() == text


def test_the_root_of_the_file_system_is_no_output_dir():
    with pytest.raises(TavcError, match="^output_dir: / is the root of the file system; give the results a folder"):
        load_config(["scale=smoke", "output_dir=/"])


def test_robots_start_clear_of_interior_walls():
    from tavc_cli.experiments.trial import start_poses
    from tavc_cli.sim.arena import START_WALL_MARGIN_M, arena_from_config, wall_distance

    cfg = load_config(["scale=smoke", "arena=two_circuits", "arena.walls=[[6,0,6,7],[0,4,4,4]]"])
    arena = arena_from_config(cfg.arena)
    for seed in range(20):
        poses = start_poses(arena, np.full(12, 0.22), np.random.default_rng(seed))
        assert wall_distance(arena.walls[4:], poses[:, 0], poses[:, 1]).min() >= START_WALL_MARGIN_M


def test_a_cluster_backend_whose_module_is_missing_is_refused_up_front(monkeypatch, tmp_path):
    import importlib.util

    find_spec = importlib.util.find_spec
    monkeypatch.setattr(importlib.util, "find_spec", lambda name, *a: None if name == "distributed" else
                        find_spec(name, *a))
    out = tmp_path / "out"
    result = runner.invoke(app, ["run", "scale=smoke", "executor.backend=dask", f"output_dir={out}"])
    assert result.exit_code == 1
    assert result.stderr.strip() == ("error: executor.backend: 'dask' needs distributed, which is not installed: "
                                     "pip install 'tavc[dask]'")
    assert not out.exists()


# ----------------------------------------------------------------- convergence follows duration


@pytest.mark.parametrize(
    ("overrides", "duration_s", "convergence_s"),
    [
        # paper 4500 of 18000 s converging: a quarter of any duration
        (["experiment=initial_distribution", "duration_s=60"], 60.0, 15.0),
        # paper 9000 of 27000 s: a third, whatever the scale
        (["experiment=breakdown", "duration_s=90"], 90.0, 30.0),
        (["experiment=breakdown", "scale=smoke", "duration_s=90"], 90.0, 30.0),
        # paper 3000 of 18000 s: a sixth
        (["experiment=value_change", "duration_s=600"], 600.0, 100.0),
        (["experiment=spatiotemporal", "duration_s=100"], 100.0, 0.0),
        # an explicit convergence_s is kept
        (["experiment=initial_distribution", "duration_s=60", "convergence_s=5"], 60.0, 5.0),
        # neither set: both scale (18000 and 4500 times smoke's 0.02)
        (["experiment=initial_distribution", "scale=smoke"], 360.0, 90.0),
    ],
)
def test_convergence_keeps_the_papers_share_of_a_duration_set_by_hand(overrides, duration_s, convergence_s):
    cfg = load_config(overrides)
    assert (cfg.duration_s, cfg.convergence_s) == (pytest.approx(duration_s), pytest.approx(convergence_s))


def test_a_shortened_initial_distribution_is_shown_with_its_convergence():
    result = runner.invoke(app, ["config", "experiment=initial_distribution", "duration_s=60"])
    assert result.exit_code == 0, result.output
    assert "\nduration_s: 60.0\n" in result.stdout and "\nconvergence_s: 15.0\n" in result.stdout
