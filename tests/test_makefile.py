"""The Makefile's check targets, which reproduce the turn-taking model's grids of blind checks
(docs/readings.md): the commands they give tavc, each prediction's two ways and the learners'
runs into the folders the report reads, and a READING that is not a reading refused in one line
before anything runs. tavc is a stand-in here that prints its arguments; make's own python is
this one, so the readings are the project's. And the targets that build the environment: the
locked set through uv, or through pip where uv fails."""

from __future__ import annotations

import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from tavc_cli.chapter import base_case
from tavc_cli.report.tally import EXPLORED
from tests.helpers import REPO

pytestmark = pytest.mark.skipif(shutil.which("make") is None, reason="make is not installed")


def _make(tmp_path: Path, *args: str) -> subprocess.CompletedProcess:
    """`make -s ARGS` in the checkout with a stand-in venv under `tmp_path`: its `tavc` prints
    each call's arguments on a line, its `python` is the one running the tests, and its stamp says
    it is installed, so no target builds anything."""
    venv = tmp_path / "venv"
    if not venv.is_dir():
        (venv / "bin").mkdir(parents=True)
        (venv / "bin" / "tavc").write_text('#!/bin/sh\necho tavc "$@"\n')
        (venv / "bin" / "python").write_text(f'#!/bin/sh\nexec "{sys.executable}" "$@"\n')
        for name in ("tavc", "python"):
            (venv / "bin" / name).chmod(0o755)
        (venv / ".installed-stamp").touch()
    # the flags of a make that runs the tests (`make test`) would reach this one through the environment
    env = {k: v for k, v in os.environ.items() if k not in ("MAKEFLAGS", "MFLAGS", "MAKELEVEL", "MAKEOVERRIDES")}
    return subprocess.run(["make", "-s", "--no-print-directory", "-C", str(REPO), f"VENV={venv}",
                           "CONVERGED_BATCH=2", *args], capture_output=True, text=True, timeout=120, env=env)


def test_transition_targets_predict_both_ways_then_run_the_learners_in_a_reading(tmp_path):
    base = base_case().name
    reading = "dock-nearest-two_circuits_parallel"
    world = "arrival=dock passing=nearest arena=two_circuits_parallel"
    done = _make(tmp_path, "transition-predictions", f"READING={reading}", "TRANSITION_TEAM=5",
                 "TRANSITION_VALUES=2300 2400")
    assert done.returncode == 0, done.stderr
    folder = f"results/turn_taking/{reading}-team_size_5-value_ratio_"
    model = f"tavc model --turn-taking experiment={base} team.n_robots=5"
    assert done.stdout.splitlines() == [
        f"{model} tasks.values=[2300,2000] scale=paper {world} output_dir={folder}2300",
        f"{model} tasks.values=[2300,2000] scale=paper {world} surrogate.switches=explorers "
        f"output_dir={folder}2300{EXPLORED}",
        f"{model} tasks.values=[2400,2000] scale=paper {world} output_dir={folder}2400",
        f"{model} tasks.values=[2400,2000] scale=paper {world} surrogate.switches=explorers "
        f"output_dir={folder}2400{EXPLORED}"]
    done = _make(tmp_path, "transition-runs", f"READING={reading}", "TRANSITION_TEAM=5",
                 "TRANSITION_VALUES=2300 2400", "TRANSITION_RUNS=converged_odd")
    assert done.returncode == 0, done.stderr
    assert done.stdout.splitlines() == [
        f"tavc run -m experiment={base} scale=converged trials=20 baselines=[] {world} executor.batch_size=2 "
        f"team.n_robots=5 tasks.values=[2300,2000],[2400,2000] output_dir=results/team_size/{reading}/converged_odd"]


def test_todays_world_is_the_check_targets_world_without_a_reading(tmp_path):
    done = _make(tmp_path, "transition-predictions", "TRANSITION_VALUES=2100")
    assert done.returncode == 0, done.stderr
    lines = done.stdout.splitlines()
    assert len(lines) == 2 and all("arrival=" not in x for x in lines)
    assert lines[0].endswith(" output_dir=results/turn_taking/team_size_3-value_ratio_2100")
    assert lines[1].endswith(f" surrogate.switches=explorers output_dir=results/turn_taking/"
                             f"team_size_3-value_ratio_2100{EXPLORED}")


def test_the_second_grids_points_each_run_in_their_own_reading(tmp_path):
    """switch-checks names a reading per point (SWITCH_POINTS), the calibrated range reading among
    them, whatever READING says: its first prediction and its runs."""
    done = _make(tmp_path, "switch-checks")
    assert done.returncode == 0, done.stderr
    lines = done.stdout.splitlines()
    assert len(lines) == 15  # five points: two predictions each, then a run each
    calibrated = [x for x in lines if "range-left-two_circuits_parallel-calibrated" in x]
    assert len(calibrated) == 3 and all("robot.behaviour.read_range_m=2.0 robot.dock.dwell_s=5.0" in x
                                        for x in calibrated)
    assert lines[10].startswith("tavc run experiment=") and lines[10].endswith(
        " output_dir=results/team_size/dock-nearest-two_circuits_parallel/converged_switches/"
        "team_size_3-value_ratio_2000")


@pytest.mark.parametrize("target", ["team-size-checks", "small-team-value-checks", "firm-checks",
                                    "transition-predictions", "transition-runs"])
def test_a_reading_that_is_not_one_is_refused_in_one_line_before_anything_runs(tmp_path, target):
    done = _make(tmp_path, target, "READING=dock-nowhere-two_circuits")
    assert done.returncode != 0 and done.stdout == ""
    assert "READING=dock-nowhere-two_circuits is not one of the readings besides today's world" in done.stderr
    assert len(done.stderr.strip().splitlines()) == 1


def test_help_lists_every_target_that_describes_itself(tmp_path):
    described = re.findall(r"^([A-Za-z0-9_.-]+):[^\n]*## ", (REPO / "Makefile").read_text(), flags=re.M)
    done = _make(tmp_path, "help")
    assert done.returncode == 0, done.stderr
    listed = [line.split()[0] for line in done.stdout.splitlines() if line.strip()]
    assert "readings-x80" in described  # a name with a digit in it
    assert set(described) <= set(listed)


@pytest.mark.parametrize("uv_works", [True, False])
def test_the_venv_installs_the_locked_set_through_uv_or_else_pip(tmp_path, uv_works):
    """`make venv` and `make venv-test` install under the lock's constraints through uv, fetched by
    pip at the lock's version; where uv fails, pip installs the same under the same constraints.
    The stand-in python logs each call, and fails the ones that are uv's where uv does not work."""
    venv, log = tmp_path / "venv", tmp_path / "calls"
    (venv / "bin").mkdir(parents=True)
    fail = "" if uv_works else 'case "$*" in *"-m uv "*) exit 1;; esac\n'
    (venv / "bin" / "python").write_text(f'#!/bin/sh\necho "$*" >> "{log}"\n{fail}exit 0\n')
    (venv / "bin" / "python").chmod(0o755)
    maker = tmp_path / "python3"  # make's own python: makes the venv (here, nothing)
    maker.write_text(f'#!/bin/sh\necho "maker $*" >> "{log}"\n')
    maker.chmod(0o755)
    env = {k: v for k, v in os.environ.items() if k not in ("MAKEFLAGS", "MFLAGS", "MAKELEVEL", "MAKEOVERRIDES")}
    done = subprocess.run(["make", "-s", "--no-print-directory", "-C", str(REPO), f"VENV={venv}",
                           f"PYTHON={maker}", "venv-test"], capture_output=True, text=True, timeout=120, env=env)
    assert done.returncode == 0, done.stderr
    py = f"{venv}/bin/python"
    uv = ["-m pip install -q -c requirements.lock uv",
          f"-m uv pip install --compile-bytecode --python {py} -c requirements.lock"]  # compiled, as pip leaves it
    calls = log.read_text().splitlines()
    expected = [f"maker -m venv {venv}"]
    for target in ("-e .", "-e .[test]"):
        expected += [uv[0], f"{uv[1]} {target}"]
        if not uv_works:
            expected += ["-m pip install --upgrade pip", f"-m pip install -c requirements.lock {target}"]
    assert calls == expected
    assert (venv / ".installed-stamp").is_file() and (venv / ".test-installed-stamp").is_file()
