"""Running batches of trials in a local process pool, with one progress report over them.

`run_pool` runs units of work (a batch, the function that simulates it and writes its
trials' files, its arguments) in this process or in forked worker processes, and shows
their progress as a share of their simulated seconds (`Progress`: a bar on a terminal,
periodic lines otherwise). Before the workers start, `load_kernels` compiles what they
will run, once. Workers (and anything they fork) die with the run that started them.
"""

from __future__ import annotations

import hashlib
import multiprocessing as mp
import os
import signal
import sys
import tempfile
import threading
import time
from collections.abc import Iterator, Sequence
from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, wait
from concurrent.futures.process import BrokenProcessPool
from contextlib import contextmanager
from dataclasses import asdict, replace
from multiprocessing.managers import SyncManager
from pathlib import Path

from tavc_cli.behaviours.navigation import compiled
from tavc_cli.confine import die_with_parent
from tavc_cli.confined import run_units
from tavc_cli.errors import TavcError
from tavc_cli.experiments.build import Batch, stand_in
from tavc_cli.experiments.contained import TrialFailure
from tavc_cli.experiments.engine import BatchEngine, run_trials
from tavc_cli.experiments.tick import NOISE_BLOCK_TICKS


class _QueueReporter:
    """Progress callback for a worker process: sends (batch id, fraction) to the parent."""

    def __init__(self, queue, key) -> None:
        self.queue, self.key = queue, key

    def __call__(self, frac: float) -> None:
        self.queue.put((self.key, frac))


class Progress:
    """What a run shows while it simulates, over the simulated seconds of its batches (each
    batch reports the fraction of itself that is done): nothing unless `shown`; a rich bar on a
    terminal; plain lines every `LINE_EVERY_S` otherwise. Until the first report it says, once,
    what the wait is most likely for: kernels compiling (`COMPILE_NOTICE_S`), and not once they
    are loaded (`kernels_ready`). The time left is the work left at the throughput measured
    since every worker was simulating: from the first report of the last batch to start before
    any batch finished (so neither the compiling nor workers still starting are taken for slow
    simulation); none is given before `ETA_AFTER_S` of measuring. The bar shows the same
    estimate as the lines."""

    LINE_EVERY_S = 10.0
    COMPILE_NOTICE_S = 3.0
    ETA_AFTER_S = 5.0
    COMPILE_NOTICE = ("  preparing: the first run after installing or changing tavc compiles the simulator's kernels "
                      "(about 20 s of computing, longer on a busy machine); later runs load them from the cache")

    def __init__(self, batches: list[Batch], shown: bool) -> None:
        """Progress over `batches`, shown only if `shown` and there is something to simulate."""
        self.weights = {(b.controller, b.index): b.sim_seconds for b in batches}
        self.total = total_s = sum(self.weights.values())
        self.done: dict = {}
        self.seen: set = set()
        self.start = self.last_line = time.perf_counter()
        self.first: tuple[float, float] | None = None  # (time, simulated seconds done) where measuring began
        self.finished_one = False  # a batch has finished: every worker has been simulating since
        self.shown = shown and total_s > 0
        self.bar = None
        self.notice = None
        if not self.shown:
            return
        if sys.stdout.isatty():
            # deferred: loads rich
            from rich.progress import BarColumn, Progress, TextColumn, TimeElapsedColumn

            self.bar = Progress(TextColumn("simulating"), BarColumn(), TextColumn("{task.percentage:>5.1f}%"),
                                TimeElapsedColumn(), TextColumn("{task.fields[eta]}"), transient=True)
            self.task = self.bar.add_task("run", total=total_s, eta="eta: measuring")
            self.bar.start()

        self.notice = threading.Timer(self.COMPILE_NOTICE_S, self._say, (self.COMPILE_NOTICE,))
        self.notice.daemon = True
        self.notice.start()

    def _say(self, line: str) -> None:
        if self.bar is not None:
            self.bar.console.print(line, highlight=False, markup=False)
        else:
            print(line, flush=True)

    def kernels_ready(self) -> None:
        """The kernels are compiled or loaded (`load_kernels` returned): nothing is left for the
        compiling notice to explain, so it is not shown from here on."""
        if self.notice is not None:
            self.notice.cancel()

    def update(self, key, frac: float) -> None:
        """Batch `key` is `frac` done: move the bar, or print a line if the last is old enough."""
        self.done[key] = frac * self.weights[key]
        if not self.shown:
            return
        new = key not in self.seen
        self.seen.add(key)
        done, now = sum(self.done.values()), time.perf_counter()
        if self.first is None:
            self.notice.cancel()
        if self.first is None or (new and not self.finished_one):  # a worker began: measure from here
            self.first = (now, done)
        self.finished_one = self.finished_one or frac >= 1.0
        if self.bar is not None:
            self.bar.update(self.task, completed=done, eta=self.eta(done, now))
        elif now - self.last_line > self.LINE_EVERY_S:
            self.last_line = now
            print(f"  {self.line(done, now)}", flush=True)

    def line(self, done: float, now: float) -> str:
        """``<share> of <total> simulated s, <elapsed> s elapsed, eta <left> s`` (the time left
        from the throughput since the first report; ``eta: measuring`` until it is known)."""
        pct = 100.0 * done / self.total
        return f"{pct:5.1f}% of {self.total:,.0f} simulated s, {now - self.start:,.0f} s elapsed, {self.eta(done, now)}"

    def eta(self, done: float, now: float) -> str:
        """``eta <left> s`` from the throughput since measuring began, or ``eta: measuring``."""
        t0, done0 = self.first if self.first is not None else (now, done)
        if now - t0 < self.ETA_AFTER_S or done <= done0:
            return "eta: measuring"
        return f"eta {(self.total - done) * (now - t0) / (done - done0):,.0f} s"

    def close(self) -> None:
        """Stop the compiling notice and the bar."""
        if self.notice is not None:
            self.notice.cancel()
        if self.bar is not None:
            self.bar.stop()


def run_pool(units: list[tuple], n_jobs: int, shown: bool, confine_to: Sequence[Path] = ()) -> list[TrialFailure]:
    """Run units of work, each (batch, function, arguments), in this process (n_jobs 1 or a
    single unit) or a process pool of n_jobs workers, with one progress report over their
    simulated seconds if `shown` (`Progress`); `function(*arguments, report)` simulates the
    batch, writes its trials' files and returns (wall time, failed trials). Returns the trials
    that failed. Where `confine_to` names folders, every unit runs in a worker process (one at
    least) that can write only beneath them and answers in JSON (`confined.run_units`), and this
    process runs no learner from outside tavc, not even to load the kernels (`load_kernels`)."""
    pending = [u[0] for u in units]
    prog = Progress(pending, shown)
    failures: list[TrialFailure] = []
    try:
        if confine_to:
            load_kernels(pending)
            prog.kernels_ready()
            return _run_confined_units(units, n_jobs, confine_to, prog)
        if n_jobs <= 1 or len(units) <= 1:
            for b, fn, args in units:
                key = (b.controller, b.index)
                failures += fn(*args, lambda f, k=key: prog.update(k, f))[1]
            return failures

        ctx = mp.get_context("fork" if sys.platform.startswith("linux") else "spawn")
        load_kernels(pending)
        prog.kernels_ready()  # a pool after the first loads them at once: no notice in its bar

        manager = SyncManager(ctx=ctx)
        manager.start(worker_start)  # the progress queue's server process: gone with the run too
        with manager:
            queue = manager.Queue()
            pool = ProcessPoolExecutor(max_workers=min(n_jobs, len(units)), mp_context=ctx, initializer=worker_start)
            try:
                futures = {pool.submit(fn, *args, _QueueReporter(queue, (b.controller, b.index))): b
                           for b, fn, args in units}
                remaining = set(futures)
                while remaining:
                    finished, remaining = wait(remaining, timeout=0.5, return_when=FIRST_COMPLETED)
                    while not queue.empty():
                        key, frac = queue.get()
                        prog.update(key, frac)
                    for f in finished:
                        b = futures[f]
                        try:
                            failures += f.result()[1]  # a worker's own error (not a trial's) is re-raised
                        except BrokenProcessPool:
                            raise TavcError(
                                f"a worker process died while running trials {batch_names(b)} (out of memory, or a "
                                "crash in compiled code); the trials finished before are kept and a rerun "
                                "computes only the missing ones") from None
                        prog.update((b.controller, b.index), 1.0)
            except BaseException:
                stop_workers(pool)
                raise
            pool.shutdown(wait=True)
        return failures
    finally:
        prog.close()


def _run_confined_units(units: list[tuple], n_jobs: int, folders: Sequence[Path], prog: Progress) -> list[TrialFailure]:
    """`run_pool`'s units in confined workers (`confined.run_units`): each answers its wall time
    and its failed trials as JSON, read back here as data (`TrialFailure.from_data`)."""

    def run_unit(i: int, report) -> dict:
        b, fn, args = units[i]
        wall, failed = fn(*args, report)
        return {"wall_s": wall, "failures": [asdict(f) for f in failed]}

    def progress(i: int, frac: float) -> None:
        prog.update((units[i][0].controller, units[i][0].index), frac)

    results = run_units(len(units), n_jobs, folders, run_unit, progress, lambda i: batch_names(units[i][0]))
    failures: list[TrialFailure] = []
    for i, result in enumerate(results):
        said = result.get("failures") if isinstance(result, dict) else None
        if not isinstance(said, list):
            raise TavcError(f"the worker process running trials {batch_names(units[i][0])} answered something else "
                            "than its failed trials")
        failures += [TrialFailure.from_data(f) for f in said]
        prog.update((units[i][0].controller, units[i][0].index), 1.0)
    return failures


def load_kernels(pending: Sequence[Batch]) -> None:
    """Compile (or load from numba's cache) the kernels these batches run, here, before any
    worker starts: forked workers inherit them, and spawned ones find them in the cache,
    instead of each compiling the same code at once (about 20 s of a core each, without a
    cache; `compile_in_two` spreads the first compile over two processes, about 11 s). A
    few seconds of one trial per controller, with no warm-up, do it; what that short run
    computes is thrown away, and anything that goes wrong in it is left to the real run to
    report. Runs started together (`make reproduce-all` runs the experiments
    beside the model) take turns (`_compiling_alone`): the first compiles and writes the
    cache, the others then load it. A learner from outside tavc is not run here: a built-in one
    stands in (`build.stand_in`), as the kernels are the same."""
    seen: set[str] = set()
    with _compiling_alone():
        for b in pending:
            if b.controller in seen:
                continue
            spec = stand_in(b.specs[0])  # a learner from outside tavc runs in its workers only
            short = replace(spec, warmup_s=0.0, start_s=0.0, duration_s=2 * NOISE_BLOCK_TICKS * spec.dt_s,
                            deliveries=None)
            try:
                if not seen:
                    compile_in_two(BatchEngine([short]))
                run_trials([short])
            except Exception:  # noqa: BLE001 - only a head start; the real run reports any error
                pass
            seen.add(b.controller)


def compile_in_two(engine: BatchEngine) -> None:
    """Compile the kernels below the engine's entry points (`BatchEngine.kernel_parts`) in two
    processes at once, where processes can be forked: the behaviours in a copy of this one,
    the rest here. Both fill numba's cache, from which this process then loads the copy's
    part when the entry points are compiled. Where the cache already holds them, this only
    loads them. Nothing here is needed for correctness: a part not compiled is compiled when
    first called."""
    apart, here = engine.kernel_parts()
    if not sys.platform.startswith("linux"):
        return
    sys.stdout.flush()
    sys.stderr.flush()
    parent = os.getpid()
    pid = os.fork()
    if pid == 0:  # the copy: its part into the cache, then out without any of the parent's clean-up
        code = 1
        try:
            die_with_parent(parent)
            for kernel, args in apart:
                compiled(kernel, *args)
            code = 0
        finally:
            os._exit(code)
    try:
        for kernel, args in here:
            compiled(kernel, *args)
    finally:
        os.waitpid(pid, 0)


def kernel_lock_path() -> Path:
    """The lock file of this installation's kernel compiles (see `_compiling_alone`)."""
    package = str(Path(__file__).resolve().parent.parent)
    return Path(tempfile.gettempdir()) / f"tavc-kernels-{hashlib.sha256(package.encode()).hexdigest()[:12]}.lock"


@contextmanager
def _compiling_alone() -> Iterator[None]:
    """Hold, where the system has it, an exclusive lock that every run of this installation of
    tavc takes to compile its kernels (`kernel_lock_path`). Released when the block ends, or
    with the process."""
    try:
        # deferred: POSIX only
        import fcntl
    except ImportError:  # no flock: each run compiles for itself, as numba does by default
        yield
        return
    try:
        handle = open(kernel_lock_path(), "a")  # noqa: SIM115 - held for the block
    except OSError:
        yield
        return
    with handle:
        fcntl.flock(handle, fcntl.LOCK_EX)
        yield


def stop_workers(pool: ProcessPoolExecutor) -> None:
    """Stop a pool's workers now and start no work that nobody will wait for (on Ctrl-C they
    stop themselves; on SIGTERM or an error in this process only this process would). They are
    killed, not asked: until `worker_start` replaces it, a worker forked a moment before runs
    whatever SIGTERM handler its parent had, which need not end it (under a test runner, one may
    not), and a worker that lived on would wait for good on the pool's queue, which a killed one
    may hold."""
    for worker in list((getattr(pool, "_processes", None) or {}).values()):  # None once shut down
        worker.kill()
    pool.shutdown(wait=True, cancel_futures=True)


def worker_start() -> None:
    """A pool worker dies on SIGTERM (the run's own handler, inherited through fork, would
    only stop its current batch) and, on Linux, when the run that started it dies, even by
    kill -9: no orphan goes on computing."""
    signal.signal(signal.SIGTERM, signal.SIG_DFL)
    die_with_parent()


def batch_names(batch: Batch) -> str:
    """The batch's trials by name, ``tavc_000`` or ``tavc_000 to tavc_003``, for messages."""
    first, last = batch.specs[0], batch.specs[-1]
    return f"{first.controller}_{first.trial:03d}" + (f" to {last.controller}_{last.trial:03d}"
                                                     if len(batch.specs) > 1 else "")
