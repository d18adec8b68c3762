"""What a reading of the world does to staying and switching: from the tasks static robots
complete in every make-up of a team (`surrogate.tasks`: robots held to staying on the
high-value circuit, staying on the low-value one, or alternating), how long a task that stays
takes beside one that switches, where the time goes, and whether staying pays.

A robot that alternates earns on average (w_h + w_l) / 2 per task of t_switch; one that stays
on the low-value circuit earns w_l per task of t_stay,low. Staying pays for it where

    w_l / t_stay,low > (w_h + w_l) / (2 t_switch)  <=>  t_switch / t_stay,low > (w_h + w_l) / (2 w_l),

and for a robot on the high-value circuit where t_switch / t_stay,high > (w_h + w_l) / (2 w_h).
The chapter's vacancy chains need the first: a robot that moved to the low-value circuit must
keep to it. Each ratio is given twice: with t the whole task (from the choice at the sink to the
next delivery, `tasks.time_from=choice`) and from the source on (`time_from=source`, the task
less its empty leg). Pure functions of the task table, and the readings' grid (`GRID`, fixed here
before any run, with their names); the measuring is `tavc_cli.stay_switch`'s.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Sequence

import pandas as pd

# the readings measured, each a config group with today's world first (docs/readings.md)
GRID: tuple[tuple[str, tuple[str, ...]], ...] = (
    ("arrival", ("dock", "range")),
    ("passing", ("nearest", "left")),
    ("arena", ("two_circuits", "two_circuits_parallel")),
)
STAY, SWITCH = "stay", "switch"
SPLIT = ("drive", "avoid", "wait", "dock")  # where a task's time goes, in the table (the rest: search, escape)
COLUMNS = ("reading", "makeup", "high_stayers", "low_stayers", "alternators",
           "n_stay_low", "n_stay_high", "n_switch", "t_stay_low_s", "t_stay_high_s", "t_switch_s",
           *(f"{a}_stay_low_s" for a in SPLIT), *(f"{a}_switch_s" for a in SPLIT),
           "ratio_low", "ratio_high", "ratio_low_source", "ratio_high_source",
           "threshold_low", "threshold_high", "stay_pays_low", "stay_pays_high",
           "stay_pays_low_source", "stay_pays_high_source")


def thresholds(values: Sequence[float]) -> tuple[float, float, int, int]:
    """(t_switch / t_stay above which staying pays on the low-value circuit, the same on the
    high-value one, the high circuit's index, the low one's) for two circuits' values."""
    if len(values) != 2 or min(float(v) for v in values) <= 0:
        raise ValueError("stay and switch are defined for two circuits of positive value")
    high = 0 if float(values[0]) >= float(values[1]) else 1
    w_h, w_l = float(values[high]), float(values[1 - high])
    return (w_h + w_l) / (2 * w_l), (w_h + w_l) / (2 * w_h), high, 1 - high


def _mean(rows: pd.DataFrame, column: str) -> float:
    return float(rows[column].mean()) if len(rows) else math.nan


def _ratio(num: float, den: float) -> float:
    return num / den if den > 0 and math.isfinite(num) and math.isfinite(den) else math.nan


def makeup_counts(makeup: str) -> tuple[int, int, int]:
    """A one-group team's make-up (``all:s0-s1-a``, as `surrogate.tasks.makeup_name` writes it):
    robots staying on circuit 0, on circuit 1, alternating."""
    parts = str(makeup).split()
    if len(parts) != 1:
        raise ValueError(f"make-up {makeup!r}: stay and switch are measured on one-group teams")
    s0, s1, a = (int(x) for x in parts[0].rsplit(":", 1)[1].split("-"))
    return s0, s1, a


def stay_switch_table(tasks: pd.DataFrame, values: Sequence[float], reading: str = "") -> pd.DataFrame:
    """One row per make-up of a one-group team (`tasks`: `surrogate.tasks.COLUMNS`, one team):
    robots staying on the high-value circuit, on the low-value one and alternating; the tasks
    of each kind, their mean times and where the time of a low-value stay and a switch goes;
    t_switch / t_stay on each circuit, with t the whole task and from the source on; the
    thresholds (`thresholds`) and whether staying pays. Make-ups without a low stayer or an
    alternator have no ratio (NaN) and do not pay."""
    t_low, t_high, high, low = thresholds(values)
    rows = []
    for makeup, mine in tasks.groupby("makeup", sort=False):
        counts = makeup_counts(makeup)
        by_circuit = {high: counts[high], low: counts[low]}
        stay_low = mine[(mine["kind"] == STAY) & (mine["circuit"] == low)]
        stay_high = mine[(mine["kind"] == STAY) & (mine["circuit"] == high)]
        switch = mine[mine["kind"] == SWITCH]
        row = {"reading": reading, "makeup": str(makeup), "high_stayers": by_circuit[high],
               "low_stayers": by_circuit[low], "alternators": counts[2],
               "n_stay_low": len(stay_low), "n_stay_high": len(stay_high), "n_switch": len(switch),
               "t_stay_low_s": _mean(stay_low, "task_time_s"), "t_stay_high_s": _mean(stay_high, "task_time_s"),
               "t_switch_s": _mean(switch, "task_time_s")}
        row.update({f"{a}_stay_low_s": _mean(stay_low, f"{a}_s") for a in SPLIT})
        row.update({f"{a}_switch_s": _mean(switch, f"{a}_s") for a in SPLIT})
        # from the source on: each task's time less its empty leg, over the tasks whose source arrival is known
        loaded = {name: float((rows_["task_time_s"] - rows_["source_s"]).dropna().mean()) if len(rows_) else math.nan
                  for name, rows_ in (("low", stay_low), ("high", stay_high), ("switch", switch))}
        row["ratio_low"] = _ratio(row["t_switch_s"], row["t_stay_low_s"])
        row["ratio_high"] = _ratio(row["t_switch_s"], row["t_stay_high_s"])
        row["ratio_low_source"] = _ratio(loaded["switch"], loaded["low"])
        row["ratio_high_source"] = _ratio(loaded["switch"], loaded["high"])
        row["threshold_low"], row["threshold_high"] = t_low, t_high
        for suffix in ("", "_source"):
            row[f"stay_pays_low{suffix}"] = bool(row[f"ratio_low{suffix}"] > t_low)
            row[f"stay_pays_high{suffix}"] = bool(row[f"ratio_high{suffix}"] > t_high)
        rows.append(row)
    out = pd.DataFrame(rows, columns=list(COLUMNS))
    return out.sort_values(["alternators", "low_stayers"], kind="stable").reset_index(drop=True)


def readings() -> list[dict[str, str]]:
    """Every combination of the grid's readings, today's world first."""
    keys = [k for k, _ in GRID]
    return [dict(zip(keys, combo, strict=True)) for combo in itertools.product(*(v for _, v in GRID))]


def reading_of(cfg) -> dict[str, str]:
    """The reading of the grid a run's settings make (`GRID`'s keys): ``{"arrival": "dock", ...}``."""
    behaviour = cfg.robot.behaviour
    return {"arrival": str(behaviour.arrival), "passing": str(behaviour.passing), "arena": str(cfg.arena.name)}


def reading_name(reading: dict[str, str]) -> str:
    """A reading as the table names it, its overrides: ``arrival=dock passing=nearest arena=two_circuits``."""
    return " ".join(f"{k}={v}" for k, v in reading.items())


def reading_folder(reading: dict[str, str]) -> str:
    """A reading's folder under the study's: its values, ``dock-nearest-two_circuits``."""
    return "-".join(reading.values())


def split_folder(name: str) -> tuple[dict[str, str], str] | None:
    """A reading's folder name (`reading_folder`), perhaps with a variant of the reading after it,
    as (the reading, the variant): ``range-left-two_circuits_parallel-calibrated`` ->
    (``{"arrival": "range", ...}``, ``"calibrated"``); None for a name of another form."""
    keys = [k for k, _ in GRID]
    parts = name.split("-", len(keys) - 1)
    if len(parts) != len(keys):
        return None
    *parts, last = parts
    last, _, variant = last.partition("-")
    return dict(zip(keys, [*parts, last], strict=True)), variant


def parse_reading(name: str) -> dict[str, str]:
    """`reading_name`'s words back into the reading: ``{"arrival": "dock", ...}``."""
    return dict(part.split("=", 1) for part in name.split() if "=" in part)

