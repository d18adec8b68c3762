"""How tavc writes files: atomically, one run per folder, and only inside the folder it holds.

A reader never sees a half-written result (`atomic_path`); a second run on a folder stops at
once (`claim_folder`); and nothing is written or read through a link, a pipe or a device
inside the folder a command holds (`owned_path`).
"""

from __future__ import annotations

import hashlib
import os
import re
import socket
import stat
import sys
import tempfile
import time
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

from tavc_cli.errors import TavcError

RUNS_DIR = "runs"


def default_root(scale: str) -> Path:
    """The folder that gets a scale's runs by default (and `tavc reproduce`'s, `tavc ladder`'s,
    `tavc surrogate`'s folders): ``runs/<scale>``. Git ignores ``runs/``; ``results/`` is the
    committed reproduction, written only when a command names it."""
    return Path(RUNS_DIR) / str(scale)


def path_of(value: object, what: str) -> Path:
    """`value`, a path a caller of the API gave (`what` names the argument), as a `Path`: one line
    where it is none (None, a number, a list)."""
    if not isinstance(value, str | os.PathLike):
        raise TavcError(f"{what}: a folder's path, not {value!r:.80}")
    return Path(value)


def plain_name(name: str) -> bool:
    """Whether `name` names one folder in the folder it is read in (a scale's, an experiment's):
    never empty, never a path that leads elsewhere, no space at either end."""
    return name not in ("", ".", "..") and not any(c in name for c in "/\\") and name == name.strip()


def folder_problem(folder: str | Path, *, in_setting: bool = False) -> str | None:
    """What is wrong with `folder` as a folder tavc writes results into, or None: empty (an unset
    variable, as a rule), or the root of the file system (where a run's files would lie among the
    system's); `in_setting`, a folder tavc will name in a setting of its own (`--results`, the
    API's folders), also one holding ``${``, which a setting reads as an interpolation."""
    if not str(folder).strip():
        return "must not be empty"
    if in_setting and "${" in str(folder):
        return f"{folder} holds '${{', which tavc's settings read as an interpolation; name a folder without it"
    resolved = Path(folder).resolve()
    if resolved == Path(resolved.anchor):
        return f"{folder} is the root of the file system; give the results a folder of their own"
    return _not_a_folder(Path(folder))


def _not_a_folder(path: Path) -> str | None:
    """What stands where `path`, a folder tavc is to make or write in, goes: a file, a link to
    nothing, or a file above it; None where it is a folder or can be made."""
    for here in (path, *path.parents):
        try:
            mode = os.stat(here).st_mode
        except (FileNotFoundError, NotADirectoryError):  # missing, or below a file: the parent says which
            if os.path.islink(here):
                return f"{here} is a link to {os.readlink(here)}, which does not exist; make that folder or name " \
                    "another"
            continue
        except OSError:
            return None  # not for tavc to judge: making the folder says what is wrong
        if stat.S_ISDIR(mode):
            return None
        what = "a file" if stat.S_ISREG(mode) else "not a folder"
        return (f"{path} is {what}; name a folder" if here == path
                else f"{path} lies below {here}, which is {what}; name a folder")
    return None


def refuse_folder_problem(folder: str | Path, what: str, *, in_setting: bool = False) -> None:
    """One line naming `what` (the option or key that gave `folder`) where `folder_problem` finds one."""
    problem = folder_problem(folder, in_setting=in_setting)
    if problem is not None:
        raise TavcError(f"{what}: {problem}")


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


_FILE_MODE = 0o666 & ~_umask()


# what a part of a path may be, by `os.lstat`'s mode, named as a refusal names it
_KINDS = ((stat.S_ISLNK, "a symbolic link"), (stat.S_ISFIFO, "a named pipe (FIFO)"), (stat.S_ISCHR, "a device"),
          (stat.S_ISBLK, "a device"), (stat.S_ISSOCK, "a socket"), (stat.S_ISDIR, "a folder"),
          (stat.S_ISREG, "a file"))


def owned_path(root: Path, path: Path, *, folder: bool = False, what: str = "") -> Path:
    """Return `path`, a path below `root`, once nothing on it leads a write or a read out of `root`.

    `root` is the folder a command holds, as its user named it (a link there is the user's
    choice). Below it tavc makes every folder itself, so no part of `path` may be a link, which
    may lead anywhere, dangling or not, nor a named pipe, a device or a socket, which a write
    would block on or reach through; nor may a folder stand where `path`, a file (unless
    `folder`), goes. Each is refused in one line naming it (prefixed by `what`, the setting
    behind the folder). Parts that do not exist yet are tavc's to make; a regular file where a
    folder goes leads nowhere, and writing below it fails on its own (the store names a file
    in the place of trials/).
    """
    root, path = Path(root), Path(path)
    parts = path.relative_to(root).parts  # ValueError for a path outside `root`: a bug, not the user's
    here = root
    for k, part in enumerate(parts):
        here = here / part
        if part == "..":
            raise TavcError(f"{what + ': ' if what else ''}{path} leads out of {root}; tavc writes only inside it")
        try:
            mode = os.lstat(here).st_mode
        except (FileNotFoundError, NotADirectoryError):
            break  # nothing exists below a missing part, or below a file (making a folder there fails on its own)
        wants_folder = folder or k < len(parts) - 1
        if wants_folder and stat.S_ISREG(mode):
            break
        if not (stat.S_ISDIR(mode) if wants_folder else stat.S_ISREG(mode)):
            raise _in_the_way(here, mode, wants_folder, what)
    return path


def _in_the_way(path: Path, mode: int, wants_folder: bool, what: str) -> TavcError:
    """The one line refusing what stands at `path` (`os.lstat`'s `mode`; a link with where it leads)."""
    kind = next((name for test, name in _KINDS if test(mode)), "not a file")
    if stat.S_ISLNK(mode):
        try:
            kind += f" to {os.readlink(path)}"
        except OSError:
            pass
    return TavcError(f"{what + ': ' if what else ''}{path} is {kind}, where tavc "
                     f"{'keeps a folder' if wants_folder else 'writes a file'} of its own; "
                     "move it away or choose another folder")


@contextmanager
def atomic_path(path: Path, root: Path | None = None) -> Iterator[Path]:
    """Yield a temporary path beside `path`; on success rename it over `path`.

    On any error the temporary file is removed and `path` is left as it was. `path` is
    checked first below `root`, the folder the command holds (`owned_path`; by default the
    folder written into): a link, a pipe or a device there is refused, and never written
    through. The rename replaces only the name at `path`, and only if the temporary name still
    holds the file made for it (`_atomic`).
    """
    with _atomic(path, root) as (tmp, _):
        yield tmp


@contextmanager
def _atomic(path: Path, root: Path | None) -> Iterator[tuple[Path, int]]:
    """`atomic_path`, yielding the temporary file's descriptor too, open for writing: what is
    written through it, its flush to disk and its permissions never go through a name that
    something else may have put a link at meanwhile."""
    path = Path(path)
    owned_path(path.parent if root is None else root, path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".tmp")
    try:
        yield Path(tmp), fd
        made, there = os.fstat(fd), os.stat(tmp, follow_symlinks=False)
        if (made.st_dev, made.st_ino) != (there.st_dev, there.st_ino):
            raise TavcError(f"{tmp}: replaced while tavc wrote it (by a link or another file); nothing was written "
                            f"over {path}")
        os.fsync(fd)  # the data is on disk before the name points at it
        os.fchmod(fd, _FILE_MODE)  # mkstemp makes files private; results are for sharing
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
    finally:
        os.close(fd)


def write_bytes_atomic(path: Path, data: bytes, root: Path | None = None) -> None:
    """Write to a temporary file beside `path`, then rename it over `path` (`atomic_path`),
    through the file's descriptor."""
    with _atomic(path, root) as (_, fd):
        view = memoryview(data)
        while view:
            view = view[os.write(fd, view):]


def write_text_atomic(path: Path, text: str, root: Path | None = None) -> None:
    """`write_bytes_atomic` of `text`, UTF-8 encoded."""
    write_bytes_atomic(path, text.encode(), root)


def file_digest(path: Path) -> str:
    """SHA-256 of the file's bytes, in hex: what `provenance.json` records of every table a run
    wrote (its ``tables`` map), so that a reader can tell a table tavc wrote from a damaged one."""
    h = hashlib.sha256()
    with open(path, "rb") as fh:
        for block in iter(lambda: fh.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


LOCK_NAME = ".tavc.lock"
_LOCK_TEXT = re.compile(r"pid \d+ on .*, since \d{4}-\d\d-\d\d \d\d:\d\d:\d\d: ")  # what `claim_folder` writes there
_HELD: set[int] = set()  # descriptors of the folders this process holds


def _forget_held() -> None:
    """In a forked child (a worker of the process pool): close the copies of the lock
    descriptors, so that only the run that took a folder holds it, and a worker outliving
    a killed run never keeps the folder locked."""
    for fd in list(_HELD):
        try:
            os.close(fd)
        except OSError:
            pass
    _HELD.clear()


os.register_at_fork(after_in_child=_forget_held)


@contextmanager
def claim_folder(folder: Path, what: str = "output_dir", *, within: Path | None = None) -> Iterator[Path]:
    """Create `folder` and hold it for this process alone until the block ends; `within`, the
    folder its user named where tavc names `folder` below it, which no part of `folder` below it
    may lead out of (`owned_path`: a link there is refused, not followed).

    The claim is an advisory lock (``flock``) on ``<folder>/.tavc.lock``: a second run on the
    same folder stops at once with a line naming the run that holds it, instead of
    interleaving its writes. The operating system drops the lock when the process exits
    however it ends (kill -9 included), so a crashed run never leaves the folder claimed; the
    file itself is removed on a normal exit. What a killed run left half-written is removed by
    `ownership.take`, which knows which files are tavc's. `what` names the setting behind the
    folder.
    """
    # deferred: POSIX only
    import fcntl

    refuse_folder_problem(folder, what)
    folder = Path(folder)
    if within is not None:
        owned_path(Path(within), folder, folder=True, what=what)
    try:
        folder.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise TavcError(f"{what}: cannot create {folder}: {exc.strerror}") from None
    lock_path = owned_path(folder, folder / LOCK_NAME, what=what)
    while True:
        fd = _open_lock(lock_path, what)
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            holder = os.read(fd, 4096).decode(errors="replace").strip()
            os.close(fd)
            raise TavcError(f"{what}: {folder} is in use by another tavc run ({holder or 'unknown'}); "
                            "wait for it to finish or choose another folder") from None
        # the file may have been removed by the run that held it just before we locked it
        try:
            same = os.lstat(lock_path).st_ino == os.fstat(fd).st_ino
        except FileNotFoundError:
            same = False
        if same:
            break
        os.close(fd)
    left = os.pread(fd, 4096, 0).decode(errors="replace")
    if left and not _LOCK_TEXT.match(left):  # a file of the user's by tavc's name: neither emptied nor removed
        os.close(fd)
        raise TavcError(f"{what}: {lock_path} was not written by tavc, which keeps its lock under that name; move it "
                        "away")
    _HELD.add(fd)
    try:
        os.ftruncate(fd, 0)
        started = time.strftime("%Y-%m-%d %H:%M:%S")
        os.write(fd, f"pid {os.getpid()} on {socket.gethostname()}, since {started}: {' '.join(sys.argv)}\n".encode())
        yield folder
    finally:
        lock_path.unlink(missing_ok=True)  # before the unlock: a waiting run then finds a fresh file
        _HELD.discard(fd)
        os.close(fd)


def _open_lock(lock_path: Path, what: str) -> int:
    """Open (or create) the lock file, never through a link, and return its descriptor.

    ``O_NOFOLLOW`` fails on a link, so one put there after `owned_path` looked is not followed
    either; and whatever was opened, if it is not a regular file (a pipe, a device), is closed
    before anything is read from it or written to it.
    """
    flags = os.O_RDWR | os.O_CREAT | os.O_NOFOLLOW | os.O_CLOEXEC | os.O_NONBLOCK  # a pipe never blocks the open
    try:
        fd = os.open(lock_path, flags, 0o666 & ~_umask())
    except OSError as exc:
        raise TavcError(f"{what}: cannot take {lock_path}: {exc.strerror}") from None
    mode = os.fstat(fd).st_mode
    if not stat.S_ISREG(mode):
        os.close(fd)
        raise _in_the_way(lock_path, mode, False, what)
    return fd
