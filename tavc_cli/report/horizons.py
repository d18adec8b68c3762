"""The report's second horizon: the same experiments at a multiple of the chapter's durations
(`scale=converged`, saved under `<results>/converged/`), beside the chapter's durations.

The chapter's durations stay the headline; this module writes what the longer runs add:
the summary's second count, the claims' second verdicts with how the group was made, and
each experiment's subsection at the long horizon
(its state table beside the chapter's, the mechanism, the vacancy chains, the model's
prediction beside the learners, and the figures). The section on the time scale is
`time_scale`'s. Everything is read from saved tables.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass, field
from pathlib import Path

import pandas as pd

from tavc_cli import chapter
from tavc_cli.analysis.claims import not_a_verdict, verdict_words
from tavc_cli.analysis.ladder import CLAIM_CONTROLLER
from tavc_cli.analysis.trial_stats import stable_from
from tavc_cli.readers import load_json
from tavc_cli.report.mechanism import mechanism, mechanism_lines, mechanism_words, vacancy_mechanism_lines
from tavc_cli.report.text import claims_table, fmt, p_cell, performance, robot_lines, state_table
from tavc_cli.settings import TavcConfig

# the claims whose chapter's mechanism is persistence: robots staying on one circuit, a vacancy
# filled by one robot that moves (section 1.5), fast robots staying on the high-value circuit (1.6)
PERSISTENCE_CLAIMS = (3, 5, 6, 7, 8, 9)
CONVERGED_DIR = "converged"
AT_CHAPTER = "at the chapter's durations"


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
        """The claims whose experiment was run at this horizon."""
        return self.claims[[chapter.experiment_of(c) in self.runs for c in self.claims["claim_id"]]]

    @property
    def n_reproduced(self) -> int:
        """How many of the tested claims are reproduced."""
        return int((self.tested["verdict"] == "reproduced").sum())

    @property
    def shortfalls(self) -> dict[str, str]:
        """experiment -> "not a verdict: scale=... (...)" for each run the claims are tested on
        that is below the chapter's scale (`analysis.claims.not_a_verdict`)."""
        from tavc_cli.report.runs import on_surrogate

        out = {name: not_a_verdict(cfg) for name, (cfg, _) in self.read.items()}
        for name, d in self.experiments.items():
            if on_surrogate(d):  # a model's answer, whatever its scale
                out[name] = (f"not a verdict: scale={self.read[name][0].scale.name} (computed by the surrogate of the "
                             "learning dynamics, not the physical simulator)")
        return {name: text for name, text in out.items() if text}

    @property
    def verdicts(self) -> bool:
        """Whether this horizon's claims are verdicts: every run they are tested on at least at
        the chapter's trial counts and durations."""
        return not self.shortfalls

    def scale_names(self) -> list[str]:
        """The scales (`scale.name`) of the runs below the chapter's, in order."""
        return list(dict.fromkeys(str(self.read[name][0].scale.name) for name in self.shortfalls))


def label(factor: float) -> str:
    """A horizon in words: "40 times the chapter's durations"."""
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


def not_a_verdict_lines(*horizons: Horizon | None) -> list[str]:
    """The report's first words where any run its claims are tested on is below the chapter's
    scale: "not a verdict: scale=<name>", why (the runs' trial counts and durations beside the
    chapter's, grouped where they are the same) and what a verdict takes; none otherwise."""
    found = [h for h in horizons if h is not None and not h.verdicts]
    if not found:
        return []
    scales = list(dict.fromkeys(n for h in found for n in h.scale_names()))
    why: dict[str, list[str]] = {}
    for h in found:
        for name, text in h.shortfalls.items():
            reason = text[text.index("(") + 1:-1]
            where = name if h is found[0] and h.folder == found[0].folder else f"{name} in {h.folder.name}"
            why.setdefault(reason, []).append(where)
    reasons = "; ".join(f"{', '.join(names)}: {reason}" for reason, names in why.items())
    return [f"**This report is not a verdict: scale={', scale='.join(scales)}.** The runs the claims are tested on "
            f"are not the chapter's trials on the simulator ({reasons}). The claims below say what the tests give on "
            "these runs, not whether the chapter's findings reproduce: that takes the chapter's trial counts and "
            "durations on the physical simulator (`tavc reproduce scale=paper`).", ""]


def count_words(h: Horizon, where: str) -> str:
    """A horizon's count of claims: "2 of 9 at <where>", or, below the chapter's scale, what
    it would be ("2 of 9 would be reproduced at scale=quick")."""
    if h.verdicts:
        return f"{h.n_reproduced} of {len(h.tested)} {where}"
    return f"{h.n_reproduced} of {len(h.tested)} would be reproduced at scale={', scale='.join(h.scale_names())}"


def summary_lines(base: Horizon, long: Horizon | None) -> list[str]:
    """The report's opening count: claims reproduced at the chapter's durations, and at the
    long horizon with whether its learners converged; "not a verdict" where a horizon's runs
    are below the chapter's scale."""
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
    head = "Claims reproduced" if base.verdicts and long.verdicts else "Claims (not a verdict)"
    return [f"**{head}: {count_words(base, AT_CHAPTER)}; "
            f"{count_words(long, f'at {long.factor:g} times them')} ({how}).** The chapter's durations are its "
            "inputs and stay the headline; the second verdict says whether its findings hold under its own world "
            "and rule given time, and by which mechanism.", ""]


def _column(h: Horizon, where: str) -> str:
    return where if h.verdicts else f"at scale={', scale='.join(h.scale_names())} (not a verdict)"


def experiment_cell(h: Horizon, exp: str, results_dir: Path) -> str:
    """The experiment a claim is about, with the folder of the run it was tested on where that
    is not the folder named after it."""
    d = h.experiments.get(exp)
    if d is None:
        return exp
    rel = d.relative_to(results_dir).as_posix()
    return exp if rel in (exp, f"{CONVERGED_DIR}/{exp}") else f"{exp} (`{rel}`)"


def claims_both_table(base: Horizon, long: Horizon) -> list[str]:
    """Every claim with its verdict at both horizons, the p of the part that decides each and
    which part that is (`analysis.claims.deciding`), and how the group was made at the long one."""
    lines = [f"| claim | experiment | {_column(base, AT_CHAPTER)} | p (the deciding part) | "
             f"{_column(long, f'at {long.factor:g}x')} | p (the deciding part) | how the group is made at "
             f"{long.factor:g}x |", "|---|---|---|---|---|---|---|"]
    by_id = {int(r.claim_id): r for r in long.claims.itertuples()}
    for r in base.claims.itertuples():
        exp = chapter.experiment_of(r.claim_id)
        verdict = verdict_words(r.verdict, base.verdicts) if exp in base.runs else "not run"
        other = by_id.get(int(r.claim_id))
        ran_long = other is not None and exp in long.runs
        verdict_long = verdict_words(other.verdict, long.verdicts) if ran_long else "not run"
        m = mechanism(long.experiments[exp]) if exp in long.experiments else None
        words = mechanism_words(m) if int(r.claim_id) not in CLAIM_CONTROLLER else ""  # a claim about random
        if other is not None and other.verdict == "reproduced" and m is not None and \
                int(r.claim_id) in PERSISTENCE_CLAIMS and m["regime"] != "persistence":
            words = f"**the test holds, but not by the chapter's persistence**; {words}"
        lines.append(f"| {r.claim_id} | {experiment_cell(base, exp, base.folder)} | {verdict} | "
                     f"{p_cell(r) if exp in base.runs else ''} | {verdict_long} | "
                     f"{p_cell(other) if ran_long else ''} | {words} |")
    return lines


def window_words(cfg: TavcConfig) -> str:
    """The stretch of the stable period a run's shares and rates were measured over, in words:
    its last stretch of the chapter's length, or all of it (`scale.stable_window`)."""
    start, end = stable_from(cfg), float(cfg.duration_s)
    if start > float(cfg.convergence_s):
        return f"its last {(end - start) / 3600:.3g} h, the length of the chapter's stable period"
    return f"all of it, {(end - float(cfg.convergence_s)) / 3600:.3g} h"


def window_lines(long: Horizon) -> list[str]:
    """Over which stretch of its stable period each run of the horizon was measured: spreads
    over trials and the power of every test depend on it."""
    words = {name: window_words(cfg) for name, (cfg, _) in long.read.items() if cfg.paper.deliveries is None}
    if not words:
        return []
    return ["Each run's shares and rates come from a stretch of its stable period (`scale.stable_window`): "
            + "; ".join(f"{name}, {w}" for name, w in words.items()) + ".", ""]


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
    from tavc_cli.report.figures import experiment_figures
    from tavc_cli.report.runs import choice_lines
    from tavc_cli.report.text import run_lines, vacancy_lines

    d = long.experiments[name]
    cfg, state_time = long.read[name]
    prov = load_json(d / "provenance.json") if (d / "provenance.json").is_file() else {}
    lines = [f"### {name} at {label(long.factor)}", ""]
    lines += choice_lines(name, [d, *long.others.get(name, [])], results_dir)
    lines += long.deliveries.get(d, [])
    known = chapter.EXPERIMENTS.get(name)
    if known is not None and known.learns == "behaviours":  # section 1.4's study, not a state table
        from tavc_cli.report.studies import spatiotemporal_lines

        body = spatiotemporal_lines(name, d, cfg, long.folder)
        lines += [*convergence_sentence(d), *(_relinked(line, results_dir, long.folder) for line in body)]
        return [*lines, *_claims_lines(name, long)]
    table = chapter.state_table_id(name)
    lines += [f"% of the stable period ({window_words(cfg)}) in each state, mean ± std over trials"
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
    lines += run_lines(name, d, cfg, prov, long.claims.iloc[0:0], long.runs)  # its claims are above
    return lines


def _claims_lines(name: str, long: Horizon) -> list[str]:
    """The experiment's claims as tested at the long horizon."""
    own = long.claims[[chapter.experiment_of(c) == name for c in long.claims["claim_id"]]]
    return [*claims_table(own, verdicts=name not in long.shortfalls), ""] if len(own) and name in long.runs else []


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

