"""Learners from outside tavc that answer badly, raise, exit, draw from global generators or are
edited between runs: each is refused, warned about or recomputed in one line, and nothing outside
the run's folder changes. Every expectation below was written before the case was first run."""

from __future__ import annotations

from pathlib import Path

import pytest
from typer.testing import CliRunner

from tavc_cli import config
from tavc_cli.cli import app
from tavc_cli.errors import TavcError
from tavc_cli.experiments.build import trial_specs
from tavc_cli.learning.plugins import CONFIG_DIRS_ENV, check_choice, target_digest
from tests.helpers import file_digests

# A learner whose choose() answers `ANSWER` from its `bad_from`-th instance on (the made-up run
# before the trials builds two; a trial run in the same process, `executor.confine=off`, builds
# the third), and 0 before.
LEARNER = '''
import random
import sys

import numpy as np


class Learner:
    built = 0

    def __init__(self, n_robots, n_circuits, rng, bad_from=1, shape=None, use_global=False):
        Learner.built += 1
        self.bad = Learner.built >= bad_from
        self.n, self.shape, self.use_global = n_circuits, shape, use_global

    def choose(self, robot, state):
        if self.use_global:
            return random.randrange(self.n)
        return ANSWER if self.bad else 0

    def learn(self, robot, state, action, reward, next_state):
        pass

    def q_tables(self):
        return None if self.shape is None else np.zeros(self.shape)
'''


def _folder(tmp_path: Path, answer: str) -> Path:
    folder = tmp_path / "mine"
    (folder / "learner").mkdir(parents=True)
    (folder / "bad.py").write_text(LEARNER.replace("ANSWER", answer))
    (folder / "learner" / "bad.yaml").write_text("name: bad\ntarget: bad.py:Learner\nparams: {}\n")
    return folder


def _run(tmp_path, monkeypatch, answer: str, *overrides: str):
    folder = _folder(tmp_path, answer)
    sibling = tmp_path / "sibling"
    sibling.mkdir(exist_ok=True)
    (sibling / "keep.txt").write_text("the user's")
    before = file_digests(sibling)
    monkeypatch.setenv(CONFIG_DIRS_ENV, "")
    monkeypatch.chdir(tmp_path)
    result = CliRunner().invoke(app, ["--config-dir", str(folder), "run", "experiment=initial_distribution",
                                      "scale=smoke", "learner=bad", "baselines=[]", "trials=1", "duration_s=300",
                                      "executor.n_jobs=1", f"output_dir={tmp_path / 'run'}", "--no-progress",
                                      *overrides])
    assert file_digests(sibling) == before  # nothing outside the run's folder changed
    return result


@pytest.mark.parametrize(("answer", "shown"), [
    ("-1", "-1 (int)"), ("2", "2 (int)"), ("1.0", "1.0 (float)"), ("None", "None (NoneType)"),
    ("True", "True (bool)"), ("'0'", "'0' (str)"), ("np.int64(5)", "(int64)"),
])
def test_a_bad_circuit_is_refused_before_any_trial_in_one_line(tmp_path, monkeypatch, answer, shown):
    result = _run(tmp_path, monkeypatch, answer)
    assert result.exit_code == 1
    line = result.output.strip().splitlines()[-1]
    assert line.startswith("error: learner bad: choose(robot=0, state=0) returned ")
    assert shown in line and "an integer from 0 to 1" in line
    assert not (tmp_path / "run" / "trials").exists()  # refused before anything ran


def test_a_bad_circuit_inside_a_trial_fails_that_trial_in_one_line(tmp_path, monkeypatch):
    result = _run(tmp_path, monkeypatch, "-1", "+learner.params.bad_from=3", "executor.confine=off")
    assert result.exit_code == 1
    line = result.output.strip().splitlines()[-1]
    assert line.startswith("error: trial bad_000 (seed [")
    assert "failed: learner bad: choose(robot=" in line and "returned -1 (int)" in line
    assert "Traceback" not in result.output


@pytest.mark.parametrize(("raised", "shown"), [
    ("sys.exit(0)", "raised SystemExit"), ("sys.exit(3)", "raised SystemExit: 3"),
    ("(_ for _ in ()).throw(GeneratorExit())", "raised GeneratorExit"),
    ("1 / 0", "raised ZeroDivisionError: division by zero"),
])
def test_a_learner_that_raises_or_exits_is_one_line_and_exit_1(tmp_path, monkeypatch, raised, shown):
    for bad_from in (1, 3):  # in the made-up run, and inside a trial
        result = _run(tmp_path / str(bad_from), monkeypatch, f"({raised})", f"+learner.params.bad_from={bad_from}",
                      f"executor.confine={'off' if bad_from == 3 else 'auto'}")
        assert result.exit_code == 1, result.output
        line = result.output.strip().splitlines()[-1]
        assert "learner bad: choose(0, 0) " + shown in line or (bad_from == 3 and "learner bad: choose(" in line
                                                                 and shown in line)
        assert "Traceback" not in result.output


def test_q_tables_of_the_wrong_shape_are_refused(tmp_path, monkeypatch):
    result = _run(tmp_path, monkeypatch, "0", "+learner.params.shape=[6,2,3]")
    assert result.exit_code == 1
    assert result.output.strip().splitlines()[-1] == (
        "error: learner bad: q_tables() has shape (6, 2, 3); it must be (6, 2, 2) (robots, states, circuits), or None")


def test_a_learner_drawing_from_the_global_generator_is_named_in_a_warning(tmp_path, monkeypatch):
    import random

    state = random.getstate()
    result = _run(tmp_path, monkeypatch, "0", "+learner.params.use_global=true")
    assert result.exit_code == 0, result.output
    assert "warning: learner bad draws from Python's or numpy's global random generator" in result.output
    quiet = _run(tmp_path / "again", monkeypatch, "0")
    assert quiet.exit_code == 0 and "warning: learner bad" not in quiet.output
    random.setstate(state)


def test_a_name_that_other_rows_carry_is_refused(tmp_path, monkeypatch):
    monkeypatch.setenv(CONFIG_DIRS_ENV, str(_folder(tmp_path, "0")))
    with pytest.raises(TavcError, match="learner.name: 'theory' names other rows of tavc's tables"):
        config.load_config(["experiment=initial_distribution", "scale=smoke", "learner=bad", "learner.name=theory"])


def test_check_choice_by_hand():
    import numpy as np

    assert check_choice("x", 0, 0, 1, 2) == 1 and check_choice("x", 0, 0, np.int32(0), 2) == 0
    for bad in (2, -1, 1.0, None, True, np.bool_(True), "1", [0]):
        with pytest.raises(TavcError, match=r"learner x: choose\(robot=0, state=0\) returned"):
            check_choice("x", 0, 0, bad, 2)


def test_editing_a_learners_file_changes_its_trials_keys_only(tmp_path, monkeypatch):
    folder = _folder(tmp_path, "0")
    monkeypatch.setenv(CONFIG_DIRS_ENV, str(folder))
    overrides = ["experiment=initial_distribution", "scale=smoke", "learner=bad", "baselines=[random]", "trials=2"]

    def keys() -> dict[tuple[str, int], str]:
        cfg = config.settings(config.load_config(overrides))
        return {(s.controller, s.trial): s.key() for s in trial_specs(cfg)}

    first = keys()
    digest = target_digest("bad.py:Learner")
    (folder / "bad.py").write_text(LEARNER.replace("ANSWER", "1"))  # a fix to the learner
    second = keys()
    assert target_digest("bad.py:Learner") != digest
    assert {k for k in first if first[k] != second[k]} == {("bad", 0), ("bad", 1)}  # random's unchanged
    (folder / "helper.py").write_text("X = 1\n")  # a module beside it, which it may import
    assert keys()[("bad", 0)] != second[("bad", 0)] and keys()[("random", 0)] == first[("random", 0)]
