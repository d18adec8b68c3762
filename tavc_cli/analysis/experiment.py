"""An experiment's tables and claims, from its saved trial records: what `tavc run` writes
after the trials (`state_time.csv`, `performance.csv`, ..., `comparison.csv`, `claims.csv`;
`outputs.write_analysis` writes them). Reads and writes no file."""

from __future__ import annotations

from collections.abc import Mapping

import pandas as pd

from tavc_cli.analysis import spatiotemporal as st
from tavc_cli.analysis.convergence import convergence_table
from tavc_cli.analysis.mechanism import mechanism_table
from tavc_cli.analysis.performance import performance_table
from tavc_cli.analysis.qvalues import q_value_table
from tavc_cli.analysis.robots import robot_table
from tavc_cli.analysis.states import allocation_table, specialisation_table, state_time_table
from tavc_cli.analysis.trial_stats import stable_from, trial_stats
from tavc_cli.analysis.vacancy import vacancy_table
from tavc_cli.chapter import claims
from tavc_cli.experiments.plan import RunPlan
from tavc_cli.experiments.records import TrialRecord
from tavc_cli.learning.parameters import CHAPTER_GAMMA
from tavc_cli.settings import TavcConfig


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
    not where `others` holds, in its place, why that run is no comparison: `alike.unlike`); the claims
    about learning on the trials of the run's learner, the first controller of its `plan`."""
    # deferred: loads scipy
    from tavc_cli.analysis.claims import CLAIM_TABLES, claim_rows, learner_under_test

    name = str(cfg.experiment_name or "")
    runs = {name: tables["trial_stats"]}
    runs.update({f"{name}/{t}": tables[t] for t in CLAIM_TABLES if t in tables})
    runs.update({other: table for other, table in others.items() if other != name and not isinstance(table, str)})
    apart = {c.id: others[c.against] for own, c in claims() if own == name and isinstance(others.get(c.against), str)}
    # the claims about learning test this run's own learner (TAVC's runs: TAVC)
    return claim_rows(runs, only_experiment=name, learner=learner_under_test([plan.controllers[0].label]),
                      apart=apart)
