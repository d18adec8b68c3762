"""Seed for seed (`analysis.matched`, the report's table of it): robots matched by their first
Q-tables, counted by their kinds at the end, beside what chance would give."""

from __future__ import annotations

from pathlib import Path
from types import SimpleNamespace

import pandas as pd

from tavc_cli.analysis.matched import seed_for_seed
from tavc_cli.report.counterfactuals import seed_for_seed_lines
from tests.helpers import KINDS_A as A
from tests.helpers import KINDS_B as B
from tests.helpers import q_table as _tables
from tests.helpers import robots_table as _robots


def test_the_same_kinds_and_the_chance_of_them_by_hand():
    """Same kind: robots 0, 2 and 3 (robot 1 is a stayer on another circuit) = 3 of 4. Chance:
    a's kinds are stayer 0 / stayer 1 / alternator at 1/2, 1/4, 1/4, b's at 1/4, 1/2, 1/4, so
    4 x (1/8 + 1/8 + 1/16) = 1.25."""
    q = _tables([0.1, -0.05, 0.02, 0.07])
    matched = seed_for_seed(_robots(A), q, _robots(B), q)
    assert (matched.robots, matched.same) == (4, 3)
    assert matched.chance == 1.25


def test_only_robots_from_the_same_first_table_are_matched():
    """Robot 3 starts from another table in b: the other three are matched (same: robots 0 and
    2); chance: a's kinds stayer 0 2/3, stayer 1 1/3, b's stayer 0 1/3, stayer 1 2/3, so
    3 x (2/9 + 2/9) = 4/3. A later snapshot that differs does not unmatch a robot; the random
    baseline, with no Q-table, is never matched."""
    q_a = pd.concat([_tables([0.1, -0.05, 0.02, 0.07]), _tables([0.5, 0.5, 0.5, 0.5], t_s=3600.0)])
    q_b = pd.concat([_tables([0.1, -0.05, 0.02, 0.03]), _tables([0.4, 0.4, 0.4, 0.4], t_s=3600.0)])
    robots_a = pd.concat([_robots(A), _robots(A, "random")])
    robots_b = pd.concat([_robots(B), _robots(A, "random")])
    matched = seed_for_seed(robots_a, q_a, robots_b, q_b)
    assert (matched.robots, matched.same) == (3, 2)
    assert abs(matched.chance - 4 / 3) < 1e-12


def test_runs_from_other_tables_are_not_set_side_by_side():
    assert seed_for_seed(_robots(A), _tables([0.1, 0.2, 0.3, 0.4]), _robots(A), _tables([0.0, 0.2, 0.3, 0.4])) \
        .robots == 3
    assert seed_for_seed(_robots(A), _tables([0.1, 0.2, 0.3, 0.4]), _robots(A), _tables([0.0, 0.0, 0.0, 0.0])) \
        is None


def test_a_robot_listed_twice_is_not_matched():
    """Robot 1 twice in b's robots (as another run's table might be): robots 0, 2 and 3 are
    matched, all three of the same kind; robot 2 twice in b's first tables: 0, 1 and 3 are."""
    q = _tables([0.1, -0.05, 0.02, 0.07])
    twice = pd.concat([_robots(B), _robots(B).iloc[[1]]])
    matched = seed_for_seed(_robots(A), q, twice, q)
    assert (matched.robots, matched.same) == (3, 3)
    matched = seed_for_seed(_robots(A), q, _robots(A), pd.concat([q, q.iloc[[2]]]))
    assert (matched.robots, matched.same) == (3, 3)


def test_a_stayers_circuit_is_part_of_its_kind_whatever_its_number_reads():
    """Circuit 1 read as 1.0 is circuit 1; an empty circuit (NaN) is no circuit: that stayer is
    of another kind than b's stayer on circuit 1."""
    a = _robots(A).astype({"circuit": float})
    a.loc[3, ["kind", "circuit"]] = ["stayer", float("nan")]
    matched = seed_for_seed(a, _tables([0.1, -0.05, 0.02, 0.07]), _robots(B), _tables([0.1, -0.05, 0.02, 0.07]))
    assert (matched.robots, matched.same) == (4, 2)


def _run(folder: Path, kinds: list[tuple[str, int]], tables: list[float]) -> Path:
    folder.mkdir(parents=True)
    _robots(kinds).to_csv(folder / "robots.csv", index=False)
    _tables(tables).to_csv(folder / "q_values.csv", index=False)
    return folder


def test_the_reports_table_has_a_row_per_reading_and_horizon_a_cell_per_experiment(tmp_path):
    """A reading's runs beside today's world's at the same horizon only (a reading at 40x with
    no run of today's at 40x has no row); a run without its robots' table leaves its cell
    empty."""
    q = [0.1, -0.05, 0.02, 0.07]
    today = SimpleNamespace(factor=1.0, experiments={"initial_distribution": _run(tmp_path / "a", A, q),
                                                     "heterogeneous": _run(tmp_path / "h", A, q)})
    reading = SimpleNamespace(factor=1.0, experiments={"initial_distribution": _run(tmp_path / "b", B, q),
                                                       "heterogeneous": tmp_path / "missing"})
    longer = SimpleNamespace(factor=40.0, experiments={"initial_distribution": _run(tmp_path / "c", B, q)})
    lines = seed_for_seed_lines([("today's world", today)],
                                [("readings/range-left-two_circuits_parallel", reading),
                                 ("converged/readings/range-left-two_circuits_parallel", longer)])
    assert lines[-3:] == [
        "| world (horizon, runs) | initial_distribution | heterogeneous |", "|---|---|---|",
        "| arrival=range passing=left arena=two_circuits_parallel (1x, `readings/range-left-two_circuits_parallel`) "
        "| 3 of 4 (1) |  |"]
    assert seed_for_seed_lines([("today's world", today)], [("converged/readings/x", longer)]) == []
