"""Run an experiment's trials through the results folder's `TrialStore` (finished ones
reused, the rest run on the chosen executor) and record how: `provenance.json`, written
atomically. The analysis is not the runner's: see
`tavc_cli.pipeline`, which runs both.
"""

from __future__ import annotations

import json
import os
import platform
import subprocess
import sys
import time
from dataclasses import dataclass, replace
from importlib import metadata
from pathlib import Path

from tavc_cli import __version__
from tavc_cli.experiments.build import trial_specs
from tavc_cli.experiments.joint import run_together
from tavc_cli.experiments.plan import RunPlan
from tavc_cli.experiments.records import TrialRecord
from tavc_cli.experiments.spec import TrialSpec, code_digest
from tavc_cli.experiments.store import Executor, TrialStore
from tavc_cli.io import file_digest, write_text_atomic
from tavc_cli.learning.parameters import PluginSettings
from tavc_cli.learning.plugins import target_digest, target_files
from tavc_cli.ownership import trial_path
from tavc_cli.settings import TavcConfig

_PACKAGES = ("numpy", "scipy", "pandas", "pymunk", "numba", "hydra-core", "omegaconf", "typer", "matplotlib")


def provenance(cfg: TavcConfig, specs: list[TrialSpec], wall_time_s: float, n_reused: int,
               n_together: int = 1) -> dict:
    """Who, what and where of a run: versions, seeds, command line, machine, and the wall time
    of its trials, said in words (``wall_time_covers``): this run's alone, or those of the
    `n_together` experiments whose trials one invocation ran together."""
    versions = {}
    for pkg in _PACKAGES:
        try:
            versions[pkg] = metadata.version(pkg)
        except metadata.PackageNotFoundError:
            versions[pkg] = None
    return {
        "tavc_version": __version__,
        "git_commit": git_commit(),
        **made_by(specs),
        "packages": versions,
        "python": platform.python_version(),
        "root_seed": int(cfg.seed),
        "batch_size": int(cfg.executor.batch_size),
        "trials": [
            {"controller": s.controller, "trial": s.trial, "seed": list(s.seed), "key": s.key(),
             "file": str(trial_path(Path("."), s.controller, s.trial))}
            for s in specs
        ],
        "command_line": sys.argv,
        "wall_time_s": wall_time_s,
        "wall_time_covers": "this run's trials, simulated or reused (not their analysis)" if n_together == 1 else
        f"the trials of the {n_together} experiments one invocation ran together, their shared history simulated "
        "once (not this run's share, nor the analysis)",
        "n_trials_reused": n_reused,
        "machine": {"platform": platform.platform(), "processor": platform.processor(),
                    "cpu_count": os.cpu_count()},
    }


def made_by(specs: list[TrialSpec]) -> dict:
    """What computed a run's trials, as its `provenance.json` records it: tavc's simulator
    (``code_digest``), the engine and the code of learners from outside tavc."""
    targets = sorted({str(s.policy.target) for s in specs if isinstance(s.policy, PluginSettings)})
    learners = {t: {"digest": target_digest(t), "files": [p.name for p in target_files(t)]} for t in targets}
    return {
        "code_digest": code_digest(),
        # what computed the trials: the simulator ("physics"), or the surrogate, its code's digest named
        "engine": specs[0].engine if specs else "physics",
        **({"learner_code": learners} if learners else {}),  # the code of learners from outside tavc
    }


def git_commit() -> str | None:
    """HEAD of the checkout tavc runs from, with '-dirty' if its files have uncommitted changes."""
    here = Path(__file__).resolve().parent
    try:
        head = subprocess.run(["git", "rev-parse", "HEAD"], cwd=here, capture_output=True, text=True, timeout=5)
        if head.returncode != 0:
            return None
        # --no-optional-locks: a status only reads; without it git refreshes the checkout's index
        dirty = subprocess.run(["git", "--no-optional-locks", "status", "--porcelain", "--untracked-files=no", "--",
                                "."], cwd=here.parent, capture_output=True, text=True, timeout=5)
    except (OSError, subprocess.SubprocessError):
        return None
    return head.stdout.strip() + ("-dirty" if dirty.stdout.strip() else "")


@dataclass(frozen=True)
class Run:
    """An experiment's trials, run or reused, with their records."""

    output_dir: Path
    plan: RunPlan
    specs: list[TrialSpec]
    records: list[TrialRecord]
    n_reused: int
    wall_time_s: float
    n_together: int = 1  # experiments whose trials ran together, all in `wall_time_s`


def run_experiment_trials(cfg: TavcConfig, plan: RunPlan, *, progress: bool = False) -> Run:
    """Run (or reuse) every trial of the experiment's `plan` into its `output_dir`. The caller holds
    the folder (`io.claim_folder`) and has written its `config.yaml` and `plan.json`; a `provenance.json` already
    there (the same configuration's finished run) stays until `write_provenance` replaces it,
    so an interrupted rerun leaves the folder as finished as it found it."""
    out_dir = Path(cfg.output_dir)
    start = time.perf_counter()
    specs = trial_specs(cfg, plan)
    store = TrialStore(out_dir, Executor.from_config(cfg.executor))
    n_reused = store.run(specs, progress, announce=True)
    wall = time.perf_counter() - start
    return Run(out_dir, plan, specs, store.load(specs), n_reused, wall)


def run_trials_together(cfgs: list[TavcConfig], plans: list[RunPlan], *, progress: bool = False) -> list[Run]:
    """Run (or reuse) every trial of several experiments at once (`joint.run_together`: the
    history their trials share is simulated once) and write each one's `config.yaml`. The
    caller holds every folder; the first config's `executor` runs them all. A run's wall time
    is that of the whole invocation. The runs come without their records (`Run.records` is
    empty: load them one experiment at a time, `load_records`). As `run_experiment_trials`,
    every folder's `config.yaml` is the caller's."""
    start = time.perf_counter()
    folders = [Path(cfg.output_dir) for cfg in cfgs]
    specs = [trial_specs(cfg, plan) for cfg, plan in zip(cfgs, plans, strict=True)]
    executor = Executor.from_config(cfgs[0].executor)
    for folder, sp in zip(folders, specs, strict=True):
        TrialStore(folder, executor).check_paths(sp)
    reused = run_together(list(zip(folders, specs, strict=True)), executor, progress)
    wall = time.perf_counter() - start
    runs = []
    for folder, plan, sp in zip(folders, plans, specs, strict=True):
        runs.append(Run(folder, plan, sp, [], reused[folder], wall, len(cfgs)))
    return runs


def load_records(cfg: TavcConfig, run: Run) -> Run:
    """The run with its trials' records read from its folder."""
    return replace(run, records=TrialStore(run.output_dir, Executor.from_config(cfg.executor)).load(run.specs))


def write_provenance(cfg: TavcConfig, run: Run, tables: list[str] = ()) -> None:
    """`provenance.json`, written last: the run is complete once it is there. `tables` (file
    names in the run's folder: its tables and `config.yaml`) are recorded with their SHA-256
    (``tables``), so that whoever reads them can tell a file this run wrote from a damaged or
    edited one."""
    record = provenance(cfg, run.specs, run.wall_time_s, run.n_reused, run.n_together)
    record["tables"] = {name: file_digest(run.output_dir / name) for name in sorted(tables)}
    write_text_atomic(run.output_dir / "provenance.json", json.dumps(record, indent=2, default=str))
