"""The report's section on the time scale: why the learners stay where they start at the
chapter's durations (the arithmetic of the learning rule and the policies measured in the runs),
then each longer horizon: how it was run, the horizon ladder's rungs where it has a ladder, and
the learner-side convergence measures. Read from saved tables, as the rest of the report is
(`horizons` holds the horizons themselves).
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import pandas as pd

from tavc_cli import chapter
from tavc_cli.analysis.ladder import ladder_value
from tavc_cli.analysis.qvalues import policy_changes
from tavc_cli.reference import chapter_table
from tavc_cli.report.files import config_of, read_ladder
from tavc_cli.report.horizons import (
    Horizon,
    convergence,
    horizons_stem,
    never_changed,
    read_horizon,
    window_lines,
)
from tavc_cli.report.runs import LADDER
from tavc_cli.report.text import fmt
from tavc_cli.run_tables import rung_folders


def time_scale_lines(results_dir: Path, horizons: list[Horizon], model_json: Path | None) -> list[str]:
    """The section on the time scale: why the learners stay where they start at the chapter's
    durations (`stay_lines`), then each longer horizon, its ladder, its convergence measures."""
    base, longer = horizons[0], horizons[1:]
    lines = ["## The time scale: where the chapter's learning rule converges", ""]
    lines += stay_lines(results_dir, base, longer, model_json)
    for h in longer:
        scale = sorted({str(cfg.scale.name) for cfg, _ in h.read.values()})
        if scale == ["converged"]:
            how = (f"The {h.ordinal} horizon runs every experiment at {h.factor:g} times the chapter's durations, "
                   "convergence periods, warm-ups and event times, at the chapter's trial counts (`scale=converged`); "
                   "section 1.4's trials at ten times its traversals. The baselines learn nothing, so their "
                   "distribution does not depend on the horizon: they run the chapter's own schedule (the same "
                   "trials as at the chapter's durations) and are compared over its stable periods.")
        else:
            how = (f"The {h.ordinal} horizon (`{h.folder.relative_to(results_dir).as_posix()}/`) runs its experiments "
                   f"at {h.factor:g} times the chapter's durations (`scale={', scale='.join(scale)}`).")
        lines += [f"### The {h.ordinal} horizon", "", how, ""]
        lines += window_lines(h)
        lines += ladder_lines(results_dir, h)
        lines += convergence_lines(h)
    return lines


def _ladder(h: Horizon) -> Path:
    return h.folder / LADDER / "ladder.csv"


STAY_EXPERIMENT = chapter.base_case().name  # the run the arithmetic and the measured policies are read from


def stay_lines(results_dir: Path, base: Horizon, longer: list[Horizon], model_json: Path | None) -> list[str]:
    """Why the learners stay where their initial tables put them at the chapter's durations:
    the learning rule's arithmetic, every number of it read from initial_distribution's
    `config.yaml` (alpha, gamma, epsilon, the chapter's duration) and the model's `model.json`
    (seconds per task), then the greedy policies as measured in the saved tables, and where the
    figures show it."""
    run = base.experiments.get(STAY_EXPERIMENT) or next(
        (h.experiments[STAY_EXPERIMENT] for h in longer if STAY_EXPERIMENT in h.experiments), None)
    if run is None:
        return []
    cfg = config_of(run / "config.yaml")
    alpha, gamma, eps = float(cfg.learner.alpha), float(cfg.learner.gamma), float(cfg.learner.epsilon)
    rate = alpha * (1.0 - gamma)
    chapter_s = float(cfg.paper.duration_s)
    rel = run.relative_to(results_dir).as_posix()
    arithmetic = (f"The chapter's rule as the `{rel}` run read it from its `config.yaml`: alpha {alpha:g}, gamma "
                  f"{gamma:g}, epsilon-greedy choice with epsilon {eps:g}.")
    items = [f"After each task a robot's value of the action it took moves toward r / (1 - gamma) = "
             f"{1 / (1 - gamma):.3g} rewards at a rate alpha (1 - gamma) = {rate:.3g} per task: one e-fold of the "
             f"way takes 1 / {rate:.3g} = {1 / rate:.0f} tasks."]
    task_s = _task_time_3_3(model_json)
    if task_s:
        tasks = chapter_s / task_s
        model_rel = model_json.relative_to(results_dir).as_posix() if model_json.is_relative_to(results_dir) \
            else model_json.name
        items += [f"A task takes {task_s:.0f} s with three robots on each circuit (`tavc model`, `{model_rel}`): one "
                  f"e-fold takes {1 / rate:.0f} x {task_s:.0f} s = {task_s / rate / 3600:.1f} h, and the chapter's "
                  f"{chapter_s / 3600:g} h hold some {tasks:.0f} tasks a robot, {tasks * rate:.2g} e-folds.",
                  f"The value of the other action moves only on exploratory choices, epsilon / 2 = "
                  f"{100 * eps / 2:.3g} % of them: some {tasks * eps / 2:.0f} updates a robot in the chapter's "
                  f"{chapter_s / 3600:g} h."]
    else:
        items.append(f"The value of the other action moves only on exploratory choices, epsilon / 2 = "
                     f"{100 * eps / 2:.3g} % of them.")
    items.append(f"So the action a robot prefers is the one it takes, and its value is the one that moves, while the "
                 f"other's moves on one choice in {2 / eps:.0f}: within the chapter's {chapter_s / 3600:g} h a robot's "
                 "greedy policy (its preferred next circuit after each circuit) mostly stays where its random initial "
                 "table put it.")
    items += _measured_policies(results_dir, run, longer)
    # each drawn by this report from saved tables: the Q-values with the experiment's section, the
    # horizons with its sections at the longer horizons, the ladder from its ladder.csv (`ladder_lines`)
    both = [h for h in longer if STAY_EXPERIMENT in h.experiments and STAY_EXPERIMENT in base.experiments]
    figures = [(f"figures/q_values_{STAY_EXPERIMENT}.png", "the Q-values of trial 0, robot by robot",
                (run / "q_values.csv").is_file()),
               *((f"figures/{horizons_stem(STAY_EXPERIMENT, h)}.png",
                  "the states at both horizons" if len(longer) == 1 else f"the states at 1x and {h.factor:g}x", True)
                 for h in both),
               *((f"{h.folder.relative_to(results_dir).as_posix()}/figures/ladder.png", "the horizon ladder",
                  _ladder(h).is_file()) for h in longer)]
    shown = [f"[{what}]({path})" for path, what, drawn in figures if drawn]
    if shown:
        items.append("Figures: " + ", ".join(shown) + ".")
    return ["### Why the learners stay where they start in the chapter's "
            f"{chapter_s / 3600:g} h", "", arithmetic, "", *[f"- {item}" for item in items], ""]


def _task_time_3_3(model_json: Path | None) -> float | None:
    """Seconds per task of a robot on a circuit with three robots on each (the model's static runs)."""
    if model_json is None or not model_json.is_file():
        return None
    budget = json.loads(model_json.read_text()).get("world", {}).get("time_budget", [])
    times = [float(b["task_time_s"]) for b in budget if b.get("split") == "3:3"]
    return sum(times) / len(times) if times else None


def _measured_policies(results_dir: Path, run: Path, longer: list[Horizon]) -> list[str]:
    """The greedy policies as measured: robots and trials of `run` whose greedy policy never
    changed (its `q_values.csv`, `trial_stats.csv`), the ladder's share of robots whose policy
    changed in the last quarter, and each longer horizon's trials in which none changed."""
    out = []
    rel = run.relative_to(results_dir).as_posix()
    q_path = run / "q_values.csv"
    if q_path.is_file():
        q = pd.read_csv(q_path)
        q = q[q["controller"] == "tavc"]
        cols = [c for c in q.columns if c.startswith("q_")]
        n_s = len({c.split("_")[1] for c in cols})
        never = total = 0
        for _, g in q.groupby(["trial", "robot"], sort=False):
            table = g.sort_values("t_s")[cols].to_numpy(float).reshape(len(g), 1, n_s, -1)
            _, changed = policy_changes(g["t_s"].to_numpy(float), table)
            never += int(not changed.any())
            total += 1
        if total:
            out.append(f"Measured at the chapter's durations: {never} of {total} TAVC robots "
                       f"({100 * never / total:.0f} %) never changed their greedy policy over the whole run "
                       f"(`{rel}/q_values.csv`, every snapshot)")
    frozen, n = never_changed(run)
    if n:
        text = f"in {frozen} of {n} trials no robot's did (`{rel}/trial_stats.csv`)"
        out[-1:] = [f"{out[-1]}; {text}."] if out else [f"Measured at the chapter's durations: {text}."]
    elif out:
        out[-1] += "."
    for h in longer:
        out += _ladder_policies(results_dir, h)
    for h in longer:
        d = h.experiments.get(STAY_EXPERIMENT)
        frozen, n = never_changed(d) if d is not None else (0, 0)
        if n:
            out.append(f"At {h.factor:g} times the chapter's durations, in {frozen} of {n} trials no robot's "
                       f"greedy policy changed from t = 0 on (`{d.relative_to(results_dir).as_posix()}/"
                       "trial_stats.csv`).")
    return out


def _ladder_policies(results_dir: Path, h: Horizon) -> list[str]:
    """The share of robots whose greedy policy changed in the last quarter, over the ladder's rungs."""
    path = _ladder(h)
    if not path.is_file():
        return []

    share = ladder_value(read_ladder(path), "tavc", "policy_changed_share").dropna()
    if not len(share):
        return []
    top, first = float(share.idxmax()), float(share.index.min())
    return [f"The horizon ladder: the share of robots whose greedy policy changed in the last quarter of the run is "
            f"{share[first]:.2f} at {first:g}x and at most {share[top]:.2f} (at {top:g}x) "
            f"(`{path.relative_to(results_dir).as_posix()}`)."]


def ladder_lines(results_dir: Path, h: Horizon) -> list[str]:
    """The ladder's figure and table, where `<horizon>/ladder/ladder.csv` is saved."""
    path = _ladder(h)
    if not path.is_file():
        return []
    # deferred: loads matplotlib
    from tavc_cli.viz.ladder import ladder_figure

    table = read_ladder(path)
    rel = path.parent.relative_to(results_dir)
    factors = sorted(set(table["factor"]))
    # redrawn from ladder.csv with the report's figures (its bars cut at 0 and 100 %, n named)
    ladder_figure(table, h.folder / "figures" / "ladder")
    rungs = rung_folders(path.parent, factors)
    deciding = {f: rung_claims(rungs[f]) if f in rungs else None for f in factors}
    lines = ["### The horizon ladder", "",
             f"{STAY_EXPERIMENT} with the same seeds at several multiples of the chapter's 5 h (`tavc ladder`; "
             "each rung's trials are the first part of the longer rungs'). The learner-side measures are fixed in "
             "`tavc_cli/analysis/convergence.py` and were written before any long run was looked at: the median "
             "relative change of a robot's Q-table over the last quarter of the run (`Q drift`), the share of "
             "robots whose greedy policy changed in that quarter, and the drift of the robots on the high-value "
             "circuit between the two halves of the stable period; converged means all three are small.", "",
             f"![the horizon ladder]({h.folder.relative_to(results_dir).as_posix()}/figures/ladder.png)", "",
             f"(Drawn from `{rel}/ladder.csv`. The claims' p is that of the part that decides each verdict, as in "
             "the claims table above.)", "",
             "| horizon | h | 2:4 | 3:3 | 4:2 | claim 3 (p) | claim 5 (p) | Q drift | policies changed | "
             "alloc. drift | converged | stayers | alternators |",
             "|---|---|---|---|---|---|---|---|---|---|---|---|---|"]
    get = {q: ladder_value(table, "tavc", q) for q in ("pct_2:4", "pct_3:3", "pct_4:2", "claim3_p", "claim3_reproduced",
                                                       "claim5_p", "claim5_reproduced", "q_drift",
                                                       "policy_changed_share", "alloc_drift", "converged",
                                                       "n_stayers_high", "n_stayers_low", "n_alternators")}
    std33 = table[(table["controller"] == "tavc") & (table["quantity"] == "pct_3:3")].set_index("factor")["std"]
    hours = table.groupby("factor")["duration_s"].first() / 3600.0
    def cell(q: str, f: float, spec: str = ".1f") -> str:
        return fmt(float(get[q][f]), spec) if f in get[q].index else ""

    def verdict(k: int, f: float) -> str:
        own = deciding[f]
        if own is not None and k in own.index:  # tested here on the rung's own trials
            r = own.loc[k]
            word = {"reproduced": "holds", "not_reproduced": "fails"}.get(r["verdict"], "inconclusive")
            return f"{word} ({fmt(float(r['deciding_p_value']), '.2g')})"
        s = get[f"claim{k}_reproduced"]
        x = float(s[f]) if f in s.index else math.nan
        word = "holds" if x == 1.0 else ("fails" if x == 0.0 else "?")
        return f"{word} ({cell(f'claim{k}_p', f, '.2g')})"

    for f in factors:
        conv = get["converged"]
        conv_word = ("yes" if float(conv[f]) == 1.0 else "no") if f in conv.index else ""
        stayers = (float(get["n_stayers_high"].get(f, math.nan)) + float(get["n_stayers_low"].get(f, math.nan)))
        lines.append(f"| {f:g}x | {hours[f]:.0f} | {cell('pct_2:4', f)} | {cell('pct_3:3', f)} ± "
                     f"{fmt(float(std33.get(f, math.nan)))} | {cell('pct_4:2', f)} | {verdict(3, f)} | "
                     f"{verdict(5, f)} | "
                     f"{cell('q_drift', f, '.3f')} | {cell('policy_changed_share', f, '.2f')} | "
                     f"{cell('alloc_drift', f, '.2f')} | {conv_word} | {fmt(stayers)} | {cell('n_alternators', f)} |")

    rand = ladder_value(table, "random", "pct_3:3")
    theory = ladder_value(table, "theory", "pct_3:3")
    table_id = chapter.base_case().state_table
    printed = chapter_table(table_id).set_index("state").loc["3:3", "tavc_mean_pct"]
    lines += ["", f"Random allocation spends {fmt(float(rand.mean()))} % of the stable period in 3:3 (the same trials "
              f"at every rung), the binomial row {fmt(float(theory.mean()))} %; the chapter's learners "
              f"{fmt(float(printed))} % in {hours[min(factors)] / min(factors):g} h (Table {table_id}). Stayers and "
              "alternators are robots per trial in the stable period (`robots.csv`'s classes).", ""]
    return lines


def rung_claims(d: Path) -> pd.DataFrame | None:
    """The claims about the base case tested on a ladder rung's own trials, indexed by claim: the
    rung read as a horizon of its own (`horizons.read_horizon`), as every horizon's claims are;
    None where the rung's folder or its `trial_stats.csv` is not there."""
    if not (d / "trial_stats.csv").is_file() or not (d / "provenance.json").is_file():
        return None
    rung = read_horizon(d.parent, {STAY_EXPERIMENT: [d]}, [])
    own = [chapter.experiment_of(c) == STAY_EXPERIMENT for c in rung.claims["claim_id"]]
    return rung.claims[own].set_index("claim_id")


def convergence_lines(h: Horizon) -> list[str]:
    """Each experiment's convergence measures at a longer horizon."""
    rows = [(name, convergence(d)) for name, d in h.experiments.items()]
    rows = [(name, v) for name, v in rows if v is not None]
    if not rows:
        return []
    lines = [f"### Did the learners converge at {h.factor:g}x?", "",
             "| experiment | trials | Q drift (median) | policies changed | alloc. drift | TD error / Q | converged | "
             "trials in which no greedy policy changed from t = 0 on |",
             "|---|---|---|---|---|---|---|---|"]
    for name, v in rows:
        failed = ", ".join(v.get("failed", []))
        frozen, n = never_changed(h.experiments[name])
        lines.append(f"| {name} | {v['n_trials']} | {fmt(v['q_drift'], '.3f')} | "
                     f"{fmt(v['policy_changed_share'], '.2f')} | {fmt(v['alloc_drift'], '.2f')} | "
                     f"{fmt(v['td_error_rel'], '.3g')} | {'yes' if v['converged'] else 'no (' + failed + ')'} | "
                     f"{f'{frozen} of {n}' if n else ''} |")
    lines += ["", "Converged means the values and the allocation no longer move. A group whose greedy policies "
              "never changed converges too, where its initial tables put it: the last column tells the two apart "
              "(t = 0 is the start of the run, or the event for runs that learn before one).", ""]
    return lines
