"""Every learner tavc knows, in one table: the name a config gives (`learner.name`,
`baselines`), the controller label its trials carry in every output, the code that enters
each trial's seed, and how its policy is built.

Adding a learner is adding one entry here. A seed code is part of every trial's seed and
key: changing one reruns (and changes) every trial of that learner.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass

import numpy as np

from tavc_cli.learning.behaviour import BehaviourPolicy
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
    Learner("tavc_egreedy", "tavc", 0, _tavc("egreedy")),
    Learner("tavc_softmax", "tavc", 0, _tavc("softmax")),
    Learner("behaviour_softmax", "behaviour", 3, _behaviour),
)}
NAMES = tuple(LEARNERS)
AVAILABLE = tuple(name for name, entry in LEARNERS.items() if entry.build is not None)
BASELINES = tuple(name for name, entry in LEARNERS.items() if entry.baseline)
SEED_CODES = {entry.label: entry.seed_code for entry in LEARNERS.values()}


def controller_label(name: str) -> str:
    """The label a learner's trials carry in outputs (`tavc`, `random`, `static`, `behaviour`)."""
    return LEARNERS[name].label


def make_policy(spec: LearnerConfig, n_robots: int, n_circuits: int, rng: np.random.Generator) -> TaskPolicy:
    """Build the policy named by `spec.name` with its settings."""
    entry = LEARNERS.get(spec.name)
    if entry is None or entry.build is None:
        raise ValueError(f"no task policy named {spec.name!r}")
    return entry.build(spec, n_robots, n_circuits, rng)
