"""One trial on the surrogate: the physical engine's book-keeping (`TrialState`: the same seeds,
policy, initial learning states, events and record), with the world replaced by measured tasks.

Time runs on the physical engine's ticks (every time a multiple of the control period). Each
robot's task is drawn when it begins, from the measured tasks of the group's make-up at that
moment (this robot's new task included): its time, its arrival at the source and where its time
went. At the task's end the robot delivers, learns r = w / t exactly as in the simulator
(`arrivals.ArrivalDesk.arrive`) and chooses again. Scheduled events fire before the arrivals of
their tick, Q-tables are kept on the same grid, and a trial that ends with its n-th delivery ends
with that delivery's tick. The task-time draws come from a stream of their own, spawned from the
trial's seed after the simulator's four, so everything else draws what the simulator draws.
"""

# The order of the imports below is in the surrogate's code digest (`run.surrogate_code_digest`):
# sorting them would draw every surrogate trial again.
from __future__ import annotations  # noqa: I001

import heapq
import math

import numpy as np

from tavc_cli.vocabulary import ACTIVITIES
from tavc_cli.experiments.clock import due_tick, end_tick
from tavc_cli.experiments.records import TrialRecord
from tavc_cli.experiments.spec import TrialSpec
from tavc_cli.experiments.trial import TrialState, seed_sequence
from tavc_cli.sim.arena import arena_from_config
from tavc_cli.vocabulary import SINK, SOURCE
from tavc_cli.surrogate.tasks import STAY, SWITCH, Team, TaskTimes, makeup_name

N_STREAMS = 5  # the simulator's trial streams (start, noise, policy, events), then the surrogate's


def task_stream(spec: TrialSpec) -> np.random.Generator:
    """The generator of a trial's task-time draws: the fifth child of its seed."""
    return np.random.default_rng(seed_sequence(spec.seed).spawn(N_STREAMS)[N_STREAMS - 1])


class SurrogateTrial:
    """A trial of `spec` drawing its tasks from `times` (`stayers`: by robots per circuit only)."""

    def __init__(self, spec: TrialSpec, times: TaskTimes, *, stayers: bool = False) -> None:
        """The trial of `spec` (two circuits) drawing from `times`: the simulator's book-keeping and
        seeds, and the stream of its task-time draws."""
        self.spec, self.times, self.stayers = spec, times, stayers
        self.arena = arena_from_config(spec.arena)
        if self.arena.n_circuits != 2:
            raise ValueError("the surrogate serves two circuits")
        self.tr = TrialState(spec, self.arena, 0)
        self.rng = task_stream(spec)
        self.dt = spec.dt_s
        n = spec.n_robots
        self.switching = np.zeros(n, dtype=bool)  # whether each robot's task leaves the circuit it served
        self.ends = np.zeros(n, dtype=np.int64)  # the tick of each robot's delivery
        self.spent = np.zeros((n, len(ACTIVITIES)))  # where its task's time goes
        self.heap: list[tuple[int, int, int, int]] = []  # (tick, kind, robot, order)
        self.order = 0
        self._names: dict[tuple, tuple[str, str]] = {}  # the make-ups met so far, by who does what

    # --- the group's make-up -------------------------------------------------
    def makeup(self) -> tuple[str, str]:
        """(team, make-up) of the live robots, as the measured table names them: by group, the
        robots whose task stays on circuit 0, on circuit 1, and those whose task switches."""
        tr, spec = self.tr, self.spec
        key = (tr.alive.tobytes(), tr.task.tobytes(), self.switching.tobytes())
        named = self._names.get(key)
        if named is None:
            live = np.flatnonzero(tr.alive)
            team = Team.of([spec.groups[i] for i in live], [spec.speeds_mps[i] for i in live])
            counts = {g: [0, 0, 0] for g, _, _ in team.groups}
            for i in live:
                c = int(tr.task[i])
                counts[spec.groups[i]][c if (self.stayers or not self.switching[i]) else 2] += 1
            named = team.name, makeup_name(team, tuple(tuple(counts[g]) for g, _, _ in team.groups))
            self._names[key] = named
        return named

    # --- tasks ---------------------------------------------------------------
    def begin(self, i: int, tick: int, draw: bool = True) -> None:
        """Robot i chooses its next circuit at `tick` (as `ArrivalDesk.assign`) and, with
        `draw`, its task is drawn."""
        tr = self.tr
        t = tick * self.dt
        circuit = tr.policy.choose(i, int(tr.state[i]))
        tr.rows.add("choices", t, i, int(tr.state[i]), circuit)
        self.switching[i] = circuit != int(tr.state[i])
        tr.task[i] = circuit
        tr.task_start[i] = t
        if draw:
            self.draw(i, tick)

    def draw(self, i: int, tick: int) -> None:
        """Draw robot i's task at `tick` from its make-up's measured tasks: its source and sink
        arrivals scheduled, its time split among the activities."""
        tr, spec = self.tr, self.spec
        team, makeup = self.makeup()
        kind = SWITCH if (self.switching[i] and not self.stayers) else STAY
        row = self.times.draw(team, makeup, spec.groups[i], kind, int(tr.task[i]), self.rng)
        task_ticks = max(1, int(round(row[0] / self.dt)))
        source = row[1] if math.isfinite(row[1]) else row[0] / 2
        source_ticks = min(task_ticks, max(0, int(round(source / self.dt))))
        self.spent[i] = row[2:] * (task_ticks * self.dt / row[0]) if row[0] > 0 else row[2:]
        self.ends[i] = tick + task_ticks
        self.push(tick + source_ticks, SOURCE, i)
        self.push(tick + task_ticks, SINK, i)

    def push(self, tick: int, kind: int, i: int) -> None:
        """Schedule robot i's arrival of `kind` at `tick`."""
        # at one tick, robots arrive in their index order, sources before sinks
        heapq.heappush(self.heap, (tick, kind, i, self.order))
        self.order += 1

    def arrive(self, i: int, tick: int, kind: int) -> None:
        """Robot i reaches its source or sink at `tick` (as `ArrivalDesk.arrive`)."""
        tr, spec = self.tr, self.spec
        t = tick * self.dt
        circuit = int(tr.task[i])
        target = self.arena.circuits[circuit].source if kind == SOURCE else self.arena.circuits[circuit].sink
        tr.rows.add("arrivals", t, i, target, circuit, kind)
        tr.last_circuit[i] = circuit
        if kind == SOURCE:
            return
        task_time = t - tr.task_start[i]
        value = float(tr.values[circuit])
        reward = value / (task_time / spec.time_unit_s)
        tr.rows.add("deliveries", t, i, circuit, task_time, reward, value, float(tr.scores[circuit]), *self.spent[i])
        if spec.t0_s + t >= 0.0:
            tr.delivered += 1
        tr.policy.learn(i, int(tr.state[i]), circuit, reward, circuit)
        tr.state[i] = circuit
        self.begin(i, tick)

    # --- the run -------------------------------------------------------------
    def run(self) -> TrialRecord:
        """Run the trial to its end (its duration, or its n-th delivery) and return its record."""
        tr, spec, dt = self.tr, self.spec, self.dt
        n_ticks = end_tick(spec.t0_s, spec.duration_s, dt)
        for i in range(spec.n_robots):  # every robot chooses at the start, then the tasks are drawn
            self.begin(i, 0, draw=False)
        for i in range(spec.n_robots):
            self.draw(i, 0)
        next_q = 0 if spec.q_snapshot_every_s > 0 else None
        q_every = due_tick(spec.q_snapshot_every_s, dt) if next_q is not None else 0
        ended = False
        while not ended:
            events = due_tick(tr.next_event_time(), dt) if math.isfinite(tr.next_event_time()) else n_ticks + 1
            arrival = self.heap[0][0] if self.heap else n_ticks + 1
            tick = min(events, arrival, next_q if next_q is not None else n_ticks + 1)
            if tick >= n_ticks:
                break
            if tick == events:
                tr.fire_events(tick * dt)
            if next_q is not None and tick == next_q:
                tr.snapshot_q(tick * dt)
                next_q += q_every
            while self.heap and self.heap[0][0] == tick:
                _, kind, i, _ = heapq.heappop(self.heap)
                if not tr.alive[i] or (kind == SINK and self.ends[i] != tick):
                    continue
                self.arrive(i, tick, kind)
                if spec.deliveries is not None and tr.delivered >= spec.deliveries:
                    tr.ended_clock = (tick + 1) * dt
                    ended = True
                    break
        return tr.record(spec, n_ticks * dt, self.arena.name, self.arena.n_circuits)


def run_trial(spec: TrialSpec, times: TaskTimes, *, stayers: bool = False) -> TrialRecord:
    """The record of one trial of `spec` on the surrogate."""
    return SurrogateTrial(spec, times, stayers=stayers).run()
