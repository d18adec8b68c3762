"""Seed for seed (`analysis.matched`, the report's tables of it): robots matched by their first
Q-tables, counted by their kinds at the end, beside what chance would give robot by robot."""

from __future__ import annotations

from pathlib import Path
from types import SimpleNamespace

import pandas as pd
import pytest

from tavc_cli.analysis.matched import seed_for_seed
from tavc_cli.errors import TavcError
from tavc_cli.report.counterfactuals import seed_for_seed_lines
from tavc_cli.report.files import seed_for_seed_cell
from tests.helpers import KINDS_A, KINDS_B, q_table, robots_table

S0, S1, ALT = ("stayer", 0), ("stayer", 1), ("alternator", -1)
Q = [0.1, -0.05, 0.02, 0.07]


def _runs(trials: list[list[tuple[str, int]]], controller: str = "tavc") -> tuple[pd.DataFrame, pd.DataFrame]:
    """A run's robots and first Q-tables: trial j's robots of `trials[j]`, the same tables in every
    trial (robot i's all Q[i] + j)."""
    robots = pd.concat([robots_table(kinds, controller, j) for j, kinds in enumerate(trials)], ignore_index=True)
    tables = pd.concat([q_table([q + j for q in Q[:len(kinds)]], 0.0, controller, j) for j, kinds in enumerate(trials)],
                       ignore_index=True)
    return robots, tables


def test_the_same_kinds_and_the_chance_of_them_robot_by_robot_by_hand():
    """a: trial 0 (stayer 0, stayer 1), trial 1 (stayer 0, alternator); b: trial 0 the same,
    trial 1 (stayer 1, alternator). Same kind: 3 of 4 (not trial 1's robot 0). Chance, robot by
    robot over the two trials: robot 0 is a stayer on 0 twice in a, once in two in b, 2 x 1/2 = 1;
    robot 1 is half stayer 1, half alternator in both, 2 x (1/4 + 1/4) = 1; so 2, where pooling the
    robots would give 4 x (1/2 1/4 + 1/4 1/2 + 1/4 1/4) = 1.25."""
    robots_a, tables = _runs([[S0, S1], [S0, ALT]])
    robots_b, _ = _runs([[S0, S1], [S1, ALT]])
    matched = seed_for_seed(robots_a, tables, robots_b, tables)
    assert (matched.robots, matched.same, matched.chance) == (4, 3, 2.0)


def test_each_controller_is_its_own_chance():
    """Two learners' runs of one robot over two trials: x's (stayer 0, stayer 1) beside (stayer 0,
    stayer 0), chance 2 x 1/2 = 1; y's (alternator, alternator) beside (alternator, stayer 0),
    chance 2 x 1/2 = 1: 2 in all, where pooling the controllers' robot 0 would give 4 x (1/4 3/4 +
    1/2 1/4) = 1.25."""
    xa, qx = _runs([[S0], [S1]], "x")
    xb, _ = _runs([[S0], [S0]], "x")
    ya, qy = _runs([[ALT], [ALT]], "y")
    yb, _ = _runs([[ALT], [S0]], "y")
    tables = pd.concat([qx, qy], ignore_index=True)
    matched = seed_for_seed(pd.concat([xa, ya]), tables, pd.concat([xb, yb]), tables)
    assert (matched.robots, matched.same, matched.chance) == (4, 2, 2.0)


def test_robots_are_matched_by_their_own_first_table():
    """Robot 3 starts from another table in b: not matched. Trial 1's first snapshots come at
    3600 s (a trial that joined late): its robots are matched by those. A later snapshot that
    differs changes nothing; nor does an earlier snapshot of one robot for the others. The random
    baseline, with no Q-table, is never matched."""
    robots_a = pd.concat([robots_table(KINDS_A), robots_table(KINDS_A, trial=1), robots_table(KINDS_A, "random")])
    robots_b = pd.concat([robots_table(KINDS_B), robots_table(KINDS_B, trial=1), robots_table(KINDS_A, "random")])
    q_a = pd.concat([q_table(Q), q_table(Q, t_s=3600.0, trial=1), q_table([0.5] * 4, t_s=7200.0)])
    q_b = pd.concat([q_table([*Q[:3], 0.03]), q_table(Q, t_s=3600.0, trial=1), q_table([0.4] * 4, t_s=7200.0)])
    matched = seed_for_seed(robots_a, q_a, robots_b, q_b)
    assert (matched.robots, matched.same) == (7, 5)  # trial 0's robots 0-2 (same: 0, 2), trial 1's 0-3 (0, 2, 3)
    early = q_table([0.9], t_s=-1.0, trial=1)  # robot 0 of trial 1 only: that robot's first table differs in a
    assert seed_for_seed(robots_a, pd.concat([q_a, early]), robots_b, q_b).robots == 6


def test_a_robot_listed_twice_or_a_stayer_without_a_circuit_is_not_matched():
    """Robot 1 twice in b's robots: 0, 2 and 3 matched, all three the same kind; robot 2 twice at
    its first snapshot: 0, 1 and 3 are matched. A stayer whose circuit is empty (robot 3 in both)
    is no stayer on a circuit: not matched, though both runs read it alike."""
    q = q_table(Q)
    twice = pd.concat([robots_table(KINDS_B), robots_table(KINDS_B).iloc[[1]]])
    assert (seed_for_seed(robots_table(KINDS_A), q, twice, q).robots,
            seed_for_seed(robots_table(KINDS_A), q, twice, q).same) == (3, 3)
    matched = seed_for_seed(robots_table(KINDS_A), q, robots_table(KINDS_A), pd.concat([q, q.iloc[[2]]]))
    assert (matched.robots, matched.same) == (3, 3)
    blank = robots_table(KINDS_A).astype({"circuit": float})
    blank.loc[3, ["kind", "circuit"]] = ["stayer", float("nan")]
    matched = seed_for_seed(blank, q, blank, q)
    assert (matched.robots, matched.same) == (3, 3)
    one = robots_table(KINDS_A).astype({"circuit": float})  # circuit 1 written 1.0: still circuit 1
    assert seed_for_seed(one, q, robots_table(KINDS_A), q).same == 4


def test_runs_from_other_tables_are_not_set_side_by_side():
    assert seed_for_seed(robots_table(KINDS_A), q_table(Q), robots_table(KINDS_A), q_table([0.0] * 4)) is None


def _run(folder: Path, kinds: list[tuple[str, int]], tables: list[float] = Q) -> Path:
    folder.mkdir(parents=True)
    robots_table(kinds).to_csv(folder / "robots.csv", index=False)
    q_table(tables).to_csv(folder / "q_values.csv", index=False)
    return folder


def test_the_cell_says_what_it_found_and_refuses_a_table_without_its_columns(tmp_path):
    a, b = _run(tmp_path / "a", KINDS_A), _run(tmp_path / "b", KINDS_B)
    assert seed_for_seed_cell(a, b) == "3 of 4 (3)"  # one trial: each robot's chance is whether it is the same
    assert seed_for_seed_cell(a, _run(tmp_path / "c", KINDS_B, [0.0] * 4)) == "none matched"
    assert seed_for_seed_cell(a, None) == "" and seed_for_seed_cell(a, tmp_path / "none") == ""
    q_table(Q).drop(columns="q_1_1").to_csv(b / "q_values.csv", index=False)
    with pytest.raises(TavcError, match=r"b/q_values.csv: cannot be read \(no column 'q_1_1'\)"):
        seed_for_seed_cell(a, b)


def _horizon(factor: float, **runs: tuple[Path, float]) -> SimpleNamespace:
    """A horizon as the report reads one: its factor, and each experiment's run and time factor."""
    return SimpleNamespace(factor=factor, experiments={e: d for e, (d, _) in runs.items()},
                           read={e: (SimpleNamespace(scale=SimpleNamespace(time_factor=f)), None)
                                 for e, (_, f) in runs.items()})


def test_the_reports_table_sets_each_run_beside_todays_at_its_own_time_factor(tmp_path):
    """A reading's run beside today's world's run of the same experiment at the run's own time
    factor: initial_distribution at 1x in a reading's folder whose other run is at 40x is set
    beside today's 1x run; heterogeneous at 40x has no run of today's at 40x, so its cell is
    empty; a reading with no run to set beside has no row."""
    today = _horizon(1.0, initial_distribution=(_run(tmp_path / "a", KINDS_A), 1.0),
                     heterogeneous=(_run(tmp_path / "h", KINDS_A), 1.0))
    reading = _horizon(40.0, initial_distribution=(_run(tmp_path / "b", KINDS_B), 1.0),
                       heterogeneous=(_run(tmp_path / "g", KINDS_A), 40.0))
    alone = _horizon(40.0, heterogeneous=(tmp_path / "g", 40.0))
    lines = seed_for_seed_lines([("today's world", today)], [("readings/range-left-two_circuits_parallel", reading),
                                                              ("converged/readings/x", alone)])
    assert lines[-3:] == [
        "| world (horizon, runs) | initial_distribution | heterogeneous |", "|---|---|---|",
        "| arrival=range passing=left arena=two_circuits_parallel (40x, `readings/range-left-two_circuits_parallel`) "
        "| 3 of 4 (3) |  |"]
    assert seed_for_seed_lines([("today's world", today)], [("converged/readings/x", alone)]) == []
