"""The processes that draw the report's figures while its text is written."""

from __future__ import annotations

import multiprocessing as mp
import os
import signal
import sys
from concurrent.futures import Future, ProcessPoolExecutor


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
        """Wait for every figure; on an error or an interrupt, stop the processes at once."""
        if self.pool is not None and kind is not None:  # Ctrl-C, SIGTERM, an error: the figures stop now
            # deferred: loads the simulator's compiled kernels
            from tavc_cli.experiments.pool import stop_workers

            stop_workers(self.pool)
        elif self.pool is not None:
            self.pool.shutdown(wait=True, cancel_futures=True)


def figure_worker_start() -> None:
    """A figure process leaves Ctrl-C to the report (which stops it), rather than printing a
    traceback of its own, and dies on SIGTERM and with the report."""
    # deferred: loads the simulator's compiled kernels
    from tavc_cli.experiments.pool import worker_start

    signal.signal(signal.SIGINT, signal.SIG_IGN)
    worker_start()
