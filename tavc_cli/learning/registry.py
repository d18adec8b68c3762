"""Every learner tavc knows, in one table: the name a config gives (`learner.name`,
`baselines`), the controller label its trials carry in every output, the code that enters
each trial's seed, and how its policy is built.

Adding a built-in learner is adding one entry here. A seed code is part of every trial's seed
and key: changing one reruns (and changes) every trial of that learner.

A learner from outside tavc is a class named by ``learner.target`` (``package.module.Class``,
or ``path/to/file.py:Class``), built with ``learner.params`` as keyword arguments beside
``n_robots``, ``n_circuits`` and ``rng`` (`plugin_policy`): its label is its ``learner.name``,
its seed code one drawn from that name (`seed_code`). docs/plugins.md shows one.
"""

from __future__ import annotations

import importlib
import importlib.util
import inspect
import sys
import zlib
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from tavc_cli.learning.behaviour import BehaviourPolicy
from tavc_cli.learning.informed import MODEL_LEARNERS, InformedPolicy, ModelPolicy
from tavc_cli.learning.literature import ThresholdPolicy, WolfPhcPolicy
from tavc_cli.learning.policies import (
    AlternatePolicy,
    RandomPolicy,
    StaticPolicy,
    TaskPolicy,
    TavcPolicy,
    alternate_roles,
    even_allocation,
)
from tavc_cli.errors import TavcError
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


CONFIG_DIRS_ENV = "TAVC_CONFIG_DIRS"  # folders of the user's own configs and learners (`--config-dir`)


def config_dirs() -> list[Path]:
    """The user's config folders, in the order given (`--config-dir`, or the environment
    variable TAVC_CONFIG_DIRS, which worker processes inherit)."""
    import os

    return [Path(p) for p in os.environ.get(CONFIG_DIRS_ENV, "").split(os.pathsep) if p]


def load_target(target: str) -> type:
    """The class ``learner.target`` names: ``package.module.Class`` (importable), or
    ``path/to/file.py:Class`` (relative to a folder given with --config-dir, else the working
    folder)."""
    if ":" in target:
        file, _, name = target.rpartition(":")
        path = Path(file)
        dirs = config_dirs()
        if not path.is_absolute():
            path = next((d / path for d in dirs if (d / path).is_file()), path)
        if not path.is_file():
            raise TavcError(f"learner.target: no file {file} (looked in {', '.join(map(str, dirs))}"
                            f"{' and ' if dirs else ''}the working folder)")
        module_name = f"tavc_plugin_{zlib.crc32(str(path.resolve()).encode()):08x}"
        module = sys.modules.get(module_name)
        if module is None:
            spec = importlib.util.spec_from_file_location(module_name, path)
            module = importlib.util.module_from_spec(spec)
            sys.modules[module_name] = module
            try:
                spec.loader.exec_module(module)
            except Exception as error:  # noqa: BLE001 - the user's file: one line naming it
                del sys.modules[module_name]
                raise TavcError(f"learner.target: {path} failed to load: {type(error).__name__}: {error}") from None
    else:
        module_path, _, name = target.rpartition(".")
        try:
            module = importlib.import_module(module_path)
        except Exception as error:  # noqa: BLE001
            raise TavcError(f"learner.target: cannot import {module_path!r} ({type(error).__name__}: {error}); "
                            "give package.module.Class on the Python path, or path/to/file.py:Class") from None
    cls = getattr(module, name, None)
    if not inspect.isclass(cls):
        raise TavcError(f"learner.target: {target!r} names no class")
    for method in ("choose", "learn"):
        if not callable(getattr(cls, method, None)):
            raise TavcError(f"learner.target: {cls.__name__} has no method {method}(...); a learner chooses a circuit "
                            "(choose(robot, state)) and learns (learn(robot, state, action, reward, next_state))")
    return cls


PLUGIN_ARGUMENTS = ("n_robots", "n_circuits", "rng")  # what every learner from outside tavc is built with


def check_params(cls: type, params: Mapping) -> None:
    """`params` against the signature of `cls.__init__`: every one a parameter it takes, every
    parameter it needs (beside `PLUGIN_ARGUMENTS`) given. One line naming the key otherwise."""
    signature = inspect.signature(cls.__init__)
    named = {k: p for k, p in list(signature.parameters.items())[1:]}
    takes_any = any(p.kind is inspect.Parameter.VAR_KEYWORD for p in named.values())
    missing = [k for k in PLUGIN_ARGUMENTS if k not in named and not takes_any]
    if missing:
        raise TavcError(f"learner.target: {cls.__name__}.__init__ must take {', '.join(PLUGIN_ARGUMENTS)} (it lacks "
                        f"{missing[0]})")
    known = [k for k, p in named.items() if k not in PLUGIN_ARGUMENTS
             and p.kind in (inspect.Parameter.POSITIONAL_OR_KEYWORD, inspect.Parameter.KEYWORD_ONLY)]
    for key in params:
        if key not in known and not takes_any:
            raise TavcError(f"learner.params.{key}: {cls.__name__} takes no parameter {key!r} "
                            f"(it takes: {', '.join(known) or 'none'})")
    for key in known:
        if named[key].default is inspect.Parameter.empty and key not in params:
            raise TavcError(f"learner.params.{key}: missing; {cls.__name__} needs it")


def plugin_policy(spec: LearnerConfig, n_robots: int, n_circuits: int, rng: np.random.Generator) -> TaskPolicy:
    """A learner from outside tavc: `spec.target` built with `spec.params`; one without
    `q_tables` has none to show, one without `n_states` has one state a circuit."""
    cls = load_target(str(spec.target))
    params = dict(spec.params or {})
    check_params(cls, params)
    policy = cls(n_robots=n_robots, n_circuits=n_circuits, rng=rng, **params)
    if not hasattr(policy, "q_tables"):
        policy.q_tables = lambda: None
    if not hasattr(policy, "n_states"):
        policy.n_states = n_circuits
    return policy


def make_policy(spec: LearnerConfig, n_robots: int, n_circuits: int, rng: np.random.Generator) -> TaskPolicy:
    """Build the policy named by `spec.name` (or `spec.target`) with its settings."""
    if getattr(spec, "target", None):
        return plugin_policy(spec, n_robots, n_circuits, rng)
    entry = LEARNERS.get(spec.name)
    if entry is None or entry.build is None:
        raise ValueError(f"no task policy named {spec.name!r}")
    return entry.build(spec, n_robots, n_circuits, rng)
