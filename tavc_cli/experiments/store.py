"""One results folder's trial records: which are done, running the rest, loading them.

`TrialStore` is what `tavc run`, `tavc model` and `tavc calibrate` all run trials through.
Given trial specs it
1. reuses every trial whose file exists with a matching key (a digest of everything that
   fixes its outcome, seed included);
2. groups the rest into batches (`build.make_batches`) and runs them on the executor
   (`Executor`: a local process pool, or a Dask or Ray cluster, `executors`), each
   trial's file written atomically as its batch finishes (a stopped run loses at most
   the batches in flight);
3. reports progress over the simulated seconds.
"""

from __future__ import annotations

import json
import sys
import time
from collections.abc import Callable, Sequence
from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, wait
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from tavc_cli.experiments.build import Batch, make_batches
from tavc_cli.experiments.engine import run_trials
from tavc_cli.experiments.records import TrialRecord
from tavc_cli.experiments.spec import TrialSpec
from tavc_cli.settings import ExecutorConfig


@dataclass(frozen=True)
class Executor:
    """Where trials run: `backend` local (processes), dask or ray; `n_jobs` workers of a local
    pool or cluster; `batch_size` trials advanced together in one process; `address` of an
    existing cluster (none: a local one is started)."""

    backend: str = "local"
    n_jobs: int = 1
    batch_size: int = 8
    address: str | None = None

    @classmethod
    def from_config(cls, executor: ExecutorConfig) -> Executor:
        """From the resolved `executor` settings."""
        return cls(str(executor.backend), int(executor.n_jobs), int(executor.batch_size), executor.address)


class TrialStore:
    """The trial records of one results folder (`<folder>/trials/<controller>_<trial>.npz`)."""

    def __init__(self, folder: Path, executor: Executor) -> None:
        """A store over `folder`, running trials on `executor`."""
        self.folder = Path(folder)
        self.executor = executor

    def path(self, spec: TrialSpec) -> Path:
        return trial_path(self.folder, spec.controller, spec.trial)

    def done(self, spec: TrialSpec) -> bool:
        """True if the trial's file exists and was made from this exact spec and seed."""
        return trial_done(self.folder, spec)

    def run(self, specs: Sequence[TrialSpec], progress: bool = False, announce: bool = False) -> int:
        """Run every trial of `specs` that is not done; return how many were reused."""
        ex = self.executor
        pending, n_reused = pending_batches(self.folder, list(specs), ex.batch_size, ex.n_jobs)
        if announce and n_reused:
            print(f"reusing {n_reused} of {len(specs)} finished trials in {self.folder / 'trials'}", flush=True)
        if ex.backend == "local":
            execute(pending, self.folder, ex.n_jobs, progress)
        else:
            _execute_on_cluster(ex, pending, self.folder, progress)
        return n_reused

    def load(self, specs: Sequence[TrialSpec]) -> list[TrialRecord]:
        """The records of trials that are done."""
        return [TrialRecord.load(self.path(s)) for s in specs]


def trial_path(out_dir: Path, controller: str, trial: int) -> Path:
    return out_dir / "trials" / f"{controller}_{trial:03d}.npz"


def _stored_key(path: Path) -> str | None:
    try:
        with np.load(path, allow_pickle=False) as data:
            return json.loads(str(data["meta"])).get("key")
    except Exception:  # missing, truncated or foreign: the trial is simply run again
        return None


def trial_done(out_dir: Path, spec: TrialSpec) -> bool:
    """True if the trial's file exists and was made from this exact spec and seed."""
    return _stored_key(trial_path(out_dir, spec.controller, spec.trial)) == spec.key()


def pending_batches(out_dir: Path, specs: list[TrialSpec], batch_size: int,
                    workers: int = 1) -> tuple[list[Batch], int]:
    """Batches of the trials still to run, and how many finished trials are reused."""
    todo = [s for s in specs if not trial_done(out_dir, s)]
    return make_batches(todo, batch_size, workers), len(specs) - len(todo)


def run_batch(batch: Batch, out_dir: str | Path, report: Callable[[float], None] | None = None) -> float:
    """Simulate one batch and write its trial files; returns the wall time (s)."""
    start = time.perf_counter()
    save_batch(batch, run_trials(batch.specs, report), out_dir)
    return time.perf_counter() - start


def save_batch(batch: Batch, records: Sequence[TrialRecord], out_dir: str | Path) -> None:
    """Write a finished batch's trial files into out_dir, each atomically."""
    for spec, rec in zip(batch.specs, records, strict=True):
        rec.save(trial_path(Path(out_dir), spec.controller, spec.trial))


class _QueueReporter:
    """Progress callback for a worker process: sends (batch id, fraction) to the parent."""

    def __init__(self, queue, key) -> None:
        self.queue, self.key = queue, key

    def __call__(self, frac: float) -> None:
        self.queue.put((self.key, frac))


class _Progress:
    """A rich bar on a terminal, plain periodic lines otherwise, over the simulated seconds
    of the batches; each batch reports the fraction of itself that is done."""

    def __init__(self, batches: list[Batch], tty: bool) -> None:
        self.weights = {(b.controller, b.index): b.sim_seconds for b in batches}
        self.total = total_s = sum(self.weights.values())
        self.done: dict = {}
        self.start = time.perf_counter()
        self.last_line = self.start
        self.bar = None
        if tty and total_s > 0:
            from rich.progress import BarColumn, Progress, TextColumn, TimeElapsedColumn, TimeRemainingColumn

            self.bar = Progress(TextColumn("simulating"), BarColumn(), TextColumn("{task.percentage:>5.1f}%"),
                                TimeElapsedColumn(), TextColumn("eta"), TimeRemainingColumn(), transient=True)
            self.task = self.bar.add_task("run", total=total_s)
            self.bar.start()

    def update(self, key, frac: float) -> None:
        self.done[key] = frac * self.weights[key]
        done = sum(self.done.values())
        if self.bar is not None:
            self.bar.update(self.task, completed=done)
        elif time.perf_counter() - self.last_line > 10.0 and self.total > 0:
            self.last_line = time.perf_counter()
            elapsed = self.last_line - self.start
            pct = 100.0 * done / self.total
            eta = elapsed * (self.total - done) / done if done > 0 else float("nan")
            print(f"  {pct:5.1f}% of {self.total:,.0f} simulated s, {elapsed:,.0f} s elapsed, eta {eta:,.0f} s",
                  flush=True)

    def close(self) -> None:
        if self.bar is not None:
            self.bar.stop()


def execute(pending: list[Batch], out_dir: Path, n_jobs: int, tty: bool) -> None:
    """Run pending batches in this process (n_jobs 1 or a single batch) or a process pool."""
    prog = _Progress(pending, tty)
    try:
        if n_jobs <= 1 or len(pending) <= 1:
            for b in pending:
                key = (b.controller, b.index)
                run_batch(b, out_dir, lambda f, k=key: prog.update(k, f))
            return
        import multiprocessing as mp

        ctx = mp.get_context("fork" if sys.platform.startswith("linux") else "spawn")
        with ctx.Manager() as manager:
            queue = manager.Queue()
            pool = ProcessPoolExecutor(max_workers=min(n_jobs, len(pending)), mp_context=ctx)
            try:
                futures = {pool.submit(run_batch, b, str(out_dir), _QueueReporter(queue, (b.controller, b.index))): b
                           for b in pending}
                remaining = set(futures)
                while remaining:
                    finished, remaining = wait(remaining, timeout=0.5, return_when=FIRST_COMPLETED)
                    while not queue.empty():
                        key, frac = queue.get()
                        prog.update(key, frac)
                    for f in finished:
                        f.result()  # re-raise a worker's error here
                        b = futures[f]
                        prog.update((b.controller, b.index), 1.0)
            except BaseException:
                pool.shutdown(wait=True, cancel_futures=True)  # don't start batches nobody will wait for
                raise
            pool.shutdown(wait=True)
    finally:
        prog.close()


def _execute_on_cluster(ex: Executor, pending: list[Batch], out_dir: Path, tty: bool) -> None:
    """Run pending batches on a Dask or Ray cluster (`executors`); this process writes the files."""
    from tavc_cli.experiments.executors import run_on_cluster

    prog = _Progress(pending, tty)
    try:
        run_on_cluster(ex.backend, pending, lambda b, records: save_batch(b, records, out_dir), ex.n_jobs, ex.address,
                       lambda b: prog.update((b.controller, b.index), 1.0))
    finally:
        prog.close()
