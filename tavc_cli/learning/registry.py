"""Every learner tavc knows, in one table: the name a config gives (`learner.name`,
`baselines`), the controller label its trials carry in every output, the code that enters
each trial's seed, and how its policy is built.

Adding a built-in learner is adding one entry here. A seed code is part of every trial's seed
and key: changing one reruns (and changes) every trial of that learner.

A learner from outside tavc is a class named by ``learner.target`` (``package.module.Class``,
or ``path/to/file.py:Class``), built with ``learner.params`` as keyword arguments beside
``n_robots``, ``n_circuits`` and ``rng`` (`plugin_policy`): its label is its ``learner.name``,
its seed code one drawn from that name (`seed_code`); `learning.plugins` loads, builds and
guards it. docs/plugins.md shows one.
"""

from __future__ import annotations

import zlib
from collections.abc import Callable, Mapping
from dataclasses import dataclass

import numpy as np

from tavc_cli.learning.behaviour import BehaviourPolicy
from tavc_cli.learning.informed import MODEL_LEARNERS, InformedPolicy, ModelPolicy
from tavc_cli.learning.literature import ThresholdPolicy, WolfPhcPolicy
from tavc_cli.learning.plugins import plugin_policy
from tavc_cli.learning.policies import (
    AlternatePolicy,
    RandomPolicy,
    StaticPolicy,
    TaskPolicy,
    TavcPolicy,
    alternate_roles,
    even_allocation,
)
from tavc_cli.settings import LearnerConfig

Builder = Callable[[Mapping, int, int, np.random.Generator], TaskPolicy]


@dataclass(frozen=True)
class Learner:
    """A learner tavc knows: its config name, the label of its trials, its seed code and its
    builder."""
    name: str
    label: str
    seed_code: int
    build: Builder | None  # None: named by the chapter but not built in this version
    baseline: bool = False  # may run beside the main learner (`baselines: [...]`)


def _random(spec: LearnerConfig, n_robots: int, n_circuits: int, rng: np.random.Generator) -> TaskPolicy:
    return RandomPolicy(n_circuits, rng)


def _static(spec: LearnerConfig, n_robots: int, n_circuits: int, rng: np.random.Generator) -> TaskPolicy:
    counts = spec.allocation or even_allocation(n_robots, n_circuits)
    return StaticPolicy(np.repeat(np.arange(n_circuits), counts), n_circuits)


def _alternate(spec: LearnerConfig, n_robots: int, n_circuits: int, rng: np.random.Generator) -> TaskPolicy:
    roles = spec.roles if spec.roles is not None else alternate_roles(spec.allocation, n_robots)
    return AlternatePolicy(roles, n_circuits)


def _wolf_phc(spec: LearnerConfig, n_robots: int, n_circuits: int, rng: np.random.Generator) -> TaskPolicy:
    return WolfPhcPolicy(n_robots, n_circuits, alpha=float(spec.alpha), gamma=float(spec.gamma),
                         epsilon=float(spec.epsilon), delta_win=float(spec.delta_win),
                         delta_lose=float(spec.delta_lose), rng=rng)


def _threshold(spec: LearnerConfig, n_robots: int, n_circuits: int, rng: np.random.Generator) -> TaskPolicy:
    return ThresholdPolicy(n_robots, n_circuits, alpha=float(spec.alpha), theta_low=float(spec.theta_low),
                           theta_high=float(spec.theta_high), steepness=float(spec.steepness), rng=rng)


def _model(informed: bool) -> Builder:
    def build(spec: LearnerConfig, n_robots: int, n_circuits: int, rng: np.random.Generator) -> TaskPolicy:
        cls = InformedPolicy if informed else ModelPolicy
        return cls(spec.allocations or {}, n_robots, n_circuits, rng)

    return build


def _q_learning(spec: LearnerConfig) -> dict:
    """The Q-learning parameters every learner of the chapter shares."""
    return {"alpha": float(spec.alpha), "gamma": float(spec.gamma), "tau": float(spec.tau),
            "q_init": (float(spec.q_init_low), float(spec.q_init_high))}


def _tavc(selection: str) -> Builder:
    def build(spec: LearnerConfig, n_robots: int, n_circuits: int, rng: np.random.Generator) -> TaskPolicy:
        return TavcPolicy(n_robots, n_circuits, selection=selection, epsilon=float(spec.epsilon),
                          rng=rng, **_q_learning(spec))

    return build


def _behaviour(spec: LearnerConfig, n_robots: int, n_circuits: int, rng: np.random.Generator) -> TaskPolicy:
    return BehaviourPolicy(n_robots, n_circuits, decision_period_s=float(spec.decision_period_s),
                           decide_on_change=bool(spec.decide_on_change), rng=rng, **_q_learning(spec))


LEARNERS: dict[str, Learner] = {entry.name: entry for entry in (
    Learner("random", "random", 1, _random, baseline=True),
    Learner("static", "static", 2, _static, baseline=True),
    Learner("alternate", "alternate", 4, _alternate, baseline=True),
    Learner("wolf_phc", "wolf_phc", 5, _wolf_phc),
    Learner("threshold", "threshold", 6, _threshold),
    Learner("model", "model", 7, _model(informed=False)),
    Learner("informed", "informed", 8, _model(informed=True)),
    Learner("tavc_egreedy", "tavc", 0, _tavc("egreedy")),
    Learner("tavc_softmax", "tavc", 0, _tavc("softmax")),
    Learner("behaviour_softmax", "behaviour", 3, _behaviour),
)}
NAMES = tuple(LEARNERS)
AVAILABLE = tuple(name for name, entry in LEARNERS.items() if entry.build is not None)
BASELINES = tuple(name for name, entry in LEARNERS.items() if entry.baseline)
LEARNS_NOTHING = (*BASELINES, *MODEL_LEARNERS)  # fixed controllers: their distribution has no horizon
SEED_CODES = {entry.label: entry.seed_code for entry in LEARNERS.values()}
# labels tavc's tables give rows that are no learner's trials (`state_time.csv`'s model row)
RESERVED_LABELS = ("theory",)


def controller_label(name: str) -> str:
    """The label a learner's trials carry in outputs (`tavc`, `random`, `static`, `behaviour`,
    `alternate`; a learner from outside tavc: its name)."""
    entry = LEARNERS.get(name)
    return entry.label if entry is not None else name


def seed_code(label: str) -> int:
    """The code a controller's label puts in its trials' seeds: the built-in ones' (`SEED_CODES`),
    else one drawn from the label itself (the same label, the same seeds, on every machine)."""
    code = SEED_CODES.get(label)
    return code if code is not None else 1000 + zlib.crc32(label.encode()) % 1_000_000


def make_policy(spec: LearnerConfig, n_robots: int, n_circuits: int, rng: np.random.Generator) -> TaskPolicy:
    """Build the policy named by `spec.name` (or `spec.target`) with its settings."""
    if getattr(spec, "target", None):
        return plugin_policy(spec, n_robots, n_circuits, rng)
    entry = LEARNERS.get(spec.name)
    if entry is None or entry.build is None:
        raise ValueError(f"no task policy named {spec.name!r}")
    return entry.build(spec, n_robots, n_circuits, rng)
