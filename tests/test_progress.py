"""What a run shows while it simulates (`pool.Progress`): nothing with --no-progress, a notice
while the kernels compile, and a time left from the throughput measured once simulating began."""

from __future__ import annotations

import time
from types import SimpleNamespace

from tavc_cli.experiments import pool
from tavc_cli.experiments.pool import Progress


def _batches(*seconds: float) -> list:
    return [SimpleNamespace(controller="tavc", index=i, sim_seconds=s) for i, s in enumerate(seconds)]


class Clock:
    """A stand-in for time.perf_counter that moves only when told."""

    def __init__(self) -> None:
        self.now = 100.0

    def __call__(self) -> float:
        return self.now


def test_not_shown_prints_nothing_whatever_happens(capsys, monkeypatch):
    monkeypatch.setattr(Progress, "COMPILE_NOTICE_S", 0.01)
    prog = Progress(_batches(1000.0, 1000.0), shown=False)
    assert prog.notice is None  # no notice is even set up
    time.sleep(0.05)
    prog.update(("tavc", 0), 0.5)
    prog.update(("tavc", 1), 1.0)
    prog.close()
    assert capsys.readouterr().out == ""


def test_a_notice_while_nothing_has_been_simulated_and_none_after(capsys, monkeypatch):
    monkeypatch.setattr(Progress, "COMPILE_NOTICE_S", 0.05)
    prog = Progress(_batches(1000.0), shown=True)
    prog.notice.join(timeout=5.0)  # the notice fires: nothing was reported
    prog.close()
    assert capsys.readouterr().out.strip() == Progress.COMPILE_NOTICE.strip()
    monkeypatch.setattr(Progress, "COMPILE_NOTICE_S", 2.0)
    quick = Progress(_batches(1000.0), shown=True)
    quick.update(("tavc", 0), 0.1)  # simulating began before the notice was due: no notice
    quick.notice.join(timeout=5.0)  # cancelled: it ends without firing
    quick.close()
    assert "compiles" not in capsys.readouterr().out


def test_time_left_comes_from_the_throughput_since_simulating_began(monkeypatch):
    clock = Clock()
    monkeypatch.setattr(pool.time, "perf_counter", clock)
    monkeypatch.setattr(Progress, "COMPILE_NOTICE_S", 60.0)
    prog = Progress(_batches(2000.0, 2000.0), shown=True)  # 4,000 simulated s in all
    clock.now += 20.0  # 20 s compiling: nothing simulated
    prog.update(("tavc", 0), 0.1)  # 200 s done at t = 20 s
    assert prog.line(200.0, clock.now).endswith("eta: measuring")
    clock.now += 10.0  # 10 s later, 1,200 s done: 1,000 simulated s in 10 s of wall time
    prog.update(("tavc", 0), 0.6)
    # by hand: 2,800 simulated s left at 100 simulated s per wall second = 28 s; 30 s since the start
    assert prog.line(1200.0, clock.now) == " 30.0% of 4,000 simulated s, 30 s elapsed, eta 28 s"
    prog.close()


def test_lines_are_printed_every_ten_seconds_off_a_terminal(capsys, monkeypatch):
    clock = Clock()
    monkeypatch.setattr(pool.time, "perf_counter", clock)
    monkeypatch.setattr(Progress, "COMPILE_NOTICE_S", 60.0)
    prog = Progress(_batches(1000.0), shown=True)  # capsys: stdout is not a terminal
    for _ in range(4):
        clock.now += 6.0
        prog.update(("tavc", 0), (clock.now - 100.0) / 100.0)
    prog.close()
    lines = capsys.readouterr().out.splitlines()
    assert len(lines) == 2  # at 12 s and 24 s: more than ten seconds apart
    assert lines[0].strip().startswith("12.0% of 1,000 simulated s, 12 s elapsed")


def test_no_compiling_notice_once_the_kernels_are_loaded(capsys, monkeypatch):
    """A pool whose kernels are loaded (a later pool of the same run: they are in memory) says
    nothing of compiling, however long its first report takes."""
    monkeypatch.setattr(Progress, "COMPILE_NOTICE_S", 0.05)
    prog = Progress(_batches(1000.0), shown=True)
    prog.kernels_ready()
    prog.notice.join(timeout=5.0)  # cancelled: it ends without firing
    prog.close()
    assert "compiles" not in capsys.readouterr().out


def test_time_left_is_measured_from_when_every_worker_was_simulating(monkeypatch):
    """Two workers, the second starting 5 s after the first: measuring from the first report would
    take half the throughput for the whole (the first estimate about twice too high); it starts
    again when a batch first reports, until one finishes."""
    clock = Clock()
    monkeypatch.setattr(pool.time, "perf_counter", clock)
    monkeypatch.setattr(Progress, "COMPILE_NOTICE_S", 60.0)
    prog = Progress(_batches(1000.0, 1000.0, 1000.0), shown=True)  # 3,000 simulated s, 2 workers
    clock.now += 10.0
    prog.update(("tavc", 0), 0.05)  # 50 s done at t = 10
    clock.now += 5.0
    prog.update(("tavc", 0), 0.30)  # the second worker starts here: 300 + 0 s done at t = 15
    prog.update(("tavc", 1), 0.0)
    clock.now += 10.0  # both simulate 50 s per wall second for 10 s: 500 s more each
    prog.update(("tavc", 0), 0.80)
    prog.update(("tavc", 1), 0.50)
    # by hand: 1,300 s done, 1,000 simulated in the 10 s since t = 15: 100 per second; 1,700 left: 17 s
    assert prog.line(1300.0, clock.now).endswith("eta 17 s")
    clock.now += 4.0
    prog.update(("tavc", 0), 1.0)  # the first batch finishes; the third starts: measuring goes on
    prog.update(("tavc", 2), 0.0)
    assert prog.first == (115.0, 300.0)
    prog.close()
