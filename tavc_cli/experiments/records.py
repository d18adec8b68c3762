"""A trial's raw record: event tables as numpy arrays, saved atomically as .npz.

Analysis reads only these records, so every table and figure can be redrawn
without simulating again.

Tables (each a dict of equal-length columns):
  arrivals     t_s, robot, target, circuit, kind (0 source, 1 sink)
  deliveries   t_s, robot, circuit, task_time_s, reward, value, score, and the seconds of
               the task spent driving, avoiding, waiting, docking, searching, escaping, idle
  choices      t_s, robot, state, circuit
  breakdowns   t_s, robot
  value_changes t_s, values (n_changes, n_circuits)
  q            t_s, tables (n_snapshots, n_robots, n_states, n_actions)
  poses        t_s, pose (n_frames, n_robots, 3), alive, circuit, mode (optional)
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from tavc_cli.io import atomic_path
from tavc_cli.vocabulary import ACTIVITIES

TABLES = {
    "arrivals": {"t_s": float, "robot": int, "target": int, "circuit": int, "kind": int},
    "deliveries": {"t_s": float, "robot": int, "circuit": int, "task_time_s": float,
                   "reward": float, "value": float, "score": float,
                   # where the task's time went (behaviours.activities), summing to task_time_s
                   **{f"{a}_s": float for a in ACTIVITIES}},
    "choices": {"t_s": float, "robot": int, "state": int, "circuit": int},
    "breakdowns": {"t_s": float, "robot": int},
}


ARRAY_FIELDS = ("value_changes_t", "value_changes", "q_t", "q", "pose_t", "poses", "pose_alive", "pose_circuit")


def records_differ(a: "TrialRecord", b: "TrialRecord") -> list[str]:
    """Names of everything in which two records differ (empty if identical, bit for bit)."""
    out = [] if a.meta == b.meta else ["meta"]
    if a.tables.keys() != b.tables.keys():
        return [*out, "tables"]
    for name, cols in a.tables.items():
        for col, values in cols.items():
            if col not in b.tables[name] or not np.array_equal(values, b.tables[name][col]):
                out.append(f"{name}.{col}")
    out += [name for name in ARRAY_FIELDS if not np.array_equal(getattr(a, name), getattr(b, name))]
    return out


@dataclass
class TrialRecord:
    """Raw output of one trial; `meta` is JSON-able (spec digest, seed, team, arena...)."""

    meta: dict
    tables: dict[str, dict[str, np.ndarray]] = field(default_factory=dict)
    value_changes_t: np.ndarray = field(default_factory=lambda: np.zeros(0))
    value_changes: np.ndarray = field(default_factory=lambda: np.zeros((0, 0)))
    q_t: np.ndarray = field(default_factory=lambda: np.zeros(0))
    q: np.ndarray = field(default_factory=lambda: np.zeros((0, 0, 0, 0)))
    pose_t: np.ndarray = field(default_factory=lambda: np.zeros(0))
    poses: np.ndarray = field(default_factory=lambda: np.zeros((0, 0, 3)))
    pose_alive: np.ndarray = field(default_factory=lambda: np.zeros((0, 0), dtype=bool))
    pose_circuit: np.ndarray = field(default_factory=lambda: np.zeros((0, 0), dtype=np.int64))
    # what analysis derives from the record, kept so that it is derived once (never saved)
    derived: dict = field(default_factory=dict, repr=False, compare=False)

    def table(self, name: str) -> dict[str, np.ndarray]:
        """The columns of table `name` (one of `TABLES`)."""
        return self.tables[name]

    @property
    def start_s(self) -> float:
        """The time of the record's first tick: minus the trial's warm-up, or its late start."""
        meta = self.meta
        return float(meta["t0_s"]) if "t0_s" in meta else 0.0 - float(meta.get("warmup_s", 0.0))

    @property
    def end_s(self) -> float:
        """The time of the record the trial ran to (its duration, or its n-th delivery)."""
        return float(self.meta["duration_s"])

    def save(self, path: Path) -> None:
        """Write atomically: a temporary file in the same folder, then a rename."""
        path = Path(path)
        path.parent.mkdir(parents=True, exist_ok=True)
        arrays = {"meta": np.array(json.dumps(self.meta, sort_keys=True))}
        for name, cols in self.tables.items():
            for col, values in cols.items():
                arrays[f"{name}__{col}"] = values
        for name in ARRAY_FIELDS:
            arrays[name] = getattr(self, name)
        with atomic_path(path) as tmp, open(tmp, "wb") as fh:
            np.savez_compressed(fh, **arrays)

    @classmethod
    def load(cls, path: Path) -> TrialRecord:
        """The record saved at `path` (`save`)."""
        with np.load(path, allow_pickle=False) as data:
            meta = json.loads(str(data["meta"]))
            tables: dict[str, dict[str, np.ndarray]] = {}
            for key in data.files:
                if "__" in key:
                    name, col = key.split("__", 1)
                    tables.setdefault(name, {})[col] = data[key]
            rec = cls(meta=meta, tables=tables)
            for name in ARRAY_FIELDS:
                setattr(rec, name, data[name])
        return rec


class TableBuilder:
    """Appends rows to named tables during a run; arrays are made once at the end."""

    def __init__(self) -> None:
        """Every table of `TABLES`, empty."""
        self.rows: dict[str, list[tuple]] = {name: [] for name in TABLES}

    def add(self, name: str, *row) -> None:
        """Append `row` (one value per column) to table `name`."""
        self.rows[name].append(row)

    def build(self) -> dict[str, dict[str, np.ndarray]]:
        """Every table as columns of arrays (float64 or int64 as `TABLES` types them)."""
        out = {}
        for name, cols in TABLES.items():
            rows = self.rows[name]
            out[name] = {
                col: np.array([r[k] for r in rows], dtype=np.float64 if typ is float else np.int64)
                for k, (col, typ) in enumerate(cols.items())
            }
        return out
