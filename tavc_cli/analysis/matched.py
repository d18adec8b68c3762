"""Seed for seed: what the learners of two runs did from the same initial tables.

Trial j of a controller draws its random initial Q-tables and its robots' first circuits from
its seed alone (the run's root seed, the controller's seed code, j), so the same experiment run
in two worlds, or at two horizons, starts trial j from the same tables in both. Set side by
side robot by robot, their kinds at the end (`analysis.robots`: a stayer on one circuit, an
alternator, mixed, idle) tell how much of what the learners did the world decided and how much
their initial tables did: many more robots of the same kind in both runs than chance would give
means the tables decided; about as many, the world did.

Chance is worked out robot by robot: for each controller's robot i, its kinds over the matched
trials in run a and in run b, drawn independently (the sum over kinds of the product of their
frequencies), summed over the robots. A robot with a part of its own in every trial (the one that
breaks down, a fast or a slow one) is thus expected to keep the kind its part gives it, and only
what the trials leave open counts as the tables' doing.

Which robots are matched is read from the runs' tables, not assumed: only robots whose first Q
snapshot (each robot's own earliest) is the same in both runs count; a robot listed twice at that
time, or twice among the kinds, and a stayer whose circuit is not a number, are not matched; runs
that share no robot are not set side by side.
"""

from __future__ import annotations

from dataclasses import dataclass

import pandas as pd

KEY = ["controller", "trial", "robot"]
Q_COLUMNS = ["q_0_0", "q_0_1", "q_1_0", "q_1_1"]
ROBOT_COLUMNS = [*KEY, "kind", "circuit"]
TABLE_COLUMNS = [*KEY, "t_s", *Q_COLUMNS]


@dataclass(frozen=True)
class Matched:
    """Robots matched seed for seed, how many are of the same kind in both runs, and how many
    would be by chance (see the module's docstring)."""

    robots: int
    same: int
    chance: float


def kinds(robots: pd.DataFrame) -> pd.Series:
    """Each robot's kind at the end of its run (`robots.csv`), a stayer's with its circuit
    ("stayer 0"), indexed by controller, trial and robot; a robot listed twice, and a stayer
    whose circuit is not a number, are left out."""
    circuit = pd.to_numeric(robots["circuit"], errors="coerce")
    stayer = robots["kind"] == "stayer"
    words = robots["kind"].astype(str).where(~stayer, circuit.map(lambda c: f"stayer {c:g}"))
    out = pd.Series(words.to_numpy(), index=pd.MultiIndex.from_frame(robots[KEY]), name="kind")
    keep = ~out.index.duplicated(keep=False) & ~(stayer & circuit.isna()).to_numpy()
    return out[keep]


def first_rows(q_values: pd.DataFrame) -> pd.DataFrame:
    """The rows of `q_values.csv` at each robot's own first snapshot (its earliest time that is a
    number): all `first_tables` needs of the table."""
    q = q_values.assign(t_s=pd.to_numeric(q_values["t_s"], errors="coerce")).dropna(subset=["t_s"])
    return q[q["t_s"] == q.groupby(KEY)["t_s"].transform("min")]


def first_tables(q_values: pd.DataFrame) -> pd.DataFrame:
    """Each robot's Q-table at its own first snapshot (`first_rows`), indexed by controller,
    trial and robot; a robot with two rows at that time, or none with a time that is a number,
    is left out."""
    first = first_rows(q_values).set_index(KEY)[Q_COLUMNS]
    return first[~first.index.duplicated(keep=False)]


def seed_for_seed(robots_a: pd.DataFrame, q_a: pd.DataFrame, robots_b: pd.DataFrame,
                  q_b: pd.DataFrame) -> Matched | None:
    """Runs a and b (their `robots.csv` and `q_values.csv`, with `ROBOT_COLUMNS` and
    `TABLE_COLUMNS`) robot by robot: of the robots both ran from the same first Q-table, how
    many end as the same kind, against the number chance gives (the module's docstring). None
    where no robot was matched."""
    return matched_robots(kinds(robots_a), first_tables(q_a), kinds(robots_b), first_tables(q_b))


def matched_robots(kinds_a: pd.Series, tables_a: pd.DataFrame, kinds_b: pd.Series,
                   tables_b: pd.DataFrame) -> Matched | None:
    """`seed_for_seed` on each run's robots' kinds (`kinds`) and first Q-tables (`first_tables`),
    for a caller that sets one run beside several others and reads each once."""
    common = tables_a.index.intersection(tables_b.index)
    same_table = (tables_a.loc[common].to_numpy() == tables_b.loc[common].to_numpy()).all(axis=1)
    matched = common[same_table].intersection(kinds_a.index).intersection(kinds_b.index)
    if len(matched) == 0:
        return None
    both = pd.DataFrame({"a": kinds_a.loc[matched].to_numpy(), "b": kinds_b.loc[matched].to_numpy(),
                         "controller": matched.get_level_values("controller"),
                         "robot": matched.get_level_values("robot")})
    # robot by robot: n * sum over kinds of (count in a / n) (count in b / n) = sum of the products of
    # the counts over n, the robot's matched trials
    robot = ["controller", "robot"]
    n = both.groupby(robot).size()
    in_a = both.groupby([*robot, "a"]).size().rename_axis([*robot, "kind"])
    in_b = both.groupby([*robot, "b"]).size().rename_axis([*robot, "kind"])
    products = (in_a * in_b).dropna().groupby(level=robot).sum()
    chance = float((products / n.loc[products.index]).sum())
    return Matched(robots=len(matched), same=int((both["a"] == both["b"]).sum()), chance=chance)
