"""The one error type users see.

Anything a user can get wrong (a bad key, a value out of range, a missing results folder) raises
``TavcError``; the command line prints its message as a single ``error: ...`` line and exits
with status 1. Any other exception is a bug and keeps its traceback.
"""

import signal
import sys
import threading
import time
from collections.abc import Iterator
from contextlib import contextmanager


class TavcError(Exception):
    """A user-facing error whose message is exactly one line.

    Args:
        message: What went wrong, naming the key or file involved. Line breaks and runs of
            whitespace are collapsed, so wrapped text from a library still prints as one line.
    """

    def __init__(self, message: str) -> None:
        """Store ``message`` with its whitespace collapsed to single spaces."""
        super().__init__(" ".join(str(message).split()))


class Terminated(KeyboardInterrupt):
    """SIGTERM, turned into an exception so that a run stops as it does on Ctrl-C: its worker
    processes stopped, its folder released, nothing half-written."""


def interrupt_behind(error: BaseException) -> KeyboardInterrupt | None:
    """The Ctrl-C or SIGTERM that `error` was raised while handling, if any.

    A library that tidies up on the way out can fail there and hide the interrupt behind an
    error of its own: OmegaConf, stopped while it builds a list, restores the flags of the
    half-built list in a ``finally``, fails on its missing items and reports that as an unknown
    key, which would then read as a mistake in the config rather than the Ctrl-C it was."""
    seen: set[int] = set()
    pending = [error]
    while pending:
        e = pending.pop()
        if e is None or id(e) in seen:
            continue
        seen.add(id(e))
        if isinstance(e, KeyboardInterrupt):
            return e
        pending += [e.__cause__, e.__context__]
    return None


@contextmanager
def sigterm_raises() -> Iterator[None]:
    """Within the block (in the main thread), SIGTERM raises `Terminated`."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return

    def _raise(signum, frame):
        raise Terminated()

    previous = signal.signal(signal.SIGTERM, _raise)
    try:
        yield
    finally:
        signal.signal(signal.SIGTERM, previous)


def interrupts_not_swallowed() -> None:
    """Make a Ctrl-C or SIGTERM that lands inside a finalizer (a pymunk body freed by the
    garbage collector, say) stop the run as anywhere else.

    Python cannot raise from a finalizer: it prints the exception as "ignored", with a
    traceback, and carries on, so the interrupt would be lost. Here it is passed on, quietly,
    to the main thread, as the same signal again."""
    # deferred: the interrupt a worker sends its parent
    import _thread

    default = sys.unraisablehook

    def hook(unraisable) -> None:
        if isinstance(unraisable.exc_value, KeyboardInterrupt):
            signum = signal.SIGTERM if isinstance(unraisable.exc_value, Terminated) else signal.SIGINT
            # from another thread, once this hook is over: raised in here, it would be swallowed again
            threading.Thread(target=_interrupt_later, args=(_thread.interrupt_main, signum), daemon=True).start()
            return
        default(unraisable)

    sys.unraisablehook = hook


def _interrupt_later(interrupt, signum: int) -> None:
    time.sleep(0.02)
    interrupt(signum)
