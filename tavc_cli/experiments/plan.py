"""A run's plan: which controllers run, how many trials each, from which seeds, on which schedule.

It is worked out once, here (`plan_run`), from the config; the runner writes it beside the run as
``plan.json`` before any trial, and builds the trials from it (`build.trial_specs`); the
analysis, the report, compare and the API read it back (`read_plan`) to know each controller's
periods, never working them out again. Where the baselines run another schedule than the learner
(`scale.baseline_time_factor`), each controller's schedule is its own: the chapter's durations
for the baselines, which learn nothing, while the learners run 40 times them.

A folder written before runs recorded their plan has none; `read_plan` then works it out from
the folder's ``config.yaml`` with the same function, which is what the run was planned with.
"""

from __future__ import annotations

import json
from dataclasses import asdict, dataclass, replace
from pathlib import Path

from tavc_cli.errors import TavcError
from tavc_cli.io import write_text_atomic
from tavc_cli.learning.parameters import settings_mapping
from tavc_cli.learning.registry import controller_label, seed_code
from tavc_cli.readers import load_json
from tavc_cli.settings import TavcConfig, settings_of

PLAN_FILE = "plan.json"
PLAN_VERSION = 1


@dataclass(frozen=True)
class Schedule:
    """One controller's times, on the record's clock (seconds; t = 0 is the end of the warm-up)."""

    duration_s: float
    convergence_s: float
    warmup_s: float                  # the schedule's warm-up (`sim.warmup_s` at its time factor)
    baseline_lead_s: float | None    # `baseline_lead_s` at its time factor
    breakdowns_s: tuple[float, ...]  # each breakdown's time, in the config's order
    value_changes_s: tuple[float, ...]
    start_s: float                   # when its trials start: before 0 by `trial_warmup_s`, or late
    trial_warmup_s: float            # seconds simulated before `start_s`'s record begins
    starts_at: str                   # what sets the start (the learner's start, the first event, ...)


@dataclass(frozen=True)
class ControllerPlan:
    """One controller's trials: its label in every output, its learner's settings (as config.yaml
    writes them), its trial count and seed code (trial j's seed is (seed, code, j)), its schedule."""

    label: str
    learner: dict
    trials: int
    seed_code: int
    schedule: Schedule


@dataclass(frozen=True)
class RunPlan:
    """Every controller of a run, the learner first."""

    seed: int
    controllers: tuple[ControllerPlan, ...]

    def controller(self, label: str) -> ControllerPlan:
        """The plan of the controller labelled `label`."""
        for entry in self.controllers:
            if entry.label == label:
                return entry
        raise TavcError(f"{PLAN_FILE}: the run planned no controller {label!r} "
                        f"(it planned {', '.join(c.label for c in self.controllers)})")

    @property
    def shared_schedule(self) -> bool:
        """Whether every controller runs the learner's periods (then one analysis covers all)."""
        first = self.controllers[0].schedule
        return all(_periods(c.schedule) == _periods(first) for c in self.controllers)

    def settings_for(self, cfg: TavcConfig, label: str) -> TavcConfig:
        """`cfg` with the periods of controller `label`'s schedule: what its trials ran on and are
        analysed on."""
        if label == self.controllers[0].label:  # the learner's schedule is the config's own
            return cfg
        schedule = self.controller(label).schedule
        events = replace(
            cfg.events,
            breakdowns=[replace(b, time_s=t) for b, t in zip(cfg.events.breakdowns, schedule.breakdowns_s,
                                                             strict=True)],
            value_changes=[replace(v, time_s=t) for v, t in zip(cfg.events.value_changes, schedule.value_changes_s,
                                                                strict=True)])
        return replace(cfg, duration_s=schedule.duration_s, convergence_s=schedule.convergence_s,
                       baseline_lead_s=schedule.baseline_lead_s, events=events,
                       sim=replace(cfg.sim, warmup_s=schedule.warmup_s))

    def to_json(self) -> str:
        """The plan as ``plan.json`` holds it."""
        return json.dumps({"version": PLAN_VERSION, **asdict(self)}, indent=2)


def _periods(schedule: Schedule) -> tuple:
    """What the analysis reads of a schedule (not when its trials start)."""
    return (schedule.duration_s, schedule.convergence_s, schedule.warmup_s, schedule.baseline_lead_s,
            schedule.breakdowns_s, schedule.value_changes_s)


def plan_run(cfg: TavcConfig) -> RunPlan:
    """Work out the run's plan from its config: the learner with `trials` trials on the config's
    schedule, then each baseline with `baseline_trials` (the static one `static_trials`) on the
    baselines' schedule, starting `baseline_lead_s` before the first thing that matters to them."""
    learner = _schedule(cfg, cfg, learner=True)
    theirs = _baseline_config(cfg)
    baseline = _schedule(theirs, cfg, learner=False)
    out = [ControllerPlan(controller_label(cfg.learner.name), settings_mapping(cfg.learner), int(cfg.trials),
                          seed_code(controller_label(cfg.learner.name)), learner)]
    n_base = int(cfg.baseline_trials or cfg.trials)
    for name in cfg.baselines or []:
        if any(c.label == name for c in out):
            continue
        static = name == "static"
        settings = settings_of({"name": name, "allocation": cfg.static_allocation} if static else {"name": name})
        out.append(ControllerPlan(name, settings_mapping(settings), int(cfg.static_trials or n_base) if static
                                  else n_base, seed_code(name), baseline))
    return RunPlan(int(cfg.seed), tuple(out))


def _baseline_config(cfg: TavcConfig) -> TavcConfig:
    """`cfg` with every time the scale multiplies (duration, stable period, warm-up, lead, events)
    at `scale.baseline_time_factor` instead of `scale.time_factor` (where it is set)."""
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


def _schedule(own: TavcConfig, cfg: TavcConfig, *, learner: bool) -> Schedule:
    """A controller's schedule from the config of its periods `own` (the learner's `cfg`, or the
    baselines')."""
    warmup_s = float(own.sim.warmup_s)
    if learner:
        start_s, trial_warmup_s, what = 0.0, warmup_s, "the learner's start"
    else:
        start, what = baseline_start(own)
        start_s, trial_warmup_s = max(0.0, start), max(0.0, -start)
    lead = own.baseline_lead_s
    return Schedule(float(own.duration_s), float(own.convergence_s), warmup_s, None if lead is None else float(lead),
                    tuple(float(b.time_s) for b in own.events.breakdowns),
                    tuple(float(v.time_s) for v in own.events.value_changes), start_s, trial_warmup_s, what)


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


def write_plan(plan: RunPlan, folder: Path) -> None:
    """``plan.json`` in the run's folder."""
    write_text_atomic(folder / PLAN_FILE, plan.to_json())


def read_plan(folder: Path, cfg: TavcConfig) -> RunPlan:
    """The plan the run in `folder` recorded (its ``plan.json``, which its ``provenance.json``
    vouches for by digest as it does the tables); a folder written before runs recorded their plan:
    the plan its config `cfg` gives."""
    path = folder / PLAN_FILE
    if not path.exists():
        return plan_run(cfg)
    data = load_json(path)
    try:
        if data.pop("version") != PLAN_VERSION:
            raise ValueError("another version of the plan")
        plan = RunPlan(int(data["seed"]), tuple(
            ControllerPlan(str(c["label"]), dict(c["learner"]), int(c["trials"]), int(c["seed_code"]),
                           Schedule(**{**c["schedule"], "breakdowns_s": tuple(c["schedule"]["breakdowns_s"]),
                                       "value_changes_s": tuple(c["schedule"]["value_changes_s"])}))
            for c in data["controllers"]))
    except (KeyError, TypeError, ValueError, AttributeError) as error:
        raise TavcError(f"{path}: not a plan tavc wrote ({type(error).__name__}: {error}); run the "
                        "experiment again to rewrite it") from None
    if plan.seed != int(cfg.seed) or plan.controllers[0].learner != settings_mapping(cfg.learner):
        raise TavcError(f"{path}: is not the plan of the config.yaml beside it; run the experiment again to "
                        "rewrite both")
    return plan
