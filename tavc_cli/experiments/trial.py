"""One trial inside a batch (`engine.BatchEngine`): its random streams rebuilt from its seed,
where its team starts, its book-keeping (tasks, policy, events, what it records, and the
record made of it), and the fault that stops it alone."""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from tavc_cli.errors import TavcError
from tavc_cli.experiments.clock import due_tick
from tavc_cli.experiments.records import TableBuilder, TrialRecord
from tavc_cli.experiments.spec import TrialSpec
from tavc_cli.learning.policies import TaskPolicy
from tavc_cli.learning.registry import make_policy
from tavc_cli.sim.arena import START_GAP_M, START_WALL_MARGIN_M, Arena, clear_to_start
from tavc_cli.vocabulary import EventKind


class TrialFault(Exception):
    """A trial of a batch went wrong in a way that is its own (a non-finite pose, a robot
    outside the walls): `index` is its place in the batch, the message says what and when."""

    def __init__(self, index: int, message: str) -> None:
        """The fault of the batch's trial number `index`, told by `message`."""
        super().__init__(message)
        self.index = index


def seed_sequence(seed: Sequence[int]) -> np.random.SeedSequence:
    """Rebuild a trial's SeedSequence from its recorded (entropy, *spawn_key)."""
    return np.random.SeedSequence(entropy=int(seed[0]), spawn_key=tuple(int(s) for s in seed[1:]))


def start_poses(arena: Arena, radii: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """Random non-overlapping start poses, clear of the walls (interior ones too), random headings."""
    poses = np.zeros((len(radii), 3))
    for i, r in enumerate(radii):
        for _ in range(10_000):
            x = rng.uniform(START_WALL_MARGIN_M, arena.width_m - START_WALL_MARGIN_M)
            y = rng.uniform(START_WALL_MARGIN_M, arena.height_m - START_WALL_MARGIN_M)
            if all(math.hypot(x - poses[k, 0], y - poses[k, 1]) > r + radii[k] + START_GAP_M for k in range(i)) \
                    and clear_to_start(arena, x, y):
                break
        else:
            raise TavcError(f"team.n_robots: cannot place {len(radii)} robots of radius {r:g} m apart "
                            f"in the {arena.width_m:g} x {arena.height_m:g} m arena")
        poses[i] = (x, y, rng.uniform(-math.pi, math.pi))
    return poses


class TrialState:
    """Book-keeping of one trial inside a batch: tasks, policy, events, records."""

    def __init__(self, spec: TrialSpec, arena: Arena, lo: int) -> None:
        """The state of `spec`'s trial in `arena`, its robots the batch's rows from `lo`: its seeded
        streams, start poses, policy, tasks and tables."""
        self.spec = spec
        self.lo, self.hi = lo, lo + spec.n_robots
        ss = seed_sequence(spec.seed)
        start_ss, noise_ss, policy_ss, event_ss = ss.spawn(4)
        self.noise_rng = np.random.default_rng(noise_ss)
        self.event_rng = np.random.default_rng(event_ss)
        self.policy_rng = np.random.default_rng(policy_ss)
        radius = float(spec.robot.radius_m)
        n = spec.n_robots
        self.start = start_poses(arena, np.full(n, radius), np.random.default_rng(start_ss))
        self.policy: TaskPolicy = make_policy(spec.policy, n, arena.n_circuits, self.policy_rng)
        self.values = np.array(spec.values, dtype=np.float64)
        self.scores = np.array(spec.score_values, dtype=np.float64)
        self.state = self.policy_rng.integers(arena.n_circuits, size=n)  # class "last serviced"
        self.task = np.full(n, -1, dtype=np.int64)
        self.task_start = np.zeros(n)
        self.loaded_at = np.zeros(n)  # when each robot last reached its source, on the clock
        self.last_arrival = np.zeros(n)  # on the clock, for behaviour learners' r = w / t per arrival
        self.learns_behaviours = hasattr(self.policy, "decide")
        self.decide_ticks = (max(1, int(round(self.policy.decision_period_s / spec.dt_s)))
                             if self.learns_behaviours else 0)
        self.last_circuit = np.full(n, -1, dtype=np.int64)
        self.alive = np.ones(n, dtype=bool)
        self.delivered = 0  # deliveries after the warm-up, for a trial that ends with its n-th
        self.ended_clock: float | None = None  # when such a trial ended, on its clock
        self.rows = TableBuilder()  # times on the trial's clock (seconds since it started)
        self.events = clock_events(spec)
        self.vc_t: list[float] = []
        self.vc: list[np.ndarray] = []
        self.q_t: list[float] = []
        self.q: list[np.ndarray] = []
        self.pose_t: list[float] = []
        self.poses: list[np.ndarray] = []
        self.pose_alive: list[np.ndarray] = []
        self.pose_circuit: list[np.ndarray] = []
        self.tell_policy()

    def tell_policy(self) -> None:
        """A policy that follows the team's events (`learning.informed`) hears which robots are
        alive and the circuits' values: at the start and after every event."""
        hook = getattr(self.policy, "on_event", None)
        if hook is not None:
            hook(self.alive.copy(), self.values.copy())

    def next_event_time(self) -> float:
        """When the next scheduled event falls due, on the trial's clock."""
        return self.events[0][0] if self.events else math.inf

    def fire_events(self, t: float) -> list[int]:
        """Apply the events due at clock time t, in order: a breakdown marks its robot dead, a
        value change sets the values and the scores that follow their ranking. Returns the
        robots that broke down, for the engine to take out of the world."""
        broken = []
        while self.events and self.events[0][0] <= t:
            _, kind, ev = self.events.pop(0)
            if kind == EventKind.BREAKDOWN:
                robot = ev.robot if ev.robot is not None else self.pick_robot(ev.circuit)
                if not self.alive[robot]:
                    continue
                self.alive[robot] = False
                broken.append(robot)
                self.rows.add("breakdowns", t, robot)
            else:
                self.values[:] = ev.values  # in place: compiled code serves arrivals with these arrays
                # scores follow the values' ranking: the new high-value circuit earns the high score
                self.scores[np.argsort(-self.values, kind="stable")] = np.sort(self.spec.score_values)[::-1]
                self.vc_t.append(t)
                self.vc.append(self.values.copy())
            self.tell_policy()
        return broken

    def pick_robot(self, circuit: str | int | None) -> int:
        """A live robot, drawn from the trial's event stream, among those whose last target was
        on `circuit` ('high' or 'low' by the current values, or an index; None: any), else among
        those tasked to it, else among all live ones."""
        live = np.flatnonzero(self.alive)
        if circuit is None:
            pool = live
        else:
            if circuit == "high":
                c = int(np.argmax(self.values))
            elif circuit == "low":
                c = int(np.argmin(self.values))
            else:
                c = int(circuit)
            pool = live[self.last_circuit[live] == c]
            if len(pool) == 0:
                pool = live[self.task[live] == c]
            if len(pool) == 0:
                pool = live
        return int(self.event_rng.choice(pool))

    def snapshot_q(self, t: float) -> None:
        """Keep the learners' Q-tables as they are at clock time t (if they have any)."""
        q = self.policy.q_tables()
        if q is not None:
            self.q_t.append(t)
            self.q.append(q)

    def record(self, spec: TrialSpec, clock_s: float, arena_name: str, n_circuits: int) -> TrialRecord:
        """The trial's record as it stands at `clock_s` (or as it ended, for a trial that ended
        with its n-th delivery), as the trial `spec`: the times of its tables are the clock from
        that trial's `t0_s` (less its warm-up, or from its late start), its duration is the time
        of the record it ran to, and its Q-tables as they are now end the snapshots. Leaves this
        book-keeping as it was."""
        if self.ended_clock is not None:
            clock_s = self.ended_clock
        t0 = spec.t0_s
        q_t, q = list(self.q_t), list(self.q)
        if spec.q_snapshot_every_s > 0 and (not q_t or q_t[-1] < clock_s):
            final = self.policy.q_tables()
            if final is not None:
                q_t.append(clock_s)
                q.append(final)
        tables = self.rows.build()
        for cols in tables.values():
            cols["t_s"] = t0 + cols["t_s"]
        rec = TrialRecord(
            meta={
                "trial": spec.trial, "controller": spec.controller, "seed": list(spec.seed),
                "key": spec.key(), "n_robots": spec.n_robots, "n_circuits": n_circuits, "groups": list(spec.groups),
                "speeds_mps": list(spec.speeds_mps), "values": list(spec.values),
                "score_values": list(spec.score_values),
                "duration_s": spec.duration_s if self.ended_clock is None else clock_s + t0,
                "deliveries": spec.deliveries, "warmup_s": spec.warmup_s, "t0_s": t0, "dt_s": spec.dt_s,
                "arena": arena_name,
                "policy": spec.policy.name,
                "start_poses": self.start.tolist(),
            },
            tables=tables,
        )
        rec.value_changes_t = t0 + np.array(self.vc_t, dtype=np.float64)
        rec.value_changes = np.array(self.vc, dtype=np.float64).reshape(len(self.vc), n_circuits)
        if q:
            rec.q_t = t0 + np.array(q_t)
            rec.q = np.stack(q)
        if self.poses:
            rec.pose_t = t0 + np.array(self.pose_t)
            rec.poses = np.stack(self.poses)
            rec.pose_alive = np.stack(self.pose_alive)
            rec.pose_circuit = np.stack(self.pose_circuit)
        return rec

    def go_on_as(self, spec: TrialSpec, tick: int, dt: float) -> None:
        """From `tick` on, this trial is `spec`: its events still to come are the spec's that
        fall due at this tick or later (those before it are the ones this trial has had); a
        trial that has ended has none."""
        self.spec = spec
        self.events = [] if self.ended_clock is not None else [
            e for e in clock_events(spec) if due_tick(e[0], dt) >= tick]


def clock_events(spec: TrialSpec) -> list[tuple]:
    """The spec's scheduled events as (clock time, kind, event), in the order they fire: an
    event at time T of the record falls due at T - t0_s on the trial's clock."""
    events = ([(b.time_s - spec.t0_s, EventKind.BREAKDOWN, b) for b in spec.breakdowns]
              + [(v.time_s - spec.t0_s, EventKind.VALUE_CHANGE, v) for v in spec.value_changes])
    return sorted(events, key=lambda e: (e[0], e[1]))
