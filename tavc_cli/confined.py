"""Copies of this process held to folders (`confine.confine_writes`), and what they tell it.

A learner from outside tavc runs only in such copies. Before anything of it runs, a copy is set
apart: below a keeper (`confine.keep_below`) that ends every process it starts, in a session of
their own (no terminal's signals reach it), its standard input /dev/null, its standard output and
error pipes that this process reads and passes on (their control characters shown as `?`), every
other file it inherited closed (a file the caller holds open stays out of its reach), and then
confined. It answers only in lines of JSON, each at most `MESSAGE_LIMIT` bytes, which this
process reads as data: nothing a copy sends is ever unpickled or run here.

`run_confined` runs one function in a copy and returns its answer; `run_units` runs numbered
units of work in a few copies, each taking the next unit when it has finished one, and returns
their results, passing on their progress.
"""

from __future__ import annotations

import codecs
import json
import math
import os
import selectors
import signal
import sys
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from tavc_cli.confine import close_quietly, confine_writes, die_with_parent, keep_below, open_fds
from tavc_cli.errors import TavcError

MESSAGE_LIMIT = 16 << 20  # the longest line of JSON a copy may send (a failed trial's traceback is a few kB)
_MESSAGES, _ORDERS = 3, 4  # the copy's ends of its two channels, as numbered in the copy
_POLL_S = 0.2  # how often a copy that may have ended is looked for
_KEEPER_S = 10.0  # how long a keeper told to end may take to end what is below it

Send = Callable[[Any], None]
Receive = Callable[[], "int | None"]


@dataclass
class _Copy:
    """A confined copy as this process sees it: its pid, the read ends of its messages, output
    and errors, the write end of its orders, what it has sent so far."""

    pid: int
    messages: int
    orders: int
    out: int
    err: int
    pending: bytearray = field(default_factory=bytearray)
    unit: int | None = None  # the unit it runs now
    ended: int | None = None  # its exit status, once it has ended
    decoders: dict = field(default_factory=dict)


def run_confined(function: Callable[..., Any], *args: Any, folders: Sequence[Path] = (), name: str = "") -> Any:
    """`function(*args)` in a copy held to writing beneath `folders` (none: nowhere), its answer
    (JSON data: lists, dicts, strings, numbers) returned here; a `TavcError` it raises is raised
    here with its line, anything else it raises, or the copy ending without one answer, is one
    `TavcError` line naming what ran (`name`, by default the function's). The copy's output is
    passed on to this process's."""
    name = name or getattr(function, "__name__", "it")

    def serve(send: Send, receive: Receive) -> None:
        send({"value": function(*args)})

    answers: list = []
    copy = _fork(folders, serve)
    try:
        _follow([copy], lambda c, message: answers.append(message), lambda c: None)
    finally:
        _end(copy)
    if len(answers) > 1:
        raise TavcError(f"the process running {name} held to its folders answered {len(answers)} times")
    if copy.ended != 0 or not answers:
        raise TavcError(f"the process running {name} held to its folders ended without an answer "
                        f"(exit status {copy.ended})")
    answer = answers[0]
    if "refused" in answer:
        raise TavcError(_text(answer["refused"], name))
    if "failed" in answer:
        raise TavcError(f"{name} failed in its confined process: {_text(answer['failed'], name)}")
    return answer.get("value")


def run_units(n_units: int, n_copies: int, folders: Sequence[Path], run_unit: Callable[[int, Callable], Any],
              progress: Callable[[int, float], None], name: Callable[[int], str]) -> list:
    """`run_unit(i, report)` for every unit i, in up to `n_copies` copies held to `folders`, each
    taking the next unit when it has finished one; `report(fraction)` in a copy reaches
    `progress(i, fraction)` here. Returns each unit's result (JSON data), in order. A copy's own
    error, or one that ends while running a unit, stops the rest and is one `TavcError` line
    naming the unit (`name(i)`)."""
    if n_units == 0:
        return []
    results: list = [None] * n_units
    done = [False] * n_units
    queue = list(range(n_units))

    def serve(send: Send, receive: Receive) -> None:
        while (unit := receive()) is not None:
            result = run_unit(unit, lambda frac, unit=unit: send({"progress": [unit, float(frac)]}))
            send({"done": unit, "result": result})

    def give(copy: _Copy) -> None:
        copy.unit = queue.pop(0) if queue else None
        if copy.unit is None:
            os.close(copy.orders)
            copy.orders = -1
        else:
            try:
                os.write(copy.orders, f"{copy.unit}\n".encode())
            except BrokenPipeError:
                pass  # it has ended: `ended` names the unit

    def heard(copy: _Copy, message: dict) -> None:
        if "progress" in message:
            unit, frac = _pair(message["progress"])
            if unit == copy.unit:
                progress(unit, frac)
        elif "done" in message and type(message["done"]) is int and message["done"] == copy.unit:
            results[copy.unit], done[copy.unit] = message.get("result"), True
            give(copy)
        elif "failed" in message or "refused" in message:
            said = _text(message.get("failed", message.get("refused")), "a worker")
            raise TavcError(f"trials {name(copy.unit)} failed in their worker process: {said}" if copy.unit is not None
                            else f"a worker process failed: {said}")
        else:
            raise TavcError("a worker process sent a message tavc does not know")

    def ended(copy: _Copy) -> None:
        if copy.unit is not None and not done[copy.unit]:
            raise TavcError(f"a worker process ended (exit status {copy.ended}) while running trials {name(copy.unit)} "
                            "(a learner that exits or crashes, out of memory, or a crash in compiled code); the trials "
                            "finished before are kept and a rerun computes only the missing ones")

    copies: list[_Copy] = []
    try:
        for _ in range(max(1, min(n_copies, n_units))):
            copies.append(_fork(folders, serve))
            give(copies[-1])
        _follow(copies, heard, ended)
    finally:
        for copy in copies:
            _end(copy)
    return results


def _pair(value: Any) -> tuple[int, float]:
    if (isinstance(value, list) and len(value) == 2 and type(value[0]) is int
            and isinstance(value[1], (int, float)) and not isinstance(value[1], bool)):
        return value[0], float(value[1])
    raise TavcError("a worker process sent a progress report tavc does not know")


def _text(value: Any, name: str) -> str:
    """A text a copy sent, its control characters (a terminal's escapes among them) shown as `?`."""
    if isinstance(value, str):
        return plain(value)
    raise TavcError(f"the process running {name} sent an answer tavc does not know")


def plain(text: str) -> str:
    """`text` with every control character but a newline or a tab as `?`: a copy's words reach a
    terminal and `failures.log` as words, never as a terminal's commands."""
    return "".join("?" if (ord(c) < 32 and c not in "\n\t") or 127 <= ord(c) < 160 else c for c in text)


# --- the copy ---------------------------------------------------------------------------------

def _fork(folders: Sequence[Path], serve: Callable[[Send, Receive], None]) -> _Copy:
    """A copy of this process that runs `serve(send, receive)` set apart and confined (the
    module's docstring): `send` writes a JSON line to this process, `receive` reads the next unit
    this process gives it (None when there are no more). The copy is the child of a keeper
    (`confine.keep_below`), whose pid the `_Copy` holds."""
    messages, orders, out, err = os.pipe(), os.pipe(), os.pipe(), os.pipe()
    sys.stdout.flush()
    sys.stderr.flush()
    parent = os.getpid()
    pid = os.fork()
    if pid == 0:
        keep_below(parent, lambda keeper: _serve(keeper, folders, serve, messages[1], orders[0], out[1], err[1]))
    for end in (messages[1], orders[0], out[1], err[1]):
        os.close(end)
    for end in (messages[0], out[0], err[0]):
        os.set_blocking(end, False)
    return _Copy(pid, messages[0], orders[1], out[0], err[0])


def _serve(keeper: int, folders: Sequence[Path], serve: Callable[[Send, Receive], None], messages: int, orders: int,
           out: int, err: int) -> None:
    """The copy: set apart, confined, then `serve`; its error as one message. Never returns."""
    code = 1
    try:
        _set_apart(keeper, messages, orders, out, err)
        try:
            confine_writes(folders)
        except OSError as error:  # a kernel or a container that refuses part of it
            _send({"refused": f"cannot hold a learner from outside tavc to its folder here ({error}); give "
                              "executor.confine=off to run it unconfined"})
            os._exit(0)
        try:
            serve(_send, _receive)
        except TavcError as error:
            _send({"refused": str(error)})
        except BaseException as error:  # noqa: BLE001 - the learner's code: its error, as one line
            _send({"failed": f"{type(error).__name__}: {error}"})
        code = 0
    finally:
        try:
            sys.stdout.flush()
            sys.stderr.flush()
        finally:
            os._exit(code)


def _set_apart(parent: int, messages: int, orders: int, out: int, err: int) -> None:
    """In the copy (in its keeper's session): dying with its keeper (`parent`); standard input
    /dev/null, output and errors to tavc's pipes; the channels as `_MESSAGES` and `_ORDERS`; every
    other file closed."""
    # deferred: POSIX only, as Landlock is Linux's
    import fcntl

    signal.signal(signal.SIGTERM, signal.SIG_DFL)
    die_with_parent(parent)
    # each out of the way of 0 to 4 first, then into its place
    high = [fcntl.fcntl(fd, fcntl.F_DUPFD, 1000) for fd in (os.open(os.devnull, os.O_RDONLY), out, err, messages,
                                                              orders)]
    for fd, place in zip(high, (0, 1, 2, _MESSAGES, _ORDERS), strict=True):
        os.dup2(fd, place)
    for fd in open_fds() - {0, 1, 2, _MESSAGES, _ORDERS}:
        close_quietly(fd)
    sys.stdin = open(0, closefd=False)  # noqa: SIM115 - the process's own streams, for its life
    sys.stdout = open(1, "w", buffering=1, closefd=False)  # noqa: SIM115
    sys.stderr = open(2, "w", buffering=1, closefd=False)  # noqa: SIM115


def _send(message: Any) -> None:
    data = (json.dumps(message) + "\n").encode()
    while data:
        data = data[os.write(_MESSAGES, data):]


_ORDER_BUFFER = bytearray()


def _receive() -> int | None:
    while b"\n" not in _ORDER_BUFFER:
        chunk = os.read(_ORDERS, 4096)
        if not chunk:
            return None
        _ORDER_BUFFER.extend(chunk)
    line, _, rest = bytes(_ORDER_BUFFER).partition(b"\n")
    _ORDER_BUFFER[:] = rest
    return int(line)


# --- this process's side ----------------------------------------------------------------------

def _follow(copies: list[_Copy], heard: Callable[[_Copy, dict], None], ended: Callable[[_Copy], None]) -> None:
    """Pass on the copies' output and errors, hand their messages to `heard`, and each copy that
    ends to `ended`, until all have ended."""
    selector = selectors.DefaultSelector()
    try:
        for copy in copies:
            for fd in (copy.messages, copy.out, copy.err):
                selector.register(fd, selectors.EVENT_READ, copy)
        live = list(copies)
        while live:
            for key, _ in selector.select(_POLL_S):
                _read(key.fd, key.data, heard)
            for copy in list(live):
                pid, status = os.waitpid(copy.pid, os.WNOHANG)
                if pid:
                    copy.ended = os.waitstatus_to_exitcode(status)
                    for fd in (copy.messages, copy.out, copy.err):  # what it wrote before it ended
                        _read(fd, copy, heard)
                        selector.unregister(fd)
                    live.remove(copy)
                    _close_pipes(copy)
                    ended(copy)
    finally:
        selector.close()


def _read(fd: int, copy: _Copy, heard: Callable[[_Copy, dict], None]) -> None:
    while True:
        try:
            chunk = os.read(fd, 1 << 16)
        except (BlockingIOError, OSError):
            return
        if not chunk:
            return
        if fd != copy.messages:
            stream = sys.stdout if fd == copy.out else sys.stderr
            decoder = copy.decoders.setdefault(fd, codecs.getincrementaldecoder("utf-8")(errors="replace"))
            stream.write(plain(decoder.decode(chunk)))  # its words, never a terminal's commands
            stream.flush()
            continue
        copy.pending.extend(chunk)
        while b"\n" in copy.pending:
            line, _, rest = bytes(copy.pending).partition(b"\n")
            copy.pending[:] = rest
            heard(copy, _message(line))
        if len(copy.pending) > MESSAGE_LIMIT:
            raise TavcError(f"a worker process sent a message longer than the {MESSAGE_LIMIT} bytes tavc reads")


def _message(line: bytes) -> dict:
    if len(line) > MESSAGE_LIMIT:
        raise TavcError(f"a worker process sent a message longer than the {MESSAGE_LIMIT} bytes tavc reads")
    try:
        message = json.loads(line)
    except (ValueError, RecursionError):  # not JSON, or nested deeper than Python reads
        message = None
    if not isinstance(message, dict):
        raise TavcError("a worker process sent a message that is not one tavc reads")
    return message


def _end(copy: _Copy) -> None:
    """The copy and every process it started gone (its keeper told to end them, `confine.keep_below`; killed
    after `_KEEPER_S` if it has not), its pipes closed."""
    if copy.ended is None:
        try:
            os.kill(copy.pid, signal.SIGTERM)
        except ProcessLookupError:
            pass
        deadline = time.monotonic() + _KEEPER_S
        while copy.ended is None:
            try:
                pid, status = os.waitpid(copy.pid, os.WNOHANG)
            except ChildProcessError:
                break
            if pid:
                copy.ended = os.waitstatus_to_exitcode(status)
            elif time.monotonic() > deadline:
                os.kill(copy.pid, signal.SIGKILL)
                deadline = math.inf
            else:
                time.sleep(0.01)
    _close_pipes(copy)


def _close_pipes(copy: _Copy) -> None:
    for fd in (copy.messages, copy.orders, copy.out, copy.err):
        if fd >= 0:
            close_quietly(fd)
    copy.messages = copy.orders = copy.out = copy.err = -1
