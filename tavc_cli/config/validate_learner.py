"""Validation of the learner: its name or the class `learner.target` names, its parameters, the
allocations it starts from. Each check raises one ``TavcError("<key>: <problem>")`` line."""

import math
import sys
from collections.abc import Sequence

from omegaconf import DictConfig, OmegaConf

from tavc_cli.config.checks import at_least, check, finite, per_circuit, positive, unit
from tavc_cli.confined import plain, run_confined
from tavc_cli.learning.parameters import (
    ALLOCATION,
    FINITE,
    POSITIVE,
    ROLES,
    STAYERS,
    UNIT,
    LearnerSettings,
    PluginSettings,
    parameters,
)
from tavc_cli.learning.plugins import check_params, load_target, rehearse
from tavc_cli.learning.registry import NAMES as LEARNERS
from tavc_cli.learning.registry import RESERVED_LABELS, SEED_CODES
from tavc_cli.settings import settings_of

# a label names its trials' records (`<label>_<trial>.npz`): kept well inside a file name's 255 bytes
MAX_LABEL_BYTES = 128


def validate_model_learner(learner: DictConfig, n_circuits: int, n_robots: int, n_breakdowns: int) -> None:
    """The model's allocations (`learning.informed`): one for the starting team, each placing its
    robots on the circuits; `informed`'s also for every team a breakdown leaves, known before hours
    of warm-up."""
    allocations = learner.allocations or {}
    check(str(n_robots) in allocations, "learner.allocations",
          f"the model predicts nothing for a team of {n_robots} (it has "
          f"{', '.join(sorted(allocations, key=int)) or 'no team'}); run `tavc model` for this team")
    for size, counts in allocations.items():
        per_circuit(f"learner.allocations.{size}", counts, n_circuits, "robot count")
        check(sum(counts) == int(size), f"learner.allocations.{size}",
              f"must place {size} robots, places {sum(counts)}")
    if learner.name == "informed":
        for left in range(n_robots - 1, n_robots - 1 - n_breakdowns, -1):
            check(str(left) in allocations, "learner.allocations",
                  f"the model predicts nothing for the {left} robots left after a breakdown; run `tavc model` "
                  "with that team, or use learner=model")


def validate_learner(learner: DictConfig, n_circuits: int, n_robots: int, confined: bool = False) -> LearnerSettings:
    """The learner's settings read into the class it declares (a key it does not take, a value of
    the wrong type: one line), then each parameter checked by the rule its declaration names and
    each ordered pair in order (`learning.parameters`); a learner from outside tavc is loaded and
    tried in a process held to writing nowhere where `confined`. Returns the typed settings."""
    settings = settings_of(OmegaConf.to_container(learner, resolve=True))
    if isinstance(settings, PluginSettings):
        _validate_plugin(settings, n_circuits, n_robots, confined)
        return settings
    for name, _, rule in parameters(type(settings)):
        value = getattr(settings, name)
        key = f"learner.{name}"
        if rule in _NUMBER_RULES:
            _NUMBER_RULES[rule](key, value)
        elif rule == ALLOCATION and value is not None:
            validate_allocation(key, value, n_circuits, n_robots)
        elif rule == STAYERS and value is not None:
            per_circuit(key, value, n_circuits, "robot count")
            for index, count in enumerate(value):
                at_least(f"{key}[{index}]", count, 0)
            check(sum(value) <= n_robots, key,
                  f"stayers must number at most team.n_robots ({n_robots}), got {sum(value)}")
        elif rule == ROLES and value is not None:
            check(len(value) == n_robots, key, f"needs one role per robot ({n_robots}), got {len(value)}")
            for index, role in enumerate(value):
                check(role == -1 or 0 <= role < n_circuits, f"{key}[{index}]",
                      f"must be a circuit index (0 to {n_circuits - 1}) or -1 to alternate, got {role!r}")
    for low, high, why in type(settings).ORDERED:
        a, b = getattr(settings, low), getattr(settings, high)
        check(math.isfinite(b - a), f"learner.{high}", f"the range [{a!r}, {b!r}] is too wide ({why})")
        check(a <= b, f"learner.{low}", f"must be <= learner.{high} ({b!r}), got {a!r}: {why}")
    return settings


_NUMBER_RULES = {UNIT: unit, POSITIVE: positive, FINITE: finite}


def _validate_plugin(learner: PluginSettings, n_circuits: int, n_robots: int, confined: bool) -> None:
    """A learner from outside tavc: a plain name of its own (its label and seed) that no table
    already gives a meaning, a class that loads, takes the parameters given, and answers a short
    made-up run as a trial needs (`plugins.rehearse`; its warnings printed once per learner).
    Where `confined`, its code runs only in a copy of this process that can write nowhere
    (`confined.run_confined`): this process never imports it."""
    name = str(learner.name)
    check(name.isidentifier(), "learner.name",
          f"a learner's name is a plain word (its label in every output), got {name!r}")
    check(len(name.encode()) <= MAX_LABEL_BYTES, "learner.name",  # its trials' files are named after it
          f"at most {MAX_LABEL_BYTES} bytes (its trials' records are files named after it), got {len(name.encode())}")
    check(name not in LEARNERS and name not in SEED_CODES, "learner.name",
          f"{name!r} is a built-in learner's; give the learner from learner.target a name of its own")
    check(name not in RESERVED_LABELS, "learner.name",
          f"{name!r} names other rows of tavc's tables; give the learner from learner.target a name of its own")
    file, colon, _ = str(learner.target).rpartition(":")
    check(not colon or file.endswith(".py"), "learner.target",
          f"{file} is not a Python file: give path/to/file.py:Class, or package.module.Class")
    tried = run_confined(_try_plugin, learner, n_circuits, n_robots, name=f"learner {name}") if confined else \
        _try_plugin(learner, n_circuits, n_robots)
    check(isinstance(tried, list) and all(isinstance(w, str) for w in tried), "learner.target",  # a copy's: checked
          f"the rehearsal of {learner.target} answered something else than its warnings")
    for warning in map(plain, tried):
        if warning not in _WARNED:
            _WARNED.add(warning)
            print(f"warning: {warning}", file=sys.stderr, flush=True)


_WARNED: set[str] = set()  # a plugin's warnings, said once per process


def _try_plugin(learner: PluginSettings, n_circuits: int, n_robots: int) -> list[str]:
    """Load the learner's class, check its parameters and rehearse it; its warnings."""
    check_params(load_target(str(learner.target)), dict(learner.params or {}))
    return rehearse(learner, n_robots, n_circuits)


def validate_allocation(
    key: str, allocation: Sequence[int], n_circuits: int, n_robots: int
) -> None:
    """Robots per circuit: one non-negative count per circuit, summing to the team size."""
    per_circuit(key, allocation, n_circuits, "robot count")
    for index, count in enumerate(allocation):
        at_least(f"{key}[{index}]", count, 0)
    check(
        sum(allocation) == n_robots,
        key,
        f"must sum to team.n_robots ({n_robots}), got {sum(allocation)}",
    )
