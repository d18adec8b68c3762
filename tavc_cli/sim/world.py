"""The physical world: a batch of trials, each in its own pymunk space.

Robots are discs with a mass. Each is driven, as in pymunk's `tank.py` example,
through a kinematic control body joined to it by a pivot joint and a gear joint
whose forces are bounded: the control body carries the commanded velocity and the
joints pull the robot toward it with at most the drive's force and torque. A robot
pushing into another or a wall is therefore stopped by contact forces instead of
being teleported through it, and the sideways pull of the pivot joint plays the
part of the wheels' lateral grip.

Every trial of a batch has a space of its own, with its own walls, so a trial computes
exactly what it computes alone, whatever its batch, its slot in it and however long it
runs: nothing of another trial is in its spatial index or its solver. (When trials
shared one space, kept apart by collision filters, Chipmunk's order of solving one
trial's contacts came to depend on the other trials' shapes, and a long trial departed
from itself alone.) One batched call still serves them all: poses are read and
velocities written for every body of every space at once, through pymunk.batch's
iterators into one buffer, and compiled code steps the spaces one after another.
"""

from __future__ import annotations

import ctypes
import math
from collections.abc import Sequence
from typing import NamedTuple

import numpy as np
import pymunk
import pymunk.batch as pb
from pymunk._chipmunk_cffi import ffi, lib

from tavc_cli.kernel import kernel
from tavc_cli.sim.arena import Arena

_FIELDS_READ = pb.BodyFields.POSITION | pb.BodyFields.ANGLE | pb.BodyFields.VELOCITY | pb.BodyFields.ANGULAR_VELOCITY
_FIELDS_WRITE = pb.BodyFields.VELOCITY | pb.BodyFields.ANGULAR_VELOCITY
# pymunk's default collision slop (0.1) suits pixels; robots here are metres across
COLLISION_SLOP_M = 0.002
WALL_FRICTION = 0.3
ROBOT_FRICTION = 0.3


class BodyIO(NamedTuple):
    """The world's side of a tick, for compiled code: where each live robot's bodies sit in the
    batch buffers, the state last read and the velocities to write. Valid until a robot is
    removed (`PhysicsWorld.io` is then rebuilt)."""

    state: np.ndarray         # (n_bodies, 6) x m, y m, angle rad, vx, vy m/s, omega rad/s, as last read
    velocities: np.ndarray    # (n_bodies, 3) vx, vy m/s, omega rad/s, set on every body by a write
    robot_rows: np.ndarray    # (n_live,) row of each live robot's disc
    control_rows: np.ndarray  # (n_live,) row of its kinematic control body
    live: np.ndarray          # (n_live,) the live robots' numbers


@kernel
def read_poses(io, out):
    """out[i] = (x, y, heading) of each live robot i, from the state last read; other rows untouched."""
    for k in range(io.live.shape[0]):
        i, row = io.live[k], io.robot_rows[k]
        for c in range(3):
            out[i, c] = io.state[row, c]


@kernel
def heading_frames(io, out):
    """out[i] = (cos, sin) of each live robot i's heading, from the state last read (as the
    laser's kernel leaves them in `Scan.heading_cs`); other rows untouched."""
    for k in range(io.live.shape[0]):
        th = io.state[io.robot_rows[k], 2]
        out[io.live[k], 0] = math.cos(th)
        out[io.live[k], 1] = math.sin(th)


@kernel
def write_commands(io, cmd, heading_cs):
    """Every body keeps its velocity, but each control body carries its robot's command
    cmd[i] = (forward m/s, turn rad/s), turned into the frame of the robot's heading, whose
    cosine and sine are heading_cs[i] (for the heading last read: see `heading_frames`)."""
    state, out = io.state, io.velocities
    for b in range(state.shape[0]):
        out[b, 0] = state[b, 3]
        out[b, 1] = state[b, 4]
        out[b, 2] = state[b, 5]
    for k in range(io.live.shape[0]):
        i = io.live[k]
        row = io.control_rows[k]
        out[row, 0] = cmd[i, 0] * heading_cs[i, 0]
        out[row, 1] = cmd[i, 0] * heading_cs[i, 1]
        out[row, 2] = cmd[i, 1]


def _address(cdata) -> int:
    return int(ffi.cast("uintptr_t", cdata))


# Chipmunk's entry points as ctypes functions, for compiled code that reads, writes and steps
# the space itself: numba calls a ctypes function handed to it as an argument through its
# address (pointers are passed as integers of their width)
CP_EACH_BODY = ctypes.CFUNCTYPE(None, ctypes.c_size_t, ctypes.c_size_t, ctypes.c_size_t)(
    _address(ffi.addressof(lib, "cpSpaceEachBody")))
CP_STEP = ctypes.CFUNCTYPE(None, ctypes.c_size_t, ctypes.c_double)(_address(ffi.addressof(lib, "cpSpaceStep")))


class SpaceIO(NamedTuple):
    """The Chipmunk spaces as compiled code drives them (`read_bodies`, `write_and_step`, with
    `CP_EACH_BODY` and `CP_STEP`): the addresses of the spaces, of pymunk.batch's get and set
    iterators and of their requests, the headers of the two batch arrays, and the step.
    Valid while the world's `BodyIO` is."""

    spaces: np.ndarray        # uint64 address of each trial's cpSpace, in slot order
    get_iterator: int
    set_iterator: int
    read_request: int
    write_request: int
    read_header: np.ndarray   # int32 (num, max) of the read array: a get appends from num
    write_header: np.ndarray  # int32 (num, max) of the write array: a set reads num numbers
    h_s: float                # one Chipmunk step
    substeps: int             # Chipmunk steps per control period


@kernel
def read_bodies(sio, each_body):
    """Every body's state into the read array (`BodyIO.state`), space after space, as
    `PhysicsWorld.read` does it; returns how many numbers came (6 a body)."""
    sio.read_header[0] = 0
    for space in sio.spaces:
        each_body(space, sio.get_iterator, sio.read_request)
    return sio.read_header[0]


@kernel
def step_only(sio, step, n_ticks):
    """`n_ticks` control periods of physics and nothing else, every body keeping its velocity
    (alone, it measures what the physics costs)."""
    for _ in range(n_ticks):
        for space in sio.spaces:
            for _ in range(sio.substeps):
                step(space, sio.h_s)


@kernel
def write_and_step(sio, each_body, step):
    """Every body's velocity from `BodyIO.velocities`, then one control period of physics: as
    `PhysicsWorld.write` and `PhysicsWorld.step` do it while pymunk has nothing pending."""
    filled = sio.write_header[0]
    sio.write_header[0] = 0
    for space in sio.spaces:
        each_body(space, sio.set_iterator, sio.write_request)
    sio.write_header[0] = filled
    step_only(sio, step, 1)


class _BodyIteration:
    """One batched get or set of every body's fields, as `pymunk.batch.get_space_bodies` and
    `set_space_bodies` do it, with the request built once instead of on every call (a tenth
    of the time of a tick went there). Uses pymunk.batch's C iterators and its Buffer's
    array (pymunk 7)."""

    def __init__(self, spaces: Sequence[pymunk.Space], fields: pb.BodyFields, buffer: pb.Buffer,
                 iterator: str) -> None:
        self._is_set = "Set" in iterator
        self._request = ffi.new("pmBatchedData *")
        self._request.fields = fields.value
        self._request.floatArray = buffer._float_arr
        self._request.intArray = buffer._int_arr
        self._array = buffer._float_arr
        self._spaces = [space._space for space in spaces]
        self._iterator = ffi.addressof(lib, iterator)
        self._buffer = buffer  # keeps the arrays alive

    def __call__(self) -> None:
        filled = self._array.num  # a set leaves it as it found it
        self._array.num = 0  # a get appends from the start, a set reads from it: space after space
        for space in self._spaces:
            lib.cpSpaceEachBody(space, self._iterator, self._request)
        if self._is_set:
            self._array.num = filled


class PhysicsWorld:
    """One pymunk space per trial slot, each a walled arena with a driven disc per robot.

    Robots are numbered 0..n-1 across all slots; `slot_of[i]` says whose space robot
    i lives in.
    """

    @staticmethod
    def _space(iterations: int) -> pymunk.Space:
        space = pymunk.Space()
        space.iterations = iterations
        space.collision_slop = COLLISION_SLOP_M
        space.gravity = (0.0, 0.0)
        return space

    def __init__(
        self,
        arena: Arena,
        start_poses: Sequence[np.ndarray],
        radius_m: float,
        mass_kg: float,
        drive_force_n: float,
        drive_torque_nm: float,
        dt_s: float,
        substeps: int = 1,
        iterations: int = 10,
    ) -> None:
        """One space per entry of `start_poses` (the slots' robots at their poses), with the arena's
        walls and a disc of `radius_m` and `mass_kg` per robot, driven by `drive_force_n` and
        `drive_torque_nm`, stepped `substeps` times per `dt_s` with `iterations` solver
        iterations."""
        self.spaces = [self._space(iterations) for _ in start_poses]
        self.h = dt_s / substeps
        self.substeps = substeps
        slots = [np.full(len(p), k, dtype=np.int64) for k, p in enumerate(start_poses)]
        self.slot_of = np.concatenate(slots) if slots else np.zeros(0, dtype=np.int64)
        self.n_robots = len(self.slot_of)
        for space in self.spaces:
            for x1, y1, x2, y2 in arena.walls:
                seg = pymunk.Segment(space.static_body, (x1, y1), (x2, y2), 0.0)
                seg.friction = WALL_FRICTION
                space.add(seg)
        poses = np.concatenate([np.asarray(p, dtype=np.float64) for p in start_poses])
        moment = pymunk.moment_for_circle(mass_kg, 0, radius_m)
        self._parts: list[tuple] = []
        for (x, y, th), slot in zip(poses, self.slot_of, strict=True):
            body = pymunk.Body(mass_kg, moment)
            body.position = (float(x), float(y))
            body.angle = float(th)
            shape = pymunk.Circle(body, radius_m)
            shape.friction = ROBOT_FRICTION
            control = pymunk.Body(body_type=pymunk.Body.KINEMATIC)
            control.position = body.position
            pivot = pymunk.PivotJoint(control, body, (0, 0), (0, 0))
            gear = pymunk.GearJoint(control, body, 0.0, 1.0)
            for joint, limit in ((pivot, drive_force_n), (gear, drive_torque_nm)):
                joint.max_force = limit
                # match velocities only, never yank the robot to a position: with no bias allowed, any
                # correction of the joint's position error is clamped to zero. Its rate is then moot;
                # an error bias of 0 gives the very same zeros for less work, as Chipmunk's power of
                # the error bias, taken every step, returns at once for a base of 0
                joint.max_bias = 0.0
                joint.error_bias = 0.0
            self.spaces[slot].add(body, shape, control, pivot, gear)
            self._parts.append((body, shape, control, pivot, gear))
        self.alive = np.ones(self.n_robots, dtype=bool)
        self._read = pb.Buffer()
        self._write = pb.Buffer()
        self._poses = poses.copy()
        self._heading_cs = np.zeros((self.n_robots, 2))
        self._index_bodies()

    def _index_bodies(self) -> None:
        """Map batch-buffer rows to robots (pymunk reorders bodies on removal)."""
        self._read.clear()
        for space in self.spaces:  # appended space after space, as every read and write goes
            pb.get_space_bodies(space, pb.BodyFields.BODY_ID, self._read)
        ids = np.frombuffer(self._read.int_buf(), dtype=np.uintp)
        row = {int(b): k for k, b in enumerate(ids)}
        live = np.flatnonzero(self.alive)
        self._removed = np.flatnonzero(~self.alive)
        n_bodies = len(ids)
        wbuf = np.zeros(3 * n_bodies)
        self._write.set_float_buf(wbuf)
        # the state is read straight into this array: one spare row, so that pymunk's array
        # never fills up and never reallocates memory it does not own
        self._rbuf = np.zeros(6 * (n_bodies + 1))
        self._read.set_float_buf(self._rbuf)
        self.io = BodyIO(
            state=self._rbuf[:6 * n_bodies].reshape(n_bodies, 6),
            velocities=wbuf.reshape(n_bodies, 3),
            robot_rows=np.array([row[self._parts[i][0].id] for i in live], dtype=np.int64),
            control_rows=np.array([row[self._parts[i][2].id] for i in live], dtype=np.int64),
            live=live,
        )
        self._get = _BodyIteration(self.spaces, _FIELDS_READ, self._read, "pmSpaceBodyGetIteratorFuncBatched")
        self._set = _BodyIteration(self.spaces, _FIELDS_WRITE, self._write, "pmSpaceBodySetIteratorFuncBatched")
        self.space_io = SpaceIO(
            spaces=np.array([_address(space._space) for space in self.spaces], dtype=np.uint64),
            get_iterator=_address(self._get._iterator), set_iterator=_address(self._set._iterator),
            read_request=_address(self._get._request), write_request=_address(self._set._request),
            read_header=np.frombuffer(ffi.buffer(self._read._float_arr, 8), dtype=np.int32),
            write_header=np.frombuffer(ffi.buffer(self._write._float_arr, 8), dtype=np.int32),
            h_s=float(self.h), substeps=int(self.substeps),
        )
        self._fresh = False

    def read(self) -> None:
        """Read every body's state into `io.state` (for compiled code that then calls
        `read_poses` and `write_commands`; `write` and `step` follow)."""
        self._get()
        if self._read._float_arr.num != self.io.state.size:  # a body added behind the world's back
            raise RuntimeError("the physics space holds bodies the world did not index")
        self._fresh = True

    def write(self) -> None:
        """Set every body's velocity from `io.velocities` (filled by `write_commands`)."""
        self._set()

    def poses(self, out: np.ndarray | None = None) -> np.ndarray:
        """(n_robots, 3) true x, y, heading of every robot, into `out` if given.

        A removed robot stays where it was taken out. Without `out` the returned array
        is reused.
        """
        self.read()
        if out is None:
            out = self._poses
        read_poses(self.io, out)
        if out is not self._poses and self._removed.size:
            out[self._removed] = self._poses[self._removed]
        return out

    def drive(self, cmd: np.ndarray) -> None:
        """Set each live robot's commanded (forward speed, turn rate) for the next step."""
        if not self._fresh:
            self.read()
        heading_frames(self.io, self._heading_cs)
        write_commands(self.io, cmd, self._heading_cs)
        self.write()

    def _straight_to_chipmunk(self) -> bool:
        """Whether a step may go to Chipmunk directly, without pymunk's book-keeping (see `step`):
        nothing of the kind pending. If so, drop what pymunk's step would drop first (removed
        shapes need no keeping now)."""
        for space in self.spaces:
            if space._bodies_to_check or space._add_later or space._remove_later or space._post_step_callbacks \
                    or space.threaded:
                return False
        for space in self.spaces:
            space._removed_shapes.clear()
        return True

    def hand_over(self) -> bool:
        """Whether compiled code may drive the space through `space_io` from here until it
        returns (nothing pending that pymunk's own step must see to: see `step`). The state
        it leaves counts as stale."""
        if not self._straight_to_chipmunk():
            return False
        self._fresh = False
        return True

    def step(self) -> None:
        """One control period of physics (`substeps` Chipmunk steps).

        pymunk's `Space.step` wraps Chipmunk's step in book-keeping this world never needs
        once its bodies are in: mass checks of newly added bodies, objects added or removed
        from callbacks, post-step callbacks (it has none). While there is nothing of the kind
        pending, the step goes to Chipmunk directly, the very same call; otherwise through pymunk.
        """
        straight = self._straight_to_chipmunk()
        for space in self.spaces:
            for _ in range(self.substeps):
                if straight:
                    lib.cpSpaceStep(space._space, self.h)
                else:
                    space.step(self.h)
        self._fresh = False

    def remove(self, robot: int) -> None:
        """Take a broken-down robot out of the world."""
        if not self.alive[robot]:
            return
        self.poses()  # where it stops
        self.spaces[self.slot_of[robot]].remove(*self._parts[robot])
        self.alive[robot] = False
        self._index_bodies()
