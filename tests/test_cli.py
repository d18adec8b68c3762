"""The ``tavc`` command line: help, config, list, and one-line errors."""

import os
import re
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
import yaml
from typer.testing import CliRunner

from tavc_cli import __version__
from tavc_cli.cli import app
from tests.helpers import REPO

runner = CliRunner()


def test_help_lists_the_commands():
    result = runner.invoke(app, ["--help"])
    assert result.exit_code == 0
    for command in ("run", "reproduce", "list", "config", "bench", "animate"):
        assert command in result.output


def test_no_arguments_shows_help():
    result = runner.invoke(app, [])
    assert "Usage" in result.output


def test_version():
    result = runner.invoke(app, ["--version"])
    assert result.exit_code == 0
    assert __version__ in result.stdout


def test_python_dash_m_works():
    completed = subprocess.run(
        [sys.executable, "-m", "tavc_cli", "--help"],
        cwd=REPO,
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert completed.returncode == 0, completed.stderr
    assert "config" in completed.stdout


def test_config_prints_parseable_yaml_with_the_override():
    result = runner.invoke(app, ["config", "experiment=breakdown", "learner.epsilon=0.2", "seed=7"])
    assert result.exit_code == 0, result.output
    parsed = yaml.safe_load(result.stdout)
    assert parsed["learner"]["epsilon"] == 0.2
    assert parsed["seed"] == 7
    assert parsed["experiment_name"] == "breakdown"
    assert parsed["trials"] == 6


def test_list_prints_one_line_per_experiment():
    expected = {
        "spatiotemporal",
        "initial_distribution",
        "breakdown",
        "breakdown_no_vacancy",
        "value_change",
        "heterogeneous",
    }
    result = runner.invoke(app, ["list"])
    assert result.exit_code == 0, result.output
    lines = [line for line in result.stdout.splitlines() if line.strip()]
    names = {line.split()[0] for line in lines}
    assert expected <= names
    assert len(lines) == len(names)


@pytest.mark.parametrize(
    ("args", "key"),
    [
        (["config", "team.n_robots=-2"], "team.n_robots"),
        (["config", "learner=tavc_egreedy", "learner.epsilon=1.5"], "learner.epsilon"),
        (["config", "arena.targets.0.x=20"], "arena.targets[0].x"),
        (["config", "team.n_robot=3"], "team.n_robot"),
        (["config", "seed=abc"], "seed"),
        (["config", "arena=nope"], "arena"),
        (["config", "experiment=breakdown", "tasks.values=[1,2,3]"], "tasks.values"),
        (["config", "learner.epsilon=[1"], "learner.epsilon"),
        (["run", "learner.epsilon=0.1,0.2"], "learner.epsilon"),
        (["run", "-m", "learner=tavc_egreedy", "learner.epsilon=0.1,1.5"], "learner.epsilon"),
        (["animate", "team.n_robots=0"], "team.n_robots"),
        (["run", "-m", "scale=smoke", "learner=tavc_egreedy", "learner.epsilon=0.1,0.2", "hydra/launcher=nope"],
         "hydra/launcher"),
        (["run", "-m", "scale=smoke", "hydra/launcher=joblib", "hydra.launcher.n_jobs=two"], "hydra.launcher.n_jobs"),
        (["run", "scale=smoke", "hydra/launcher=joblib"], "hydra/launcher"),
        (["config", "robot.dock.patience_s=-5"], "robot.dock.patience_s"),
        (["report", "/nonexistent/results"], "RESULTS_DIR"),
    ],
)
def test_bad_input_is_one_error_line_and_exit_1(args, key):
    result = runner.invoke(app, args)
    assert result.exit_code == 1, result.output
    lines = [line for line in result.output.splitlines() if line.strip()]
    assert len(lines) == 1, result.output
    assert lines[0].startswith("error: ")
    assert key in lines[0]
    assert result.stderr.strip() == lines[0]
    assert "Traceback" not in result.output


def test_a_sweep_writes_its_jobs_side_by_side(tmp_path):
    import pandas as pd

    out = tmp_path / "sweep"
    result = CliRunner().invoke(app, ["run", "-m", "experiment=initial_distribution", "scale=smoke", "baselines=[]",
                                      "learner.epsilon=0.05,0.3", f"output_dir={out}"])
    assert result.exit_code == 0, result.output
    table = pd.read_csv(out / "sweep.csv")
    assert sorted(table["learner.epsilon"].unique()) == [0.05, 0.3]
    for job, eps in ((0, 0.05), (1, 0.3)):
        rows = table[(table["job"] == job) & (table["controller"] == "tavc")]
        assert set(rows["learner.epsilon"]) == {eps}
        # the job's own state table, row for row
        own = pd.read_csv(out / f"{job}_learner.epsilon={eps}" / "state_time.csv")
        own = own[own["controller"] == "tavc"]
        assert list(rows["state"]) == list(own["state"])
        assert list(rows["mean_pct"].round(4)) == list(own["mean_pct"].round(4))
    assert (out / "sweep.png").is_file() and (out / "sweep.svg").is_file()


@pytest.mark.slow
def test_sweep_jobs_run_through_submitit_as_on_slurm_with_the_basic_launchers_results(tmp_path):
    """Slurm's launcher (hydra-submitit-launcher) has a local twin that runs each job as a
    submitit job in a process of its own, pickled and unpickled as on a cluster: its tables are
    the basic launcher's byte for byte."""
    sweep = ["run", "-m", "experiment=initial_distribution", "scale=smoke", "trials=1", "baselines=[]",
             "duration_s=300", "learner.epsilon=0.05,0.3"]
    basic = CliRunner().invoke(app, [*sweep, f"output_dir={tmp_path / 'basic'}"])
    assert basic.exit_code == 0, basic.output
    local = CliRunner().invoke(app, [*sweep, f"output_dir={tmp_path / 'submitit'}", "hydra/launcher=submitit_local",
                                     "hydra.launcher.timeout_min=20"])
    assert local.exit_code == 0, local.output
    for job in ("0_learner.epsilon=0.05", "1_learner.epsilon=0.3"):
        for table in ("state_time.csv", "performance.csv", "trial_stats.csv"):
            assert (tmp_path / "basic" / job / table).read_bytes() == (
                tmp_path / "submitit" / job / table).read_bytes()
    # the sweep's table names each job's folder: the same table but for the folder's name
    assert (tmp_path / "submitit" / "sweep.csv").read_text().replace("submitit", "basic") == (
        tmp_path / "basic" / "sweep.csv").read_text()
    # submitit keeps its jobs' logs in the sweep's folder, under .submitit/ (documented)
    assert (tmp_path / "submitit" / ".submitit").is_dir()


@pytest.mark.slow
def test_sweep_jobs_run_through_hydras_joblib_launcher_with_the_basic_launchers_results(tmp_path):
    """The launcher decides where jobs run, never what they compute."""
    sweep = ["run", "-m", "experiment=initial_distribution", "scale=smoke", "learner.epsilon=0.05,0.3"]
    basic = CliRunner().invoke(app, [*sweep, f"output_dir={tmp_path / 'basic'}"])
    assert basic.exit_code == 0, basic.output
    joblib = CliRunner().invoke(app, [*sweep, f"output_dir={tmp_path / 'joblib'}", "hydra/launcher=joblib",
                                      "hydra.launcher.n_jobs=2"])
    assert joblib.exit_code == 0, joblib.output
    for job in ("0_learner.epsilon=0.05", "1_learner.epsilon=0.3"):
        for table in ("state_time.csv", "performance.csv", "claims.csv"):
            assert (tmp_path / "basic" / job / table).read_bytes() == (tmp_path / "joblib" / job / table).read_bytes()
    # Hydra writes nothing of its own: no .hydra/ folder, no log file (.tavc.json is tavc's list of its files)
    assert sorted(p.name for p in (tmp_path / "joblib").iterdir()) == [
        ".tavc.json", "0_learner.epsilon=0.05", "1_learner.epsilon=0.3", "sweep.csv", "sweep.png", "sweep.svg"]
    assert not list((tmp_path / "joblib").rglob(".hydra")) and not list((tmp_path / "joblib").rglob("*.log"))


def test_a_refused_launcher_writes_nothing(tmp_path):
    out = tmp_path / "never"
    result = runner.invoke(app, ["run", "-m", "scale=smoke", "learner=tavc_egreedy", "learner.epsilon=0.1,0.2",
                                 "hydra/launcher=nope",
                                 f"output_dir={out}"])
    assert result.exit_code == 1
    assert "basic" in result.output  # the message lists the launchers there are
    assert not out.exists()


def test_an_empty_config_dir_is_refused_not_taken_for_the_working_folder(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)  # a working folder that holds configs: '' would have read them
    (tmp_path / "experiment").mkdir()
    (tmp_path / "experiment" / "mine.yaml").write_text("# @package _global_\nseed: 3\n")
    result = runner.invoke(app, ["--config-dir", "", "config", "experiment=mine"], catch_exceptions=False)
    assert result.exit_code == 1
    assert result.output.strip() == ("error: --config-dir: an empty folder name; give the folder of your configs "
                                     "('.' for the working folder)")


@pytest.mark.parametrize(("args", "line"), [
    (["surrogate", "--results", "elsewhere", "experiment=breakdown", "scale=smoke"],
     "error: --results: belongs to --study; a surrogate run writes into output_dir"),
    (["surrogate", "--simulator", "nowhere", "experiment=breakdown", "scale=smoke"],
     "error: --simulator: belongs to --study; a surrogate run writes into output_dir"),
    (["surrogate", "--parts", "nope", "experiment=breakdown", "scale=smoke"],
     "error: --parts: belongs to --study; a surrogate run writes into output_dir"),
    (["surrogate", "--study", "--parts", " , "],
     "error: --parts: names no part; give one or more of compare, ladder, phase, horizon, speed"),
])
def test_a_surrogate_option_out_of_place_is_one_line_and_runs_nothing(tmp_path, monkeypatch, args, line):
    monkeypatch.chdir(tmp_path)
    result = runner.invoke(app, args, catch_exceptions=False)
    assert result.exit_code == 1
    assert result.output.splitlines() == [line]
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize(("args", "line"), [
    (["bench", "--batch", "0"], "error: Invalid value for '--batch': Input should be greater than or equal to 1"),
    (["nosuch"], "error: No such command 'nosuch'."),
    (["run", "--cfg", "job"], "error: No such option: --cfg"),
    (["list", "foo"], "error: Got unexpected extra argument(s) (foo)"),
])
def test_a_usage_mistake_is_one_line_and_exit_2(args, line):
    """What the option parser refuses is one line too, in the installed command as in python -m."""
    result = subprocess.run([sys.executable, "-m", "tavc_cli", *args], capture_output=True, text=True)
    assert result.returncode == 2
    assert result.stderr.strip() == f"{line} (tavc --help)"
    assert result.stdout == ""


@pytest.mark.parametrize(("args", "line"), [
    (["--duration-s", "nan"],
     "--duration-s: must be in [2, 36000] s (two frames to 36,000, a frame every 1 s), got nan"),
    (["--duration-s", "0.01"],
     "--duration-s: must be in [2, 36000] s (two frames to 36,000, a frame every 1 s), got 0.01"),
])
def test_animate_refuses_what_it_cannot_draw_before_simulating(tmp_path, args, line):
    result = runner.invoke(app, ["animate", "scale=smoke", f"output_dir={tmp_path / 'out'}", *args])
    assert result.exit_code == 1
    assert result.output.strip() == f"error: {line}"
    assert not (tmp_path / "out").exists()


def test_animate_refuses_an_output_it_cannot_write_before_simulating(tmp_path):
    (tmp_path / "afile").write_text("")
    result = runner.invoke(app, ["animate", "scale=smoke", "--out", str(tmp_path / "afile" / "x.gif")])
    assert result.exit_code == 1
    assert result.output.startswith(f"error: --out: cannot write into {tmp_path / 'afile'}: ")


def test_a_sweep_holds_its_folder_and_an_empty_sweep_is_refused(tmp_path):
    from tavc_cli.io import LOCK_NAME, claim_folder

    sweep = ["run", "-m", "scale=smoke", "trials=1", "baselines=[]", "seed=1,2", f"output_dir={tmp_path}"]
    with claim_folder(tmp_path):  # another run holds the folder the jobs' folders would go in
        result = runner.invoke(app, sweep)
    assert result.exit_code == 1
    assert result.output.startswith(f"error: output_dir: {tmp_path} is in use by another tavc run (")
    assert sorted(p.name for p in tmp_path.iterdir()) == []
    result = runner.invoke(app, ["run", "-m", "scale=smoke", "seed=range(5,1)", f"output_dir={tmp_path}"])
    assert result.exit_code == 1
    assert result.output.strip() == "error: seed: the sweep gives it no values, so there is no job to run"
    assert not (tmp_path / LOCK_NAME).exists()


# ------------------------------------------------------------------------------- faults of the machine


def _failing_saves(monkeypatch, counter: Path, after: int, error) -> None:
    """Trial records fail to save with `error(path)` after the first `after` (counted in a file,
    so that worker processes count too)."""
    from tavc_cli.experiments.records import TrialRecord

    counter.write_text("0")
    save = TrialRecord.save

    def failing(self, path):
        done = int(counter.read_text())
        counter.write_text(str(done + 1))
        if done >= after:
            raise error(path)
        return save(self, path)

    monkeypatch.setattr(TrialRecord, "save", failing)


SMALL_RUN = ["run", "scale=smoke", "experiment=initial_distribution", "executor.n_jobs=1", "executor.batch_size=1"]


def test_a_full_disk_is_one_line_and_the_finished_trials_resume(tmp_path, monkeypatch):
    import errno

    out = tmp_path / "out"
    _failing_saves(monkeypatch, tmp_path / "saves", 2,
                   lambda path: OSError(errno.ENOSPC, "No space left on device", str(path)))
    result = runner.invoke(app, [*SMALL_RUN, f"output_dir={out}"])
    assert result.exit_code == 1
    assert result.output.splitlines() == [
        f"error: {out / 'trials' / 'random_000.npz'}: No space left on device; free some space on that disk or "
        "choose another output_dir (finished trials are kept: rerun the same command to resume)"]
    monkeypatch.undo()  # space again
    result = runner.invoke(app, [*SMALL_RUN, f"output_dir={out}"])
    assert result.exit_code == 0, result.output
    assert "trials: 4 (2 reused)" in result.output


def test_an_os_error_without_a_file_names_the_output_folder(tmp_path, monkeypatch):
    """As one raised in a worker process and sent back to the run arrives: no file name."""
    import errno

    out = tmp_path / "out"
    _failing_saves(monkeypatch, tmp_path / "saves", 0, lambda path: OSError(errno.ENOSPC, "No space left on device"))
    result = runner.invoke(app, [*SMALL_RUN, f"output_dir={out}"])
    assert result.exit_code == 1
    assert result.output.startswith(f"error: {out}: No space left on device; free some space")
    assert len(result.output.splitlines()) == 1


def test_a_trials_folder_without_write_permission_is_one_line(tmp_path, monkeypatch):
    import errno

    out = tmp_path / "out"
    # what atomic_path's temporary file beside the record raises in a folder one may not write
    _failing_saves(monkeypatch, tmp_path / "saves", 0, lambda path: PermissionError(
        errno.EACCES, "Permission denied", str(Path(path).parent / f".{Path(path).name}.x1y2.tmp")))
    result = runner.invoke(app, [*SMALL_RUN, f"output_dir={out}"])
    assert result.exit_code == 1
    assert result.output.splitlines() == [
        f"error: {out / 'trials'}: Permission denied; make the folder writable for you or choose another "
        "output_dir (finished trials are kept: rerun the same command to resume)"]


@pytest.mark.skipif(not hasattr(os, "geteuid") or os.geteuid() == 0, reason="root writes where permissions forbid")
def test_a_real_trials_folder_without_write_permission_is_one_line(tmp_path):
    out = tmp_path / "out"
    (out / "trials").mkdir(parents=True)
    (out / "trials").chmod(0o500)
    try:
        result = subprocess.run([sys.executable, "-m", "tavc_cli", *SMALL_RUN, f"output_dir={out}"],
                                capture_output=True, text=True, timeout=300)
    finally:
        (out / "trials").chmod(0o700)
    assert result.returncode == 1
    assert result.stderr.startswith(f"error: {out / 'trials'}: Permission denied;"), result.stderr
    assert len(result.stderr.splitlines()) == 1


def test_a_real_full_disk_is_one_line(tmp_path):
    """On a tmpfs of 100 kB, mounted in a mount namespace of this process's own (skipped where the
    system does not let a process make one)."""
    if not shutil.which("unshare") or subprocess.run(
            ["unshare", "-rm", "sh", "-c", f"mount -t tmpfs -o size=100k tmpfs {tmp_path}"],
            capture_output=True).returncode != 0:
        pytest.skip("cannot mount a small tmpfs here")
    out = tmp_path / "out"
    command = " ".join([sys.executable, "-m", "tavc_cli", *SMALL_RUN, "trials=8", f"output_dir={out}", "--no-progress"])
    result = subprocess.run(["unshare", "-rm", "sh", "-c", f"mount -t tmpfs -o size=100k tmpfs {tmp_path} && "
                             f"cd {REPO} && {command}; echo rc=$?; ls {out / 'trials'}"],
                            capture_output=True, text=True, timeout=300)
    assert "rc=1" in result.stdout, result.stdout + result.stderr
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith(f"error: {out}"), result.stderr
    assert lines[0].endswith(": No space left on device; free some space on that disk or choose another output_dir "
                             "(finished trials are kept: rerun the same command to resume)"), lines[0]
    assert ".npz" in result.stdout  # the trials finished before the disk filled are there


def test_ctrl_c_at_any_moment_is_one_line_and_exit_130(tmp_path):
    """While the modules load (before any command runs), and in the middle of a run."""
    interrupted = 0
    for args, delay in ((["config", "scale=smoke"], 0.1), (["config", "scale=smoke"], 0.25),
                        (["config", "scale=smoke"], 0.5), ([*SMALL_RUN, "trials=8", f"output_dir={tmp_path}"], 1.5)):
        process = subprocess.Popen([sys.executable, "-m", "tavc_cli", *args], cwd=REPO, stdout=subprocess.PIPE,
                                   stderr=subprocess.PIPE, text=True, start_new_session=True)
        time.sleep(delay)
        os.killpg(process.pid, signal.SIGINT)  # as the terminal sends Ctrl-C: to every process of the group
        _, stderr = process.communicate(timeout=60)
        assert "Traceback" not in stderr, stderr
        # killed by SIGINT itself (the shell's 130 too) only once the interpreter is winding down
        if stderr:
            assert stderr.strip() == "error: interrupted" and process.returncode in (130, -signal.SIGINT), stderr
            interrupted += 1
        else:  # done before the signal came, or ended by it in the interpreter's last moments
            assert process.returncode in (0, -signal.SIGINT)
    assert interrupted >= 2


def test_an_interrupt_a_library_hid_behind_its_own_error_is_still_an_interrupt(capsys):
    """Stopped by Ctrl-C while it builds a list, OmegaConf fails in its own clean-up and reports an
    unknown key (the chain below is the one it raises); the command still ends as interrupted, not
    as a mistake in the config. An error with no interrupt behind it stays that error."""
    import typer
    from omegaconf.errors import ConfigKeyError

    from tavc_cli.console import user_errors
    from tavc_cli.errors import TavcError, Terminated

    def unknown_key_over(stop):
        try:
            try:
                raise stop
            except KeyboardInterrupt:
                raise AttributeError("'NoneType' object has no attribute '_invalidate_flags_cache'") from None
        except AttributeError as error:
            try:
                raise ConfigKeyError(str(error)) from error
            except ConfigKeyError:
                raise TavcError("targets: unknown key") from None

    for stop, code, line in ((KeyboardInterrupt(), 130, "error: interrupted"),
                             (Terminated(), 143, "error: terminated"), (None, 1, "error: targets: unknown key")):
        with pytest.raises(typer.Exit) as ended, user_errors():
            if stop is None:
                raise TavcError("targets: unknown key")
            unknown_key_over(stop)
        assert ended.value.exit_code == code
        assert capsys.readouterr().err.strip() == line
    # OmegaConf also lets the clean-up's own error out as it is: an interrupt still, not a bug's traceback
    with pytest.raises(typer.Exit) as ended, user_errors():
        try:
            raise KeyboardInterrupt
        except KeyboardInterrupt:
            raise AttributeError("'NoneType' object has no attribute '_invalidate_flags_cache'") from None
    assert ended.value.exit_code == 130 and capsys.readouterr().err.strip() == "error: interrupted"
    with pytest.raises(AttributeError), user_errors():  # a bug with no interrupt behind it keeps its traceback
        raise AttributeError("a bug")
    # out of memory while stopping is the stop; an inner user_errors' line is said once, not read again
    with pytest.raises(typer.Exit) as ended, user_errors():
        try:
            raise KeyboardInterrupt
        except KeyboardInterrupt:
            raise MemoryError from None
    assert ended.value.exit_code == 130 and capsys.readouterr().err.strip() == "error: interrupted"
    with pytest.raises(typer.Exit) as ended, user_errors(), user_errors():
        raise KeyboardInterrupt
    assert ended.value.exit_code == 130 and capsys.readouterr().err.strip() == "error: interrupted"


# ------------------------------------------------------------------------------- what a summary says


def test_a_run_in_which_nothing_was_delivered_says_so(tmp_path):
    result = runner.invoke(app, ["run", "scale=smoke", "experiment=initial_distribution", "robot.speed_mps=0.001",
                                 "trials=1", f"output_dir={tmp_path / 'out'}"])
    assert result.exit_code == 0, result.output
    warnings = [line for line in result.output.splitlines() if line.startswith("warning:")]
    assert warnings == ["warning: nothing was delivered: no robot delivered anything in any of the 2 trials, so no "
                        "claim could be tested; can the robots move and reach the targets? (robot.speed_mps, "
                        "robot.mass_kg, robot.drive_force_n, arena.walls)"]


def test_one_trial_shows_no_spread(tmp_path):
    result = runner.invoke(app, ["run", "scale=smoke", "experiment=initial_distribution", "trials=1",
                                 f"output_dir={tmp_path / 'out'}"])
    assert result.exit_code == 0, result.output
    rows = [line for line in result.output.splitlines() if re.match(r"\s+\d:\d ", line)]
    assert len(rows) == 7 and all(line.count("+- nan") == 2 for line in rows), result.output
    assert "+- 0.0" not in result.output and "warning:" not in result.output


def test_animate_into_a_folder_names_the_folder_not_the_suffix(tmp_path):
    result = runner.invoke(app, ["animate", "scale=smoke", "--out", str(tmp_path)])
    assert result.exit_code == 1
    assert result.output.strip() == (f"error: --out: {tmp_path} is a folder; give the file to write in it, e.g. "
                                     f"--out {tmp_path / 'animation.gif'}")
    assert list(tmp_path.iterdir()) == []


def test_compare_help_lists_every_default_at_eighty_columns():
    """At 80 columns the help of `tavc compare` names every default learner and scenario in full
    (none cut off with an ellipsis), and its flags carry no type label."""
    from tavc_cli.cli import app
    from tavc_cli.compare import CONTROLLERS, SCENARIOS

    text = CliRunner().invoke(app, ["compare", "--help"], env={"COLUMNS": "80", "TERM": "dumb"}).output
    flat = " ".join(re.sub(r"[│╭╮╰╯─]", " ", text).split())
    for name in (*CONTROLLERS, *SCENARIOS):
        assert re.search(rf"\b{name}[,.]", flat), name
    assert "…" not in text
    assert not re.search(r"--no-progress\s+<bool>", flat)


@pytest.mark.parametrize("command", [[], *([c.name or c.callback.__name__] for c in app.registered_commands)])
def test_no_help_carries_a_type_label(command):
    """Every command's help says what an option takes in words: no `<bool>`, `<str>`,
    `<list[str]>` or `<path>` beside the options and arguments, and an argument is named in
    capitals (`OVERRIDES`, `RESULTS_DIR`) in the usage line and its panel."""
    text = runner.invoke(app, [*command, "--help"], env={"COLUMNS": "100", "TERM": "dumb"}).output
    assert "Usage" in text
    assert not re.search(r"<(bool|str|int|float|path|list\[\w+\])>", text), text
    usage = next(line for line in text.splitlines() if "Usage" in line)
    assert not re.search(r"\[[a-z_]+\]", usage), usage  # `[overrides]...` was lower case
