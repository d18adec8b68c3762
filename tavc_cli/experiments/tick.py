"""The compiled part of the engine's tick, and runs of whole ticks in compiled code.

`sense_decide_command` is one tick's compiled work: the true poses from the physics
state just read, the control kernel (`behaviours.navigation.control_tick`) for every
robot of every trial, the wheel commands into the velocities the world writes next.

`run_ticks` goes further: between the moments Python is needed (an arrival to serve, an
event, snapshot or pose frame due, a new block of odometry noise, a progress report) it
reads, decides, writes and steps the physics tick after tick without returning, calling
Chipmunk through the world's `SpaceIO`. Each tick does exactly what the Python loop
would do, in the same order, so the numbers are the same either way (checked by the tests).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from tavc_cli.behaviours.navigation import control_tick
from tavc_cli.sim.arena import SOURCE
from tavc_cli.sim.kernel import kernel
from tavc_cli.sim.world import read_bodies, read_poses, write_and_step, write_commands

NOISE_BLOCK_TICKS = 512  # odometry noise is drawn a block of ticks at a time; poses are checked as often

# why `run_ticks` stopped
RUN_DONE = 0         # it reached the tick it was told to stop at
RUN_ARRIVED = 1      # a robot delivered in the tick it stopped in: its arrivals, then the move, are Python's
RUN_DUE = 2          # something falls due at the tick it stopped at (nothing of that tick done)
RUN_LOST_BODIES = 3  # the space holds bodies the world did not index


class SourceArrivals(NamedTuple):
    """What compiled code needs to send a robot that reached its circuit's source on to the
    sink, which is all the engine does for such an arrival, and the log of those arrivals
    that it leaves for the engine to put in the trials' tables. Rows are robots of the batch."""

    task: np.ndarray          # (n,) int64: the circuit each robot serves (the engine's own array)
    last_circuit: np.ndarray  # (n,) int64: each robot's circuit at its last arrival (likewise)
    kind_of: np.ndarray       # (n_targets,) int64: SOURCE or SINK, per target
    sink_of: np.ndarray       # (n_circuits,) int64: each circuit's sink
    log: np.ndarray           # (capacity, 4) int64: tick, robot, target, circuit of each arrival
    logged: np.ndarray        # (1,) int64: rows of `log` in use


@kernel
def send_on_from_sources(robots, arrivals, tick):
    """If every robot that arrived in `tick` did so at a source, and the log has room for them:
    log each arrival, note its circuit as the robot's last, send the robot on to that circuit's
    sink, and return True. Otherwise change nothing and return False: a delivery needs the
    robot's policy, so the engine serves that tick's arrivals itself."""
    n = 0
    for g in range(robots.shape[0]):
        if robots[g].arrived:
            if arrivals.kind_of[robots[g].target] != SOURCE:
                return False
            n += 1
    log, logged = arrivals.log, arrivals.logged
    if logged[0] + n > log.shape[0]:
        return False
    for g in range(robots.shape[0]):
        if robots[g].arrived:
            circuit = arrivals.task[g]
            row = logged[0]
            log[row, 0] = tick
            log[row, 1] = g
            log[row, 2] = robots[g].target
            log[row, 3] = circuit
            logged[0] = row + 1
            arrivals.last_circuit[g] = circuit
            robots[g].target = arrivals.sink_of[circuit]
    return True


@kernel
def sense_decide_command(io, pose, robots, noise, params, arena, laser, scan, cmd, act_s, work):
    """The compiled part of a tick, in one call: the true poses from the physics state just read
    (`io`, the world's side), the control kernel for every robot, and the wheel commands
    into the velocities the world writes next. Returns how many robots arrived.

    `params` is the PARAMS record as an array of one (passing a bare record costs every
    call a description of its whole dtype, the bulk of the call's cost)."""
    read_poses(io, pose)
    n_arrived = control_tick(robots, pose, noise, params[0], arena, laser, scan, cmd, act_s, work)
    write_commands(io, cmd, scan.heading_cs)  # cos and sin of the headings, as the laser left them
    return n_arrived


@kernel
def run_ticks(sio, each_body, step, io, pose, robots, noise, params, arena, laser, scan, cmd, act_s, work,
              arrivals, tick, stop, t0_s, dt_s, next_due_s, move_first):
    """Whole ticks from `tick` up to `stop` (exclusive), each as the engine's Python loop does
    it: read the bodies, `sense_decide_command`, serve the arrivals, write the velocities,
    step. Arrivals at sources are served here (`send_on_from_sources`, logged in `arrivals`
    for the engine's tables). Stops early before a tick at whose time t0 + tick dt something
    is due (all but the first: the caller has seen to that one), in a tick in which a robot
    delivered (its kernel done, its arrivals and move not), or if the space's bodies are not
    the world's. `noise` is the block of odometry draws, row tick % NOISE_BLOCK_TICKS for each
    tick. With `move_first`, tick `tick` is one whose kernel has run and whose arrivals Python
    has served: its move comes first, then the ticks after it (the next one checked for what
    is due). Returns (ticks completed, RUN_*)."""
    n_numbers = io.state.size
    done = 0
    if move_first:
        write_and_step(sio, each_body, step)
        done = 1
    while tick + done < stop:
        k = tick + done
        if done > 0 and t0_s + k * dt_s >= next_due_s:
            return done, RUN_DUE
        if read_bodies(sio, each_body) != n_numbers:
            return done, RUN_LOST_BODIES
        if sense_decide_command(io, pose, robots, noise[k % NOISE_BLOCK_TICKS], params, arena, laser, scan,
                                cmd, act_s, work) and not send_on_from_sources(robots, arrivals, k):
            return done, RUN_ARRIVED
        write_and_step(sio, each_body, step)
        done += 1
    return done, RUN_DONE
