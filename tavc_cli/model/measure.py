"""Measure c_i(n) and t_i(n) in the simulator: static allocations, several seeds each.

For every split n of up to N robots, `trials_per_split` trials run with robots
fixed to circuits as n says (the robots on the other circuits are there too, and
get in the way where the circuits cross). After `warmup_s`, deliveries on each
circuit are counted for `measure_s`: c_i(n) = deliveries / measure_s, and the task
time t_i(n) = n_i / c_i(n) is the robot-seconds each delivery took (a stuck robot
counts). Intervals are Student-t intervals over the trials. Trials are cached like
any other run: a rerun reuses them.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping
from dataclasses import replace
from pathlib import Path

import numpy as np
from scipy import stats

from tavc_cli.experiments.build import base_spec
from tavc_cli.experiments.records import TrialRecord
from tavc_cli.experiments.spec import TrialSpec
from tavc_cli.experiments.store import Executor, TrialStore
from tavc_cli.learning.parameters import StaticSettings
from tavc_cli.model.core import Cell, CTable, Split, splits_up_to
from tavc_cli.settings import TavcConfig
from tavc_cli.vocabulary import ACTIVITIES

MODEL_CONTROLLER_CODE = 10


def split_name(n: Split) -> str:
    """The name of split n's measurements, ``split_<n_0>_<n_1>...``."""
    return "split_" + "_".join(str(v) for v in n)


def measurement_specs(cfg: TavcConfig, n_max: int, trials: int, warmup_s: float, measure_s: float,
                      only: Iterable[Split] | None = None, prefix: str = "") -> dict[Split, list[TrialSpec]]:
    """Per split (every split of up to n_max robots, or those in `only`), `trials`
    static-allocation trials of warm-up plus measurement, named `prefix` + the split.

    Static robots do not learn, so the task values play no part: they are fixed at 1 so
    that measurements are reused whatever values the model is then applied with.
    """
    base = base_spec(cfg)
    speed = float(cfg.robot.speed_mps)
    k = len(cfg.arena.circuits)
    wanted = None if only is None else set(only)
    out = {}
    for n in splits_up_to(n_max, k):
        if wanted is not None and n not in wanted:
            continue
        m = sum(n)
        out[n] = [
            replace(base, speeds_mps=(speed,) * m, groups=("all",) * m, values=(1.0,) * k, score_values=(1.0,) * k,
                    policy=StaticSettings(allocation=list(n)), controller=prefix + split_name(n), trial=j,
                    seed=(int(cfg.seed), MODEL_CONTROLLER_CODE, *n, j), duration_s=warmup_s + measure_s,
                    warmup_s=0.0, deliveries=None, breakdowns=(), value_changes=(), q_snapshot_every_s=0.0,
                    pose_every_s=0.0)
            for j in range(trials)
        ]
    return out


def _interval(x: np.ndarray, confidence: float) -> tuple[float, float, float]:
    """Mean and Student-t interval of per-trial values."""
    mean = float(x.mean())
    if len(x) < 2:
        return mean, math.nan, math.nan
    half = float(stats.t.ppf(0.5 + confidence / 2, len(x) - 1) * x.std(ddof=1) / math.sqrt(len(x)))
    return mean, mean - half, mean + half


def _per_robot_time(n_i: int, c: float) -> float:
    """Task time implied by a delivery rate: n_i robots completing c tasks per second
    spend n_i / c robot-seconds per task (infinite when nothing is delivered)."""
    if math.isnan(c):
        return math.nan
    return n_i / c if c > 0 else math.inf


def cells_for(records: list[TrialRecord], n: Split, warmup_s: float, measure_s: float,
              confidence: float) -> tuple[Cell, ...]:
    """c_i, t_i and where the time went, for every circuit of split n, from its trials.

    t_i(n) = n_i / c_i(n): the robot-seconds per delivery over the whole measurement
    window. Unlike the mean time of the tasks that were completed, it counts a robot that
    is stuck, and a trial whose robots delivered nothing at all (c = 0, t infinite). Its
    interval is c's interval inverted. The mean time of the completed tasks is kept as
    `t_delivered`, with their split into activities in `budget`.
    """
    cells = []
    for i in range(len(n)):
        rates = np.zeros(len(records))
        times, budgets = [], []
        for k, rec in enumerate(records):
            d = rec.table("deliveries")
            mask = (d["t_s"] >= warmup_s) & (d["t_s"] < warmup_s + measure_s) & (d["circuit"] == i)
            rates[k] = mask.sum() / measure_s
            times.append(d["task_time_s"][mask])
            budgets.append(np.column_stack([d[f"{a}_s"][mask] for a in ACTIVITIES]))
        if n[i] == 0:
            cells.append(Cell(c=0.0, t=math.inf, c_lo=0.0, c_hi=0.0, n_trials=len(records)))
            continue
        c, c_lo, c_hi = _interval(rates, confidence)
        done = np.concatenate(times)
        spent = np.concatenate(budgets)
        cells.append(Cell(
            c=c, t=_per_robot_time(n[i], c), c_lo=c_lo, c_hi=c_hi,
            t_lo=_per_robot_time(n[i], c_hi), t_hi=_per_robot_time(n[i], c_lo),
            n_trials=len(records),
            t_delivered=float(done.mean()) if len(done) else math.nan,
            budget=tuple(float(v) for v in spent.mean(axis=0)) if len(done) else (),
        ))
    return tuple(cells)


def arrivals_per_hour(records: list[TrialRecord], warmup_s: float, measure_s: float) -> float:
    """Target arrivals (sources and sinks) of the whole group per hour, mean over trials."""
    counts = [np.count_nonzero((rec.table("arrivals")["t_s"] >= warmup_s)
                               & (rec.table("arrivals")["t_s"] < warmup_s + measure_s)) for rec in records]
    return float(np.mean(counts)) * 3600.0 / measure_s


def measure(cfg: TavcConfig, out_dir: Path, *, n_max: int, trials: int, warmup_s: float, measure_s: float,
            confidence: float, n_jobs: int, progress: bool,
            only: Iterable[Split] | None = None) -> tuple[CTable, int]:
    """Run (or reuse) every split's trials (or only the splits in `only`); return the
    table and how many trials were reused."""
    plan = measurement_specs(cfg, n_max, trials, warmup_s, measure_s, only)
    all_specs = [s for specs in plan.values() for s in specs]
    executor = replace(Executor.from_config(cfg.executor), n_jobs=n_jobs)
    n_reused = TrialStore(out_dir, executor).run(all_specs, progress)
    return table_from(plan, out_dir, len(cfg.arena.circuits), warmup_s, measure_s, confidence), n_reused


def table_from(plan: Mapping[Split, list[TrialSpec]], out_dir: Path, n_circuits: int, warmup_s: float,
               measure_s: float, confidence: float) -> CTable:
    """The table of a measurement plan whose trials have all been run into `out_dir`."""
    table = CTable(n_circuits)
    for n, specs in plan.items():
        records = TrialStore(out_dir, Executor()).load(specs)
        table.cells[n] = cells_for(records, n, warmup_s, measure_s, confidence)
        table.arrivals_per_h[n] = arrivals_per_hour(records, warmup_s, measure_s)
    return table
