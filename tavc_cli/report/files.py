"""Reading a run's files for the report: each `config.yaml` parsed once per version of the
file (the report reads every run's settings several times), and a file no library can parse
refused in one line naming it."""

from __future__ import annotations

from functools import lru_cache
from pathlib import Path

from tavc_cli.errors import TavcError
from tavc_cli.settings import TavcConfig, from_yaml


def config_of(path: Path) -> TavcConfig:
    """A run's settings from its `config.yaml`, read once per version of the file (its
    resolved path, modification time and size). The settings are shared between callers:
    read them, never change them."""
    stat = path.stat()
    return _config_of(str(path.resolve()), stat.st_mtime_ns, stat.st_size)


@lru_cache(maxsize=256)
def _config_of(path: str, mtime_ns: int, size: int) -> TavcConfig:
    return from_yaml(Path(path))


def read_or_refuse(path: Path, read):
    """`read(path)`, with any failure to parse the file as one line naming it."""
    try:
        return read(path)
    except TavcError:
        raise
    except Exception as exc:  # any library's parse error: the file is damaged, whatever the library
        detail = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
        raise TavcError(f"{path}: cannot be read ({detail}); rerun its experiment to rewrite it") from None
