"""How a group of learners is made, read alike from a simulator's run and from the model that
knows turn-taking, and that model's prediction.

A group is read over the measured stretch of its stable period (`trial_stats.stable_from`):
its regime (`mechanism.mechanism_summary`: persistence, turn-taking or mixed), the robots on the
high-value circuit (the run's `allocation.csv`), and its modal state, the state the group spent
most of that stretch in (`state_time.csv`).

The model that knows turn-taking predicts from two runs of its own, neither of which is fitted
to the learners it is checked against. The chapter's learning rule runs on the surrogate, its
tasks drawn from those static robots complete in each make-up of the world being predicted
(`surrogate.tasks`): where those learners end up is the basin the measured rewards lead to from
random tables, and gives the regime and the robots on the high-value circuit. The modal state
of a group that takes turns depends on the order in which the robots circulate, which the
surrogate does not keep (it draws each task on its own); so where its learners take turns, the
modal state is that of static robots that all alternate in the simulator, where they keep their
order; elsewhere it is the surrogate learners' own. Pure functions of saved tables.
"""

from __future__ import annotations

import math

import numpy as np
import pandas as pd

from tavc_cli.analysis.mechanism import TURN_TAKING, mechanism_summary
from tavc_cli.notation import STATE_PREFIX, column_state


def state_shares(state_time: pd.DataFrame, controller: str) -> dict[str, float]:
    """`controller`'s mean share (%) of the measured stretch in each state, from a run's
    `state_time` table, in the table's order."""
    mine = state_time[state_time["controller"] == controller]
    return dict(zip(mine["state"], mine["mean_pct"], strict=True))


def modal_state(state_time: pd.DataFrame, controller: str) -> tuple[str, float]:
    """The state `controller`'s groups spent most of the measured stretch in and its mean share
    (%), the first in the table's order on a tie; ("", NaN) where the table has no such rows."""
    mine = state_time[state_time["controller"] == controller]
    if mine.empty:
        return "", math.nan
    i = int(mine["mean_pct"].to_numpy().argmax())
    return str(mine["state"].iloc[i]), float(mine["mean_pct"].iloc[i])


ALTERNATOR = "alternate"  # the static alternators' controller in their run's tables (`learner=alternate`)
RESAMPLES = 2000  # `modal_support`'s resamples of a run's trials
# the learners' horizon, times a run's scale: where the chapter's rule converges in today's world; the turn-taking
# model's learners run there, and its checks are the learners' runs there
HORIZON = 40.0
FIRM = 0.9  # a run's trials name its modal state firmly where it is modal in this share of `modal_support`'s
# resamples (docs/readings.md: fixed before the team-size checks in a reading were run)


def modal_support(trial_stats: pd.DataFrame, state: str, controller: str = "tavc", draws: int = RESAMPLES,
                  seed: int = 0) -> float:
    """How firmly a run's trials make `state` the modal state of `controller`'s groups: the share
    of `draws` resamples of its trials (drawn with replacement, from a generator seeded with
    `seed`, so the same tables give the same share) in which `state` has the largest mean share of
    the measured stretch (`trial_stats.csv`'s `pct_<state>` columns, whose means are
    `state_time.csv`'s; the first in the table's order on a tie, as `modal_state` picks). Where
    each trial settles in one state, eight trials make a modal state of two or three of them, and
    the share says how often another eight like them would name the same one. Columns that only
    other controllers' trials fill, and trials without shares, are left out. NaN where there are
    no such trials or no such state."""
    mine = trial_stats.loc[trial_stats["controller"] == controller,
                           [c for c in trial_stats.columns if column_state(c) is not None]]
    mine = mine.dropna(axis=1, how="all").dropna()
    columns = list(mine.columns)
    if STATE_PREFIX + state not in columns:
        return math.nan
    shares = mine.to_numpy(float)
    if not len(shares):
        return math.nan
    picks = np.random.default_rng(seed).integers(0, len(shares), size=(draws, len(shares)))
    means = shares[picks].mean(axis=1)
    return float((means.argmax(axis=1) == columns.index(STATE_PREFIX + state)).mean())


def robots_high(allocation: pd.DataFrame, controller: str, t_from: float, t_to: float) -> float:
    """The mean number of `controller`'s robots on the high-value circuit over [t_from, t_to)."""
    mine = allocation[(allocation["controller"] == controller) & (allocation["t_s"] >= t_from)
                      & (allocation["t_s"] < t_to)]
    return float(mine["mean_high"].mean()) if len(mine) else math.nan


def group_reading(mechanism: pd.DataFrame, allocation: pd.DataFrame, state_time: pd.DataFrame,
                  t_from: float, t_to: float, controller: str = "tavc") -> dict:
    """How `controller`'s groups were made over [t_from, t_to) of a run's stable period (its
    tables `mechanism.csv`, `allocation.csv`, `state_time.csv`): its regime, stayers and
    alternators per trial, robots on the high-value circuit, modal state and its share (%)."""
    m = mechanism_summary(mechanism, controller=controller)
    state, share = modal_state(state_time, controller)
    return {"regime": m["regime"], "stayers": m["n_stayers_high"] + m["n_stayers_low"],
            "alternators": m["n_alternators"], "robots_high": robots_high(allocation, controller, t_from, t_to),
            "modal_state": state, "modal_share_pct": share}


def prediction(learners: dict, alternators_state: tuple[str, float] | None) -> dict:
    """The model's prediction from its learners on the surrogate (`group_reading`) and, where they
    take turns, the modal state of static alternators in the simulator (`modal_state`): the
    regime and robots on the high-value circuit of the former; the modal state of the latter
    where the regime is turn-taking (``modal_from``: ``alternators``), else of the former
    (``learners``)."""
    out = dict(learners)
    out["modal_from"] = "learners"
    if learners["regime"] == TURN_TAKING:
        if alternators_state is None:
            raise ValueError("a turn-taking prediction takes its modal state from static alternators' runs")
        out["modal_state"], out["modal_share_pct"] = alternators_state
        out["modal_from"] = "alternators"
    return out
