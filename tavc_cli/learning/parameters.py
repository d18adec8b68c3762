"""Each built-in learner's parameters, declared once as its own typed dataclass.

A learner's settings are the ``learner:`` node of a config: its ``name`` and the parameters its
class declares here, nothing else. The declaration is the whole of what tavc knows about them:
the config reads them into it (`settings.settings_of`, which refuses a key the learner does not
take and a value of the wrong type), `config.validate_learner` checks each field by the rule its
metadata names (`CHECK`) and each ordered pair in `ORDERED`, ``config.yaml`` writes them, and a
trial's key digests them. A learner from outside tavc declares its parameters by its class's
signature instead (`PluginSettings`, `plugins.check_params`).

This module imports nothing of tavc's and no library, so the settings can be read without
loading the simulator or the config's own machinery.
"""

from __future__ import annotations

from dataclasses import MISSING, asdict, dataclass, field, fields
from typing import Any, ClassVar, Dict, List, Optional

# the rules a field's metadata may name (`CHECK`), applied by `config.validate_learner`
UNIT = "unit"              # in [0, 1]
POSITIVE = "positive"      # finite and > 0
FINITE = "finite"          # a finite number
ALLOCATION = "allocation"  # robots per circuit, non-negative, summing to the team (null: even split)
STAYERS = "stayers"        # robots per circuit that stay, non-negative, at most the team
ROLES = "roles"            # one circuit per robot, or -1 to alternate
CHECK = "check"

# the discount the convergence measures use for a learner that declares none (the chapter's)
CHAPTER_GAMMA = 0.95


def _param(default: Any, check: Optional[str] = None) -> Any:
    """A parameter with its default and the rule it is checked by."""
    return field(default=default, metadata={CHECK: check})


@dataclass(frozen=True)
class LearnerSettings:
    """What every learner's settings hold: its name (`learning.registry`)."""

    name: str = "random"
    # (lower field, upper field, why the lower may not exceed the upper)
    ORDERED: ClassVar[tuple[tuple[str, str, str], ...]] = ()


@dataclass(frozen=True)
class RandomSettings(LearnerSettings):
    """`random`: a uniformly random circuit for every task; no parameters."""

    name: str = "random"


@dataclass(frozen=True)
class StaticSettings(LearnerSettings):
    """`static`: a fixed allocation, robots per circuit (null: an even split)."""

    name: str = "static"
    allocation: Optional[List[int]] = _param(None, ALLOCATION)


@dataclass(frozen=True)
class AlternateSettings(LearnerSettings):
    """`alternate`: `allocation` robots stay on each circuit (the first robots first) and the rest
    alternate; or `roles`, one per robot (a circuit, or -1 to alternate)."""

    name: str = "alternate"
    allocation: Optional[List[int]] = _param(None, STAYERS)
    roles: Optional[List[int]] = _param(None, ROLES)


_Q_ORDER = (("q_init_low", "q_init_high", "the initial Q-values are drawn from [q_init_low, q_init_high]"),)


@dataclass(frozen=True)
class TavcEgreedySettings(LearnerSettings):
    """`tavc_egreedy` (section 1.5.3): Q-learning over task classes, epsilon-greedy."""

    name: str = "tavc_egreedy"
    alpha: float = _param(0.1, UNIT)
    gamma: float = _param(0.95, UNIT)
    epsilon: float = _param(0.1, UNIT)
    q_init_low: float = _param(-0.1, FINITE)
    q_init_high: float = _param(0.1, FINITE)
    ORDERED: ClassVar = _Q_ORDER


@dataclass(frozen=True)
class TavcSoftmaxSettings(LearnerSettings):
    """`tavc_softmax` (section 1.6.1): as `tavc_egreedy`, Boltzmann selection at temperature `tau`."""

    name: str = "tavc_softmax"
    alpha: float = _param(0.1, UNIT)
    gamma: float = _param(0.95, UNIT)
    tau: float = _param(0.005, POSITIVE)
    q_init_low: float = _param(-0.1, FINITE)
    q_init_high: float = _param(0.1, FINITE)
    ORDERED: ClassVar = _Q_ORDER


@dataclass(frozen=True)
class BehaviourSettings(LearnerSettings):
    """`behaviour_softmax` (section 1.4): Q-learning over (sensed state, behaviour), softmax; the
    state read every `decision_period_s`, a behaviour chosen when it changed (`decide_on_change`)."""

    name: str = "behaviour_softmax"
    alpha: float = _param(0.1, UNIT)
    gamma: float = _param(0.95, UNIT)
    tau: float = _param(0.005, POSITIVE)
    q_init_low: float = _param(-0.1, FINITE)
    q_init_high: float = _param(0.1, FINITE)
    decision_period_s: float = _param(0.1, POSITIVE)
    decide_on_change: bool = _param(True)
    ORDERED: ClassVar = _Q_ORDER


@dataclass(frozen=True)
class WolfPhcSettings(LearnerSettings):
    """`wolf_phc` (Bowling and Veloso 2002): the policy's step while winning and while losing."""

    name: str = "wolf_phc"
    alpha: float = _param(0.1, UNIT)
    gamma: float = _param(0.95, UNIT)
    epsilon: float = _param(0.1, UNIT)
    delta_win: float = _param(0.01, UNIT)
    delta_lose: float = _param(0.04, UNIT)
    ORDERED: ClassVar = (("delta_win", "delta_lose", "WoLF learns fast when losing"),)


@dataclass(frozen=True)
class ThresholdSettings(LearnerSettings):
    """`threshold` (Bonabeau, Theraulaz and Deneubourg 1996): each robot's threshold drawn in
    [theta_low, theta_high], the response's steepness n."""

    name: str = "threshold"
    alpha: float = _param(0.1, UNIT)
    theta_low: float = _param(0.5, POSITIVE)
    theta_high: float = _param(1.5, POSITIVE)
    steepness: float = _param(2.0, POSITIVE)
    ORDERED: ClassVar = (("theta_low", "theta_high", "each robot's threshold is drawn from [theta_low, theta_high]"),)


@dataclass(frozen=True)
class ModelSettings(LearnerSettings):
    """`model`, `informed`: the model whose allocation they follow, read into `allocations` (robots
    per circuit by team size, the most valuable circuit first) when the config is resolved."""

    name: str = "model"
    model_file: str = _param("results/initial_distribution/model/model.json")
    allocations: Optional[Dict[str, List[int]]] = _param(None)


@dataclass(frozen=True)
class PluginSettings(LearnerSettings):
    """A learner from outside tavc: the class `target` names (``package.module.Class`` or
    ``path/to/file.py:Class``) and the keyword arguments `params` it is built with beside
    n_robots, n_circuits and rng (docs/plugins.md); `name` is its label."""

    target: str = ""
    params: Dict[str, Any] = field(default_factory=dict)


# every key a config.yaml's learner node has held: records written before each learner declared its
# own parameters list them all, whichever learner ran
RECORDED_KEYS = ("name", "alpha", "gamma", "epsilon", "tau", "q_init_low", "q_init_high", "decision_period_s",
                 "decide_on_change", "allocation", "delta_win", "delta_lose", "theta_low", "theta_high",
                 "steepness", "roles", "target", "params", "model_file", "allocations")


def recorded_learner(node: dict, classes: dict[str, type[LearnerSettings]]) -> dict:
    """A results folder's ``learner:`` node as the learner that ran declares it: a record that lists
    every learner's parameters (see `RECORDED_KEYS`) keeps the ones its built-in learner takes. Any
    other key stays, for `settings.settings_of` to refuse."""
    cls = classes.get(node.get("name")) if node.get("target") is None else None
    if cls is None:
        return node
    declared = {f.name for f in fields(cls)}
    return {k: v for k, v in node.items() if k in declared or k not in RECORDED_KEYS}


def settings_mapping(settings: LearnerSettings) -> dict:
    """The settings as the ``learner:`` node of ``config.yaml`` holds them: the name first, then
    the declared parameters in their order."""
    return asdict(settings)


def parameters(cls: type[LearnerSettings]) -> list[tuple[str, Any, Optional[str]]]:
    """(name, default, rule) of each parameter `cls` declares, its name left out."""
    out = []
    for f in fields(cls):
        if f.name == "name":
            continue
        default = f.default if f.default is not MISSING else f.default_factory()  # type: ignore[misc]
        out.append((f.name, default, f.metadata.get(CHECK)))
    return out
