"""Section 1.4's measures: performance over traversals, the learned policies, lanes.

- Traversal (Table 1.1, individual): a robot's time from one sink arrival to the next
  (sink -> source -> sink); its first is counted from the start of the trial. "After n
  traversals" is the robot's traversal number n + 1; mean and std over every robot of every
  trial that made it.
- Target time (Table 1.1, group; Figure 1.4): the time between consecutive target arrivals
  of the group (any robot, source or sink), the first counted from the start; "after m
  arrivals" is interval m + 1, mean and std over trials. Figure 1.4 smooths it over a
  window of 10 arrivals.
- Policies (`policy.csv`, from each robot's final Q-table): over the states it learned in
  (its Q-row changed during the run), the share whose best behaviour is each behaviour, and
  stop-rates: the share of learned states with a marking condition whose best behaviour is
  stop (yellow: the rear marking seen; red, green: that marking seen and no yellow; front:
  red or green and no yellow).
- Lanes (from pose frames, `sim.pose_every_s`): each robot's lateral offset from the
  source-sink axis while it drives along the axis, signed so that positive is left of its
  direction of travel, averaged per trial over a window early and late in the run. Two lanes
  show as an offset away from zero with robots in both directions on their own side.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterable, Mapping, Sequence

import numpy as np
import pandas as pd

from tavc_cli.experiments.records import TrialRecord
from tavc_cli.learning.behaviour import ACTION_NAMES, N_STATES, state_bits
from tavc_cli.vocabulary import SINK

TRAVERSAL_ROWS = (0, 25, 50, 75, 100, 150, 200)
ARRIVAL_ROWS = (0, 125, 250, 375, 500, 750, 1000)
WINDOW = 10  # arrivals in Figure 1.4's moving mean
# a robot counts as driving along the axis when its heading is within this angle of it
ALONG_AXIS_RAD = math.radians(30.0)
# and as away from the docks when at least this far from either end of the axis
END_MARGIN_M = 1.5


def traversal_times(rec: TrialRecord) -> list[np.ndarray]:
    """Per robot: the durations of its traversals (sink arrival to sink arrival, the first from t = 0)."""
    a = rec.table("arrivals")
    out = []
    for robot in range(int(rec.meta["n_robots"])):
        t = np.sort(a["t_s"][(a["robot"] == robot) & (a["kind"] == SINK)])
        out.append(np.diff(np.concatenate([[0.0], t])))
    return out


def target_times(rec: TrialRecord) -> np.ndarray:
    """The group's intervals between consecutive target arrivals (the first from t = 0)."""
    t = np.sort(rec.table("arrivals")["t_s"])
    return np.diff(np.concatenate([[0.0], t]))


def _at(samples: Sequence[np.ndarray], k: int) -> np.ndarray:
    return np.array([s[k] for s in samples if len(s) > k], dtype=float)


def table_1_1(records: Iterable[TrialRecord]) -> pd.DataFrame:
    """Table 1.1's columns (named as in the chapter's CSV), plus how many samples each mean has."""
    records = list(records)
    return table_1_1_from(traversal_table(records), target_time_table(records))


def target_time_curve(targets: pd.DataFrame, window: int = WINDOW) -> pd.DataFrame:
    """`m_arrivals,mean_target_s,std_target_s,n_trials` (Figure 1.4): each trial's target times
    (`target_times.csv`) smoothed by a moving mean over `window` arrivals (at m: intervals
    m .. m + window - 1), then mean and std over the trials that got that far."""
    smooth = []
    for _, g in targets.groupby(["controller", "trial"], sort=False):
        x = g.sort_values("arrival")["time_s"].to_numpy(float)
        if len(x) >= window:
            smooth.append(np.convolve(x, np.ones(window) / window, mode="valid"))
    rows = []
    for m in range(max((len(s) for s in smooth), default=0)):
        col = _at(smooth, m)
        rows.append({"m_arrivals": m, "mean_target_s": col.mean(),
                     "std_target_s": col.std(ddof=1) if len(col) > 1 else math.nan, "n_trials": len(col)})
    return pd.DataFrame(rows, columns=["m_arrivals", "mean_target_s", "std_target_s", "n_trials"])


def _rate(best: np.ndarray, states: np.ndarray, action: int) -> float:
    return float(np.mean(best[states] == action)) if len(states) else math.nan


STOP = ACTION_NAMES.index("stop")
CONDITIONS = {
    "yellow": [s for s in range(N_STATES) if state_bits(s)["yellow"]],
    "red": [s for s in range(N_STATES) if state_bits(s)["red"] and not state_bits(s)["yellow"]],
    "green": [s for s in range(N_STATES) if state_bits(s)["green"] and not state_bits(s)["yellow"]],
    "front": [s for s in range(N_STATES)
              if (state_bits(s)["red"] or state_bits(s)["green"]) and not state_bits(s)["yellow"]],
}


def policy_rows(rec: TrialRecord) -> list[dict]:
    """One row per robot: share of its learned states per best behaviour, and the stop-rates.

    Only states the robot learned in count: those whose Q-row differs between the first and the
    last snapshot (a choice made in a state updates its row at the next decision). Many of the 32
    never occur (the camera shows red, green or yellow, hardly ever two at once), and an unvisited
    state's best behaviour is only its initial random values."""
    q = np.asarray(rec.q)
    if q.ndim != 4 or not len(q) or q.shape[2] != N_STATES:
        return []
    best = np.argmax(q[-1], axis=2)  # (robots, states)
    learned = (q[-1] != q[0]).any(axis=2)
    rows = []
    for robot in range(best.shape[0]):
        seen = np.flatnonzero(learned[robot])
        row = {"controller": rec.meta["controller"], "trial": int(rec.meta["trial"]), "robot": robot,
               "n_states": len(seen)}
        row.update({f"share_{name}": _rate(best[robot], seen, k) for k, name in enumerate(ACTION_NAMES)})
        row.update({f"stop_rate_{c}": _rate(best[robot], np.intersect1d(states, seen), STOP)
                    for c, states in CONDITIONS.items()})
        rows.append(row)
    return rows


def policy_table(records: Iterable[TrialRecord]) -> pd.DataFrame:
    """`policy_rows` of every record, one row per robot."""
    return pd.DataFrame([r for rec in records for r in policy_rows(rec)])


def _directed_frames(rec: TrialRecord, source_xy: Sequence[float], sink_xy: Sequence[float], t_from: float,
                     t_to: float) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The pose frames in [t_from, t_to) seen along the source-sink axis: (poses, distance along
    the axis from the source, offset to the left of source -> sink, live robots heading to the
    sink, live robots heading to the source), each (frames, robots) but the poses."""
    t = np.asarray(rec.pose_t, float)
    sel = (t >= t_from) & (t < t_to)
    n = int(rec.meta["n_robots"])  # no frames recorded (sim.pose_every_s = 0): empty arrays of the right shape
    poses = np.asarray(rec.poses, float).reshape(len(t), n, 3)[sel]
    alive = np.asarray(rec.pose_alive, bool).reshape(len(t), n)[sel]
    p0, p1 = np.asarray(source_xy, float), np.asarray(sink_xy, float)
    axis = (p1 - p0) / np.linalg.norm(p1 - p0)
    rel = poses[..., :2] - p0
    heading = np.cos(poses[..., 2]) * axis[0] + np.sin(poses[..., 2]) * axis[1]  # cos of angle to the axis
    return (poses, rel @ axis, rel @ np.array([-axis[1], axis[0]]), alive & (heading >= math.cos(ALONG_AXIS_RAD)),
            alive & (heading <= -math.cos(ALONG_AXIS_RAD)))


def lane_offsets(rec: TrialRecord, source_xy: Sequence[float], sink_xy: Sequence[float],
                 t_from: float, t_to: float) -> np.ndarray:
    """Signed lateral offsets (m, positive left of the direction of travel) of robots driving
    along the source-sink axis and away from its ends, over pose frames in [t_from, t_to)."""
    _, along, lateral, to_sink, to_source = _directed_frames(rec, source_xy, sink_xy, t_from, t_to)
    length = float(np.linalg.norm(np.asarray(sink_xy, float) - np.asarray(source_xy, float)))
    away = (along > END_MARGIN_M) & (along < length - END_MARGIN_M)
    # left of the direction of travel: + offset heading to the sink, - offset heading to the source
    return np.concatenate([lateral[to_sink & away], -lateral[to_source & away]])


# time windows by name: the same for every trial, or a function of its record
Windows = Mapping[str, tuple[float, float]] | Callable[[TrialRecord], Mapping[str, tuple[float, float]]]


def _windows_of(windows: Windows, rec: TrialRecord) -> Mapping[str, tuple[float, float]]:
    """The windows for one trial: the same for all, or a function of its record."""
    return windows(rec) if callable(windows) else windows


def lane_table(records: Iterable[TrialRecord], source_xy, sink_xy, windows: Windows) -> pd.DataFrame:
    """`controller,trial,window,mean_left_m,n_frames`: per trial and window, the mean offset to the
    left of the direction of travel (the lane index)."""
    rows = []
    for rec in records:
        for name, (a, b) in _windows_of(windows, rec).items():
            x = lane_offsets(rec, source_xy, sink_xy, a, b)
            rows.append({"controller": rec.meta["controller"], "trial": int(rec.meta["trial"]), "window": name,
                         "mean_left_m": float(x.mean()) if len(x) else math.nan, "n_frames": len(x)})
    return pd.DataFrame(rows)


def traversal_table(records: Iterable[TrialRecord]) -> pd.DataFrame:
    """`traversals.csv`: `controller,trial,robot,traversal,time_s` (traversal 0 is the first)."""
    rows = []
    for rec in records:
        for robot, times in enumerate(traversal_times(rec)):
            for k, x in enumerate(times):
                rows.append((rec.meta["controller"], int(rec.meta["trial"]), robot, k, float(x)))
    return pd.DataFrame(rows, columns=["controller", "trial", "robot", "traversal", "time_s"])


def target_time_table(records: Iterable[TrialRecord]) -> pd.DataFrame:
    """`target_times.csv`: `controller,trial,arrival,time_s` (interval 0 ends at the first arrival)."""
    rows = []
    for rec in records:
        for k, x in enumerate(target_times(rec)):
            rows.append((rec.meta["controller"], int(rec.meta["trial"]), k, float(x)))
    return pd.DataFrame(rows, columns=["controller", "trial", "arrival", "time_s"])


def table_1_1_from(traversals: pd.DataFrame, targets: pd.DataFrame) -> pd.DataFrame:
    """Table 1.1 from the saved samples (the same numbers `table_1_1` gives from the records)."""
    rows = []
    for n, m in zip(TRAVERSAL_ROWS, ARRIVAL_ROWS, strict=True):
        ti = traversals.loc[traversals["traversal"] == n, "time_s"].to_numpy(float)
        tg = targets.loc[targets["arrival"] == m, "time_s"].to_numpy(float)
        rows.append({"n_traversals": n, "mean_traversal_s": ti.mean() if len(ti) else math.nan,
                     "std_traversal_s": ti.std(ddof=1) if len(ti) > 1 else math.nan, "n_robots": len(ti),
                     "m_arrivals": m, "mean_target_s": tg.mean() if len(tg) else math.nan,
                     "std_target_s": tg.std(ddof=1) if len(tg) > 1 else math.nan, "n_trials": len(tg)})
    return pd.DataFrame(rows)


def lane_windows(rec: TrialRecord) -> dict[str, tuple[float, float]]:
    """The first and the last tenth of the trial's run (its own length: a trial that ends with
    its n-th delivery ends when it does)."""
    duration_s = rec.end_s
    return {"early": (0.0, duration_s / 10.0), "late": (duration_s * 0.9, duration_s)}


def occupancy_table(records: Iterable[TrialRecord], source_xy, sink_xy, width_m: float, height_m: float,
                    windows: Windows, cell_m: float = 0.25) -> pd.DataFrame:
    """`window,direction,x_m,y_m,count`: pose frames per cell of robots driving along the axis,
    toward the sink or toward the source, summed over trials (the lane heat map)."""
    nx, ny = int(round(width_m / cell_m)), int(round(height_m / cell_m))
    records = list(records)
    names = list(dict.fromkeys(w for rec in records for w in _windows_of(windows, rec)))
    counts = {(w, d): np.zeros((nx, ny), dtype=np.int64) for w in names for d in ("to_sink", "to_source")}
    for rec in records:
        for w, (a, b) in _windows_of(windows, rec).items():
            poses, _, _, to_sink, to_source = _directed_frames(rec, source_xy, sink_xy, a, b)
            for d, mask in (("to_sink", to_sink), ("to_source", to_source)):
                xy = poses[mask][:, :2]
                ix = np.clip((xy[:, 0] / cell_m).astype(int), 0, nx - 1)
                iy = np.clip((xy[:, 1] / cell_m).astype(int), 0, ny - 1)
                np.add.at(counts[(w, d)], (ix, iy), 1)
    rows = []
    for (w, d), grid in counts.items():
        for (i, j), c in np.ndenumerate(grid):
            rows.append((w, d, (i + 0.5) * cell_m, (j + 0.5) * cell_m, int(c)))
    return pd.DataFrame(rows, columns=["window", "direction", "x_m", "y_m", "count"])
