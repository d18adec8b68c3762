"""Hand-made trial records for the analysis tests: tables from rows, Q snapshots from greedy
choices."""

from __future__ import annotations

import numpy as np

from tavc_cli.experiments.records import TABLES


def table(name, rows):
    """Table `name` from rows given as dicts; missing columns are 0."""
    return {col: np.array([r.get(col, 0) for r in rows], dtype=np.float64 if typ is float else np.int64)
            for col, typ in TABLES[name].items()}


def greedy_snapshots(greedy_per_snapshot):
    """Q snapshots (n_snap, n_robots, 2, 2) whose greedy action in each state is given:
    greedy_per_snapshot[k][robot] = (best after circuit 0, best after circuit 1)."""
    q = np.zeros((len(greedy_per_snapshot), len(greedy_per_snapshot[0]), 2, 2))
    for k, robots in enumerate(greedy_per_snapshot):
        for r, best in enumerate(robots):
            for s, a in enumerate(best):
                q[k, r, s, a] = 1.0
    return q
