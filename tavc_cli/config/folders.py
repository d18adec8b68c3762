"""Where configs are found: tavc's own folder (`find_conf_dir`), then the user's config folders
(``--config-dir``, `plugins.config_dirs`) in the order Hydra searches them (`config_folders`), and
the file a config Hydra names is read from (`config_file`)."""

from __future__ import annotations

from pathlib import Path

from tavc_cli.errors import TavcError
from tavc_cli.learning.plugins import config_dirs


def find_conf_dir() -> Path:
    """Return the directory holding ``config.yaml`` and the config groups.

    An installed wheel ships the configs as ``tavc_cli/conf``; a source checkout (or an
    editable install) keeps them at the repository's top-level ``conf/``.

    Returns:
        The absolute path of the config directory.

    Raises:
        TavcError: If neither location holds a ``config.yaml``.
    """
    package_dir = Path(__file__).resolve().parent.parent
    candidates = (package_dir / "conf", package_dir.parent / "conf")
    for candidate in candidates:
        if (candidate / "config.yaml").is_file():
            return candidate
    raise TavcError(
        f"no config directory: looked for config.yaml in {candidates[0]} and {candidates[1]}"
    )


def config_folders(own: bool = False) -> list[Path]:
    """The folders configs are searched in, in Hydra's order: tavc's own first, then the user's
    (``--config-dir``), unless `own`."""
    return [find_conf_dir(), *([] if own else config_dirs())]


def config_file(name: str) -> str:
    """The file of the config Hydra names `name` (``experiment/fast``): ``conf/<name>.yaml`` where it
    is tavc's own, else its path in the first folder of the user's that has it."""
    for folder in config_folders():
        if (folder / f"{name}.yaml").is_file():
            return f"conf/{name}.yaml" if folder == find_conf_dir() else str(folder / f"{name}.yaml")
    return f"conf/{name}.yaml"
