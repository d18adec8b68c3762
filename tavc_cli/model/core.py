"""The TAVC model (section 1.5.2) on a measured table of task-processing frequencies.

A *split* n = (n_1, ..., n_k) says how many robots serve each circuit. For every
split the table holds, per circuit i, the frequency c_i(n) at which the robots on
i complete tasks (deliveries per second) and their mean task time t_i(n). The
circuits may interfere with each other (those of `two_circuits` cross), so c_i
depends on the whole split, not only on n_i.

From the table and task values w:

- slot value of adding a robot to circuit i in split n (eq. 1.2):
  s_i(n) = w_i * (c_i(n + e_i) - c_i(n));
- the model's optimum: the split of N robots with the largest total value
  sum_i w_i c_i(n), and the split reached by filling slots one robot at a time in
  order of slot value (the two agree when slot values fall monotonically);
- the individual equilibrium: a split where no robot can raise its own reward
  rate r_i(n) = w_i / t_i(n) by moving to another circuit, which is where greedy
  individual learners should settle;
- the chapter's constraints (1.3) and (1.4), and a calibration of w that makes a
  chosen allocation the individual equilibrium, as the authors chose 2200/2000.

Everything here is pure arithmetic on plain data.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field
from itertools import product

from tavc_cli.vocabulary import split_label

Split = tuple[int, ...]

# a split in the state notation of the tables: high-value circuit first
state_label = split_label


@dataclass(frozen=True)
class Cell:
    """Measurements of one circuit in one split (rates per second, times in seconds)."""

    c: float
    t: float
    c_lo: float = math.nan
    c_hi: float = math.nan
    t_lo: float = math.nan
    t_hi: float = math.nan
    n_trials: int = 0
    t_delivered: float = math.nan  # mean time of the tasks completed (t counts stuck robots too)
    budget: tuple[float, ...] = ()  # mean seconds per completed task in each activity


@dataclass
class CTable:
    """c_i(n) and t_i(n) for the splits that were measured."""

    n_circuits: int
    cells: dict[Split, tuple[Cell, ...]] = field(default_factory=dict)
    arrivals_per_h: dict[Split, float] = field(default_factory=dict)  # whole group, sources and sinks

    def c(self, n: Split, i: int) -> float:
        """c_i(n): circuit i's deliveries per second in split n (0 with nobody on it)."""
        return 0.0 if n[i] == 0 else self.cells[n][i].c

    def t(self, n: Split, i: int) -> float:
        """t_i(n): the mean task time on circuit i in split n."""
        return self.cells[n][i].t

    def has(self, n: Split) -> bool:
        """Whether split n was measured (the empty split always is)."""
        return sum(n) == 0 or n in self.cells


def splits(n_robots: int, n_circuits: int) -> list[Split]:
    """Every split of exactly n_robots over n_circuits, first circuit's count descending."""
    out = [c for c in product(range(n_robots + 1), repeat=n_circuits) if sum(c) == n_robots]
    return sorted(out, reverse=True)


def splits_up_to(n_robots: int, n_circuits: int) -> list[Split]:
    """Every non-empty split of at most n_robots robots."""
    return [s for m in range(1, n_robots + 1) for s in splits(m, n_circuits)]


def add_robot(n: Split, i: int, d: int = 1) -> Split:
    """Split n with `d` robots more on circuit i."""
    return tuple(v + d if k == i else v for k, v in enumerate(n))


def total_value(table: CTable, n: Split, values: Sequence[float]) -> float:
    """Group value per second: sum_i w_i c_i(n)."""
    return sum(values[i] * table.c(n, i) for i in range(table.n_circuits))


def slot_value(table: CTable, n: Split, i: int, values: Sequence[float]) -> float:
    """s_i(n) = w_i (c_i(n + e_i) - c_i(n)), eq. 1.2; NaN if n + e_i was not measured."""
    m = add_robot(n, i)
    if not table.has(m):
        return math.nan
    return values[i] * (table.c(m, i) - table.c(n, i))


def reward_rate(table: CTable, n: Split, i: int, values: Sequence[float], time_unit_s: float = 1.0) -> float:
    """A robot's reward per task on circuit i in split n: w_i / t_i(n), t in `time_unit_s` units."""
    return values[i] / (table.t(n, i) / time_unit_s)


def optimal_split(table: CTable, n_robots: int, values: Sequence[float]) -> Split:
    """The split of n_robots with the largest total value (ties: the first in `splits` order)."""
    return max(splits(n_robots, table.n_circuits), key=lambda n: total_value(table, n, values))


def slot_fill(table: CTable, n_robots: int, values: Sequence[float]) -> Split:
    """Add robots one at a time to the circuit whose free slot is worth most."""
    n: Split = (0,) * table.n_circuits
    for _ in range(n_robots):
        gains = [slot_value(table, n, i, values) for i in range(table.n_circuits)]
        best = max(range(table.n_circuits), key=lambda i: (-math.inf if math.isnan(gains[i]) else gains[i]))
        n = add_robot(n, best)
    return n


def deviation_gains(table: CTable, n: Split, values: Sequence[float]) -> list[tuple[int, int, float]]:
    """(from, to, relative gain in own reward) for every single-robot move out of split n.

    A circuit that delivered nothing in the measurement (t infinite) pays nothing: leaving it
    for one that pays is an infinite gain, for another that pays nothing no gain."""
    out = []
    for i in range(table.n_circuits):
        if n[i] == 0:
            continue
        here = reward_rate(table, n, i, values)
        for j in range(table.n_circuits):
            if j == i:
                continue
            m = add_robot(add_robot(n, i, -1), j)
            if table.has(m) and m[j] > 0:
                there = reward_rate(table, m, j, values)
                gain = there / here - 1.0 if here > 0 else (math.inf if there > 0 else 0.0)
                out.append((i, j, gain))
    return out


def is_equilibrium(table: CTable, n: Split, values: Sequence[float]) -> bool:
    """No robot can raise its own reward rate by switching circuit."""
    return all(g <= 0.0 for _, _, g in deviation_gains(table, n, values))


def equilibria(table: CTable, n_robots: int, values: Sequence[float]) -> list[Split]:
    """Every split of `n_robots` that is an equilibrium (`is_equilibrium`)."""
    return [n for n in splits(n_robots, table.n_circuits) if is_equilibrium(table, n, values)]


def predicted_split(table: CTable, n_robots: int, values: Sequence[float]) -> Split:
    """The individual equilibrium; among several the most valuable, and if there is
    none, the split where the best move gains least."""
    eq = equilibria(table, n_robots, values)
    if eq:
        return max(eq, key=lambda n: total_value(table, n, values))

    def worst_gain(n: Split) -> float:
        return max((g for _, _, g in deviation_gains(table, n, values)), default=0.0)

    return min(splits(n_robots, table.n_circuits), key=worst_gain)


def intended_split(n_robots: int, values: Sequence[float]) -> Split:
    """Robots spread evenly, the extra ones on the most valuable circuits (6 -> 3:3, 5 -> 3:2)."""
    k = len(values)
    order = sorted(range(k), key=lambda i: -values[i])
    base, extra = divmod(n_robots, k)
    n = [base] * k
    for i in order[:extra]:
        n[i] += 1
    return tuple(n)


# --- the chapter's constraints, two circuits ------------------------------------


def pair_split(n_robots: int, x: int, k: int) -> Split:
    """Two circuits: k robots on circuit x, the rest on the other."""
    return (k, n_robots - k) if x == 0 else (n_robots - k, k)


def constraint_1_3(table: CTable, n_robots: int, values: Sequence[float], m: int) -> dict:
    """(1.3): being the (m+1)th robot on any circuit pays less than being the m-th on any:
    for all x, y: r_x(m+1 on x) < r_y(m on y), the rest of the n_robots on the other circuit."""
    checks = []
    for x, y in product(range(2), repeat=2):
        a, b = pair_split(n_robots, x, m + 1), pair_split(n_robots, y, m)
        if table.has(a) and table.has(b) and a[x] > 0 and b[y] > 0:
            ra, rb = reward_rate(table, a, x, values), reward_rate(table, b, y, values)
            checks.append({"x": x, "y": y, "r_x_m+1": ra, "r_y_m": rb, "holds": bool(ra < rb)})
    return {"m": m, "n_robots": n_robots, "holds": bool(checks) and all(c["holds"] for c in checks),
            "checks": checks}


def constraint_1_4(table: CTable, n_robots: int, values: Sequence[float], m: int, preferred: int) -> dict:
    """(1.4): the m-th robot on the preferred circuit earns more than the m-th on the other
    (with n_robots in all, e.g. 5 after a breakdown: r_high(3:2) > r_low(2:3))."""
    other = 1 - preferred
    a, b = pair_split(n_robots, preferred, m), pair_split(n_robots, other, m)
    if not (table.has(a) and table.has(b)):
        return {"m": m, "n_robots": n_robots, "holds": False, "checks": []}
    rp, ro = reward_rate(table, a, preferred, values), reward_rate(table, b, other, values)
    return {"m": m, "n_robots": n_robots, "holds": bool(ro < rp),
            "checks": [{"r_preferred_m": rp, "r_other_m": ro}]}


# --- calibration -------------------------------------------------------------------


def ratio_bounds(table: CTable, targets: Iterable[tuple[int, Split]], high: int = 0,
                 pessimistic: bool = False) -> tuple[float, float]:
    """Interval of rho = w_high / w_low (two circuits) that makes every target split the
    individual equilibrium for its team size.

    For a robot on circuit i in split n moving to j (split m), staying pays iff
    w_i / t_i(n) >= w_j / t_j(m): with w_high = rho w_low this is a bound on rho.
    `pessimistic` uses each task time's confidence bound that makes the bound tighter. A bound on
    a task time the measurement did not give is unknown, and so is the interval: (nan, nan), which
    no calibration satisfies: no task delivered there (infinite over infinite), or, pessimistic,
    a confidence bound that one trial cannot give (nan).
    """
    lo, hi = 0.0, math.inf
    for _n_robots, n in targets:
        for i in range(2):
            if n[i] == 0:
                continue
            j = 1 - i
            m = add_robot(add_robot(n, i, -1), j)
            if not table.has(m):
                continue
            t_stay, t_move = table.cells[n][i], table.cells[m][j]
            if i == high:  # rho / t_stay >= 1 / t_move  ->  rho >= t_stay / t_move
                ts = t_stay.t_hi if pessimistic else t_stay.t
                tm = t_move.t_lo if pessimistic else t_move.t
                if math.isnan(ts / tm):
                    return math.nan, math.nan
                lo = max(lo, ts / tm)
            else:  # 1 / t_stay >= rho / t_move  ->  rho <= t_move / t_stay
                ts = t_stay.t_hi if pessimistic else t_stay.t
                tm = t_move.t_lo if pessimistic else t_move.t
                if math.isnan(tm / ts):
                    return math.nan, math.nan
                hi = min(hi, tm / ts)
    return lo, hi


def calibrate(table: CTable, targets: Sequence[tuple[int, Split]], low_value: float, high: int = 0) -> dict:
    """Task values (high circuit first in `high`) under which every target split is the
    individual equilibrium, with the high circuit worth more than the low one.

    Picks rho at the geometric middle of the feasible interval (the point furthest, in
    ratio, from both ends); if the interval is open above, 10 % above its lower end.
    """
    lo, hi = ratio_bounds(table, targets, high)
    lo = max(lo, 1.0)
    rlo, rhi = ratio_bounds(table, targets, high, pessimistic=True)
    feasible = lo < hi
    if not feasible:
        rho = math.nan
    elif math.isinf(hi):
        rho = lo * 1.1
    else:
        rho = math.sqrt(lo * hi)
    values = [math.nan, math.nan]
    values[high] = round(rho * low_value) if feasible else math.nan
    values[1 - high] = low_value
    return {"feasible": feasible, "ratio_interval": [lo, hi], "ratio": rho,
            "robust_ratio_interval": [max(rlo, 1.0), rhi], "robust": max(rlo, 1.0) < rhi,
            "values": values, "targets": [{"n_robots": n_r, "split": list(n)} for n_r, n in targets]}
