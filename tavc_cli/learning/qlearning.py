"""Tabular Q-learning and action selection, on plain numpy arrays.

Each robot learns alone: its Q-table is a (n_states, n_actions) slice of a
(n_robots, n_states, n_actions) array. Nothing here knows about robots moving.
"""

from __future__ import annotations

import math

import numpy as np


def q_update(q: np.ndarray, state: int, action: int, reward: float, next_state: int,
             alpha: float, gamma: float) -> float:
    """One Q-learning step on table `q` (n_states, n_actions), in place.

    Q(s, a) += alpha * (r + gamma * max_b Q(s', b) - Q(s, a)). Returns the TD error.
    The row's maximum is taken in plain Python, the same number numpy's would be for a
    handful of actions at a tenth of the cost.
    """
    q_sa = float(q[state, action])
    td = reward + gamma * max(q[next_state].tolist()) - q_sa
    q[state, action] = q_sa + alpha * td
    return td


def epsilon_greedy(q_row: np.ndarray, epsilon: float, rng: np.random.Generator) -> int:
    """The greedy action, or with probability epsilon a uniformly random one.

    Ties among greedy actions are broken at random so that no action is favoured
    by its position in the table. The handful of actions a row holds are compared in plain
    Python: the same actions and draws as numpy's `flatnonzero(q == q.max())`, at a fraction
    of its cost on tiny arrays.
    """
    if rng.random() < epsilon:
        return int(rng.integers(len(q_row)))
    q = q_row.tolist()
    top = max(q)
    best = [k for k, v in enumerate(q) if v == top]
    return best[0] if len(best) == 1 else int(rng.choice(best))


def softmax_probs(q_row: np.ndarray, tau: float) -> np.ndarray:
    """Boltzmann probabilities exp(Q/tau) / sum exp(Q/tau), computed without overflow."""
    z = (q_row - q_row.max()) / tau
    e = np.exp(z)
    return e / e.sum()


def softmax_choice(q_row: np.ndarray, tau: float, rng: np.random.Generator) -> int:
    """Draw an action from the Boltzmann distribution at temperature tau: the first action whose
    cumulative probability exceeds a uniform draw.

    The handful of actions a row holds are done in plain Python, step for step as
    `softmax_probs`, a running sum and a search would do them in numpy (each rounding in the
    same order), at a fraction of the cost of numpy's calls on tiny arrays.
    """
    q = q_row.tolist()
    top = max(q)
    e = [math.exp((v - top) / tau) for v in q]
    total = 0.0
    for v in e:
        total += v
    u = rng.random()
    cumulative, chosen = 0.0, 0
    for k, v in enumerate(e):
        cumulative += v / total  # 0.0 + x is x exactly: the first sum is numpy's first element
        if cumulative <= u:
            chosen = k + 1
    return min(chosen, len(q) - 1)
