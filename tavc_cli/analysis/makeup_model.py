"""A model of the learners that knows turn-taking: which make-ups of stayers and alternators
are rest points, and which one a group starting from random tables drifts to.

The chapter's model counts robots per circuit, as if every robot stayed. Here a robot of a
team of n holds one of the strategies a 2-state Q-learner can hold greedily: stay on the
high-value circuit, stay on the low-value one, or alternate. A make-up (h, l, a) counts them.
From the tasks static robots complete in each make-up (`surrogate.tasks`: each kind of task,
its circuit and its time), each strategy's reward rate is that of a renewal process: the mean
value of its tasks over their mean time, its greedy task taken with probability 1 - eps/2 and
the other with eps/2 (epsilon-greedy over two actions). A make-up is a rest point where no
robot gains by taking another strategy (the robot's rate in the make-up its change leads to,
against its rate now). A group starting from random Q-tables holds each greedy policy of the
four a 2x2 table can have with probability 1/4: alternate; stay where it is (on the high-value
circuit or the low one, half each); go to and keep to the high-value circuit; or the low one;
so a robot is a high stayer with 3/8, a low stayer with 3/8 and an alternator with 1/4, and
the starting make-ups are multinomial. From each, the make-up drifts by the single change of
one robot that gains most, until none gains (a rest point) or a make-up repeats (a cycle).
The rest points' basins, weighted by the starting make-ups' probabilities, give the predicted
regime (named by the rule the learners' groups are named by, `mechanism.regime`) and the
robots on the high-value circuit (h + a / 2).

Every number comes from the measured tasks and the chapter's values and epsilon; nothing is
fitted to the learners. Pure functions; `stay_switch` applies them to each reading.

Two simplifications to keep in mind when reading its predictions. A stayer's exploratory task
to the other circuit is counted, but not its way back (the greedy switch home that follows);
and a strategy is rated by its long-run value per second (the mean value of its tasks over
their mean time), while a learner's reward is per task (w / t), so its Q-values weigh a
strategy by the mean of w / t; the two differ where a strategy's tasks differ in length.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from math import comb

import pandas as pd

from tavc_cli.analysis.mechanism import regime as mechanism_regime
from tavc_cli.analysis.stay_switch import makeup_counts, thresholds

STRATEGIES = ("high", "low", "alternate")
START = {"high": 3 / 8, "low": 3 / 8, "alternate": 1 / 4}  # a random 2x2 table's greedy policy
MAX_STEPS = 200


@dataclass(frozen=True)
class Times:
    """Mean task times (s) by make-up (h, l, a) and kind: ``stay_high``, ``stay_low``,
    ``switch_high`` (a switch that ends on the high-value circuit), ``switch_low``."""

    by_makeup: dict[tuple[int, int, int], dict[str, float]]

    def time(self, makeup: tuple[int, int, int], kind: str) -> float:
        """The mean time of `kind` in `makeup`, or where it was not measured there (no robot
        does that kind of task in it), in the nearest make-up that measured it."""
        own = self.by_makeup.get(makeup, {}).get(kind, math.nan)
        if math.isfinite(own):
            return own
        found = [(sum(abs(x - y) for x, y in zip(m, makeup, strict=True)), m) for m, t in self.by_makeup.items()
                 if math.isfinite(t.get(kind, math.nan))]
        return self.by_makeup[min(found)[1]][kind] if found else math.nan


def times_of(tasks: pd.DataFrame, high: int) -> Times:
    """`Times` from a one-group team's measured tasks (`surrogate.tasks.COLUMNS`), the
    high-value circuit's index `high`."""
    out: dict[tuple[int, int, int], dict[str, float]] = {}
    for makeup, rows in tasks.groupby("makeup", sort=False):
        counts = makeup_counts(makeup)
        key = (counts[high], counts[1 - high], counts[2])
        on_high = rows["circuit"] == high
        out[key] = {f"{kind}_{where}": float(rows.loc[(rows["kind"] == kind) & (on_high == (where == "high")),
                                                      "task_time_s"].mean())
                    for kind in ("stay", "switch") for where in ("high", "low")}
    return Times(out)


def rate(times: Times, makeup: tuple[int, int, int], strategy: str, values: tuple[float, float],
         epsilon: float) -> float:
    """The reward per second of a robot holding `strategy` in `makeup` (values: high, low)."""
    w_h, w_l = values
    g, x = 1.0 - epsilon / 2.0, epsilon / 2.0  # the greedy task's share, the other's
    t = {k: times.time(makeup, k) for k in ("stay_high", "stay_low", "switch_high", "switch_low")}
    if strategy == "high":
        value, time = g * w_h + x * w_l, g * t["stay_high"] + x * t["switch_low"]
    elif strategy == "low":
        value, time = g * w_l + x * w_h, g * t["stay_low"] + x * t["switch_high"]
    else:
        value = (w_h + w_l) / 2.0
        time = g * (t["switch_high"] + t["switch_low"]) / 2.0 + x * (t["stay_high"] + t["stay_low"]) / 2.0
    return value / time if time > 0 else math.nan


def _moved(makeup: tuple[int, int, int], src: int, dst: int) -> tuple[int, int, int]:
    m = list(makeup)
    m[src] -= 1
    m[dst] += 1
    return (m[0], m[1], m[2])


def best_change(times: Times, makeup: tuple[int, int, int], values: tuple[float, float],
                epsilon: float) -> tuple[float, tuple[int, int, int] | None]:
    """(the largest relative gain any robot of `makeup` has by taking another strategy, the
    make-up that change leads to); (gain <= 0, None) where no robot gains: a rest point."""
    best, where = 0.0, None
    for src, s in enumerate(STRATEGIES):
        if makeup[src] == 0:
            continue
        now = rate(times, makeup, s, values, epsilon)
        for dst, d in enumerate(STRATEGIES):
            if dst == src:
                continue
            after = _moved(makeup, src, dst)
            gain = rate(times, after, d, values, epsilon) / now - 1.0
            if gain > best:
                best, where = gain, after
    return best, where


def rest_point(times: Times, start: tuple[int, int, int], values: tuple[float, float],
               epsilon: float) -> tuple[tuple[int, int, int], bool]:
    """Where the drift from `start` ends: (the make-up, True) at a rest point; (the first make-up
    met again, False) in a cycle."""
    seen, m = {start}, start
    for _ in range(MAX_STEPS):
        _, nxt = best_change(times, m, values, epsilon)
        if nxt is None:
            return m, True
        if nxt in seen:
            return nxt, False
        seen.add(nxt)
        m = nxt
    return m, False


def start_probability(makeup: tuple[int, int, int]) -> float:
    """The probability that random Q-tables start the team in `makeup` (multinomial)."""
    high, low, alternate = makeup
    n = high + low + alternate
    return (comb(n, high) * comb(n - high, low) * START["high"] ** high * START["low"] ** low
            * START["alternate"] ** alternate)


def regime(makeup: tuple[int, int, int]) -> str:
    """persistence, turn-taking or mixed, by the rule the learners' groups are named by
    (`mechanism.regime`: stayers, or alternators, at least its share of the robots)."""
    high, low, alternate = makeup
    return mechanism_regime(high + low, alternate, high + low + alternate)


def predict(times: Times, n: int, values: tuple[float, float], epsilon: float) -> pd.DataFrame:
    """The rest points (and cycles) the drift reaches from every starting make-up of n robots,
    one row each: the make-up, whether it is a rest point, its regime, the robots on the
    high-value circuit (h + a / 2), its basin (the probability of starting where the drift
    leads to it) and every strategy's reward rate there; by basin, largest first."""
    basins: dict[tuple[tuple[int, int, int], bool], float] = {}
    for high in range(n + 1):
        for low in range(n + 1 - high):
            start = (high, low, n - high - low)
            end = rest_point(times, start, values, epsilon)
            basins[end] = basins.get(end, 0.0) + start_probability(start)
    rows = []
    for (m, rest), p in basins.items():
        row = {"makeup": f"{m[0]}-{m[1]}-{m[2]}", "high_stayers": m[0], "low_stayers": m[1], "alternators": m[2],
               "rest_point": rest, "regime": regime(m) if rest else "cycle", "robots_high": m[0] + m[2] / 2.0,
               "basin": p}
        row.update({f"rate_{s}": rate(times, m, s, values, epsilon) for s in STRATEGIES})
        rows.append(row)
    return pd.DataFrame(rows).sort_values("basin", ascending=False, kind="stable").reset_index(drop=True)


def predicted_regime(prediction: pd.DataFrame) -> tuple[str, float]:
    """The regime with the largest basin over the rest points (and cycles), and that basin."""
    by = prediction.groupby("regime")["basin"].sum().sort_values(ascending=False, kind="stable")
    return str(by.index[0]), float(by.iloc[0])


def expected_high(prediction: pd.DataFrame) -> float:
    """Robots on the high-value circuit, expected over the basins."""
    return float((prediction["robots_high"] * prediction["basin"]).sum() / prediction["basin"].sum())


def values_high_low(values: Sequence[float]) -> tuple[tuple[float, float], int]:
    """((w_high, w_low), the high-value circuit's index) of two circuits' values
    (`stay_switch.thresholds` picks the circuit)."""
    high = thresholds(values)[2]
    return (float(values[high]), float(values[1 - high])), high


def readings_summary(table: pd.DataFrame, model: pd.DataFrame | None = None) -> pd.DataFrame:
    """One row per reading of a stay/switch table (`stay_switch.stay_switch_table`, several
    readings) over its make-ups with both a low-value stayer and an alternator: how many, a
    low-value stayer's t_switch / t_stay (min, median, max) and the threshold, in how many
    staying pays (t the whole task; from the source on); with `model` (`predict`'s rows, with
    their reading), the regime it predicts, that regime's basin and its robots on the
    high-value circuit (NaN where it has no rows for the reading)."""
    rows = []
    for reading, mine in table.dropna(subset=["ratio_low"]).groupby("reading", sort=False):
        r = mine["ratio_low"]
        row = {"reading": reading, "n": len(mine), "ratio_min": r.min(), "ratio_median": r.median(),
               "ratio_max": r.max(), "threshold": float(mine["threshold_low"].iloc[0]),
               "pays": int(mine["stay_pays_low"].sum()), "pays_source": int(mine["stay_pays_low_source"].sum()),
               "regime": None, "basin": math.nan, "robots_high": math.nan}
        predicted = model[model["reading"] == reading] if model is not None else None
        if predicted is not None and len(predicted):
            row["regime"], row["basin"] = predicted_regime(predicted)
            row["robots_high"] = expected_high(predicted)
        rows.append(row)
    return pd.DataFrame(rows)
