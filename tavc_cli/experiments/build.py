"""Turn an experiment's settings into the trials it needs.

Controllers: the configured `learner` (labelled `tavc` for the TAVC learners,
else by its name) and every entry of `baselines`. Each controller runs its own
trials; trial j of controller c gets the seed SeedSequence(seed).spawn-key (c, j),
where c is the controller's fixed code below, so adding trials or baselines never
changes the seeds of the others.

Batches: trials still to run are advanced together in groups of up to
`executor.batch_size` (one process, one physics space). A trial computes exactly
what it would compute alone (see `sim.world`), so batching changes speed, never
results, and neither does the number of processes.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

from tavc_cli.experiments.spec import Breakdown, TrialSpec, ValueChange
from tavc_cli.learning.parameters import LearnerSettings
from tavc_cli.learning.registry import controller_label, seed_code, settings_of
from tavc_cli.settings import TavcConfig

TIME_UNITS_S = {"s": 1.0, "ms": 1e-3}  # unit of t in r = w / t, in seconds


@dataclass(frozen=True)
class Batch:
    """Trials advanced together in one process."""

    controller: str
    index: int
    specs: tuple[TrialSpec, ...]

    @property
    def sim_seconds(self) -> float:
        """The seconds the batch's trials simulate, added up: its weight in the progress shown."""
        return sum(s.span_s for s in self.specs)


def controllers(cfg: TavcConfig) -> list[tuple[str, LearnerSettings, int]]:
    """(label, learner settings, number of trials) for the learner and each baseline."""
    out = [(controller_label(cfg.learner.name), cfg.learner, int(cfg.trials))]
    n_base = int(cfg.baseline_trials or cfg.trials)
    for name in cfg.baselines or []:
        if any(label == name for label, _, _ in out):
            continue
        static = name == "static"
        n = int(cfg.static_trials or n_base) if static else n_base
        out.append((name, settings_of({"name": name, "allocation": cfg.static_allocation} if static
                                      else {"name": name}), n))
    return out


def base_spec(cfg: TavcConfig) -> TrialSpec:
    """The spec every trial of this config shares, before controller, index and seed."""
    sim, tasks, events = cfg.sim, cfg.tasks, cfg.events
    return TrialSpec(
        arena=cfg.arena,
        robot=cfg.robot,
        speeds_mps=tuple(float(m.speed_mps) for m in cfg.team.members),
        groups=tuple(str(m.group) for m in cfg.team.members),
        policy=cfg.learner,
        values=tuple(float(v) for v in tasks.values),
        score_values=tuple(float(v) for v in tasks.score_values),
        time_unit_s=TIME_UNITS_S[tasks.time_unit],
        duration_s=float(cfg.duration_s),
        warmup_s=float(sim.warmup_s),
        deliveries=None if cfg.deliveries is None else int(cfg.deliveries),
        dt_s=float(sim.dt_s),
        physics_substeps=int(sim.physics_substeps),
        solver_iterations=int(sim.solver_iterations),
        breakdowns=tuple(Breakdown(float(b.time_s), b.robot, b.circuit) for b in events.breakdowns),
        value_changes=tuple(ValueChange(float(v.time_s), tuple(float(x) for x in v.values))
                            for v in events.value_changes),
        q_snapshot_every_s=float(sim.q_snapshot_every_s),
        pose_every_s=float(sim.pose_every_s),
    )


def settings_for(cfg: TavcConfig, controller: str) -> TavcConfig:
    """The settings a controller's trials ran on: the learner's `cfg`, or `baseline_settings`."""
    return cfg if controller == controller_label(cfg.learner.name) else baseline_settings(cfg)


def baseline_settings(cfg: TavcConfig) -> TavcConfig:
    """The settings the baselines run and are analysed on: `cfg` itself, or, where the scale
    puts them on another schedule (`scale.baseline_time_factor`), a copy whose every time
    that the scale multiplies (duration, stable period, warm-up, lead, events) is `cfg`'s times
    that factor over `scale.time_factor`. The baselines learn nothing, so their
    distribution does not depend on the horizon: at `scale=converged` they run the chapter's
    own schedule while the learners run 40 times it."""
    factor, theirs = float(cfg.scale.time_factor), cfg.scale.baseline_time_factor
    if theirs is None or float(theirs) == factor:
        return cfg

    def at(t: float | None) -> float | None:
        # times the factor, then over it: exact for the whole seconds configs hold
        return None if t is None else float(t) * float(theirs) / factor

    events = replace(
        cfg.events,
        breakdowns=[replace(b, time_s=at(b.time_s)) for b in cfg.events.breakdowns],
        value_changes=[replace(v, time_s=at(v.time_s)) for v in cfg.events.value_changes])
    return replace(cfg, duration_s=at(cfg.duration_s), convergence_s=at(cfg.convergence_s),
                   baseline_lead_s=at(cfg.baseline_lead_s), events=events,
                   sim=replace(cfg.sim, warmup_s=at(cfg.sim.warmup_s)))


def baseline_start(cfg: TavcConfig) -> tuple[float, str]:
    """The time of the record at which the baselines start, and what they start before: with the
    learner (at minus the warm-up), or `baseline_lead_s` before the first thing that matters
    to them, their first event or else the stable period, though never before the learner."""
    learner_start = 0.0 - float(cfg.sim.warmup_s)  # not -warmup_s: that is -0.0 without one
    if cfg.baseline_lead_s is None:
        return learner_start, "the learner's start"
    events = sorted(float(e.time_s) for e in [*cfg.events.breakdowns, *cfg.events.value_changes])
    first, what = ((events[0], "the first event") if events and events[0] < float(cfg.convergence_s)
                   else (float(cfg.convergence_s), "the stable period"))
    return max(learner_start, first - float(cfg.baseline_lead_s)), what


def trial_specs(cfg: TavcConfig) -> list[TrialSpec]:
    """Every trial of every controller, in a fixed order. The baselines that start after the
    learner have a shorter warm-up, or none and a late start (`baseline_start`)."""
    base, theirs = base_spec(cfg), baseline_settings(cfg)
    base_baselines = base if theirs is cfg else base_spec(theirs)
    seed = int(cfg.seed)
    start, _ = baseline_start(theirs)
    specs = []
    for k, (label, policy, n_trials) in enumerate(controllers(cfg)):
        code = seed_code(label)
        # the learner comes first, then the baselines
        spec = base if k == 0 else base_baselines
        warmup_s, start_s = (spec.warmup_s, 0.0) if k == 0 else (max(0.0, -start), max(0.0, start))
        for j in range(n_trials):
            specs.append(replace(spec, policy=policy, controller=label, trial=j, seed=(seed, code, j),
                                 warmup_s=warmup_s, start_s=start_s))
    return specs


def make_batches(specs: list[TrialSpec], size: int, workers: int = 1) -> list[Batch]:
    """Group trials, controller by controller, into batches of at most `size`, and small
    enough that `workers` processes all get one when there are trials enough."""
    size = max(1, min(size, -(-len(specs) // max(1, workers))))
    by_controller: dict[str, list[TrialSpec]] = {}
    for spec in specs:
        by_controller.setdefault(spec.controller, []).append(spec)
    out = []
    for label, group in by_controller.items():
        for k in range(0, len(group), size):
            out.append(Batch(label, k // size, tuple(group[k:k + size])))
    return out
