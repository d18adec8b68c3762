"""The user's config files, checked before Hydra reads them (`check_user_configs`).

Hydra loads a config through OmegaConf, which copies what each YAML alias names: a file of a few
lines of nested aliases (a "billion laughs") expands to billions of nodes, and composing it would
take hours and every byte of memory before anything could be said. tavc's own files use no alias;
a user's may, within `MAX_CONFIG_NODES`. Every YAML file in the user's config folders
(``--config-dir``) is counted as it would expand (`readers.yaml_nodes`, on the composed document,
where an alias costs what its text does), once per version of the file in a process, and one beyond
the bound is refused in one line naming it.
"""

from __future__ import annotations

import os
from pathlib import Path

import yaml

from tavc_cli.config.composed import MAX_BYTES, MAX_DEPTH
from tavc_cli.errors import TavcError
from tavc_cli.learning.plugins import config_dirs
from tavc_cli.readers import yaml_nodes

# Nodes a config file of the user's may expand to. tavc's largest, conf/config.yaml, holds 196 and
# its whole composed config under a thousand; a hundred thousand is a hundred times that, and
# OmegaConf builds it in a few seconds.
MAX_CONFIG_NODES = 100_000
_ADVICE = "mend it, or take it out of your config folder"

_checked: set[tuple] = set()  # (path, device, inode, size, modification time) of files found within bounds


def check_user_configs() -> None:
    """Refuse a YAML file of the user's config folders that expands beyond `MAX_CONFIG_NODES` nodes,
    nests deeper than `readers.MAX_DEPTH`, holds an alias of itself, or is larger than
    `composed.MAX_BYTES` (folders are walked `composed.MAX_DEPTH` deep, following links, as Hydra
    follows them). Malformed YAML is left to Hydra, which names it when it reads the file.

    Raises:
        TavcError: One line naming the file and what is wrong with it.
    """
    for path in _yaml_files(config_dirs()):
        try:
            info = path.stat()
        except OSError:
            continue  # gone, or a broken link: Hydra says so if it is the file it needs
        version = (str(path), info.st_dev, info.st_ino, info.st_size, info.st_mtime_ns)
        if version in _checked:
            continue
        try:
            nodes = yaml_nodes(path, MAX_BYTES, _ADVICE)
        except (yaml.YAMLError, ValueError):
            continue  # malformed, or not UTF-8: Hydra's own message names it where it is read
        if nodes > MAX_CONFIG_NODES:
            raise TavcError(f"{path}: its aliases expand it to {nodes:,} YAML nodes, more than the "
                            f"{MAX_CONFIG_NODES:,} a config may hold; {_ADVICE}")
        _checked.add(version)


def _yaml_files(folders: list[Path]) -> list[Path]:
    """The ``.yaml`` and ``.yml`` files below `folders`, at most `MAX_DEPTH` folders down."""
    found = []
    for folder in folders:
        for top, dirs, files in os.walk(folder, followlinks=True):
            if len(Path(top).relative_to(folder).parts) >= MAX_DEPTH:
                dirs.clear()  # a link that loops ends here
            found += [Path(top) / name for name in sorted(files) if name.endswith((".yaml", ".yml"))]
    return found
