"""The user's own config folders (``--config-dir``, the API's ``config_dir=``): searched besides
tavc's for experiment/, learner/, team/ ... options and learners' files. They travel in the
environment variable `plugins.CONFIG_DIRS_ENV`, which worker processes inherit."""

from __future__ import annotations

import os
from collections.abc import Iterable, Iterator, Sequence
from contextlib import contextmanager
from pathlib import Path

from tavc_cli.errors import TavcError
from tavc_cli.learning.plugins import CONFIG_DIRS_ENV


def extended_config_dirs(dirs: Sequence[str | Path], what: str = "--config-dir") -> str:
    """The value of the variable with the folders `dirs` added after those already there; a folder
    that is not one is a `TavcError` naming it (`what`: the option or argument that gave it)."""
    if any(not str(d).strip() for d in dirs):  # not the working folder, which "." names
        raise TavcError(f"{what}: an empty folder name; give the folder of your configs ('.' for the working folder)")
    missing = [Path(d) for d in dirs if not Path(d).is_dir()]
    if missing:
        raise TavcError(f"{what}: {missing[0]} is not a folder")
    known = [p for p in os.environ.get(CONFIG_DIRS_ENV, "").split(os.pathsep) if p]
    return os.pathsep.join([*known, *(str(Path(d).resolve()) for d in dirs)])


@contextmanager
def using_config_dirs(dirs: str | Path | Sequence[str | Path] | None, what: str = "config_dir") -> Iterator[None]:
    """Within the block, the folders `dirs` (one, or several in order) are searched besides
    tavc's, as ``--config-dir`` makes them for a command; processes started inside inherit them.
    None changes nothing."""
    if dirs is None:
        yield
        return
    folders = [dirs] if isinstance(dirs, (str, os.PathLike)) else list(dirs) if isinstance(dirs, Iterable) else [dirs]
    bad = [d for d in folders if not isinstance(d, (str, os.PathLike))]
    if bad:
        raise TavcError(f"{what}: a folder's path, or a list of them, not {bad[0]!r:.80}")
    before = os.environ.get(CONFIG_DIRS_ENV)
    os.environ[CONFIG_DIRS_ENV] = extended_config_dirs(folders, what)
    try:
        yield
    finally:
        if before is None:
            os.environ.pop(CONFIG_DIRS_ENV, None)
        else:
            os.environ[CONFIG_DIRS_ENV] = before
