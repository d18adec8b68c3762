"""The vacancy-chain model's allocation as a pre-programmed controller: the floor and the ceiling
for the chapter's claim that learners beat pre-programmed allocations.

- `ModelPolicy` (``learner=model``): the allocation `tavc model` predicts for the starting team,
  robots drawn at random onto it (the model knows no robot from another, so a fast robot is as
  likely to land on the low-value circuit as a slow one), kept as it is through every event,
  as the chapter's static allocation is: after a breakdown the gap stays open.
- `InformedPolicy` (``learner=informed``): handed the model's allocation for the team it has
  after every event (a breakdown, a change of values), it moves the fewest robots that reach it:
  robots on a circuit with too many move, chosen at random, to the circuits with too few.

Both learn nothing and talk to no one; what they know comes from the model's output file
(``learner.model_file``, read and checked once when the config is resolved into ``learner.allocations``
(`model.allocations`):
robots per circuit by team size, the most valuable circuit first).

The trial calls ``on_event(alive, values)`` once at its start and again after every event
(`experiments.trial.TrialState`), with which robots are alive and the circuits' values then.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np

from tavc_cli.errors import TavcError
from tavc_cli.learning.policies import StaticPolicy


def ranked(counts_high_first: Sequence[int], values: np.ndarray) -> np.ndarray:
    """Robots per circuit index from counts listed most valuable circuit first (ties: the lower
    index is the more valuable, as `np.argmax` reads the values)."""
    out = np.zeros(len(values), dtype=np.int64)
    out[np.argsort(-np.asarray(values), kind="stable")] = counts_high_first
    return out


class ModelPolicy(StaticPolicy):
    """The model's allocation for the starting team, kept through every event: a static
    allocation (choosing and learning as `StaticPolicy` does, in Python: the compiled paths serve
    only the exact built-in classes) whose assignment is drawn when the trial starts."""

    @classmethod
    def from_settings(cls, settings, n_robots: int, n_circuits: int, rng: np.random.Generator) -> ModelPolicy:
        """The policy of `model`'s or `informed`'s settings: the allocations resolved from its model file."""
        return cls(settings.allocations or {}, n_robots, n_circuits, rng)

    def __init__(self, allocations: Mapping[str, Sequence[int]], n_robots: int, n_circuits: int,
                 rng: np.random.Generator) -> None:
        """The allocations the model gives each team size (robots per circuit, most valuable circuit
        first), for `n_robots` robots on `n_circuits` circuits."""
        super().__init__([], n_circuits)
        self.allocations = {int(k): list(v) for k, v in allocations.items()}
        self.n_circuits = n_circuits
        self.rng = rng
        self.assignment: np.ndarray | None = None

    def target(self, n_alive: int, values: np.ndarray) -> np.ndarray:
        """Robots per circuit index the model gives a team of `n_alive`."""
        counts = self.allocations.get(n_alive)
        if counts is None:
            raise TavcError(f"learner.allocations: the model predicts nothing for {n_alive} robots "
                            f"(it has {', '.join(map(str, sorted(self.allocations)))}); "
                            "run `tavc model` for this team")
        return ranked(counts, values)

    def on_event(self, alive: np.ndarray, values: np.ndarray) -> None:
        """At the start: robots drawn at random onto the model's allocation. After: nothing."""
        if self.assignment is not None:
            return
        counts = self.target(len(alive), values)
        self.assignment = np.repeat(np.arange(self.n_circuits), counts)[self.rng.permutation(len(alive))]


class InformedPolicy(ModelPolicy):
    """The model's allocation for the team as it is after every event, reached by moving the
    fewest robots."""

    def on_event(self, alive: np.ndarray, values: np.ndarray) -> None:
        """At the start as `ModelPolicy`; after, move the fewest robots (drawn at random from the
        circuits over their share) to the circuits short of the live team's allocation."""
        if self.assignment is None:
            super().on_event(alive, values)
            return
        target = self.target(int(alive.sum()), values)
        live = np.flatnonzero(alive)
        here = np.bincount(self.assignment[live], minlength=self.n_circuits)
        movers = []
        for c in range(self.n_circuits):
            surplus = int(here[c] - target[c])
            if surplus > 0:
                on_c = live[self.assignment[live] == c]
                movers.extend(self.rng.choice(on_c, size=surplus, replace=False).tolist())
        short = [c for c in range(self.n_circuits) for _ in range(max(0, int(target[c] - here[c])))]
        for robot, c in zip(sorted(movers), short, strict=True):  # as many places short as robots over
            self.assignment[robot] = c
