"""Validation of the learner: its name or the class `learner.target` names, its parameters, the
allocations it starts from. Each check raises one ``TavcError("<key>: <problem>")`` line."""

import math
import sys
from collections.abc import Sequence

from omegaconf import DictConfig

from tavc_cli.config.checks import at_least, check, finite, one_of, per_circuit, positive, unit
from tavc_cli.learning.plugins import check_params, load_target, rehearse
from tavc_cli.learning.registry import AVAILABLE as AVAILABLE_LEARNERS
from tavc_cli.learning.registry import NAMES as LEARNERS
from tavc_cli.learning.registry import RESERVED_LABELS, SEED_CODES
from tavc_cli.settings import LearnerConfig


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


def validate_learner(learner: DictConfig, n_circuits: int, n_robots: int) -> None:
    """Learner name and Q-learning parameters."""
    if learner.target is not None:
        _validate_plugin(learner, n_circuits, n_robots)
    else:
        one_of("learner.name", learner.name, LEARNERS)
        check(learner.name in AVAILABLE_LEARNERS, "learner.name",
              f"'{learner.name}' is not available in this version; use one of {', '.join(AVAILABLE_LEARNERS)}")
    for name in ("alpha", "gamma", "epsilon"):
        unit(f"learner.{name}", learner[name])
    positive("learner.tau", learner.tau)
    for name in ("delta_win", "delta_lose"):
        unit(f"learner.{name}", learner[name])
    positive("learner.theta_low", learner.theta_low)
    check(learner.theta_low <= learner.theta_high, "learner.theta_low",
          f"must be <= learner.theta_high ({learner.theta_high!r}), got {learner.theta_low!r}")
    positive("learner.steepness", learner.steepness)
    check(learner.delta_win <= learner.delta_lose, "learner.delta_win",
          f"must be <= learner.delta_lose ({learner.delta_lose!r}): WoLF learns fast when losing")
    positive("learner.decision_period_s", learner.decision_period_s)
    finite("learner.q_init_low", learner.q_init_low)
    finite("learner.q_init_high", learner.q_init_high)
    check(
        math.isfinite(learner.q_init_high - learner.q_init_low),
        "learner.q_init_high",
        f"the range [{learner.q_init_low!r}, {learner.q_init_high!r}] is too wide to draw initial Q-values from",
    )
    check(
        learner.q_init_low <= learner.q_init_high,
        "learner.q_init_low",
        f"must be <= learner.q_init_high ({learner.q_init_high!r}), got {learner.q_init_low!r}",
    )
    if learner.allocation is not None and learner.name == "alternate":
        per_circuit("learner.allocation", learner.allocation, n_circuits, "robot count")
        for index, count in enumerate(learner.allocation):
            at_least(f"learner.allocation[{index}]", count, 0)
        check(sum(learner.allocation) <= n_robots, "learner.allocation",
              f"stayers must number at most team.n_robots ({n_robots}), got {sum(learner.allocation)}")
    elif learner.allocation is not None:
        validate_allocation("learner.allocation", learner.allocation, n_circuits, n_robots)
    if learner.roles is not None:
        check(len(learner.roles) == n_robots, "learner.roles",
              f"needs one role per robot ({n_robots}), got {len(learner.roles)}")
        for index, role in enumerate(learner.roles):
            check(role == -1 or 0 <= role < n_circuits, f"learner.roles[{index}]",
                  f"must be a circuit index (0 to {n_circuits - 1}) or -1 to alternate, got {role!r}")


def _validate_plugin(learner: DictConfig, n_circuits: int, n_robots: int) -> None:
    """A learner from outside tavc: a plain name of its own (its label and seed) that no table
    already gives a meaning, a class that loads, takes the parameters given, and answers a short
    made-up run as a trial needs (`plugins.rehearse`; its warnings printed once per learner)."""
    name = str(learner.name)
    check(name.isidentifier(), "learner.name",
          f"a learner's name is a plain word (its label in every output), got {name!r}")
    check(name not in LEARNERS and name not in SEED_CODES, "learner.name",
          f"{name!r} is a built-in learner's; give the learner from learner.target a name of its own")
    check(name not in RESERVED_LABELS, "learner.name",
          f"{name!r} names other rows of tavc's tables; give the learner from learner.target a name of its own")
    check_params(load_target(str(learner.target)), dict(learner.params or {}))
    spec = LearnerConfig(name=name, target=str(learner.target), params=dict(learner.params or {}))
    for warning in rehearse(spec, n_robots, n_circuits):
        if warning not in _WARNED:
            _WARNED.add(warning)
            print(f"warning: {warning}", file=sys.stderr, flush=True)


_WARNED: set[str] = set()  # a plugin's warnings, said once per process


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
