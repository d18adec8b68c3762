"""Holding a process to the folders it was given, with the Linux kernel's Landlock.

A learner from outside tavc is code (docs/security.md). Where the kernel offers Landlock (Linux
5.13 and later, no privileges needed), the processes that run one restrict themselves, for the
rest of their lives and for every process they start, to creating, writing, renaming and
deleting files only beneath the folders they were given (`confine_writes`); anything else is
refused by the kernel with a `PermissionError`, whatever the code does. They make no device
(Landlock), type into no terminal and trace no process (a seccomp filter), keep of root's
capabilities only those to read and write files, and, where the kernel knows how, open no TCP
connection and signal no process outside; numba compiles for them without writing its cache. Reading, and writing to
files already open, stay as they were: `confined` sets a process apart (closes what it need not
hold) before it confines it. `keep_below` is the keeper that ends every process a confined one
starts.

`executor.confine` says when (`confinement`): ``auto`` (the default) confines where this system
can (`refusal`) and says in one line where it cannot, ``on`` refuses to run a learner from
outside tavc unconfined, ``off`` never confines.
"""

from __future__ import annotations

import os
import signal
import sys
import time
from collections.abc import Callable, Sequence
from functools import cache
from pathlib import Path

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
_DEVICES = 1 << 6 | 1 << 11  # MAKE_CHAR, MAKE_BLOCK: handled, never granted
_TCP = 1 | 2  # LANDLOCK_ACCESS_NET_BIND_TCP, _CONNECT_TCP
_SCOPES = 1 | 2  # LANDLOCK_SCOPE_ABSTRACT_UNIX_SOCKET, _SIGNAL
_DEV_NULL = "/dev/null"  # written to by libraries that silence output: allowed, as it holds nothing


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
    files only beneath `folders` (which must exist); where the kernel knows how (Landlock 4 and 6),
    it can neither bind nor connect a TCP socket, nor signal a process or reach an abstract socket
    outside its confinement (tavc's own process among them). Irrevocable. Raises `OSError` where
    the kernel cannot (`landlock_abi` is 0) or refuses."""
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
        _fields_ = [("handled_access_fs", ctypes.c_uint64), ("handled_access_net", ctypes.c_uint64),
                    ("scoped", ctypes.c_uint64)]

    class PathBeneath(ctypes.Structure):
        _pack_ = 1
        _fields_ = [("allowed_access", ctypes.c_uint64), ("parent_fd", ctypes.c_int32)]

    # with no rule for them: no TCP port bound or connected to (ABI 4), no signal to a process and
    # no abstract socket outside this process's own confinement (ABI 6)
    attr = RulesetAttr(writes, _TCP if abi >= 4 else 0, _SCOPES if abi >= 6 else 0)
    size = ctypes.sizeof(attr) if abi >= 6 else 16 if abi >= 4 else 8  # the fields this kernel knows
    ruleset = libc.syscall(_CREATE_RULESET, ctypes.byref(attr), ctypes.c_size_t(size), 0)
    if ruleset < 0:
        raise _os_error(ctypes, "cannot make a Landlock ruleset")
    try:
        granted = writes & ~_DEVICES  # a device made beneath a folder would reach the disk it stands for
        rules = [(Path(f), granted) for f in folders]
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
    _no_terminal_input()
    _fewer_capabilities()
    _keep_compiled_code_here()


# capabilities: what a process of root's may do beyond its files' permissions
_PR_CAPBSET_DROP, _PR_CAP_AMBIENT, _PR_CAP_AMBIENT_CLEAR_ALL = 24, 47, 4
_CAPABILITY_VERSION_3 = 0x20080522
_KEPT_CAPABILITIES = 1 << 1 | 1 << 2  # CAP_DAC_OVERRIDE, CAP_DAC_READ_SEARCH: reading and writing as its files allow


def _fewer_capabilities() -> None:
    """A process of root's keeps only the capabilities to read and write its files as root does
    (within its folders: Landlock still holds), and loses every other for good: devices, mounts,
    kernel modules, ownership, other processes, the network's privileged parts. A process of
    another user has none to lose."""
    # deferred: only where a process is confined
    import ctypes

    libc = _libc()
    last = int(Path("/proc/sys/kernel/cap_last_cap").read_text()) if os.path.exists("/proc/sys/kernel/cap_last_cap") \
        else 40
    for cap in range(last + 1):
        if not _KEPT_CAPABILITIES >> cap & 1:
            libc.prctl(_PR_CAPBSET_DROP, cap, 0, 0, 0)  # refused without CAP_SETPCAP: nothing to drop
    libc.prctl(_PR_CAP_AMBIENT, _PR_CAP_AMBIENT_CLEAR_ALL, 0, 0, 0)

    class Header(ctypes.Structure):
        _fields_ = [("version", ctypes.c_uint32), ("pid", ctypes.c_int)]

    class Data(ctypes.Structure):
        _fields_ = [("effective", ctypes.c_uint32), ("permitted", ctypes.c_uint32), ("inheritable", ctypes.c_uint32)]

    header, data = Header(_CAPABILITY_VERSION_3, 0), (Data * 2)()
    if libc.capget(ctypes.byref(header), data) != 0:
        raise _os_error(ctypes, "cannot read this process's capabilities")
    for word, kept in zip(data, (_KEPT_CAPABILITIES, 0), strict=True):
        word.effective &= kept
        word.permitted &= kept
        word.inheritable = 0
    if libc.capset(ctypes.byref(header), data) != 0:
        raise _os_error(ctypes, "cannot drop this process's capabilities")


# seccomp: a filter the kernel runs on every system call of this process and those it starts
_PR_SET_SECCOMP, _SECCOMP_MODE_FILTER = 22, 2
_ALLOW, _DENY = 0x7FFF0000, 0x00050000 | 1  # SECCOMP_RET_ALLOW; SECCOMP_RET_ERRNO with EPERM
# AUDIT_ARCH_*, and the numbers of ioctl, ptrace and process_vm_writev there
_ARCHES = {"x86_64": (0xC000003E, 16, 101, 311), "aarch64": (0xC00000B7, 29, 117, 271)}
_TERMINAL_INPUT = (0x5412, 0x541C)  # TIOCSTI (type into a terminal), TIOCLINUX (its subcommands can too)


def _no_terminal_input() -> None:
    """Refuse this process the two requests that type into a terminal (TIOCSTI, TIOCLINUX): a
    confined process must not have a shell run what it types once tavc exits. Refuse it ptrace
    and process_vm_writev too: a process tracing another keeps that one's end from its keeper
    (`end_below`). Any system call of another architecture's numbering (a 32-bit call on a
    64-bit machine) is refused, so that none passes the filter by another number. Where the
    machine is neither x86_64 nor aarch64, nothing is filtered."""
    # deferred: only where a process is confined
    import ctypes
    import platform

    arch = _ARCHES.get(platform.machine())
    if arch is None:
        return
    audit_arch, ioctl, ptrace, vm_write = arch

    class Filter(ctypes.Structure):
        _fields_ = [("code", ctypes.c_uint16), ("jt", ctypes.c_uint8), ("jf", ctypes.c_uint8), ("k", ctypes.c_uint32)]

    class Program(ctypes.Structure):
        _fields_ = [("len", ctypes.c_uint16), ("filter", ctypes.POINTER(Filter))]

    load, jeq, jge, ret = 0x20, 0x15, 0x35, 0x06  # BPF_LD|W|ABS, BPF_JMP|JEQ|K, BPF_JMP|JGE|K, BPF_RET|K
    code = [
        (load, 0, 0, 4),                   # 0: the call's architecture
        (jeq, 1, 0, audit_arch),           # 1: this machine's: on to 3
        (ret, 0, 0, _DENY),                # 2: another's: refused
        (load, 0, 0, 0),                   # 3: the call's number
        (jge, 7, 0, 0x40000000),           # 4: x32's numbering: refused (12)
        (jeq, 6, 0, ptrace),               # 5: ptrace (a process tracing another below its keeper): refused
        (jeq, 5, 0, vm_write),             # 6: process_vm_writev: refused
        (jeq, 0, 3, ioctl),                # 7: not ioctl: allowed (11)
        (load, 0, 0, 24),                  # 8: ioctl's request (the low half of its second argument)
        (jeq, 2, 0, _TERMINAL_INPUT[0]),   # 9: TIOCSTI: refused (12)
        (jeq, 1, 0, _TERMINAL_INPUT[1]),   # 10: TIOCLINUX: refused (12)
        (ret, 0, 0, _ALLOW),               # 11
        (ret, 0, 0, _DENY),                # 12
    ]
    filters = (Filter * len(code))(*[Filter(*c) for c in code])
    program = Program(len(code), filters)
    if _libc().prctl(_PR_SET_SECCOMP, _SECCOMP_MODE_FILTER, ctypes.byref(program), 0, 0) != 0:
        raise _os_error(ctypes, "cannot keep this process from typing into a terminal")


def _keep_compiled_code_here() -> None:
    """numba's cache of compiled code lies outside the folders (and a confined learner must not
    write code that unconfined processes load): from now on this process loads tavc's kernels from
    it as before, but what it compiles afresh it keeps to itself instead of failing to save it,
    and a function of the learner's own asking for a cache (``cache=True``) is compiled without."""
    try:
        # deferred: numba is tavc's, but a process confined before it loads its kernels loads it here
        from numba.core import caching, dispatcher
    except ImportError:
        return
    caching.Cache.save_overload = lambda self, sig, data: None
    dispatcher.Dispatcher.enable_caching = lambda self: None


def die_with_parent(parent: int | None = None, sign: int = signal.SIGKILL) -> None:
    """On Linux, this process is sent `sign` (killed, by default) when its parent dies
    (PR_SET_PDEATHSIG); given the parent's pid, it also exits at once if that parent died before
    this could be asked."""
    if not sys.platform.startswith("linux"):
        return
    libc = _libc()
    if libc is not None:
        libc.prctl(1, int(sign))  # PR_SET_PDEATHSIG
    if parent is not None and os.getppid() != parent:
        os._exit(1)


# --- keeping what a confined process starts ---------------------------------------------------

_PR_SET_CHILD_SUBREAPER = 36  # a process's orphaned descendants become its children


def keep_below(parent: int, copy: Callable[[int], None]) -> None:
    """The keeper, a process of tavc's code alone, outside the confinement (so that nothing
    confined can signal or trace it): a session of its own, in which every orphan of the copy it
    starts (`copy(keeper_pid)`) becomes its child (PR_SET_CHILD_SUBREAPER). When the copy ends,
    or this process is told to end (SIGTERM, sent too when `parent` dies), it kills every process
    left below it and exits with the copy's status. Never returns."""
    code = 1
    try:
        os.setsid()
        signal.signal(signal.SIGINT, signal.SIG_IGN)  # Ctrl-C is the run's to handle: it ends its copies
        _libc().prctl(_PR_SET_CHILD_SUBREAPER, 1, 0, 0, 0)
        die_with_parent(parent, signal.SIGTERM)
        me = os.getpid()
        signal.signal(signal.SIGTERM, lambda *_: (end_below(me), os._exit(143)))
        pid = os.fork()
        if pid == 0:
            copy(me)  # never returns
        for fd in open_fds() - {0, 1, 2}:  # the copy's pipes are its own: this process holds none
            close_quietly(fd)
        _, status = os.waitpid(pid, 0)
        code = os.waitstatus_to_exitcode(status)
        end_below(me)
    finally:
        os._exit(code)


def end_below(me: int) -> None:
    """Kill every process below `me` (its children, and the orphans that become its children as
    their parents die), until none is left; reaped as they end, never waited for one by one (a
    child another process traces reports its end to that one first)."""
    while children := [pid for pid in _pids() if _parent_of(pid) == me]:
        for pid in children:
            try:
                os.kill(pid, signal.SIGKILL)
            except ProcessLookupError:
                pass
        try:
            while os.waitpid(-1, os.WNOHANG)[0]:
                pass
        except ChildProcessError:
            pass
        time.sleep(0.005)


def _pids() -> list[int]:
    return [int(name) for name in os.listdir("/proc") if name.isdigit()]


def _parent_of(pid: int) -> int | None:
    try:
        with open(f"/proc/{pid}/stat", "rb") as stat:
            return int(stat.read().rpartition(b")")[2].split()[1])
    except (OSError, ValueError, IndexError):
        return None


def open_fds() -> set[int]:
    """The file descriptors this process holds."""
    return {int(f) for f in os.listdir("/proc/self/fd")}


def close_quietly(fd: int) -> None:
    """Close `fd`, whether or not it is still open."""
    try:
        os.close(fd)
    except OSError:
        pass  # the listing's own descriptor, closed with it


def confinement(choice: str, backend: str = "local") -> bool:
    """Whether processes running a learner from outside tavc are to be confined, by
    `executor.confine` (`choice`) and what this system offers: True to confine; False to run
    unconfined, having said why in one line where ``auto`` wanted it. Raises `TavcError` where
    ``on`` asks for what cannot be had."""
    if choice == "off":
        return False
    why = ("its trials run on a cluster's workers (executor.backend=" + backend + ")" if backend != "local"
           else refusal())
    if why is None:
        return True
    if choice == "on":
        raise TavcError(f"executor.confine=on: cannot hold a learner from outside tavc to its run's folder: {why}; "
                        "give executor.confine=auto to run it unconfined")
    _say_once(f"note: a learner from outside tavc runs unconfined (it can write anywhere you can): {why}")
    return False


@cache
def refusal() -> str | None:
    """Why this system cannot confine a process (`confine_writes`), None where it can: tried
    once per process, in a copy of it that confines itself and ends (a kernel without Landlock,
    or a container whose own filter refuses a part of it)."""
    if not landlock_abi():
        return "this system has no Landlock (Linux 5.13 or later)"
    read_end, write_end = os.pipe()
    sys.stdout.flush()
    sys.stderr.flush()
    pid = os.fork()
    if pid == 0:
        code = 1
        try:
            os.close(read_end)
            try:
                confine_writes([])
                code = 0
            except OSError as error:
                os.write(write_end, str(error).encode()[:1000])
        finally:
            os._exit(code)
    os.close(write_end)
    with os.fdopen(read_end, "rb") as said:
        why = said.read(1001).decode(errors="replace")
    _, status = os.waitpid(pid, 0)
    return None if os.waitstatus_to_exitcode(status) == 0 else f"this system refuses it ({why or 'no reason given'})"


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
