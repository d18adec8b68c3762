"""Holding a process's writes to the folders it was given, with the Linux kernel's Landlock.

A learner from outside tavc is code (docs/security.md). Where the kernel offers Landlock (Linux
5.13 and later, no privileges needed), the processes that run one restrict themselves, for the
rest of their lives and for every process they start, to creating, writing, renaming and
deleting files only beneath the folders they were given (`confine_writes`); anything else is
refused by the kernel with a `PermissionError`, whatever the code does. Reading, and writing to
files already open (the terminal, the pipes back to the run), stay as they were.

`executor.confine` says when: ``auto`` (the default) confines where the kernel can and says in
one line where it cannot, ``on`` refuses to run a learner from outside tavc unconfined, ``off``
never confines.
"""

from __future__ import annotations

import os
import signal
import sys
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any, TypeVar

from tavc_cli.errors import TavcError

CONFINE_CHOICES = ("auto", "on", "off")

# Linux's syscall numbers for Landlock (the same on every architecture) and its access rights
_CREATE_RULESET, _ADD_RULE, _RESTRICT_SELF = 444, 445, 446
_CREATE_RULESET_VERSION = 1
_RULE_PATH_BENEATH = 1
_PR_SET_NO_NEW_PRIVS = 38
_WRITE_FILE = 1 << 1
_WRITES_BY_ABI = (  # (first ABI that has them, rights): every way to change what the file system holds
    (1, _WRITE_FILE | 1 << 4 | 1 << 5 | 1 << 6 | 1 << 7 | 1 << 8 | 1 << 9 | 1 << 10 | 1 << 11 | 1 << 12),
    (2, 1 << 13),  # REFER: moving or linking a file to another folder
    (3, 1 << 14),  # TRUNCATE
)
_TRUNCATE = 1 << 14
_DEV_NULL = "/dev/null"  # written to by libraries that silence output: allowed, as it holds nothing
T = TypeVar("T")


def landlock_abi() -> int:
    """The Landlock version this kernel offers, 0 where it has none (or this is not Linux)."""
    if not sys.platform.startswith("linux"):
        return 0
    libc = _libc()
    if libc is None:
        return 0
    version = libc.syscall(_CREATE_RULESET, None, 0, _CREATE_RULESET_VERSION)
    return max(int(version), 0)


def confine_writes(folders: Sequence[Path]) -> None:
    """From now on this process, and every process it starts, can make, change, move or remove
    files only beneath `folders` (which must exist). Irrevocable. Raises `OSError` where the kernel
    cannot (`landlock_abi` is 0) or refuses."""
    # deferred: only where a process is confined
    import ctypes

    abi = landlock_abi()
    if abi < 1:
        raise OSError("this system has no Landlock (Linux 5.13 or later)")
    libc = _libc()
    writes = 0
    for since, rights in _WRITES_BY_ABI:
        if abi >= since:
            writes |= rights

    class RulesetAttr(ctypes.Structure):
        _fields_ = [("handled_access_fs", ctypes.c_uint64)]

    class PathBeneath(ctypes.Structure):
        _pack_ = 1
        _fields_ = [("allowed_access", ctypes.c_uint64), ("parent_fd", ctypes.c_int32)]

    attr = RulesetAttr(writes)
    ruleset = libc.syscall(_CREATE_RULESET, ctypes.byref(attr), ctypes.c_size_t(ctypes.sizeof(attr)), 0)
    if ruleset < 0:
        raise _os_error(ctypes, "cannot make a Landlock ruleset")
    try:
        rules = [(Path(f), writes) for f in folders]
        if os.path.exists(_DEV_NULL):
            rules.append((Path(_DEV_NULL), writes & (_WRITE_FILE | _TRUNCATE)))
        for path, rights in rules:
            fd = os.open(path, os.O_PATH | os.O_CLOEXEC)
            try:
                rule = PathBeneath(rights, fd)
                if libc.syscall(_ADD_RULE, ruleset, _RULE_PATH_BENEATH, ctypes.byref(rule), 0) != 0:
                    raise _os_error(ctypes, f"cannot let this process write beneath {path}")
            finally:
                os.close(fd)
        if libc.prctl(_PR_SET_NO_NEW_PRIVS, 1, 0, 0, 0) != 0:
            raise _os_error(ctypes, "cannot drop the right to gain privileges")
        if libc.syscall(_RESTRICT_SELF, ruleset, 0) != 0:
            raise _os_error(ctypes, "cannot confine this process")
    finally:
        os.close(ruleset)
    _keep_compiled_code_here()


def _keep_compiled_code_here() -> None:
    """numba's cache of compiled kernels lies outside the folders (and a confined learner must
    not write code that unconfined processes load): from now on this process loads kernels from
    it as before, but what it compiles afresh it keeps to itself instead of failing to save it."""
    caching = sys.modules.get("numba.core.caching")
    if caching is not None and hasattr(caching, "Cache"):
        caching.Cache.save_overload = lambda self, sig, data: None


def confinement(choice: str, backend: str = "local") -> bool:
    """Whether processes running a learner from outside tavc are to be confined, by
    `executor.confine` (`choice`) and what this system offers: True to confine; False to run
    unconfined, having said why in one line where ``auto`` wanted it. Raises `TavcError` where
    ``on`` asks for what cannot be had."""
    if choice == "off":
        return False
    why = ("its trials run on a cluster's workers (executor.backend=" + backend + ")" if backend != "local"
           else None if landlock_abi() else "this system has no Landlock (Linux 5.13 or later)")
    if why is None:
        return True
    if choice == "on":
        raise TavcError(f"executor.confine=on: cannot hold a learner from outside tavc to its run's folder: {why}; "
                        "give executor.confine=auto to run it unconfined")
    _say_once(f"note: a learner from outside tavc runs unconfined (it can write anywhere you can): {why}")
    return False


def run_confined(function: Callable[..., T], *args: Any, folders: Sequence[Path] = ()) -> T:
    """`function(*args)` in a forked copy of this process held to writing beneath `folders` (none:
    nowhere; `confine_writes`), its result (which must pickle) returned here and a `TavcError` it
    raises raised here; anything else it raises, or its process ending without an answer, is one
    `TavcError` line. This process is never confined. Linux only (where Landlock is)."""
    # deferred: only where something runs confined
    import pickle

    sys.stdout.flush()
    sys.stderr.flush()
    read_end, write_end = os.pipe()
    pid = os.fork()
    if pid == 0:  # the copy: confine, run, answer, and leave without any of the parent's clean-up
        code = 1
        try:
            os.close(read_end)
            try:
                confine_writes(folders)
                answer = ("value", function(*args))
            except TavcError as error:
                answer = ("refused", str(error))
            except BaseException as error:  # noqa: BLE001 - the learner's code: its error, as one line
                answer = ("failed", f"{type(error).__name__}: {error}")
            with os.fdopen(write_end, "wb") as out:
                try:
                    pickle.dump(answer, out)
                except Exception as error:  # noqa: BLE001 - an answer that does not pickle
                    pickle.dump(("failed", f"its answer cannot be sent back ({type(error).__name__})"), out)
            code = 0
        finally:
            sys.stdout.flush()
            sys.stderr.flush()
            os._exit(code)
    os.close(write_end)
    try:
        with os.fdopen(read_end, "rb") as answers:
            data = answers.read()
    except BaseException:  # Ctrl-C while it runs: it stops too
        _kill(pid)
        raise
    _, status = os.waitpid(pid, 0)
    try:
        kind, value = pickle.loads(data)
    except Exception:  # noqa: BLE001 - nothing, or half an answer: the copy died
        raise TavcError(f"the process running {getattr(function, '__name__', 'it')} held to its folders ended without "
                        f"an answer (exit status {os.waitstatus_to_exitcode(status)})") from None
    if kind == "value":
        return value
    if kind == "refused":
        raise TavcError(value)
    raise TavcError(f"{getattr(function, '__name__', 'it')} failed in its confined process: {value}")


def _kill(pid: int) -> None:
    try:
        os.kill(pid, signal.SIGKILL)
        os.waitpid(pid, 0)
    except (ProcessLookupError, ChildProcessError):
        pass


_SAID: set[str] = set()


def _say_once(line: str) -> None:
    if line not in _SAID:
        _SAID.add(line)
        print(line, file=sys.stderr, flush=True)


def _libc():
    # deferred: only on Linux, to ask for Landlock
    import ctypes

    try:
        libc = ctypes.CDLL(None, use_errno=True)
        libc.syscall.restype = ctypes.c_long
        return libc
    except (OSError, AttributeError):
        return None


def _os_error(ctypes, what: str) -> OSError:
    errno = ctypes.get_errno()
    return OSError(errno, f"{what}: {os.strerror(errno)}")
