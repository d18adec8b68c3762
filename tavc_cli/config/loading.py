"""Composing configs with Hydra's compose API, sweeps, and one-line error messages."""

import contextlib
import dataclasses
import difflib
import itertools
import re
from collections.abc import Iterator, Sequence
from pathlib import Path
from typing import Any, Optional

import yaml
from hydra import compose, initialize_config_dir
from hydra.core.config_store import ConfigStore
from hydra.core.override_parser.overrides_parser import OverridesParser
from hydra.errors import HydraException, MissingConfigException, OverrideParseException
from omegaconf import DictConfig, OmegaConf
from omegaconf.errors import (
    ConfigAttributeError,
    ConfigKeyError,
    OmegaConfBaseException,
    ValidationError,
)

from tavc_cli.config.resolve import resolve
from tavc_cli.config.schema import SCHEMA_NAME, TavcConfig
from tavc_cli.config.validate import check_no_missing, validate, validate_scaling
from tavc_cli.errors import TavcError

# --------------------------------------------------------------------------------------------
# Public API
# --------------------------------------------------------------------------------------------


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
    for text in overrides:
        if is_hydra_override(text):
            raise TavcError(f"{_override_key(text)}: Hydra's own settings (its launcher) apply to sweeps; add -m")
    for override in _parse_overrides(overrides):
        if override.is_sweep_override():
            key = override.get_key_element()
            raise TavcError(
                f"{key}: a sweep needs -m/--multirun (to set a list, write {key}=[a,b])"
            )
    return _load(overrides)


def is_hydra_override(text: str) -> bool:
    """Whether an override sets Hydra's own config (``hydra/launcher=...``, ``hydra.x=...``)."""
    key = text.lstrip("~+").split("=", 1)[0].strip()
    return key == "hydra" or key.startswith(("hydra.", "hydra/"))


def expand_sweep(overrides: Sequence[str]) -> list[list[str]]:
    """Expand Hydra sweep syntax into the override list of every job.

    Comma lists (``a=1,2``), ``range(...)`` and ``choice(...)`` are expanded into their cartesian
    product in the order given, as Hydra's basic sweeper does; a key given twice keeps its last
    value.

    Args:
        overrides: Overrides that may contain sweeps.

    Returns:
        One list of plain overrides per job.

    Raises:
        TavcError: On bad override syntax or a sweep that is not a discrete list of values.
    """
    choices = _sweep_choices(overrides)
    return [list(job) for job in itertools.product(*choices.values())]


def swept_values(overrides: Sequence[str]) -> list[dict[str, str]]:
    """Each job's value of every swept key (as written), in sweep order.

    Raises:
        TavcError: On bad override syntax or a sweep that is not a discrete list of values.
    """
    choices = _sweep_choices(overrides)
    swept = [key for key, values in choices.items() if len(values) > 1]
    return [{_override_key(c): c.split("=", 1)[1] for c in job if _override_key(c) in swept}
            for job in itertools.product(*choices.values())]


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
    choices = _sweep_choices(overrides)
    swept = {key for key, values in choices.items() if len(values) > 1}
    jobs = [list(job) for job in itertools.product(*choices.values())]
    width = len(str(len(jobs) - 1))
    plan = []
    for index, job in enumerate(jobs):
        label = _slug(choice for choice in job if _override_key(choice) in swept)
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
    for path in sorted((find_conf_dir() / "experiment").glob("*.yaml")):
        cfg = _compose([f"experiment={path.stem}"])
        experiments.append(
            {"name": path.stem, "section": cfg.section, "description": cfg.description}
        )
    return experiments


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
# Composition and Hydra/OmegaConf error translation
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
        resolve(cfg, job_dir=job_dir)
        validate(cfg)
    except OmegaConfBaseException as error:
        raise TavcError(_omegaconf_message(error)) from None
    OmegaConf.set_readonly(cfg, True)
    return cfg


def _compose(overrides: Sequence[str]) -> DictConfig:
    """Compose ``config.yaml`` with overrides (untyped: ``complete`` types it).

    Only the compose API is used, never ``@hydra.main``: Hydra's own error reporting (and its
    ``HYDRA_FULL_ERROR`` traceback switch) is never involved, and every failure surfaces here
    as an exception that becomes one ``TavcError`` line.
    """
    with hydra_errors(overrides), initialize_conf():
        return compose(config_name="config", overrides=list(overrides))


def initialize_conf():
    """Hydra initialised on ``conf/`` with the schema registered (a context manager)."""
    ConfigStore.instance().store(name=SCHEMA_NAME, node=TavcConfig)
    return initialize_config_dir(config_dir=str(find_conf_dir()), version_base="1.3", job_name="tavc")


@contextlib.contextmanager
def hydra_errors(overrides: Sequence[str]) -> Iterator[None]:
    """Turn what composing with ``overrides`` may raise into one ``TavcError`` line."""
    try:
        yield
    except MissingConfigException as error:
        raise TavcError(_missing_option_message(error)) from None
    except HydraException as error:
        raise TavcError(_hydra_message(error)) from None
    except OmegaConfBaseException as error:
        raise TavcError(_omegaconf_message(error)) from None
    except yaml.YAMLError as error:
        raise TavcError(_yaml_message(error)) from None
    except AssertionError as error:
        # Hydra asserts instead of raising when an override walks through a null node
        # (``team.members.0.speed_mps=1`` while ``team.members`` is null).
        raise TavcError(
            f"cannot apply overrides {' '.join(overrides)} (is a parent key null?): {error}"
        ) from None


def _typed(cfg: DictConfig) -> DictConfig:
    """Resolve interpolations and re-type the config, rejecting keys the schema lacks.

    ``+key=value`` overrides open the struct flag, so compose alone lets unknown keys in;
    merging a plain copy into a fresh schema catches them.
    """
    try:
        OmegaConf.resolve(cfg)
        return OmegaConf.merge(OmegaConf.structured(TavcConfig), OmegaConf.to_container(cfg))
    except OmegaConfBaseException as error:
        raise TavcError(_omegaconf_message(error)) from None


def _parse_overrides(overrides: Sequence[str]) -> list:
    """Parse overrides one by one so that a syntax error names the override at fault."""
    parser = OverridesParser.create()
    parsed = []
    for text in overrides:
        try:
            parsed.extend(parser.parse_overrides([text]))
        except OverrideParseException as error:
            raise TavcError(
                f"{_override_key(text)}: cannot parse override {text!r} ({_hydra_detail(error)})"
            ) from None
    return parsed


def _sweep_choices(overrides: Sequence[str]) -> dict[str, list[str]]:
    """Map each override key to the plain overrides it expands to (one unless swept)."""
    choices: dict[str, list[str]] = {}
    for text, override in zip(overrides, _parse_overrides(overrides), strict=True):
        key = override.get_key_element()
        if not override.is_sweep_override():
            choices[key] = [text]
        elif override.is_discrete_sweep():
            try:
                choices[key] = [f"{key}={value}" for value in override.sweep_string_iterator()]
            except HydraException:
                raise TavcError(
                    f"{key}: glob() sweeps are not supported; list the options"
                ) from None
        else:
            raise TavcError(f"{key}: only lists, range() and choice() can be swept, not interval()")
    return choices


def _override_key(text: str) -> str:
    """The key part of an override string (everything before the first ``=``)."""
    return text.split("=", 1)[0].strip() or text


def _slug(choices: Any) -> str:
    """A short, filesystem-safe folder name from ``key=value`` overrides."""
    text = ",".join(choices)
    return re.sub(r"[^A-Za-z0-9._=,+-]", "_", text)[:80]


def _hydra_detail(error: Exception) -> str:
    """The informative lines of a Hydra error, without its boilerplate, as one line."""
    lines = []
    for line in str(error).splitlines():
        line = line.strip()
        if not line or line.startswith(("See https://", "Error parsing override")):
            continue
        lines.append(line.split(" expecting {")[0])
    return "; ".join(lines) or type(error).__name__


def _yaml_message(error: yaml.YAMLError) -> str:
    """``conf/arena/x.yaml:3: invalid YAML (expected ',' or ']' ...)``."""
    mark = getattr(error, "problem_mark", None)
    where = f"{mark.name}:{mark.line + 1}" if mark is not None else "config"
    problem = getattr(error, "problem", None) or type(error).__name__
    return f"{where}: invalid YAML ({problem})"


def _missing_option_message(error: MissingConfigException) -> str:
    """``arena=nope: no such option; choose one of one_circuit, two_circuits``."""
    missing = error.missing_cfg_file or ""
    if "/" not in missing:
        return f"config: {_hydra_detail(error).split(';')[0]}"
    group, option = missing.rsplit("/", 1)
    if error.options:
        return f"{group}={option}: no such option; choose one of {', '.join(error.options)}"
    return f"{group}={option}: could not load {missing!r}"


def _hydra_message(error: HydraException) -> str:
    """A composition error, reported against the override or config file that caused it."""
    text = str(error)
    in_file = re.match(r"In '([^']+)': \w+ raised while composing config:\n(.*)", text)
    if in_file:
        # A config file itself is wrong (e.g. a key the schema lacks); name the key and file.
        full_key = re.search(r"full_key: (\S+)", text)
        key = full_key.group(1) if full_key else "config"
        return f"{key}: {_validation_detail(in_file.group(2))} (in conf/{in_file.group(1)}.yaml)"
    match = re.search(r"override '?([^'=\s]+)", text)
    context = match.group(1) if match else None
    if isinstance(error.__cause__, OmegaConfBaseException):
        return _omegaconf_message(error.__cause__, context=context)
    detail = text.splitlines()[0] if text else type(error).__name__
    return f"{context}: {detail}" if context else detail


def _omegaconf_message(error: OmegaConfBaseException, context: Optional[str] = None) -> str:
    """One line naming the key for an OmegaConf key or type error.

    Args:
        error: The OmegaConf exception.
        context: The override key being applied, if known. An element of a list literal (a
            breakdown dict, say) reports its key without the path, so the override names it.
    """
    full_key = getattr(error, "full_key", None) or ""
    nested = bool(context) and not full_key.startswith(context.split(".")[0])
    where = context if nested or not full_key else full_key
    if isinstance(error, (ConfigKeyError, ConfigAttributeError)):
        unknown = f"unknown key {error.key!r}" if nested else "unknown key"
        return f"{where}: {unknown}{_key_hint(error)}"
    if isinstance(error, ValidationError):
        return f"{where}: {_validation_detail(str(error))}"
    detail = str(error).splitlines()[0] if str(error) else type(error).__name__
    return f"{where or 'config'}: {detail}"


def _key_hint(error: OmegaConfBaseException) -> str:
    """Suggest the closest valid key, or list the valid keys."""
    object_type = getattr(error, "object_type", None)
    if not dataclasses.is_dataclass(object_type):
        return ""
    names = [item.name for item in dataclasses.fields(object_type)]
    close = difflib.get_close_matches(str(error.key), names, n=1)
    return f" (did you mean {close[0]!r}?)" if close else f"; valid keys: {', '.join(names)}"


def _validation_detail(text: str) -> str:
    """Rephrase OmegaConf's type errors as ``expected an integer, got 'abc'``."""
    first = text.strip().splitlines()[0] if text.strip() else "invalid value"
    match = re.match(r"Value '(.*)' of type '\w+' could not be converted to (\w+)", first)
    if match:
        kinds = {"Integer": "an integer", "Float": "a number", "Boolean": "true or false"}
        return f"expected {kinds.get(match.group(2), match.group(2))}, got {match.group(1)!r}"
    if "is not Optional" in first:
        return "must not be null"
    return first
