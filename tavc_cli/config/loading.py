"""Composing configs with Hydra's compose API, and a sweep's jobs (`overrides` reads the overrides,
`messages` turns failures into one line)."""

import functools
import itertools
import math
from collections.abc import Sequence
from pathlib import Path
from typing import Any, Optional

from hydra import compose, initialize_config_dir
from hydra.core.config_store import ConfigStore
from omegaconf import DictConfig, OmegaConf
from omegaconf.errors import (
    OmegaConfBaseException,
)

from tavc_cli.chapter import EXPERIMENTS, base_case
from tavc_cli.config.composed import composed
from tavc_cli.config.folders import config_folders, find_conf_dir
from tavc_cli.config.limits import sources, validate_measurement_time
from tavc_cli.config.messages import hydra_errors, omegaconf_message, uncaught_by_hydra, uncomposable_message
from tavc_cli.config.overrides import (
    MAX_SWEEP_JOBS,
    is_hydra_override,
    parse_overrides,
    refuse_deletions,
    refuse_group_lists,
    slug,
    sweep_choices,
)
from tavc_cli.config.resolve import resolve
from tavc_cli.config.user_files import search_path_entry
from tavc_cli.config.validate import check_no_missing, validate, validate_scaling
from tavc_cli.errors import TavcError
from tavc_cli.io import default_root, owned_path, refuse_folder_problem
from tavc_cli.learning.parameters import settings_mapping
from tavc_cli.learning.plugins import config_dirs
from tavc_cli.override_keys import override_key, setting, setting_key
from tavc_cli.settings import SCHEMA_NAME, TavcConfig, settings_of

# --------------------------------------------------------------------------------------------
# Public API
# --------------------------------------------------------------------------------------------


def load_config(overrides: Sequence[str] = ()) -> DictConfig:
    """Compose, validate and resolve the configuration.

    Args:
        overrides: Hydra overrides such as ``experiment=breakdown`` or ``team.n_robots=4``.
            Sweeps (``a=1,2``) are refused here; see ``load_sweep``.

    Returns:
        A read-only ``DictConfig`` with every derived value filled in (see the module docstring).

    Raises:
        TavcError: On an unknown key, option or override syntax, a wrong type, or a value out of
            range; the message is one line naming the key.
    """
    _refuse_sweeps(overrides)
    return _load(overrides)


def _refuse_sweeps(overrides: Sequence[str]) -> None:
    """One line for a deletion, Hydra's own setting or a sweep among `overrides`: a single run's."""
    refuse_deletions(overrides)
    for text in overrides:
        if is_hydra_override(text):
            raise TavcError(f"{override_key(text)}: Hydra's own settings (its launcher) apply to sweeps; add -m")
    for override in parse_overrides(overrides):
        if override.is_sweep_override():
            key = override.get_key_element()
            raise TavcError(
                f"{key}: a sweep needs -m/--multirun (to set a list, write {key}=[a,b])"
            )


def check_measurement(overrides: Sequence[str], group: str) -> None:
    """Refuse `tavc model` (`group` model) or `tavc calibrate` (calibration) estimated to take more
    than a day, unless ``force=true`` (`limits.validate_measurement_time`).

    Raises:
        TavcError: On a bad config, or a measurement longer than a day.
    """
    overrides = list(overrides)
    if group == "calibration" and not any(setting_key(o) == "experiment" for o in overrides):
        overrides = [f"experiment={base_case().name}", *overrides]  # as `api.calibrate` composes it
    validate_measurement_time(load_config(overrides), group)


def load_sweep(overrides: Sequence[str]) -> list[DictConfig]:
    """Load, validate and resolve every job of a sweep before any of them runs.

    Each job's ``output_dir`` is the folder it would write to on its own, plus a subfolder
    ``<job index>_<swept key=value,...>``, so jobs never overwrite each other and reruns land
    in the same place.

    Args:
        overrides: Overrides that may contain sweeps (``learner.epsilon=0.05,0.1``).

    Returns:
        One resolved, read-only config per job, in sweep order.

    Raises:
        TavcError: If any job's config is invalid; the message names the job.
    """
    return [cfg for _, cfg in plan_sweep(overrides)]


def plan_sweep(overrides: Sequence[str]) -> list[tuple[list[str], DictConfig]]:
    """Every job of a sweep as (its plain overrides, its resolved config); see ``load_sweep``."""
    refuse_deletions(overrides)
    choices = sweep_choices(overrides)
    empty = [key for key, values in choices.items() if not values]
    if empty:
        raise TavcError(f"{empty[0]}: the sweep gives it no values, so there is no job to run")
    n_jobs = math.prod(len(values) for values in choices.values())
    if n_jobs > MAX_SWEEP_JOBS:
        product = " x ".join(str(len(values)) for values in choices.values() if len(values) > 1)
        raise TavcError(f"the sweep has {n_jobs:,} jobs ({product} values); a sweep runs at most "
                        f"{MAX_SWEEP_JOBS:,} jobs")
    swept = {key for key, values in choices.items() if len(values) > 1}
    jobs = [list(job) for job in itertools.product(*choices.values())]
    width = len(str(len(jobs) - 1))
    plan = []
    for index, job in enumerate(jobs):
        label = slug(choice for choice in job if override_key(choice) in swept)
        job_dir = f"{index:0{width}d}_{label}" if label else f"{index:0{width}d}"
        try:
            plan.append((job, _load(job, job_dir=job_dir)))
        except TavcError as error:
            raise TavcError(f"job {index} ({' '.join(job)}): {error}") from None
    return plan


def list_experiments() -> list[dict]:
    """Describe every experiment file in ``conf/experiment``.

    Returns:
        One dict per experiment, sorted by name, with keys ``name`` (what ``experiment=``
        takes), ``section`` (of the chapter) and ``description``.

    Raises:
        TavcError: If an experiment file does not compose.
    """
    experiments = []
    for name in experiment_names(own=True):
        cfg = _compose([f"experiment={name}"])
        experiments.append({"name": name, "section": cfg.section, "description": cfg.description})
    return experiments


def results_root(overrides: Sequence[str] = (), default_scale: str | None = None) -> Path:
    """The folder `tavc reproduce` and `tavc ladder` write into when none is named: ``runs/<scale>``
    (`io.default_root`), the scale as the overrides compose it (else `default_scale`, else
    the config's default)."""
    scale = [o for o in overrides if setting_key(o).split(".")[0] == "scale"]
    if default_scale is not None and not any(setting_key(o) == "scale" for o in scale):
        scale = [f"scale={default_scale}", *scale]
    return default_root(load_config(scale).scale.name)


def experiment_names(own: bool = False) -> list[str]:
    """The experiments there are files for (``experiment/<name>.yaml``), sorted: tavc's and those of
    the user's config folders (``--config-dir``), or tavc's only (`own`)."""
    return group_options("experiment", own)


def group_options(group: str, own: bool = False) -> list[str]:
    """The options of config group `group` there are files for (``<group>/<name>.yaml``), sorted:
    tavc's and those of the user's config folders (``--config-dir``), or tavc's only (`own`)."""
    return sorted({p.stem for d in config_folders(own) for p in (d / group).glob("*.yaml")})


def load_experiments(names: Sequence[str] | None, overrides: Sequence[str] = (),
                     results_dir: str | Path | None = None) -> list[DictConfig]:
    """Compose several experiments with the same overrides, each into ``results_dir/<name>``
    (what ``tavc reproduce`` runs).

    Args:
        names: Experiment names (as ``experiment=`` takes them), tavc's or, from the user's
            config folders (``--config-dir``), their own; None for every one of tavc's.
        overrides: Hydra overrides for all of them; ``experiment`` and ``output_dir`` are set
            per experiment and refused here.
        results_dir: The folder that gets one folder per experiment; by default
            ``runs/<scale>`` (`results_root`).

    Raises:
        TavcError: For an unknown or missing name, a refused key, or any override that fails.
    """
    own, known = experiment_names(own=True), experiment_names()
    chosen = own if names is None else [n.strip() for n in names if n.strip()]
    unknown = [n for n in chosen if n not in known]
    if unknown or not chosen:
        raise TavcError(f"--experiments: no experiment {unknown[0] if unknown else ''!r} "
                        f"(known: {', '.join(known)})")
    if len(set(chosen)) != len(chosen):
        raise TavcError(f"--experiments: name each experiment once ({', '.join(chosen)})")
    for override in overrides:
        key = setting_key(override)
        if key in ("experiment", "output_dir"):
            raise TavcError(f"{key}: set for each experiment by itself; choose experiments and the results folder "
                            "instead (--experiments, --results)")
    if results_dir is None:
        results_dir = results_root(overrides)
    refuse_folder_problem(results_dir, "--results", in_setting=True)  # '' would be the working folder
    cfgs = []
    for name in dict.fromkeys(chosen):
        try:
            folder = owned_path(Path(results_dir), Path(results_dir) / name, folder=True, what="--results")
            cfgs.append(load_config([f"experiment={name}", *overrides, setting("output_dir", folder)]))
        except TavcError as error:
            raise TavcError(f"{error} (experiment={name})") from None
    return cfgs


def experiment_lines() -> list[str]:
    """`list_experiments` as aligned lines: name, chapter section, description."""
    experiments = list_experiments()
    name_width = max((len(item["name"]) for item in experiments), default=0)
    section_width = max((len(item["section"]) for item in experiments), default=0)
    return [f"{item['name']:<{name_width}}  {item['section']:<{section_width}}  {item['description']}"
            for item in experiments]


def to_yaml(cfg: DictConfig | dict) -> str:
    """Render a config as YAML.

    Args:
        cfg: A config from ``load_config``, or its plain form from ``to_container``.

    Returns:
        The YAML text, interpolations resolved.
    """
    return OmegaConf.to_yaml(cfg, resolve=True)


def settings(cfg: DictConfig) -> TavcConfig:
    """The library's view of a config from ``load_config``: typed dataclasses, no OmegaConf.

    Returns:
        A ``TavcConfig`` whose groups are the ``tavc_cli.settings`` dataclasses.
    """
    return OmegaConf.to_object(cfg)


def to_container(cfg: DictConfig | dict) -> dict:
    """Convert a config to plain, picklable Python dicts and lists.

    Args:
        cfg: A config from ``load_config``; a plain dict is already converted and is
            returned as it is.

    Returns:
        A nested dict of builtin types.
    """
    if isinstance(cfg, dict):
        return cfg
    return OmegaConf.to_container(cfg, resolve=True, throw_on_missing=True)


# --------------------------------------------------------------------------------------------
# Composition (what it raises becomes one line in `messages`)
# --------------------------------------------------------------------------------------------


def _load(overrides: Sequence[str], *, job_dir: Optional[str] = None) -> DictConfig:
    """Compose, check, resolve and freeze one config (no sweeps)."""
    return complete(_compose(overrides), job_dir=job_dir)


def complete(cfg: DictConfig, *, job_dir: Optional[str] = None) -> DictConfig:
    """Type, check, resolve and freeze a config Hydra composed (by ``_compose`` or a launcher).

    Raises:
        TavcError: On a key the schema lacks, a wrong type or a value out of range.
    """
    cfg = _typed(cfg)
    try:
        check_no_missing(cfg)
        validate_scaling(cfg)
        named = sources(cfg)  # the keys resolution derives, for messages
        resolve(cfg, job_dir=job_dir)
        validate(cfg, named)
        # the learner's node as its settings class declares it: its own parameters, typed, no others
        cfg.learner = settings_mapping(settings_of(OmegaConf.to_container(cfg.learner)))
    except OmegaConfBaseException as error:
        raise TavcError(omegaconf_message(error)) from None
    OmegaConf.set_readonly(cfg, True)
    return cfg


def setting_of(overrides: Sequence[str], key: str) -> Any:
    """The value `overrides` give the dotted `key`, as composed and its interpolations resolved, the
    rest neither resolved nor validated (a setting read before the run it belongs to is made)."""
    _refuse_sweeps(overrides)
    cfg = _compose(overrides)
    with hydra_errors(overrides):
        try:
            return OmegaConf.select(cfg, key, throw_on_missing=True)
        except (ValueError, TypeError, KeyError) as error:
            raise TavcError(f"{key}: {str(error).splitlines()[0]}") from None


def _compose(overrides: Sequence[str]) -> DictConfig:
    """Compose ``config.yaml`` with overrides (untyped: ``complete`` types it).

    Only the compose API is used, never ``@hydra.main``: Hydra's own error reporting (and its
    ``HYDRA_FULL_ERROR`` traceback switch) is never involved, and every failure surfaces here
    as an exception that becomes one ``TavcError`` line. The same overrides over the same config
    files are composed once in a process (`composed`).
    """
    refuse_deletions(overrides)
    refuse_group_lists(overrides)
    search = search_overrides()
    if any(map(is_hydra_override, overrides)):  # Hydra's own settings (its search path) reach files the key
        cfg = _compose_now(overrides, search)  # does not read: composed every time
    else:
        cfg = composed(overrides, search, config_folders(), lambda: _compose_now(overrides, search))
    _refuse_borrowed_name(overrides, cfg)
    return cfg


def _refuse_borrowed_name(overrides: Sequence[str], cfg: DictConfig) -> None:
    """Refuse a config named after one of the registry's experiments (`experiment_name`) that is not
    that experiment's file: the report would test that experiment's claims on another's runs."""
    name = cfg.get("experiment_name")
    chosen = [str(o.value()) for o in parse_overrides([t for t in overrides if setting_key(t) == "experiment"])]
    if isinstance(name, str) and name in EXPERIMENTS and (not chosen or chosen[-1] != name):
        raise TavcError(f"experiment_name: {name!r} names one of the experiments whose claims the report tests, "
                        f"and this config is {'experiment=' + chosen[-1] if chosen else 'no experiment'}; "
                        f"choose experiment={name}, or another name")


def _compose_now(overrides: Sequence[str], search: list[str]) -> DictConfig:
    with hydra_errors(overrides), initialize_conf():
        try:
            return compose(config_name="config", overrides=[*search, *overrides])
        except (ValueError, TypeError, KeyError, IndexError, RecursionError) as error:
            if not uncaught_by_hydra(error):
                raise  # Hydra's and OmegaConf's own, made one line by `hydra_errors`
            culprit = next((o for o in overrides if not _composes([o])), None)
            raise TavcError(uncomposable_message(overrides, culprit, error)) from None


def _composes(overrides: Sequence[str]) -> bool:
    try:
        compose(config_name="config", overrides=[*search_overrides(), *overrides])
    except Exception:  # noqa: BLE001 - only whether it composes
        return False
    return True


def search_overrides() -> list[str]:
    """Hydra's search path extended by the user's config folders (`plugins.config_dirs`): their
    ``learner/``, ``experiment/``, ... options join tavc's own, each file checked as Hydra reads it
    (`user_files.CheckedFileSource`)."""
    dirs = config_dirs()
    if not dirs:
        return []
    return ["hydra.searchpath=[" + ",".join(f"'{search_path_entry(d)}'" for d in dirs) + "]"]


def initialize_conf():
    """Hydra initialised on ``conf/`` with the schema registered (a context manager)."""
    ConfigStore.instance().store(name=SCHEMA_NAME, node=TavcConfig)
    return initialize_config_dir(config_dir=str(find_conf_dir()), version_base="1.3", job_name="tavc")


def _typed(cfg: DictConfig) -> DictConfig:
    """Resolve interpolations and re-type the config, rejecting keys the schema lacks.

    ``+key=value`` overrides open the struct flag, so compose alone lets unknown keys in;
    merging a plain copy into a fresh schema catches them.
    """
    try:
        OmegaConf.resolve(cfg)
        return OmegaConf.merge(_schema(), OmegaConf.to_container(cfg))
    except OmegaConfBaseException as error:
        raise TavcError(omegaconf_message(error)) from None


@functools.cache
def _schema() -> DictConfig:
    """The schema as OmegaConf types it, built once in a process (a fifth of what typing a config
    costs): `OmegaConf.merge` copies it before merging into the copy, so it is never changed."""
    return OmegaConf.structured(TavcConfig)


