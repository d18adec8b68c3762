"""Configuration: schemas, composition, validation and resolution.

This package is the only place that imports Hydra or OmegaConf. Everything else receives the
``DictConfig`` that ``load_config`` returns: composed from ``conf/`` with Hydra's override
grammar, type-checked against the dataclass schemas (``schema``), validated with one-line
messages that name the offending key (``validate``), and with every derived value filled in
(``resolve``), so no ``null`` is left for the simulator to interpret.
"""

from tavc_cli.config.loading import (
    expand_sweep,
    find_conf_dir,
    is_hydra_override,
    list_experiments,
    load_config,
    load_sweep,
    swept_values,
    to_container,
    to_yaml,
)
from tavc_cli.config.schema import TavcConfig

__all__ = [
    "TavcConfig",
    "expand_sweep",
    "find_conf_dir",
    "is_hydra_override",
    "list_experiments",
    "load_config",
    "load_sweep",
    "swept_values",
    "to_container",
    "to_yaml",
]
