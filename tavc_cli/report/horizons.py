"""The report's second horizon: the same experiments at a multiple of the chapter's durations
(`scale=converged`, saved under `<results>/converged/`), beside the chapter's durations.

The chapter's durations stay the headline; this module writes what the longer runs add:
the summary's second count, the claims' second verdicts with how the group was made, the
section on the time scale (the arithmetic of the learning rule, the horizon ladder, the
learner-side convergence measures), and each experiment's subsection at the long horizon
(its state table beside the chapter's, the mechanism, the vacancy chains, the model's
prediction beside the learners, and the figures). Everything is read from saved tables.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass, field
from pathlib import Path

import pandas as pd

from tavc_cli.analysis.claims import CLAIMS
from tavc_cli.report.mechanism import mechanism, mechanism_lines, mechanism_words, vacancy_mechanism_lines
from tavc_cli.report.text import claims_table, fmt, performance, robot_lines, state_table
from tavc_cli.settings import TavcConfig

# the claims whose chapter's mechanism is persistence: robots staying on one circuit, a vacancy
# filled by one robot that moves (section 1.5), fast robots staying on the high-value circuit (1.6)
PERSISTENCE_CLAIMS = (3, 5, 6, 7, 8, 9)
CONVERGED_DIR = "converged"


@dataclass
class Horizon:
    """One horizon's saved runs: the folder, its experiments (name -> the folder of the run
    the claims are tested on), each one's settings and state table, the per-trial tables the
    claims read, the claims, the runs that did not finish, each experiment's other runs, and
    what the report says of every run's deliveries (`text.delivery_lines`, by folder)."""

    folder: Path
    experiments: dict[str, Path]
    read: dict[str, tuple[TavcConfig, pd.DataFrame]]
    runs: dict[str, pd.DataFrame]
    claims: pd.DataFrame
    unfinished: list[Path] = field(default_factory=list)
    others: dict[str, list[Path]] = field(default_factory=dict)
    deliveries: dict[Path, list[str]] = field(default_factory=dict)

    @property
    def factor(self) -> float:
        """The horizon as a multiple of the chapter's durations (the learners' time factor)."""
        factors = {float(cfg.scale.time_factor) for cfg, _ in self.read.values()}
        return max(factors) if factors else math.nan

    @property
    def tested(self) -> pd.DataFrame:
        return self.claims[[CLAIMS[c][0] in self.runs for c in self.claims["claim_id"]]]

    @property
    def n_reproduced(self) -> int:
        return int((self.tested["verdict"] == "reproduced").sum())


def label(factor: float) -> str:
    return f"{factor:g} times the chapter's durations"


def convergence(d: Path, controller: str | None = None) -> dict | None:
    """The convergence verdict of an experiment's learners (`analysis.convergence`; by default
    the first controller of its table, the learner), or None."""
    path = d / "convergence.csv"
    if not path.is_file():
        return None
    from tavc_cli.analysis.convergence import convergence_verdict

    table = pd.read_csv(path)
    if controller is None and len(table):
        controller = str(table["controller"].iloc[0])
    if controller is None or not (table["controller"] == controller).any():
        return None
    return convergence_verdict(table, controller=controller)


def summary_lines(base: Horizon, long: Horizon | None) -> list[str]:
    """The report's opening count: claims reproduced at the chapter's durations, and at the
    long horizon with whether its learners converged."""
    n_base = f"{base.n_reproduced} of {len(base.tested)}"
    if long is None or not long.experiments:
        return []
    learners = [(name, convergence(d)) for name, d in long.experiments.items()]
    judged = [(name, v) for name, v in learners if v is not None]
    done = [name for name, v in judged if v["converged"]]
    if judged and len(done) == len(judged):
        how = "the learning rule converged in every experiment, by measures fixed before the runs"
    elif judged:
        how = (f"the learning rule converged, by measures fixed before the runs, in {len(done)} of {len(judged)} "
               "experiments: see *The time scale*")
    else:
        how = "no convergence measures saved"
    return [f"**Claims reproduced: {n_base} at the chapter's durations; {long.n_reproduced} of {len(long.tested)} "
            f"at {long.factor:g} times them ({how}).** The chapter's durations are its inputs and stay the "
            "headline; the second verdict says whether its findings hold under its own world and rule given "
            "time, and by which mechanism.", ""]


def claims_both_table(base: Horizon, long: Horizon) -> list[str]:
    """Every claim with its verdict at both horizons and how the group was made at the long one."""
    lines = [f"| claim | experiment | at the chapter's durations | p | at {long.factor:g}x | p | "
             f"how the group is made at {long.factor:g}x |", "|---|---|---|---|---|---|---|"]
    by_id = {int(r.claim_id): r for r in long.claims.itertuples()}
    for r in base.claims.itertuples():
        exp = CLAIMS[r.claim_id][0]
        verdict = r.verdict.replace("_", " ") if exp in base.runs else "not run"
        other = by_id.get(int(r.claim_id))
        verdict_long = other.verdict.replace("_", " ") if other is not None and exp in long.runs else "not run"
        m = mechanism(long.experiments[exp]) if exp in long.experiments else None
        words = mechanism_words(m)
        if other is not None and other.verdict == "reproduced" and m is not None and \
                int(r.claim_id) in PERSISTENCE_CLAIMS and m["regime"] != "persistence":
            words = f"**the test holds, but not by the chapter's persistence**; {words}"
        lines.append(f"| {r.claim_id} | {exp} | {verdict} | {fmt(r.p_value, '.3g')} | {verdict_long} | "
                     f"{fmt(other.p_value, '.3g') if other is not None else ''} | {words} |")
    return lines


def time_scale_lines(results_dir: Path, long: Horizon, model_json: Path | None) -> list[str]:
    """The section on the time scale: the rule's arithmetic, the ladder, the convergence measures."""
    cfg = next(iter(long.read.values()))[0]
    alpha, gamma = float(cfg.learner.alpha), float(cfg.learner.gamma)
    rate = alpha * (1.0 - gamma)
    task_s = _task_time_3_3(model_json)
    lines = ["## The time scale: where the chapter's learning rule converges", "",
             f"With the chapter's rule (alpha {alpha:g}, gamma {gamma:g}, epsilon-greedy with epsilon "
             f"{float(cfg.learner.epsilon):g}) the value of the action a robot takes after each task moves toward "
             f"r / (1 - gamma), twenty rewards, at a rate alpha (1 - gamma) = {rate:.3g} per task in the long run: "
             f"one e-fold takes {1 / rate:.0f} tasks"
             + (f", some {1 / rate * task_s / 3600:.1f} h at the {task_s:.0f} s a task that three robots on a "
                "circuit take in this world (`tavc model`)" if task_s else "")
             + ". The value of the other action moves only on the exploratory choices, epsilon / 2 of them. "
             "Within the chapter's 5 h the greedy policies therefore stay as the random initial tables drew "
             f"them. The second horizon runs every experiment at {long.factor:g} times the chapter's durations, "
             "convergence periods, warm-ups and event times, at the chapter's trial counts (`scale=converged`); "
             "section 1.4's trials at ten times its traversals. The baselines learn nothing, so their "
             "distribution does not depend on the horizon: they run the chapter's own schedule (the same trials "
             "as at the chapter's durations) and are compared over its stable periods.", ""]
    lines += ladder_lines(results_dir, long)
    lines += convergence_lines(long)
    return lines


def _task_time_3_3(model_json: Path | None) -> float | None:
    """Seconds per task of a robot on a circuit with three robots on each (the model's static runs)."""
    if model_json is None or not model_json.is_file():
        return None
    budget = json.loads(model_json.read_text()).get("world", {}).get("time_budget", [])
    times = [float(b["task_time_s"]) for b in budget if b.get("split") == "3:3"]
    return sum(times) / len(times) if times else None


def ladder_lines(results_dir: Path, long: Horizon) -> list[str]:
    """The ladder's figure and table, where `<long>/ladder/ladder.csv` is saved."""
    path = long.folder / "ladder" / "ladder.csv"
    if not path.is_file():
        return []
    from tavc_cli.analysis.ladder import ladder_value

    table = pd.read_csv(path)
    rel = path.parent.relative_to(results_dir)
    factors = sorted(set(table["factor"]))
    lines = ["### The horizon ladder", "",
             "initial_distribution with the same seeds at several multiples of the chapter's 5 h (`tavc ladder`; "
             "each rung's trials are the first part of the longer rungs'). The learner-side measures are fixed in "
             "`tavc_cli/analysis/convergence.py` and were written before any long run was looked at: the median "
             "relative change of a robot's Q-table over the last quarter of the run (`Q drift`), the share of "
             "robots whose greedy policy changed in that quarter, and the drift of the robots on the high-value "
             "circuit between the two halves of the stable period; converged means all three are small.", "",
             f"![the horizon ladder]({rel}/ladder.png)", "",
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
        s = get[f"claim{k}_reproduced"]
        x = float(s[f]) if f in s.index else math.nan
        word = "holds" if x == 1.0 else ("fails" if x == 0.0 else "?")
        return f"{word} ({cell(f'claim{k}_p', f, '.2g')})"

    for f in factors:
        conv = get["converged"]
        conv_word = ("yes" if float(conv[f]) == 1.0 else "no") if f in conv.index else ""
        stayers = (float(get["n_stayers_high"].get(f, math.nan)) + float(get["n_stayers_low"].get(f, math.nan)))
        lines.append(f"| {f:g}x | {hours[f]:.0f} | {cell('pct_2:4', f)} | {cell('pct_3:3', f)} ± "
                     f"{fmt(float(std33.get(f)))} | {cell('pct_4:2', f)} | {verdict(3, f)} | {verdict(5, f)} | "
                     f"{cell('q_drift', f, '.3f')} | {cell('policy_changed_share', f, '.2f')} | "
                     f"{cell('alloc_drift', f, '.2f')} | {conv_word} | {fmt(stayers)} | {cell('n_alternators', f)} |")
    rand = ladder_value(table, "random", "pct_3:3")
    theory = ladder_value(table, "theory", "pct_3:3")
    lines += ["", f"Random allocation spends {fmt(float(rand.mean()))} % of the stable period in 3:3 (the same trials "
              f"at every rung), the binomial row {fmt(float(theory.mean()))} %; the chapter's learners 44.5 % in 5 h "
              "(Table 1.2). Stayers and alternators are robots per trial in the stable period (`robots.csv`'s "
              "classes).", ""]
    return lines


def convergence_lines(long: Horizon) -> list[str]:
    """Each experiment's convergence measures at the long horizon."""
    rows = [(name, convergence(d)) for name, d in long.experiments.items()]
    rows = [(name, v) for name, v in rows if v is not None]
    if not rows:
        return []
    lines = [f"### Did the learners converge at {long.factor:g}x?", "",
             "| experiment | trials | Q drift (median) | policies changed | alloc. drift | TD error / Q | converged | "
             "trials in which no greedy policy changed from t = 0 on |",
             "|---|---|---|---|---|---|---|---|"]
    for name, v in rows:
        failed = ", ".join(v.get("failed", []))
        frozen, n = never_changed(long.experiments[name])
        lines.append(f"| {name} | {v['n_trials']} | {fmt(v['q_drift'], '.3f')} | "
                     f"{fmt(v['policy_changed_share'], '.2f')} | {fmt(v['alloc_drift'], '.2f')} | "
                     f"{fmt(v['td_error_rel'], '.3g')} | {'yes' if v['converged'] else 'no (' + failed + ')'} | "
                     f"{f'{frozen} of {n}' if n else ''} |")
    lines += ["", "Converged means the values and the allocation no longer move. A group whose greedy policies "
              "never changed converges too, where its initial tables put it: the last column tells the two apart "
              "(t = 0 is the start of the run, or the event for runs that learn before one).", ""]
    return lines


def never_changed(d: Path) -> tuple[int, int]:
    """(trials of the learner in which no robot's greedy policy changed from t = 0 on, trials
    with snapshots), from `trial_stats.csv`."""
    path = d / "trial_stats.csv"
    if not path.is_file():
        return 0, 0
    stats = pd.read_csv(path)
    if "policy_changes" not in stats or not len(stats):
        return 0, 0
    mine = stats[stats["controller"] == stats["controller"].iloc[0]]["policy_changes"].dropna()
    return int((mine == 0).sum()), len(mine)


def experiment_lines(name: str, results_dir: Path, long: Horizon, model_json: Path | None,
                     base_state: pd.DataFrame | None = None) -> list[str]:
    """An experiment's subsection at the long horizon: the chapter's table beside ours, the
    learners' convergence, how the group is made, the model beside the learners, the
    vacancy chains, the figures and the claims."""
    if name not in long.experiments:
        return []
    from tavc_cli.analysis.comparison import experiment_comparison
    from tavc_cli.reference import TABLES
    from tavc_cli.report.figures import experiment_figures
    from tavc_cli.report.runs import choice_lines
    from tavc_cli.report.text import run_lines, vacancy_lines

    d = long.experiments[name]
    cfg, state_time = long.read[name]
    prov = json.loads((d / "provenance.json").read_text()) if (d / "provenance.json").is_file() else {}
    lines = [f"### {name} at {label(long.factor)}", ""]
    lines += choice_lines(name, [d, *long.others.get(name, [])], results_dir)
    lines += long.deliveries.get(d, [])
    if name == "spatiotemporal":
        from tavc_cli.report.studies import spatiotemporal_lines

        body = spatiotemporal_lines(name, d, cfg, long.folder)
        lines += [*convergence_sentence(d), *(_relinked(line, results_dir, long.folder) for line in body)]
        return [*lines, *_claims_lines(name, long)]
    table = TABLES.get(name)
    lines += ["% of the stable period in each state, mean ± std over trials"
              + (f"; the chapter's Table {table} beside ours:" if table else ":"), "",
              *state_table(state_time, experiment_comparison(name, state_time)), ""]
    if name in long.runs:
        lines += [performance(long.runs[name]), ""]
    lines += convergence_sentence(d)
    lines += mechanism_lines(d)
    lines += model_lines(name, d, cfg, model_json)
    if base_state is not None and cfg.analysis.state == "circuits":
        from tavc_cli.reference import chapter_table
        from tavc_cli.viz.figures import horizon_state_figure

        stem = results_dir / "figures" / f"horizons_{name}"
        horizon_state_figure(base_state, state_time, chapter_table(table) if table else None, long.factor,
                             f"{name}: % of the stable period in each state at both horizons", stem)
        lines += [f"![{name} at both horizons](figures/{stem.name}.png)", ""]
    figures = experiment_figures(name, d, cfg, state_time, long.folder, model_json)
    lines += [_relinked(line, results_dir, long.folder) for line in figures]
    lines += robot_lines(d)
    lines += vacancy_lines(d)
    lines += vacancy_mechanism_lines(d)
    lines += _claims_lines(name, long)
    lines += run_lines(name, cfg, prov, long.claims.iloc[0:0], long.runs)  # its claims are above
    return lines


def _claims_lines(name: str, long: Horizon) -> list[str]:
    """The experiment's claims as tested at the long horizon."""
    own = long.claims[[CLAIMS[c][0] == name for c in long.claims["claim_id"]]]
    return [*claims_table(own), ""] if len(own) and name in long.runs else []


def convergence_sentence(d: Path) -> list[str]:
    """The learners' convergence measures and verdict, in a sentence."""
    v = convergence(d)
    if v is None:
        return []
    frozen, n = never_changed(d)
    text = (f"Convergence of the learners (measures fixed before the runs): Q drift over the last quarter "
            f"{fmt(v['q_drift'], '.3f')} (median over trials), greedy policies changed there for "
            f"{fmt(100 * v['policy_changed_share'], '.0f')} % of robots, the high-value circuit's robots "
            f"drifted by {fmt(v['alloc_drift'], '.2f')} between the halves of the stable period: "
            + ("**converged**" if v["converged"] else f"**not converged** ({', '.join(v['failed'])})"))
    if n and frozen * 2 >= n:
        from tavc_cli.settings import from_yaml

        if float(from_yaml(d / "config.yaml").sim.warmup_s) > 0:
            text += (f"; in {frozen} of {n} trials no robot's greedy policy changed after the event: the "
                     "policies the group had before it served after it too")
        else:
            text += (f"; but in {frozen} of {n} trials no robot's greedy policy changed at all over the whole run, "
                     "so the group settled where its initial tables put it rather than learning an allocation")
    return [text + ".", ""]


def _relinked(line: str, results_dir: Path, folder: Path) -> str:
    """A markdown line written for `folder`'s own report, its links made relative to `results_dir`."""
    rel = folder.relative_to(results_dir)
    return line.replace("](figures/", f"]({rel}/figures/")


def model_lines(name: str, d: Path, cfg: TavcConfig, model_json: Path | None) -> list[str]:
    """The model's predicted allocation beside the learners' modal state and robots on the
    high-value circuit, before the event and in the stable period after it."""
    if model_json is None or not (d / "allocation.csv").is_file():
        return []
    by_size = json.loads(model_json.read_text()).get("by_team_size", {})
    alloc = pd.read_csv(d / "allocation.csv")
    tavc = alloc[alloc["controller"] == "tavc"]
    n_end = int(cfg.team.n_robots) - len(cfg.events.breakdowns)
    conv, end = float(cfg.convergence_s), float(cfg.duration_s)
    after = tavc[(tavc["t_s"] >= conv) & (tavc["t_s"] < end)]["mean_high"].mean()
    st = pd.read_csv(d / "state_time.csv", dtype={"state": str})
    learners = st[st["controller"] == "tavc"].sort_values("mean_pct", ascending=False)
    modal = learners.iloc[0] if len(learners) else None
    pred = by_size.get(str(n_end), {}).get("predicted_state", "?")
    text = (f"The model against the learners: for {n_end} robots it predicts **{pred}** "
            f"({pred.split(':')[0] if pred != '?' else '?'} robots on the high-value circuit); in the stable "
            f"period the learners' most frequent state is {modal['state'] if modal is not None else '?'} "
            f"({fmt(modal['mean_pct']) if modal is not None else ''} %), with {fmt(after, '.2f')} robots on the "
            "high-value circuit on average")
    warm = float(cfg.sim.warmup_s)
    if warm > 0:
        n_start = int(cfg.team.n_robots) - sum(1 for b in cfg.events.breakdowns if float(b.time_s) < 0)
        window = min(warm, end - conv)
        before = tavc[(tavc["t_s"] >= -window) & (tavc["t_s"] < 0)]["mean_high"].mean()
        pred_before = by_size.get(str(n_start), {}).get("predicted_state", "?")
        text += (f"; before the event ({n_start} robots, the model: {pred_before}) "
                 f"{fmt(before, '.2f')} over the last {window:,.0f} s")
    return [text + ".", ""]

