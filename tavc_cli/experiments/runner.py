"""Run an experiment's trials: batches over processes, reuse of finished trials, outputs.

`run_experiment` is what `tavc run` calls. It
1. skips every trial whose file already exists with a matching key (a digest of
   everything that fixes its outcome, seed included);
2. groups the rest into batches (see `build`) and runs them on the chosen
   executor, each batch writing one file per trial atomically when it finishes
   (a killed run loses at most the batches in flight);
3. writes `config.yaml`, `provenance.json`, and the shared analysis tables
   (`state_time.csv`, `performance.csv`), each atomically.
"""

from __future__ import annotations

import json
import os
import platform
import subprocess
import sys
import time
from collections.abc import Callable, Mapping
from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, wait
from importlib import metadata
from pathlib import Path

import numpy as np
import pandas as pd

from tavc_cli.analysis.performance import performance_table
from tavc_cli.analysis.qvalues import q_value_table
from tavc_cli.analysis.robots import robot_table
from tavc_cli.analysis.states import allocation_table, specialisation_table, state_time_table
from tavc_cli.analysis.trial_stats import trial_stats
from tavc_cli.analysis.vacancy import vacancy_table
from tavc_cli.errors import TavcError
from tavc_cli.experiments.build import Batch, make_batches, trial_specs
from tavc_cli.experiments.engine import run_trials
from tavc_cli.experiments.records import TrialRecord
from tavc_cli.experiments.spec import TrialSpec, code_digest
from tavc_cli.io import write_text_atomic

_PACKAGES = ("numpy", "scipy", "pandas", "pymunk", "numba", "hydra-core", "omegaconf", "typer", "matplotlib")


def trial_path(out_dir: Path, controller: str, trial: int) -> Path:
    return out_dir / "trials" / f"{controller}_{trial:03d}.npz"


def _stored_key(path: Path) -> str | None:
    try:
        with np.load(path, allow_pickle=False) as data:
            return json.loads(str(data["meta"])).get("key")
    except Exception:  # missing, truncated or foreign: the trial is simply run again
        return None


def trial_done(out_dir: Path, spec: TrialSpec) -> bool:
    """True if the trial's file exists and was made from this exact spec and seed."""
    return _stored_key(trial_path(out_dir, spec.controller, spec.trial)) == spec.key()


def pending_batches(out_dir: Path, specs: list[TrialSpec], batch_size: int,
                    workers: int = 1) -> tuple[list[Batch], int]:
    """Batches of the trials still to run, and how many finished trials are reused."""
    todo = [s for s in specs if not trial_done(out_dir, s)]
    return make_batches(todo, batch_size, workers), len(specs) - len(todo)


def run_batch(batch: Batch, out_dir: str | Path, report: Callable[[float], None] | None = None) -> float:
    """Simulate one batch and write its trial files; returns the wall time (s)."""
    start = time.perf_counter()
    records = run_trials(batch.specs, report)
    for spec, rec in zip(batch.specs, records, strict=True):
        rec.save(trial_path(Path(out_dir), spec.controller, spec.trial))
    return time.perf_counter() - start


class _QueueReporter:
    """Progress callback for a worker process: sends (batch id, fraction) to the parent."""

    def __init__(self, queue, key) -> None:
        self.queue, self.key = queue, key

    def __call__(self, frac: float) -> None:
        self.queue.put((self.key, frac))


class _Progress:
    """A rich bar on a terminal, plain periodic lines otherwise, over the simulated seconds
    of the batches; each batch reports the fraction of itself that is done."""

    def __init__(self, batches: list[Batch], tty: bool) -> None:
        self.weights = {(b.controller, b.index): b.sim_seconds for b in batches}
        self.total = total_s = sum(self.weights.values())
        self.done: dict = {}
        self.start = time.perf_counter()
        self.last_line = self.start
        self.bar = None
        if tty and total_s > 0:
            from rich.progress import BarColumn, Progress, TextColumn, TimeElapsedColumn, TimeRemainingColumn

            self.bar = Progress(TextColumn("simulating"), BarColumn(), TextColumn("{task.percentage:>5.1f}%"),
                                TimeElapsedColumn(), TextColumn("eta"), TimeRemainingColumn(), transient=True)
            self.task = self.bar.add_task("run", total=total_s)
            self.bar.start()

    def update(self, key, frac: float) -> None:
        self.done[key] = frac * self.weights[key]
        done = sum(self.done.values())
        if self.bar is not None:
            self.bar.update(self.task, completed=done)
        elif time.perf_counter() - self.last_line > 10.0 and self.total > 0:
            self.last_line = time.perf_counter()
            elapsed = self.last_line - self.start
            pct = 100.0 * done / self.total
            eta = elapsed * (self.total - done) / done if done > 0 else float("nan")
            print(f"  {pct:5.1f}% of {self.total:,.0f} simulated s, {elapsed:,.0f} s elapsed, eta {eta:,.0f} s",
                  flush=True)

    def close(self) -> None:
        if self.bar is not None:
            self.bar.stop()


def execute(pending: list[Batch], out_dir: Path, n_jobs: int, tty: bool) -> None:
    """Run pending batches in this process (n_jobs 1 or a single batch) or a process pool."""
    prog = _Progress(pending, tty)
    try:
        if n_jobs <= 1 or len(pending) <= 1:
            for b in pending:
                key = (b.controller, b.index)
                run_batch(b, out_dir, lambda f, k=key: prog.update(k, f))
            return
        import multiprocessing as mp

        ctx = mp.get_context("fork" if sys.platform.startswith("linux") else "spawn")
        with ctx.Manager() as manager:
            queue = manager.Queue()
            pool = ProcessPoolExecutor(max_workers=min(n_jobs, len(pending)), mp_context=ctx)
            try:
                futures = {pool.submit(run_batch, b, str(out_dir), _QueueReporter(queue, (b.controller, b.index))): b
                           for b in pending}
                remaining = set(futures)
                while remaining:
                    finished, remaining = wait(remaining, timeout=0.5, return_when=FIRST_COMPLETED)
                    while not queue.empty():
                        key, frac = queue.get()
                        prog.update(key, frac)
                    for f in finished:
                        f.result()  # re-raise a worker's error here
                        b = futures[f]
                        prog.update((b.controller, b.index), 1.0)
            except BaseException:
                pool.shutdown(wait=True, cancel_futures=True)  # don't start batches nobody will wait for
                raise
            pool.shutdown(wait=True)
    finally:
        prog.close()


def _execute_on_cluster(backend: str, pending: list[Batch], out_dir: Path, executor: Mapping, tty: bool) -> None:
    """Run pending batches on a Dask or Ray cluster (`executors`); this process writes the files."""
    from tavc_cli.experiments.executors import run_on_cluster, saver

    prog = _Progress(pending, tty)
    try:
        run_on_cluster(backend, pending, saver(out_dir, trial_path), int(executor["n_jobs"]),
                       executor.get("address"), lambda b: prog.update((b.controller, b.index), 1.0))
    finally:
        prog.close()


def load_records(out_dir: Path, specs: list[TrialSpec]) -> list[TrialRecord]:
    return [TrialRecord.load(trial_path(out_dir, s.controller, s.trial)) for s in specs]


def provenance(cfg: Mapping, specs: list[TrialSpec], wall_time_s: float, n_reused: int) -> dict:
    """Who, what and where of a run: versions, seeds, command line, machine."""
    from tavc_cli import __version__

    versions = {}
    for pkg in _PACKAGES:
        try:
            versions[pkg] = metadata.version(pkg)
        except metadata.PackageNotFoundError:
            versions[pkg] = None
    return {
        "tavc_version": __version__,
        "git_commit": _git_commit(),
        "code_digest": code_digest(),
        "packages": versions,
        "python": platform.python_version(),
        "root_seed": int(cfg["seed"]),
        "batch_size": int(cfg["executor"]["batch_size"]),
        "trials": [
            {"controller": s.controller, "trial": s.trial, "seed": list(s.seed), "key": s.key(),
             "file": str(trial_path(Path("."), s.controller, s.trial))}
            for s in specs
        ],
        "command_line": sys.argv,
        "wall_time_s": wall_time_s,
        "n_trials_reused": n_reused,
        "machine": {"platform": platform.platform(), "processor": platform.processor(),
                    "cpu_count": os.cpu_count()},
    }


def _git_commit() -> str | None:
    """HEAD of the checkout tavc runs from, with '-dirty' if its files have uncommitted changes."""
    here = Path(__file__).resolve().parent
    try:
        head = subprocess.run(["git", "rev-parse", "HEAD"], cwd=here, capture_output=True, text=True, timeout=5)
        if head.returncode != 0:
            return None
        dirty = subprocess.run(["git", "status", "--porcelain", "--untracked-files=no", "--", "."],
                               cwd=here.parent, capture_output=True, text=True, timeout=5)
    except (OSError, subprocess.SubprocessError):
        return None
    return head.stdout.strip() + ("-dirty" if dirty.stdout.strip() else "")


def analyse(cfg: Mapping, records: list[TrialRecord]) -> dict[str, pd.DataFrame]:
    """The tables every experiment shares, from saved records only."""
    t_from, t_to = float(cfg["convergence_s"]), float(cfg["duration_s"])
    scheme = cfg["analysis"]["state"]
    state = state_time_table(records, t_from, t_to, scheme)
    perf = performance_table(records, float(cfg["analysis"]["performance_bin_s"]),
                             -float(cfg["sim"]["warmup_s"]), t_to)
    alloc = allocation_table(records, float(cfg["analysis"]["performance_bin_s"]), -float(cfg["sim"]["warmup_s"]),
                             t_to) if scheme == "circuits" else None
    tables = {"state_time": state, "performance": perf, "trial_stats": trial_stats(records, cfg)}
    if alloc is not None:
        tables["allocation"] = alloc
    if scheme == "groups":
        tables["specialisation"] = specialisation_table(records, float(cfg["analysis"]["performance_bin_s"]),
                                                        -float(cfg["sim"]["warmup_s"]), t_to)
    if records and "choices" in records[0].tables:
        tables["robots"] = robot_table(records, t_from, t_to)
    q_values = q_value_table(records)
    if q_values is not None:
        tables["q_values"] = q_values
    if any(rec.meta["controller"] == "behaviour" for rec in records):
        tables.update(spatiotemporal_tables(cfg, records))
    vacancy = vacancy_table(records)
    if len(vacancy):
        tables["vacancy"] = vacancy
    return tables


def spatiotemporal_tables(cfg: Mapping, records: list[TrialRecord]) -> dict[str, pd.DataFrame]:
    """Section 1.4's tables for the behaviour learners' trials: Table 1.1 and the samples behind
    it, the learned policies, and the lanes (offsets and a heat map, first and last tenth)."""
    from tavc_cli.analysis import spatiotemporal as st

    mine = [rec for rec in records if rec.meta["controller"] == "behaviour"]
    arena = cfg["arena"]
    xy = {t["name"]: (float(t["x"]), float(t["y"])) for t in arena["targets"]}
    source, sink = xy[arena["circuits"][0]["source"]], xy[arena["circuits"][0]["sink"]]
    windows = st.lane_windows(float(cfg["duration_s"]))
    traversals, targets = st.traversal_table(mine), st.target_time_table(mine)
    return {"table_1_1": st.table_1_1_from(traversals, targets), "traversals": traversals,
            "target_times": targets, "policy": st.policy_table(mine),
            "lanes": st.lane_table(mine, source, sink, windows),
            "occupancy": st.occupancy_table(mine, source, sink, float(arena["width_m"]), float(arena["height_m"]),
                                            windows)}


def experiment_claims(cfg: Mapping, tables: Mapping[str, pd.DataFrame], out_dir: Path) -> pd.DataFrame:
    """The chapter's claims about this experiment, tested on its trials (and, where a claim
    compares two experiments, on the other's `trial_stats.csv` beside this output if present)."""
    from tavc_cli.analysis.claims import CLAIM_TABLES, CLAIMS, claim_rows

    name = str(cfg.get("experiment_name") or "")
    runs = {name: tables["trial_stats"]}
    runs.update({f"{name}/{t}": tables[t] for t in CLAIM_TABLES if t in tables})
    for other in {e for e, _ in CLAIMS.values()} - {name}:
        path = out_dir.parent / other / "trial_stats.csv"
        if path.is_file():
            runs[other] = pd.read_csv(path)
    return claim_rows(runs, only_experiment=name)


def run_experiment(cfg, *, progress: bool = False) -> dict:
    """Run (or reuse) every trial of the config's experiment and write its outputs."""
    from tavc_cli.config import to_container, to_yaml

    plain = to_container(cfg)
    out_dir = Path(plain["output_dir"])
    try:
        (out_dir / "trials").mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise TavcError(f"output_dir: cannot create {out_dir}: {exc.strerror}") from None
    backend = plain["executor"]["backend"]
    start = time.perf_counter()
    specs = trial_specs(plain)
    pending, n_reused = pending_batches(out_dir, specs, int(plain["executor"]["batch_size"]),
                                        int(plain["executor"]["n_jobs"]))
    n_total = len(specs)
    if n_reused:
        print(f"reusing {n_reused} of {n_total} finished trials in {out_dir / 'trials'}", flush=True)
    if backend == "local":
        execute(pending, out_dir, int(plain["executor"]["n_jobs"]), progress)
    else:
        _execute_on_cluster(backend, pending, out_dir, plain["executor"], progress)
    wall = time.perf_counter() - start
    write_text_atomic(out_dir / "config.yaml", to_yaml(cfg))
    records = load_records(out_dir, specs)
    tables = analyse(plain, records)
    for name, df in tables.items():
        # Q-values span the reward's scale (about 0.05 per task with t in ms, 50 with t in s): significant digits
        fmt = "%.6g" if name == "q_values" else "%.4f"
        write_text_atomic(out_dir / f"{name}.csv", df.to_csv(index=False, float_format=fmt))
    from tavc_cli.analysis.comparison import experiment_comparison

    comparison = experiment_comparison(str(plain.get("experiment_name") or ""), tables["state_time"])
    if comparison is not None:
        write_text_atomic(out_dir / "comparison.csv", comparison.to_csv(index=False, float_format="%.4f"))
    claims = experiment_claims(plain, tables, out_dir)
    if len(claims):
        write_text_atomic(out_dir / "claims.csv", claims.to_csv(index=False, float_format="%.6g"))
    write_text_atomic(out_dir / "provenance.json",
                      json.dumps(provenance(plain, specs, wall, n_reused), indent=2, default=str))
    return {"output_dir": str(out_dir), "n_trials": n_total, "n_reused": n_reused, "wall_time_s": wall,
            "tables": tables, "claims": claims}
