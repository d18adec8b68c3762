"""Configuration: composition, validation, resolution and sweeps.

This package is the only place that imports Hydra, and only the front doors (``cli.py``,
``api.py``) import it. ``load_config`` composes ``conf/`` with Hydra's override grammar,
type-checks it against the dataclass schemas of ``tavc_cli.settings``, validates it with
one-line messages that name the offending key (``validate``) and fills in every derived value
(``resolve``), so no ``null`` is left for the simulator to interpret. ``settings`` turns the
result into the typed ``TavcConfig`` the library takes. ``launch`` runs a sweep's jobs through
a Hydra launcher.
"""

from tavc_cli.config.experiments import describe_experiments
from tavc_cli.config.folders import find_conf_dir
from tavc_cli.config.ladder import ladder_folder, load_ladder, parse_factors, runs_beside
from tavc_cli.config.loading import (
    check_measurement,
    experiment_lines,
    experiment_names,
    group_options,
    list_experiments,
    load_config,
    load_experiments,
    load_sweep,
    results_root,
    setting_of,
    settings,
    to_container,
    to_yaml,
)
from tavc_cli.config.overrides import expand_sweep, is_hydra_override, parse_overrides, refuse_deletions, swept_values
from tavc_cli.settings import TavcConfig

__all__ = [
    "TavcConfig",
    "check_measurement",
    "describe_experiments",
    "expand_sweep",
    "experiment_lines",
    "experiment_names",
    "find_conf_dir",
    "group_options",
    "is_hydra_override",
    "ladder_folder",
    "list_experiments",
    "load_config",
    "load_experiments",
    "load_ladder",
    "load_sweep",
    "parse_factors",
    "parse_overrides",
    "refuse_deletions",
    "results_root",
    "runs_beside",
    "setting_of",
    "settings",
    "swept_values",
    "to_container",
    "to_yaml",
]
