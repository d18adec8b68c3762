"""Learners from the literature beside TAVC, over the same states (the circuit a robot served
last) and actions (the circuit of its next task), communication-free like TAVC.

- `WolfPhcPolicy`: Win or Learn Fast policy hill-climbing (Bowling and Veloso, "Multiagent
  learning using a variable learning rate", Artificial Intelligence 136(2), 2002, Table 2): a
  Q-learner whose mixed policy climbs towards its greedy action, slowly while it is winning
  (its policy's expected value above its average policy's), fast while it is losing.
"""

from __future__ import annotations

import numpy as np


class WolfPhcPolicy:
    """WoLF-PHC for each robot alone.

    Q(s, a) += alpha (r + gamma max_b Q(s', b) - Q(s, a)); the average policy
    pi_avg(s) += (pi(s) - pi_avg(s)) / C(s) after C(s) visits of s; then pi(s, a) moves by
    -min(pi(s, a), delta / (|A| - 1)) for every non-greedy a, the greedy action taking what
    they give up, with delta = delta_w when sum_a pi(s, a) Q(s, a) > sum_a pi_avg(s, a) Q(s, a)
    (winning) and delta_l otherwise. Actions are drawn from pi, uniformly with probability
    epsilon (the exploration the paper leaves to the user). Q starts at 0, pi and pi_avg
    uniform.
    """

    def __init__(self, n_robots: int, n_circuits: int, *, alpha: float, gamma: float, epsilon: float,
                 delta_win: float, delta_lose: float, rng: np.random.Generator) -> None:
        self.n_states = n_circuits
        self.alpha, self.gamma, self.epsilon = alpha, gamma, epsilon
        self.delta_win, self.delta_lose = delta_win, delta_lose
        self.rng = rng
        self.q = np.zeros((n_robots, n_circuits, n_circuits))
        self.pi = np.full((n_robots, n_circuits, n_circuits), 1.0 / n_circuits)
        self.pi_avg = self.pi.copy()
        self.visits = np.zeros((n_robots, n_circuits), dtype=np.int64)

    def choose(self, robot: int, state: int) -> int:
        n = self.pi.shape[2]
        if self.rng.random() < self.epsilon:
            return int(self.rng.integers(n))
        u, cumulative = self.rng.random(), 0.0
        for a, p in enumerate(self.pi[robot, state].tolist()):
            cumulative += p
            if u < cumulative:
                return a
        return n - 1

    def learn(self, robot: int, state: int, action: int, reward: float, next_state: int) -> None:
        q, pi, avg = self.q[robot], self.pi[robot], self.pi_avg[robot]
        q[state, action] += self.alpha * (reward + self.gamma * q[next_state].max() - q[state, action])
        self.visits[robot, state] += 1
        avg[state] += (pi[state] - avg[state]) / self.visits[robot, state]
        winning = float(pi[state] @ q[state]) > float(avg[state] @ q[state])
        delta = self.delta_win if winning else self.delta_lose
        n = q.shape[1]
        best = int(np.argmax(q[state]))
        given = 0.0
        for a in range(n):
            if a != best:
                step = min(float(pi[state, a]), delta / (n - 1))
                pi[state, a] -= step
                given += step
        pi[state, best] += given

    def q_tables(self) -> np.ndarray:
        return self.q.copy()
