"""Serving the robots' arrivals, in Python and for compiled code, as one book-keeping.

A robot that reaches its circuit's source is sent on to the sink; one that reaches the
sink has delivered: the delivery is recorded (task time, reward r = w / t, value, score,
the task's seconds in each activity), its policy learns, and it chooses its next circuit.
`ArrivalDesk` does that in Python (`serve`), and holds the bundle (`tick.Arrivals`) with
which compiled code does the same (`tick.serve_arrivals`), whose log it then takes into
the trials' tables (`take_served`). The trials' per-robot state and the TAVC policies'
Q-tables are views of the bundle's arrays, so that either way an arrival is served on the
same numbers, drawing from the same generators.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from tavc_cli.errors import TavcError
from tavc_cli.experiments.tick import (
    LOG_CHOICE,
    LOG_COLUMNS,
    LOG_SCORE,
    LOG_SPENT,
    LOG_TASK_S,
    Arrivals,
)
from tavc_cli.experiments.trial import TrialFault, TrialState
from tavc_cli.learning.compiled import POLICY_EGREEDY, POLICY_PYTHON, POLICY_SOFTMAX, POLICY_STATIC, policy_kind
from tavc_cli.learning.draws import entry_points, same_functions
from tavc_cli.learning.plugins import check_choice
from tavc_cli.sim.arena import Arena
from tavc_cli.vocabulary import SOURCE

LOG_ROWS = 1024  # arrivals compiled code may serve before Python takes them into the trials' tables


class ArrivalDesk:
    """The arrivals of a batch's trials: served here in Python, or by compiled code with
    `bundle` (drawing through `draws`, the policies' bit generator's next_uint32 and
    next_double).

    `robots` is the batch's ROBOT records; `act_s` the seconds each robot spent in each
    activity (the engine's, which the kernel adds to every tick); `dt` the control period.
    """

    def __init__(self, trials: Sequence[TrialState], arena: Arena, robots: np.ndarray, act_s: np.ndarray,
                 dt: float) -> None:
        """The desk of the batch's `trials` in `arena`, its robots `robots` (their `act_s` the
        activity seconds), on a control period of `dt` seconds."""
        self.trials, self.dt, self.act_s = trials, dt, act_s
        n = len(robots)
        self.act_at_task = np.zeros_like(act_s)  # each robot's activity seconds as its task began
        self.tick_started = False  # whether the kernel has run a tick (and counted its activity)
        self.source_of = np.array([c.source for c in arena.circuits], dtype=np.int64)
        self.sink_of = np.array([c.sink for c in arena.circuits], dtype=np.int64)
        self.kind_of = np.array([t.kind for t in arena.targets], dtype=np.int64)
        self.trial_of = robots["trial"].tolist()
        # views of the robots' fields Python reads and writes per arrival (cheaper than a record's)
        self.target, self.activity, self.arrived = (robots[f] for f in ("target", "activity", "arrived"))
        self.bundle, self.draws = self._bundle(n, arena.n_circuits)

    def _bundle(self, n: int, n_c: int) -> tuple[Arrivals, tuple]:
        """What compiled code serves arrivals with (`tick.Arrivals`) and the two entry points of
        the policies' bit generator it draws through (the trials' generators keep them alive). Each
        trial's per-robot state (tasks, learning states, task starts), its values and scores
        (which a value change rewrites in place) and each TAVC policy's Q-tables become views
        of the bundle's arrays."""
        trials = self.trials
        task, last_circuit = np.full(n, -1, dtype=np.int64), np.full(n, -1, dtype=np.int64)
        state, task_start, loaded_at = np.zeros(n, dtype=np.int64), np.zeros(n), np.zeros(n)
        q, assignment = np.zeros((n, n_c, n_c)), np.zeros(n, dtype=np.int64)
        values, scores = np.zeros((len(trials), n_c)), np.zeros((len(trials), n_c))
        time_unit_s = np.array([tr.spec.time_unit_s for tr in trials], dtype=np.float64)
        from_source = np.array([tr.spec.time_from_source for tr in trials], dtype=np.bool_)
        policy = np.array([policy_kind(tr.policy) for tr in trials], dtype=np.int64)
        learning = np.zeros((4, len(trials)))  # epsilon, alpha, gamma, tau of each TAVC trial
        points = [entry_points(tr.policy_rng) for tr in trials]
        if not same_functions(points):  # one pair of functions serves the batch, or Python does
            policy[:] = POLICY_PYTHON
        for b, tr in enumerate(trials):
            lo, hi = tr.lo, tr.hi
            tr.task, tr.last_circuit = task[lo:hi], last_circuit[lo:hi]
            state[lo:hi] = tr.state
            tr.state, tr.task_start = state[lo:hi], task_start[lo:hi]
            loaded_at[lo:hi] = tr.loaded_at
            tr.loaded_at = loaded_at[lo:hi]
            values[b], scores[b] = tr.values, tr.scores
            tr.values, tr.scores = values[b], scores[b]
            if policy[b] in (POLICY_EGREEDY, POLICY_SOFTMAX):
                q[lo:hi] = tr.policy.q
                tr.policy.q = q[lo:hi]
                learning[:, b] = tr.policy.epsilon, tr.policy.alpha, tr.policy.gamma, tr.policy.tau
            elif policy[b] == POLICY_STATIC:
                assignment[lo:hi] = tr.policy.assignment
        bundle = Arrivals(
            task, last_circuit, state, task_start, loaded_at, self.act_at_task, q, assignment, self.kind_of,
            self.source_of, self.sink_of, policy, *learning, time_unit_s, from_source, values, scores,
            np.array([p.state for p in points], dtype=np.uint64),
            np.zeros((LOG_ROWS, LOG_COLUMNS)), np.zeros(1, dtype=np.int64))
        return bundle, (points[0].next_uint32, points[0].next_double)

    # --- in Python ------------------------------------------------------------
    def serve(self, t: float) -> None:
        """Every robot flagged as arrived, at clock time t."""
        for g in np.flatnonzero(self.arrived).tolist():
            tr = self.trials[self.trial_of[g]]
            self.arrive(tr, g - tr.lo, t)

    def assign(self, tr: TrialState, i: int, t: float) -> None:
        """Robot i of trial tr picks its next circuit and heads for that circuit's source."""
        state = int(tr.state[i])
        try:
            circuit = check_choice(tr.spec.controller, i, state, tr.policy.choose(i, state), len(tr.values))
        except TavcError as error:  # the learner's own fault: this trial's, not the batch's
            raise TrialFault(int(self.trial_of[tr.lo]), str(error)) from None
        tr.rows.add("choices", t, i, state, circuit)
        tr.task[i] = circuit
        tr.task_start[i] = t
        self.act_at_task[tr.lo + i] = self._act_before_tick(tr.lo + i)
        # the robot finishes what it is doing at the dock it leaves before heading off
        self.target[tr.lo + i] = self.source_of[circuit]

    def arrive(self, tr: TrialState, i: int, t: float) -> None:
        """Robot i of trial tr reached its target at clock time t."""
        g = tr.lo + i
        target = int(self.target[g])
        circuit = int(tr.task[i])
        kind = int(self.kind_of[target])
        self.log_arrival(tr, t, i, target, circuit, kind)
        tr.last_circuit[i] = circuit
        if tr.learns_behaviours:
            tr.policy.arrived(i, float(tr.values[circuit]) / ((t - tr.last_arrival[i]) / tr.spec.time_unit_s))
            tr.last_arrival[i] = t
        if kind == SOURCE:
            tr.loaded_at[i] = t
            self.target[g] = self.sink_of[circuit]
            return
        task_time = t - tr.task_start[i]
        value = float(tr.values[circuit])
        # the reward's t: the whole task, or from the loading on (`TrialSpec.time_from_source`)
        reward = value / ((t - tr.loaded_at[i] if tr.spec.time_from_source else task_time) / tr.spec.time_unit_s)
        spent = self._act_before_tick(g) - self.act_at_task[g]
        tr.rows.add("deliveries", t, i, circuit, task_time, reward, value, float(tr.scores[circuit]), *spent)
        if tr.spec.t0_s + t >= 0.0:  # its time in the record is not negative
            tr.delivered += 1
        try:
            tr.policy.learn(i, int(tr.state[i]), circuit, reward, circuit)
        except TavcError as error:
            raise TrialFault(int(self.trial_of[tr.lo]), str(error)) from None
        tr.state[i] = circuit
        self.assign(tr, i, t)

    def _act_before_tick(self, g: int) -> np.ndarray:
        """Robot g's activity seconds up to the start of this tick: the tick in which a robot
        arrives is spent at the dock, on its next task (none yet before the first tick)."""
        spent = self.act_s[g].copy()
        if self.tick_started:
            spent[self.activity[g]] -= self.dt
        return spent

    # --- by compiled code -----------------------------------------------------
    def take_served(self) -> None:
        """The arrivals and deliveries compiled code served (`tick.serve_arrivals`), into their
        trials' tables as `arrive` and `assign` put them."""
        logged = self.bundle.logged
        if not logged[0]:
            return
        for row in self.bundle.log[:logged[0]].tolist():
            tick, g, target, circuit, kind = (int(x) for x in row[:5])
            tr = self.trials[self.trial_of[g]]
            t, i = tick * self.dt, g - tr.lo
            self.log_arrival(tr, t, i, target, circuit, kind)
            if kind != SOURCE:
                tr.rows.add("deliveries", t, i, circuit, *row[LOG_TASK_S:LOG_SCORE + 1], *row[LOG_SPENT:LOG_CHOICE])
                tr.rows.add("choices", t, i, circuit, int(row[LOG_CHOICE]))
        logged[0] = 0

    @staticmethod
    def log_arrival(tr: TrialState, t: float, i: int, target: int, circuit: int, kind: int) -> None:
        """Robot i of trial tr reached `target` (a SOURCE or SINK of `circuit`) at time t."""
        tr.rows.add("arrivals", t, i, target, circuit, kind)
