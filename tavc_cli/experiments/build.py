"""Turn an experiment's settings into the trials it needs.

Controllers: the configured `learner` (labelled `tavc` for the TAVC learners,
else by its name) and every entry of `baselines`, as the run's plan lists them
(`plan.plan_run`). Each controller runs its own trials; trial j of controller c
gets the seed SeedSequence(seed).spawn-key (c, j), where c is the controller's
fixed code (`registry.seed_code`), so adding trials or baselines never changes the
seeds of the others.

Batches: trials still to run are advanced together in groups of up to
`executor.batch_size` (one process, one physics space). A trial computes exactly
what it would compute alone (see `sim.world`), so batching changes speed, never
results, and neither does the number of processes.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass, replace

from tavc_cli.errors import TavcError
from tavc_cli.experiments.plan import RunPlan, plan_run
from tavc_cli.experiments.spec import Breakdown, TrialSpec, ValueChange
from tavc_cli.learning.parameters import PluginSettings
from tavc_cli.learning.registry import SETTINGS
from tavc_cli.settings import TavcConfig, settings_of

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
        time_from_source=tasks.time_from == "source",
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


def trial_specs(cfg: TavcConfig, plan: RunPlan | None = None) -> list[TrialSpec]:
    """Every trial of every controller of the run's plan (`plan.plan_run`, worked out here if not
    given), in its order: each controller's trials on its own schedule (the baselines that start
    after the learner with a shorter warm-up, or none and a late start)."""
    plan = plan or plan_run(cfg)
    specs = []
    for entry in plan.controllers:
        own = plan.settings_for(cfg, entry.label)
        spec = base_spec(own)
        schedule = entry.schedule
        policy = settings_of(entry.learner)
        for j in range(entry.trials):
            specs.append(replace(spec, policy=policy, controller=entry.label, trial=j,
                                 seed=(plan.seed, entry.seed_code, j), warmup_s=schedule.trial_warmup_s,
                                 start_s=schedule.start_s))
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


# A learner from outside tavc runs only where `confine` holds it; what tavc builds of its trials elsewhere
# is built with a built-in one standing in.
STAND_IN = "random"


def foreign(specs: Iterable[TrialSpec]) -> bool:
    """Whether any of these trials runs a learner from outside tavc (`learner.target`)."""
    return any(isinstance(spec.policy, PluginSettings) for spec in specs)


def stand_in(spec: TrialSpec) -> TrialSpec:
    """`spec`, with a built-in learner (`STAND_IN`) in place of one from outside tavc: for what
    a process builds of a trial without running its learner (the kernels it compiles, the start it
    places), where that learner's code must not run."""
    return replace(spec, policy=SETTINGS[STAND_IN]()) if foreign([spec]) else spec


def in_this_process(specs: Iterable[TrialSpec], choice: str, what: str) -> None:
    """Refuse, in one line, to run a learner from outside tavc in this process (which is never
    confined) for `what` (a command timing the simulator), unless ``executor.confine=off``."""
    if choice != "off" and foreign(specs):
        raise TavcError(f"{what} runs its trials in its own process, which is not held to a folder; a learner from "
                        "outside tavc (learner.target) runs there only with executor.confine=off")
