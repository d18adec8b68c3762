"""The user's config files, checked as Hydra reads them (`CheckedFileSource`).

Hydra loads a config through OmegaConf, which copies what each YAML alias names: a file of a few
lines of nested aliases (a "billion laughs") expands to billions of nodes, and composing it would
take hours and every byte of memory before anything could be said. tavc's own files use no alias;
a user's may, within `MAX_CONFIG_NODES`. The user's config folders (``--config-dir``) are on
Hydra's search path under a scheme of tavc's own (`SCHEME`), whose source counts each file as it
would expand (`readers.yaml_nodes`, on the composed document, where an alias costs what its text
does) just before Hydra loads it, and refuses one beyond the bound in one line naming it. Only the
files a composition reads are checked, once per version of a file in a process.
"""

from __future__ import annotations

import os
from pathlib import Path

import yaml
from hydra._internal.core_plugins.file_config_source import FileConfigSource
from hydra.core.plugins import Plugins
from hydra.plugins.config_source import ConfigResult

from tavc_cli.errors import TavcError
from tavc_cli.readers import yaml_nodes

SCHEME = "tavcfile"  # the user's folders on Hydra's search path: tavcfile:///their/path
# Nodes a config file of the user's may expand to. tavc's largest, conf/config.yaml, holds 196 and
# its whole composed config under a thousand; a hundred thousand is a hundred times that, and
# OmegaConf builds it in a few seconds.
MAX_CONFIG_NODES = 100_000
# Bytes of a config file of the user's read to count it (tavc's largest is 6 KB).
MAX_CONFIG_BYTES = 16 << 20
_ADVICE = "mend it, or take it out of your config folder"

_checked: set[tuple] = set()  # (path, device, inode, size, modification time) of files found within bounds


class CheckedFileSource(FileConfigSource):
    """Hydra's source of configs in a folder, each file checked by `check_config_file` first."""

    @staticmethod
    def scheme() -> str:
        """The scheme of the user's folders on Hydra's search path."""
        return SCHEME

    def load_config(self, config_path: str) -> ConfigResult:
        """The config at `config_path` in this folder, as Hydra's file source reads it, checked first."""
        check_config_file(Path(os.path.realpath(os.path.join(self.path, self._normalize_file_name(config_path)))))
        return super().load_config(config_path)


def check_config_file(path: Path) -> None:
    """Refuse the config file `path` where it expands beyond `MAX_CONFIG_NODES` nodes, nests deeper
    than `readers.MAX_DEPTH`, holds an alias of itself, or is larger than `MAX_CONFIG_BYTES`.
    Malformed YAML and a missing file are left to Hydra, which names them as it reads the file.

    Raises:
        TavcError: One line naming the file and what is wrong with it.
    """
    try:
        info = path.stat()
    except OSError:
        return
    version = (str(path), info.st_dev, info.st_ino, info.st_size, info.st_mtime_ns)
    if version in _checked:
        return
    try:
        nodes = yaml_nodes(path, MAX_CONFIG_BYTES, _ADVICE)
    except (yaml.YAMLError, ValueError):
        return  # malformed, or not UTF-8
    if nodes > MAX_CONFIG_NODES:
        raise TavcError(f"{path}: its aliases expand it to {nodes:,} YAML nodes, more than the "
                        f"{MAX_CONFIG_NODES:,} a config may hold; {_ADVICE}")
    _checked.add(version)


def search_path_entry(folder: Path) -> str:
    """The entry of Hydra's search path for the user's config folder `folder`, read through
    `CheckedFileSource` (registered with Hydra here, in whichever process composes)."""
    Plugins.instance().register(CheckedFileSource)
    return f"{SCHEME}://{folder.resolve()}"
