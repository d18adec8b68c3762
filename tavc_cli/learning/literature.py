"""Learners from the literature beside TAVC, over the same states (the circuit a robot served
last) and actions (the circuit of its next task), communication-free like TAVC.

- `WolfPhcPolicy`: Win or Learn Fast policy hill-climbing (Bowling and Veloso, "Multiagent
  learning using a variable learning rate", Artificial Intelligence 136(2), 2002, Table 2): a
  Q-learner whose mixed policy climbs towards its greedy action, slowly while it is winning
  (its policy's expected value above its average policy's), fast while it is losing.
- `ThresholdPolicy`: the fixed response-threshold model of division of labour (Bonabeau,
  Theraulaz and Deneubourg, "Quantitative study of the fixed threshold model for the regulation
  of division of labour in insect societies", Proc. R. Soc. Lond. B 263, 1996): an individual
  takes up a task with probability s^n / (s^n + theta^n) for the task's stimulus s and its own
  threshold theta.
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

    @classmethod
    def from_settings(cls, settings, n_robots: int, n_circuits: int, rng: np.random.Generator) -> WolfPhcPolicy:
        """The policy of `wolf_phc`'s settings (`parameters.WolfPhcSettings`)."""
        return cls(n_robots, n_circuits, alpha=float(settings.alpha), gamma=float(settings.gamma),
                   epsilon=float(settings.epsilon), delta_win=float(settings.delta_win),
                   delta_lose=float(settings.delta_lose), rng=rng)

    def __init__(self, n_robots: int, n_circuits: int, *, alpha: float, gamma: float, epsilon: float,
                 delta_win: float, delta_lose: float, rng: np.random.Generator) -> None:
        """Learners for `n_robots` robots over `n_circuits` circuits (states and actions alike)."""
        self.n_states = n_circuits
        self.alpha, self.gamma, self.epsilon = alpha, gamma, epsilon
        self.delta_win, self.delta_lose = delta_win, delta_lose
        self.rng = rng
        self.q = np.zeros((n_robots, n_circuits, n_circuits))
        self.pi = np.full((n_robots, n_circuits, n_circuits), 1.0 / n_circuits)
        self.pi_avg = self.pi.copy()
        self.visits = np.zeros((n_robots, n_circuits), dtype=np.int64)

    def choose(self, robot: int, state: int) -> int:
        """An action drawn from pi(state), or uniformly with probability epsilon."""
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
        """The Q-update, then the average policy and the policy's step towards the greedy action."""
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
        """A copy of the Q-tables, (n_robots, n_circuits, n_circuits)."""
        return self.q.copy()


class ThresholdPolicy:
    """The fixed-threshold model, each robot alone. The stimulus of a circuit, in this task, is
    what a robot itself has seen it pay: its running mean of r = w / t there (rate `alpha`, the
    first reward taken whole), over the mean of its running means of every circuit (1 while it
    has seen fewer than two), so that a circuit paying more than the others stimulates more
    whatever the unit of t. After each task a robot stays on the circuit it served with
    probability T(s) = s^n / (s^n + theta^n) of that circuit's stimulus, else takes another
    circuit, drawn uniformly; its first task is drawn uniformly. Each robot's thresholds, one a
    circuit, are drawn once, uniformly in [theta_low, theta_high]: a low threshold makes a
    robot keep to a circuit, a high one makes it leave unless the circuit pays more than the
    rest. No Q-table: `q_tables` gives the running means."""

    @classmethod
    def from_settings(cls, settings, n_robots: int, n_circuits: int, rng: np.random.Generator) -> ThresholdPolicy:
        """The policy of `threshold`'s settings (`parameters.ThresholdSettings`)."""
        return cls(n_robots, n_circuits, alpha=float(settings.alpha), theta_low=float(settings.theta_low),
                   theta_high=float(settings.theta_high), steepness=float(settings.steepness), rng=rng)

    def __init__(self, n_robots: int, n_circuits: int, *, alpha: float, theta_low: float, theta_high: float,
                 steepness: float, rng: np.random.Generator) -> None:
        """Learners for `n_robots` robots, thresholds drawn uniformly in [theta_low, theta_high]."""
        self.n_states = n_circuits
        self.alpha, self.n = alpha, steepness
        self.rng = rng
        self.theta = rng.uniform(theta_low, theta_high, size=(n_robots, n_circuits))
        self.mean = np.full((n_robots, n_circuits), np.nan)  # each robot's running mean reward per circuit
        self.started = np.zeros(n_robots, dtype=bool)

    def stimulus(self, robot: int, circuit: int) -> float:
        """The stimulus of `circuit` for `robot`: its running mean there over the mean of its
        running means (1 while it has seen fewer than two, or has seen nothing there)."""
        seen = self.mean[robot][~np.isnan(self.mean[robot])]
        if len(seen) < 2 or np.isnan(self.mean[robot, circuit]) or seen.mean() <= 0:
            return 1.0
        return float(self.mean[robot, circuit] / seen.mean())

    def stay_probability(self, robot: int, circuit: int) -> float:
        """T(s) = s^n / (s^n + theta^n): the chance that `robot` stays on `circuit`."""
        s, theta = self.stimulus(robot, circuit) ** self.n, float(self.theta[robot, circuit]) ** self.n
        return s / (s + theta) if s + theta > 0 else 0.5

    def choose(self, robot: int, state: int) -> int:
        """The first task drawn uniformly; after, stay on `state` with the probability
        `stay_probability`, else another circuit drawn uniformly."""
        n_circuits = self.mean.shape[1]
        if not self.started[robot]:
            self.started[robot] = True
            return int(self.rng.integers(n_circuits))
        if self.rng.random() < self.stay_probability(robot, state):
            return state
        others = [c for c in range(n_circuits) if c != state]
        return int(others[self.rng.integers(len(others))])

    def learn(self, robot: int, state: int, action: int, reward: float, next_state: int) -> None:
        """Move the running mean of the circuit served towards `reward` (the first reward taken
        whole)."""
        m = self.mean[robot, action]
        self.mean[robot, action] = reward if np.isnan(m) else m + self.alpha * (reward - m)

    def q_tables(self) -> None:
        """None: the model keeps no Q-table."""
        return None
