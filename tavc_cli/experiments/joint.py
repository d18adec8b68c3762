"""The trials of several results folders run together, their shared history simulated once.

`run_together` is what `tavc reproduce` runs its experiments' trials through. Each folder
keeps its own `TrialStore` semantics (finished trials reused, files written atomically,
failures named in the folder's `failures.log`); on the local executor the trials of all
folders are planned as trees (`lineage`) and a tree batch runs in one worker process,
which forks at every point where its trials part. A trial so computed is the same, bit for
bit, as the trial run alone. Where anything in a tree goes wrong, the trials it did not
finish are run alone, each from its start, so that a fault is reported as it would be
without the tree. On a Dask or Ray cluster, each folder's trials are run as `tavc run`
runs them, without sharing.
"""

from __future__ import annotations

import os
import signal
import struct
import sys
import time
from collections.abc import Callable, Sequence
from dataclasses import replace
from pathlib import Path

from tavc_cli.confine import die_with_parent
from tavc_cli.errors import TavcError
from tavc_cli.experiments.contained import TrialFailure, simulate_contained
from tavc_cli.experiments.engine import BatchEngine
from tavc_cli.experiments.lineage import Item, Node, TreeBatch, plan
from tavc_cli.experiments.pool import batch_names, run_pool
from tavc_cli.experiments.spec import TrialSpec
from tavc_cli.experiments.store import Executor, TrialStore, pending_batches, save_record, trial_done, trials_of

CAN_FORK = hasattr(os, "fork") and sys.platform.startswith("linux")


def run_together(folders: Sequence[tuple[Path, Sequence[TrialSpec]]], executor: Executor,
                 progress: bool = False) -> dict[Path, int]:
    """Run every trial of every (folder, specs) that is not done; return how many were reused
    in each folder. Stops with one line naming the first failed trial, after every other
    trial has finished and every folder's `failures.log` is written."""
    stores = [(TrialStore(Path(folder), executor), list(specs)) for folder, specs in folders]
    for store, specs in stores:
        store.check_paths(specs)
    if executor.backend != "local" or not CAN_FORK:
        reused, errors = {}, []
        for store, specs in stores:
            try:
                reused[store.folder] = store.run(specs, progress, announce=True)
            except TavcError as exc:  # a folder's failed trials: the other folders still run
                errors.append(exc)
        if errors:
            raise errors[0]
        return reused
    items, pending, reused = [], set(), {}
    for store, specs in stores:
        batches, n_reused, redone = pending_batches(store.folder, specs, executor.batch_size)
        store.announce(len(specs), n_reused, redone)
        reused[store.folder] = n_reused
        todo = {(s.controller, s.trial) for b in batches for s in b.specs}
        for spec in specs:
            item = Item(spec, store.folder)
            items.append(item)
            if (spec.controller, spec.trial) in todo:
                pending.add(item)
    batches = plan(items, pending, executor.batch_size, executor.n_jobs)
    failures = run_pool([(b, run_tree_batch, (b,)) for b in batches], executor.n_jobs, progress,
                        executor.confine_to(trials_of(batches), [store.folder for store, _ in stores]))
    by_folder: dict[str, list[TrialFailure]] = {}
    for f in failures:
        by_folder.setdefault(f.folder, []).append(f)
    errors = []
    for store, specs in stores:
        try:
            store.settle(by_folder.get(str(store.folder), []), len(specs))
        except TavcError as exc:  # every folder's log is written before the first stops the run
            errors.append(exc)
    if errors:
        raise errors[0]
    return reused


def run_tree_batch(batch: TreeBatch,
                   report: Callable[[float], None] | None = None) -> tuple[float, list[TrialFailure]]:
    """Simulate one tree batch, writing each trial's file at the node where it ends; returns
    the wall time (s) and the trials that failed. Trials the tree did not finish (a fault, an
    error, a branch that died) are then run alone from their start, and fail or not as they
    would in any run."""
    start = time.perf_counter()
    walk = _Walk(batch, report)
    try:
        walk.run()
    except Exception as exc:  # noqa: BLE001 - what went wrong is found again, trial by trial, below
        walk.broken.append(f"{type(exc).__name__}: {exc}")
    left: dict[Path, list[TrialSpec]] = {}
    for item in [i for end in batch.root.items() for i in end]:
        if not trial_done(item.folder, item.spec):
            left.setdefault(item.folder, []).append(item.spec)
    if left:
        n_left = sum(map(len, left.values()))
        print(f"note: {n_left} trials of a tree from {batch_names(batch)} were left unfinished "
              f"({'; '.join(walk.broken) or 'no reason given'}); running them alone", file=sys.stderr, flush=True)
    failures: list[TrialFailure] = []
    for folder, specs in left.items():  # one experiment's trials: they share warm-up and duration
        done, failed = simulate_contained(specs)
        for spec, rec in done:
            save_record(rec, spec, folder)
        failures += [replace(f, folder=str(folder)) for f in failed]
    return time.perf_counter() - start, failures


class _Walk:
    """A tree batch, node by node, in one engine: each branch but the last in a forked copy
    of this process, the last in this one. `broken` says what went wrong in copies that failed."""

    def __init__(self, batch: TreeBatch, report: Callable[[float], None] | None) -> None:
        self.batch = batch
        self.report = report
        self.total = max(1, batch.root.ticks)
        self.done = 0
        self.broken: list[str] = []

    def run(self) -> None:
        engine = BatchEngine(self.batch.root.specs)
        self._node(engine, self.batch.root)

    def _node(self, engine: BatchEngine, node: Node) -> None:
        span = node.end - node.start
        report = None if self.report is None else (lambda f: self.report((self.done + f * span) / self.total))
        engine.run(report, until_tick=node.end)
        self.done += span
        if node.ends:
            engine.check()
            for end in node.ends:
                for tr, item in zip(engine.trials, end, strict=True):
                    save_record(engine.record(tr, item.spec), item.spec, item.folder)
        for child in node.children[:-1]:
            self._fork(engine, child)
            self.done += child.ticks
            if self.report is not None:
                self.report(self.done / self.total)
        if node.children:
            last = node.children[-1]
            engine.branch(last.specs)
            self._node(engine, last)

    def _fork(self, engine: BatchEngine, child: Node) -> None:
        """Simulate `child` in a copy of this process, whose trials are this engine's trials
        as they are now; wait for it, passing on the progress it reports through a pipe. A
        copy that fails leaves its trials' files unwritten. Signals are held while the copy
        is made, so that none runs this process's handlers in the copy; if this process is
        stopped while it waits, the copy is stopped too."""
        sys.stdout.flush()
        sys.stderr.flush()
        parent = os.getpid()
        progress_r, progress_w = os.pipe()
        held = signal.pthread_sigmask(signal.SIG_BLOCK, _STOPPING)
        pid = os.fork()
        if pid == 0:  # the copy: its own branch, its files, and out without any of the parent's clean-up
            code = 1
            try:
                die_with_parent(parent)
                sys.stdout, sys.stderr = sys.__stdout__, sys.__stderr__  # not a progress bar's console
                os.close(progress_r)
                signal.pthread_sigmask(signal.SIG_SETMASK, held)
                if self.report is not None:
                    self.report = lambda frac: os.write(progress_w, struct.pack("d", frac))
                engine.branch(child.specs)
                self._node(engine, child)
                code = 0
            except BaseException:  # noqa: BLE001, S110 - its trials are run alone, and fail there if they must
                pass
            finally:
                os._exit(code)
        signal.pthread_sigmask(signal.SIG_SETMASK, held)
        os.close(progress_w)
        try:
            self._pass_on_progress(progress_r)
            _, status = os.waitpid(pid, 0)
        except BaseException:
            os.kill(pid, signal.SIGKILL)
            os.waitpid(pid, 0)
            raise
        finally:
            os.close(progress_r)
        if status != 0:
            self.broken.append(f"the copy of the process for a branch at tick {child.start} ended with status "
                               f"{os.waitstatus_to_exitcode(status)}")

    def _pass_on_progress(self, pipe: int) -> None:
        """Report each fraction of the tree done that a copy writes (8 bytes each) until it closes."""
        size = struct.calcsize("d")
        pending = b""
        while chunk := os.read(pipe, 4096):
            pending += chunk
            whole = len(pending) - len(pending) % size
            if self.report is not None and whole:
                self.report(struct.unpack(f"{whole // size}d", pending[:whole])[-1])
            pending = pending[whole:]


_STOPPING = {signal.SIGINT, signal.SIGTERM}
