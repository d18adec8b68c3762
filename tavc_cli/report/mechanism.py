"""How the group is made, in the report's words: the regime (persistence, turn-taking or
mixed) and the robots of each kind, what a task that stays on a robot's circuit and one that
switches cost, whether persistence pays at those costs, and whether a vacancy after an event
was filled by a robot that moved and stayed or absorbed by robots that alternate. Read from
each run's `mechanism.csv` and `vacancy.csv`."""

from __future__ import annotations

import math
from pathlib import Path

import pandas as pd

from tavc_cli.analysis.convergence import convergence_verdict
from tavc_cli.analysis.mechanism import mechanism_summary
from tavc_cli.analysis.stay_switch import thresholds
from tavc_cli.analysis.trial_stats import stable_from
from tavc_cli.analysis.turn_taking import group_reading
from tavc_cli.learning.registry import TITLES
from tavc_cli.report.files import config_of
from tavc_cli.report.text import fmt
from tavc_cli.settings import TavcConfig


def mechanism(d: Path, controller: str = "tavc") -> dict | None:
    """How an experiment's learners' group was made in the stable period (`analysis.mechanism`), or None."""
    path = d / "mechanism.csv"
    if not path.is_file():
        return None

    table = pd.read_csv(path)
    if not ((table["controller"] == controller) & (table["window"] == "stable")).any():
        return None
    return mechanism_summary(table, controller=controller)


def read_group(folder: Path, cfg: TavcConfig, controller: str = "tavc") -> dict:
    """How `controller`'s groups were made over the measured stretch of the stable period of the
    run in `folder` (its `cfg`): `analysis.turn_taking.group_reading` of its tables (the robots
    on the high-value circuit NaN where the run has no `allocation.csv`)."""
    tables = {name: pd.read_csv(folder / f"{name}.csv", dtype={"state": str}) for name in ("mechanism", "state_time")}
    # a team of several groups has no allocation.csv (its states count each group): no robots on the high circuit
    tables["allocation"] = pd.read_csv(folder / "allocation.csv") if (folder / "allocation.csv").is_file() else \
        pd.DataFrame(columns=["t_s", "controller", "mean_high"])
    return group_reading(tables["mechanism"], tables["allocation"], tables["state_time"], stable_from(cfg),
                         float(cfg.duration_s), controller)


def mechanism_words(m: dict | None) -> str:
    """A mechanism summary in a few words: the regime and the robots of each kind per trial."""
    if m is None:
        return ""
    stayers = float(m.get("n_stayers_high", 0.0)) + float(m.get("n_stayers_low", 0.0))
    return (f"{m['regime']}: {fmt(stayers)} stayers ({fmt(m.get('n_stayers_high'))} high, "
            f"{fmt(m.get('n_stayers_low'))} low), {fmt(m.get('n_alternators'))} alternators, "
            f"{fmt(m.get('n_mixed'))} mixed per trial; {fmt(100 * float(m.get('switch_share', math.nan)), '.0f')} % "
            "of tasks switch")


def _secs(x) -> str:
    """Seconds to one decimal, or a dash where there were no such tasks."""
    return "-" if x is None or not math.isfinite(float(x)) else f"{float(x):.1f} s"


def persistence_ratio(values) -> float:
    """How much longer than a stay task a switch task must take for a robot on the low-value
    circuit to earn more per task by staying than by alternating (`analysis.stay_switch.thresholds`),
    or NaN where the values are not two positive ones."""
    try:
        return thresholds([float(v) for v in values])[0] if values is not None else math.nan
    except ValueError:
        return math.nan


def mechanism_lines(d: Path) -> list[str]:
    """How the group is made in the stable period, what stay and switch tasks cost, and
    whether persistence pays at those costs."""
    m = mechanism(d)
    if m is None:
        return []
    text = (f"How the group is made in the stable period: {mechanism_words(m)}. A task that stays on the robot's "
            f"circuit took {_secs(m.get('task_s_stay'))}, one that switches {_secs(m.get('task_s_switch'))} (of "
            f"which avoiding other robots {_secs(m.get('avoid_s_stay'))} and {_secs(m.get('avoid_s_switch'))}, "
            f"waiting for a dock {_secs(m.get('wait_s_stay'))} and {_secs(m.get('wait_s_switch'))}); the final "
            f"Q(stay) - Q(switch), over states and robots, is {fmt(m.get('q_gap_stay_switch'), '.3g')}")
    needed = math.nan
    if (d / "config.yaml").is_file():
        needed = persistence_ratio(config_of(d / "config.yaml").tasks.values)
    ratio = float(m.get("task_s_switch", math.nan)) / float(m.get("task_s_stay", math.nan))
    if math.isfinite(needed) and math.isfinite(ratio):
        text += (f". A robot on the low-value circuit earns more per task by staying than by alternating only if a "
                 f"switch task takes more than {needed:.2f} times a stay task; among these robots it took "
                 f"{ratio:.2f} times")
    others = []
    for controller in ("random", "static"):
        o = mechanism(d, controller)
        if o is not None:
            others.append(f"{TITLES.get(controller, controller)}: stay {_secs(o.get('task_s_stay'))}, "
                          f"switch {_secs(o.get('task_s_switch'))}")
    if others:
        text += " (" + "; ".join(others) + ")"
    return [text + ".", ""]


def vacancy_mechanism_lines(d: Path) -> list[str]:
    """Whether the vacancy after the event was filled by a robot that moved and stayed (the
    chapter's vacancy chain) or absorbed by robots that alternate."""
    vac, mech = d / "vacancy.csv", d / "mechanism.csv"
    if not vac.is_file() or not mech.is_file():
        return []
    v = pd.read_csv(vac)
    m = pd.read_csv(mech)
    v = v[v["controller"] == "tavc"]
    stable = m[(m["controller"] == "tavc") & (m["window"] == "stable")].set_index("trial")
    if not len(v) or not len(stable):
        return []
    chain = absorbed = other = 0
    for r in v.itertuples():
        if r.trial not in stable.index:
            continue
        s = stable.loc[r.trial]
        live = float(s["n_stayers_high"] + s["n_stayers_low"] + s["n_alternators"] + s["n_mixed"])
        if bool(r.filled) and float(s["n_stayers_high"] + s["n_stayers_low"]) >= live / 2:
            chain += 1
        elif float(s["n_alternators"]) >= live / 2:
            absorbed += 1
        else:
            other += 1
    return [f"After the event, in {chain} of {chain + absorbed + other} TAVC trials a robot moved to the short "
            "circuit and the group kept to its circuits (most robots stayers: the chapter's vacancy chain); in "
            f"{absorbed} the group was mostly alternators, so the vacancy was absorbed by turn-taking; "
            f"{other} neither.", ""]


def convergence(d: Path, controller: str | None = None) -> dict | None:
    """The convergence verdict of an experiment's learners (`analysis.convergence`; by default
    the first controller of its table, the learner), or None."""
    path = d / "convergence.csv"
    if not path.is_file():
        return None
    table = pd.read_csv(path)
    if controller is None and len(table):
        controller = str(table["controller"].iloc[0])
    if controller is None or not (table["controller"] == controller).any():
        return None
    return convergence_verdict(table, controller=controller)
