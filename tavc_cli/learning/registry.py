"""Every learner tavc knows, in one table: the name a config gives (`learner.name`,
`baselines`), the class declaring its parameters (`learning.parameters`), the controller label
its trials carry in every output, its title and colour in figures, the code that enters each
trial's seed, and the class its policy is built from.

Adding a built-in learner is its policy class (with a ``from_settings`` constructor), its
settings class and one entry here. The built-ins are named by a class path as a learner from
outside tavc is (``learner.target``): the entry holds ``module:Class``, loaded when a policy is
built, so reading the table loads no numerical code. A seed code is part of every trial's seed
and key: changing one reruns (and changes) every trial of that learner.

A learner from outside tavc is built with ``learner.params`` as keyword arguments beside
``n_robots``, ``n_circuits`` and ``rng`` (`plugins.plugin_policy`): its label is its
``learner.name``, its seed code one drawn from that name (`seed_code`); `learning.plugins`
loads, builds and guards it. docs/plugins.md shows one.
"""

from __future__ import annotations

import importlib
import zlib
from dataclasses import dataclass
from typing import TYPE_CHECKING, Optional

from tavc_cli.learning.parameters import (
    AlternateSettings,
    BehaviourSettings,
    LearnerSettings,
    ModelSettings,
    PluginSettings,
    RandomSettings,
    StaticSettings,
    TavcEgreedySettings,
    TavcSoftmaxSettings,
    ThresholdSettings,
    WolfPhcSettings,
)

if TYPE_CHECKING:
    import numpy as np

    from tavc_cli.learning.policies import TaskPolicy


@dataclass(frozen=True)
class Learner:
    """A learner tavc knows: its config name, settings class, label, seed code and policy class."""

    name: str
    settings: type[LearnerSettings]
    label: str
    seed_code: int
    policy: str                     # ``module:Class`` under tavc_cli.learning, built by its ``from_settings``
    title: Optional[str] = None     # its name in figures' legends (None: its label)
    colour: Optional[str] = None    # its colour in figures (None: one drawn from its label)
    baseline: bool = False          # may run beside the main learner (`baselines: [...]`)
    follows_model: bool = False     # takes the model's allocation (`model_file`)


LEARNERS: dict[str, Learner] = {entry.name: entry for entry in (
    Learner("random", RandomSettings, "random", 1, "policies:RandomPolicy", colour="tab:orange", baseline=True),
    Learner("static", StaticSettings, "static", 2, "policies:StaticPolicy", colour="tab:green", baseline=True),
    Learner("alternate", AlternateSettings, "alternate", 4, "policies:AlternatePolicy", baseline=True),
    Learner("wolf_phc", WolfPhcSettings, "wolf_phc", 5, "literature:WolfPhcPolicy", "WoLF-PHC", "tab:purple"),
    Learner("threshold", ThresholdSettings, "threshold", 6, "literature:ThresholdPolicy", "response threshold",
            "tab:brown"),
    Learner("model", ModelSettings, "model", 7, "informed:ModelPolicy", "model's allocation", "tab:olive",
            follows_model=True),
    Learner("informed", ModelSettings, "informed", 8, "informed:InformedPolicy", "model, informed", "tab:cyan",
            follows_model=True),
    Learner("tavc_egreedy", TavcEgreedySettings, "tavc", 0, "policies:TavcPolicy", "TAVC", "tab:blue"),
    Learner("tavc_softmax", TavcSoftmaxSettings, "tavc", 0, "policies:TavcPolicy", "TAVC", "tab:blue"),
    Learner("behaviour_softmax", BehaviourSettings, "behaviour", 3, "behaviour:BehaviourPolicy"),
)}
NAMES = tuple(LEARNERS)
BASELINES = tuple(name for name, entry in LEARNERS.items() if entry.baseline)
MODEL_LEARNERS = tuple(name for name, entry in LEARNERS.items() if entry.follows_model)
LEARNS_NOTHING = (*BASELINES, *MODEL_LEARNERS)  # fixed controllers: their distribution has no horizon
SEED_CODES = {entry.label: entry.seed_code for entry in LEARNERS.values()}
SETTINGS = {name: entry.settings for name, entry in LEARNERS.items()}
# labels tavc's tables give rows that are no learner's trials (`state_time.csv`'s model row), with
# their titles and colours in figures
RESERVED_LABELS = {"theory": ("theory", "0.4")}
# each controller label's title and colour in figures (a label not here: its own name, a colour drawn from it)
TITLES = {entry.label: entry.title or entry.label for entry in LEARNERS.values()} | {
    label: title for label, (title, _) in RESERVED_LABELS.items()}
COLOURS = {entry.label: entry.colour for entry in LEARNERS.values() if entry.colour} | {
    label: colour for label, (_, colour) in RESERVED_LABELS.items()}


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


def make_policy(settings: LearnerSettings, n_robots: int, n_circuits: int, rng: np.random.Generator) -> TaskPolicy:
    """Build the policy `settings` name (a built-in's, or the class its ``target`` names)."""
    if isinstance(settings, PluginSettings):
        from tavc_cli.learning.plugins import plugin_policy  # deferred: loads numpy and the learner's own code

        return plugin_policy(settings, n_robots, n_circuits, rng)
    entry = LEARNERS.get(settings.name)
    if entry is None:
        raise ValueError(f"no task policy named {settings.name!r}")
    module, cls = entry.policy.split(":")
    # the policies are numba-compiled: loaded when one is built, not when the table is read
    policy = getattr(importlib.import_module(f"tavc_cli.learning.{module}"), cls)
    return policy.from_settings(settings, n_robots, n_circuits, rng)
