"""Resolution: fill every derived value of a composed config in place.

Rules:

- ``trials``: ``min(scale.trials, paper.trials)``, or ``paper.trials`` when the scale sets none.
- ``baseline_trials``: ``paper.baseline_trials`` capped by ``scale.trials`` like ``trials``;
  when the paper gives none, the same as ``trials``.
- ``static_trials`` (the static baseline's): ``paper.static_trials`` capped likewise; when the
  paper gives none, the same as ``baseline_trials``.
- ``duration_s``, ``convergence_s``: the paper's value times ``scale.time_factor``. When the user
  sets ``duration_s`` but not ``convergence_s``, the stable period keeps the paper's share of
  the run: ``convergence_s = duration_s * (paper.convergence_s / paper.duration_s)`` (what
  ``scale`` gives too, since it multiplies both by the same factor).
- ``deliveries``: ``paper.deliveries`` times ``scale.deliveries_factor`` (null: ``scale.time_factor``),
  rounded, at least 1 (none when
  the paper measures its trials in seconds). A trial then ends with the tick of its team's
  n-th delivery after the warm-up, ``duration_s`` being its longest.
- ``baseline_lead_s``, ``sim.warmup_s`` and every event time (``events.breakdowns[*].time_s``,
  ``events.value_changes[*].time_s``) are ALWAYS multiplied by ``scale.time_factor``, also when
  set on the command line, so that an experiment keeps its shape at every scale.
- ``scale.baseline_time_factor``: ``scale.time_factor`` when null. The baselines then run every
  time above at that factor instead (`experiments.plan.plan_run`).
- ``output_dir``: ``runs/<scale.name>/<experiment_name>`` (`default_output_dir`). Outside
  ``results/``, which holds the committed reproduction and is written only where named, and
  apart by scale, so that a smoke run never meets a quick or a paper run of the same experiment.
- ``team.members``: ``team.n_robots`` copies of ``{speed_mps: robot.speed_mps, group: all}``.
- ``tasks.values``: 1.0 per circuit; ``tasks.score_values``: ``tasks.values``.
- ``executor.n_jobs``: ``os.cpu_count()``.
- ``learner.allocations`` (``learner=model``, ``learner=informed``): robots per circuit by team
  size, read from the model's output ``learner.model_file`` (`model.allocations.model_allocations`).
"""

import math
import os
from pathlib import Path
from typing import Optional

from omegaconf import DictConfig

from tavc_cli.errors import TavcError
from tavc_cli.io import default_root
from tavc_cli.learning.registry import MODEL_LEARNERS
from tavc_cli.model.allocations import model_allocations, model_world
from tavc_cli.settings import MemberConfig
from tavc_cli.sim.arena import most_robots


def resolve(cfg: DictConfig, *, job_dir: Optional[str] = None) -> None:
    """Fill every derived value in place (rules in the module docstring)."""
    factor = cfg.scale.time_factor
    if cfg.scale.baseline_time_factor is None:
        cfg.scale.baseline_time_factor = factor
    if cfg.trials is None:
        cfg.trials = _capped(cfg.paper.trials, cfg.scale.trials)
    if cfg.baseline_trials is None:
        paper_baseline = cfg.paper.baseline_trials
        cfg.baseline_trials = (
            cfg.trials if paper_baseline is None else _capped(paper_baseline, cfg.scale.trials)
        )
    if cfg.static_trials is None:
        paper_static = cfg.paper.static_trials
        cfg.static_trials = (
            cfg.baseline_trials if paper_static is None else _capped(paper_static, cfg.scale.trials)
        )
    user_duration = cfg.duration_s is not None
    if not user_duration:
        cfg.duration_s = cfg.paper.duration_s * factor
    if cfg.convergence_s is None:
        # a duration set by hand keeps the paper's converging share; else scale both alike
        share = cfg.paper.convergence_s / cfg.paper.duration_s
        cfg.convergence_s = cfg.duration_s * share if user_duration else cfg.paper.convergence_s * factor
    if cfg.deliveries is None and cfg.paper.deliveries is not None:
        count_factor = factor if cfg.scale.deliveries_factor is None else cfg.scale.deliveries_factor
        cfg.deliveries = max(1, round(cfg.paper.deliveries * count_factor))
    # Warm-up and event times scale with the experiment, even when set by hand, so that a
    # quick run keeps the paper run's shape (a breakdown a third of the way in stays there).
    cfg.sim.warmup_s = cfg.sim.warmup_s * factor
    if cfg.baseline_lead_s is not None:
        cfg.baseline_lead_s = cfg.baseline_lead_s * factor
    for event in [*cfg.events.breakdowns, *cfg.events.value_changes]:
        event.time_s = event.time_s * factor
    base_dir = cfg.output_dir if cfg.output_dir is not None else str(default_output_dir(cfg.scale.name,
                                                                                        cfg.experiment_name))
    if job_dir and not str(base_dir).strip():  # a sweep's jobs would land in the working folder
        raise TavcError("output_dir: must not be empty")
    cfg.output_dir = str(Path(base_dir) / job_dir) if job_dir else base_dir
    # (a team that could never start is left for validation to refuse: expanding it could take minutes)
    if cfg.team.members is None and 1 <= cfg.team.n_robots <= _most_robots(cfg):
        speed_mps = cfg.robot.speed_mps
        cfg.team.members = [MemberConfig(speed_mps=speed_mps) for _ in range(cfg.team.n_robots)]
    # ``values`` is read by subscript: on a DictConfig, ``.values`` is the dict method.
    if cfg.tasks["values"] is None:
        cfg.tasks["values"] = [1.0] * len(cfg.arena.circuits)
    if cfg.tasks.score_values is None:
        cfg.tasks.score_values = list(cfg.tasks["values"])
    if cfg.executor.n_jobs is None:
        cfg.executor.n_jobs = os.cpu_count() or 1
    if cfg.learner.name in MODEL_LEARNERS and cfg.learner.target is None and cfg.learner.allocations is None:
        cfg.learner.allocations = model_allocations(cfg.learner.model_file, len(cfg.arena.circuits), model_world(cfg))


def default_output_dir(scale: str, experiment: str) -> Path:
    """Where a run goes when no ``output_dir`` is given: ``runs/<scale>/<experiment>``."""
    return default_root(scale) / experiment


def _most_robots(cfg: DictConfig) -> float:
    """`sim.arena.most_robots` for the config's arena and robot, or no limit while those are not
    numbers yet (validation says so)."""
    try:
        return most_robots(float(cfg.arena.width_m), float(cfg.arena.height_m), float(cfg.robot.radius_m))
    except (TypeError, ValueError, OverflowError, ZeroDivisionError):
        return math.inf


def _capped(count: int, cap: Optional[int]) -> int:
    """``count``, limited to ``cap`` when the scale sets one."""
    return count if cap is None else min(cap, count)
