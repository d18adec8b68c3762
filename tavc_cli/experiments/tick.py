"""The compiled part of the engine's tick, and runs of whole ticks in compiled code.

`sense_decide_command` is one tick's compiled work: the true poses from the physics
state just read, the control kernel (`behaviours.navigation.control_tick`) for every
robot of every trial, the wheel commands into the velocities the world writes next.

`run_ticks` goes further: between the moments Python is needed (an event, snapshot or pose
frame due, a new block of odometry noise, a progress report, a delivery of a policy only
Python runs) it reads, decides, serves arrivals and deliveries, writes and steps the physics
tick after tick without returning, calling Chipmunk through the world's `SpaceIO`. Each tick
does exactly what the Python loop would do, in the same order, so the numbers are the same
either way (checked by the tests).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from tavc_cli.behaviours.navigation import control_tick
from tavc_cli.kernel import kernel
from tavc_cli.learning.compiled import (
    POLICY_EGREEDY,
    POLICY_PYTHON,
    POLICY_RANDOM,
    POLICY_SOFTMAX,
    egreedy,
    q_learn,
    softmax,
)
from tavc_cli.learning.draws import below
from tavc_cli.sim.world import read_bodies, read_poses, write_and_step, write_commands
from tavc_cli.vocabulary import N_ACT, SOURCE

NOISE_BLOCK_TICKS = 512  # odometry noise is drawn a block of ticks at a time; poses are checked as often

# why `run_ticks` stopped
RUN_DONE = 0         # it reached the tick it was told to stop at
RUN_ARRIVED = 1      # a robot arrived in the tick it stopped in, and Python serves it: its arrivals, then the move
RUN_DUE = 2          # something falls due at the tick it stopped at (nothing of that tick done)
RUN_LOST_BODIES = 3  # the space holds bodies the world did not index


# the columns of `Arrivals.log`: every arrival compiled code served, and for a delivery what
# its record and the robot's next choice hold
LOG_TICK, LOG_ROBOT, LOG_TARGET, LOG_CIRCUIT, LOG_KIND = range(5)
LOG_TASK_S, LOG_REWARD, LOG_VALUE, LOG_SCORE = range(5, 9)
LOG_SPENT = 9  # N_ACT columns: the task's seconds in each activity
LOG_CHOICE = LOG_SPENT + N_ACT  # the next circuit (chosen in the state LOG_CIRCUIT, the one just served)
LOG_COLUMNS = LOG_CHOICE + 1


class Arrivals(NamedTuple):
    """What compiled code needs to serve an arrival as the engine does: send a robot on from
    its source to the sink; at the sink, record the delivery, update the robot's Q-table and
    choose its next circuit (for trials whose policy `learning.compiled` runs; the others are
    left to the engine), drawing from the trial's own generator. Rows are robots of the batch
    unless said otherwise; every array is `arrivals.ArrivalDesk`'s (its trials' views, its policies'
    tables), so Python and compiled code serve arrivals alike."""

    task: np.ndarray          # (n,) int64: the circuit each robot serves
    last_circuit: np.ndarray  # (n,) int64: each robot's circuit at its last arrival
    state: np.ndarray         # (n,) int64: each robot's learning state (the circuit it last served)
    task_start: np.ndarray    # (n,) float64: when each robot's task began, on the clock
    loaded_at: np.ndarray     # (n,) float64: when each robot last reached its source, on the clock
    act_at_task: np.ndarray   # (n, N_ACT): its activity seconds as its task began
    q: np.ndarray             # (n, n_circuits, n_circuits): each robot's Q-table (TAVC trials)
    assignment: np.ndarray    # (n,) int64: each robot's circuit under a static policy
    kind_of: np.ndarray       # (n_targets,) int64: SOURCE or SINK, per target
    source_of: np.ndarray     # (n_circuits,) int64: each circuit's source
    sink_of: np.ndarray       # (n_circuits,) int64: each circuit's sink
    policy: np.ndarray        # (n_trials,) int64: `learning.compiled.POLICY_*`
    epsilon: np.ndarray       # (n_trials,) float64, and likewise alpha, gamma, tau
    alpha: np.ndarray
    gamma: np.ndarray
    tau: np.ndarray
    time_unit_s: np.ndarray   # (n_trials,) float64: the unit of t in r = w / t
    from_source: np.ndarray   # (n_trials,) bool: t runs from the loading at the source, not the choice
    values: np.ndarray        # (n_trials, n_circuits): learning values as they stand
    scores: np.ndarray        # (n_trials, n_circuits): score per delivery as they stand
    rng: np.ndarray           # (n_trials,) uint64: address of each trial's policy generator's state
    log: np.ndarray           # (capacity, LOG_COLUMNS) float64: the arrivals served, in order
    logged: np.ndarray        # (1,) int64: rows of `log` in use


@kernel
def serve_arrivals(robots, arr, tick, dt_s, act_s, next_uint32, next_double):
    """Serve every robot that arrived in `tick`, as `ArrivalDesk.arrive` does, and log each
    arrival; return True. If a robot delivered for a trial whose policy only Python runs, or
    the log has no room for them all, change nothing and return False: the engine serves
    that tick's arrivals itself."""
    n = 0
    for g in range(robots.shape[0]):
        if robots[g].arrived:
            n += 1
            if arr.kind_of[robots[g].target] != SOURCE and arr.policy[robots[g].trial] == POLICY_PYTHON:
                return False
    log, logged = arr.log, arr.logged
    if logged[0] + n > log.shape[0]:
        return False
    t = tick * dt_s
    for g in range(robots.shape[0]):
        rob = robots[g]
        if not rob.arrived:
            continue
        circuit, target = arr.task[g], rob.target
        kind = arr.kind_of[target]
        row = logged[0]
        logged[0] = row + 1
        log[row, LOG_TICK] = tick
        log[row, LOG_ROBOT] = g
        log[row, LOG_TARGET] = target
        log[row, LOG_CIRCUIT] = circuit
        log[row, LOG_KIND] = kind
        arr.last_circuit[g] = circuit
        if kind == SOURCE:
            arr.loaded_at[g] = t
            rob.target = arr.sink_of[circuit]
            continue
        b = rob.trial
        task_s = t - arr.task_start[g]
        value = arr.values[b, circuit]
        reward = value / (((t - arr.loaded_at[g]) if arr.from_source[b] else task_s) / arr.time_unit_s[b])
        log[row, LOG_TASK_S] = task_s
        log[row, LOG_REWARD] = reward
        log[row, LOG_VALUE] = value
        log[row, LOG_SCORE] = arr.scores[b, circuit]
        # the activity seconds up to this tick (which is spent at the dock, on the next task)
        for a in range(act_s.shape[1]):
            before = act_s[g, a] - dt_s if a == rob.activity else act_s[g, a]
            log[row, LOG_SPENT + a] = before - arr.act_at_task[g, a]
            arr.act_at_task[g, a] = before
        policy = arr.policy[b]
        if policy == POLICY_EGREEDY or policy == POLICY_SOFTMAX:  # TAVC: learn, then choose
            q_learn(arr.q[g], arr.state[g], circuit, reward, circuit, arr.alpha[b], arr.gamma[b])
        if policy == POLICY_EGREEDY:
            choice = egreedy(arr.q[g, circuit], arr.epsilon[b], next_uint32, next_double, arr.rng[b])
        elif policy == POLICY_SOFTMAX:
            choice = softmax(arr.q[g, circuit], arr.tau[b], next_double, arr.rng[b])
        elif policy == POLICY_RANDOM:
            choice = below(next_uint32, arr.rng[b], arr.q.shape[1])
        else:
            choice = arr.assignment[g]
        arr.state[g] = circuit
        log[row, LOG_CHOICE] = choice
        arr.task[g] = choice
        arr.task_start[g] = t
        rob.target = arr.source_of[choice]
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
              arrivals, next_uint32, next_double, tick, stop, t0_s, dt_s, next_due_s, move_first):
    """Whole ticks from `tick` up to `stop` (exclusive), each as the engine's Python loop does
    it: read the bodies, `sense_decide_command`, serve the arrivals, write the velocities,
    step. Arrivals are served here (`serve_arrivals`, drawing through `next_uint32` and
    `next_double`, the policies' bit generator's; logged in `arrivals` for the engine's
    tables). Stops early before a tick at whose time t0 + tick dt something is due (all but
    the first: the caller has seen to that one), in a tick with an arrival left to Python
    (its kernel done, its arrivals and move not), or if the space's bodies are not the
    world's. `noise` is the block of odometry draws, row tick % NOISE_BLOCK_TICKS for each
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
                                cmd, act_s, work) and not serve_arrivals(robots, arrivals, k, dt_s, act_s,
                                                                         next_uint32, next_double):
            return done, RUN_ARRIVED
        write_and_step(sio, each_body, step)
        done += 1
    return done, RUN_DONE
