"""Composing, resolving and validating configs (tavc_cli.config)."""

import os
import re
from collections import Counter
from pathlib import Path

import pytest
import yaml

from tavc_cli.chapter import EXPERIMENTS as CHAPTER
from tavc_cli.config import (
    expand_sweep,
    find_conf_dir,
    list_experiments,
    load_config,
    load_experiments,
    load_sweep,
    settings,
    to_container,
    to_yaml,
)
from tavc_cli.dotted import dotted
from tavc_cli.errors import TavcError
from tavc_cli.experiments.build import trial_specs
from tavc_cli.user_configs import using_config_dirs

CONF_DIR = find_conf_dir()
EXPERIMENTS = sorted(path.stem for path in (CONF_DIR / "experiment").glob("*.yaml"))
SCALES = sorted(path.stem for path in (CONF_DIR / "scale").glob("*.yaml"))
GROUP_OPTIONS = sorted(
    f"{path.parent.name}={path.stem}"
    for group in ("arena", "robot", "team", "learner", "scale", "executor", "arrival", "passing", "reward_time")
    for path in (CONF_DIR / group).glob("*.yaml")
)


# ----------------------------------------------------------------------------- composition


def test_conf_dir_holds_the_main_config():
    assert (CONF_DIR / "config.yaml").is_file()


def test_the_six_chapter_experiments_exist():
    expected = {
        "spatiotemporal",
        "initial_distribution",
        "breakdown",
        "breakdown_no_vacancy",
        "value_change",
        "heterogeneous",
    }
    assert expected <= set(EXPERIMENTS)


@pytest.mark.parametrize("scale", SCALES)
@pytest.mark.parametrize("experiment", EXPERIMENTS)
def test_every_experiment_composes_and_validates(experiment, scale):
    cfg = load_config([f"experiment={experiment}", f"scale={scale}"])
    assert cfg.experiment_name == experiment
    assert cfg.trials >= 1 and cfg.duration_s > 0
    assert len(cfg.team.members) == cfg.team.n_robots
    assert len(cfg.tasks["values"]) == len(cfg.arena.circuits)


@pytest.mark.parametrize("option", GROUP_OPTIONS)
def test_every_group_option_composes(option, tmp_path):
    if option in ("learner=model", "learner=informed"):
        # the model's allocations stand for a run of the world and values it was measured in: the
        # committed model's, the chapter's, not a free-form run's values of 1 and 1
        with pytest.raises(TavcError, match=r"was measured with other settings than this run's \(tasks.values "
                                            r"\[2200.0, 2000.0\] \(the run: \[1.0, 1.0\]\)\)"):
            load_config([option])
        load_config([option, "experiment=initial_distribution"])
        return
    if option != "learner=plugin":
        load_config([option])
        return
    # the slot for a learner from outside tavc composes once it is given a name and a class
    with pytest.raises(TavcError, match="^learner.name: a learner needs a name, got None$"):
        load_config([option])
    (tmp_path / "mine.py").write_text("class Mine:\n    def __init__(self, n_robots, n_circuits, rng):\n"
                                      "        pass\n    def choose(self, robot, state):\n        return 0\n"
                                      "    def learn(self, *args):\n        pass\n")
    cfg = load_config([option, "learner.name=mine", f"learner.target={tmp_path / 'mine.py'}:Mine"])
    assert dict(cfg.learner) == {"name": "mine", "target": f"{tmp_path / 'mine.py'}:Mine", "params": {}}


def test_default_config_composes():
    cfg = load_config()
    assert cfg.experiment_name == "default"
    assert cfg.output_dir == "runs/quick/default"


# ------------------------------------------------------------------------------ resolution


def calibrated_values() -> list[float]:
    """The alternative task values recorded by `tavc model --save-calibration`."""
    text = (find_conf_dir() / "tasks" / "calibrated.yaml").read_text()
    return list(yaml.safe_load(text)["values"])


def test_experiments_use_the_chapters_values_and_calibrated_ones_are_one_override_away():
    for name in ("initial_distribution", "breakdown", "breakdown_no_vacancy", "value_change", "heterogeneous"):
        assert list(load_config([f"experiment={name}"]).tasks["values"]) == [2200.0, 2000.0], name
    cfg = load_config(["experiment=breakdown", "tasks=calibrated"])
    assert list(cfg.tasks["values"]) == calibrated_values()
    cfg = load_config(["experiment=breakdown", "tasks.values=[2200,2000]"])
    assert list(cfg.tasks["values"]) == [2200.0, 2000.0]


def test_breakdown_at_quick_scale_resolves_by_hand():
    cfg = load_config(["experiment=breakdown", "scale=quick"])
    assert cfg.trials == 6  # min(scale 6, paper 20)
    assert cfg.baseline_trials == 6  # min(scale 6, paper baseline 20)
    assert cfg.static_trials == 6  # min(scale 6, paper static 20)
    assert cfg.duration_s == 27000 * 0.25
    assert cfg.convergence_s == 9000 * 0.25
    assert cfg.sim.warmup_s == 18000 * 0.25
    assert cfg.events.breakdowns[0].time_s == 0.0
    assert cfg.events.breakdowns[0].circuit == "high"
    assert cfg.output_dir == "runs/quick/breakdown"
    assert list(cfg.tasks["values"]) == [2200.0, 2000.0]
    assert list(cfg.tasks.score_values) == [10.0, 1.0]


def test_breakdown_at_paper_scale_uses_the_chapter_counts():
    # 20 TAVC trials; random: "a group of five random controllers" is five robots, the chapter gives no
    # count of trials, so Table 1.2's 20; a static allocation's mean "over 20 trials"
    cfg = load_config(["experiment=breakdown", "scale=paper"])
    assert (cfg.trials, cfg.baseline_trials, cfg.static_trials) == (20, 20, 20)
    assert (cfg.duration_s, cfg.convergence_s, cfg.sim.warmup_s) == (27000.0, 9000.0, 18000.0)
    counts = Counter(s.controller for s in trial_specs(settings(cfg)))
    assert counts == {"tavc": 20, "random": 20, "static": 20}


@pytest.mark.parametrize("experiment", ["breakdown_no_vacancy", "value_change"])
def test_five_robot_experiments_compare_with_twenty_random_trials_as_table_1_2(experiment):
    # "random allocation among five robots": five robots, in as many trials as Table 1.2's random runs
    cfg = load_config([f"experiment={experiment}", "scale=paper"])
    assert Counter(s.controller for s in trial_specs(settings(cfg))) == {"tavc": 20, "random": 20}


def test_static_trials_follow_the_baselines_unless_set():
    cfg = load_config(["experiment=initial_distribution", "scale=paper", "baselines=[random,static]",
                       "baseline_trials=3"])
    assert (cfg.baseline_trials, cfg.static_trials) == (3, 3)
    cfg = load_config(["experiment=breakdown", "scale=paper", "static_trials=2"])
    assert Counter(s.controller for s in trial_specs(settings(cfg)))["static"] == 2


def test_heterogeneous_random_trials_start_half_an_hour_before_the_stable_period():
    # paper: 72,000 s, stable from 54,000 s; the baseline starts 1,800 s earlier, at 52,200 s,
    # and runs 19,800 s instead of 72,000; the learners start at 0. Quick (x 0.25): 13,500 - 450
    cfg = load_config(["experiment=heterogeneous", "scale=paper"])
    specs = trial_specs(settings(cfg))
    starts = {(s.controller, s.start_s, s.span_s) for s in specs}
    assert starts == {("tavc", 0.0, 72_000.0), ("random", 52_200.0, 19_800.0)}
    assert sum(s.span_s for s in specs) == 15 * 72_000 + 15 * 19_800
    quick = load_config(["experiment=heterogeneous", "scale=quick"])
    assert {s.start_s for s in trial_specs(settings(quick)) if s.controller == "random"} == {13_050.0}
    # null: the baselines run the whole trial; a lead longer than the convergence period starts them at 0
    for lead in ("null", "60000"):
        cfg = load_config(["experiment=heterogeneous", "scale=paper", f"baseline_lead_s={lead}"])
        assert {s.start_s for s in trial_specs(settings(cfg))} == {0.0}


def test_the_baselines_of_the_breakdown_runs_start_half_an_hour_before_their_first_event():
    # breakdown: the learners warm up 18,000 s before the breakdown at t = 0; random and static
    # warm up 1,800 s, and all run the 27,000 s after it. value_change: the breakdown at -18,000 s
    # comes first, so the baselines start at -19,800 s (a warm-up of 19,800 s, not 36,000)
    def warmups(experiment, *extra):
        specs = trial_specs(settings(load_config([f"experiment={experiment}", "scale=paper", *extra])))
        return {(s.controller, s.warmup_s, s.start_s, s.span_s) for s in specs}

    assert warmups("breakdown") == {("tavc", 18_000.0, 0.0, 45_000.0), ("random", 1_800.0, 0.0, 28_800.0),
                                    ("static", 1_800.0, 0.0, 28_800.0)}
    assert warmups("breakdown_no_vacancy") == {("tavc", 18_000.0, 0.0, 45_000.0), ("random", 1_800.0, 0.0, 28_800.0)}
    assert warmups("value_change") == {("tavc", 36_000.0, 0.0, 54_000.0), ("random", 19_800.0, 0.0, 37_800.0)}
    # the chapter's 5 h random trials of initial_distribution run whole; null: as the learners;
    # never before the learners: a lead longer than their warm-up is their warm-up
    assert warmups("initial_distribution") == {("tavc", 0.0, 0.0, 18_000.0), ("random", 0.0, 0.0, 18_000.0)}
    assert {w for _, w, _, _ in warmups("breakdown", "baseline_lead_s=null")} == {18_000.0}
    assert {w for _, w, _, _ in warmups("breakdown", "baseline_lead_s=50000")} == {18_000.0}


@pytest.mark.parametrize("override, named", [
    (["experiment=spatiotemporal", "baselines=[random]", "baseline_lead_s=600"], "deliveries"),
    (["experiment=heterogeneous", "baseline_lead_s=-1"], "must be"),
    (["experiment=breakdown", "baseline_lead_s=0"], "must be"),  # the breakdown would come at its first tick
])
def test_a_late_start_is_refused_where_it_cannot_be(override, named):
    with pytest.raises(TavcError, match=r"baseline_lead_s.*" + named):
        load_config([*override, "scale=smoke"])


def test_a_lead_is_no_concern_of_a_run_without_baselines():
    # `tavc reproduce baseline_lead_s=600` passes it to section 1.4, which counts deliveries
    # but has no baseline to start late
    cfg = load_config(["experiment=spatiotemporal", "scale=smoke", "baseline_lead_s=600"])
    assert cfg.baseline_lead_s == 600 * 0.02 and list(cfg.baselines) == []


def test_baseline_trials_default_to_trials():
    cfg = load_config(["experiment=initial_distribution", "scale=quick"])
    assert cfg.baseline_trials == cfg.trials == 6
    cfg = load_config(["experiment=initial_distribution", "scale=quick", "trials=4"])
    assert cfg.baseline_trials == 4


def test_scale_trials_only_ever_reduce_the_paper_count():
    cfg = load_config(["experiment=spatiotemporal", "scale=quick", "scale.trials=10"])
    assert cfg.trials == 5


def test_smoke_scale_shrinks_time():
    cfg = load_config(["experiment=spatiotemporal", "scale=smoke"])
    assert cfg.trials == 2
    assert cfg.duration_s == pytest.approx(200000 * 0.02)
    assert cfg.convergence_s == 0.0


def test_event_times_and_warmup_scale_with_time_factor():
    cfg = load_config(["experiment=value_change", "scale=quick"])
    assert cfg.sim.warmup_s == 36000 * 0.25
    assert cfg.events.breakdowns[0].time_s == -18000 * 0.25
    assert cfg.events.value_changes[0].time_s == 0.0
    assert list(cfg.events.value_changes[0]["values"]) == [2000.0, 2200.0]  # the chapter's, swapped


def test_explicit_values_beat_derived_ones():
    cfg = load_config(
        [
            "experiment=breakdown",
            "trials=3",
            "baseline_trials=2",
            "duration_s=100",
            "convergence_s=10",
            "output_dir=/tmp/somewhere",
        ]
    )
    assert (cfg.trials, cfg.baseline_trials) == (3, 2)
    assert (cfg.duration_s, cfg.convergence_s) == (100.0, 10.0)
    assert cfg.output_dir == "/tmp/somewhere"


def test_homogeneous_team_gets_one_member_per_robot():
    cfg = load_config(["team.n_robots=4", "robot.speed_mps=0.3"])
    members = to_container(cfg)["team"]["members"]
    assert members == [{"speed_mps": 0.3, "group": "all"}] * 4


def test_heterogeneous_team_keeps_its_members():
    cfg = load_config(["experiment=heterogeneous"])
    groups = [member.group for member in cfg.team.members]
    assert groups == ["fast"] * 3 + ["slow"] * 3
    assert cfg.analysis.state == "groups"


def test_task_values_default_to_one_per_circuit():
    cfg = load_config(["arena=two_circuits"])
    assert list(cfg.tasks["values"]) == [1.0, 1.0]
    assert list(cfg.tasks.score_values) == [1.0, 1.0]


def test_n_jobs_defaults_to_all_cores():
    assert load_config().executor.n_jobs == (os.cpu_count() or 1)


def test_learner_defaults_fill_fields_an_option_does_not_set():
    cfg = load_config(["learner=tavc_egreedy"])
    assert (cfg.learner.alpha, cfg.learner.gamma, cfg.learner.epsilon) == (0.1, 0.95, 0.1)
    # the node holds exactly the parameters tavc_egreedy declares: no softmax temperature, no slots
    assert list(cfg.learner) == ["name", "alpha", "gamma", "epsilon", "q_init_low", "q_init_high"]
    soft = load_config(["learner=tavc_softmax"])
    assert (soft.learner.tau, "epsilon" in soft.learner) == (0.005, False)


def test_config_is_read_only():
    cfg = load_config()
    with pytest.raises(Exception, match="read-only"):
        cfg.seed = 3


def test_yaml_round_trips_to_the_container():
    cfg = load_config(["experiment=breakdown"])
    assert yaml.safe_load(to_yaml(cfg)) == to_container(cfg)


# ------------------------------------------------------------------------------ validation


@pytest.mark.parametrize(
    ("overrides", "message"),
    [
        (["team.n_robots=-2"], "team.n_robots: must be >= 1, got -2"),
        (
            ["learner=tavc_egreedy", "learner.epsilon=1.5"],
            "learner.epsilon: must be in [0, 1], got 1.5",
        ),
        (
            ["experiment=initial_distribution", "arena.targets.1.x=13", "arena.targets.1.y=4"],
            "arena.targets[1].x: target (13.0, 4.0) lies outside the 12 x 8 m arena",
        ),
        (
            ["experiment=initial_distribution", "tasks.values=[1,2,3]"],
            "tasks.values: needs one value per circuit (2), got 3",
        ),
        (
            ["calibration.grid=[{key: robot.behaviour.passing, values: [nearest, left]}]"],
            "calibration.grid[0].values: 'nearest' is not a number; the search varies numeric settings of the world",
        ),
        (
            ["calibration.grid=[{key: robot.dock.dwell_s, values: [0.0, nan]}]"],
            "calibration.grid[0].values: nan is not a number; the search varies numeric settings of the world",
        ),
    ],
)
def test_errors_read_exactly(overrides, message):
    with pytest.raises(TavcError) as caught:
        load_config(overrides)
    assert str(caught.value) == message


@pytest.mark.parametrize(
    ("overrides", "key"),
    [
        (["team.n_robot=3"], "team.n_robot"),
        (["seed=abc"], "seed"),
        (["seed=-1"], "seed"),
        (["arena=nope"], "arena"),
        (["experiment=nope"], "experiment"),
        (["+colour=red"], "colour"),
        (["learner.epsilon=[1"], "learner.epsilon"),
        (["learner.epsilon=0.1,0.2"], "learner.epsilon"),
        (["learner.gamma=-0.1"], "learner.gamma"),
        (["learner.alpha=2"], "learner.alpha"),
        (["learner.tau=0"], "learner.tau"),
        (["learner.name=greedy"], "learner.name"),
        (["trials=0"], "trials"),
        (["duration_s=-5"], "duration_s"),
        (["duration_s=100", "convergence_s=100"], "convergence_s"),
        (["robot.radius_m=0"], "robot.radius_m"),
        (["robot.speed_mps=-0.1"], "robot.speed_mps"),
        (["robot.laser.n_rays=0"], "robot.laser.n_rays"),
        (["robot.laser.fov_deg=400"], "robot.laser.fov_deg"),
        (["robot.laser.range_m=0"], "robot.laser.range_m"),
        (["arena=one_circuit", "arena.targets.0.x=4"], "arena.targets[0]"),
        (["arena.circuits.0.source=nowhere"], "arena.circuits[0].source"),
        (["arena.circuits.0.source=sink"], "arena.circuits[0].source"),
        (["arena=two_circuits", "arena.targets.1.barcode=11"], "arena.targets"),
        (["team=heterogeneous", "team.n_robots=4"], "team.n_robots"),
        (["team=heterogeneous", "team.members.0.speed_mps=0"], "team.members[0].speed_mps"),
        (["experiment=breakdown", "static_allocation=[3,2]"], "static_allocation"),
        (["experiment=breakdown", "static_allocation=[6]"], "static_allocation"),
        (
            ["learner=static", "arena=two_circuits", "learner.allocation=[1,1]"],
            "learner.allocation",
        ),
        (
            ["experiment=breakdown", "events.breakdowns.0.circuit=middle"],
            "events.breakdowns[0].circuit",
        ),
        (["experiment=breakdown", "events.breakdowns.0.circuit=2"], "events.breakdowns[0].circuit"),
        (["events.breakdowns=[{time_s: 0}, {time_s: 0}]", "team.n_robots=2"], "events.breakdowns"),
        (["experiment=value_change", "sim.warmup_s=0"], "events.breakdowns[0].time_s"),
        (
            ["experiment=value_change", "events.value_changes.0.values=[1]"],
            "events.value_changes[0].values",
        ),
        (["baselines=[random,oracle]"], "baselines[1]"),
        (["executor.backend=slurm"], "executor.backend"),
        (["executor.n_jobs=0"], "executor.n_jobs"),
        (["analysis.state=robots"], "analysis.state"),
        (["sim.dt_s=0"], "sim.dt_s"),
        (["arena.walls=[[1,1,30,1]]"], "arena.walls[0][2]"),
        (["arena.walls=[[1,1,3]]"], "arena.walls[0]"),
        (["sim.physics_substeps=0"], "sim.physics_substeps"),
        (["scale.time_factor=0"], "scale.time_factor"),
        (["paper.trials=null"], "paper.trials"),
        (["experiment=spatiotemporal", "paper.deliveries=0"], "paper.deliveries"),
        (["deliveries=-3"], "deliveries"),
    ],
)
def test_bad_values_fail_with_one_line_naming_the_key(overrides, key):
    with pytest.raises(TavcError) as caught:
        load_config(overrides)
    message = str(caught.value)
    assert "\n" not in message
    assert message.startswith(key), message


def test_interior_walls_are_four_numbers():
    cfg = load_config(["arena.walls=[[1,1,3.5,1]]"])
    assert to_container(cfg)["arena"]["walls"] == [[1, 1, 3.5, 1]]


def test_target_must_be_on_a_wall():
    with pytest.raises(TavcError, match="not on a wall"):
        load_config(["arena.targets.0.x=4", "arena.targets.0.y=3"])


def test_misspelled_key_suggests_the_right_one():
    with pytest.raises(TavcError, match="n_robots"):
        load_config(["team.n_robot=3"])


def test_error_messages_are_single_lines():
    assert str(TavcError("first\n  second")) == "first second"


# ---------------------------------------------------------------------------------- sweeps


def test_expand_sweep_is_a_cartesian_product_in_order():
    jobs = expand_sweep(["learner.epsilon=0.05,0.1", "seed=range(0,2)", "scale=smoke"])
    assert jobs == [
        ["learner.epsilon=0.05", "seed=0", "scale=smoke"],
        ["learner.epsilon=0.05", "seed=1", "scale=smoke"],
        ["learner.epsilon=0.1", "seed=0", "scale=smoke"],
        ["learner.epsilon=0.1", "seed=1", "scale=smoke"],
    ]


def test_expand_sweep_accepts_choice():
    assert expand_sweep(["learner=choice(random,tavc_egreedy)"]) == [
        ["learner=random"],
        ["learner=tavc_egreedy"],
    ]


def test_load_sweep_gives_each_job_its_own_folder():
    configs = load_sweep(["experiment=breakdown", "learner.epsilon=0.05,0.2"])
    assert [cfg.learner.epsilon for cfg in configs] == [0.05, 0.2]
    assert [cfg.output_dir for cfg in configs] == [
        "runs/quick/breakdown/0_learner.epsilon=0.05",
        "runs/quick/breakdown/1_learner.epsilon=0.2",
    ]


def test_load_sweep_validates_every_job_and_names_the_bad_one():
    with pytest.raises(TavcError, match=r"job 1 .*learner\.epsilon: must be in \[0, 1\]"):
        load_sweep(["learner=tavc_egreedy", "learner.epsilon=0.1,1.5"])


def test_a_sweep_too_large_to_be_a_study_is_refused_before_it_is_spelled_out():
    """range() is read lazily: a slip of a few zeros is one line at once, not an hour of listing
    jobs; so is a product of sweeps past the limit (10,000 jobs), and a range() that cannot count."""
    with pytest.raises(TavcError, match="^seed: the sweep gives it more than 10,000 values; a sweep runs at most "
                                        "10,000 jobs$"):
        load_sweep(["seed=range(0,100000000000)"])
    with pytest.raises(TavcError, match=r"^the sweep has 10,100 jobs \(101 x 100 values\); a sweep runs at most "
                                        r"10,000 jobs$"):
        load_sweep(["seed=range(0,101)", "trials=range(1,101)"])
    with pytest.raises(TavcError, match="^seed: range\\(\\) arg 3 must not be zero$"):
        load_sweep(["seed=range(0,3,0)"])


@pytest.mark.parametrize(("override", "line"), [
    ("arena.targets.foo=1", "arena.targets.foo: 'arena.targets.foo=1' cannot be applied (ValueError: invalid "
                            "literal for int() with base 10: 'foo')"),
    ("tasks=[1]", "tasks: takes one option, not a list (Hydra would merge the options into one config named after "
                  "the last); choose one (tasks=<option>), or sweep them with -m (tasks=a,b)"),
    ("seed=" + "[" * 500 + "]" * 500, "seed: its value is nested too deeply to read"),
    ("+experiment=value_change", "experiment: a config group holds one option, and it was given two; choose it "
                                 "once, without a + (which adds a second): experiment=<option>"),
    ("events.breakdowns=[{time_s:0,circuit:'²'}]", "events.breakdowns[0].circuit: must be null, high, low or a "
                                                  "circuit index in [0, 2), got '²'"),
])
def test_an_override_hydra_cannot_apply_is_one_line_naming_it(override, line):
    """Hydra lets some slips through as Python's errors (a list given a key that is no index, a
    group given a list, a value nested past its parser): each is one line naming the override."""
    with pytest.raises(TavcError) as caught:
        load_config(["experiment=breakdown", override])
    assert str(caught.value).startswith(line), str(caught.value)


@pytest.mark.parametrize(("override", "line"), [
    ("~seed", "seed: every run reads it, so ~ cannot remove it (the schema's default would take its place); set "
              "it (seed=<value>)"),
    ("~seed=3", "seed: every run reads it"),
    ("~team", "team: every run reads it, so ~ cannot remove it (the schema's default would take its place); "
              "choose an option (team=<option>)"),
    ("~learner.alpha", "learner.alpha: every run reads it"),
    ("~arena.targets.0", "arena.targets.0: every run reads it"),
])
def test_a_setting_cannot_be_removed(override, line):
    """Hydra's ``~key`` would not remove a setting tavc reads but put the schema's default in its
    place: the heterogeneous experiment ran a homogeneous team under ``~team``, and ``~seed`` seed 0."""
    with pytest.raises(TavcError) as caught:
        load_config(["experiment=heterogeneous", override])
    assert str(caught.value).startswith(line), str(caught.value)
    with pytest.raises(TavcError, match="^seed: every run reads it"):  # before any job is composed
        load_sweep(["learner.epsilon=0.05,0.1", "~seed"])
    with pytest.raises(TavcError, match="^seed: every run reads it"):  # not told to write ~seed=[a,b]
        load_config(["~seed=1,2"])


@pytest.mark.parametrize(("value", "shown"), [("null", "null"), ("''", "''"), ("[1]", "[1]"), ("true", "true")])
def test_a_model_learners_model_file_must_be_a_path(value, shown):
    """learner.model_file is read while the config resolves, before the learner's settings type it:
    null was a TypeError's traceback."""
    with pytest.raises(TavcError, match=r"^learner.model_file: must be the path of a model.json \(`tavc model` "
                                        rf"writes one\), got {re.escape(shown)}$"):
        load_config(["learner=model", f"learner.model_file={value}"])



def test_an_arena_too_long_for_its_reach_grid_is_one_line():
    """The grid on which the walls' free space is checked has at most `REACH_MAX_CELLS` cells a
    side, however long and thin the arena: 1,000 km by 8 m, the longest side allowed, is checked
    on 2 m cells (its full grid would have 2e10); a side longer than that is refused by itself."""
    cfg = load_config(["arena.walls=[[1,1,2,2]]", "arena.width_m=1e6"])
    assert cfg.arena.width_m == 1e6
    with pytest.raises(TavcError, match=r"^arena.width_m: must be at most 1,000,000 m \(1,000 km\), got 1e\+200$"):
        load_config(["arena.walls=[[1,1,2,2]]", "arena.width_m=1e200"])
    with pytest.raises(TavcError, match=r"^arena.height_m: must be at most 1,000,000 m \(1,000 km\), got "
                                        r"1,000,001$"):
        load_config(["arena.height_m=1000001"])
    with pytest.raises(TavcError, match=r"^arena.height_m: must be at most 1,000,000 m \(1,000 km\), got "
                                        r"1000000.0000001$"):
        load_config(["arena.height_m=1000000.0000001"])


@pytest.mark.parametrize(("name", "text", "why"), [
    ("learner/bin.yaml", b"\x00\x01\xff\xfe", "(UnicodeDecodeError: 'utf-8' codec can't decode byte 0xff"),
    ("experiment/selfref.yaml", b"defaults:\n  - /experiment/selfref\n",
     "(nested too deeply, or a config file that includes itself)"),
    ("experiment/five.yaml", b"defaults: 5\n", "(ValueError: Invalid defaults list in 'experiment/five', defaults "
                                                "must be a list (got int))"),
])
def test_a_config_file_of_ones_own_hydra_cannot_read_is_one_line_naming_it(tmp_path, name, text, why):
    (tmp_path / name).parent.mkdir()
    (tmp_path / name).write_bytes(text)
    group, option = name.removesuffix(".yaml").split("/")
    with using_config_dirs(tmp_path), pytest.raises(TavcError) as caught:
        load_config([f"{group}={option}"])
    assert str(caught.value).startswith(f"{group}: '{group}={option}' cannot be applied {why}"), str(caught.value)


# ------------------------------------------------------------------------------ experiments


def test_list_experiments_describes_every_file():
    experiments = list_experiments()
    assert [item["name"] for item in experiments] == EXPERIMENTS
    for item in experiments:
        assert item["section"] and item["description"]


def test_long_scale_multiplies_durations_and_warm_up_by_ten():
    # breakdown: 7.5 h with 2.5 h to converge after 5 h of warm-up, each ten times longer
    cfg = load_config(["experiment=breakdown", "scale=long"])
    assert (cfg.duration_s, cfg.convergence_s, cfg.sim.warmup_s) == (270000.0, 90000.0, 180000.0)
    assert cfg.trials == 8


@pytest.mark.parametrize(("overrides", "deliveries"), [
    (["experiment=spatiotemporal", "scale=paper"], 1000),  # the chapter's 1000 traversals a trial
    (["experiment=spatiotemporal", "scale=quick"], 250),  # a quarter of the time, a quarter of them
    (["experiment=spatiotemporal", "scale=smoke"], 20),
    (["experiment=spatiotemporal", "scale=paper", "deliveries=40"], 40),  # set by hand: as given
    (["experiment=spatiotemporal", "scale=paper", "paper.deliveries=null"], None),  # back to a fixed length
    (["experiment=initial_distribution", "scale=paper"], None),  # the chapter gives its length in hours
])
def test_trials_counted_in_deliveries_scale_like_durations(overrides, deliveries):
    assert load_config(overrides).deliveries == deliveries


@pytest.mark.parametrize("overrides, message", [
    # the shell split `output_dir=/tmp/my results` at the space
    (["output_dir=/tmp/my", "results"],
     "results: not an override (key=value); if it is the rest of output_dir's value, cut off at a space, quote the "
     """whole override: 'output_dir="/tmp/my results"'"""),
    # every word the shell split off, not only the first
    (["output_dir=/tmp/my", "new", "results", "seed=1"],
     "new: not an override (key=value); if it is the rest of output_dir's value, cut off at a space, quote the "
     """whole override: 'output_dir="/tmp/my new results"'"""),
    (["output_dir=/tmp/résultats"],
     "output_dir: the value '/tmp/résultats' has a character Hydra's override grammar reads only in quotes ('é'); "
     """quote it: 'output_dir="/tmp/résultats"'"""),
    (["output_dir=/tmp/a(b)"],
     "output_dir: the value '/tmp/a(b)' has a character Hydra's override grammar reads only in quotes ('('); "
     """quote it: 'output_dir="/tmp/a(b)"'"""),
    (["results"], "results: not an override (key=value); to set a key, write results=<value>"),
])
def test_a_path_hydra_cannot_read_unquoted_gets_the_quoting_that_reads_it(overrides, message):
    with pytest.raises(TavcError) as error:
        load_config(overrides)
    assert str(error.value) == message
    with pytest.raises(TavcError) as error:  # a sweep parses its overrides alike
        expand_sweep(overrides)
    assert str(error.value) == message


@pytest.mark.parametrize("override, folder", [('output_dir="/tmp/my results"', "/tmp/my results"),
                                              ("output_dir=/tmp/my results", "/tmp/my results"),
                                              ('output_dir="/tmp/résultats"', "/tmp/résultats")])
def test_the_suggested_quoting_reads_the_path(override, folder):
    assert load_config([override]).output_dir == folder


def test_a_record_listing_every_learners_parameters_reads_as_the_learner_that_ran(tmp_path):
    """A results folder whose config.yaml lists every learner's parameters (as records once did)
    reads as its learner's own settings; a key no learner ever had is still refused."""
    from tavc_cli.errors import TavcError
    from tavc_cli.learning.parameters import TavcEgreedySettings
    from tavc_cli.settings import from_yaml, to_yaml

    text = to_yaml(settings(load_config(["experiment=initial_distribution", "scale=smoke"])))
    flat = ("  tau: 0.005\n  decision_period_s: 0.1\n  decide_on_change: true\n  allocation: null\n"
            "  delta_win: 0.01\n  roles: null\n  target: null\n  params: {}\n  model_file: m.json\n"
            "  allocations: null\nscale:")
    (tmp_path / "config.yaml").write_text(text.replace("\nscale:", "\n" + flat, 1))
    assert from_yaml(tmp_path / "config.yaml").learner == TavcEgreedySettings(name="tavc_egreedy")
    (tmp_path / "config.yaml").write_text(text.replace("\nscale:", "\n  alpah: 0.2\nscale:", 1))
    with pytest.raises(TavcError, match="learner.alpah: the learner tavc_egreedy takes no parameter alpah"):
        from_yaml(tmp_path / "config.yaml")


def test_a_key_a_config_of_your_own_lacks_names_your_file_not_tavcs(tmp_path):
    (tmp_path / "experiment").mkdir()
    (tmp_path / "experiment" / "misplaced.yaml").write_text("seed: 3\n")  # no `# @package _global_`
    with using_config_dirs(tmp_path), pytest.raises(TavcError) as info:
        load_config(["experiment=misplaced"])
    assert str(info.value) == ("experiment: Key 'experiment' not in 'TavcConfig' "
                               f"(in {tmp_path / 'experiment' / 'misplaced.yaml'})")
    # where tavc has a config of that name, Hydra takes tavc's, which `conf/...` names
    (tmp_path / "experiment" / "breakdown.yaml").write_text("seed: 3\n")
    with using_config_dirs(tmp_path):
        assert load_config(["experiment=breakdown"]).seed == 0  # tavc's, found first


def test_the_committed_headline_runs_hold_the_settings_make_reproduce_all_writes_now(monkeypatch):
    """`make reproduce-all` writes each experiment's `config.yaml` again; where tavc composes
    settings the committed runs lack (a key added since), the main command would change the
    committed results' settings. Only the number of processes (`executor.n_jobs`, this
    machine's cores) may differ; every other key is the same."""
    repo = Path(__file__).resolve().parent.parent
    monkeypatch.chdir(repo)
    names = list(CHAPTER.own())
    assert len(names) == 6
    for name, cfg in zip(names, load_experiments(names, ["scale=paper"], "results"), strict=True):
        committed = dotted(yaml.safe_load((repo / "results" / name / "config.yaml").read_text()))
        now = dotted(yaml.safe_load(to_yaml(cfg)))
        differ = sorted(k for k in set(committed) | set(now)
                        if k != "executor.n_jobs" and committed.get(k, "absent") != now.get(k, "absent"))
        assert not differ, f"results/{name}/config.yaml: {differ[:3]}; run make reproduce-all and commit it"


@pytest.mark.parametrize(("overrides", "line"), [
    (["experiment=[value_change,breakdown]"],
     "experiment: takes one option, not a list (Hydra would merge the options into one config named after the last); "
     "choose one (experiment=<option>), or sweep them with -m (experiment=a,b)"),
    (["experiment=breakdown", "team=[homogeneous]"],
     "team: takes one option, not a list (Hydra would merge the options into one config named after the last); "
     "choose one (team=<option>), or sweep them with -m (team=a,b)"),
    (["experiment=value_change", "experiment_name=breakdown"],
     "experiment_name: 'breakdown' names one of the experiments whose claims the report tests, and this config is "
     "experiment=value_change; choose experiment=breakdown, or another name"),
    (["experiment_name=initial_distribution"],
     "experiment_name: 'initial_distribution' names one of the experiments whose claims the report tests, and this "
     "config is no experiment; choose experiment=initial_distribution, or another name"),
    (["experiment=initial_distribution", "experiment_name=" + "a" * 101],
     "experiment_name: at most 100 bytes (it names the run's folder and, in a report, files of its figures), got 101"),
])
def test_a_config_that_would_pass_for_another_experiment_is_one_line(overrides, line):
    """A list of experiments would merge them into one named after the last, whose claims the report
    would then test on the others' events; a chapter experiment's name on another's settings likewise."""
    with pytest.raises(TavcError) as caught:
        load_config(overrides)
    assert str(caught.value) == line


def test_an_experiment_keeps_its_own_name_and_may_take_another():
    assert load_config(["experiment='breakdown'"]).experiment_name == "breakdown"
    assert load_config(["experiment=breakdown", "experiment_name=my_breakdown"]).experiment_name == "my_breakdown"
    # 50 characters of two bytes each: at the bound, which counts bytes
    assert load_config(["experiment=initial_distribution", f"experiment_name='{'é' * 50}'"]).experiment_name == "é" * 50
    with pytest.raises(TavcError, match="at most 100 bytes .* got 102$"):
        load_config(["experiment=initial_distribution", f"experiment_name='{'é' * 51}'"])
    assert list(load_config(["experiment=breakdown", "baselines=[random]"]).baselines) == ["random"]


@pytest.mark.parametrize(("override", "line", "bound"), [
    ("robot.radius_m=1e-300", "robot.radius_m: must be at least 0.01 m (a smaller disc falls between the laser's rays "
                              "and its moment of inertia vanishes in the physics), got 1e-300",
     "robot.radius_m=0.01"),
    ("sim.solver_iterations=99999999999999",
     "sim.solver_iterations: must be at most 100 (pymunk's default is 10; each step solves every contact this many "
     "times, a cost the estimate of a run's time does not count), got 99999999999999", "sim.solver_iterations=100"),
])
def test_a_body_the_physics_cannot_hold_or_a_solver_without_end_is_one_line(override, line, bound):
    """Both were accepted and failed inside every trial (a disc without a moment of inertia; an iteration
    count past 32 bits), or ran without end (a billion solver passes a step)."""
    with pytest.raises(TavcError) as caught:
        load_config(["experiment=initial_distribution", override])
    assert str(caught.value) == line
    load_config(["experiment=initial_distribution", bound])  # the bound itself is taken
