"""What the surrogate's study reads of a run's folder (the simulator's or the surrogate's) and how
it sets runs side by side; and the model's prediction from the measured stay tasks."""

from __future__ import annotations

import math
from collections.abc import Sequence
from pathlib import Path

import pandas as pd

from tavc_cli.analysis.alike import unlike
from tavc_cli.analysis.convergence import convergence_verdict
from tavc_cli.analysis.mechanism import mechanism_summary
from tavc_cli.analysis.turn_taking import state_shares
from tavc_cli.errors import TavcError
from tavc_cli.model import core
from tavc_cli.notation import high_of
from tavc_cli.settings import from_yaml
from tavc_cli.surrogate.tasks import STAY


def run_facts(folder: Path, controller: str = "tavc") -> dict:
    """What the comparison reads of a run's folder (simulator's or surrogate's): the state
    shares, the modal state, the make-up and convergence of `controller`, its score rate in
    the stable period, and the claims' verdicts."""
    folder = Path(folder)
    states = pd.read_csv(folder / "state_time.csv", dtype={"state": str})
    mine = states[states["controller"] == controller]
    shares = state_shares(states, controller)
    out: dict = {"states": shares, "n_trials": int(mine["n_trials"].max()) if len(mine) else 0}
    out["modal_state"] = max(shares, key=shares.get) if shares else ""
    out["pct_modal"] = shares.get(out["modal_state"], math.nan)
    if (folder / "mechanism.csv").is_file():
        m = mechanism_summary(pd.read_csv(folder / "mechanism.csv"), controller)
        out.update({k: m[k] for k in ("n_stayers_high", "n_stayers_low", "n_alternators", "n_mixed", "switch_share",
                                      "regime")})
    if (folder / "convergence.csv").is_file():
        v = convergence_verdict(pd.read_csv(folder / "convergence.csv"), controller)
        out.update({k: v[k] for k in ("q_drift", "policy_changed_share", "alloc_drift", "converged")})
    stats = pd.read_csv(folder / "trial_stats.csv")
    out["value_rate_stable"] = float(stats.loc[stats["controller"] == controller, "value_rate_stable"].mean())
    if (folder / "claims.csv").is_file():
        claims = pd.read_csv(folder / "claims.csv")
        out["claims"] = " ".join(f"{r.claim_id}:{_short(r.verdict)}" for r in claims.itertuples())
    return out


def _short(verdict: str) -> str:
    return {"reproduced": "yes", "not_reproduced": "no"}.get(str(verdict), str(verdict).replace("_", " "))


def largest_difference(a: dict, b: dict) -> tuple[float, str]:
    """The largest difference, in points, between two runs' shares of one state, and the state."""
    states = sorted(set(a) | set(b))
    if not states:
        return math.nan, ""
    diffs = {s: abs(a.get(s, 0.0) - b.get(s, 0.0)) for s in states}
    worst = max(diffs, key=diffs.get)
    return diffs[worst], worst


def comparison_rows(experiment: str, horizon: str, simulator: Path | None, engines: dict[str, Path]) -> list[dict]:
    """One row per engine (the simulator first, when its run exists) of one experiment at one
    horizon; the differences are against the simulator's run."""
    rows, reference = [], None
    runs = ([("simulator", simulator)] if simulator is not None and (simulator / "state_time.csv").is_file() else [])
    if runs:
        check_beside(simulator, ((f, from_yaml(f / "config.yaml")) for f in engines.values()
                                 if (f / "config.yaml").is_file()))  # each read as it is compared
    for engine, folder in [*runs, *engines.items()]:
        if not (folder / "state_time.csv").is_file():
            continue
        facts = run_facts(folder)
        if engine == "simulator":
            reference = facts
        diff, state = largest_difference(facts["states"], reference["states"]) if reference else (math.nan, "")
        if engine == "simulator":
            state = ""  # its own reference
        rows.append({"experiment": experiment, "horizon": horizon, "engine": engine, "n_trials": facts["n_trials"],
                     "largest_diff_pts": diff, "at_state": state, "modal_state": facts["modal_state"],
                     "pct_modal": facts["pct_modal"],
                     **{k: facts.get(k, math.nan) for k in ("n_stayers_high", "n_stayers_low", "n_alternators",
                                                            "n_mixed", "switch_share", "regime", "q_drift",
                                                            "policy_changed_share", "converged",
                                                            "value_rate_stable", "claims")}})
    return rows


def check_beside(simulator: Path, runs) -> None:
    """Refuse a simulator's run set beside the surrogate's `runs` ((folder, settings) each) that
    was not made as they were: of the same experiment and events, in the same world, team,
    learner, tasks and horizon (`alike.unlike`; what computed the trials differs by design), on
    the same seed, so that trial j draws the same start in both. The study checks the settings
    it will run with before it runs; the comparison checks the runs it reads."""
    theirs = from_yaml(simulator / "config.yaml")
    for folder, ours in runs:
        if ours.experiment_name != theirs.experiment_name:
            why = f"is a run of {theirs.experiment_name} (the surrogate's: {ours.experiment_name})"
        elif ours.events != theirs.events:
            why = "ran with other events (breakdowns, value changes)"
        elif int(ours.seed) != int(theirs.seed):
            why = f"ran with another seed ({theirs.seed}; the surrogate's: {ours.seed})"
        else:
            why = unlike(ours, {}, theirs, {}).replace("(this run: ", "(the surrogate's: ")
        if why:
            raise TavcError(f"{simulator}: is no simulator's run of the surrogate's {folder}: it {why}; name the "
                            "results folder that holds the runs the study compares with (--simulator)")


def stayer_table(times, team_name: str, n_robots: int):
    """The model's c_i(n), t_i(n) table for every split of the team from the measured stay tasks
    of the make-ups without alternators: t_i the mean time of a stay task on circuit i,
    c_i = n_i / t_i."""
    table = core.CTable(2)
    frame = times.frame
    frame = frame[(frame["team"] == team_name) & (frame["kind"] == STAY)]
    for n0 in range(n_robots + 1):
        n = (n0, n_robots - n0)
        makeup = f"all:{n0}-{n_robots - n0}-0"
        cells = []
        for i in range(2):
            t = frame.loc[(frame["makeup"] == makeup) & (frame["circuit"] == i), "task_time_s"]
            mean = float(t.mean()) if len(t) else math.inf
            cells.append(core.Cell(c=0.0 if n[i] == 0 else n[i] / mean, t=mean, n_trials=len(t)))
        table.cells[n] = tuple(cells)
    return table


def predicted_state(times, team_name: str, n_robots: int, values: Sequence[float]) -> str:
    """The model's predicted state for `n_robots` robots of team `team_name` at `values`, from the
    measured stayers' task times (`stayer_table`)."""
    return core.state_label(core.predicted_split(stayer_table(times, team_name, n_robots), n_robots, values), values)


def high_share(states: dict, n_robots: int) -> float:
    """The share of robot-time on the high-value circuit, from the state shares (states ``h:l``)."""
    total = sum(states.values())
    if not total:
        return math.nan
    return sum(p * high_of(s) for s, p in states.items()) / (n_robots * total)
