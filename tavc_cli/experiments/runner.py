"""Run an experiment: its trials through the results folder's `TrialStore` (finished ones
reused, the rest run on the chosen executor), then `config.yaml`, `provenance.json` and the
analysis tables (`state_time.csv`, `performance.csv`, ...), each written atomically.

`run_experiment` is what `tavc run` calls.
"""

from __future__ import annotations

import json
import os
import platform
import subprocess
import sys
import time
from collections.abc import Mapping
from importlib import metadata
from pathlib import Path

import pandas as pd

from tavc_cli.analysis.performance import performance_table
from tavc_cli.analysis.qvalues import q_value_table
from tavc_cli.analysis.robots import robot_table
from tavc_cli.analysis.states import allocation_table, specialisation_table, state_time_table
from tavc_cli.analysis.trial_stats import trial_stats
from tavc_cli.analysis.vacancy import vacancy_table
from tavc_cli.errors import TavcError
from tavc_cli.experiments.build import trial_specs
from tavc_cli.experiments.records import TrialRecord
from tavc_cli.experiments.spec import TrialSpec, code_digest
from tavc_cli.experiments.store import Executor, TrialStore, trial_path
from tavc_cli.io import write_text_atomic

_PACKAGES = ("numpy", "scipy", "pandas", "pymunk", "numba", "hydra-core", "omegaconf", "typer", "matplotlib")


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
    start = time.perf_counter()
    specs = trial_specs(plain)
    store = TrialStore(out_dir, Executor.from_mapping(plain["executor"]))
    n_total = len(specs)
    n_reused = store.run(specs, progress, announce=True)
    wall = time.perf_counter() - start
    write_text_atomic(out_dir / "config.yaml", to_yaml(cfg))
    records = store.load(specs)
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
