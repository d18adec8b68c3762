"""`tavc bench`: how many simulated seconds the simulator advances per wall second.

Measures, in one process (one core), the full robot loop (sensing, behaviours,
learning, physics) on a batch of trials of a scenario, and the same pymunk spaces
stepped with no robot logic at all; the ratio of the two says what the robot
loop costs on top of the physics. Then, unless told not to, how the figure
scales: with robots in one arena (2, 6, 12, 24), and with processes (1, 2 and
all cores, each running the same batch at once). With `against="enki"` it also
runs the same scenario written for Enki, a C++ robot simulator (`bench/enki/`).
"""

from __future__ import annotations

import json
import math
import multiprocessing
import os
import platform
import statistics
import time
from collections.abc import Callable
from dataclasses import replace

import numpy as np

from tavc_cli import estimates
from tavc_cli.bench_enki import build_enki_bench, run_enki
from tavc_cli.errors import TavcError
from tavc_cli.experiments.build import trial_specs
from tavc_cli.experiments.engine import BatchEngine
from tavc_cli.profiling import run_profile
from tavc_cli.settings import ExecutorConfig, TavcConfig
from tavc_cli.sim.world import CP_STEP, step_only

SettingsFor = Callable[[int, float], TavcConfig]  # (robots, duration_s) -> the benchmark's settings


def bench_overrides(scenario: str, n_robots: int, duration_s: float, n_rays: int | None) -> list[str]:
    """The config the benchmark runs: `scenario`'s arena, TAVC learners, no snapshots. Its trials
    are the benchmark's own (`check_bench_size` estimates them), not the config's: force=true."""
    rays = [f"robot.laser.n_rays={n_rays}"] if n_rays else []
    return [f"arena={scenario}", "learner=tavc_egreedy", f"team.n_robots={n_robots}", f"duration_s={duration_s}",
            "convergence_s=0", "sim.q_snapshot_every_s=0", "force=true", *rays]


# The benchmark's sizes as their options name them, with their defaults: the one furthest above
# its default is named when the whole is too long or too large.
_BENCH_OPTIONS = {"--duration-s": 600.0, "--repeats": 3, "--batch": ExecutorConfig.batch_size, "--n-robots": 6,
                  "--n-rays": estimates.BENCH_RAYS}


def check_bench_size(*, n_robots: int, duration_s: float, repeats: int, batch: int | None, n_rays: int | None,
                     scaling: bool, profile: bool, against: str | None, force: bool) -> None:
    """Refuse, before anything is built, a benchmark that could never run (a trial longer than its
    clock counts, batches larger than memory) or, unless `force`, one estimated to take more than a
    day (`config.limits`, from the simulator's measured throughput)."""
    if repeats < 1:
        raise TavcError(f"--repeats: must be >= 1, got {repeats}")
    if not 0 < duration_s < math.inf:
        raise TavcError(f"--duration-s: must be a finite number > 0, got {duration_s}")
    batch, rays = int(batch or ExecutorConfig.batch_size), int(n_rays or estimates.BENCH_RAYS)
    given = {"--duration-s": duration_s, "--repeats": repeats, "--batch": batch, "--n-robots": n_robots,
             "--n-rays": rays}
    ticks = max(duration_s, 5000.0 if profile else 0.0) / estimates.BENCH_DT_S
    if ticks > estimates.MAX_TICKS:
        raise TavcError(f"--duration-s: {duration_s:g} simulated s is {ticks:.3g} control periods, more than a "
                        f"trial's clock counts (2**53); not even --force runs that")
    cores = os.cpu_count() or 1
    robots = max(n_robots, 24) if scaling else n_robots
    need = estimates.batch_bytes(batch * (max(2, cores) if scaling else 1), robots, rays)
    memory = estimates.physical_memory()
    if need > memory:
        key = _furthest(given, ("--batch", "--n-robots", "--n-rays"))
        raise TavcError(f"{key}: {batch:,} trials of {robots:,} robots with {rays:,} laser rays in each process would "
                        f"need about {estimates.in_bytes(need)} of memory, more than this machine's "
                        f"{estimates.in_bytes(memory)}; not even --force runs that")
    wall = _bench_wall_s(n_robots, duration_s, repeats, batch, rays, scaling, profile, against, cores)
    if wall > estimates.DAY_S and not force:
        raise TavcError(f"{_furthest(given, tuple(given))}: the benchmark would take about {estimates.about(wall)} "
                        f"{estimates.speed_note()}; more than a day: make it smaller, or pass --force to run it anyway")


def _bench_wall_s(n_robots: int, duration_s: float, repeats: int, batch: int, rays: int, scaling: bool, profile: bool,
                  against: str | None, cores: int) -> float:
    """`run_bench`'s (or `profile_bench`'s) wall seconds, as `config.limits` estimates a run's."""

    def trials(n: int, span_s: float, count: int = batch) -> float:
        return count * estimates.trial_cost_s(span_s, estimates.BENCH_DT_S, n, 1, rays)

    if profile:
        return trials(n_robots, max(duration_s, 5000.0))
    full = trials(n_robots, duration_s)
    wall = trials(n_robots, min(duration_s, 30.0)) + repeats * full * (1 + estimates.PHYSICS_SHARE)
    if scaling:
        wall += sum(trials(n, min(duration_s / 2, 10.0)) + repeats * trials(n, duration_s / 2) for n in (2, 6, 12, 24))
        wall += sum(math.ceil(k / cores) * (full + trials(n_robots, min(duration_s, 10.0)))
                    for k in sorted({1, 2, cores}))
    if against == "enki":
        wall += 2 * repeats * trials(n_robots, duration_s, 1)
    return wall


def _furthest(given: dict[str, float], options: tuple[str, ...]) -> str:
    """Of `options`, the one whose value is the most times its default."""
    return max(options, key=lambda option: given[option] / _BENCH_OPTIONS[option])


def _batch_specs(settings: TavcConfig, batch: int):
    return trial_specs(replace(settings, trials=batch, baselines=[]))


def bench_text(settings_for: Callable[[int, float], TavcConfig], *, json_output: bool, scenario: str,
               n_robots: int, duration_s: float, repeats: int, batch: int | None, n_rays: int | None = None,
               scaling: bool = True, against: str | None = None, profile: bool = False, force: bool = False) -> str:
    """`tavc bench`'s output: a profile of the loop (`profile`) or the benchmark (`run_bench`), as
    one JSON object or as aligned lines. `settings_for(n_robots, duration_s)` gives the settings.
    A benchmark longer than a day is refused unless `force` (`check_bench_size`)."""
    check_bench_size(n_robots=n_robots, duration_s=duration_s, repeats=repeats, batch=batch, n_rays=n_rays,
                     scaling=scaling, profile=profile, against=against, force=force)
    if profile:
        if against:
            raise TavcError("--profile: profiles tavc alone; leave out --against")
        result, lines = profile_bench(settings_for(n_robots, max(duration_s, 5000.0)), batch)
        return json.dumps(result) if json_output else "\n".join(lines)
    result = run_bench(settings_for, scenario=scenario, n_robots=n_robots, duration_s=duration_s, repeats=repeats,
                       batch=batch, n_rays=n_rays, scaling=scaling, against=against)
    return json.dumps(result) if json_output else "\n".join(bench_lines(result))


def bench_lines(result: dict) -> list[str]:
    """`run_bench`'s result as aligned `key  value` lines."""
    width = max((len(key) for key in result), default=0)
    return [f"{key:<{width}}  {f'{value:,.2f}' if isinstance(value, float) else str(value)}"
            for key, value in result.items()]


def profile_bench(settings: TavcConfig, batch: int | None) -> tuple[dict, list[str]]:
    """`tavc bench --profile`: where one batch's time goes (`profiling.run_profile`), and the
    lines that show it."""
    specs = _batch_specs(settings, int(batch or settings.executor.batch_size))
    result = run_profile(specs)
    lines = [f"{len(specs)} trials of {specs[0].n_robots} robots, {specs[0].duration_s:,.0f} simulated s each: "
             f"{result['sim_seconds_per_wall_second']:,.0f} simulated s per wall s under perf; "
             f"{result['functions_named']} compiled functions named", "", "share of the samples:"]
    lines += [f"  {pct:5.1f} %  {name}" for name, pct in result["groups_pct"].items()]
    lines += ["", "top functions:"]
    lines += [f"  {row['pct']:5.2f} %  {row['function']}  ({row['object']})" for row in result["top"]]
    return result, lines


def _full_loop(specs) -> float:
    engine = BatchEngine(specs)
    start = time.perf_counter()
    engine.run()
    return sum(s.span_s for s in specs) / (time.perf_counter() - start)


def _physics_only(specs) -> float:
    """The same spaces, robots and joints, stepped with no robot logic.

    Each robot is given one constant command (forward at its speed while turning
    gently) so that the physics still has moving bodies, wall contacts and robot
    collisions to resolve, as in a real run. The ticks run in compiled code, as the full
    loop's do, so that neither side pays Python per tick.
    """
    engine = BatchEngine(specs)
    n_ticks = int(round(specs[0].span_s / specs[0].dt_s))
    world = engine.world
    cmd = np.column_stack([engine.robots["top_speed_mps"], np.full(engine.n, 0.2)])
    world.poses()
    world.drive(cmd)
    world.step()  # the first step goes through pymunk, which checks the new bodies
    if not world.hand_over():
        raise RuntimeError("the physics space has pending changes; cannot step it from compiled code")
    step_only(world.space_io, CP_STEP, 0)  # load the compiled loop
    start = time.perf_counter()
    step_only(world.space_io, CP_STEP, n_ticks)
    return sum(s.span_s for s in specs) / (time.perf_counter() - start)


def _full_loop_best(specs, repeats: int) -> float:
    return max(_full_loop(specs) for _ in range(repeats))


def _robots_scaling(settings_for: SettingsFor, counts, duration_s: float, batch: int, repeats: int) -> list[dict]:
    rows = []
    for n in counts:
        specs = _batch_specs(settings_for(n, duration_s), batch)
        _full_loop([replace(s, duration_s=min(duration_s, 10.0)) for s in specs])
        rtf = _full_loop_best(specs, repeats)
        rows.append({"n_robots": n, "sim_seconds_per_wall_second": round(rtf, 1),
                     "robot_seconds_per_wall_second": round(rtf * n, 1)})
    return rows


def _worker(specs, barrier, out) -> None:
    """One process of the core-scaling run: warm up, start with the others, time one batch."""
    _full_loop([replace(s, duration_s=min(s.duration_s, 10.0)) for s in specs])
    barrier.wait()
    start = time.time()
    engine = BatchEngine(specs)
    engine.run()
    out.put((sum(s.span_s for s in specs), start, time.time()))


def _cores_scaling(specs, counts) -> list[dict]:
    """Processes running the same batch at once: their simulated seconds over the wall time
    from the first start to the last end."""
    ctx = multiprocessing.get_context("spawn")
    rows = []
    for k in counts:
        barrier, out = ctx.Barrier(k), ctx.Queue()
        procs = [ctx.Process(target=_worker, args=(specs, barrier, out)) for _ in range(k)]
        for p in procs:
            p.start()
        results = [out.get() for _ in procs]
        for p in procs:
            p.join()
        wall = max(r[2] for r in results) - min(r[1] for r in results)
        total = sum(r[0] for r in results) / wall
        rows.append({"processes": k, "sim_seconds_per_wall_second": round(total, 1),
                     "per_process": round(total / k, 1)})
    return rows


def run_bench(settings_for: SettingsFor, *, scenario: str = "two_circuits", n_robots: int = 6,
              duration_s: float = 600.0,
              repeats: int = 3, batch: int | None = None, n_rays: int | None = None, scaling: bool = True,
              against: str | None = None) -> dict:
    """Median real-time factors over `repeats` runs (after one warm-up run); with `scaling`, the
    best of `repeats` runs of half the duration per robot count and one run per process count.
    `settings_for(n_robots, duration_s)` gives the settings of `bench_overrides` for that team."""
    if against not in (None, "enki"):
        raise TavcError(f"--against: the only reference simulator is 'enki', got {against!r}")
    if against == "enki":
        build_enki_bench()  # before anything is measured: says in one line what is missing
    if repeats < 1:
        raise TavcError(f"--repeats: must be >= 1, got {repeats}")
    if not 0 < duration_s < math.inf:
        raise TavcError(f"--duration-s: must be a finite number > 0, got {duration_s}")
    settings = settings_for(n_robots, duration_s)
    batch = int(batch or settings.executor.batch_size)
    specs = _batch_specs(settings, batch)
    _full_loop([replace(s, duration_s=min(duration_s, 30.0)) for s in specs])  # load compiled kernels
    full, phys = [], []
    for _ in range(repeats):
        full.append(_full_loop(specs))
        phys.append(_physics_only(specs))
    full_rtf, phys_rtf = statistics.median(full), statistics.median(phys)
    # each physics-only run follows its full-loop run at once: the ratio of the pair is the
    # least disturbed by a machine whose speed drifts, so the overhead is the pairs' median
    overhead = statistics.median(p / f for p, f in zip(phys, full, strict=True))
    result = {
        "scenario": scenario,
        "n_robots": n_robots,
        "trials_per_batch": batch,
        "duration_s": duration_s,
        "repeats": repeats,
        "laser_rays": int(settings.robot.laser.n_rays),
        "dt_s": float(settings.sim.dt_s),
        "physics_substeps": int(settings.sim.physics_substeps),
        "sim_seconds_per_wall_second": round(full_rtf, 1),
        "physics_only_sim_seconds_per_wall_second": round(phys_rtf, 1),
        "overhead_ratio": round(overhead, 3),
        "measure": f"simulated seconds summed over the {batch} trials of {n_robots} robots advanced together "
                   "in one process on one core, per wall second",
        "full_loop_runs": [round(x, 1) for x in full],
        "physics_only_runs": [round(x, 1) for x in phys],
        "machine": {"python": platform.python_version(), "platform": platform.platform(),
                    "cpu_count": os.cpu_count()},
    }
    if scaling:
        short = duration_s / 2
        result["scaling_robots"] = _robots_scaling(settings_for, (2, 6, 12, 24), short, batch, repeats)
        result["scaling_processes"] = _cores_scaling(specs, sorted({1, 2, os.cpu_count() or 1}))
    if against == "enki":
        enki = run_enki(duration_s, repeats, n_robots)
        one = _full_loop_best(specs[:1], repeats)
        result["enki"] = enki
        result["batch_1_sim_seconds_per_wall_second"] = round(one, 1)
        result["ratio_to_enki"] = round(full_rtf / enki["sim_seconds_per_wall_second"], 3)
        result["ratio_to_enki_batch_1"] = round(one / enki["sim_seconds_per_wall_second"], 3)
    return result
