"""Whether the runs of two experiments that a claim compares (`Claim.against`: claims 7 and 8 set
breakdown_no_vacancy's and value_change's trials beside breakdown's) were made alike: the same
world, team, learner, tasks and horizon, computed by the same code. A run's own `claims.csv`
(`tavc run`, the report's retest) and the report's claims across runs ask it here, so that both
decide alike. Light: it loads no simulator."""

from __future__ import annotations

from collections.abc import Mapping

from tavc_cli.chapter import claims
from tavc_cli.dotted import dotted, plain
from tavc_cli.settings import TavcConfig

# What claims 7 and 8 (`Claim.against`) take to be alike in the runs of the two experiments they
# compare: the world, the team, the learner, the tasks, the simulation's step and the window the
# stable period is read over (`_horizon` adds the horizon). The rest is each experiment's own (its
# events, durations, warm-up, baselines) or draws other samples of the same (the seed, the trial
# counts).
ALIKE = ("arena", "robot", "team", "learner", "tasks", "sim.dt_s", "sim.physics_substeps", "sim.solver_iterations",
         "analysis.state", "scale.stable_window")


def unlike(cfg: TavcConfig, made_by: Mapping, other: TavcConfig, other_made_by: Mapping, limit: int = 3) -> str:
    """Why the run of `other` is no comparison for this one's (`cfg`) in claims 7 and 8, or "" where
    it is: "ran with other settings (...)" naming the first `limit` in which they differ, each as
    ``key value (this run: value)`` (a long value, such as a list of targets, as ``key (other
    values)``), then how many more: a setting of `ALIKE`, the horizon (`_horizon`), or what computed
    the trials (`made_by`, as `provenance.json` records it: tavc's simulator where both record it,
    the engine, the code of a learner from outside tavc)."""
    ours, theirs = _comparable(cfg, made_by), _comparable(other, other_made_by)
    keys = [k for k in dict.fromkeys([*ours, *theirs]) if ours.get(k) != theirs.get(k)
            and not (k == "the simulator's code" and None in (ours.get(k), theirs.get(k)))]
    if not keys:
        return ""
    shown = [_difference(k, theirs.get(k, "not set"), ours.get(k, "not set")) for k in keys[:limit]]
    more = [f"{len(keys) - limit} more"] if len(keys) > limit else []
    return f"ran with other settings ({'; '.join([*shown, *more])})"


def _comparable(cfg: TavcConfig, made_by: Mapping) -> dict[str, object]:
    """A run's settings of `ALIKE` as dotted keys, its horizon, and what computed its trials."""
    settings = dotted(plain(cfg), keep_empty=False)
    out = {k: v for k, v in settings.items() if any(k == a or k.startswith(f"{a}.") for a in ALIKE)}
    out.update(_horizon(cfg))
    learners = made_by.get("learner_code") or {}
    out.update({"the simulator's code": made_by.get("code_digest"), "engine": made_by.get("engine") or "physics",
                "the learner's code": {t: d.get("digest") for t, d in learners.items() if isinstance(d, dict)}})
    return out


def _horizon(cfg: TavcConfig) -> dict[str, object]:
    """How long a run's learners ran, as the experiments of claims 7 and 8 share it: its trials and
    convergence periods as multiples of the chapter's, the deliveries that end a trial, and the time
    they learned before the first event, or the record's start if none comes before it
    (value_change's warm-up is breakdown's warm-up and its breakdown's time together)."""
    first = min([0.0, *(float(e.time_s) for e in [*cfg.events.breakdowns, *cfg.events.value_changes])])
    return {"duration_s (of the chapter's)": _ratio(cfg.duration_s, cfg.paper.duration_s),
            "convergence_s (of the chapter's)": _ratio(cfg.convergence_s, cfg.paper.convergence_s),
            "deliveries": cfg.deliveries,
            "learning before the first event (s)": round(float(cfg.sim.warmup_s) + first, 6)}


def _ratio(ours, chapter) -> float | None:
    return None if ours is None or not chapter else round(float(ours) / float(chapter), 9)


def _difference(key: str, theirs, ours) -> str:
    """One setting in which two runs differ, as `unlike` names it."""
    if max(len(str(theirs)), len(str(ours))) > 24:
        return f"{key} (other values)"
    return f"{key} {theirs} (this run: {ours})"


def claims_apart(settings: Mapping[str, tuple[TavcConfig, Mapping]]) -> dict[int, str]:
    """For each claim that compares two experiments' runs (`Claim.against`: 7 and 8), both in
    `settings` (experiment -> its run's settings and what computed its trials, `runner.made_by`),
    why the other's run is no comparison for its own (`unlike`), by claim id, where it is not."""
    out = {}
    for own, claim in claims():
        if claim.against and own in settings and claim.against in settings:
            why = unlike(*settings[own], *settings[claim.against])
            if why:
                out[claim.id] = why
    return out
