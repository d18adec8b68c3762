"""The processes that draw the report's figures while its text is written, and the figures an
earlier report drew that this one did not, removed once it is written."""

from __future__ import annotations

import multiprocessing as mp
import os
import signal
import sys
from concurrent.futures import Future, ProcessPoolExecutor
from pathlib import Path

from tavc_cli.errors import TavcError
from tavc_cli.io import owned_path


class FigurePool:
    """Processes that draw figures while the report is written (forked, where the system
    forks; elsewhere each figure is drawn when submitted)."""

    def __enter__(self):
        """Start the processes (none where the system does not fork, or has one core)."""
        self.pool = None
        if sys.platform.startswith("linux") and (os.cpu_count() or 1) > 1:
            self.pool = ProcessPoolExecutor(max_workers=min(2, os.cpu_count() or 1), mp_context=mp.get_context("fork"),
                                            initializer=figure_worker_start)
        return self

    def submit(self, fn, *args) -> Future:
        """`fn(*args)` in a figure process; at once, here, without one."""
        if self.pool is not None:
            return self.pool.submit(fn, *args)
        done: Future = Future()
        done.set_result(fn(*args))
        return done

    def __exit__(self, kind, *exc) -> None:
        """Wait for every figure; on an error or an interrupt, here or while waiting, stop the
        processes at once."""
        if self.pool is None:
            return
        if kind is None:
            try:
                self.pool.shutdown(wait=True, cancel_futures=True)
                return
            except BaseException:  # Ctrl-C or SIGTERM while waiting: stopped as below, then raised
                _stop(self.pool)
                raise
        _stop(self.pool)  # Ctrl-C, SIGTERM, an error: the figures stop now


def _stop(pool) -> None:
    """`experiments.pool.stop_workers`, loaded when needed."""
    # deferred: loads the simulator's compiled kernels
    from tavc_cli.experiments.pool import stop_workers

    stop_workers(pool)


def figure_worker_start() -> None:
    """A figure process leaves Ctrl-C to the report (which stops it), rather than printing a
    traceback of its own, and dies on SIGTERM and with the report."""
    # deferred: loads the simulator's compiled kernels
    from tavc_cli.experiments.pool import worker_start

    signal.signal(signal.SIGINT, signal.SIG_IGN)
    worker_start()


def figure_files(taken: list) -> dict[Path, tuple[int, int]]:
    """Each file under the figures/ of the folders `tavc report` draws in
    (`ownership.take_report_folders`), with its inode and modification time: what a report finds
    there before it draws."""
    out = {}
    for owned in taken:
        for p in (owned.folder / "figures").rglob("*") if (owned.folder / "figures").is_dir() else ():
            if p.is_file() and not p.is_symlink():
                stat = p.stat()
                out[p] = (stat.st_ino, stat.st_mtime_ns)
    return out


def remove_stale_figures(taken: list, before: dict[Path, tuple[int, int]]) -> list[Path]:
    """After a report is written: the figures an earlier report drew that this one did not draw
    again (still the file `figure_files` found) are removed where tavc wrote them (the folder's
    manifest lists them), then each folder under figures/ that a removal left empty. Every
    figure is drawn through a new file renamed over the old (`viz.figures.write_figure`), so one
    drawn again is never the same file. Nothing on a path through a link is touched."""
    removed = []
    for owned in taken:
        figures = owned.folder / "figures"
        mine = []
        for path, seen in sorted(before.items()):
            name = path.relative_to(owned.folder).as_posix() if figures in path.parents else None
            if name is None or not owned.owns(name):
                continue
            try:
                owned_path(owned.folder, path)
            except TavcError:
                continue  # a link, a pipe or a folder where the figure was: not tavc's to remove
            stat = path.lstat() if path.is_file() else None
            if stat is not None and (stat.st_ino, stat.st_mtime_ns) == seen:
                path.unlink()
                owned.files.discard(name)
                mine.append(path)
        if mine:
            owned.save()
        for d in sorted({p.parent for p in mine}, key=lambda d: -len(d.parts)):
            while d != figures and d.is_dir() and not d.is_symlink() and not any(d.iterdir()):
                d.rmdir()
                d = d.parent
        removed += mine
    return removed
