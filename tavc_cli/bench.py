"""`tavc bench`: how many simulated seconds the simulator advances per wall second.

Measures, in one process (one core), the full robot loop (sensing, behaviours,
learning, physics) on a batch of trials of a scenario, and the same pymunk space
stepped with no robot logic at all; the ratio of the two says what the robot
loop costs on top of the physics.
"""

from __future__ import annotations

import os
import platform
import statistics
import time
from dataclasses import replace

import numpy as np

from tavc_cli.errors import TavcError
from tavc_cli.experiments.build import trial_specs
from tavc_cli.experiments.engine import BatchEngine


def _config(scenario: str, n_robots: int, duration_s: float, n_rays: int | None) -> dict:
    from tavc_cli.config import load_config, to_container

    rays = [f"robot.laser.n_rays={n_rays}"] if n_rays else []
    return to_container(load_config([f"arena={scenario}", "learner=tavc_egreedy", f"team.n_robots={n_robots}",
                                     f"duration_s={duration_s}", "convergence_s=0", "sim.q_snapshot_every_s=0",
                                     *rays]))


def _full_loop(specs) -> float:
    engine = BatchEngine(specs)
    start = time.perf_counter()
    engine.run()
    return sum(s.duration_s for s in specs) / (time.perf_counter() - start)


def _physics_only(specs) -> float:
    """The same space, robots and joints, stepped with no robot logic.

    Each robot is given one constant command (forward at its speed while turning
    gently) so that the physics still has moving bodies, wall contacts and robot
    collisions to resolve, as in a real run.
    """
    engine = BatchEngine(specs)
    n_ticks = int(round(specs[0].duration_s / specs[0].dt_s))
    world = engine.world
    cmd = np.column_stack([engine.robots["top_speed_mps"], np.full(engine.n, 0.2)])
    world.poses()
    world.drive(cmd)
    start = time.perf_counter()
    for _ in range(n_ticks):
        world.step()
    return sum(s.duration_s for s in specs) / (time.perf_counter() - start)


def run_bench(*, scenario: str = "two_circuits", n_robots: int = 6, duration_s: float = 600.0,
              repeats: int = 3, batch: int | None = None, n_rays: int | None = None) -> dict:
    """Median real-time factors over `repeats` runs (after one warm-up run)."""
    if repeats < 1:
        raise TavcError(f"--repeats: must be >= 1, got {repeats}")
    if duration_s <= 0:
        raise TavcError(f"--duration-s: must be > 0, got {duration_s}")
    cfg = _config(scenario, n_robots, duration_s, n_rays)
    batch = int(batch or cfg["executor"]["batch_size"])
    if batch < 1:
        raise TavcError(f"--batch: must be >= 1, got {batch}")
    specs = trial_specs({**cfg, "trials": batch, "baselines": []})
    _full_loop([replace(s, duration_s=min(duration_s, 30.0)) for s in specs])  # load compiled kernels
    full, phys = [], []
    for _ in range(repeats):
        full.append(_full_loop(specs))
        phys.append(_physics_only(specs))
    full_rtf, phys_rtf = statistics.median(full), statistics.median(phys)
    return {
        "scenario": scenario,
        "n_robots": n_robots,
        "trials_per_batch": batch,
        "duration_s": duration_s,
        "repeats": repeats,
        "laser_rays": int(cfg["robot"]["laser"]["n_rays"]),
        "dt_s": float(cfg["sim"]["dt_s"]),
        "physics_substeps": int(cfg["sim"]["physics_substeps"]),
        "sim_seconds_per_wall_second": round(full_rtf, 1),
        "physics_only_sim_seconds_per_wall_second": round(phys_rtf, 1),
        "overhead_ratio": round(phys_rtf / full_rtf, 3),
        "measure": f"simulated seconds summed over the {batch} trials of {n_robots} robots advanced together "
                   "in one process on one core, per wall second",
        "full_loop_runs": [round(x, 1) for x in full],
        "physics_only_runs": [round(x, 1) for x in phys],
        "machine": {"python": platform.python_version(), "platform": platform.platform(),
                    "cpu_count": os.cpu_count()},
    }
