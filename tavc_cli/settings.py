"""The settings every command runs on: one typed dataclass per config group.

The config package composes and validates them with Hydra (registered in its ConfigStore, they
make a misspelled key or a wrong type fail at compose time; the learner's node when its own
settings class reads it, before anything runs) and hands the library a `TavcConfig`, whose
attributes everything below the CLI reads. `from_yaml` reads a run's ``config.yaml`` back."""

from dataclasses import dataclass, field, fields
from functools import cache
from pathlib import Path
from typing import Any, Dict, List, Optional

import yaml
from omegaconf import MISSING, OmegaConf
from omegaconf._utils import get_omega_conf_dumper, get_yaml_loader
from omegaconf.errors import OmegaConfBaseException

from tavc_cli.dotted import plain
from tavc_cli.errors import TavcError
from tavc_cli.learning.parameters import LearnerSettings, PluginSettings, recorded_learner
from tavc_cli.learning.registry import SETTINGS
from tavc_cli.readers import load_yaml
from tavc_cli.settings_studies import CalibrationConfig, GridAxis, ModelConfig, SurrogateConfig  # noqa: F401 (groups)
from tavc_cli.typed_data import DECLINED, exact

SCHEMA_NAME = "tavc_schema"
AVAILABLE_BACKENDS = ("local", "ray", "dask")
BACKENDS = ("local", "ray", "dask")
ANALYSIS_STATES = ("circuits", "groups")
# scale.stable_window: the whole stable period, or its last stretch of the chapter's length
STABLE_WINDOWS = ("whole", "chapter")
TARGET_KINDS = ("source", "sink")
TIME_UNITS = ("s", "ms")
WALL_TOLERANCE_M = 1e-6  # a target must sit on a wall (bar-codes are mounted on walls): how close counts as on
MIN_DOCK_CLEARANCE_M = 0.03  # a docked robot's front stays at least this far from the wall


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
    arrive_dist_m: float = 0.30
    # readings of what the chapter leaves unsaid (conf/arrival/, conf/passing/; docs/readings.md):
    # arrival `dock` (into the dock spot) or `range` (on reading the code within read_range_m);
    # passing `nearest` (the free heading nearest the goal's), `left` or `right` (that side first)
    arrival: str = "dock"
    read_range_m: float = 1.5
    passing: str = "nearest"
    wall_dist_m: float = 0.5
    visible_margin_m: float = 0.5
    relocalise_dist_m: float = 2.0
    stall_s: float = 20.0
    progress_m: float = 0.3
    escape_s: float = 15.0


@dataclass
class DockConfig:
    """How a robot serves a source or sink: at the dock spot in front of the bar-code."""

    lateral_tol_m: float = 0.1
    heading_tol_deg: float = 20.0
    approach_m: float = 0.8
    dwell_s: float = 0.0
    backout_m: float = 0.4
    occupied_m: float = 0.6
    hold_margin_m: float = 0.6
    patience_s: float = 90.0


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
    dock: DockConfig = field(default_factory=DockConfig)


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


def _learner_node() -> dict:
    """The ``learner:`` node before a learner group fills it: the slots of a learner from outside
    tavc (so that ``learner.target=...`` and ``learner.params`` need no ``+``); every other key is
    the chosen learner's own, declared by its settings class (`learning.parameters`)."""
    return {"name": "random", "target": None, "params": {}}


@dataclass
class ScaleConfig:
    """How much of the chapter's trials and simulated time to run."""

    name: str = "paper"
    trials: Optional[int] = None
    time_factor: float = 1.0
    # section 1.4's trials end with a number of deliveries: that count's factor (null = time_factor)
    deliveries_factor: Optional[float] = None
    # the baselines' (random, static) schedule: every time of theirs at this factor of the chapter's
    # instead of time_factor (null = time_factor); they learn nothing, so no horizon moves them
    baseline_time_factor: Optional[float] = None
    # the window the stable period's shares and rates are measured over: `whole`, the whole
    # stable period, or `chapter`, its last stretch as long as the chapter's stable period, so
    # that spreads over trials are compared over windows of equal length at every horizon
    stable_window: str = "whole"


@dataclass
class ExecutorConfig:
    """Where trials run."""

    backend: str = "local"
    n_jobs: Optional[int] = None
    batch_size: int = 8
    address: Optional[str] = None
    confine: str = "auto"  # hold a learner from outside tavc to its run's folder: auto, on or off (`confine`)


@dataclass
class PaperConfig:
    """The chapter-scale trial count and durations of an experiment."""

    trials: int = 20
    duration_s: float = 3600.0
    convergence_s: float = 900.0
    baseline_trials: Optional[int] = None
    static_trials: Optional[int] = None  # the static baseline's, where the chapter ran it apart
    # a trial the chapter measures in deliveries (section 1.4: 1000 traversals of the group)
    # ends with the tick of its robots' n-th delivery after the warm-up; duration_s caps it
    deliveries: Optional[int] = None


@dataclass
class TasksConfig:
    """Task values per circuit.

    On a ``DictConfig`` read ``tasks["values"]``: ``tasks.values`` is the dict method.
    """

    values: Optional[List[float]] = None
    score_values: Optional[List[float]] = None
    time_unit: str = "ms"
    # a reading of "the last task processing time" (conf/reward_time/): from the robot's choice at the
    # sink, the empty leg included (choice), or from its loading at the source (source)
    time_from: str = "choice"


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
    before_s: Optional[float] = None


@dataclass
class TavcConfig:
    """The whole configuration, as composed from conf/config.yaml."""

    arena: ArenaConfig = field(default_factory=ArenaConfig)
    robot: RobotConfig = field(default_factory=RobotConfig)
    team: TeamConfig = field(default_factory=TeamConfig)
    # the chosen learner's settings: composed as an open node, read into the class the learner
    # declares (`learning.parameters`), which refuses any key it does not take
    learner: Dict[str, Any] = field(default_factory=_learner_node)
    scale: ScaleConfig = field(default_factory=ScaleConfig)
    executor: ExecutorConfig = field(default_factory=ExecutorConfig)
    experiment_name: str = "default"
    section: str = ""
    description: str = ""
    seed: int = 0
    trials: Optional[int] = None
    baseline_trials: Optional[int] = None
    static_trials: Optional[int] = None
    duration_s: Optional[float] = None
    convergence_s: Optional[float] = None
    deliveries: Optional[int] = None
    baseline_lead_s: Optional[float] = None
    output_dir: Optional[str] = None
    overwrite: bool = False
    # run what is estimated to take more than a day (config/limits.py); what could never run is refused even so
    force: bool = False
    paper: PaperConfig = field(default_factory=PaperConfig)
    baselines: List[str] = field(default_factory=list)
    static_allocation: Optional[List[int]] = None
    tasks: TasksConfig = field(default_factory=TasksConfig)
    events: EventsConfig = field(default_factory=EventsConfig)
    sim: SimConfig = field(default_factory=SimConfig)
    analysis: AnalysisConfig = field(default_factory=AnalysisConfig)
    model: ModelConfig = field(default_factory=ModelConfig)
    calibration: CalibrationConfig = field(default_factory=CalibrationConfig)
    surrogate: SurrogateConfig = field(default_factory=SurrogateConfig)

    def __post_init__(self) -> None:
        """The learner's node read into its typed settings (`settings_of`)."""
        self.learner = settings_of(self.learner)


def settings_of(node: Any) -> LearnerSettings:
    """The typed settings of a ``learner:`` node (a mapping, or settings already typed), read into
    the class its name gives in the registry (`registry.SETTINGS`), or `PluginSettings` where it
    names a ``target``.

    A key the learner does not declare, a missing name and a value of the wrong type are one
    `TavcError` line naming the key. The config's slots ``target: null`` and ``params: {}`` (kept
    so that ``learner.target=...`` needs no ``+``) belong to no built-in learner and are dropped.
    """
    if isinstance(node, LearnerSettings):
        return node
    data = dict(node)
    name = data.get("name")
    if not isinstance(name, str) or not name:
        raise TavcError(f"learner.name: a learner needs a name, got {name!r}")
    if data.get("target") is not None:
        cls: type[LearnerSettings] = PluginSettings
    else:
        params = data.pop("params", None)
        if params:
            raise TavcError("learner.params: only a learner from learner.target takes params; "
                            f"set {name}'s parameters as learner.<name>")
        data.pop("target", None)
        if name not in SETTINGS:
            raise TavcError(f"learner.name: must be one of {', '.join(SETTINGS)}; got {name!r}")
        cls = SETTINGS[name]
    declared = [f.name for f in fields(cls)]
    for key in data:
        if key not in declared:
            takes = ", ".join(p for p in declared if p != "name") or "no parameters"
            raise TavcError(f"learner.{key}: the learner {name} takes no parameter {key} (it takes {takes})")
    try:  # values of their fields' types already read without OmegaConf (`typed_data.exact`), else as it reads them
        return fast if (fast := exact(cls, data)) is not DECLINED else from_mapping(cls, data)
    except OmegaConfBaseException as error:
        key = getattr(error, "key", None) or "name"
        raise TavcError(f"learner.{key}: {str(error).splitlines()[0]}") from None



def to_yaml(settings: TavcConfig) -> str:
    """The settings as the YAML ``config.yaml`` holds: OmegaConf's text, its dumper on `dotted.plain`'s data."""
    return yaml.dump(plain(settings), Dumper=get_omega_conf_dumper(), default_flow_style=False, allow_unicode=True,
                     sort_keys=False)


def from_yaml(path: Path) -> TavcConfig:
    """A results folder's ``config.yaml`` read back as typed settings."""
    data = load_yaml(path, loader=get_yaml_loader())  # as `OmegaConf.load` reads it, bounded as a run's files are
    if data is not None and not isinstance(data, (list, dict, str)):
        raise OSError(f"Invalid loaded object type: {type(data).__name__}")
    if isinstance(data, dict) and isinstance(data.get("learner"), dict):
        data["learner"] = recorded_learner(data["learner"], SETTINGS)
    fast = exact(TavcConfig, data)  # what tavc wrote is of its fields' types already; else OmegaConf decides
    if fast is not DECLINED:
        return fast
    return from_mapping(TavcConfig, OmegaConf.create() if data is None else OmegaConf.create(data))


def from_mapping(cls: type, data: Any) -> Any:
    """An instance of the settings dataclass ``cls`` from plain data (a dict, as YAML gives it),
    checked against its fields' types."""
    return OmegaConf.to_object(OmegaConf.merge(_schema(cls), data))


@cache
def _schema(cls: type) -> Any:
    """The typed, empty config of a settings dataclass (merging copies it: it stays empty)."""
    return OmegaConf.structured(cls)
