"""A learner from outside tavc runs in processes held to its run's folder (`confine`): what it
writes elsewhere is refused by the kernel, and tavc's own process never runs its code."""

from __future__ import annotations

import ctypes
import errno
import fcntl
import importlib
import os
import pickle
import socket
import sys
import termios
import time
import zlib
from pathlib import Path

import numba.core.config
import pytest
from typer.testing import CliRunner

from tavc_cli import config, confine, confined
from tavc_cli.cli import app
from tavc_cli.errors import TavcError
from tavc_cli.experiments.build import in_this_process, trial_specs

CAN_CONFINE = confine.refusal() is None  # Landlock, and nothing (a container's filter) refusing a part
needs_landlock = pytest.mark.skipif(not CAN_CONFINE, reason="this system cannot confine a process")

# a learner that writes `where` when its module is imported (at_import) or on its 400th choice
# (rehearsals choose fewer times than that; one trial of 30,000 s more)
LEARNER = '''
import os

WHERE, AT_IMPORT = {where!r}, {at_import!r}
if AT_IMPORT:
    with open(WHERE, "w") as f:
        f.write("written at import")


class Writer:
    calls = 0

    def __init__(self, n_robots, n_circuits, rng):
        pass

    def choose(self, robot, state):
        Writer.calls += 1
        if not AT_IMPORT and Writer.calls == 400:
            with open(WHERE, "w") as f:
                f.write("written by a choice")
        return robot % 2

    def learn(self, robot, state, action, reward, next_state):
        pass
'''


def _write(path: Path, text: str) -> str:
    path.write_text(text)
    return "written"


@needs_landlock
def test_a_confined_process_writes_beneath_its_folders_only(tmp_path):
    inside, outside = tmp_path / "inside", tmp_path / "outside"
    inside.mkdir()
    outside.mkdir()
    (inside / "kept").write_text("mine")
    assert confined.run_confined(_write, inside / "table.csv", "a,b\n", folders=[inside]) == "written"
    assert (inside / "table.csv").read_text() == "a,b\n"
    with pytest.raises(TavcError, match=r"_write failed in its confined process: PermissionError: .*outside"):
        confined.run_confined(_write, outside / "x", "no", folders=[inside])
    with pytest.raises(TavcError, match="PermissionError"):  # moving a file out is writing outside
        confined.run_confined(os.rename, inside / "kept", outside / "kept", folders=[inside])
    with pytest.raises(TavcError, match="PermissionError"):  # held to nothing: not even its own folder
        confined.run_confined(_write, inside / "y", "no", folders=[])
    assert confined.run_confined(_write, Path(os.devnull), "x", folders=[]) == "written"  # holds nothing
    assert sorted(p.name for p in tmp_path.rglob("*")) == ["inside", "kept", "outside", "table.csv"]
    assert (tmp_path / "z").write_text("this process is not confined") > 0


@needs_landlock
def test_a_confined_process_compiles_a_kernel_without_writing_numbas_cache(tmp_path, monkeypatch):
    monkeypatch.setattr(numba.core.config, "CACHE_DIR", str(tmp_path / "cache"))  # outside the folder below
    (tmp_path / "fresh_kernel.py").write_text("import numba\n\n\n@numba.njit(cache=True)\ndef doubled(x):\n"
                                              "    return 2 * x\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    fresh = importlib.import_module("fresh_kernel")  # its cache folder chosen here, as tavc's kernels' are
    (tmp_path / "run").mkdir()
    assert confined.run_confined(fresh.doubled, 21, folders=[tmp_path / "run"]) == 42  # compiled there, not saved
    assert not [p for p in (tmp_path / "cache").rglob("*") if p.is_file()]
    assert fresh.doubled(4) == 8 and [p for p in (tmp_path / "cache").rglob("*") if p.is_file()]  # saved here
    (tmp_path / "learners_kernel.py").write_text((tmp_path / "fresh_kernel.py").read_text())
    # a learner's own cache=True function, decorated in the copy
    assert confined.run_confined(_import_and_call, "learners_kernel", folders=[tmp_path / "run"]) == 6


def _import_and_call(module: str) -> int:
    return importlib.import_module(module).doubled(3)


def _gone(pid: int) -> bool:
    """Whether `pid` is gone within 5 s (a process killed and reaped by another is so at once)."""
    for _ in range(100):
        try:
            os.kill(pid, 0)
        except ProcessLookupError:
            return True
        time.sleep(0.05)
    return False


def _refuse() -> None:
    raise TavcError("learner.target: a line of its own")


def _die() -> None:
    os._exit(3)


def test_what_a_confined_process_answers_comes_back_as_one_line(tmp_path):
    if not CAN_CONFINE:
        pytest.skip("this system cannot confine a process")
    with pytest.raises(TavcError, match=r"^learner.target: a line of its own$"):
        confined.run_confined(_refuse)
    with pytest.raises(TavcError, match=r"_die held to its folders ended without an answer \(exit status 3\)"):
        confined.run_confined(_die)
    assert confined.run_confined(sorted, [3, 1, 2]) == [1, 2, 3]


class _Payload:
    """An object that would run code where it is unpickled."""
    def __reduce__(self):
        return (os.system, ("touch payload-ran",))


def _payload() -> _Payload:
    return _Payload()


def _forged_answer() -> str:
    os.write(confined._MESSAGES, pickle.dumps(("value", _Payload())) + b"\n")  # straight into the channel
    return "forged"


def _held_file(fd: int) -> str:
    try:
        os.write(fd, b"overwritten")
    except OSError as error:
        return error.strerror
    return "written"


def _type_into(tty: str) -> str:
    fd = os.open(tty, os.O_RDONLY | os.O_NOCTTY)
    try:
        fcntl.ioctl(fd, termios.TIOCSTI, b"x")
    except OSError as error:
        return error.strerror
    return "typed"


def _leave_a_helper() -> int:
    pid = os.fork()
    if pid == 0:
        time.sleep(120)
        os._exit(0)
    print("said by the copy\x1b]0;a title\x07", file=sys.stderr)
    return pid


@needs_landlock
def test_a_confined_process_can_touch_nothing_of_this_one(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    with pytest.raises(TavcError, match="TypeError: Object of type _Payload is not JSON serializable"):
        confined.run_confined(_payload)  # its answer is JSON or nothing
    with pytest.raises(TavcError, match="a worker process sent a message that is not one tavc reads"):
        confined.run_confined(_forged_answer)  # a pickle is never read here
    assert not (tmp_path / "payload-ran").exists()
    with open(tmp_path / "mine.txt", "w") as held:  # a file the caller holds open is closed in the copy
        assert confined.run_confined(_held_file, held.fileno()) == "Bad file descriptor"
    assert (tmp_path / "mine.txt").read_text() == ""
    _, tty = os.openpty()
    assert confined.run_confined(_type_into, os.ttyname(tty)) == "Operation not permitted"  # no TIOCSTI
    helper = confined.run_confined(_leave_a_helper)  # answers at once, and its helper goes with it
    said = capsys.readouterr().err  # its errors passed on here, a terminal's escape as words
    assert "said by the copy?]0;a title?" in said and "\x1b" not in said and "\x07" not in said
    assert _gone(helper), "the helper the copy left is still running"


def _reach_out() -> list:
    said = []
    for what, attempt in (("signal", lambda: os.kill(os.getppid(), 0)),
                          ("tcp", lambda: socket.create_connection(("127.0.0.1", 9), timeout=1))):
        try:
            attempt()
            said.append(f"{what}: done")
        except OSError as error:
            said.append(f"{what}: {error.errno}")
    return said


@pytest.mark.skipif(confine.landlock_abi() < 6, reason="this kernel's Landlock scopes neither signals nor TCP")
def test_a_confined_process_neither_signals_this_one_nor_opens_a_tcp_connection():
    assert confined.run_confined(_reach_out) == [f"signal: {errno.EPERM}", f"tcp: {errno.EACCES}"]
    os.kill(os.getpid(), 0)  # this process is not confined


def _escape_and_stay() -> int:
    """A helper that leaves the copy's session and its own parent, as a daemon does."""
    read_end, write_end = os.pipe()
    if os.fork() == 0:
        os.setsid()
        if os.fork() == 0:
            os.write(write_end, f"{os.getpid()}\n".encode())

            time.sleep(120)
        os._exit(0)
    return int(os.read(read_end, 64))


def _trace_me() -> str:
    libc = ctypes.CDLL(None, use_errno=True)
    if libc.ptrace(0, 0, None, None) != 0:  # PTRACE_TRACEME
        return os.strerror(ctypes.get_errno())
    return "traced"


def _make_a_device(folder: str) -> str:
    try:
        os.mknod(os.path.join(folder, "disk"), 0o600 | 0o060000, os.makedev(7, 0))
    except OSError as error:
        return error.strerror
    return "made"


def _deep() -> str:
    os.write(confined._MESSAGES, b"[" * 200_000 + b"\n")
    return "sent"


@needs_landlock
def test_nothing_a_confined_process_starts_outlives_it_and_it_makes_no_device(tmp_path):
    daemon = confined.run_confined(_escape_and_stay)
    assert _gone(daemon), "a process the copy started outlived it"  # though it left its session and its parent
    assert confined.run_confined(_make_a_device, str(tmp_path), folders=[tmp_path]) == "Permission denied"
    assert confined.run_confined(_trace_me) == "Operation not permitted"  # no tracing: none hides from the keeper
    with pytest.raises(TavcError, match="^a worker process sent a message that is not one tavc reads$"):
        confined.run_confined(_deep)  # nested deeper than Python reads: one line


def _unit(i: int, report) -> dict:
    report(0.5)
    if i == 2:
        os._exit(7)
    return {"square": i * i}


@needs_landlock
def test_units_run_in_confined_copies_and_a_copy_that_ends_is_named(tmp_path):
    heard: list = []
    results = confined.run_units(2, 2, [tmp_path], _unit, lambda i, f: heard.append((i, f)), str)
    assert results == [{"square": 0}, {"square": 1}] and sorted(heard) == [(0, 0.5), (1, 0.5)]
    with pytest.raises(TavcError, match=r"a worker process ended \(exit status 7\) while running trials 2 "):
        confined.run_units(4, 2, [tmp_path], _unit, lambda i, f: None, str)


def test_a_kernel_that_refuses_the_confinement_is_one_line(monkeypatch):
    if not CAN_CONFINE:
        pytest.skip("this system cannot confine a process")

    def refused(folders):
        raise PermissionError(1, "Operation not permitted")

    monkeypatch.setattr(confined, "confine_writes", refused)  # as a container's seccomp profile may
    with pytest.raises(TavcError, match=r"^cannot hold a learner from outside tavc to its folder here \(\[Errno 1\] "
                                        r"Operation not permitted\); give executor.confine=off"):
        confined.run_confined(sorted, [2, 1])


def test_when_a_learner_from_outside_runs_confined(monkeypatch, capsys):
    tried = confine.refusal
    assert confine.confinement("off") is False
    with pytest.raises(TavcError, match=r"executor.confine=on: .*executor.backend=dask"):
        confine.confinement("on", "dask")
    monkeypatch.setattr(confine, "refusal", lambda: "this system has no Landlock (Linux 5.13 or later)")
    monkeypatch.setattr(confine, "_SAID", set())
    with pytest.raises(TavcError, match="executor.confine=on: .*no Landlock"):
        confine.confinement("on")
    assert confine.confinement("auto") is False
    assert confine.confinement("auto") is False
    said = capsys.readouterr().err
    assert said.count("note: a learner from outside tavc runs unconfined") == 1 and "no Landlock" in said
    monkeypatch.setattr(confine, "refusal", lambda: None)
    assert confine.confinement("auto") is True and confine.confinement("on") is True
    if CAN_CONFINE:  # tried for real, not from the cache: this machine confines; a container may refuse
        assert tried.__wrapped__() is None

        def refused(folders):
            raise PermissionError(1, "Operation not permitted")

        monkeypatch.setattr(confine, "confine_writes", refused)
        assert tried.__wrapped__() == "this system refuses it ([Errno 1] Operation not permitted)"


def _run(tmp_path: Path, at_import: bool, *extra: str):
    (tmp_path / "writer.py").write_text(LEARNER.format(where=str(tmp_path / "outside.txt"), at_import=at_import))
    args = ["run", "experiment=initial_distribution", "scale=smoke", "learner=plugin", "learner.name=writer",
            f"learner.target={tmp_path / 'writer.py'}:Writer", "baselines=[]", "trials=1", "duration_s=30000",
            "executor.n_jobs=1", f"output_dir={tmp_path / 'run'}", "--no-progress", *extra]
    return CliRunner().invoke(app, args)


@needs_landlock
def test_a_learner_that_writes_outside_its_run_is_refused_as_it_loads(tmp_path):
    result = _run(tmp_path, at_import=True)
    assert result.exit_code == 1
    assert "learner.target" in result.output and "PermissionError" in result.output
    assert "Traceback" not in result.output
    assert not (tmp_path / "outside.txt").exists() and not (tmp_path / "run").exists()
    loaded = f"tavc_plugin_{zlib.crc32(str((tmp_path / 'writer.py').resolve()).encode()):08x}"
    assert loaded not in sys.modules  # tavc's own process never loaded it (`plugins.load_target` names it so)

    result = _run(tmp_path, True, "executor.confine=off")  # unconfined, it writes (the test can fail)
    assert (tmp_path / "outside.txt").read_text() == "written at import"


@pytest.mark.slow
@needs_landlock
def test_a_learner_that_writes_outside_its_run_fails_its_trial(tmp_path):
    result = _run(tmp_path, at_import=False)
    assert result.exit_code == 1
    assert "trial writer_000" in result.output and "PermissionError" in result.output
    assert not (tmp_path / "outside.txt").exists()
    assert "PermissionError" in (tmp_path / "run" / "failures.log").read_text()

    result = _run(tmp_path, False, "executor.confine=off")
    assert result.exit_code == 0, result.output
    assert (tmp_path / "outside.txt").read_text() == "written by a choice"


def test_a_study_that_times_trials_here_refuses_a_learner_from_outside(tmp_path):
    (tmp_path / "writer.py").write_text(LEARNER.format(where=str(tmp_path / "outside.txt"), at_import=False))
    learner = ["learner=plugin", "learner.name=writer", f"learner.target={tmp_path / 'writer.py'}:Writer"]
    specs = trial_specs(config.settings(config.load_config(["experiment=initial_distribution", "scale=smoke",
                                                             "executor.confine=off", *learner])))
    with pytest.raises(TavcError, match=r"^the study's speed runs its trials in its own process.*confine=off$"):
        in_this_process(specs, "auto", "the study's speed")
    in_this_process(specs, "off", "the study's speed")  # asked for: it may
    tavc = [s for s in specs if s.controller == "random"]
    in_this_process(tavc, "on", "the study's speed")  # tavc's own learners run anywhere
    assert not (tmp_path / "outside.txt").exists()


def test_tavc_animate_refuses_to_run_a_learner_from_outside_in_its_own_process(tmp_path):
    (tmp_path / "writer.py").write_text(LEARNER.format(where=str(tmp_path / "outside.txt"), at_import=False))
    result = CliRunner().invoke(app, ["animate", "experiment=initial_distribution", "scale=smoke", "learner=plugin",
                                      "learner.name=writer", f"learner.target={tmp_path / 'writer.py'}:Writer",
                                      f"output_dir={tmp_path / 'anim'}", "--duration-s", "5", "--fps", "1"])
    assert result.exit_code == 1 and "Traceback" not in result.output
    assert result.output.strip().splitlines()[-1] == (
        "error: tavc animate runs its trials in its own process, which is not held to a folder; a learner from "
        "outside tavc (learner.target) runs there only with executor.confine=off")
    assert not (tmp_path / "anim").exists()


def test_executor_confine_takes_its_three_words():
    result = CliRunner().invoke(app, ["run", "experiment=initial_distribution", "scale=smoke", "executor.confine=yes"])
    assert result.exit_code == 1
    assert "executor.confine" in result.output and "auto" in result.output and "Traceback" not in result.output
