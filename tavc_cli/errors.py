"""The one error type users see.

Anything a user can get wrong (a bad key, a value out of range, a missing results folder) raises
``TavcError``; the command line prints its message as a single ``error: ...`` line and exits
with status 1. Any other exception is a bug and keeps its traceback.
"""

import signal
import threading
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
