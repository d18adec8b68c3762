"""`tavc run` below the CLI: an experiment's trials (`experiments.runner`), then its tables
and claims (`analysis.experiment`), then its provenance, with the output folder held by this
run alone for the whole time."""

from __future__ import annotations

from tavc_cli.analysis.experiment import write_analysis
from tavc_cli.experiments.runner import run_experiment_trials, write_provenance
from tavc_cli.experiments.store import Executor
from tavc_cli.io import claim_folder
from tavc_cli.settings import TavcConfig


def run_experiment(cfg: TavcConfig, *, progress: bool = False) -> dict:
    """Run (or reuse) every trial of the experiment and write all its outputs; return a summary
    with the tables and claims."""
    Executor.from_config(cfg.executor).check()
    with claim_folder(cfg.output_dir):
        run = run_experiment_trials(cfg, progress=progress)
        tables, claims = write_analysis(cfg, run.output_dir, run.records)
        write_provenance(cfg, run)
    return {"output_dir": str(run.output_dir), "n_trials": len(run.specs), "n_reused": run.n_reused,
            "wall_time_s": run.wall_time_s, "tables": tables, "claims": claims}
