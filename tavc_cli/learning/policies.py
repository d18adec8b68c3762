"""Task-selection policies: which circuit (task class) each robot serves next.

A policy sees integers and rewards, never the simulator. The transport loop asks
`choose(robot, state)` when a robot finishes a task and tells `learn(...)` the
reward r = w / t it earned (equation 1.1). In the TAVC learners the state is the
class the robot last serviced (section 1.5.3).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Protocol

import numpy as np

from tavc_cli.learning.qlearning import epsilon_greedy, q_update, softmax_choice


class TaskPolicy(Protocol):
    """What the transport loop needs from a controller."""

    n_states: int

    def choose(self, robot: int, state: int) -> int:
        """The circuit `robot` serves next, having last served `state`."""
        ...

    def learn(self, robot: int, state: int, action: int, reward: float, next_state: int) -> None:
        """The reward earned for taking `action` in `state`, which led to `next_state`."""
        ...

    def q_tables(self) -> np.ndarray | None:
        """The Q-tables, (n_robots, n_states, n_circuits), or None without them."""
        ...


class RandomPolicy:
    """A uniformly random circuit for every task."""

    @classmethod
    def from_settings(cls, settings, n_robots: int, n_circuits: int, rng: np.random.Generator) -> RandomPolicy:
        """The policy of `random`'s settings (`parameters.RandomSettings`)."""
        return cls(n_circuits, rng)

    def __init__(self, n_circuits: int, rng: np.random.Generator) -> None:
        """A random policy over `n_circuits` circuits."""
        self.n_states = n_circuits
        self.n_circuits = n_circuits
        self.rng = rng

    def choose(self, robot: int, state: int) -> int:
        """A circuit drawn uniformly."""
        return int(self.rng.integers(self.n_circuits))

    def learn(self, robot: int, state: int, action: int, reward: float, next_state: int) -> None:
        """Nothing: a random policy learns nothing."""
        return None

    def q_tables(self) -> None:
        """None: no Q-table."""
        return None


class StaticPolicy:
    """A fixed allocation: robot i always serves circuit `assignment[i]`."""

    @classmethod
    def from_settings(cls, settings, n_robots: int, n_circuits: int, rng: np.random.Generator) -> StaticPolicy:
        """The policy of `static`'s settings: `allocation` robots per circuit, the first robots on
        the first circuit (an even split without one)."""
        counts = settings.allocation or even_allocation(n_robots, n_circuits)
        return cls(np.repeat(np.arange(n_circuits), counts), n_circuits)

    def __init__(self, assignment: Sequence[int], n_circuits: int) -> None:
        """Robot i serves circuit `assignment[i]`."""
        self.assignment = np.asarray(assignment, dtype=np.int64)
        self.n_states = n_circuits

    def choose(self, robot: int, state: int) -> int:
        """The robot's circuit in the assignment."""
        return int(self.assignment[robot])

    def learn(self, robot: int, state: int, action: int, reward: float, next_state: int) -> None:
        """Nothing: a static policy learns nothing."""
        return None

    def q_tables(self) -> None:
        """None: no Q-table."""
        return None


class AlternatePolicy:
    """Fixed roles: robot i stays on circuit `roles[i]` for every task, or, where
    `roles[i]` is -1, alternates: each task on the circuit after the one it last served. The
    static controller of the turn-taking groups learners form at long horizons; its runs
    measure what a task takes by the group's make-up (`tavc surrogate`)."""

    ALTERNATE = -1

    @classmethod
    def from_settings(cls, settings, n_robots: int, n_circuits: int, rng: np.random.Generator) -> AlternatePolicy:
        """The policy of `alternate`'s settings: its `roles`, or roles from its stayers per circuit."""
        roles = settings.roles if settings.roles is not None else alternate_roles(settings.allocation, n_robots)
        return cls(roles, n_circuits)

    def __init__(self, roles: Sequence[int], n_circuits: int) -> None:
        """Robot i keeps to circuit `roles[i]`, or alternates where it is `ALTERNATE`."""
        self.roles = np.asarray(roles, dtype=np.int64)
        self.n_states = n_circuits
        self.n_circuits = n_circuits

    def choose(self, robot: int, state: int) -> int:
        """The robot's circuit, or the one after `state` for an alternating robot."""
        role = int(self.roles[robot])
        return (state + 1) % self.n_circuits if role == self.ALTERNATE else role

    def learn(self, robot: int, state: int, action: int, reward: float, next_state: int) -> None:
        """Nothing: fixed roles learn nothing."""
        return None

    def q_tables(self) -> None:
        """None: no Q-table."""
        return None


def alternate_roles(allocation: Sequence[int] | None, n_robots: int) -> list[int]:
    """Roles from stayers per circuit: the first `allocation[0]` robots stay on circuit 0, the
    next `allocation[1]` on circuit 1, ..., the rest alternate (all of them without one)."""
    roles = [c for c, count in enumerate(allocation or ()) for _ in range(int(count))]
    return roles + [AlternatePolicy.ALTERNATE] * (n_robots - len(roles))


class TavcPolicy:
    """Independent Q-learners over task classes (sections 1.5.3 and 1.6.1).

    Exploration never decays, so the group stays able to fill new vacancies.
    """

    @classmethod
    def from_settings(cls, settings, n_robots: int, n_circuits: int, rng: np.random.Generator) -> TavcPolicy:
        """The policy of `tavc_egreedy`'s or `tavc_softmax`'s settings (the one's `tau` and the
        other's `epsilon`, which its selection never reads, at their defaults)."""
        softmax = hasattr(settings, "tau")
        return cls(n_robots, n_circuits, alpha=float(settings.alpha), gamma=float(settings.gamma),
                   selection="softmax" if softmax else "egreedy",
                   epsilon=0.1 if softmax else float(settings.epsilon), tau=float(settings.tau) if softmax else 0.005,
                   q_init=(float(settings.q_init_low), float(settings.q_init_high)), rng=rng)

    def __init__(self, n_robots: int, n_circuits: int, *, alpha: float, gamma: float,
                 selection: str, epsilon: float, tau: float, q_init: tuple[float, float],
                 rng: np.random.Generator) -> None:
        """Learners for `n_robots` robots over `n_circuits` circuits, Q-tables drawn uniformly in
        `q_init`, choosing by `selection` (``softmax`` at temperature `tau`, else
        epsilon-greedy)."""
        self.n_states = n_circuits
        self.alpha, self.gamma = alpha, gamma
        self.selection, self.epsilon, self.tau = selection, epsilon, tau
        self.rng = rng
        self.q = rng.uniform(q_init[0], q_init[1], size=(n_robots, n_circuits, n_circuits))

    def choose(self, robot: int, state: int) -> int:
        """A circuit from the robot's Q-row for `state`, softmax or epsilon-greedy."""
        row = self.q[robot, state]
        if self.selection == "softmax":
            return softmax_choice(row, self.tau, self.rng)
        return epsilon_greedy(row, self.epsilon, self.rng)

    def learn(self, robot: int, state: int, action: int, reward: float, next_state: int) -> None:
        """One Q-learning update of the robot's table (`q_update`)."""
        q_update(self.q[robot], state, action, reward, next_state, self.alpha, self.gamma)

    def q_tables(self) -> np.ndarray:
        """A copy of the Q-tables, (n_robots, n_circuits, n_circuits)."""
        return self.q.copy()


def even_allocation(n_robots: int, n_circuits: int) -> list[int]:
    """Robots per circuit as even as possible, extra robots on the first circuits."""
    base, extra = divmod(n_robots, n_circuits)
    return [base + (1 if c < extra else 0) for c in range(n_circuits)]
