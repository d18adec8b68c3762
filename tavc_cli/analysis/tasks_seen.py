"""The tasks the learners made, by the group's make-up at their choice, beside the tasks the
surrogate draws for the same make-up.

The turn-taking model's learners (the surrogate) draw each task from static robots held to
their roles: a switching task from robots that alternate on every task, in step with the
others. A learner that stays and switches only when it explores joins the other circuit at a
moment of its own. `seen_tasks` measures what the simulator's learners met: every delivered
task of the measured stretch (from `from_share` of the trial on), by the robots on circuit 0
once the chooser had chosen (`on_0`, the chooser counted), the kind of task (stay: the circuit
the robot last served; switch: the other) and its circuit; the mean task time and the means of
its waiting and avoiding. `seen_switches` then gives the surrogate's task table with each
switching task of a make-up with one switcher moved to the learners' mean in the state that
make-up makes (a diagnostic of the model, never its input: the learners' runs are what it is
checked against).
"""

from __future__ import annotations

from collections.abc import Iterable

import numpy as np
import pandas as pd

from tavc_cli.experiments.records import TrialRecord

STAY, SWITCH = "stay", "switch"
SEEN_COLUMNS = ["on_0", "kind", "circuit", "n", "task_s", "wait_s", "avoid_s"]


def delivered_choices(c: dict, d: dict, n: int) -> np.ndarray:
    """For every delivery of the table `d` (in its order), the row of the choice in `c` that
    began its task: a robot's k-th delivery, by time, ends the task of its k-th choice, by time
    (choices at one time taken in robot order); -1 for a delivery with no choice to pair."""
    out = np.full(len(d["t_s"]), -1, dtype=np.int64)
    order = np.lexsort((c["robot"], c["t_s"]))
    for robot in range(n):
        chose = order[c["robot"][order] == robot]
        done = np.flatnonzero(d["robot"] == robot)
        done = done[np.argsort(d["t_s"][done], kind="stable")]
        k = min(len(chose), len(done))
        out[done[:k]] = chose[:k]
    return out


def task_rows(rec: TrialRecord, from_share: float = 0.5) -> pd.DataFrame:
    """One row per task delivered from `from_share` of the trial on: `on_0`, `kind`, `circuit`,
    and its task time, waiting and avoiding. A robot's k-th delivery ends the task of its k-th
    choice; the robots counted on a circuit are those alive whose last choice took it, the
    choices of one instant (the trial's start) counted together."""
    c, d = rec.table("choices"), rec.table("deliveries")
    n = int(rec.meta["n_robots"])
    broken = rec.table("breakdowns") if "breakdowns" in rec.tables else {"t_s": np.zeros(0), "robot": np.zeros(0)}
    down = np.full(n, np.inf)  # when each robot broke down
    for t, r in zip(broken["t_s"], broken["robot"], strict=True):
        down[int(r)] = float(t)
    order = np.lexsort((c["robot"], c["t_s"]))
    current = np.full(n, -1)
    on_0 = np.zeros(len(order), dtype=np.int64)
    times = c["t_s"][order]
    for at in np.split(order, np.flatnonzero(np.diff(times)) + 1) if len(order) else []:
        current[c["robot"][at]] = c["circuit"][at]  # the choices of one instant (the start) together
        on_0[at] = int(((current == 0) & (down > float(c["t_s"][at[0]]))).sum())
    start = rec.start_s + from_share * (rec.end_s - rec.start_s)
    choice = delivered_choices(c, d, n)
    rows = []
    for j in np.lexsort((d["t_s"], d["robot"])):  # robot by robot, each in time order
        i = choice[j]
        if i < 0 or d["t_s"][j] < start:
            continue
        circuit = int(c["circuit"][i])
        rows.append((int(on_0[i]), STAY if int(c["state"][i]) == circuit else SWITCH, circuit,
                     float(d["task_time_s"][j]), float(d["wait_s"][j]) if "wait_s" in d else np.nan,
                     float(d["avoid_s"][j]) if "avoid_s" in d else np.nan))
    return pd.DataFrame(rows, columns=["on_0", "kind", "circuit", "task_s", "wait_s", "avoid_s"])


def seen_tasks(records: Iterable[TrialRecord], from_share: float = 0.5) -> pd.DataFrame:
    """`SEEN_COLUMNS`: the learners' tasks (`task_rows`) of every record, by robots on circuit 0,
    kind and circuit: how many, and their mean task time, waiting and avoiding."""
    rows = pd.concat([task_rows(rec, from_share) for rec in records], ignore_index=True)
    if not len(rows):
        return pd.DataFrame(columns=SEEN_COLUMNS)
    out = rows.groupby(["on_0", "kind", "circuit"]).agg(n=("task_s", "size"), task_s=("task_s", "mean"),
                                                        wait_s=("wait_s", "mean"), avoid_s=("avoid_s", "mean"))
    return out.reset_index()[SEEN_COLUMNS]


def seen_switches(frame: pd.DataFrame, seen: pd.DataFrame) -> pd.DataFrame:
    """The surrogate's task table (`surrogate.tasks.COLUMNS`, one group) with the switching
    tasks of every make-up with one switcher shifted by the learners' mean task in the state
    it makes (`seen_tasks`) minus the cell's own mean; cells the learners never met are kept."""
    # deferred: the surrogate's tasks module loads the simulator's compiled kernels
    from tavc_cli.surrogate.tasks import parse_makeup

    means = {(int(r.on_0), int(r.circuit)): float(r.task_s) for r in seen.itertuples() if r.kind == SWITCH}
    out = frame.copy()
    cell_mean = frame.groupby(["makeup", "kind", "circuit"])["task_time_s"].transform("mean")
    for makeup in frame["makeup"].unique():
        groups = parse_makeup(str(makeup))
        if len(groups) != 1 or groups[0][1][2] != 1:
            continue
        high = groups[0][1][0]
        for circuit in (0, 1):
            target = means.get((high + (circuit == 0), circuit))
            rows = (frame["makeup"] == makeup) & (frame["kind"] == SWITCH) & (frame["circuit"] == circuit)
            if target is not None and rows.any():
                out.loc[rows, "task_time_s"] = frame.loc[rows, "task_time_s"] + target - cell_mean[rows]
    return out
