"""The report's section on the surrogate of the learning dynamics (`tavc surrogate --study`,
`make surrogate-study`), from the study's tables only: how far it agrees with the simulator,
where it does not and why, and what it then maps (phase diagram, convergence horizon)."""

from __future__ import annotations

import math
from pathlib import Path

import pandas as pd

from tavc_cli.analysis.mechanism import PERSISTENCE, TURN_TAKING
from tavc_cli.chapter import base_case
from tavc_cli.readers import TableSpec, read_table
from tavc_cli.report.files import read_record, there
from tavc_cli.report.text import fmt

STUDY_DIR = "surrogate"
ENGINE_WORDS = {"simulator": "simulator", "surrogate_makeup": "surrogate (make-up)",
                "surrogate_stayers": "surrogate (stayers alone)"}
FAR_PTS = 10.0  # a difference in a state's share worth naming, in points (fixed with the study)
REWRITE = "run `tavc surrogate --study` again to rewrite it"
_RUNS = ("horizon", "engine", "modal_state", "at_state", "converged", "pct_modal", "n_alternators", "largest_diff_pts")
_RUN_NUMBERS = ("pct_modal", "n_alternators", "largest_diff_pts")
# the study's tables the section reads (below the study's folder), as it reads them
TABLES = {
    "comparison.csv": TableSpec(
        columns=(*_RUNS, "experiment", "regime", "claims", "n_stayers_high", "n_stayers_low", "switch_share"),
        numbers=(*_RUN_NUMBERS, "n_stayers_high", "n_stayers_low", "switch_share"), text=("at_state", "modal_state"),
        filled=("experiment", "horizon", "engine")),
    "ladder.csv": TableSpec(columns=_RUNS, numbers=_RUN_NUMBERS, text=("at_state", "modal_state"),
                            filled=("horizon", "engine")),
    "phase.csv": TableSpec(
        columns=("engine", "horizon", "n_robots", "ratio", "n_trials", "high_share", "modal_state", "model_state",
                 "regime"),
        numbers=("n_robots", "ratio", "n_trials", "high_share"), text=("modal_state", "model_state"),
        filled=("engine", "horizon", "n_robots", "ratio", "n_trials"), counts=("n_robots", "n_trials")),
    "horizon.csv": TableSpec(columns=("parameter", "value", "factor", "horizon"),
                             numbers=("value", "factor", "horizon"), filled=("parameter", "factor")),
    "speed.csv": TableSpec(columns=("engine", "sim_s_per_wall_s"), numbers=("sim_s_per_wall_s",), filled=("engine",)),
    "tasks/task_times_summary.csv": TableSpec(columns=("team", "makeup", "n"), numbers=("n",),
                                              filled=("team", "makeup", "n"), counts=("n",)),
}


def study_tables(results_dir: Path) -> tuple[dict[str, pd.DataFrame], dict | None]:
    """The study's tables in results_dir/surrogate that the section reads (`TABLES`, by name), each
    read bounded and checked (`readers.read_table`: one line naming a damaged one), and the
    measurement its `tasks/task_times.json` records (`files.read_record`; None without one); no
    tables without its comparison.csv, which makes the section."""
    root = Path(results_dir) / STUDY_DIR
    if not there(root / "comparison.csv"):
        return {}, None
    tables = {name: read_table(root / name, spec, REWRITE) for name, spec in TABLES.items() if there(root / name)}
    record = root / "tasks" / "task_times.json"
    return tables, read_record(record, REWRITE).get("measurement", {}) if there(record) else None


def surrogate_lines(results_dir: Path) -> list[str]:
    """The section, if the study was run into results_dir/surrogate."""
    tables, measurement = study_tables(results_dir)
    if not tables:
        return []
    lines = ["## The surrogate: the learning dynamics on measured tasks", "",
             *_intro(measurement, tables.get("tasks/task_times_summary.csv")), ""]
    lines += _comparison_lines(tables["comparison.csv"])
    for name, section in (("ladder.csv", _ladder_lines), ("phase.csv", _phase_lines),
                          ("horizon.csv", _horizon_lines), ("speed.csv", _speed_lines)):
        if name in tables:
            lines += section(tables[name])
    return lines


def _intro(m: dict | None, cells: pd.DataFrame | None) -> list[str]:
    measured = ""
    if m is not None and cells is not None:
        measured = (f" The tasks were measured in {cells[['team', 'makeup']].drop_duplicates().shape[0]} make-ups of "
                    f"{cells['team'].nunique()} teams, {m.get('trials_per_makeup')} static trials each of "
                    f"{fmt(m.get('warmup_s'), 'g')} s warm-up and {fmt(m.get('measure_s'), 'g')} s measured: "
                    f"{int(cells['n'].sum()):,} tasks (`{STUDY_DIR}/tasks/task_times_summary.csv`).")
    return [
        "A labelled model beside the simulator, never in its place. The learners are the simulator's own (the same "
        "policy classes, seeds, events and records); the world is replaced by whole tasks measured in it. Each "
        "make-up of the group (per group of robots: how many stay on each circuit, how many alternate) runs with the "
        "static `alternate` controller, and a learner's task is drawn from the tasks of the make-up it is in, of its "
        "group, kind (stay or switch) and circuit. Calibrated by stayers alone, every task is drawn as a stay of the "
        "robots on its circuit: the view of the vacancy-chain model, in which a task's time depends on the robots "
        "per circuit only." + measured + " What it leaves out: where the robots are and the order in which they "
        "arrive, and the make-up changing while a task runs.",
    ]


def _comparison_lines(table: pd.DataFrame) -> list[str]:
    lines = ["### Beside the simulator", "",
             "Every experiment the surrogate serves, on the same trial counts and seeds as the simulator's runs in "
             "this folder. *Largest difference*: the largest difference in a state's share of the stable period "
             "(points), and the state. Make-up: stayers and alternators per trial in the stable period "
             "(`mechanism.csv`).", "",
             "| experiment | horizon | engine | largest difference | modal state | stayers | alternators | "
             "switching tasks | converged | claims |",
             "|---|---|---|---|---|---|---|---|---|---|"]
    for r in table.itertuples():
        diff = "" if r.engine == "simulator" else f"{fmt(r.largest_diff_pts, '.1f')} ({r.at_state})"
        stayers = (r.n_stayers_high or 0) + (r.n_stayers_low or 0)
        lines.append(f"| {r.experiment} | {r.horizon} | {ENGINE_WORDS.get(r.engine, r.engine)} | {diff} | "
                     f"{r.modal_state} ({fmt(r.pct_modal, '.1f')} %) | {fmt(stayers, '.1f')} | "
                     f"{fmt(r.n_alternators, '.1f')} | {fmt(100 * r.switch_share, '.0f')} % | "
                     f"{_yes(r.converged)} | {r.claims if isinstance(r.claims, str) else ''} |")
    lines += ["", "![the surrogate beside the simulator](surrogate/comparison.png)", ""]
    lines += _headline(table)
    lines += _disagreements(table)
    return lines


def _yes(value) -> str:
    if isinstance(value, str):
        value = value.strip().lower() == "true"
    if value is None or (isinstance(value, float) and math.isnan(value)):
        return ""
    return "yes" if value else "no"


def _headline(table: pd.DataFrame) -> list[str]:
    lines = []
    for engine in ("surrogate_makeup", "surrogate_stayers"):
        for horizon, group in table[table["engine"] == engine].groupby("horizon", sort=False):
            if not group["largest_diff_pts"].notna().any():
                continue
            worst = group.loc[group["largest_diff_pts"].idxmax()]
            lines.append(f"- {ENGINE_WORDS[engine]} at {horizon}: the largest difference from the simulator is "
                         f"{worst['largest_diff_pts']:.1f} points ({worst['experiment']}, state {worst['at_state']}); "
                         f"the median over the experiments {group['largest_diff_pts'].median():.1f}.")
    return [*lines, ""] if lines else []


def _disagreements(table: pd.DataFrame) -> list[str]:
    """Where the surrogate and the simulator part, each named with the reason its numbers point to."""
    lines = []
    for (experiment, horizon), group in table.groupby(["experiment", "horizon"], sort=False):
        sim = group[group["engine"] == "simulator"]
        if not len(sim):
            continue
        s = sim.iloc[0]
        for r in group[group["engine"] != "simulator"].itertuples():
            name = f"{experiment} at {horizon}, {ENGINE_WORDS.get(r.engine, r.engine)}"
            if r.regime != s["regime"]:
                lines.append(f"- **{name}**: the group is made differently ({r.regime}: {fmt(r.n_alternators, '.1f')} "
                             f"alternators per trial, {fmt(100 * r.switch_share, '.0f')} % of tasks switch; the "
                             f"simulator: {s['regime']}, {fmt(s['n_alternators'], '.1f')} alternators, "
                             f"{fmt(100 * s['switch_share'], '.0f')} %)." +
                             (" Calibrated by stayers alone no task is quicker for switching circuit, so nothing "
                              "rewards alternating: in the simulator it is the traffic (alternators drive one way "
                              "round the arena, a stayer against them) that makes turn-taking pay."
                              if r.engine == "surrogate_stayers" and s["regime"] == TURN_TAKING else ""))
            elif r.largest_diff_pts > FAR_PTS:
                lines.append(f"- **{name}**: the make-up agrees ({r.regime}, {fmt(r.n_alternators, '.1f')} alternators "
                             f"against {fmt(s['n_alternators'], '.1f')}) but the states differ by "
                             f"{r.largest_diff_pts:.1f} points in {r.at_state} ({r.modal_state} "
                             f"{fmt(r.pct_modal, '.1f')} % against {s['modal_state']} {fmt(s['pct_modal'], '.1f')} %)."
                             + (" When every robot alternates, which state the group is in depends on the robots' "
                                "phases: in the arena they circulate in order, so that about half of them are on "
                                "each circuit at any time; the surrogate draws every task on its own and lets the "
                                "phases drift apart. Positions and the order of arrivals, which it leaves out, "
                                "matter here." if r.regime == TURN_TAKING else ""))
            if isinstance(r.claims, str) and isinstance(s["claims"], str) and r.claims != s["claims"]:
                differ = sorted(set(r.claims.split()) - set(s["claims"].split()))
                lines.append(f"- **{name}**: claims {', '.join(differ)} against the simulator's "
                             f"{', '.join(sorted(set(s['claims'].split()) - set(r.claims.split())))}.")
    if not lines:
        return []
    return ["Where they part:", "", *lines, ""]


def _ladder_lines(table: pd.DataFrame) -> list[str]:
    lines = ["### The horizon ladder on the surrogate", "",
             f"{base_case().name} at each multiple of the chapter's 5 h, on the simulator (the ladder above) and "
             "on the surrogate by make-up, same seeds and trials.", "",
             "| horizon | engine | 3:3 modal? | modal state | alternators | converged | largest difference |",
             "|---|---|---|---|---|---|---|"]
    for r in table.itertuples():
        lines.append(f"| {r.horizon} | {ENGINE_WORDS.get(r.engine, r.engine)} | {_yes(r.modal_state == '3:3')} | "
                     f"{r.modal_state} ({fmt(r.pct_modal, '.1f')} %) | {fmt(r.n_alternators, '.1f')} | "
                     f"{_yes(r.converged)} | "
                     f"{'' if r.engine == 'simulator' else fmt(r.largest_diff_pts, '.1f') + f' ({r.at_state})'} |")
    return [*lines, ""]


def _phase_lines(table: pd.DataFrame) -> list[str]:
    sur = table[table["engine"] == "surrogate"]
    sim = table[table["engine"] == "simulator"]
    n = int(sur["n_trials"].max()) if len(sur) else 0
    lines = ["### Phase diagram: team size and value ratio", "",
             f"The learners (the chapter's rule) on the surrogate by make-up, {n} trials a cell, {base_case().name} "
             "with 2 to 10 robots and w_high / w_low from 1 to 2 (w_low = 2000), at the chapter's 5 h and at 40 "
             "times it. The model's prediction comes from the same static runs' stay tasks (t_i the mean stay, "
             "c_i = n_i / t_i). Red circles: the physical simulator at the checked points (`phase.csv`).", "",
             "![phase diagram](surrogate/phase.png)", ""]
    for horizon, group in sur.groupby("horizon", sort=False):
        agree = (group["modal_state"] == group["model_state"]).mean()
        persist = group[group["regime"] == PERSISTENCE]
        turn = group[group["regime"] == TURN_TAKING]
        lines.append(f"- {horizon}: the learners' modal state is the model's prediction in {100 * agree:.0f} % of the "
                     f"{len(group)} cells; persistence holds in {len(persist)} cells, turn-taking in {len(turn)}"
                     + (f" (persistence with {_span(persist)})" if len(persist) else "") + ".")
    for r in sim.itertuples():
        twin = sur[(sur["horizon"] == r.horizon) & (sur["n_robots"] == r.n_robots) & (sur["ratio"] == r.ratio)]
        if len(twin):
            t = twin.iloc[0]
            lines.append(f"- checked, {r.n_robots} robots, ratio {r.ratio:g}, {r.horizon}: share on the high-value "
                         f"circuit {r.high_share:.2f} in the simulator ({r.n_trials} trials, {r.regime}), "
                         f"{t['high_share']:.2f} on the surrogate ({t['regime']}).")
    return [*lines, ""]


def _span(group: pd.DataFrame) -> str:
    return (f"{int(group['n_robots'].min())} to {int(group['n_robots'].max())} robots, ratios "
            f"{group['ratio'].min():g} to {group['ratio'].max():g}")


def _horizon_lines(table: pd.DataFrame) -> list[str]:
    engine = table["engine"] if "engine" in table else pd.Series("surrogate", index=table.index)
    checked = table[engine == "simulator"]
    table = table[engine != "simulator"]
    points = table.drop_duplicates(["parameter", "value"])
    factors = sorted(table["factor"].unique())
    lines = ["### The convergence horizon", "",
             f"The first multiple of the chapter's 5 h (of {', '.join(f'{f:g}' for f in factors)}) at which the "
             "learner-side convergence measure is met (`analysis.convergence`), one parameter away from the "
             f"chapter's at a time, on the surrogate by make-up ({base_case().name}).", "",
             "| parameter | value | converged from |", "|---|---|---|"]
    for r in points.itertuples():
        value = "the chapter's" if r.parameter == "chapter" else f"{r.value:g}"
        first = f"{r.horizon:g}x" if math.isfinite(r.horizon) else f"not within {max(factors):g}x"
        lines.append(f"| {r.parameter} | {value} | {first} |")
    if len(checked):
        first = float(checked["horizon"].iloc[0])
        lines.append(f"| chapter, the physical simulator (its ladder) | the chapter's | "
                     f"{f'{first:g}x' if math.isfinite(first) else 'not within its ladder'} |")
    return [*lines, "", "![convergence horizon](surrogate/horizon.png)", ""]


def _speed_lines(table: pd.DataFrame) -> list[str]:
    by = table.groupby("engine")["sim_s_per_wall_s"].median()
    if not {"simulator", "surrogate"} <= set(by.index):
        return []
    return [f"Speed, one core: the surrogate simulates {by['surrogate']:,.0f} seconds of a trial per second, the "
            f"physical simulator {by['simulator']:,.0f} (medians over the experiments, `speed.csv`): "
            f"{by['surrogate'] / by['simulator']:.0f} times faster; a trial of 200 h takes "
            f"{720000 / by['surrogate']:.1f} s against {720000 / by['simulator']:.0f} s.", ""]
