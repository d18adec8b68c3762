"""Tabular Q-learning and action selection, on plain numpy arrays.

Each robot learns alone: its Q-table is a (n_states, n_actions) slice of a
(n_robots, n_states, n_actions) array. Nothing here knows about robots moving.
"""

from __future__ import annotations

import numpy as np


def q_update(q: np.ndarray, state: int, action: int, reward: float, next_state: int,
             alpha: float, gamma: float) -> float:
    """One Q-learning step on table `q` (n_states, n_actions), in place.

    Q(s, a) += alpha * (r + gamma * max_b Q(s', b) - Q(s, a)). Returns the TD error.
    """
    td = reward + gamma * float(np.max(q[next_state])) - float(q[state, action])
    q[state, action] += alpha * td
    return td


def epsilon_greedy(q_row: np.ndarray, epsilon: float, rng: np.random.Generator) -> int:
    """The greedy action, or with probability epsilon a uniformly random one.

    Ties among greedy actions are broken at random so that no action is favoured
    by its position in the table.
    """
    if rng.random() < epsilon:
        return int(rng.integers(len(q_row)))
    best = np.flatnonzero(q_row == q_row.max())
    return int(best[0]) if len(best) == 1 else int(rng.choice(best))


def softmax_probs(q_row: np.ndarray, tau: float) -> np.ndarray:
    """Boltzmann probabilities exp(Q/tau) / sum exp(Q/tau), computed without overflow."""
    z = (q_row - q_row.max()) / tau
    e = np.exp(z)
    return e / e.sum()


def softmax_choice(q_row: np.ndarray, tau: float, rng: np.random.Generator) -> int:
    """Draw an action from the Boltzmann distribution at temperature tau."""
    p = softmax_probs(q_row, tau)
    return int(min(np.searchsorted(np.cumsum(p), rng.random(), side="right"), len(p) - 1))
