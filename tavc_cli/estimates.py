"""What a run costs: wall time from the simulator's measured throughput, memory from measured
sizes. Plain arithmetic, no config: `config.limits` refuses runs with it, `bench` benchmarks.

The estimates are rough (within a factor of two or so); messages built on them say "about".
"""

from __future__ import annotations

import math
import os

# Throughput: `tavc bench --json` (6 robots in two_circuits, 61 laser rays, camera, behaviours,
# learning, physics at sim.dt_s = 0.1 s, 8 trials per batch) runs 10,965 simulated s per wall s
# on one core of the 2-core reference machine (PERFORMANCE.md, "Where tavc stands"; 12,523 on
# the development machine, 2026-12). That is about 110,000 control periods of a 6-robot trial
# per wall second and core.
TICKS_PER_CORE_S = 110_000.0
BENCH_ROBOTS = 6
BENCH_DT_S = 0.1
# A tick costs more than linearly in the team: the laser and the camera test every robot against
# every other (6 -> 24 robots cost 7.3x per simulated second, PERFORMANCE.md), so n ** 1.43.
ROBOTS_EXPONENT = math.log(7.3) / math.log(24 / 6)
BENCH_RAYS = 61
# Of a tick, the physics takes 1 / 1.67 (the bench's overhead ratio: physics-only over full
# throughput) and is repeated for every physics substep; the laser's rays take 0.23 (`tavc bench
# --n-rays 610` ran 3,666 simulated s per wall s against 11,300 at 61 rays, physics alike), in
# proportion to their number; the rest of the robot loop takes what is left.
PHYSICS_SHARE = 1 / 1.67
RAYS_SHARE = 0.23
DAY_S = 86_400.0
# Ticks are int64 and a trial's clock reads tick x sim.dt_s as a float: beyond 2**53 ticks,
# consecutive ticks can read the same time, and events could no longer be told apart.
MAX_TICKS = 2**53
# Memory, measured with tracemalloc (initial_distribution, scale=smoke):
PLAN_BYTES = 1_200            # a trial's spec and key, every trial's held from the start of a run
RECORD_BYTES = 40_000         # a trial's record as analysis loads it, before its events
Q_SNAPSHOT_BYTES = 120        # one Q-table snapshot: an array's own bytes, plus 8 per entry
POSE_FRAME_BYTES = 4 * 112    # one pose frame: four arrays, plus 33 bytes per robot
POSE_ROBOT_BYTES = 33
BATCH_ROBOT_BYTES = 32_000    # a robot in a batch being simulated (noise block, bodies, arrays)...
RAY_BYTES = 8                 # ... plus this per laser ray (measured: 4 more at 6,100 rays than at 61)


def physical_memory() -> float:
    """Bytes of memory this machine has (infinite when the system does not say)."""
    try:
        return float(os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES"))
    except (ValueError, OSError, AttributeError):
        return math.inf


def tick_cost_s(n_robots: int, substeps: int = 1, n_rays: int = BENCH_RAYS) -> float:
    """Wall seconds on one core for one control period of one trial of `n_robots`."""
    shares = (1 - PHYSICS_SHARE - RAYS_SHARE) + PHYSICS_SHARE * substeps + RAYS_SHARE * n_rays / BENCH_RAYS
    return (n_robots / BENCH_ROBOTS) ** ROBOTS_EXPONENT * shares / TICKS_PER_CORE_S


def trial_cost_s(span_s: float, dt_s: float, n_robots: int, substeps: int = 1, n_rays: int = BENCH_RAYS) -> float:
    """Wall seconds on one core for a trial of `span_s` simulated seconds."""
    return span_s / dt_s * tick_cost_s(n_robots, substeps, n_rays)


def batch_bytes(n_trials: int, n_robots: int, n_rays: int) -> float:
    """Memory for `n_trials` of `n_robots` advanced together in one process."""
    return float(n_trials) * n_robots * (BATCH_ROBOT_BYTES + RAY_BYTES * n_rays)


def about(seconds: float) -> str:
    """A wall time, roughly: ``40 s``, ``12 min``, ``5.5 h``, ``3.2 days``, ``1,250 years``."""
    if not math.isfinite(seconds):
        return "longer than any number of years a float can hold"
    for limit, unit, size, digits in ((90, "s", 1, 0), (5400, "min", 60, 0), (172_800, "h", 3600, 1),
                                      (3_650 * DAY_S, "days", DAY_S, 1)):
        if seconds < limit:
            return f"{seconds / size:,.{digits}f} {unit}"
    years = seconds / (365.25 * DAY_S)
    return f"{years:,.0f} years" if years < 1e6 else f"{years:.1e} years"


def in_bytes(n: float) -> str:
    """An amount of memory: ``512.0 MB``, ``3.1 GB``, ``2.0e+21 bytes``."""
    if n >= 1e15:
        return f"{n:.1e} bytes"
    unit, size = next(((u, s) for u, s in (("TB", 1e12), ("GB", 1e9), ("MB", 1e6)) if n >= s), ("bytes", 1))
    return f"{n / size:,.1f} {unit}" if size > 1 else f"{n:,.0f} bytes"


def speed_note() -> str:
    """Where the estimates come from, for messages."""
    return (f"at the simulator's measured speed, about {TICKS_PER_CORE_S * BENCH_DT_S:,.0f} simulated s per "
            f"wall s for {BENCH_ROBOTS} robots at sim.dt_s = {BENCH_DT_S:g} s")
