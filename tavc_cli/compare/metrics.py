"""The four numbers `tavc compare` reads per trial from a run folder, and their table.

- ``score_per_s``: score value delivered per second in the stable period (`trial_stats.csv`'s
  ``value_rate_stable``), the chapter's measure of group performance.
- ``predicted_state_pct``: the share of the stable period the group spent in the allocation the
  vacancy-chain model predicts for the team it then has (the model's ``by_team_size``: six robots
  3:3; five, after a breakdown, 3:2). With fast and slow robots (states by group), the model's
  count on the high-value circuit filled fastest first (3:0: the three fast robots high).
- ``fill_delay_s``: where a robot of the high-value circuit breaks down or the values swap (the
  chapter's vacancies: breakdown, value_change), the seconds from the event until a robot moves
  into the vacancy (`vacancy.csv`), cut at one window for every controller of a scenario: the
  shortest period after the event any of them ran (at scale=converged the chapter's, which the
  controllers that learn nothing run). A vacancy not filled within it counts as the whole window,
  so that the rank test orders it after every filled one.
- ``filled_pct``: 100 for a trial whose vacancy was filled within that window, else 0 (its mean:
  the share of trials).
- ``fast_high_share``: with fast and slow robots, the time-weighted share of the fast robots whose
  last task was on the high-value circuit in the stable period (random allocation: 0.5).

Each controller's trials are tested against TAVC's and against random allocation's with the
two-sided Mann-Whitney U test (rank-based: the learners' trials are often bimodal, a trial
settling in one allocation or another), and the direction given as the chance that one of its
trials is above one of theirs (`above`: U / (n m)); a controller is not tested against itself.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping
from pathlib import Path

import numpy as np
import pandas as pd
from scipy import stats

from tavc_cli.chapter import served_by
from tavc_cli.compare import FLOOR, REFERENCE
from tavc_cli.errors import TavcError
from tavc_cli.notation import STATE_PREFIX, column_state, high_of, join_counts
from tavc_cli.readers import load_yaml

METRICS = {
    "score_per_s": "score per second, stable period",
    "predicted_state_pct": "time in the model's predicted state (%)",
    "fill_delay_s": "time to fill the vacancy (s)",
    "filled_pct": "vacancy filled (% of trials)",
    "fast_high_share": "share of fast robots on the high-value circuit",
}
TRIAL_COLUMNS = ["experiment", "controller", "trial", "metric", "value"]
TABLE_COLUMNS = ["experiment", "metric", "controller", "time_factor", "n_trials", "mean", "std", "median",
                 "p_vs_tavc", "p_vs_random", "above_tavc", "above_random"]
WINDOW = "fill_window_s"  # each trial's period after its vacancy, until `cut_fill_delays` reads it


def predicted_state(config: Mapping, allocations: Mapping[str, list[int]]) -> str | None:
    """The model's allocation for the team a run has in its stable period, in the notation of
    its state tables (`analysis.states`); None when the model predicts nothing for that team."""
    members = config["team"]["members"]
    n_alive = len(members) - len(config["events"]["breakdowns"])
    counts = allocations.get(str(n_alive))
    if counts is None:
        return None
    if (config.get("analysis") or {}).get("state") != "groups":
        return join_counts(counts)
    speeds: dict[str, list[float]] = {}
    for m in members:
        speeds.setdefault(str(m["group"]), []).append(float(m["speed_mps"]))
    groups = sorted(speeds, key=lambda g: -np.mean(speeds[g]))  # fastest group first, as the tables
    high, out = counts[0], []
    for g in groups:
        take = min(high, len(speeds[g]))
        out.append(take)
        high -= take
    return join_counts(out)


def fast_share(stats_: pd.DataFrame, n_fast: int) -> np.ndarray:
    """Per trial, the time-weighted share of the `n_fast` fast robots on the high-value circuit,
    from the group states' shares (``pct_<fast>:<slow>``)."""
    total = np.zeros(len(stats_))
    for column in stats_.columns:
        state = column_state(column)
        if state is not None:
            total += stats_[column].to_numpy(float) * high_of(state)
    return total / 100.0 / n_fast


def trial_metrics(folder: Path, experiment: str, controller: str, label: str,
                  allocations: Mapping[str, list[int]]) -> pd.DataFrame:
    """`TRIAL_COLUMNS` for one controller's trials (those labelled `label`) in one run folder;
    fill delays uncut, with their windows (`cut_fill_delays`)."""
    config = load_yaml(folder / "config.yaml")
    stats_ = pd.read_csv(folder / "trial_stats.csv")
    found = sorted(set(stats_["controller"]))
    stats_ = stats_[stats_["controller"] == label].sort_values("trial")
    if stats_.empty:
        raise TavcError(f"--learners: {folder} holds no trials of {controller} (label {label}; it holds "
                        f"{', '.join(found) or 'none'})")
    rows: list[tuple[str, np.ndarray]] = [("score_per_s", stats_["value_rate_stable"].to_numpy(float))]
    state = predicted_state(config, allocations)
    if state is not None:
        column = STATE_PREFIX + state
        rows.append(("predicted_state_pct", stats_[column].to_numpy(float) if column in stats_
                     else np.zeros(len(stats_))))
    groups = [str(m["group"]) for m in config["team"]["members"]]
    if (config.get("analysis") or {}).get("state") == "groups":
        speeds = {g: float(m["speed_mps"]) for g, m in zip(groups, config["team"]["members"], strict=True)}
        fastest = max(speeds, key=speeds.get)
        rows.append(("fast_high_share", fast_share(stats_, groups.count(fastest))))
    trials = stats_["trial"].to_numpy(int)
    out = [pd.DataFrame({"experiment": experiment, "controller": controller, "trial": trials, "metric": metric,
                         "value": values}) for metric, values in rows]
    if experiment in served_by("vacancy") and (folder / "vacancy.csv").is_file():  # a vacancy on the high circuit
        out.append(_fill_delays(folder, experiment, controller, label, stats_))
    return pd.concat(out, ignore_index=True)[TRIAL_COLUMNS]


def _fill_delays(folder: Path, experiment: str, controller: str, label: str, stats_: pd.DataFrame) -> pd.DataFrame:
    """Per trial, the delay of the last event's vacancy (inf: never filled) and the period after
    that event (`WINDOW`)."""
    vacancy = pd.read_csv(folder / "vacancy.csv")
    vacancy = vacancy[vacancy["controller"] == label]
    last = vacancy.sort_values("event_t_s").groupby("trial").tail(1).set_index("trial")
    delays, windows = [], []
    for trial, duration in zip(stats_["trial"], stats_["duration_s"], strict=True):
        if trial not in last.index:
            delays.append(math.nan)
            windows.append(math.nan)
            continue
        row = last.loc[trial]
        delays.append(float(row["fill_delay_s"]) if bool(row["filled"]) else math.inf)
        windows.append(float(duration) - float(row["event_t_s"]))
    trials = stats_["trial"].to_numpy(int)
    return pd.concat([pd.DataFrame({"experiment": experiment, "controller": controller, "trial": trials,
                                    "metric": metric, "value": values})
                      for metric, values in (("fill_delay_s", delays), (WINDOW, windows))], ignore_index=True)


def cut_fill_delays(trials: pd.DataFrame) -> pd.DataFrame:
    """Every scenario's fill delays cut at one window, the shortest period after the event any
    controller ran (module docstring), and each trial's `filled_pct` within it; the windows dropped."""
    out = [trials[~trials["metric"].isin(["fill_delay_s", WINDOW])]]
    for experiment, rows in trials[trials["metric"] == WINDOW].groupby("experiment", sort=False):
        window = float(rows["value"].min())
        delays = trials[(trials["experiment"] == experiment) & (trials["metric"] == "fill_delay_s")]
        values = delays["value"].to_numpy(float)
        out.append(delays.assign(value=np.minimum(values, window)))
        out.append(delays.assign(metric="filled_pct", value=np.where(np.isnan(values), math.nan,
                                                                     100.0 * (values <= window))))
    frame = pd.concat(out, ignore_index=True)
    return frame[TRIAL_COLUMNS]


def above(a: np.ndarray, b: np.ndarray) -> float:
    """The chance that a trial of `a` is above one of `b`, ties counting half (the Mann-Whitney U
    over n_a n_b: 0.5 when neither side is above the other)."""
    a, b = a[np.isfinite(a)], b[np.isfinite(b)]
    if not len(a) or not len(b):
        return math.nan
    return float(((a[:, None] > b[None, :]).sum() + 0.5 * (a[:, None] == b[None, :]).sum()) / (len(a) * len(b)))


def rank_test(a: np.ndarray, b: np.ndarray) -> float:
    """Two-sided Mann-Whitney U p-value; NaN when either side has fewer than two trials."""
    a, b = a[np.isfinite(a)], b[np.isfinite(b)]
    if len(a) < 2 or len(b) < 2:
        return math.nan
    if np.ptp(np.concatenate([a, b])) == 0:
        return 1.0  # every trial the same: nothing tells them apart
    return float(stats.mannwhitneyu(a, b, alternative="two-sided").pvalue)


def comparison_table(trials: pd.DataFrame, time_factors: Mapping[str, float]) -> pd.DataFrame:
    """`TABLE_COLUMNS`: per scenario, metric and controller, the trials' spread and the tests
    against TAVC and random (`rank_test`). `time_factors`: each controller's multiple of the
    chapter's durations."""
    rows = []
    for (experiment, metric), group in trials.groupby(["experiment", "metric"], sort=False):
        by = {c: g["value"].to_numpy(float) for c, g in group.groupby("controller", sort=False)}
        for controller, values in by.items():
            finite = values[np.isfinite(values)]
            rows.append({
                "experiment": experiment, "metric": metric, "controller": controller,
                "time_factor": time_factors.get(controller, math.nan), "n_trials": len(finite),
                "mean": finite.mean() if len(finite) else math.nan,
                "std": finite.std(ddof=1) if len(finite) > 1 else math.nan,
                "median": float(np.median(finite)) if len(finite) else math.nan,
                "p_vs_tavc": rank_test(values, by[REFERENCE]) if controller != REFERENCE and REFERENCE in by
                else math.nan,
                "p_vs_random": rank_test(values, by[FLOOR]) if controller != FLOOR and FLOOR in by else math.nan,
                "above_tavc": above(values, by[REFERENCE]) if controller != REFERENCE and REFERENCE in by
                else math.nan,
                "above_random": above(values, by[FLOOR]) if controller != FLOOR and FLOOR in by else math.nan,
            })
    return pd.DataFrame(rows, columns=TABLE_COLUMNS)


def order(frame: pd.DataFrame, experiments: Iterable[str], controllers: Iterable[str]) -> pd.DataFrame:
    """Rows in the order scenarios, metrics and controllers were given."""
    rank_e = {e: i for i, e in enumerate(experiments)}
    rank_m = {m: i for i, m in enumerate(METRICS)}
    rank_c = {c: i for i, c in enumerate(controllers)}
    key = frame.apply(lambda r: (rank_e.get(r["experiment"], 99), rank_m.get(r["metric"], 99),
                                 rank_c.get(r["controller"], 99)), axis=1)
    return frame.loc[key.sort_values(kind="stable").index].reset_index(drop=True)
