"""Trials that share their history (tavc_cli.experiments.lineage, joint): a warm-up is the trial
without one, continued; trees of trials compute each trial as it is computed alone; `tavc reproduce`."""

import json
from dataclasses import replace

import numpy as np
import pytest
from typer.testing import CliRunner

from tavc_cli.cli import app
from tavc_cli.config import load_config, settings
from tavc_cli.experiments import engine as engine_module
from tavc_cli.experiments import joint
from tavc_cli.experiments.build import trial_specs
from tavc_cli.experiments.engine import run_trials
from tavc_cli.experiments.joint import run_together
from tavc_cli.experiments.lineage import Item, plan, trees
from tavc_cli.experiments.records import ARRAY_FIELDS, TrialRecord, records_differ
from tavc_cli.experiments.spec import Breakdown
from tavc_cli.experiments.store import Executor
from tavc_cli.ownership import trial_path

SECTION_1_5 = ("initial_distribution", "breakdown", "breakdown_no_vacancy", "value_change")


def _specs(experiment, *overrides):
    return trial_specs(settings(load_config([f"experiment={experiment}", *overrides])))


def _items(tmp_path, *overrides):
    return [Item(s, tmp_path / e) for e in SECTION_1_5 for s in _specs(e, *overrides)]


def test_a_warm_up_is_the_trial_without_one_continued():
    """The first 600 s of a trial with a 600 s warm-up are, row for row and bit for bit, the
    trial without a warm-up, its times 600 s earlier: rewards go by the trial's own clock."""
    base = _specs("initial_distribution", "scale=paper", "trials=1", "baselines=[]")[0]
    plain = run_trials([replace(base, duration_s=600.0)])[0]
    warm = run_trials([replace(base, warmup_s=600.0, duration_s=60.0)])[0]
    for name, cols in plain.tables.items():
        before = warm.tables[name]["t_s"] < 0
        assert before.sum() == len(cols["t_s"]) > 0 or name == "breakdowns"
        assert np.array_equal(warm.tables[name]["t_s"][before], -600.0 + cols["t_s"])
        for col, values in cols.items():
            if col != "t_s":
                assert np.array_equal(warm.tables[name][col][before], values), (name, col)
    # the Q-tables the warm-up ends with are the plain trial's last
    assert np.array_equal(warm.q[warm.q_t == 0.0][0], plain.q[-1])


def test_a_late_start_is_the_trial_from_t_0_with_its_times_moved():
    """A baseline that starts 900 s into the record and runs to 1500 s is, row for row and bit
    for bit, the same trial run from t = 0 for 600 s, its times 900 s later."""
    base = _specs("initial_distribution", "scale=paper", "trials=1", "baseline_trials=1")[1]
    assert base.controller == "random"
    plain = run_trials([replace(base, duration_s=600.0)])[0]
    late = run_trials([replace(base, start_s=900.0, duration_s=1500.0)])[0]
    assert (late.start_s, late.end_s, late.meta["t0_s"], plain.meta["t0_s"]) == (900.0, 1500.0, 900.0, 0.0)
    assert all(len(cols["t_s"]) > 0 or name == "breakdowns" for name, cols in plain.tables.items())
    moved = TrialRecord(meta=late.meta, tables={name: {col: 900.0 + v if col == "t_s" else v
                                                      for col, v in cols.items()}
                                                for name, cols in plain.tables.items()})
    for name in ARRAY_FIELDS:
        values = getattr(plain, name)
        setattr(moved, name, 900.0 + values if name.endswith("_t") else values)
    assert records_differ(moved, late) == []


def test_trials_that_start_late_share_history_only_with_their_own_start(tmp_path, monkeypatch):
    # two baselines starting at 300 s (one longer) share their first 600 s; one starting at
    # 0 s shares nothing with them: the tree keeps apart trials whose records start at
    # different times, though their clocks run alike (a conservative rule, not a needed one)
    base = _specs("initial_distribution", "scale=smoke", "trials=1", "baseline_trials=1")[1]
    late = replace(base, start_s=300.0, duration_s=900.0)
    items = [Item(late, tmp_path / "a"), Item(replace(late, duration_s=1200.0), tmp_path / "b"),
             Item(replace(base, duration_s=900.0), tmp_path / "c")]
    forest = sorted(trees(items), key=lambda t: len(t.items()))
    assert [len(t.items()) for t in forest] == [1, 2]
    assert (forest[1].start, forest[1].end) == (0, 6000)  # 600 s of shared history, in ticks
    monkeypatch.setattr(joint, "simulate_contained", _no_trial_alone)
    run_together(_by_folder(items), Executor(n_jobs=1, batch_size=8))
    for item in items:
        assert _alone_equals_stored(item) == [], item.folder.name


def test_the_section_1_5_trials_of_one_seed_form_one_tree_with_the_work_computed_by_hand():
    """TAVC trial j of the four experiments of section 1.5: initial_distribution (18,000 s) is the
    trunk; breakdown_no_vacancy parts from it with a low-circuit breakdown (27,000 s more);
    breakdown and value_change with a high-circuit one, and part 18,000 s later when the values
    swap (breakdown 9,000 s more, value_change 18,000 s more): 18,000 + 27,000 + 18,000 + 9,000
    + 18,000 = 90,000 s instead of 18,000 + 45,000 + 45,000 + 54,000 = 162,000 s alone."""
    items = [Item(s, None) for e in SECTION_1_5 for s in _specs(e, "scale=paper", "trials=1", "baselines=[]")]
    (tree,) = trees(items)
    assert tree.ticks * 0.1 == pytest.approx(90_000.0)
    assert sum(i.spec.warmup_s + i.spec.duration_s for i in items) == 162_000.0
    assert (tree.start, tree.end) == (0, 180_000)
    assert [i.folder for (i,) in tree.ends] == [None] and tree.ends[0][0].spec.warmup_s == 0.0
    (low,) = [c for c in tree.children if c.specs[0].breakdowns[0].circuit == "low"]
    (high,) = [c for c in tree.children if c.specs[0].breakdowns[0].circuit == "high"]
    assert len(tree.children) == 2 and (low.end, len(low.ends), low.children) == (450_000, 1, [])
    assert (high.start, high.end, high.ends) == (180_000, 360_000, [])
    assert sorted((c.end, len(c.ends[0][0].spec.value_changes)) for c in high.children) == [(450_000, 0),
                                                                                           (540_000, 1)]


def test_random_trials_that_start_half_an_hour_before_the_breakdown_still_form_one_tree():
    """Random trial j of the four experiments: the three with a breakdown start their random
    trials 1,800 s before it, so they share only initial_distribution's first 1,800 s; breakdown
    and value_change then share the 18,000 s up to the swap. 1,800 + 16,200 (initial_distribution
    to its end) + 27,000 (low breakdown) + 18,000 + 9,000 (breakdown) + 18,000 (value_change) =
    90,000 s, as before they started late, against 18,000 + 28,800 + 28,800 + 37,800 alone."""
    items = [Item(s, None) for e in SECTION_1_5
             for s in _specs(e, "scale=paper", "trials=1", "baseline_trials=1") if s.controller == "random"]
    assert sum(i.spec.span_s for i in items) == 113_400.0
    (tree,) = trees(items)
    assert tree.ticks * 0.1 == pytest.approx(90_000.0)
    assert (tree.start, tree.end) == (0, 18_000)
    assert sorted((c.start, c.end) for c in tree.children) == [(18_000, 180_000), (18_000, 198_000),
                                                               (18_000, 288_000)]


def test_trials_of_other_seeds_or_learners_share_nothing(tmp_path):
    items = _items(tmp_path, "scale=smoke", "trials=2", "baseline_trials=2")
    # one tree per (controller, trial index): TAVC and random over four experiments, static in one
    assert len(trees(items)) == 2 + 2 + 2
    batches = plan(items, set(items), size=8)
    assert sorted((b.controller, len(b.specs)) for b in batches) == [("random", 2), ("static", 2), ("tavc", 2)]


def _no_trial_alone(specs, *args):
    raise AssertionError(f"{len(specs)} trials were run alone: the tree left them unfinished")


def _by_folder(items):
    folders = {}
    for i in items:
        folders.setdefault(i.folder, []).append(i.spec)
    return list(folders.items())


@pytest.fixture(scope="module")
def together(tmp_path_factory):
    out = tmp_path_factory.mktemp("together")
    items = _items(out, "scale=smoke", "trials=2", "baseline_trials=2")
    with pytest.MonkeyPatch.context() as patch:
        patch.setattr(joint, "simulate_contained", _no_trial_alone)  # every record comes from the tree
        reused = run_together(_by_folder(items), Executor(n_jobs=1, batch_size=8))
    return items, reused


def _alone_equals_stored(item):
    alone = run_trials([item.spec])[0]
    return records_differ(alone, TrialRecord.load(trial_path(item.folder, item.spec.controller, item.spec.trial)))


def test_trees_compute_every_trial_as_it_is_computed_alone(together):
    items, reused = together
    assert set(reused.values()) == {0}
    assert len(items) == 2 * 4 + 2 * 4 + 2  # TAVC and random in each experiment, static in breakdown
    for item in items:
        assert _alone_equals_stored(item) == [], (item.folder.name, item.spec.controller, item.spec.trial)


def test_a_folder_already_done_is_reused_and_the_trunk_still_feeds_the_rest(tmp_path, monkeypatch):
    items = _items(tmp_path, "scale=smoke", "trials=1", "baselines=[]")
    trunk = [i for i in items if i.folder.name == "initial_distribution"]
    run_together([(trunk[0].folder, [trunk[0].spec])], Executor(n_jobs=1))
    stamp = trial_path(trunk[0].folder, "tavc", 0).stat().st_mtime_ns
    monkeypatch.setattr(joint, "simulate_contained", _no_trial_alone)
    reused = run_together(_by_folder(items), Executor(n_jobs=1))
    monkeypatch.undo()
    assert reused[trunk[0].folder] == 1 and sum(reused.values()) == 1
    assert trial_path(trunk[0].folder, "tavc", 0).stat().st_mtime_ns == stamp  # not written again
    for item in items:
        assert _alone_equals_stored(item) == []


def test_a_branch_that_fails_in_its_forked_copy_is_run_alone(tmp_path, monkeypatch):
    """A branch whose copy of the process dies leaves its trials to be run alone, from their
    start: every file is there and the same as alone."""
    real = engine_module.BatchEngine.branch

    def branch(self, specs):  # the high-breakdown branch, the first of two, runs in a forked copy
        if specs[0].breakdowns[0].circuit == "high":
            raise RuntimeError("this branch fails")
        return real(self, specs)

    alone = []
    real_alone = joint.simulate_contained

    def simulate_contained(specs, *args):
        alone.extend((s.breakdowns[0].circuit, len(s.value_changes)) for s in specs)
        return real_alone(specs, *args)

    monkeypatch.setattr(engine_module.BatchEngine, "branch", branch)
    monkeypatch.setattr(joint, "simulate_contained", simulate_contained)
    items = _items(tmp_path, "scale=smoke", "trials=1", "baselines=[]")
    run_together(_by_folder(items), Executor(n_jobs=1))
    monkeypatch.undo()
    # only the branch that failed ran alone: breakdown and value_change; the trunk and the
    # low-breakdown branch came from the tree
    assert sorted(alone) == [("high", 0), ("high", 1)]
    for item in items:
        assert _alone_equals_stored(item) == []


runner = CliRunner()


@pytest.mark.slow
def test_reproduce_writes_what_run_writes_for_each_experiment(tmp_path):
    common = ["scale=smoke", "trials=2", "baseline_trials=1", "executor.n_jobs=2"]
    result = runner.invoke(app, ["reproduce", "--experiments", "initial_distribution,breakdown",
                                 "--results", str(tmp_path / "together"), *common])
    assert result.exit_code == 0, result.output
    for name in ("initial_distribution", "breakdown"):
        alone = runner.invoke(app, ["run", f"experiment={name}", *common, f"output_dir={tmp_path / 'alone' / name}"])
        assert alone.exit_code == 0, alone.output
        tables = sorted(p.name for p in (tmp_path / "alone" / name).glob("*.csv"))
        assert "state_time.csv" in tables and "claims.csv" in tables
        for table in tables:
            assert (tmp_path / "together" / name / table).read_bytes() == \
                (tmp_path / "alone" / name / table).read_bytes(), (name, table)
        covers = json.loads((tmp_path / "together" / name / "provenance.json").read_text())["wall_time_covers"]
        assert covers.startswith("the trials of the 2 experiments one invocation ran together"), covers


@pytest.mark.parametrize(
    ("args", "key"),
    [
        (["reproduce", "--experiments", "initial_distribution,nope", "scale=smoke"], "--experiments"),
        (["reproduce", "--experiments", ",", "scale=smoke"], "--experiments"),
        (["reproduce", "scale=smoke", "output_dir=/tmp/x"], "output_dir"),
        (["reproduce", "scale=smoke", "experiment=breakdown"], "experiment"),
        (["reproduce", "scale=smoke", "team.n_robots=-1"], "team.n_robots"),
    ],
)
def test_reproduce_bad_input_is_one_error_line(args, key, tmp_path):
    result = runner.invoke(app, [*args, "--results", str(tmp_path)])
    assert result.exit_code == 1, result.output
    lines = [line for line in result.output.splitlines() if line.strip()]
    assert len(lines) == 1 and lines[0].startswith("error: ") and key in lines[0], result.output
    assert not any(tmp_path.iterdir())  # nothing written


def test_a_forked_branch_reports_its_progress_through_the_process_that_forked_it(tmp_path):
    """One TAVC seed at smoke scale (x 0.02): the trunk is ticks 0-3600 (initial_distribution's
    360 s); the high-breakdown branch, forked first, is 3600-7200 and then 1800 (breakdown) and
    3600 (value_change) ticks more; the low-breakdown branch, run last in this process, 5400.
    Of 18,000 ticks, fractions strictly between 3600 / 18000 = 0.2 and 12600 / 18000 = 0.7 can
    only come from the forked copy."""
    items = _items(tmp_path, "scale=smoke", "trials=1", "baselines=[]")
    (batch,) = plan(items, set(items), size=8)
    assert batch.root.ticks == 18_000
    seen = []
    joint.run_tree_batch(batch, seen.append)
    assert seen == sorted(seen) and 0.99 < seen[-1] <= 1.0  # the pool marks the batch done at its end
    assert any(0.2 < f < 0.7 for f in seen)


def test_trials_counted_in_deliveries_share_history_only_with_their_own_warm_up_and_length(tmp_path, monkeypatch):
    # a trial that ends with its n-th delivery after the warm-up may end anywhere: it shares its
    # history only with trials of the same warm-up, duration and count, which may still part
    # at an event; in a tree each is computed as it is alone
    base = _specs("initial_distribution", "scale=smoke", "trials=1", "baselines=[]")[0]
    counted = replace(base, deliveries=8)
    items = [Item(counted, tmp_path / "a"),
             Item(replace(counted, breakdowns=(Breakdown(30.0, circuit="high"),)), tmp_path / "b"),
             Item(replace(counted, warmup_s=20.0), tmp_path / "c"),
             Item(replace(counted, duration_s=counted.duration_s / 2), tmp_path / "d"),
             Item(base, tmp_path / "e")]
    forest = trees(items)
    assert sorted(len(t.items()) for t in forest) == [1, 1, 1, 2]  # a and b part at the breakdown
    monkeypatch.setattr(joint, "simulate_contained", _no_trial_alone)
    run_together(_by_folder(items), Executor(n_jobs=1, batch_size=8))
    for item in items:
        assert _alone_equals_stored(item) == [], item.folder.name
    ended = [TrialRecord.load(trial_path(i.folder, "tavc", 0)).meta["duration_s"] for i in items]
    assert ended[0] < base.duration_s and ended[-1] == base.duration_s
