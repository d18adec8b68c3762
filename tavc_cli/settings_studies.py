"""The settings of the commands that study the world rather than run an experiment: `tavc model`,
`tavc surrogate` and `tavc calibrate` (part of `settings.TavcConfig`, one dataclass per group)."""

from dataclasses import dataclass, field
from typing import Any, List, Optional

from omegaconf import MISSING


@dataclass
class ModelConfig:
    """How `tavc model` measures task-processing frequencies (times scale with `scale`)."""

    trials_per_split: int = 12
    warmup_s: float = 300.0
    measure_s: float = 3000.0
    confidence: float = 0.9
    max_robots: Optional[int] = None


ALTERNATORS, EXPLORERS = "alternators", "explorers"
SWITCHES = (ALTERNATORS, EXPLORERS)  # `surrogate.switches`: where a lone switcher's tasks come from


@dataclass
class SurrogateConfig:
    """`tavc surrogate`: the learners on tasks measured in the simulator (`tavc_cli.surrogate`)."""

    # where the measured tasks and the static trials that measured them are kept; null:
    # runs/<scale>/surrogate/tasks
    tasks_dir: Optional[str] = None
    trials_per_makeup: int = 4     # static trials per make-up of the group (capped by the scale)
    warmup_s: float = 300.0        # left out of each measurement; times shortened by a scale below 1
    measure_s: float = 3000.0
    calibration: str = "makeup"    # makeup: by stayers and alternators; stayers: by robots per circuit only
    # a lone switcher's tasks: alternators (a robot that alternates on every task), or explorers
    # (robots that keep to a home circuit and explore at epsilon; tavc_cli/surrogate/explorers.py)
    switches: str = ALTERNATORS
    explore_trials: int = 16       # the explorers' static trials per allocation of stayers (capped by the scale)
    explore_epsilon: Optional[float] = None  # their exploration rate; null: the learner's epsilon
    explore_min_tasks: int = 10    # a cell is drawn from the explorers' tasks where they have at least this many


@dataclass
class GridAxis:
    """One axis of the world search: a config key and the values it takes."""

    key: str = MISSING
    values: List[Any] = MISSING


@dataclass
class CalibrationConfig:
    """How `tavc calibrate` searches the reconstructed world (times scale with `scale`)."""

    trials_per_split: int = 6
    warmup_s: float = 300.0
    measure_s: float = 3000.0
    grid: List[GridAxis] = field(default_factory=list)
