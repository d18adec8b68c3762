"""The report's horizons: the chapter's durations (the headline), and any number of longer
ones, each a folder directly under the results folder that holds the same experiments at a
multiple of the chapter's durations (`converged/`, from `scale=converged`; `x10/`, ...:
`files.horizon_folders`).

A `Horizon` is one horizon's runs as read (`read_horizon`); this module writes what the
horizons say together: the summary's counts, the claims' verdicts at every horizon with how
the group was made, and the parts of an experiment's section that only a longer horizon has
(how its window was chosen, the learners' convergence, the model beside the learners). An
experiment's section itself is `sections`', the section on the time scale `time_scale`'s.
Everything is read from saved tables.
"""

from __future__ import annotations

import json
import math
from collections.abc import Iterable
from dataclasses import dataclass, field
from pathlib import Path

import pandas as pd

from tavc_cli import chapter
from tavc_cli.analysis.alike import claims_apart
from tavc_cli.analysis.claims import CLAIM_TABLES, claim_table, learner_under_test, not_a_verdict, verdict_words
from tavc_cli.analysis.ladder import CLAIM_CONTROLLER
from tavc_cli.analysis.mechanism import PERSISTENCE
from tavc_cli.analysis.trial_stats import stable_from
from tavc_cli.errors import TavcError
from tavc_cli.experiments.plan import RunPlan, read_plan
from tavc_cli.notation import state_counts
from tavc_cli.readers import load_json
from tavc_cli.report.files import CONVERGED_DIR, config_of, model_misfit
from tavc_cli.report.mechanism import convergence, mechanism, mechanism_words
from tavc_cli.report.runs import on_surrogate
from tavc_cli.report.text import delivery_lines, fmt, p_cell
from tavc_cli.run_provenance import made_by_of
from tavc_cli.settings import TavcConfig

# the claims whose chapter's mechanism is persistence: robots staying on one circuit, a vacancy
# filled by one robot that moves (section 1.5), fast robots staying on the high-value circuit (1.6)
PERSISTENCE_CLAIMS = (3, 5, 6, 7, 8, 9)
AT_CHAPTER = "at the chapter's durations"
_ORDINALS = ("first", "second", "third", "fourth", "fifth", "sixth", "seventh", "eighth", "ninth", "tenth")


@dataclass
class Horizon:
    """One horizon's saved runs: the folder, its experiments (name -> the folder of the run
    the claims are tested on), each one's settings and state table, the per-trial tables the
    claims read, the claims, the runs that did not finish, each experiment's other runs,
    what the report says of every run's deliveries (`text.delivery_lines`, by folder), and
    its place among the report's horizons."""

    folder: Path
    experiments: dict[str, Path]
    read: dict[str, tuple[TavcConfig, pd.DataFrame]]
    runs: dict[str, pd.DataFrame]
    claims: pd.DataFrame
    unfinished: list[Path] = field(default_factory=list)
    others: dict[str, list[Path]] = field(default_factory=dict)
    deliveries: dict[Path, list[str]] = field(default_factory=dict)
    index: int = 0  # 0: the chapter's durations; 1, 2, ...: the longer horizons by their factors

    @property
    def headline(self) -> bool:
        """Whether this is the chapter's durations, the report's headline."""
        return self.index == 0

    @property
    def ordinal(self) -> str:
        """"second" for the first longer horizon, and so on."""
        return _ORDINALS[self.index] if self.index < len(_ORDINALS) else f"{self.index + 1}th"

    @property
    def named(self) -> str:
        """The horizon in the list of runs: "at the chapter's durations", "at the second horizon"."""
        return AT_CHAPTER if self.headline else f"at the {self.ordinal} horizon"

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


def horizons_stem(name: str, h: Horizon) -> str:
    """The name of the figure of an experiment's states at the chapter's durations and at the
    longer horizon `h` (under the report's `figures/`)."""
    return f"horizons_{name}" if h.folder.name == CONVERGED_DIR else f"horizons_{name}_{h.folder.name}"


def read_horizon(folder: Path, found: dict[str, list[Path]], unfinished: list[Path], index: int = 0) -> Horizon:
    """One horizon's runs, read (`runs.finished_runs`; its folders already checked, and a
    damaged trial record that `text.delivery_lines` reads is refused here, before anything is
    written): settings, state tables, the per-trial tables the claims read, and the claims
    tested on them together, for the run of each experiment they are tested on; the other
    runs' folders beside, and what every run delivered."""
    experiments = {name: folders[0] for name, folders in found.items()}
    runs = {name: pd.read_csv(d / "trial_stats.csv") for name, d in experiments.items()
            if (d / "trial_stats.csv").is_file()}
    runs.update({f"{name}/{t}": pd.read_csv(d / f"{t}.csv") for name, d in experiments.items()
                 for t in CLAIM_TABLES if (d / f"{t}.csv").is_file()})
    read = {name: (config_of(d / "config.yaml"), pd.read_csv(d / "state_time.csv", dtype={"state": str}))
            for name, d in experiments.items()}
    at = {float(cfg.scale.time_factor): experiments[name] for name, (cfg, _) in read.items()}
    if len(at) > 1:  # the horizon's claims, and its label, are those of one horizon
        (a, run_a), (b, run_b) = sorted(at.items())[:2]
        raise TavcError(f"{folder}: its runs are at {a:g} and {b:g} times the chapter's durations ({run_a}, {run_b}); "
                        "a folder's runs are tested as one horizon: move one of them into the folder of its horizon "
                        "(converged/, x<factor>/)")
    others = {name: folders[1:] for name, folders in found.items() if len(folders) > 1}
    records = {d: load_json(d / "provenance.json") for folders in found.values() for d in folders}
    deliveries = {d: delivery_lines(d, record) for d, record in records.items()}
    learner = under_test(read_plan(experiments[name], cfg) for name, (cfg, _) in read.items())
    # claims 7 and 8 compare two experiments' runs only where they were made alike, as each run's own claims do
    apart = claims_apart({name: (cfg, made_by_of(records[experiments[name]])) for name, (cfg, _) in read.items()})
    return Horizon(folder, experiments, read, runs, claim_table(runs, learner=learner, apart=apart), unfinished,
                   others, deliveries, index)


def under_test(plans: Iterable[RunPlan]) -> str:
    """The learner the claims about learning test: the task learner every run's trials are of, its
    plan's first controller (TAVC's runs: `tavc`), else TAVC (`claims.learner_under_test`)."""
    return learner_under_test(plan.controllers[0].label for plan in plans)


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
            where = name if h.headline else f"{name} in {h.folder.name}"
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


def _how(h: Horizon) -> str:
    """Whether a longer horizon's learners converged, in words."""
    learners = [(name, convergence(d)) for name, d in h.experiments.items()]
    judged = [(name, v) for name, v in learners if v is not None]
    done = [name for name, v in judged if v["converged"]]
    if judged and len(done) == len(judged):
        return "the learning rule converged in every experiment, by measures fixed before the runs"
    if judged:
        return (f"the learning rule converged, by measures fixed before the runs, in {len(done)} of {len(judged)} "
                "experiments: see *The time scale*")
    return "no convergence measures saved"


def summary_lines(horizons: list[Horizon]) -> list[str]:
    """The report's opening count where there are longer horizons: claims reproduced at the
    chapter's durations, and at each longer horizon with whether its learners converged; "not
    a verdict" where a horizon's runs are below the chapter's scale."""
    base, longer = horizons[0], [h for h in horizons[1:] if h.experiments]
    if not longer:
        return []
    head = "Claims reproduced" if all(h.verdicts for h in [base, *longer]) else "Claims (not a verdict)"
    counts = "; ".join([count_words(base, AT_CHAPTER),
                        *(f"{count_words(h, f'at {h.factor:g} times them')} ({_how(h)})" for h in longer)])
    return [f"**{head}: {counts}.** The chapter's durations are its inputs and stay the headline; the "
            f"{'second verdict says' if len(longer) == 1 else 'other verdicts say'} whether its findings hold under "
            "its own world and rule given time, and by which mechanism.", ""]


def _column(h: Horizon, where: str) -> str:
    return where if h.verdicts else f"at scale={', scale='.join(h.scale_names())} (not a verdict)"


def experiment_cell(h: Horizon, exp: str, results_dir: Path) -> str:
    """The experiment a claim is about, with the folder of the run it was tested on where that
    is not the folder named after it in its horizon's folder."""
    d = h.experiments.get(exp)
    if d is None or d.relative_to(h.folder).as_posix() == exp:
        return exp
    return f"{exp} (`{d.relative_to(results_dir).as_posix()}`)"


def claims_by_horizon_table(horizons: list[Horizon]) -> list[str]:
    """Every claim with its verdict at each horizon, the p of the part that decides each and
    which part that is (`analysis.claims.deciding`), and how the group was made at each longer
    one."""
    base, longer = horizons[0], horizons[1:]
    head = f"| claim | experiment | {_column(base, AT_CHAPTER)} | p (the deciding part) |"
    for h in longer:
        head += (f" {_column(h, f'at {h.factor:g}x')} | p (the deciding part) | how the group is made at "
                 f"{h.factor:g}x |")
    lines = [head, "|---|---|---|---|" + "---|---|---|" * len(longer)]
    by_id = [{int(r.claim_id): r for r in h.claims.itertuples()} for h in longer]
    for r in base.claims.itertuples():
        exp = chapter.experiment_of(r.claim_id)
        verdict = verdict_words(r.verdict, base.verdicts) if exp in base.runs else "not run"
        line = f"| {r.claim_id} | {experiment_cell(base, exp, base.folder)} | {verdict} | " \
               f"{p_cell(r) if exp in base.runs else ''} |"
        for h, claims in zip(longer, by_id, strict=True):
            other = claims.get(int(r.claim_id))
            ran = other is not None and exp in h.runs
            line += (f" {verdict_words(other.verdict, h.verdicts) if ran else 'not run'} | "
                     f"{p_cell(other) if ran else ''} | {mechanism_cell(h, exp, int(r.claim_id), other)} |")
        lines.append(line)
    return lines


def mechanism_cell(h: Horizon, exp: str, claim_id: int, claim) -> str:
    """How the group of `exp` was made at `h`, beside the verdict on claim `claim_id` (its row
    `claim`, or None); flagged where the test holds but the group does not persist, the chapter's
    mechanism for the claims on learning; empty for a claim about random."""
    m = mechanism(h.experiments[exp]) if exp in h.experiments else None
    if claim_id in CLAIM_CONTROLLER:
        return ""
    words = mechanism_words(m)
    if claim is not None and claim.verdict == "reproduced" and m is not None and claim_id in PERSISTENCE_CLAIMS \
            and m["regime"] != PERSISTENCE:
        words = f"**the test holds, but not by the chapter's persistence**; {words}"
    return words


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
        if float(config_of(d / "config.yaml").sim.warmup_s) > 0:
            text += (f"; in {frozen} of {n} trials no robot's greedy policy changed after the event: the "
                     "policies the group had before it served after it too")
        else:
            text += (f"; but in {frozen} of {n} trials no robot's greedy policy changed at all over the whole run, "
                     "so the group settled where its initial tables put it rather than learning an allocation")
    return [text + ".", ""]


def model_lines(name: str, d: Path, cfg: TavcConfig, model_json: Path | None) -> list[str]:
    """The model's predicted allocation beside the learners' modal state and robots on the
    high-value circuit, before the event and in the stable period after it."""
    if model_json is None or not (d / "allocation.csv").is_file() or model_misfit(model_json, cfg):
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
    counts = state_counts(pred)
    text = (f"The model against the learners: for {n_end} robots it predicts **{pred}** "
            f"({counts[0] if counts else '?'} robots on the high-value circuit); in the stable "
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

