"""Configuration: schemas, composition, validation and resolution.

This is the only module that imports Hydra or OmegaConf. Everything else receives the
``DictConfig`` that ``load_config`` returns: composed from ``conf/`` with Hydra's override
grammar, type-checked against the dataclass schemas below, validated with one-line messages
that name the offending key, and with every derived value filled in (no ``null`` left for the
simulator to interpret).

Resolution rules (applied in ``_resolve``):

- ``trials``: ``min(scale.trials, paper.trials)``, or ``paper.trials`` when the scale sets none.
- ``baseline_trials``: ``paper.baseline_trials`` capped by ``scale.trials`` like ``trials``;
  when the paper gives none, the same as ``trials``.
- ``duration_s``, ``convergence_s``: the paper's value times ``scale.time_factor``.
- ``sim.warmup_s`` and every event time (``events.breakdowns[*].time_s``,
  ``events.value_changes[*].time_s``) are ALWAYS multiplied by ``scale.time_factor``, also when
  set on the command line, so that an experiment keeps its shape at every scale.
- ``output_dir``: ``results/<experiment_name>``.
- ``team.members``: ``team.n_robots`` copies of ``{speed_mps: robot.speed_mps, group: all}``.
- ``tasks.values``: 1.0 per circuit; ``tasks.score_values``: ``tasks.values``.
- ``executor.n_jobs``: ``os.cpu_count()``.
"""

import dataclasses
import difflib
import itertools
import math
import os
import re
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, List, NoReturn, Optional

import yaml
from hydra import compose, initialize_config_dir
from hydra.core.config_store import ConfigStore
from hydra.core.override_parser.overrides_parser import OverridesParser
from hydra.errors import HydraException, MissingConfigException, OverrideParseException
from omegaconf import MISSING, DictConfig, OmegaConf
from omegaconf.errors import (
    ConfigAttributeError,
    ConfigKeyError,
    OmegaConfBaseException,
    ValidationError,
)

from tavc_cli.errors import TavcError

SCHEMA_NAME = "tavc_schema"
LEARNERS = ("random", "static", "tavc_egreedy", "tavc_softmax", "behaviour_softmax")
AVAILABLE_LEARNERS = ("random", "static", "tavc_egreedy", "tavc_softmax")
AVAILABLE_BACKENDS = ("local",)
BASELINES = ("random", "static")
BACKENDS = ("local", "ray", "dask")
ANALYSIS_STATES = ("circuits", "groups")
TARGET_KINDS = ("source", "sink")
TIME_UNITS = ("s", "ms")
# A target must sit on a wall (bar-codes are mounted on walls); this is how close counts as on.
WALL_TOLERANCE_M = 1e-6


# --------------------------------------------------------------------------------------------
# Schemas. Defaults mirror conf/; the YAML files are what users read and edit. The arena has no
# defaults: an arena is data and must come from conf/arena/.
# --------------------------------------------------------------------------------------------


@dataclass
class TargetConfig:
    """A source or sink: a bar-code on a wall, at ``(x, y)`` metres from the lower-left corner."""

    name: str = MISSING
    kind: str = MISSING
    barcode: int = MISSING
    x: float = MISSING
    y: float = MISSING


@dataclass
class CircuitConfig:
    """A task class: carry from the target named ``source`` to the target named ``sink``."""

    name: str = MISSING
    source: str = MISSING
    sink: str = MISSING


@dataclass
class ArenaConfig:
    """A rectangular arena with its targets and circuits.

    ``walls`` lists interior wall segments, each ``[x1, y1, x2, y2]`` in metres (the outer
    walls come from ``width_m`` and ``height_m``).
    """

    name: str = MISSING
    width_m: float = MISSING
    height_m: float = MISSING
    barcode_width_m: float = 0.6
    # Any, not List[float]: OmegaConf 2.3 rejects ints in nested typed lists ([1, 1, 3, 1]).
    walls: List[Any] = field(default_factory=list)
    targets: List[TargetConfig] = MISSING
    circuits: List[CircuitConfig] = MISSING


@dataclass
class LaserConfig:
    """Laser range finder (also reads bar-codes)."""

    fov_deg: float = 180.0
    n_rays: int = 31
    range_m: float = 8.0


@dataclass
class CameraConfig:
    """Colour camera that sees the markings on the nearest robot in view."""

    fov_deg: float = 80.0
    range_m: float = 6.0
    side_sector_deg: float = 112.5


@dataclass
class OdometryConfig:
    """Odometry noise; errors grow with the square root of distance travelled or turned."""

    trans_noise_per_sqrt_m: float = 0.03
    rot_noise_per_sqrt_m: float = 0.03
    rot_noise_per_sqrt_rad: float = 0.03


@dataclass
class BehaviourConfig:
    """Distances used by the transport sub-behaviours."""

    avoid_dist_m: float = 0.7
    stop_dist_m: float = 0.25
    arrive_dist_m: float = 0.75
    wall_dist_m: float = 0.5
    visible_margin_m: float = 0.5
    relocalise_dist_m: float = 2.0
    stall_s: float = 20.0
    progress_m: float = 0.3
    escape_s: float = 15.0


@dataclass
class RobotConfig:
    """A differential-drive disc robot with its sensors."""

    name: str = "pioneer2dx"
    radius_m: float = 0.22
    mass_kg: float = 15.0
    speed_mps: float = 0.25
    turn_rate_radps: float = 1.2
    drive_force_n: float = 60.0
    drive_torque_nm: float = 10.0
    laser: LaserConfig = field(default_factory=LaserConfig)
    camera: CameraConfig = field(default_factory=CameraConfig)
    odometry: OdometryConfig = field(default_factory=OdometryConfig)
    behaviour: BehaviourConfig = field(default_factory=BehaviourConfig)


@dataclass
class MemberConfig:
    """One robot of a heterogeneous team."""

    speed_mps: float = MISSING
    group: str = "all"


@dataclass
class TeamConfig:
    """The team: ``n_robots`` copies of ``robot``, or an explicit list of members."""

    n_robots: int = 6
    members: Optional[List[MemberConfig]] = None


@dataclass
class LearnerConfig:
    """Every learner's parameters in one schema; each learner reads the fields it needs."""

    name: str = "random"
    alpha: float = 0.1
    gamma: float = 0.95
    epsilon: float = 0.1
    tau: float = 0.005
    q_init_low: float = -0.1
    q_init_high: float = 0.1
    allocation: Optional[List[int]] = None


@dataclass
class ScaleConfig:
    """How much of the chapter's trials and simulated time to run."""

    name: str = "paper"
    trials: Optional[int] = None
    time_factor: float = 1.0


@dataclass
class ExecutorConfig:
    """Where trials run."""

    backend: str = "local"
    n_jobs: Optional[int] = None
    batch_size: int = 8
    address: Optional[str] = None


@dataclass
class PaperConfig:
    """The chapter-scale trial count and durations of an experiment."""

    trials: int = 20
    duration_s: float = 3600.0
    convergence_s: float = 900.0
    baseline_trials: Optional[int] = None


@dataclass
class TasksConfig:
    """Task values per circuit.

    On a ``DictConfig`` read ``tasks["values"]``: ``tasks.values`` is the dict method.
    """

    values: Optional[List[float]] = None
    score_values: Optional[List[float]] = None
    time_unit: str = "ms"


@dataclass
class BreakdownConfig:
    """A robot removed at ``time_s``: a given robot, one on a circuit, or a random one."""

    time_s: float = MISSING
    robot: Optional[int] = None
    # null, "high", "low" or a circuit index; a string so that all four fit one type.
    circuit: Optional[str] = None


@dataclass
class ValueChangeConfig:
    """New learning values for every circuit from ``time_s`` on (read ``change["values"]``)."""

    time_s: float = MISSING
    values: List[float] = MISSING


@dataclass
class EventsConfig:
    """Scheduled events; times are relative to the start of the record (warm-up is negative)."""

    breakdowns: List[BreakdownConfig] = field(default_factory=list)
    value_changes: List[ValueChangeConfig] = field(default_factory=list)


@dataclass
class SimConfig:
    """Simulator timing."""

    dt_s: float = 0.1
    physics_substeps: int = 1
    solver_iterations: int = 10
    q_snapshot_every_s: float = 600.0
    pose_every_s: float = 0.0
    warmup_s: float = 0.0


@dataclass
class AnalysisConfig:
    """How records are summarised."""

    state: str = "circuits"
    performance_bin_s: float = 600.0


@dataclass
class ModelConfig:
    """How `tavc model` measures task-processing frequencies (times scale with `scale`)."""

    trials_per_split: int = 4
    warmup_s: float = 300.0
    measure_s: float = 3000.0
    confidence: float = 0.9
    max_robots: Optional[int] = None


@dataclass
class TavcConfig:
    """The whole configuration, as composed from conf/config.yaml."""

    arena: ArenaConfig = field(default_factory=ArenaConfig)
    robot: RobotConfig = field(default_factory=RobotConfig)
    team: TeamConfig = field(default_factory=TeamConfig)
    learner: LearnerConfig = field(default_factory=LearnerConfig)
    scale: ScaleConfig = field(default_factory=ScaleConfig)
    executor: ExecutorConfig = field(default_factory=ExecutorConfig)
    experiment_name: str = "default"
    section: str = ""
    description: str = ""
    seed: int = 0
    trials: Optional[int] = None
    baseline_trials: Optional[int] = None
    duration_s: Optional[float] = None
    convergence_s: Optional[float] = None
    output_dir: Optional[str] = None
    paper: PaperConfig = field(default_factory=PaperConfig)
    baselines: List[str] = field(default_factory=list)
    static_allocation: Optional[List[int]] = None
    tasks: TasksConfig = field(default_factory=TasksConfig)
    events: EventsConfig = field(default_factory=EventsConfig)
    sim: SimConfig = field(default_factory=SimConfig)
    analysis: AnalysisConfig = field(default_factory=AnalysisConfig)
    model: ModelConfig = field(default_factory=ModelConfig)


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
    package_dir = Path(__file__).resolve().parent
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
    for override in _parse_overrides(overrides):
        if override.is_sweep_override():
            key = override.get_key_element()
            raise TavcError(
                f"{key}: a sweep needs -m/--multirun (to set a list, write {key}=[a,b])"
            )
    return _load(overrides)


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
    choices = _sweep_choices(overrides)
    swept = {key for key, values in choices.items() if len(values) > 1}
    jobs = list(itertools.product(*choices.values()))
    width = len(str(len(jobs) - 1))
    configs = []
    for index, job in enumerate(jobs):
        label = _slug(choice for choice in job if _override_key(choice) in swept)
        job_dir = f"{index:0{width}d}_{label}" if label else f"{index:0{width}d}"
        try:
            configs.append(_load(job, job_dir=job_dir))
        except TavcError as error:
            raise TavcError(f"job {index} ({' '.join(job)}): {error}") from None
    return configs


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


def to_yaml(cfg: DictConfig) -> str:
    """Render a config as YAML.

    Args:
        cfg: A config from ``load_config``.

    Returns:
        The YAML text, interpolations resolved.
    """
    return OmegaConf.to_yaml(cfg, resolve=True)


def to_container(cfg: DictConfig) -> dict:
    """Convert a config to plain, picklable Python dicts and lists.

    Args:
        cfg: A config from ``load_config``.

    Returns:
        A nested dict of builtin types.
    """
    return OmegaConf.to_container(cfg, resolve=True, throw_on_missing=True)


# --------------------------------------------------------------------------------------------
# Composition and Hydra/OmegaConf error translation
# --------------------------------------------------------------------------------------------


def _load(overrides: Sequence[str], *, job_dir: Optional[str] = None) -> DictConfig:
    """Compose, check, resolve and freeze one config (no sweeps)."""
    cfg = _compose(overrides)
    try:
        _check_no_missing(cfg)
        _validate_scaling(cfg)
        _resolve(cfg, job_dir=job_dir)
        _validate(cfg)
    except OmegaConfBaseException as error:
        raise TavcError(_omegaconf_message(error)) from None
    OmegaConf.set_readonly(cfg, True)
    return cfg


def _compose(overrides: Sequence[str]) -> DictConfig:
    """Compose ``config.yaml`` with overrides and return it typed against ``TavcConfig``.

    Only the compose API is used, never ``@hydra.main``: Hydra's own error reporting (and its
    ``HYDRA_FULL_ERROR`` traceback switch) is never involved, and every failure surfaces here
    as an exception that becomes one ``TavcError`` line.
    """
    ConfigStore.instance().store(name=SCHEMA_NAME, node=TavcConfig)
    try:
        with initialize_config_dir(
            config_dir=str(find_conf_dir()), version_base="1.3", job_name="tavc"
        ):
            cfg = compose(config_name="config", overrides=list(overrides))
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
    return _typed(cfg)


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


# --------------------------------------------------------------------------------------------
# Resolution
# --------------------------------------------------------------------------------------------


def _resolve(cfg: DictConfig, *, job_dir: Optional[str] = None) -> None:
    """Fill every derived value in place (rules in the module docstring)."""
    factor = cfg.scale.time_factor
    if cfg.trials is None:
        cfg.trials = _capped(cfg.paper.trials, cfg.scale.trials)
    if cfg.baseline_trials is None:
        paper_baseline = cfg.paper.baseline_trials
        cfg.baseline_trials = (
            cfg.trials if paper_baseline is None else _capped(paper_baseline, cfg.scale.trials)
        )
    if cfg.duration_s is None:
        cfg.duration_s = cfg.paper.duration_s * factor
    if cfg.convergence_s is None:
        cfg.convergence_s = cfg.paper.convergence_s * factor
    # Warm-up and event times scale with the experiment, even when set by hand, so that a
    # quick run keeps the paper run's shape (a breakdown a third of the way in stays there).
    cfg.sim.warmup_s = cfg.sim.warmup_s * factor
    for event in [*cfg.events.breakdowns, *cfg.events.value_changes]:
        event.time_s = event.time_s * factor
    base_dir = cfg.output_dir if cfg.output_dir is not None else f"results/{cfg.experiment_name}"
    cfg.output_dir = str(Path(base_dir) / job_dir) if job_dir else base_dir
    if cfg.team.members is None and cfg.team.n_robots >= 1:
        speed_mps = cfg.robot.speed_mps
        cfg.team.members = [MemberConfig(speed_mps=speed_mps) for _ in range(cfg.team.n_robots)]
    # ``values`` is read by subscript: on a DictConfig, ``.values`` is the dict method.
    if cfg.tasks["values"] is None:
        cfg.tasks["values"] = [1.0] * len(cfg.arena.circuits)
    if cfg.tasks.score_values is None:
        cfg.tasks.score_values = list(cfg.tasks["values"])
    if cfg.executor.n_jobs is None:
        cfg.executor.n_jobs = os.cpu_count() or 1


def _capped(count: int, cap: Optional[int]) -> int:
    """``count``, limited to ``cap`` when the scale sets one."""
    return count if cap is None else min(cap, count)


# --------------------------------------------------------------------------------------------
# Validation: each check raises TavcError("<key>: <problem>")
# --------------------------------------------------------------------------------------------


def _fail(key: str, problem: str) -> NoReturn:
    raise TavcError(f"{key}: {problem}")


def _check(ok: bool, key: str, problem: str) -> None:
    if not ok:
        _fail(key, problem)


def _positive(key: str, value: float) -> None:
    _check(math.isfinite(value) and value > 0, key, f"must be > 0, got {value!r}")


def _at_least(key: str, value: float, low: float) -> None:
    _check(math.isfinite(value) and value >= low, key, f"must be >= {low}, got {value!r}")


def _unit(key: str, value: float) -> None:
    _check(0 <= value <= 1, key, f"must be in [0, 1], got {value!r}")


def _angle(key: str, value: float, high: float) -> None:
    _check(0 < value <= high, key, f"must be in (0, {high:g}], got {value!r}")


def _one_of(key: str, value: Any, choices: Sequence[str]) -> None:
    _check(value in choices, key, f"must be one of {', '.join(choices)}; got {value!r}")


def _per_circuit(key: str, values: Sequence[Any], n_circuits: int, what: str) -> None:
    _check(
        len(values) == n_circuits,
        key,
        f"needs one {what} per circuit ({n_circuits}), got {len(values)}",
    )


def _unique(key: str, values: Sequence[Any], what: str) -> None:
    seen = set()
    for value in values:
        _check(value not in seen, key, f"{what} {value!r} appears more than once")
        seen.add(value)


def _check_no_missing(cfg: DictConfig) -> None:
    """Every ``???`` in the schema must have been filled by a config file or override."""
    missing = sorted(OmegaConf.missing_keys(cfg))
    if missing:
        _fail(missing[0], "missing value (set it in its config file or on the command line)")


def _validate_scaling(cfg: DictConfig) -> None:
    """Check what resolution derives values from, so errors name the key the user set."""
    _positive("scale.time_factor", cfg.scale.time_factor)
    if cfg.scale.trials is not None:
        _at_least("scale.trials", cfg.scale.trials, 1)
    paper = cfg.paper
    _at_least("paper.trials", paper.trials, 1)
    if paper.baseline_trials is not None:
        _at_least("paper.baseline_trials", paper.baseline_trials, 1)
    _positive("paper.duration_s", paper.duration_s)
    _check(
        0 <= paper.convergence_s < paper.duration_s,
        "paper.convergence_s",
        f"must be in [0, paper.duration_s = {paper.duration_s:g}), got {paper.convergence_s!r}",
    )


def _validate(cfg: DictConfig) -> None:
    """Validate a resolved config."""
    _validate_arena(cfg.arena)
    _validate_robot(cfg.robot)
    _validate_team(cfg.team)
    n_circuits, n_robots = len(cfg.arena.circuits), cfg.team.n_robots
    _validate_learner(cfg.learner, n_circuits, n_robots)
    _validate_run(cfg)
    if cfg.static_allocation is not None:
        _validate_allocation("static_allocation", cfg.static_allocation, n_circuits, n_robots)
    _validate_tasks(cfg.tasks, n_circuits)
    _validate_events(cfg, n_circuits)
    _validate_sim(cfg.sim)
    _validate_executor(cfg.executor)
    _one_of("analysis.state", cfg.analysis.state, ANALYSIS_STATES)
    _positive("analysis.performance_bin_s", cfg.analysis.performance_bin_s)
    _validate_model(cfg.model)


def _validate_model(model: DictConfig) -> None:
    """Measurement settings of the TAVC model."""
    _at_least("model.trials_per_split", model.trials_per_split, 2)
    _at_least("model.warmup_s", model.warmup_s, 0)
    _positive("model.measure_s", model.measure_s)
    _check(0 < model.confidence < 1, "model.confidence", f"must be in (0, 1), got {model.confidence!r}")
    if model.max_robots is not None:
        _at_least("model.max_robots", model.max_robots, 1)


def _validate_arena(arena: DictConfig) -> None:
    """Walls, targets on walls, circuits between existing sources and sinks."""
    _positive("arena.width_m", arena.width_m)
    _positive("arena.height_m", arena.height_m)
    _positive("arena.barcode_width_m", arena.barcode_width_m)
    for index, wall in enumerate(arena.walls):
        _validate_wall(f"arena.walls[{index}]", wall, arena)
    for index, target in enumerate(arena.targets):
        _validate_target(f"arena.targets[{index}]", target, arena)
    _unique("arena.targets", [target.name for target in arena.targets], "name")
    _unique("arena.targets", [target.barcode for target in arena.targets], "barcode")
    _check(len(arena.circuits) >= 1, "arena.circuits", "needs at least one circuit")
    _unique("arena.circuits", [circuit.name for circuit in arena.circuits], "name")
    kinds = {target.name: target.kind for target in arena.targets}
    for index, circuit in enumerate(arena.circuits):
        for end in ("source", "sink"):
            key, name = f"arena.circuits[{index}].{end}", circuit[end]
            _check(name in kinds, key, f"no target named {name!r} in arena.targets")
            _check(kinds[name] == end, key, f"target {name!r} is a {kinds[name]}, not a {end}")


def _arena_size(arena: DictConfig) -> str:
    return f"the {arena.width_m:g} x {arena.height_m:g} m arena"


def _validate_target(key: str, target: DictConfig, arena: DictConfig) -> None:
    """A target lies on one of the four walls: its bar-code is mounted there."""
    _one_of(f"{key}.kind", target.kind, TARGET_KINDS)
    _at_least(f"{key}.barcode", target.barcode, 0)
    x, y, width, height = target.x, target.y, arena.width_m, arena.height_m
    where = f"target ({x!r}, {y!r})"
    for axis, value, size in (("x", x, width), ("y", y, height)):
        inside = -WALL_TOLERANCE_M <= value <= size + WALL_TOLERANCE_M
        _check(inside, f"{key}.{axis}", f"{where} lies outside {_arena_size(arena)}")
    gap_m = min(abs(x), abs(x - width), abs(y), abs(y - height))
    _check(
        gap_m <= WALL_TOLERANCE_M,
        key,
        f"{where} is not on a wall of {_arena_size(arena)} (bar-codes are mounted on walls)",
    )


def _validate_wall(key: str, wall: Sequence[float], arena: DictConfig) -> None:
    """An interior wall ``[x1, y1, x2, y2]`` lies inside the arena and has a length."""
    shape_ok = OmegaConf.is_list(wall) and len(wall) == 4
    numbers_ok = shape_ok and all(
        isinstance(v, (int, float)) and not isinstance(v, bool) for v in wall
    )
    _check(numbers_ok, key, f"a wall is [x1, y1, x2, y2] in metres, got {_plain(wall)!r}")
    sizes = (arena.width_m, arena.height_m) * 2
    for index, (value, size) in enumerate(zip(wall, sizes, strict=True)):
        problem = f"{value!r} lies outside {_arena_size(arena)}"
        _check(0 <= value <= size, f"{key}[{index}]", problem)
    _check(tuple(wall[:2]) != tuple(wall[2:]), key, "a wall needs two distinct end points")


def _plain(value: Any) -> Any:
    """A config node as builtin types, for messages."""
    return OmegaConf.to_container(value) if OmegaConf.is_config(value) else value


def _validate_robot(robot: DictConfig) -> None:
    """Body, drive and sensors."""
    body = (
        "radius_m",
        "mass_kg",
        "speed_mps",
        "turn_rate_radps",
        "drive_force_n",
        "drive_torque_nm",
    )
    for name in body:
        _positive(f"robot.{name}", robot[name])
    _at_least("robot.laser.n_rays", robot.laser.n_rays, 1)
    _angle("robot.laser.fov_deg", robot.laser.fov_deg, 360.0)
    _positive("robot.laser.range_m", robot.laser.range_m)
    _angle("robot.camera.fov_deg", robot.camera.fov_deg, 360.0)
    _positive("robot.camera.range_m", robot.camera.range_m)
    _angle("robot.camera.side_sector_deg", robot.camera.side_sector_deg, 180.0)
    for name, value in robot.odometry.items():
        _at_least(f"robot.odometry.{name}", value, 0)
    for name in ("avoid_dist_m", "arrive_dist_m", "wall_dist_m", "relocalise_dist_m", "stall_s", "escape_s",
                 "progress_m"):
        _positive(f"robot.behaviour.{name}", robot.behaviour[name])
    for name in ("stop_dist_m", "visible_margin_m"):
        _at_least(f"robot.behaviour.{name}", robot.behaviour[name], 0)
    _check(robot.behaviour.avoid_dist_m > robot.behaviour.stop_dist_m, "robot.behaviour.avoid_dist_m",
           f"must exceed robot.behaviour.stop_dist_m ({robot.behaviour.stop_dist_m:g}), "
           f"got {robot.behaviour.avoid_dist_m:g}")


def _validate_team(team: DictConfig) -> None:
    """Team size, and members matching it."""
    _at_least("team.n_robots", team.n_robots, 1)
    _check(
        len(team.members) == team.n_robots,
        "team.n_robots",
        f"{team.n_robots} does not match the {len(team.members)} robots listed in team.members",
    )
    for index, member in enumerate(team.members):
        _positive(f"team.members[{index}].speed_mps", member.speed_mps)
        _check(bool(member.group), f"team.members[{index}].group", "must not be empty")


def _validate_learner(learner: DictConfig, n_circuits: int, n_robots: int) -> None:
    """Learner name and Q-learning parameters."""
    _one_of("learner.name", learner.name, LEARNERS)
    _check(learner.name in AVAILABLE_LEARNERS, "learner.name",
           f"'{learner.name}' is not available in this version; use one of {', '.join(AVAILABLE_LEARNERS)}")
    for name in ("alpha", "gamma", "epsilon"):
        _unit(f"learner.{name}", learner[name])
    _positive("learner.tau", learner.tau)
    _check(
        learner.q_init_low <= learner.q_init_high,
        "learner.q_init_low",
        f"must be <= learner.q_init_high ({learner.q_init_high!r}), got {learner.q_init_low!r}",
    )
    if learner.allocation is not None:
        _validate_allocation("learner.allocation", learner.allocation, n_circuits, n_robots)


def _validate_allocation(
    key: str, allocation: Sequence[int], n_circuits: int, n_robots: int
) -> None:
    """Robots per circuit: one non-negative count per circuit, summing to the team size."""
    _per_circuit(key, allocation, n_circuits, "robot count")
    for index, count in enumerate(allocation):
        _at_least(f"{key}[{index}]", count, 0)
    _check(
        sum(allocation) == n_robots,
        key,
        f"must sum to team.n_robots ({n_robots}), got {sum(allocation)}",
    )


def _validate_run(cfg: DictConfig) -> None:
    """Seed, trial counts, durations, baselines, output folder."""
    _at_least("seed", cfg.seed, 0)
    _at_least("trials", cfg.trials, 1)
    _at_least("baseline_trials", cfg.baseline_trials, 1)
    _positive("duration_s", cfg.duration_s)
    _check(
        0 <= cfg.convergence_s < cfg.duration_s,
        "convergence_s",
        f"must be in [0, duration_s = {cfg.duration_s:g}), got {cfg.convergence_s!r}",
    )
    for index, baseline in enumerate(cfg.baselines):
        _one_of(f"baselines[{index}]", baseline, BASELINES)
    _unique("baselines", list(cfg.baselines), "controller")
    _check(bool(cfg.output_dir), "output_dir", "must not be empty")


def _validate_tasks(tasks: DictConfig, n_circuits: int) -> None:
    """One learning value and one score value per circuit."""
    for name in ("values", "score_values"):
        key = f"tasks.{name}"
        _per_circuit(key, tasks[name], n_circuits, "value")
        for index, value in enumerate(tasks[name]):
            problem = f"must be a finite number, got {value!r}"
            _check(math.isfinite(value), f"{key}[{index}]", problem)
    _one_of("tasks.time_unit", tasks.time_unit, TIME_UNITS)


def _validate_events(cfg: DictConfig, n_circuits: int) -> None:
    """Scheduled breakdowns and value changes fall inside the simulated time."""
    n_robots = cfg.team.n_robots
    breakdowns = cfg.events.breakdowns
    _check(
        len(breakdowns) < n_robots,
        "events.breakdowns",
        f"{len(breakdowns)} breakdowns would leave none of the {n_robots} robots running",
    )
    for index, breakdown in enumerate(breakdowns):
        key = f"events.breakdowns[{index}]"
        _validate_event_time(f"{key}.time_s", breakdown.time_s, cfg)
        _validate_breakdown_target(key, breakdown, n_robots, n_circuits)
    robots = [breakdown.robot for breakdown in breakdowns if breakdown.robot is not None]
    _unique("events.breakdowns", robots, "robot")
    for index, change in enumerate(cfg.events.value_changes):
        key = f"events.value_changes[{index}]"
        _validate_event_time(f"{key}.time_s", change.time_s, cfg)
        _per_circuit(f"{key}.values", change["values"], n_circuits, "value")


def _validate_event_time(key: str, time_s: float, cfg: DictConfig) -> None:
    """Events happen between the start of the warm-up (negative time) and the end of a trial."""
    start_s = 0.0 - cfg.sim.warmup_s  # not -warmup_s: that prints "-0" when there is none
    _check(
        start_s <= time_s < cfg.duration_s,
        key,
        f"{time_s:g} s (after scaling) is outside the simulated time "
        f"[-sim.warmup_s = {start_s:g}, duration_s = {cfg.duration_s:g})",
    )


def _validate_breakdown_target(
    key: str, breakdown: DictConfig, n_robots: int, n_circuits: int
) -> None:
    """A breakdown names a robot, a circuit (high, low or an index), or neither (random robot)."""
    if breakdown.robot is not None:
        _check(
            0 <= breakdown.robot < n_robots,
            f"{key}.robot",
            f"must be a robot index in [0, {n_robots}), got {breakdown.robot!r}",
        )
        _check(breakdown.circuit is None, key, "give robot or circuit, not both")
    circuit = breakdown.circuit
    if circuit is None or circuit in ("high", "low"):
        return
    _check(
        circuit.isdigit() and int(circuit) < n_circuits,
        f"{key}.circuit",
        f"must be null, high, low or a circuit index in [0, {n_circuits}), got {circuit!r}",
    )


def _validate_sim(sim: DictConfig) -> None:
    """Simulator timing."""
    _positive("sim.dt_s", sim.dt_s)
    _at_least("sim.physics_substeps", sim.physics_substeps, 1)
    _at_least("sim.solver_iterations", sim.solver_iterations, 1)
    _at_least("sim.q_snapshot_every_s", sim.q_snapshot_every_s, 0)
    _at_least("sim.pose_every_s", sim.pose_every_s, 0)
    _at_least("sim.warmup_s", sim.warmup_s, 0)


def _validate_executor(executor: DictConfig) -> None:
    """Backend and parallelism."""
    _one_of("executor.backend", executor.backend, BACKENDS)
    _check(executor.backend in AVAILABLE_BACKENDS, "executor.backend",
           f"'{executor.backend}' is not available in this version; use 'local'")
    _at_least("executor.n_jobs", executor.n_jobs, 1)
    _at_least("executor.batch_size", executor.batch_size, 1)
    _check(executor.batch_size <= 32, "executor.batch_size",
           f"must be at most 32 (one collision-filter bit per trial), got {executor.batch_size}")
