"""The tables a run writes (`TABLE_NAMES`), column by column (`TABLES`): which columns each has, which hold
numbers, which are never empty, which values a column may take. `schema` checks a table
against its entry before a reader trusts it."""

from __future__ import annotations

from dataclasses import dataclass, field

from tavc_cli.notation import STATE_PREFIX

# every table a run may write in its folder (`outputs.write_analysis`), by file stem
TABLE_NAMES = ("state_time", "performance", "trial_stats", "allocation", "specialisation", "robots", "q_values",
               "convergence", "mechanism", "vacancy", "table_1_1", "traversals", "target_times", "policy", "lanes",
               "occupancy", "comparison", "claims")
# trial_stats: one column of shares of the stable period per state (`analysis.trial_stats`; named by
# `notation.STATE_PREFIX`), and per group of robots (heterogeneous teams) one of the mean final
# Q(s, high) - Q(s, low) (`analysis.qvalues.q_gaps`)
Q_GAP_PREFIX = "q_gap_"


@dataclass(frozen=True)
class TableSchema:
    """One table's columns: `columns` are always there and hold numbers unless named in
    `text`; `optional` columns hold numbers where they are there (tables of runs written
    before they were added lack them); `keys` are never empty; columns whose names start
    with one of `prefixes` hold numbers too (one per state, per Q-table entry, ...);
    `choices` limit a column's values; no two rows have the same values in the `unique`
    columns; a table that a run writes only with rows in it is not `empty_ok`."""

    columns: tuple[str, ...]
    text: tuple[str, ...] = ("controller",)
    keys: tuple[str, ...] = ("controller", "trial")
    optional: tuple[str, ...] = ()
    prefixes: tuple[str, ...] = ()
    choices: dict[str, frozenset[str]] = field(default_factory=dict)
    empty_ok: bool = True
    unique: tuple[str, ...] = ()


TABLES: dict[str, TableSchema] = {
    "state_time": TableSchema(("state", "controller", "mean_pct", "std_pct", "n_trials"),
                              text=("state", "controller"),
                              # one trial has no spread: its std_pct is empty
                              keys=("state", "controller", "mean_pct", "n_trials"), empty_ok=False,
                              unique=("state", "controller")),
    "performance": TableSchema(("t_s", "controller", "mean", "std", "n_trials"),
                               keys=("t_s", "controller", "n_trials"), unique=("t_s", "controller")),
    "trial_stats": TableSchema(("controller", "trial", "value_rate_stable", "value_rate_convergence",
                                "value_rate_before", "settle_s", "policy_settle_s", "policy_changes"),
                               keys=("controller", "trial", "duration_s"), optional=("duration_s",),
                               prefixes=(STATE_PREFIX, Q_GAP_PREFIX), unique=("controller", "trial")),
    "allocation": TableSchema(("t_s", "controller", "mean_high", "std_high", "n_trials"),
                              keys=("t_s", "controller", "n_trials"), unique=("t_s", "controller")),
    "specialisation": TableSchema(("t_s", "controller", "group", "mean_share_high", "std_share_high", "n_trials"),
                                  text=("controller", "group"), keys=("t_s", "controller", "group", "n_trials")),
    "robots": TableSchema(("controller", "trial", "robot", "kind", "circuit", "n_choices", "share_main",
                           "switch_rate"), text=("controller", "kind"), keys=("controller", "trial", "robot", "kind"),
                          unique=("controller", "trial", "robot")),
    "q_values": TableSchema(("controller", "trial", "robot", "t_s"), keys=("controller", "trial", "robot", "t_s"),
                            prefixes=("q_",)),
    "convergence": TableSchema(("controller", "trial", "t_from_s", "t_to_s", "q_drift", "policy_changed_share",
                                "alloc_first_half", "alloc_second_half", "alloc_drift", "td_error_rel"),
                               empty_ok=False),
    "mechanism": TableSchema(("controller", "trial", "window", "t_from_s", "t_to_s", "n_stayers_high",
                              "n_stayers_low", "n_alternators", "n_mixed", "n_idle", "switch_share", "task_s_stay",
                              "task_s_switch", "avoid_s_stay", "avoid_s_switch", "wait_s_stay", "wait_s_switch",
                              "q_gap_stay_switch"), text=("controller", "window"),
                             keys=("controller", "trial", "window"), empty_ok=False),
    "vacancy": TableSchema(("controller", "trial", "event", "event_t_s", "vacancy_circuit", "filled", "filler",
                            "filler_from", "fill_delay_s", "moves_before_fill", "chain"),
                           text=("controller", "event", "filled", "chain"), keys=("controller", "trial", "filled"),
                           choices={"filled": frozenset({"True", "False"})}, empty_ok=False),
    "table_1_1": TableSchema(("n_traversals", "mean_traversal_s", "std_traversal_s", "n_robots", "m_arrivals",
                              "mean_target_s", "std_target_s", "n_trials"), text=(),
                             keys=("n_traversals", "m_arrivals")),
    "traversals": TableSchema(("controller", "trial", "robot", "traversal", "time_s"),
                              keys=("controller", "trial", "robot", "traversal", "time_s")),
    "target_times": TableSchema(("controller", "trial", "arrival", "time_s"),
                                keys=("controller", "trial", "arrival", "time_s")),
    "policy": TableSchema(("controller", "trial", "robot", "n_states"), keys=("controller", "trial", "robot"),
                          prefixes=("share_", "stop_rate_")),
    "lanes": TableSchema(("controller", "trial", "window", "mean_left_m", "n_frames"), text=("controller", "window"),
                         keys=("controller", "trial", "window")),
    "occupancy": TableSchema(("window", "direction", "x_m", "y_m", "count"), text=("window", "direction"),
                             keys=("window", "direction", "x_m", "y_m", "count")),
    # the chapter's states, whatever team this run had: its `state` column is not checked
    "comparison": TableSchema(("table", "state", "quantity", "chapter", "ours", "difference"),
                              text=("table", "state", "quantity"), keys=("table", "state", "quantity", "chapter"),
                              empty_ok=False),
    "claims": TableSchema(("claim_id", "claim", "verdict", "statistic", "p_value", "detail"),
                          text=("claim", "verdict", "detail"), keys=("claim_id", "claim", "verdict"),
                          choices={"verdict": frozenset({"reproduced", "not_reproduced", "inconclusive"})},
                          empty_ok=False),
}
# the settings' sections every config.yaml tavc has written holds, each a block, `calibration` last (a
# section added later is not asked of the files written before it)
