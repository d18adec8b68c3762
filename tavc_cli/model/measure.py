"""Measure c_i(n) and t_i(n) in the simulator: static allocations, several seeds each.

For every split n of up to N robots, `trials_per_split` trials run with robots
fixed to circuits as n says (the robots on the other circuits are there too, and
get in the way where the circuits cross). After `warmup_s`, deliveries on each
circuit are counted for `measure_s`: c_i(n) = deliveries / measure_s, and t_i(n) is
the mean task time of the robots on circuit i. Intervals are Student-t intervals
over the trials. Trials are cached like any other run: a rerun reuses them.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import replace
from pathlib import Path

import numpy as np
from scipy import stats

from tavc_cli.experiments.build import base_spec
from tavc_cli.experiments.records import TrialRecord
from tavc_cli.experiments.runner import execute, pending_batches, trial_path
from tavc_cli.experiments.spec import TrialSpec
from tavc_cli.model.core import Cell, CTable, Split, splits_up_to

MODEL_CONTROLLER_CODE = 10


def split_name(n: Split) -> str:
    return "split_" + "_".join(str(v) for v in n)


def measurement_specs(cfg: Mapping, n_max: int, trials: int, warmup_s: float,
                      measure_s: float) -> dict[Split, list[TrialSpec]]:
    """Per split, `trials` static-allocation trials of warm-up plus measurement.

    Static robots do not learn, so the task values play no part: they are fixed at 1 so
    that measurements are reused whatever values the model is then applied with.
    """
    base = base_spec(cfg)
    speed = float(cfg["robot"]["speed_mps"])
    k = len(cfg["arena"]["circuits"])
    out = {}
    for n in splits_up_to(n_max, k):
        m = sum(n)
        out[n] = [
            replace(base, speeds_mps=(speed,) * m, groups=("all",) * m, values=(1.0,) * k, score_values=(1.0,) * k,
                    policy={"name": "static", "allocation": list(n)}, controller=split_name(n), trial=j,
                    seed=(int(cfg["seed"]), MODEL_CONTROLLER_CODE, *n, j), duration_s=warmup_s + measure_s,
                    warmup_s=0.0, breakdowns=(), value_changes=(), q_snapshot_every_s=0.0, pose_every_s=0.0)
            for j in range(trials)
        ]
    return out


def _interval(x: np.ndarray, confidence: float) -> tuple[float, float, float]:
    x = x[np.isfinite(x)]
    if len(x) == 0:
        return math.inf, math.nan, math.nan
    mean = float(x.mean())
    if len(x) < 2:
        return mean, math.nan, math.nan
    half = float(stats.t.ppf(0.5 + confidence / 2, len(x) - 1) * x.std(ddof=1) / math.sqrt(len(x)))
    return mean, mean - half, mean + half


def cells_for(records: list[TrialRecord], n: Split, warmup_s: float, measure_s: float,
              confidence: float) -> tuple[Cell, ...]:
    """c_i and t_i of every circuit of split n from its trials' deliveries."""
    cells = []
    for i in range(len(n)):
        rates, times = [], []
        for rec in records:
            d = rec.table("deliveries")
            mask = (d["t_s"] >= warmup_s) & (d["t_s"] < warmup_s + measure_s) & (d["circuit"] == i)
            rates.append(mask.sum() / measure_s)
            times.append(d["task_time_s"][mask].mean() if mask.any() else math.nan)
        c, c_lo, c_hi = _interval(np.array(rates), confidence)
        t, t_lo, t_hi = _interval(np.array(times), confidence)
        if n[i] == 0:
            c, c_lo, c_hi, t, t_lo, t_hi = 0.0, 0.0, 0.0, math.inf, math.nan, math.nan
        cells.append(Cell(c=c, t=t, c_lo=c_lo, c_hi=c_hi, t_lo=t_lo, t_hi=t_hi, n_trials=len(records)))
    return tuple(cells)


def measure(cfg: Mapping, out_dir: Path, *, n_max: int, trials: int, warmup_s: float, measure_s: float,
            confidence: float, n_jobs: int, progress: bool) -> tuple[CTable, int]:
    """Run (or reuse) every split's trials; return the table and how many trials were reused."""
    plan = measurement_specs(cfg, n_max, trials, warmup_s, measure_s)
    all_specs = [s for specs in plan.values() for s in specs]
    pending, n_reused = pending_batches(out_dir, all_specs, int(cfg["executor"]["batch_size"]))
    execute(pending, out_dir, n_jobs, progress)
    table = CTable(len(cfg["arena"]["circuits"]))
    for n, specs in plan.items():
        records = [TrialRecord.load(trial_path(out_dir, s.controller, s.trial)) for s in specs]
        table.cells[n] = cells_for(records, n, warmup_s, measure_s, confidence)
    return table, n_reused
