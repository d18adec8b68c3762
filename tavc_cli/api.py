"""tavc from Python: run an experiment from overrides, and read any results folder as pandas
DataFrames, for notebooks and scripts.

    from tavc_cli import api

    run = api.run(["experiment=breakdown", "scale=smoke"], output_dir="/tmp/tavc-demo")
    run.state_time                     # % of the stable period in each state, per controller
    run.events("deliveries")           # every delivery of every trial, one row each
    api.load("results/initial_distribution").claims

`run` takes the same overrides as `tavc run` and writes the same folder; `reproduce` runs
several experiments together as `tavc reproduce` does; `load` only reads.
Errors a user can make (a bad override, a folder without results) raise `TavcError` with one
line that names the problem.
"""

from __future__ import annotations

from collections.abc import Sequence
from functools import cached_property
from pathlib import Path

import pandas as pd
import yaml

from tavc_cli.errors import TavcError
from tavc_cli.experiments.records import TABLES, TrialRecord


class Results:
    """One experiment's results folder (as `tavc run` writes it), read lazily."""

    def __init__(self, path: str | Path) -> None:
        """Open the folder at `path`; fails in one line unless it holds a run's `config.yaml`."""
        self.path = Path(path)
        if not (self.path / "config.yaml").is_file():
            raise TavcError(f"{self.path}: not a results folder of tavc run (no config.yaml in it)")

    def __repr__(self) -> str:
        return f"Results({str(self.path)!r})"

    def table(self, name: str) -> pd.DataFrame:
        """The run's table `name`.csv (state_time, performance, trial_stats, claims, ...)."""
        path = self.path / f"{name}.csv"
        if not path.is_file():
            have = ", ".join(sorted(p.stem for p in self.path.glob("*.csv"))) or "none"
            raise TavcError(f"{self.path}: no table {name!r} (tables here: {have})")
        return pd.read_csv(path)

    @property
    def tables(self) -> list[str]:
        """Names of the tables in the folder."""
        return sorted(p.stem for p in self.path.glob("*.csv"))

    state_time = property(lambda self: self.table("state_time"), doc="% of the stable period in each state.")
    performance = property(lambda self: self.table("performance"), doc="Score delivered per second over time.")
    trial_stats = property(lambda self: self.table("trial_stats"), doc="One row per trial.")
    claims = property(lambda self: self.table("claims"), doc="Every part of the chapter's claims, tested.")

    @cached_property
    def config(self) -> dict:
        """The composed config the run used."""
        return yaml.safe_load((self.path / "config.yaml").read_text())

    def records(self) -> list[TrialRecord]:
        """Every trial's raw record (trials/*.npz), in file-name order."""
        files = sorted((self.path / "trials").glob("*.npz"))
        if not files:
            raise TavcError(f"{self.path}: no trial records in trials/ (tables only: rerun with tavc run to "
                            "get the events)")
        return [TrialRecord.load(f) for f in files]

    def events(self, kind: str) -> pd.DataFrame:
        """Every event of one kind (arrivals, deliveries, choices, breakdowns) of every trial, with the
        trial's controller and number as the first columns."""
        if kind not in TABLES:
            raise TavcError(f"events: no kind {kind!r}; one of {', '.join(TABLES)}")
        frames = []
        for rec in self.records():
            frame = pd.DataFrame(rec.table(kind))
            frame.insert(0, "trial", rec.meta["trial"])
            frame.insert(0, "controller", rec.meta["controller"])
            frames.append(frame)
        return pd.concat(frames, ignore_index=True)


def load(path: str | Path) -> Results:
    """Open a results folder (one experiment's, as `tavc run` writes it)."""
    return Results(path)


def run(overrides: Sequence[str] = (), *, output_dir: str | Path | None = None, progress: bool = False) -> Results:
    """Run an experiment as `tavc run` does (finished trials in the folder are reused) and open its results.

    Args:
        overrides: Hydra overrides, e.g. ``["experiment=breakdown", "scale=quick", "seed=3"]``.
        output_dir: Where to write; by default the config's (``results/<experiment>``).
        progress: Show a progress bar.
    """
    from tavc_cli import config
    from tavc_cli.pipeline import run_experiment

    overrides = list(overrides)
    if output_dir is not None:
        overrides.append(f"output_dir={Path(output_dir)}")
    summary = run_experiment(config.settings(config.load_config(overrides)), progress=progress)
    return Results(summary["output_dir"])


def reproduce(overrides: Sequence[str] = (), *, experiments: Sequence[str] | None = None,
              results_dir: str | Path = "results", progress: bool = False) -> dict[str, Results]:
    """Run several experiments together as `tavc reproduce` does (the history their trials share
    simulated once) and open each one's results, by experiment name.

    Args:
        overrides: Hydra overrides for every experiment, e.g. ``["scale=quick"]``.
        experiments: Experiment names; by default every one.
        results_dir: The folder that gets one folder per experiment.
        progress: Show a progress bar.
    """
    from tavc_cli import config
    from tavc_cli.pipeline import run_experiments

    names = [experiments] if isinstance(experiments, str) else experiments
    cfgs = config.load_experiments(names, list(overrides), results_dir)
    summaries = run_experiments([config.settings(cfg) for cfg in cfgs], progress=progress)
    return {str(cfg.experiment_name): Results(summary["output_dir"])
            for cfg, summary in zip(cfgs, summaries, strict=True)}
