"""Advance a batch of trials together: the transport loop over the physical world.

Each trial has its own pymunk space, its own random streams and its own policy,
so it computes the same alone or in any batch. The batch shares one batched read
and write of the physics and one call of the compiled sensing and behaviour kernel
per tick for every robot of every trial. Python runs per event (a breakdown, a
value change, a snapshot), never per robot per tick: between events whole ticks run
in compiled code (`tick.run_ticks`), which serves arrivals and deliveries too (the
rewards, the Q-learning and the next choices of the TAVC policies, epsilon-greedy or
Boltzmann, and of the random and static ones, drawn from each trial's own generator),
except with section 1.4's behaviour learners, whose robots choose a behaviour in Python
when their sensed state changes, so that their batches go tick by tick, and with trials
that end with their n-th delivery, which Python counts.

Per tick (`BatchEngine.run`): what falls due (events, snapshots, pose frames) ->
behaviour choices of section 1.4's learners -> sense and decide (the kernel, over
the bundles of `behaviours.layout`) -> serve arrivals (rewards, next tasks: the
`arrivals.ArrivalDesk`, in Python or by compiled code) -> move
(wheel commands to the physics, one control period of it).

Time: a trial runs on its own clock, `tick * dt` seconds since it started; rewards,
events and snapshots go by it. A record's times are that clock less the trial's
warm-up (`t0 + clock`, t0 = -warmup_s), so t = 0 is the end of the warm-up; a trial
that starts late (a baseline that has nothing to learn, `TrialSpec.start_s`) has
t0 = start_s, and its record begins there. Since
nothing a trial computes depends on its warm-up's length, a trial with a warm-up is
the trial without one, continued: `branch` turns a batch, mid-run, into trials whose
history so far is the same and whose futures differ (`experiments.lineage`).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from functools import cached_property

import numpy as np

from tavc_cli.behaviours.layout import build_arena, build_laser, build_params, build_robots, empty_scan, empty_work
from tavc_cli.behaviours.navigation import behave, compiled
from tavc_cli.experiments.arrivals import ArrivalDesk
from tavc_cli.experiments.clock import Schedule, end_tick, next_multiple
from tavc_cli.experiments.records import TrialRecord
from tavc_cli.experiments.spec import TrialSpec
from tavc_cli.experiments.tick import (
    NOISE_BLOCK_TICKS,
    RUN_ARRIVED,
    RUN_DUE,
    RUN_LOST_BODIES,
    run_ticks,
    sense_decide_command,
    serve_arrivals,
)
from tavc_cli.experiments.trial import TrialFault, TrialState
from tavc_cli.learning.behaviour import BatchDecisions
from tavc_cli.sim.sensors import camera_nearest, cast_laser, odometry_update
from tavc_cli.sim.world import (
    CP_EACH_BODY,
    CP_STEP,
    PhysicsWorld,
    read_bodies,
    read_poses,
    write_and_step,
    write_commands,
)
from tavc_cli.vocabulary import N_ACT


class BatchEngine:
    """Runs trials of one arena and robot model side by side, tick by tick."""

    def __init__(self, specs: Sequence[TrialSpec]) -> None:
        """A batch of `specs`, which must share the arena, the robot model and the time step: their
        trials' book-keeping, one physics world and the kernel's arrays."""
        if not specs:
            raise ValueError("a batch needs at least one trial")
        first = specs[0]
        self.arena = first.build_arena()
        for s in specs[1:]:
            if (s.arena, s.robot, s.dt_s) != (first.arena, first.robot, first.dt_s):
                raise ValueError("trials in one batch must share arena, robot model and time step")
        self.dt = first.dt_s
        robot = first.robot
        self.trials: list[TrialState] = []
        lo = 0
        for spec in specs:
            self.trials.append(TrialState(spec, self.arena, lo))
            lo += spec.n_robots
        n = lo
        self.n = n
        self.world = PhysicsWorld(
            self.arena, [tr.start for tr in self.trials], float(robot.radius_m), float(robot.mass_kg),
            float(robot.drive_force_n), float(robot.drive_torque_nm),
            first.dt_s, first.physics_substeps, first.solver_iterations,
        )
        # the kernel's bundles (behaviours.layout): robots, shared parameters, arena, laser, scan
        start = np.concatenate([tr.start for tr in self.trials])
        self.robots = build_robots(robot, np.concatenate([tr.spec.speeds_mps for tr in self.trials]),
                                   [(tr.lo, tr.hi) for tr in self.trials], start)
        # the camera is read only by section 1.4's learners
        self.params = build_params(robot, self.arena, self.dt,
                                   camera_on=any(tr.learns_behaviours for tr in self.trials))
        self.geometry = build_arena(self.arena)
        self.laser = build_laser(float(robot.laser.fov_deg), int(robot.laser.n_rays))
        self.scan = empty_scan(n, len(self.laser.angle_rad))
        self.work = empty_work(n, len(self.laser.angle_rad))
        self.pose = start.copy()  # true poses, read from the physics every tick
        self.noise = np.zeros((NOISE_BLOCK_TICKS, n, 3))
        self.cmd = np.zeros((n, 2))
        # seconds each robot spent in each activity (activities.ACTIVITIES), in all and at its task's start
        self.act_s = np.zeros((n, N_ACT))
        self.desk = ArrivalDesk(self.trials, self.arena, self.robots, self.act_s, self.dt)
        self.tick = 0  # every trial's clock is tick * dt
        self.schedule = Schedule(self.trials)
        self.on_tick: Callable[[BatchEngine], None] | None = None
        self._leaving: list[TrialState] = []  # trials that ended with a delivery, robots still in the world
        self._all_ended = False  # every trial ended with its n-th delivery (`_end_delivered`)
        learners = [(tr.lo, tr.hi, tr.policy, tr.decide_ticks) for tr in self.trials if tr.learns_behaviours]
        self._decisions = BatchDecisions(self.robots, self.scan.camera, learners) if learners else None
        self._params = np.array([self.params], dtype=self.params.dtype)
        for tr in self.trials:
            for i in range(tr.spec.n_robots):
                self.desk.assign(tr, i, 0.0)

    # --- compiled code ---------------------------------------------------------
    @cached_property
    def _kernel(self):
        """`tick.sense_decide_command`, compiled (or loaded from numba's cache) for this batch's
        bundles when first needed."""
        return compiled(sense_decide_command, self.world.io, self.pose, self.robots, self.noise[0], self._params,
                        self.geometry, self.laser, self.scan, self.cmd, self.act_s, self.work)

    @cached_property
    def _run(self):
        """`tick.run_ticks`, likewise."""
        return compiled(run_ticks, self.world.space_io, CP_EACH_BODY, CP_STEP, self.world.io, self.pose,
                        self.robots, self.noise, self._params, self.geometry, self.laser, self.scan, self.cmd,
                        self.act_s, self.work, self.desk.bundle, *self.desk.draws, 0, 0, 0.0, 0.0, 0.0, False)

    def compile(self) -> BatchEngine:
        """Compile (or load) both entry points now rather than when first needed."""
        _ = self._kernel, self._run
        return self

    def kernel_parts(self) -> tuple[list[tuple], list[tuple]]:
        """The kernels below this batch's two entry points, as (kernel, arguments) with arguments
        of the types they are called with, in two parts of similar compile time, neither calling
        into the other: the behaviours (about half of the whole), and the sensors, the serving of
        arrivals and the physics' input and output. Compiled apart, the two fill numba's cache,
        and the entry points then compile only what is their own."""
        r, k = np.int64(0), np.int64(0)
        record = self._params[0]
        behaviours = [(behave, (r, self.robots, self.pose, record, self.geometry, self.laser, self.scan, self.cmd,
                                self.work))]
        world = self.world
        rest = [(cast_laser, (r, self.robots, self.pose, self.laser, self.geometry, record, self.scan)),
                (camera_nearest, (r, self.robots, self.pose, self.geometry, record, self.scan)),
                (odometry_update, (r, self.robots, self.pose, self.noise[0])),
                (serve_arrivals, (self.robots, self.desk.bundle, k, float(self.dt), self.act_s, *self.desk.draws)),
                (read_poses, (world.io, self.pose)), (write_commands, (world.io, self.cmd, self.scan.heading_cs)),
                (read_bodies, (world.space_io, CP_EACH_BODY)),
                (write_and_step, (world.space_io, CP_EACH_BODY, CP_STEP))]
        return behaviours, rest

    # --- time ---------------------------------------------------------------
    @property
    def clock(self) -> float:
        """Seconds since the trials started (their warm-ups included)."""
        return self.tick * self.dt

    def _remove(self, g: int) -> None:
        """Robot g (of the batch) out of the world and out of the kernel's loop."""
        self.world.remove(g)
        self.robots[g]["alive"] = False

    # --- the loop -----------------------------------------------------------
    def end_tick(self) -> int:
        """The tick at which the batch's trials end (warm-up and duration); they must end together."""
        ends = {end_tick(tr.spec.t0_s, tr.spec.duration_s, self.dt) for tr in self.trials}
        if len(ends) > 1:
            raise ValueError("trials run to their end in one batch must end at the same tick")
        return ends.pop()

    def run(self, progress: Callable[[float], None] | None = None,
            until_tick: int | None = None) -> list[TrialRecord] | None:
        """Advance until every trial reaches its duration (or has ended with its n-th delivery,
        `TrialSpec.deliveries`); return their records. With
        `until_tick`, advance only up to that tick (not served yet) and return None: the batch
        can go on from there, or `branch` first.

        Each tick, at clock time t (when it senses and decides): what falls due (scheduled
        events, Q-table snapshots, pose frames); section 1.4's learners choose
        behaviours; the kernel senses and decides for every robot; arrivals are
        served (rewards, next tasks); the physics moves the robots one period on.
        """
        n_ticks = self.end_tick() if until_tick is None else until_tick
        schedule = self.schedule
        start = self.tick
        report_every = max(1, (n_ticks - start) // 200)
        # runs of ticks in compiled code wherever nothing in between needs Python (not with
        # section 1.4's learners, who choose every tick, nor with a hook watching every tick,
        # nor with trials that end with a delivery, which Python counts)
        counting = any(tr.spec.deliveries is not None for tr in self.trials)
        runs = self._decisions is None and self.on_tick is None and not counting
        while self.tick < n_ticks and not self._all_ended:
            t = self.tick * self.dt
            if self._leaving:
                self._take_out_ended()
            if t >= schedule.next_due:
                self._fall_due(t, schedule)
            if self._decisions is not None:
                # section 1.4's learners read their five bits (a bar-code in the laser's view, the
                # random bit, the nearest robot's markings) and pick a behaviour where they changed
                self._decisions.decide(self.tick, t)
            if runs and self.tick % NOISE_BLOCK_TICKS and self.world.hand_over():
                # up to the next block of noise (drawn in Python) or progress report, at the latest
                stop = min(n_ticks, next_multiple(self.tick, NOISE_BLOCK_TICKS),
                           next_multiple(self.tick, report_every) if progress is not None else n_ticks)
                self._run_compiled(stop, schedule.next_due)
            else:
                n_arrived = self._sense_and_decide()
                if n_arrived:
                    self.desk.serve(t)
                    if counting:
                        self._end_delivered()
                self._move()
                self.tick += 1
            if self.on_tick is not None:
                self.on_tick(self)
            if progress is not None and self.tick % report_every == 0:
                progress((self.tick - start) / (n_ticks - start))
        if until_tick is not None:
            return None
        self.check()
        return [self.record(tr) for tr in self.trials]

    def branch(self, specs: Sequence[TrialSpec]) -> None:
        """Go on, from this tick, as the trials `specs` (one per trial of the batch, in order):
        trials whose history up to now is the batch's, so that they differ only in what is still
        to come (their events from this tick on, their ends, their warm-ups' lengths).
        `experiments.lineage` decides which trials may continue which."""
        if len(specs) != len(self.trials):
            raise ValueError("a branch names one trial for each trial of the batch")
        for tr, spec in zip(self.trials, specs, strict=True):
            tr.go_on_as(spec, self.tick, self.dt)
        self.schedule.update(self.trials)

    def _end_delivered(self) -> None:
        """End, with this tick, every trial whose robots have made the deliveries it ends with:
        it takes no snapshot, pose frame or event from here on, its record is the trial as it
        ended (`TrialState.record`), and its robots leave the world before the next tick (as a
        broken-down robot does, without a record of it; not in the middle of this one, whose
        wheel commands are ready for the bodies as they are)."""
        for b, tr in enumerate(self.trials):
            if tr.ended_clock is not None or tr.spec.deliveries is None or tr.delivered < tr.spec.deliveries:
                continue
            tr.ended_clock = (self.tick + 1) * self.dt
            tr.events = []
            self._leaving.append(tr)
            self.schedule.next_q[b] = self.schedule.next_pose[b] = math.inf
        if self._leaving:
            self.schedule.update(self.trials)
            self._all_ended = all(tr.ended_clock is not None for tr in self.trials)

    def _take_out_ended(self) -> None:
        """The robots of the trials that ended last tick out of the world."""
        for tr in self._leaving:
            for g in range(tr.lo, tr.hi):
                if self.robots[g]["alive"]:
                    self._remove(g)
        self._leaving = []

    def _run_compiled(self, stop: int, next_due: float) -> None:
        """The ticks up to `stop` (or to the first at which something falls due) in compiled code
        (`tick.run_ticks`), which serves arrivals and deliveries and logs them for the tables
        (`ArrivalDesk.take_served`), Python serving only the ticks it leaves (a delivery of a policy it
        does not run, a full log): the same work, in the same order, as the loop of `run`
        does it tick by tick."""
        world, move_first = self.world, False  # `run` has seen to what is due at the first tick
        while self.tick < stop:
            done, why = self._run(world.space_io, CP_EACH_BODY, CP_STEP, world.io, self.pose, self.robots, self.noise,
                                  self._params, self.geometry, self.laser, self.scan, self.cmd, self.act_s,
                                  self.work, self.desk.bundle, *self.desk.draws, self.tick, stop, 0.0, self.dt,
                                  next_due, move_first)
            self.desk.take_served()
            self.tick += done
            self.desk.tick_started = True
            move_first = why == RUN_ARRIVED
            if move_first:  # this tick's kernel ran: its arrivals here, its move back in compiled code
                self.desk.serve(self.clock)
            elif why == RUN_DUE:
                return
            elif why == RUN_LOST_BODIES:
                raise RuntimeError("the physics space holds bodies the world did not index")

    def _fall_due(self, t: float, schedule: Schedule) -> None:
        """Scheduled events, Q-table snapshots and pose frames that fall due at time t.

        Pose frames show where the robots are at t, before its events (a robot that
        breaks down at t is shown where it stopped).
        """
        poses = self.world.poses(out=np.empty_like(self.pose))
        for b, tr in enumerate(self.trials):
            for robot in tr.fire_events(t):
                self._remove(tr.lo + robot)
            if t >= schedule.next_q[b]:
                tr.snapshot_q(t)
                schedule.next_q[b] += tr.spec.q_snapshot_every_s  # on the schedule's own grid: no drift
            if t >= schedule.next_pose[b]:
                tr.pose_t.append(t)
                tr.poses.append(poses[tr.lo:tr.hi].copy())
                tr.pose_alive.append(tr.alive.copy())
                tr.pose_circuit.append(tr.task.copy())
                schedule.next_pose[b] += tr.spec.pose_every_s
        schedule.update(self.trials)

    def _sense_and_decide(self) -> int:
        """Read the physics, then the compiled kernel for every robot of every trial: odometry,
        laser, camera, behaviours; leaves the wheel commands ready for the world to write.
        Returns how many robots arrived."""
        k = self.tick % NOISE_BLOCK_TICKS
        world = self.world
        if k == 0:  # each trial's odometry noise, drawn from its own stream a block at a time
            for tr in self.trials:
                self.noise[:, tr.lo:tr.hi] = tr.noise_rng.standard_normal((NOISE_BLOCK_TICKS, tr.hi - tr.lo, 3))
            self._check_poses(world.poses(out=self.pose), self.clock)
        else:
            world.read()
        n_arrived = self._kernel(world.io, self.pose, self.robots, self.noise[k], self._params, self.geometry,
                                 self.laser, self.scan, self.cmd, self.act_s, self.work)
        self.desk.tick_started = True
        return n_arrived

    def _check_poses(self, pose: np.ndarray, t: float) -> None:
        """Raise `TrialFault` for the first trial with a robot whose pose is not a number or
        lies outside the arena's outer walls (by more than its radius): the physics has failed
        for that trial, and nothing it records from here on would mean anything. A lost pose
        stays lost, so a check every few hundred ticks finds it."""
        margin = float(self.trials[0].spec.robot.radius_m)
        x, y = pose[:, 0], pose[:, 1]
        with np.errstate(invalid="ignore"):
            bad = ~(np.isfinite(pose).all(axis=1) & (x >= -margin) & (x <= self.arena.width_m + margin)
                    & (y >= -margin) & (y <= self.arena.height_m + margin))
        bad &= self.robots["alive"]
        if not bad.any():
            return
        g = int(np.flatnonzero(bad)[0])
        b = int(self.robots[g]["trial"])
        i = g - self.trials[b].lo
        where = ("has no valid pose" if not np.isfinite(pose[g]).all()
                 else f"is outside the walls at ({x[g]:.2f}, {y[g]:.2f}) m")
        raise TrialFault(b, f"robot {i} {where} at t = {t + self.trials[b].spec.t0_s:.1f} s")

    def _move(self) -> None:
        """The wheel commands the kernel left to the physics, and one control period of it."""
        self.world.write()
        self.world.step()

    def record(self, tr: TrialState, spec: TrialSpec | None = None) -> TrialRecord:
        """Trial tr's record as it stands now, as the trial `spec` (by default its own), leaving
        the trial as it was so that it can go on (`branch`)."""
        return tr.record(spec or tr.spec, self.clock, self.arena.name, self.arena.n_circuits)

    def check(self) -> None:
        """Raise `TrialFault` for the first trial whose physics has failed (`_check_poses`)."""
        self._check_poses(self.world.poses(out=self.pose), self.clock)


def run_trials(specs: Sequence[TrialSpec], progress: Callable[[float], None] | None = None) -> list[TrialRecord]:
    """Run trials (sharing arena and robot model) side by side and return their records."""
    return BatchEngine(specs).run(progress)
