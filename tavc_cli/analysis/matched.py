"""Seed for seed: what the learners of two runs did from the same initial tables.

Trial j of a controller draws its random initial Q-tables and its robots' first circuits from
its seed alone (the run's root seed, the controller's seed code, j), so the same experiment run
in two worlds, or at two horizons, starts trial j from the same tables in both. Set side by
side robot by robot, their kinds at the end (`analysis.robots`: a stayer on one circuit, an
alternator, mixed, idle) tell how much of what the learners did the world decided and how much
their initial tables did: many more robots of the same kind in both runs than two independent
draws of each run's own mix of kinds would give means the tables decided; about as many, the
world did. Which robots are matched is read from the runs' tables, not assumed: only robots
whose first Q snapshot is the same in both runs count (a robot listed twice in either run's
tables is not matched), and runs that share none are not set side by side.
"""

from __future__ import annotations

from dataclasses import dataclass

import pandas as pd

KEY = ["controller", "trial", "robot"]
Q_COLUMNS = ["q_0_0", "q_0_1", "q_1_0", "q_1_1"]


@dataclass(frozen=True)
class Matched:
    """Robots matched seed for seed, how many are of the same kind in both runs, and how many
    would be if each run's kinds were drawn independently with that run's own frequencies."""

    robots: int
    same: int
    chance: float


def kinds(robots: pd.DataFrame) -> pd.Series:
    """Each robot's kind at the end of its run (`robots.csv`), a stayer's with its circuit
    ("stayer 0"), indexed by controller, trial and robot; a robot listed twice is left out."""
    circuit = pd.to_numeric(robots["circuit"], errors="coerce").map(lambda c: f"stayer {c:g}")
    words = robots["kind"].astype(str).where(robots["kind"] != "stayer", circuit)
    out = pd.Series(words.to_numpy(), index=pd.MultiIndex.from_frame(robots[KEY]), name="kind")
    return out[~out.index.duplicated(keep=False)]


def first_tables(q_values: pd.DataFrame) -> pd.DataFrame:
    """Each robot's Q-table at its run's first snapshot (`q_values.csv`), indexed by controller,
    trial and robot; a robot listed twice there is left out."""
    first = q_values[q_values["t_s"] == q_values["t_s"].min()].set_index(KEY)[Q_COLUMNS]
    return first[~first.index.duplicated(keep=False)]


def seed_for_seed(robots_a: pd.DataFrame, q_a: pd.DataFrame, robots_b: pd.DataFrame,
                  q_b: pd.DataFrame) -> Matched | None:
    """Runs a and b (their `robots.csv` and `q_values.csv`) robot by robot: of the robots both
    ran from the same first Q-table, how many end as the same kind, against the number
    expected by chance (per controller, its matched robots times the sum over kinds of the two
    runs' frequencies' product). None where no robot was matched."""
    tables_a, tables_b = first_tables(q_a), first_tables(q_b)
    common = tables_a.index.intersection(tables_b.index)
    same_table = (tables_a.loc[common].to_numpy() == tables_b.loc[common].to_numpy()).all(axis=1)
    kinds_a, kinds_b = kinds(robots_a), kinds(robots_b)
    matched = common[same_table].intersection(kinds_a.index).intersection(kinds_b.index)
    if len(matched) == 0:
        return None
    a, b = kinds_a.loc[matched], kinds_b.loc[matched]
    chance = 0.0
    for controller in matched.get_level_values("controller").unique():
        pa = a.xs(controller, level="controller").value_counts(normalize=True)
        pb = b.xs(controller, level="controller").value_counts(normalize=True)
        n = int((matched.get_level_values("controller") == controller).sum())
        chance += n * float(sum(pa[k] * pb[k] for k in pa.index.intersection(pb.index)))
    return Matched(robots=len(matched), same=int((a.to_numpy() == b.to_numpy()).sum()), chance=chance)
