"""Group states over time and the share of time spent in each (Tables 1.2-1.6).

The state of the group at a moment counts, among the working robots, where each
robot's LAST target was. Two notations, both as in the chapter:

- `circuits`: robots per circuit, high-value circuit first (`3:3`, `3:2`); with
  more circuits, one number per circuit in order of value.
- `groups`: for a team made of groups (fast and slow robots), how many robots of
  each group, fastest group first, had their last target on the high-value
  circuit (`2:1` = two fast and one slow robot on the high circuit).

Which circuit is "high" follows the task values in force at that moment, so a
value change relabels the circuits. Times before every working robot has reached
a first target have no state and are left out.

All functions are pure: they read a `TrialRecord` and return numbers.
"""

from __future__ import annotations

import math
from bisect import bisect_right
from collections.abc import Iterable, Sequence
from functools import cache
from itertools import product

import numpy as np
import pandas as pd

from tavc_cli.analysis.series import bin_edges, over_trials
from tavc_cli.experiments.records import TrialRecord
from tavc_cli.notation import counts_of, high_of, join_counts
from tavc_cli.vocabulary import EventKind


def _events(rec: TrialRecord) -> list[tuple[float, int, object]]:
    """Time-ordered (t, kind, payload) of everything that changes the state: ordered by time,
    then kind, and within both as the record lists them (a stable sort)."""
    a = rec.table("arrivals")
    b = rec.table("breakdowns")
    times = a["t_s"].tolist() + b["t_s"].tolist() + [float(t) for t in rec.value_changes_t]
    kinds = ([EventKind.ARRIVAL] * len(a["t_s"]) + [EventKind.BREAKDOWN] * len(b["t_s"])
             + [EventKind.VALUE_CHANGE] * len(rec.value_changes_t))
    payloads = (list(zip(_ints(a["robot"]), _ints(a["circuit"]), strict=True)) + _ints(b["robot"])
                + [tuple(float(v) for v in values) for values in rec.value_changes])
    by_kind = np.argsort(np.array(kinds, dtype=np.int64), kind="stable")
    order = by_kind[np.argsort(np.array(times, dtype=np.float64)[by_kind], kind="stable")].tolist()
    return [(times[k], kinds[k], payloads[k]) for k in order]


def _ints(column: np.ndarray) -> list[int]:
    return np.asarray(column).astype(np.int64).tolist()


def group_order(groups: Sequence[str], speeds: Sequence[float]) -> list[str]:
    """Group names, fastest (by mean speed) first, ties by first appearance."""
    names = list(dict.fromkeys(groups))
    mean = {g: np.mean([s for s, gg in zip(speeds, groups, strict=True) if gg == g]) for g in names}
    return sorted(names, key=lambda g: (-mean[g], names.index(g)))


def state_label(last: np.ndarray, alive: np.ndarray, values: Sequence[float], scheme: str,
                groups: Sequence[str] = (), order: Sequence[str] = ()) -> str | None:
    """The state string for robots' last circuits, or None while one has none yet."""
    return _label([int(c) for c in last], [bool(a) for a in alive], _rank(values), scheme, groups, order)


def state_intervals(rec: TrialRecord, scheme: str = "circuits") -> list[tuple[float, float, str | None]]:
    """(start, end, state) pieces covering the record from its first to its last second
    (derived once per record and scheme: every table of a run reads them)."""
    key = ("state_intervals", scheme)
    if key not in rec.derived:
        rec.derived[key] = _state_intervals(rec, scheme)
    return rec.derived[key]


def _state_intervals(rec: TrialRecord, scheme: str) -> list[tuple[float, float, str | None]]:
    meta = rec.meta
    n = int(meta["n_robots"])
    groups = meta["groups"]
    order = group_order(groups, meta["speeds_mps"])
    by_group = scheme == "groups"
    counter = _StateCounter(n, _rank(meta["values"]), [order.index(g) for g in groups] if by_group else [0] * n,
                            len(order) if by_group else 1, by_group)
    t_prev, t_end = rec.start_s, rec.end_s
    state = None
    out = []
    for t, kind, payload in _events(rec):
        if t > t_prev:
            out.append((t_prev, min(t, t_end), state))
            t_prev = t
        if kind == EventKind.ARRIVAL:
            counter.arrive(*payload)
        elif kind == EventKind.BREAKDOWN:
            counter.break_down(payload)
        else:
            counter.rank_by(_rank(payload))
        state = counter.label()
    if t_end > t_prev:
        out.append((t_prev, t_end, state))
    return [(a, b, s) for a, b, s in out if b > a]


class _StateCounter:
    """The group's state kept up to date event by event: how many live robots of each group
    (one group for the `circuits` scheme) had their last target on each circuit, and how many
    live robots have none yet. `label` is `_label` of the same robots, from these counts."""

    def __init__(self, n: int, rank: list[int], group_of: list[int], n_groups: int, by_group: bool) -> None:
        self.last = [-1] * n
        self.alive = [True] * n
        self.group_of = group_of
        self.counts = [[0] * len(rank) for _ in range(n_groups)]
        self.n_live, self.unknown = n, n  # live robots; live robots without a last circuit
        self.rank, self.by_group = rank, by_group
        self.changed, self.current = True, None

    def arrive(self, robot: int, circuit: int) -> None:
        before = self.last[robot]
        self.last[robot] = circuit
        if not self.alive[robot] or before == circuit:
            return
        counts = self.counts[self.group_of[robot]]
        if before < 0:
            self.unknown -= 1
        else:
            counts[before] -= 1
        counts[circuit] += 1
        self.changed = True

    def break_down(self, robot: int) -> None:
        if not self.alive[robot]:
            return
        self.alive[robot] = False
        self.n_live -= 1
        if self.last[robot] < 0:
            self.unknown -= 1
        else:
            self.counts[self.group_of[robot]][self.last[robot]] -= 1
        self.changed = True

    def rank_by(self, rank: list[int]) -> None:
        """The circuits' ranking after a change of values."""
        self.rank, self.changed = rank, True

    def label(self) -> str | None:
        if self.changed:
            self.changed = False
            if not self.n_live or self.unknown:
                self.current = None
            elif self.by_group:
                self.current = ":".join(str(counts[self.rank[0]]) for counts in self.counts)
            else:
                self.current = ":".join(str(self.counts[0][c]) for c in self.rank)
        return self.current


def _rank(values: Sequence[float]) -> list[int]:
    """Circuits by value, most valuable first, ties in index order (as `split_label`)."""
    return [int(c) for c in np.argsort(-np.asarray(values, dtype=np.float64), kind="stable")]


def _label(last: list[int], alive: list[bool], rank: list[int], scheme: str, groups: Sequence[str],
           order: Sequence[str]) -> str | None:
    """`state_label` on plain lists, with the circuits' ranking given: the interval loop
    labels the state after every arrival."""
    live = [i for i, a in enumerate(alive) if a]
    if not live or any(last[i] < 0 for i in live):
        return None
    if scheme == "groups":
        high = rank[0]
        return ":".join(str(sum(1 for i in live if groups[i] == g and last[i] == high)) for g in order)
    counts = [0] * len(rank)
    for i in live:
        counts[last[i]] += 1
    return ":".join(str(counts[c]) for c in rank)


def time_shares(rec: TrialRecord, t_from: float, t_to: float, scheme: str = "circuits") -> dict[str, float]:
    """Percent of the defined time in [t_from, t_to] spent in each state."""
    share: dict[str, float] = {}
    for a, b, s in state_intervals(rec, scheme):
        lo, hi = max(a, t_from), min(b, t_to)
        if hi > lo and s is not None:
            share[s] = share.get(s, 0.0) + (hi - lo)
    total = sum(share.values())
    return {s: 100.0 * v / total for s, v in share.items()} if total > 0 else {}


def all_states(n_robots: int, n_circuits: int, scheme: str, group_sizes: Sequence[int] = ()) -> list[str]:
    """Every possible state, in the chapter's order (first number ascending)."""
    if scheme == "groups":
        return [join_counts(c) for c in product(*(range(g + 1) for g in group_sizes))]
    states = [c for c in product(range(n_robots + 1), repeat=n_circuits) if sum(c) == n_robots]
    return [join_counts(c) for c in sorted(states)]


def theory_pct(n_robots: int, n_circuits: int, scheme: str, group_sizes: Sequence[int] = ()) -> dict[str, float]:
    """Share of each state if every robot picks a circuit uniformly at random (eq. 1.5, 1.7).

    circuits: multinomial m! / (n_1! ... n_k!) / k^m; groups: the product over groups
    of C(g, f) p^f (1 - p)^(g - f) with p = 1/k, the chance of the high circuit.
    """
    out = {}
    if scheme == "groups":
        p = 1.0 / n_circuits
        for label in all_states(n_robots, n_circuits, scheme, group_sizes):
            counts = counts_of(label)
            prob = 1.0
            for g, f in zip(group_sizes, counts, strict=True):
                prob *= math.comb(g, f) * p**f * (1 - p) ** (g - f)
            out[label] = 100.0 * prob
        return out
    for label in all_states(n_robots, n_circuits, scheme):
        counts = counts_of(label)
        ways = math.factorial(n_robots)
        for c in counts:
            ways //= math.factorial(c)
        out[label] = 100.0 * ways / n_circuits**n_robots
    return out


def alive_at_end(rec: TrialRecord) -> np.ndarray:
    """Whether each robot of `rec` is still working at the end of its trial (not broken down)."""
    alive = np.ones(int(rec.meta["n_robots"]), dtype=bool)
    alive[rec.table("breakdowns")["robot"].astype(int)] = False
    return alive


def state_time_table(records: Iterable[TrialRecord], t_from: float, t_to: float, scheme: str = "circuits",
                     with_theory: bool = True) -> pd.DataFrame:
    """`state,controller,mean_pct,std_pct,n_trials` over trials, plus `theory` rows.

    Every possible state of the team that is working at the end appears, with 0 %
    where it never occurred. The std is the sample standard deviation over trials;
    a trial whose state is never defined in the window (a robot that never reached
    a target) is left out, and `n_trials` counts the trials used.
    """
    records = list(records)
    if not records:
        return pd.DataFrame(columns=["state", "controller", "mean_pct", "std_pct", "n_trials"])
    first = records[0]
    alive = alive_at_end(first)
    groups = [g for g, a in zip(first.meta["groups"], alive, strict=True) if a]
    order = group_order(first.meta["groups"], first.meta["speeds_mps"])
    sizes = [groups.count(g) for g in order]
    n_live, n_c = int(alive.sum()), int(first.meta["n_circuits"])
    states = all_states(n_live, n_c, scheme, sizes)
    by_ctrl: dict[str, list[dict[str, float]]] = {}
    for rec in records:
        shares = time_shares(rec, t_from, t_to, scheme)
        if shares:  # a trial with no defined state in the window has nothing to say
            by_ctrl.setdefault(rec.meta["controller"], []).append(shares)
    rows = []
    for ctrl, shares in by_ctrl.items():
        extra = sorted({s for sh in shares for s in sh} - set(states))
        for s in states + extra:
            x = np.array([sh.get(s, 0.0) for sh in shares])
            rows.append({"state": s, "controller": ctrl, "mean_pct": float(x.mean()),
                         "std_pct": float(x.std(ddof=1)) if len(x) > 1 else math.nan, "n_trials": len(x)})
    if with_theory:
        for s, v in theory_pct(n_live, n_c, scheme, sizes).items():
            rows.append({"state": s, "controller": "theory", "mean_pct": v, "std_pct": 0.0, "n_trials": 0})
    return pd.DataFrame(rows)


def _from_start(mean: np.ndarray, edges: np.ndarray, rec: TrialRecord) -> np.ndarray:
    """`mean` (n_bins, n_values) with NaN in the bins that begin before the record's start (a
    baseline that started late), as its performance has (`performance.value_rate_series`)."""
    return np.where((edges[:-1] >= rec.start_s)[:, None], mean, np.nan)


def _binned_mean(intervals, value, edges: np.ndarray, n_values: int = 1) -> np.ndarray:
    """(n_bins, n_values): the time-weighted mean of value(state, start) (a vector) over each bin
    of `edges`, from (start, end, state) intervals; NaN where no state was defined in a bin.

    Each interval's piece in each bin it overlaps is added in the intervals' order, bins
    ascending within one (`np.add.at` adds in index order), so the sums are those of a
    plain loop over intervals and bins."""
    n_bins = len(edges) - 1
    weighted, covered = np.zeros((n_bins, n_values)), np.zeros(n_bins)
    kept = [(a, b, s) for a, b, s in intervals if s is not None]
    if not kept or n_bins <= 0:
        return np.full((max(n_bins, 0), n_values), np.nan)
    a = np.array([iv[0] for iv in kept], dtype=float)
    b = np.array([iv[1] for iv in kept], dtype=float)
    v = np.array([value(s, start) for start, _, s in kept], dtype=float).reshape(len(kept), -1)
    first = np.maximum(np.searchsorted(edges, a, side="right") - 1, 0)
    last = np.minimum(np.searchsorted(edges, b, side="left"), n_bins)
    count = np.maximum(last - first, 0)
    which = np.repeat(np.arange(len(kept)), count)  # interval of each (interval, bin) piece
    k = first[which] + (np.arange(len(which)) - np.repeat(np.cumsum(count) - count, count))
    lo, hi = np.maximum(a[which], edges[k]), np.minimum(b[which], edges[k + 1])
    piece = hi > lo
    which, k, width = which[piece], k[piece], (hi - lo)[piece]
    for j in range(n_values):
        np.add.at(weighted[:, j], k, v[which, j] * width)
    np.add.at(covered, k, width)
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(covered[:, None] > 0, weighted / covered[:, None], np.nan)


@cache
def _first_number(label: str) -> float:
    return float(high_of(label))


def high_circuit_series(rec: TrialRecord, bin_s: float, t_from: float, t_to: float) -> tuple[np.ndarray, np.ndarray]:
    """(bin centres, time-weighted mean number of robots whose last target was on the
    high-value circuit, per bin) for one trial; NaN where the state is not yet defined.
    The first number of a circuits-state label is that count (the high circuit first)."""
    edges = bin_edges(t_from, t_to, bin_s)
    mean = _binned_mean(state_intervals(rec, "circuits"), lambda s, a: _first_number(s), edges)
    return 0.5 * (edges[:-1] + edges[1:]), _from_start(mean, edges, rec)[:, 0]


def group_high_series(rec: TrialRecord, bin_s: float, t_from: float,
                      t_to: float) -> tuple[np.ndarray, list[str], np.ndarray]:
    """(bin centres, group names fastest first, (n_groups, n_bins) time-weighted share of each
    group's live robots whose last target was on the high-value circuit) for one trial: the
    numbers of a groups-state label divided by the groups' live sizes at the time."""
    order = group_order(rec.meta["groups"], rec.meta["speeds_mps"])
    groups = np.asarray(rec.meta["groups"])
    b = rec.table("breakdowns")
    broken_at = np.full(len(groups), np.inf)
    broken_at[b["robot"].astype(int)] = b["t_s"]

    broken_sorted = sorted(broken_at.tolist())
    known: dict[tuple[str, int], np.ndarray] = {}

    def share(s: str, start: float) -> np.ndarray:
        # who is alive at `start` is fixed by how many breakdowns came before it
        key = (s, bisect_right(broken_sorted, start))
        if key not in known:
            alive = broken_at > start
            sizes = np.array([((groups == g) & alive).sum() for g in order], dtype=float)
            with np.errstate(invalid="ignore", divide="ignore"):
                known[key] = np.array(counts_of(s), dtype=float) / sizes
        return known[key]

    edges = bin_edges(t_from, t_to, bin_s)
    mean = _binned_mean(state_intervals(rec, "groups"), share, edges, len(order))
    return 0.5 * (edges[:-1] + edges[1:]), order, _from_start(mean, edges, rec).T


def specialisation_table(records: Iterable[TrialRecord], bin_s: float, t_from: float, t_to: float) -> pd.DataFrame:
    """`t_s,controller,group,mean_share_high,std_share_high,n_trials`: per speed group, the share
    of its robots on the high-value circuit over time."""
    by_key: dict[tuple[str, str], list[np.ndarray]] = {}
    centres = np.array([])
    for rec in records:
        centres, names, shares = group_high_series(rec, bin_s, t_from, t_to)
        for g, series in zip(names, shares, strict=True):
            by_key.setdefault((rec.meta["controller"], g), []).append(series)
    frames = []
    for (ctrl, g), runs in by_key.items():
        f = over_trials({ctrl: runs}, centres, "mean_share_high", "std_share_high", std_of_one=np.nan)
        f.insert(2, "group", g)
        frames.append(f)
    columns = ["t_s", "controller", "group", "mean_share_high", "std_share_high", "n_trials"]
    return pd.concat(frames, ignore_index=True)[columns] if frames else pd.DataFrame(columns=columns)


def allocation_table(records: Iterable[TrialRecord], bin_s: float, t_from: float, t_to: float) -> pd.DataFrame:
    """`t_s,controller,mean_high,std_high,n_trials`: robots on the high-value circuit over time."""
    by_ctrl: dict[str, list[np.ndarray]] = {}
    centres = np.array([])
    for rec in records:
        centres, series = high_circuit_series(rec, bin_s, t_from, t_to)
        by_ctrl.setdefault(rec.meta["controller"], []).append(series)
    return over_trials(by_ctrl, centres, "mean_high", "std_high", std_of_one=np.nan)
