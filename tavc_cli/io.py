"""Atomic file writes (a reader never sees a half-written result) and one run per folder."""

from __future__ import annotations

import os
import socket
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


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


_FILE_MODE = 0o666 & ~_umask()


@contextmanager
def atomic_path(path: Path) -> Iterator[Path]:
    """Yield a temporary path beside `path`; on success rename it over `path`.

    On any error the temporary file is removed and `path` is left as it was.
    """
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".tmp")
    os.close(fd)
    try:
        yield Path(tmp)
        with open(tmp, "rb") as fh:
            os.fsync(fh.fileno())  # the data is on disk before the name points at it
        os.chmod(tmp, _FILE_MODE)  # mkstemp makes files private; results are for sharing
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise


def write_bytes_atomic(path: Path, data: bytes) -> None:
    """Write to a temporary file beside `path`, then rename it over `path`."""
    with atomic_path(path) as tmp:
        tmp.write_bytes(data)


def write_text_atomic(path: Path, text: str) -> None:
    write_bytes_atomic(path, text.encode())


def file_digest(path: Path) -> str:
    """SHA-256 of the file's bytes, in hex: what `provenance.json` records of every table a run
    wrote (its ``tables`` map), so that a reader can tell a table tavc wrote from a damaged one."""
    import hashlib

    h = hashlib.sha256()
    with open(path, "rb") as fh:
        for block in iter(lambda: fh.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


LOCK_NAME = ".tavc.lock"
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
def claim_folder(folder: Path, what: str = "output_dir") -> Iterator[Path]:
    """Create `folder` and hold it for this process alone until the block ends.

    The claim is an advisory lock (``flock``) on ``<folder>/.tavc.lock``: a second run on the
    same folder stops at once with a line naming the run that holds it, instead of
    interleaving its writes. The operating system drops the lock when the process exits
    however it ends (kill -9 included), so a crashed run never leaves the folder claimed; the
    file itself is removed on a normal exit. What a killed run left half-written is removed by
    `ownership.take`, which knows which files are tavc's. `what` names the setting behind the
    folder.
    """
    import fcntl

    folder = Path(folder)
    try:
        folder.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise TavcError(f"{what}: cannot create {folder}: {exc.strerror}") from None
    lock_path = folder / LOCK_NAME
    while True:
        try:
            fd = os.open(lock_path, os.O_RDWR | os.O_CREAT | os.O_CLOEXEC, 0o666 & ~_umask())
        except OSError as exc:
            raise TavcError(f"{what}: cannot take {lock_path}: {exc.strerror}") from None
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            holder = os.read(fd, 4096).decode(errors="replace").strip()
            os.close(fd)
            raise TavcError(f"{what}: {folder} is in use by another tavc run ({holder or 'unknown'}); "
                            "wait for it to finish or choose another folder") from None
        # the file may have been removed by the run that held it just before we locked it
        try:
            same = os.stat(lock_path).st_ino == os.fstat(fd).st_ino
        except FileNotFoundError:
            same = False
        if same:
            break
        os.close(fd)
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
