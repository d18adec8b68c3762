"""An experiment's tables and claims, from its saved trial records: what `tavc run` writes
after the trials (`state_time.csv`, `performance.csv`, ..., `comparison.csv`, `claims.csv`;
`outputs.write_analysis` writes them). Reads and writes no file."""

from __future__ import annotations

from collections.abc import Mapping

import pandas as pd
import yaml

from tavc_cli.analysis import spatiotemporal as st
from tavc_cli.analysis.convergence import convergence_table
from tavc_cli.analysis.mechanism import mechanism_table
from tavc_cli.analysis.performance import performance_table
from tavc_cli.analysis.qvalues import q_value_table
from tavc_cli.analysis.robots import robot_table
from tavc_cli.analysis.states import allocation_table, specialisation_table, state_time_table
from tavc_cli.analysis.trial_stats import stable_from, trial_stats
from tavc_cli.analysis.vacancy import vacancy_table
from tavc_cli.dotted import dotted
from tavc_cli.experiments.plan import RunPlan
from tavc_cli.experiments.records import TrialRecord
from tavc_cli.learning.parameters import CHAPTER_GAMMA
from tavc_cli.settings import TavcConfig, to_yaml


def analyse(cfg: TavcConfig, plan: RunPlan, records: list[TrialRecord]) -> dict[str, pd.DataFrame]:
    """The tables every experiment shares, from saved records only. Where the baselines ran
    another schedule than the learner (`scale.baseline_time_factor`, as the run's `plan` records),
    each controller's records are summarised over its own periods and the rows put together, the
    learner's first."""
    if plan.shared_schedule:
        return _analyse(cfg, records)
    parts: dict[str, list[TrialRecord]] = {}
    for rec in records:
        parts.setdefault(str(rec.meta["controller"]), []).append(rec)
    tables: dict[str, list[pd.DataFrame]] = {}
    for k, (controller, mine) in enumerate(parts.items()):
        for name, df in _analyse(plan.settings_for(cfg, controller), mine, with_theory=k == len(parts) - 1).items():
            tables.setdefault(name, []).append(df)
    return {name: pd.concat(dfs, ignore_index=True) for name, dfs in tables.items()}


def _analyse(cfg: TavcConfig, records: list[TrialRecord], with_theory: bool = True) -> dict[str, pd.DataFrame]:
    t_from, t_to = float(cfg.convergence_s), float(cfg.duration_s)
    scheme = cfg.analysis.state
    bin_s, start = float(cfg.analysis.performance_bin_s), -float(cfg.sim.warmup_s)
    # shares over the window the claims test (the whole stable period, or its last stretch of
    # the chapter's length: `scale.stable_window`)
    state = state_time_table(records, stable_from(cfg), t_to, scheme, with_theory=with_theory)
    perf = performance_table(records, bin_s, start, t_to)
    alloc = allocation_table(records, bin_s, start, t_to) if scheme == "circuits" else None
    tables = {"state_time": state, "performance": perf, "trial_stats": trial_stats(records, cfg)}
    if alloc is not None:
        tables["allocation"] = alloc
    if scheme == "groups":
        tables["specialisation"] = specialisation_table(records, bin_s, start, t_to)
    if records and "choices" in records[0].tables:
        tables["robots"] = robot_table(records, t_from, t_to)
    # a long run's snapshots thinned to the chapter's number per trial (same table at time_factor 1)
    q_values = q_value_table(records, every_s=float(cfg.sim.q_snapshot_every_s) * float(cfg.scale.time_factor))
    if q_values is not None:
        tables["q_values"] = q_values
    convergence = convergence_table(records, t_from, float(getattr(cfg.learner, "gamma", CHAPTER_GAMMA)))
    if len(convergence):
        tables["convergence"] = convergence
    mechanism = mechanism_table(records, t_from)
    if len(mechanism):
        tables["mechanism"] = mechanism
    if any(rec.meta["controller"] == "behaviour" for rec in records):
        tables.update(spatiotemporal_tables(cfg, records))
    vacancy = vacancy_table(records)
    if len(vacancy):
        tables["vacancy"] = vacancy
    return tables


def spatiotemporal_tables(cfg: TavcConfig, records: list[TrialRecord]) -> dict[str, pd.DataFrame]:
    """Section 1.4's tables for the behaviour learners' trials: Table 1.1 and the samples behind
    it, the learned policies, and the lanes (offsets and a heat map, first and last tenth)."""
    mine = [rec for rec in records if rec.meta["controller"] == "behaviour"]
    arena = cfg.arena
    xy = {t.name: (float(t.x), float(t.y)) for t in arena.targets}
    source, sink = xy[arena.circuits[0].source], xy[arena.circuits[0].sink]
    windows = st.lane_windows  # each trial's own first and last tenth
    traversals, targets = st.traversal_table(mine), st.target_time_table(mine)
    return {"table_1_1": st.table_1_1_from(traversals, targets), "traversals": traversals,
            "target_times": targets, "policy": st.policy_table(mine),
            "lanes": st.lane_table(mine, source, sink, windows),
            "occupancy": st.occupancy_table(mine, source, sink, float(arena.width_m), float(arena.height_m),
                                            windows)}


def experiment_claims(cfg: TavcConfig, plan: RunPlan, tables: Mapping[str, pd.DataFrame],
                      others: Mapping[str, pd.DataFrame | str]) -> pd.DataFrame:
    """The chapter's claims about this experiment, tested on its trials (and, where a claim
    compares two experiments, on the other's `trial_stats` in `others`, by experiment name, or
    not where `others` holds, in its place, the settings in which that run differs from this one:
    `unlike_settings`); the claims about learning on the trials of the run's learner, the first
    controller of its `plan`."""
    # deferred: loads scipy
    from tavc_cli.analysis.claim_rules import unlike_run
    from tavc_cli.analysis.claims import CLAIM_TABLES, claim_rows, learner_under_test

    name = str(cfg.experiment_name or "")
    runs = {name: tables["trial_stats"]}
    runs.update({f"{name}/{t}": tables[t] for t in CLAIM_TABLES if t in tables})
    runs.update({other: unlike_run(table) if isinstance(table, str) else table
                 for other, table in others.items() if other != name})
    # the claims about learning test this run's own learner (TAVC's runs: TAVC)
    return claim_rows(runs, only_experiment=name, learner=learner_under_test([plan.controllers[0].label]))


# What claims 7 and 8 (`Claim.against`) take to be alike in the runs of the two experiments they
# compare: the world, the team, the learner, the tasks, the horizon and the simulation's step. The
# rest is each experiment's own (its events, durations, warm-up, baselines) or draws other samples
# of the same (the seed, the trial counts).
ALIKE = ("arena", "robot", "team", "learner", "tasks", "scale.time_factor", "scale.deliveries_factor",
         "scale.baseline_time_factor", "scale.stable_window", "sim.dt_s", "sim.physics_substeps",
         "sim.solver_iterations", "analysis.state")


def unlike_settings(cfg: TavcConfig, other: TavcConfig, limit: int = 3) -> str:
    """The settings of `ALIKE` in which the run of `other` differs from this one's (`cfg`), each as
    ``key value (this run: value)`` (a long value, such as a list of targets, as ``key (other
    values)``), at most `limit` of them and then how many more; "" where there are none: the two
    runs may be compared."""
    ours, theirs = (dotted(yaml.safe_load(to_yaml(c))) for c in (cfg, other))
    keys = [k for k in sorted({*ours, *theirs}) if any(k == a or k.startswith(f"{a}.") for a in ALIKE)
            and ours.get(k) != theirs.get(k)]
    shown = [_difference(k, theirs.get(k, "not set"), ours.get(k, "not set")) for k in keys[:limit]]
    return "; ".join([*shown, *([f"{len(keys) - limit} more"] if len(keys) > limit else [])])


def _difference(key: str, theirs, ours) -> str:
    """One setting in which two runs differ, as `unlike_settings` names it."""
    if max(len(str(theirs)), len(str(ours))) > 24:
        return f"{key} (other values)"
    return f"{key} {theirs} (this run: {ours})"

