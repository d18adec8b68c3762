"""Section 1.4: each robot learns which transport behaviour to use in what it senses.

State: five bits (section 1.4.2), as an integer 0..31:

- bit 0: a bar-code (a source or a sink) is in the laser's view;
- bit 1: a random bit, switched at random intervals (each on and each off interval drawn
  uniformly from 1-30 s), so that a robot can express a behaviour for short spells
  whatever else it senses;
- bits 2, 3, 4: the red (left), green (right) and yellow (rear) markings seen on the
  nearest robot in the camera's view.

Actions: direct target approach, wall following, stop (obstacle avoidance stays under all
of them). The learner maps states to behaviours: every `decision_period_s` each robot reads
its state, and when it differs from the state of its last choice (`decide_on_change`; the
random bit's switches make sure this happens at least every 30 s) it updates the value of
that choice with the rewards earned since (r = w / t at each target arrival, t the time
since its previous arrival) and draws its next behaviour from a Boltzmann softmax over its
Q-row at temperature tau, never decayed. Deciding on changes, not on a clock, keeps gamma's
horizon at a number of sensed situations rather than of seconds. The task level is trivial here: one circuit, or a
uniformly random one if the arena has several.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from tavc_cli.behaviours.layout import BEH_DIRECT, BEH_STOP, BEH_WALL
from tavc_cli.behaviours.navigation import compiled
from tavc_cli.learning.qlearning import q_update, softmax_choice

ACTIONS = np.array([BEH_DIRECT, BEH_WALL, BEH_STOP], dtype=np.int64)
ACTION_NAMES = ("direct", "wall", "stop")
N_BITS = 5
N_STATES = 2 ** N_BITS
BIT_TARGET, BIT_RANDOM, BIT_RED, BIT_GREEN, BIT_YELLOW = range(N_BITS)
RANDOM_INTERVAL_S = (1.0, 30.0)


def state_index(target_visible, random_bit, red, green, yellow):
    """The five bits as one integer (arrays or scalars)."""
    return (np.asarray(target_visible, np.int64) << BIT_TARGET | np.asarray(random_bit, np.int64) << BIT_RANDOM
            | np.asarray(red, np.int64) << BIT_RED | np.asarray(green, np.int64) << BIT_GREEN
            | np.asarray(yellow, np.int64) << BIT_YELLOW)


@njit(cache=True)
def sensed_states(robots, camera, deciding, random_bit, last_state, every_time, states, due):
    """For every robot row g with deciding[g]: its state (as `state_index` makes it, from what
    the kernel sensed last tick) into states[g]; the live ones whose state differs from that of
    their last choice (all live ones where every_time[g]) into due[0:m]. Returns m. The other
    arrays are indexed by row too."""
    m = 0
    for g in range(robots.shape[0]):
        if not deciding[g]:
            continue
        s = (np.int64(robots[g].code_in_view) << BIT_TARGET | random_bit[g] << BIT_RANDOM
             | camera[g, 0] << BIT_RED | camera[g, 1] << BIT_GREEN | camera[g, 2] << BIT_YELLOW)
        states[g] = s
        if robots[g].alive and (s != last_state[g] or every_time[g]):
            due[m] = g
            m += 1
    return m


def state_bits(s: int) -> dict[str, int]:
    """The named bits of state s."""
    names = ("target", "random", "red", "green", "yellow")
    return {name: (int(s) >> k) & 1 for k, name in enumerate(names)}


class BehaviourPolicy:
    """Independent Q-learners over (5-bit state, behaviour), Boltzmann softmax, one per robot."""

    @classmethod
    def from_settings(cls, settings, n_robots: int, n_circuits: int, rng: np.random.Generator) -> BehaviourPolicy:
        """The policy of `behaviour_softmax`'s settings (`parameters.BehaviourSettings`)."""
        return cls(n_robots, n_circuits, alpha=float(settings.alpha), gamma=float(settings.gamma),
                   tau=float(settings.tau), q_init=(float(settings.q_init_low), float(settings.q_init_high)),
                   decision_period_s=float(settings.decision_period_s),
                   decide_on_change=bool(settings.decide_on_change), rng=rng)

    def __init__(self, n_robots: int, n_circuits: int, *, alpha: float, gamma: float, tau: float,
                 q_init: tuple[float, float], decision_period_s: float, rng: np.random.Generator,
                 decide_on_change: bool = True) -> None:
        """Learners for `n_robots` robots, Q-tables drawn uniformly in `q_init`, each reading its
        state every `decision_period_s` and deciding when it differs from its last choice's (every
        time, without `decide_on_change`)."""
        self.n_states = n_circuits  # the task level's states: the circuit last served
        self.n_circuits = n_circuits
        self.alpha, self.gamma, self.tau = alpha, gamma, tau
        self.decision_period_s = decision_period_s
        self.decide_on_change = decide_on_change
        self.rng = rng
        self.q = rng.uniform(q_init[0], q_init[1], size=(n_robots, N_STATES, len(ACTIONS)))
        self.last_state = np.full(n_robots, -1, dtype=np.int64)
        self.last_action = np.full(n_robots, -1, dtype=np.int64)
        self.reward = np.zeros(n_robots)  # earned since the last decision
        self.random_bit = np.zeros(n_robots, dtype=np.int64)
        self.random_until = rng.uniform(*RANDOM_INTERVAL_S, size=n_robots)
        self._next_switch = float(self.random_until.min()) if n_robots else np.inf

    # --- the task level ------------------------------------------------------
    def choose(self, robot: int, state: int) -> int:
        """A circuit drawn uniformly: these learners choose behaviours, not circuits."""
        return 0 if self.n_circuits == 1 else int(self.rng.integers(self.n_circuits))

    def learn(self, robot: int, state: int, action: int, reward: float, next_state: int) -> None:
        """Nothing: the reward is learnt at the behaviour level (`arrived`)."""
        return None

    def q_tables(self) -> np.ndarray:
        """A copy of the behaviour Q-tables, (n_robots, states, behaviours)."""
        return self.q.copy()

    # --- the behaviour level -------------------------------------------------
    def arrived(self, robot: int, reward: float) -> None:
        """A target arrival's reward, credited to the behaviour chosen last."""
        self.reward[robot] += reward

    def random_bits(self, t: float) -> np.ndarray:
        """The random bit of every robot at time t (switching whenever an interval ends)."""
        if t < self._next_switch:
            return self.random_bit
        until = self.random_until
        for robot in np.flatnonzero(until <= t).tolist():
            while until[robot] <= t:
                self.random_bit[robot] ^= 1
                until[robot] += self.rng.uniform(*RANDOM_INTERVAL_S)
        self._next_switch = min(until.tolist())
        return self.random_bit

    def keep_in(self, random_bit: np.ndarray, last_state: np.ndarray) -> None:
        """Hold the random bits and the states of the last choices in these arrays from now on
        (a batch's rows of this trial, so that one compiled pass reads every trial's)."""
        random_bit[:] = self.random_bit
        last_state[:] = self.last_state
        self.random_bit, self.last_state = random_bit, last_state

    def decide(self, robot: int, state: int) -> int:
        """Learn from the last choice, then choose a behaviour (a kernel BEH_* code) for `state`."""
        if self.last_action[robot] >= 0:
            q_update(self.q[robot], int(self.last_state[robot]), int(self.last_action[robot]),
                     float(self.reward[robot]), state, self.alpha, self.gamma)
        a = softmax_choice(self.q[robot, state], self.tau, self.rng)
        self.last_state[robot], self.last_action[robot] = state, a
        self.reward[robot] = 0.0
        return int(ACTIONS[a])


class BatchDecisions:
    """The behaviour learners of a batch's trials, deciding together each tick: one compiled
    pass over every robot row finds the robots whose five bits changed since their last choice,
    then each of those chooses in Python (its own policy, its own random stream)."""

    def __init__(self, robots: np.ndarray, camera: np.ndarray, trials) -> None:
        """`trials`: (first row, end row, BehaviourPolicy, decide every so many ticks) of each
        learning trial of the batch."""
        n = robots.shape[0]
        self.robots, self.camera = robots, camera
        self.random_bit = np.zeros(n, dtype=np.int64)
        self.last_state = np.full(n, -1, dtype=np.int64)
        self.every_time = np.zeros(n, dtype=np.bool_)
        self.states, self.due = np.zeros(n, dtype=np.int64), np.zeros(n, dtype=np.int64)
        self.forced = robots["forced"]  # a view: the choices go straight to the kernel's robots
        # decide_ticks -> (rows deciding on those ticks, their policies)
        self.groups: dict[int, tuple[np.ndarray, list[BehaviourPolicy]]] = {}
        self.policy_of: list[tuple[BehaviourPolicy, int] | None] = [None] * n
        for lo, hi, policy, ticks in trials:
            policy.keep_in(self.random_bit[lo:hi], self.last_state[lo:hi])
            self.every_time[lo:hi] = not policy.decide_on_change
            rows, policies = self.groups.setdefault(ticks, (np.zeros(n, dtype=np.bool_), []))
            rows[lo:hi] = True
            policies.append(policy)
            for g in range(lo, hi):
                self.policy_of[g] = (policy, lo)
        self._pass = compiled(sensed_states, robots, camera, np.zeros(n, dtype=np.bool_), self.random_bit,
                              self.last_state, self.every_time, self.states, self.due)

    def decide(self, tick: int, t: float) -> None:
        """Every learner due at this tick reads its bits and, where they changed, picks a
        behaviour (the robot's `forced` field)."""
        for ticks, (deciding, policies) in self.groups.items():
            if tick % ticks:
                continue
            for policy in policies:
                policy.random_bits(t)  # switches its bits in place
            m = self._pass(self.robots, self.camera, deciding, self.random_bit, self.last_state, self.every_time,
                           self.states, self.due)
            if not m:
                continue
            states = self.states.tolist()
            for g in self.due[:m].tolist():
                policy, lo = self.policy_of[g]
                self.forced[g] = policy.decide(g - lo, states[g])
