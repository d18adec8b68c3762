"""The tasks the surrogate draws: measured in the physical simulator, by the group's make-up.

A make-up says, for each group of the team (``all``, or ``fast`` and ``slow``), how many of
its robots stay on circuit 0, how many stay on circuit 1 and how many alternate: (s0, s1, a).
Every make-up of every team an experiment can have (its team, and the teams left after its
breakdowns) runs with the static `alternate` controller, which holds each robot to its role:
after a warm-up, every task completed in the measurement window is kept whole: its time, the
time to the source, and where its time went. A learner's task is then drawn from the tasks of
the same make-up, the same group, the same kind (stay or switch) and the same circuit.

`stayers` calibration (the vacancy-chain model's view) draws every task from the make-ups
without alternators, by the robots on each circuit, as if every task stayed.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Sequence
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np
import pandas as pd

from tavc_cli.errors import TavcError
from tavc_cli.experiments.build import base_spec
from tavc_cli.experiments.records import TrialRecord
from tavc_cli.experiments.spec import TrialSpec
from tavc_cli.learning.parameters import AlternateSettings
from tavc_cli.learning.policies import AlternatePolicy
from tavc_cli.settings import TavcConfig
from tavc_cli.vocabulary import ACTIVITIES, SOURCE

SURROGATE_CODE = 11  # enters the seeds of the measuring trials (the model's are 10)
STAY, SWITCH = "stay", "switch"
MAKEUPS = ("makeup", "stayers")  # `surrogate.calibration`
COLUMNS = ("team", "makeup", "group", "kind", "circuit", "task_time_s", "source_s", *(f"{a}_s" for a in ACTIVITIES))
DRAWN = ("task_time_s", "source_s", *(f"{a}_s" for a in ACTIVITIES))  # what a draw gives, in this order

Makeup = tuple[tuple[int, int, int], ...]  # per group: robots staying on circuit 0, on circuit 1, alternating


@dataclass(frozen=True)
class Team:
    """A team by its groups, in the order they first appear among the members: each group's
    name, size and speed (one speed a group)."""

    groups: tuple[tuple[str, int, float], ...]

    @classmethod
    def of(cls, groups: Sequence[str], speeds: Sequence[float]) -> Team:
        """The team of members in `groups`, moving at `speeds`; a group's members must share one
        speed."""
        out: dict[str, list] = {}
        for g, v in zip(groups, speeds, strict=True):
            if g in out and out[g][1] != float(v):
                raise TavcError(f"team.members: the surrogate needs one speed per group; group {g!r} has "
                                f"{out[g][1]:g} and {float(v):g} m/s")
            out.setdefault(g, [0, float(v)])[0] += 1
        return cls(tuple((g, n, v) for g, (n, v) in out.items()))

    @property
    def name(self) -> str:
        """The team as its tables name it: ``group:size@speed`` for each group."""
        return ",".join(f"{g}:{n}@{v:g}" for g, n, v in self.groups)

    @property
    def size(self) -> int:
        """How many robots the team has."""
        return sum(n for _, n, _ in self.groups)

    def without(self, group: str) -> Team:
        """The team with one robot of `group` fewer (a group left empty goes)."""
        return Team(tuple((g, n - (g == group), v) for g, n, v in self.groups if n - (g == group) > 0))


def makeups(team: Team) -> list[Makeup]:
    """Every make-up of the team: per group, every (s0, s1, a) summing to its size."""
    per_group = [[(s0, s1, n - s0 - s1) for s0 in range(n + 1) for s1 in range(n + 1 - s0)] for _, n, _ in team.groups]
    return [tuple(m) for m in itertools.product(*per_group)]


def makeup_name(team: Team, makeup: Makeup) -> str:
    """A make-up as its tables name it: ``group:s0-s1-a`` for each group."""
    return " ".join(f"{g}:{s0}-{s1}-{a}" for (g, _, _), (s0, s1, a) in zip(team.groups, makeup, strict=True))


def teams_needed(team: Team, n_breakdowns: int) -> list[Team]:
    """The team and every team its breakdowns can leave (any robot may be the one that fails)."""
    seen, frontier = {team.name: team}, [team]
    for _ in range(n_breakdowns):
        frontier = [t.without(g) for t in frontier for g, _, _ in t.groups if t.size > 1]
        for t in frontier:
            seen.setdefault(t.name, t)
    return list(seen.values())


def roles_of(team: Team, makeup: Makeup) -> tuple[list[str], list[float], list[int]]:
    """Members (groups, speeds) and each one's role (a circuit, or -1 to alternate) in a make-up."""
    groups, speeds, roles = [], [], []
    for (g, n, v), (s0, s1, a) in zip(team.groups, makeup, strict=True):
        groups += [g] * n
        speeds += [v] * n
        roles += [0] * s0 + [1] * s1 + [AlternatePolicy.ALTERNATE] * a
    return groups, speeds, roles


def measurement(cfg: TavcConfig) -> tuple[int, float, float]:
    """Trials per make-up, warm-up and measurement window: `surrogate.*`, the trials capped by
    the scale, the times shortened by a scale below the chapter's (never lengthened)."""
    s, scale = cfg.surrogate, cfg.scale
    trials = int(s.trials_per_makeup)
    if scale.trials:
        trials = max(2, min(trials, int(scale.trials)))
    factor = min(1.0, float(scale.time_factor))
    return trials, float(s.warmup_s) * factor, float(s.measure_s) * factor


def measurement_specs(cfg: TavcConfig, teams: Sequence[Team]) -> dict[tuple[str, Makeup], list[TrialSpec]]:
    """The static trials that measure every make-up of every team: the experiment's world and
    robot, no events, values 1 (static robots do not learn)."""
    trials, warmup_s, measure_s = measurement(cfg)
    base = base_spec(cfg)
    k = len(cfg.arena.circuits)
    out = {}
    for t_index, team in enumerate(teams):
        for m_index, makeup in enumerate(makeups(team)):
            groups, speeds, roles = roles_of(team, makeup)
            label = "makeup_" + makeup_name(team, makeup).replace(" ", "_").replace(":", "-") + f"_n{team.size}"
            if len(team.groups) > 1:
                label += f"_t{t_index}"
            out[(team.name, makeup)] = [
                replace(base, speeds_mps=tuple(speeds), groups=tuple(groups), values=(1.0,) * k,
                        score_values=(1.0,) * k, policy=AlternateSettings(roles=roles),
                        controller=label, trial=j,
                        seed=(int(cfg.seed), SURROGATE_CODE, team.size, t_index, m_index, j),
                        duration_s=warmup_s + measure_s, warmup_s=0.0, start_s=0.0, deliveries=None, breakdowns=(),
                        value_changes=(), q_snapshot_every_s=0.0, pose_every_s=0.0)
                for j in range(trials)
            ]
    return out


def tasks_of(record: TrialRecord, team: Team, makeup: Makeup, roles: Sequence[int], warmup_s: float,
             measure_s: float) -> pd.DataFrame:
    """The tasks a measuring trial completed within its window, whole: one row each."""
    d, arr = record.table("deliveries"), record.table("arrivals")
    keep = (d["t_s"] >= warmup_s) & (d["t_s"] < warmup_s + measure_s)
    robots = d["robot"][keep]
    ends, times = d["t_s"][keep], d["task_time_s"][keep]
    starts = ends - times
    source_s = np.full(len(ends), math.nan)
    at_source = arr["kind"] == SOURCE
    for i in np.unique(robots):
        mine = robots == i
        arrived = np.sort(arr["t_s"][at_source & (arr["robot"] == i)])
        # the task's source arrival: the first after its start (a task begins at the sink it left)
        k = np.searchsorted(arrived, starts[mine] + 1e-9)
        ok = k < len(arrived)
        found = np.full(mine.sum(), math.nan)
        found[ok] = arrived[k[ok]] - starts[mine][ok]
        source_s[mine] = found
    groups = record.meta["groups"]
    frame = pd.DataFrame({
        "team": team.name, "makeup": makeup_name(team, makeup),
        "group": [groups[i] for i in robots],
        "kind": [SWITCH if roles[i] == AlternatePolicy.ALTERNATE else STAY for i in robots],
        "circuit": d["circuit"][keep], "task_time_s": times, "source_s": np.minimum(source_s, times),
        **{f"{a}_s": d[f"{a}_s"][keep] for a in ACTIVITIES},
    })
    return frame[list(COLUMNS)]


def parse_makeup(name: str) -> tuple[tuple[str, tuple[int, int, int]], ...]:
    """``all:2-1-3 ...`` back into ((group, (s0, s1, a)), ...)."""
    out = []
    for part in name.split():
        g, counts = part.rsplit(":", 1)
        out.append((g, tuple(int(x) for x in counts.split("-"))))
    return tuple(out)


class TaskTimes:
    """The measured tasks, by (team, make-up, group, kind, circuit), to draw from."""

    def __init__(self, frame: pd.DataFrame) -> None:
        """The tasks of `frame` (`COLUMNS`), grouped by cell."""
        missing = [c for c in COLUMNS if c not in frame.columns]
        if missing:
            raise TavcError(f"task_times.csv: no column {missing[0]!r}; measure again (tavc surrogate)")
        self.frame = frame
        self.borrowed: set[tuple] = set()  # cells drawn from a neighbouring make-up (`nearest`)
        self.cells: dict[tuple, np.ndarray] = {}
        for key, rows in frame.groupby(["team", "makeup", "group", "kind", "circuit"], sort=False):
            self.cells[(key[0], key[1], key[2], key[3], int(key[4]))] = rows[list(DRAWN)].to_numpy(dtype=np.float64)

    @classmethod
    def read(cls, path: Path) -> TaskTimes:
        """The tasks measured in `path`; one line naming it if it cannot be read."""
        try:
            return cls(pd.read_csv(path, dtype={"team": str, "makeup": str, "group": str, "kind": str}))
        except (OSError, ValueError, pd.errors.ParserError) as error:
            raise TavcError(f"{path}: cannot be read as measured task times ({error}); measure again "
                            "(tavc surrogate)") from None

    def draw(self, team: str, makeup: str, group: str, kind: str, circuit: int,
             rng: np.random.Generator) -> np.ndarray:
        """One measured task of that cell, drawn uniformly (every column of `DRAWN`). A cell in
        which the measurement completed no task draws from the nearest make-up that has one
        (`nearest`), and is counted in `borrowed`."""
        key = (team, makeup, group, kind, circuit)
        cell = self.cells.get(key)
        if cell is None:
            cell = self.nearest(key)
        return cell[rng.integers(len(cell))]

    def nearest(self, key: tuple) -> np.ndarray:
        """The cell of the same team, group, kind and circuit whose make-up is fewest robots'
        roles away from `key`'s (the first measured of equals); remembered for `key`."""
        team, makeup, group, kind, circuit = key
        want = dict(parse_makeup(makeup))
        best, best_d = None, math.inf
        for other, cell in self.cells.items():
            if other[0] != team or other[2:] != (group, kind, circuit) or not len(cell):
                continue
            have = dict(parse_makeup(other[1]))
            d = sum(abs(a - b) for g in want for a, b in zip(want[g], have.get(g, (0, 0, 0)), strict=True))
            if d < best_d:
                best, best_d = cell, d
        if best is None:
            raise TavcError(f"surrogate: no measured {kind} task on circuit {circuit} for a robot of group {group!r} "
                            f"in team {team}; measure the team's make-ups (tavc surrogate measures what an "
                            "experiment needs) or lengthen surrogate.measure_s")
        self.cells[key] = best
        self.borrowed.add(key)
        return best
