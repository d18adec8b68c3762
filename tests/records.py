"""Hand-made trial records for the analysis tests: records and tables from rows, Q snapshots from
greedy choices."""

from __future__ import annotations

import numpy as np

from tavc_cli.experiments.records import TABLES, TrialRecord


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


def record(*, n_robots=2, values=(2.0, 1.0), duration_s=100.0, arrivals=(), breakdowns=(), deliveries=(), choices=(),
           value_changes=(), q_t=(), q=None, groups=None, speeds=None, controller="tavc", trial=0):
    """A TrialRecord: arrivals (t, robot, circuit), breakdowns (t, robot), deliveries as dicts
    (t_s, robot, circuit, task_time_s, reward, ...), choices (t, robot, state, circuit), value
    changes (t, values), Q snapshots `q` at times `q_t`. One group, "all", unless `groups`;
    speeds 0.3 m/s for a "fast" robot, 0.2 for a "slow" one, else 0.25, unless `speeds`."""
    groups = list(groups or ["all"] * n_robots)
    if speeds is None:
        speeds = [{"fast": 0.3, "slow": 0.2}.get(g, 0.25) for g in groups]
    rec = TrialRecord(
        meta={"n_robots": n_robots, "n_circuits": len(values), "groups": groups, "speeds_mps": list(speeds),
              "values": list(values), "duration_s": duration_s, "warmup_s": 0.0, "controller": controller,
              "trial": trial},
        tables={"arrivals": table("arrivals", [{"t_s": a[0], "robot": a[1], "circuit": a[2]} for a in arrivals]),
                "breakdowns": table("breakdowns", [{"t_s": b[0], "robot": b[1]} for b in breakdowns]),
                "deliveries": table("deliveries", list(deliveries)),
                "choices": table("choices", [dict(zip(("t_s", "robot", "state", "circuit"), c, strict=True))
                                              for c in choices])},
    )
    rec.value_changes_t = np.array([v[0] for v in value_changes], dtype=float)
    rec.value_changes = np.array([v[1] for v in value_changes], dtype=float).reshape(len(value_changes), len(values))
    if q is not None:
        rec.q_t, rec.q = np.asarray(q_t, float), np.asarray(q, float)
    return rec
