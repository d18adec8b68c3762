"""Switching tasks measured the way a learner that stays makes them (`surrogate.switches=explorers`).

The surrogate's tasks come from static robots held to their roles (`surrogate.tasks`): a
switching task from a robot that alternates on every task. Such a robot keeps step with the
robots it joins; a learner that stays switches only when it explores, at a moment of its own.
So here every allocation of stayers (per group, s0 on circuit 0 and s1 on circuit 1, no
alternator) also runs with robots that keep to their home circuit and choose as an
epsilon-greedy learner whose greedy choice is always home (`ExplorerPolicy`): with probability
epsilon a circuit drawn uniformly, else home; a robot that went away comes back the same way.
Each task is tabulated by the group's make-up at its choice, as the surrogate names it when it
draws (robots whose task stays on circuit 0, on circuit 1, and those whose task switches, the
chooser counted): an excursion and its return each make a make-up with one switcher where no
other robot is away.

In every make-up with exactly one switcher, each cell (group, stay or switch, circuit) that the
explorers filled with at least `surrogate.explore_min_tasks` tasks is drawn from theirs instead
of from the alternators'; every other cell, and every other make-up, keeps the alternators'.

The explorers run through the interface of a learner from outside tavc (a module target,
`EXPLORER_TARGET`), so their trials are keyed by the digest of all of tavc's Python files
(`learning.plugins.target_digest`): after an edit anywhere, a table measured again runs them
again. The table itself is measured again when this module's code changes (`explorers_code`).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import replace
from pathlib import Path

import numpy as np
import pandas as pd

from tavc_cli import meaning_digest
from tavc_cli.analysis.tasks_seen import delivered_choices
from tavc_cli.errors import TavcError
from tavc_cli.experiments.records import TrialRecord
from tavc_cli.experiments.spec import TrialSpec
from tavc_cli.learning.parameters import PluginSettings
from tavc_cli.settings import TavcConfig
from tavc_cli.settings_studies import EXPLORERS
from tavc_cli.surrogate.tasks import (
    COLUMNS,
    STAY,
    SWITCH,
    Makeup,
    Team,
    makeup_name,
    makeups,
    measurement_specs,
    parse_makeup,
    tasks_of,
)

EXPLORER_CODE = 12  # enters the seeds of the explorers' trials (the alternators' are 11)
EXPLORER_TARGET = "tavc_cli.surrogate.explorers.ExplorerPolicy"
EXPLORER_LABEL = "explorers"


class ExplorerPolicy:
    """Robots that keep to a home circuit each and choose as an epsilon-greedy learner whose
    greedy choice is always home: with probability `epsilon` a circuit drawn uniformly (home
    included), else home. They learn nothing."""

    def __init__(self, n_robots: int, n_circuits: int, rng: np.random.Generator, homes: Sequence[int],
                 epsilon: float) -> None:
        """Robot i's home is `homes[i]`; `rng` is the trial's policy stream."""
        if len(homes) != n_robots:
            raise ValueError(f"{len(homes)} homes for {n_robots} robots")
        self.homes = [int(h) for h in homes]
        self.n_circuits, self.rng, self.epsilon = n_circuits, rng, float(epsilon)
        self.n_states = n_circuits

    def choose(self, robot: int, state: int) -> int:
        """Home, or with probability epsilon a circuit drawn uniformly."""
        if self.rng.random() < self.epsilon:
            return int(self.rng.integers(self.n_circuits))
        return self.homes[robot]

    def learn(self, robot: int, state: int, action: int, reward: float, next_state: int) -> None:
        """Nothing: the explorers learn nothing."""


def explore_epsilon(cfg: TavcConfig) -> float:
    """The explorers' epsilon: `surrogate.explore_epsilon`, else the learner's own epsilon; one
    line where neither is given (a learner that does not explore by an epsilon)."""
    given = cfg.surrogate.explore_epsilon
    if given is not None:
        return float(given)
    own = getattr(cfg.learner, "epsilon", None)
    if own is None:
        raise TavcError(f"surrogate.explore_epsilon: learner {cfg.learner.name} explores by no epsilon; give the "
                        "explorers' rate (surrogate.explore_epsilon=...) or use surrogate.switches=alternators")
    return float(own)


def explore_trials(cfg: TavcConfig) -> int:
    """Trials per allocation of stayers: `surrogate.explore_trials`, capped by the scale as the
    alternators' are."""
    trials = int(cfg.surrogate.explore_trials)
    return max(2, min(trials, int(cfg.scale.trials))) if cfg.scale.trials else trials


def stayers_makeups(team: Team) -> list[Makeup]:
    """The team's make-ups without an alternator: its allocations of stayers."""
    return [m for m in makeups(team) if all(a == 0 for _, _, a in m)]


def explorer_specs(cfg: TavcConfig, teams: Sequence[Team]) -> dict[tuple[str, Makeup], list[TrialSpec]]:
    """The explorers' static trials: for every allocation of stayers of every team, the
    alternators' measuring trial of that make-up (`tasks.measurement_specs`: the measurement's
    world, window and values of 1) with its robots homed there (`ExplorerPolicy`), its own label
    and seeds, `surrogate.explore_trials` of them."""
    trials, epsilon = explore_trials(cfg), explore_epsilon(cfg)
    by_name = {team.name: team for team in teams}
    out = {}
    for (name, makeup), specs in measurement_specs(cfg, teams).items():
        if any(a for _, _, a in makeup):
            continue
        first = specs[0]
        policy = PluginSettings(name=EXPLORER_LABEL, target=EXPLORER_TARGET,
                                params={"homes": list(first.policy.roles), "epsilon": epsilon})
        seed = (int(cfg.seed), EXPLORER_CODE, first.seed[2], first.seed[3],
                stayers_makeups(by_name[name]).index(makeup))
        out[(name, makeup)] = [replace(first, policy=policy, controller="explore_" + first.controller.removeprefix(
            "makeup_"), trial=j, seed=(*seed, j)) for j in range(trials)]
    return out


def choice_makeups(record: TrialRecord, team: Team) -> tuple[np.ndarray, np.ndarray]:
    """For every delivery of `record` (in its table's order), the make-up at the choice that began
    its task and its kind, as the surrogate names them when it draws (`engine.SurrogateTrial`): a
    robot's k-th delivery ends the task of its k-th choice; the make-up counts, by group, the
    robots whose last choice stays on circuit 0, on circuit 1, and those whose last choice
    switched. The choices of the trial's start count together (every robot chooses, then the
    tasks are drawn); every later one in turn, by time and then robot (robots that deliver at one
    tick choose, and draw, in their index order)."""
    c, d = record.table("choices"), record.table("deliveries")
    groups = list(record.meta["groups"])
    n = len(groups)
    index = {g: k for k, (g, _, _) in enumerate(team.groups)}
    order = np.lexsort((c["robot"], c["t_s"]))
    current = np.full(n, -1)
    switching = np.zeros(n, dtype=bool)
    named = np.empty(len(c["t_s"]), dtype=object)
    start = int(np.searchsorted(c["t_s"][order], c["t_s"][order][0], side="right")) if len(order) else 0
    for at in [order[:start], *np.split(order[start:], np.arange(1, len(order) - start))] if len(order) else []:
        robots = c["robot"][at]
        current[robots] = c["circuit"][at]
        switching[robots] = c["circuit"][at] != c["state"][at]
        counts = [[0, 0, 0] for _ in team.groups]
        for i in np.flatnonzero(current >= 0):
            counts[index[groups[i]]][2 if switching[i] else int(current[i])] += 1
        named[at] = makeup_name(team, tuple(tuple(x) for x in counts))
    choice = delivered_choices(c, d, n)
    if (choice < 0).any():
        raise ValueError(f"{int((choice < 0).sum())} deliveries after every choice of their robot")
    makeup = named[choice]
    kind = np.where(c["circuit"][choice] != c["state"][choice], SWITCH, STAY).astype(object)
    return makeup, kind


def explorer_tasks(record: TrialRecord, team: Team, warmup_s: float, measure_s: float) -> pd.DataFrame:
    """The tasks an explorers' trial completed within its window, whole (`COLUMNS`), each by the
    make-up at its choice and its kind (`choice_makeups`)."""
    d = record.table("deliveries")
    keep = (d["t_s"] >= warmup_s) & (d["t_s"] < warmup_s + measure_s)
    makeup, kind = choice_makeups(record, team)
    frame = tasks_of(record, team, tuple((0, 0, 0) for _ in team.groups), [0] * len(record.meta["groups"]),
                     warmup_s, measure_s)
    frame["makeup"], frame["kind"] = makeup[keep], kind[keep]
    return frame


def one_switcher(name: str) -> bool:
    """Whether a make-up named `name` has exactly one robot whose task switches."""
    return sum(counts[2] for _, counts in parse_makeup(name)) == 1


def with_explorers(alternating: pd.DataFrame, exploring: pd.DataFrame, min_tasks: int) -> pd.DataFrame:
    """The alternators' task table with every cell of a one-switcher make-up that the explorers
    filled with at least `min_tasks` tasks taken from theirs (`COLUMNS`, the alternators' rows
    first)."""
    cell = ["team", "makeup", "group", "kind", "circuit"]
    explored = exploring[exploring["makeup"].map(one_switcher).astype(bool)]
    sizes = explored.groupby(cell).size()
    taken = sizes[sizes >= min_tasks].index
    if not len(taken):
        return alternating[list(COLUMNS)].reset_index(drop=True)
    keep = ~pd.MultiIndex.from_frame(alternating[cell]).isin(taken)
    chosen = pd.MultiIndex.from_frame(explored[cell]).isin(taken)
    return pd.concat([alternating[keep], explored[chosen]], ignore_index=True)[list(COLUMNS)]


def explorer_record(cfg: TavcConfig) -> dict:
    """The settings of the explorers' measurement `task_times.json` records (with
    `surrogate.switches=explorers` only: a table of the alternators alone records nothing of them)."""
    return {"switches": EXPLORERS, "explore_trials": explore_trials(cfg), "explore_epsilon": explore_epsilon(cfg),
            "explore_min_tasks": int(cfg.surrogate.explore_min_tasks)}


def explorers_code() -> str:
    """Digest of this module's code (`meaning_digest`), which tabulates and picks the explorers'
    tasks: recorded beside an explorers' table (`explorers_code`), which is measured again once
    it changes."""
    return meaning_digest(Path(__file__).resolve().parent.parent, ("surrogate/explorers.py",))
