"""The prose of an experiment's section of REPORT.md: its state table beside the chapter's,
performance, settling, greedy policies, robot classes, vacancy chains, the model's
prediction, its claims, and the command, seeds and versions of its run."""

from __future__ import annotations

import math
from pathlib import Path

import pandas as pd

from tavc_cli.analysis.claims import not_a_verdict, verdict_words
from tavc_cli.analysis.robots import ALTERNATOR_RATE, STAYER_SHARE, robot_summary
from tavc_cli.analysis.stay_switch import reading_name, reading_of, readings
from tavc_cli.analysis.table_schemas import Q_GAP_PREFIX
from tavc_cli.analysis.trial_stats import SETTLE_TOL
from tavc_cli.analysis.vacancy import SETTLE_TASKS, vacancy_summary
from tavc_cli.chapter import EXPERIMENTS, experiment_of
from tavc_cli.experiments.plan import RunPlan, read_plan
from tavc_cli.learning.registry import TITLES
from tavc_cli.model.allocations import MODEL_LIMIT
from tavc_cli.readers import load_json
from tavc_cli.run_checks import read_trial
from tavc_cli.settings import TavcConfig

KIND_WORDS = {"stayer": "stayers", "alternator": "alternators", "mixed": "mixed", "idle": "idle (broken down or stuck)"}


def fmt(x, spec=".1f") -> str:
    """`x` in the format `spec`; empty for a number that is missing or not finite."""
    return "" if x is None or (isinstance(x, float) and not math.isfinite(x)) else format(x, spec)


def state_table(state_time: pd.DataFrame, comparison: pd.DataFrame | None) -> list[str]:
    """Markdown: per state, the chapter's number and ours for each controller it printed."""
    ours = {(r.state, r.controller): r for r in state_time.itertuples()}
    controllers = [c for c in dict.fromkeys(state_time["controller"])]
    chapter = {}
    if comparison is not None:
        chapter = {(r.state, r.quantity): r.chapter for r in comparison.itertuples()}
    head = ["state"]
    for c in controllers:
        name = TITLES.get(c, c)
        key = "theory_pct" if c == "theory" else f"{c}_mean_pct"
        if any(q == key for _, q in chapter):
            head.append(f"{name}, chapter")
        head.append(f"{name}, ours" if chapter else name)
    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for state in dict.fromkeys(state_time["state"]):
        cells = [state]
        for c in controllers:
            r = ours.get((state, c))
            if c == "theory":
                key = "theory_pct"
                if any(q == key for _, q in chapter):
                    cells.append(fmt(chapter.get((state, key))))
                cells.append(fmt(r.mean_pct) if r is not None else "")
                continue
            mean_key, std_key = f"{c}_mean_pct", f"{c}_std_pct"
            if any(q == mean_key for _, q in chapter):
                m, s = chapter.get((state, mean_key)), chapter.get((state, std_key))
                cells.append(f"{fmt(m)} ± {fmt(s)}" if m is not None and s is not None else fmt(m))
            if r is not None:  # one trial has no spread: its mean alone
                cells.append(f"{fmt(r.mean_pct)} ± {fmt(r.std_pct)}" if math.isfinite(r.std_pct) else
                             f"{fmt(r.mean_pct)} (one trial)")
            else:
                cells.append("")
        lines.append("| " + " | ".join(cells) + " |")
    return lines


def chapter_says(text: str) -> str:
    """A claim or an experiment's description as the chapter's, not as a fact: "The chapter
    reports that ..." (the text's first letter lowered unless it starts an acronym)."""
    text = str(text or "").strip()
    if not text:
        return ""
    first = text[0].lower() if len(text) > 1 and not text[1].isupper() else text[0]
    return f"The chapter reports that {first}{text[1:]}"


def decided_by(r) -> str:
    """Which part of a claim decides its verdict (`analysis.claims.deciding`), as a table cell:
    the part's question, or why the claim could not be tested; a comparison of means says so."""
    if r.verdict == "inconclusive":
        return f"inconclusive: {getattr(r, 'not_testable_because', '') or 'see the parts'}".replace("|", "/")
    name = str(getattr(r, "deciding_test", "") or "")
    rule = str(getattr(r, "deciding_holds_if", "") or "")
    if name and rule.startswith("p >="):  # a "not different" part: a large p is what it needs
        name += f", which holds if {rule}"
    elif name and rule and not rule.startswith("p"):
        name += f" ({rule})"
    return name.replace("|", "/")


def p_cell(r) -> str:
    """A claim's p in a summary table: the deciding part's p (for a comparison of means, which
    has none, "value" and the compared value) and, in brackets, which part that is (`decided_by`)."""
    p = fmt(getattr(r, "deciding_p_value", r.p_value), ".3g")
    if not p and str(getattr(r, "deciding_holds_if", "")).startswith("a comparison of means"):
        value = fmt(getattr(r, "deciding_statistic", math.nan), ".3g")  # the compared value (Cohen's w, a gap)
        p = f"value {value}" if value else ""
    by = decided_by(r)
    return f"{p} ({by})" if p and by else (p or (f"({by})" if by else ""))


def claims_table(claims: pd.DataFrame, verdicts: bool = True) -> list[str]:
    """The claims as a table: the chapter's claim, the verdict ("would be: ..." where the run
    is below the chapter's scale: `verdicts` False), the t and p of the part that decides it and
    which part that is, then every part, and what is observed beside the verdict."""
    lines = ["| claim | verdict | t | p | decided by | what was tested |", "|---|---|---|---|---|---|"]
    for r in claims.itertuples():
        detail = str(r.detail).replace("|", "/").replace("; ", "<br>")
        seen = getattr(r, "observations", "")
        if isinstance(seen, str) and seen:
            detail += "<br>*beside the verdict:* " + seen.replace("|", "/").replace("; ", "<br>")
        t = getattr(r, "deciding_statistic", r.statistic)
        p = getattr(r, "deciding_p_value", r.p_value)
        lines.append(f"| {r.claim_id}: {chapter_says(r.claim)} | **{verdict_words(r.verdict, verdicts)}** | "
                     f"{fmt(t, '.2f')} | {fmt(p, '.3g')} | {decided_by(r)} | {detail} |")
    return lines


def performance(stats: pd.DataFrame) -> str:
    """Each controller's score per second over the stable period, mean and spread over trials."""
    parts = []
    for ctrl, g in stats.groupby("controller", sort=False):
        x = g["value_rate_stable"].dropna()
        spread = f" ± {x.std(ddof=1):.4f}" if len(x) > 1 else ""  # one trial has none
        parts.append(f"{TITLES.get(ctrl, ctrl)} {x.mean():.4f}{spread} (n = {len(x)})")
    return "score value delivered per second in the stable period: " + ", ".join(parts)


def model_lines(model_json: Path, state_time: pd.DataFrame) -> list[str]:
    """The model's prediction from `model_json` (every team size it predicts) beside the learners'
    most frequent state; nothing without a model file."""
    if not model_json.is_file():
        return []
    m = load_json(model_json, MODEL_LIMIT)  # bounded, as every file of a folder tavc reads
    tavc = state_time[state_time["controller"] == "tavc"]
    top = tavc.sort_values("mean_pct", ascending=False).iloc[0] if len(tavc) else None
    lines = [f"The model (`tavc model`, {m['measurement']['trials_per_split']} static trials per split) predicts "
             f"**{m['predicted_state']}** for {m['n_robots']} robots"]
    by = m.get("by_team_size", {})
    others = [f"{v['predicted_state']} for {k}" for k, v in by.items() if int(k) != int(m["n_robots"])]
    if others:
        lines[0] += " and " + ", ".join(others)
    lines[0] += "."
    if top is not None:
        lines.append(f"The learners' most frequent state in the stable period: {top['state']} "
                     f"({top['mean_pct']:.1f} % of it).")
    return [" ".join(lines)]


def differences(cfg: TavcConfig) -> list[str]:
    """Settings of this run that differ from the chapter's for the experiment."""
    out = []
    paper = cfg.paper
    if paper.trials is not None and cfg.trials != paper.trials:
        out.append(f"trials {cfg.trials} (the chapter: {paper.trials})")
    if paper.duration_s is not None and float(cfg.duration_s or 0) != float(paper.duration_s):
        if paper.deliveries is None:
            out.append(f"duration {float(cfg.duration_s):g} s (the chapter: {float(paper.duration_s):g} s)")
        else:  # the chapter counts the trial in deliveries; the duration only bounds it
            out.append(f"longest trial {float(cfg.duration_s):g} s (at paper scale: {float(paper.duration_s):g} s)")
    if cfg.deliveries != paper.deliveries:
        ours = "none" if cfg.deliveries is None else f"{cfg.deliveries}"
        out.append(f"deliveries per trial {ours} (the chapter: {paper.deliveries})")
    values = cfg.tasks.values
    known = EXPERIMENTS.get(cfg.experiment_name)
    chapter_values = known is None or known.learns == "tasks"  # section 1.4's one circuit has no such pair
    if values is not None and chapter_values and [float(v) for v in values] != [2200.0, 2000.0]:
        out.append(f"task values {values} (the chapter: [2200, 2000])")
    # the headline's world is today's reading of what the chapter leaves unsaid (section 1.4's one circuit is
    # its own arena, no reading)
    skip = set() if cfg.arena.name in {r["arena"] for r in readings()} else {"arena"}
    world = {k: v for k, v in reading_of(cfg).items() if k not in skip}
    today = {k: v for k, v in readings()[0].items() if k not in skip}
    if world != today:
        out.append(f"the world read as {reading_name(world)} (today's: {reading_name(today)}; docs/readings.md)")
    return out


def settle_lines(stats: pd.DataFrame, cfg: TavcConfig) -> list[str]:
    """When the trials' allocations settled, beside the chapter's convergence period."""
    if "settle_s" not in stats or not stats["settle_s"].notna().any():
        return []

    parts = []
    for ctrl, g in stats.groupby("controller", sort=False):
        x = g["settle_s"].to_numpy(float)
        done = x[pd.notna(x)]
        text = f"{TITLES.get(ctrl, ctrl)} settled in {len(done)} of {len(x)} trials"
        if len(done):
            text += f", median {pd.Series(done).median():.0f} s"
        parts.append(text)
    paper = cfg.paper.convergence_s
    lines = [f"Settling (the first {float(cfg.analysis.performance_bin_s):g} s bin after which the mean number "
            f"of robots on the high-value circuit stays within {SETTLE_TOL:g} of its stable-period mean, counted "
            "from t = 0): " + "; ".join(parts)
            + (f". The chapter took {float(paper):g} s as its convergence period." if paper else "."), ""]
    return lines + policy_lines(stats)


def policy_lines(stats: pd.DataFrame) -> list[str]:
    """When the learners' greedy policies stopped changing, and how often they changed."""
    if "policy_changes" not in stats or not stats["policy_changes"].notna().any():
        return []
    parts = []
    for ctrl, g in stats.groupby("controller", sort=False):
        changes = g["policy_changes"].dropna()
        if not len(changes):
            continue
        settle = g["policy_settle_s"].dropna()
        text = (f"{TITLES.get(ctrl, ctrl)}: in {int((changes == 0).sum())} of {len(changes)} trials no "
                f"robot's greedy policy changed at all; {changes.sum():.0f} changes in all "
                f"({changes.mean():.2f} per trial)")
        if len(settle) < len(changes):
            text += f"; still changing at the end in {len(changes) - len(settle)} trials"
        if len(settle):
            text += f"; the last change came at {settle.max():.0f} s at the latest"
        parts.append(text)
    return ["Greedy policies (a robot's best next circuit after each circuit it may have served, read from its "
            "Q-table snapshots, counted from t = 0): " + "; ".join(parts) + ".", ""]


def robot_lines(d: Path) -> list[str]:
    """How many robots per trial stayed on one circuit, alternated, or mixed (`robots.csv`)."""
    path = d / "robots.csv"
    if not path.is_file():
        return []

    parts = []
    for ctrl, kinds in robot_summary(pd.read_csv(path)).items():
        parts.append(f"{TITLES.get(ctrl, ctrl)} " + ", ".join(
            f"{v:.1f} {KIND_WORDS[k]}" for k, v in kinds.items() if v > 0))
    return [f"Robots per trial in the stable period (stayer: {STAYER_SHARE:.0%} or more of its choices on one "
            f"circuit; alternator: {ALTERNATOR_RATE:.0%} or more of its choices switch): " + "; ".join(parts) + ".", ""]


def vacancy_lines(d: Path) -> list[str]:
    """The vacancy chains of a run with an event: a summary per controller, TAVC's trials in a table."""
    path = d / "vacancy.csv"
    if not path.is_file():
        return []

    table = pd.read_csv(path)
    lines = [f"Vacancy chains. The event leaves one circuit short: the broken robot's, or the one that became "
             f"high-valued. A move counts once the robot serves its new circuit {SETTLE_TASKS} tasks running, and "
             "the first such move onto the short circuit fills it; this does not check that the circuit's count is "
             "restored, and random choices make such moves by chance (`vacancy.csv` has every trial):", ""]
    lines += [f"- {text}" for text in (vacancy_summary(table, c) for c in dict.fromkeys(table["controller"])) if text]
    tavc = table[table["controller"] == "tavc"]
    if len(tavc):
        lines += ["", "| trial | vacancy on circuit | filled by | from circuit | after (s) | moves before | chain |",
                  "|---|---|---|---|---|---|---|"]
        for r in tavc.itertuples():
            filled = bool(r.filled)
            chain = "" if pd.isna(r.chain) else r.chain
            lines.append(f"| {r.trial} | {r.vacancy_circuit} | {r.filler if filled else '-'} | "
                         f"{r.filler_from if filled else '-'} | {fmt(r.fill_delay_s, '.0f')} | "
                         f"{r.moves_before_fill} | {chain} |")
    return [*lines, ""]


def q_gap_lines(stats: pd.DataFrame) -> list[str]:
    """Mean final Q(high) - Q(low) per speed group (heterogeneous teams)."""
    cols = [c for c in stats.columns if c.startswith(Q_GAP_PREFIX)]
    tavc = stats[stats["controller"] == "tavc"]
    if len(cols) < 2 or not len(tavc):
        return []
    parts = [f"{c[len(Q_GAP_PREFIX):]} robots {tavc[c].mean():.4g} ± {fmt(tavc[c].std(ddof=1), '.2g')}"
             for c in cols]
    return ["Final Q(high) - Q(low), averaged over states and over each group's robots, mean ± std over TAVC "
            "trials: " + "; ".join(parts) + ".", ""]


def run_lines(name: str, d: Path, cfg: TavcConfig, prov: dict, claims: pd.DataFrame, runs: dict) -> list[str]:
    """An experiment's claims table, the command and provenance of its run (in folder `d`), when
    its controllers ran (its plan), and its settings that differ from the chapter's."""
    short = not_a_verdict(cfg)
    lines = [f"This run is {short}.", ""] if short else []
    own = claims[[experiment_of(c) == name for c in claims["claim_id"]]]
    if len(own) and name in runs:
        lines += [*claims_table(own, verdicts=not short), ""]
    diffs = differences(cfg)
    command = prov.get("command_line") or ["tavc", "run", f"experiment={name}"]
    if isinstance(command, list):
        command = " ".join(["tavc", *command[1:]])
    # only what decides the run's numbers: the version, commit, wall time and trials reused of
    # whoever ran it last are in its provenance.json, and a rerun of the same code and settings
    # leaves this line as it was
    learners = prov.get("learner_code") or {}  # learners from outside tavc, by their own code's digest
    theirs = "".join(f", {target}'s of digest `{v.get('digest', '?')}`" for target, v in sorted(learners.items())
                     if isinstance(v, dict))
    lines += [f"Run: `{command}`; root seed {prov.get('root_seed', cfg.seed)}; "
              f"{len(prov.get('trials', []))} trials, by tavc's code of digest `{prov.get('code_digest') or '?'}`"
              f"{theirs} (tavc's version and commit, the machine and the wall time: the run's "
              "`provenance.json`).", ""]
    lines += late_start_lines(cfg, read_plan(d, cfg))
    if diffs:
        lines += ["Differs from the chapter: " + "; ".join(diffs) + ".", ""]
    return lines


def late_start_lines(cfg: TavcConfig, plan: RunPlan) -> list[str]:
    """When the baselines started, as the run's `plan` records: where they started after the learner
    (`baseline_lead_s`), and their schedule where it is not the learner's
    (`scale.baseline_time_factor`)."""
    if len(plan.controllers) < 2:
        return []
    theirs = plan.controllers[1].schedule
    start, what = theirs.start_s - theirs.trial_warmup_s, theirs.starts_at
    learner_start = 0.0 - float(cfg.sim.warmup_s)
    names = " and ".join(TITLES.get(b.label, b.label) for b in plan.controllers[1:])
    if not plan.shared_schedule:
        return [f"The baselines ({names}) learn nothing, so their distribution does not depend on the horizon: "
                f"they ran the chapter's own schedule ({float(cfg.scale.baseline_time_factor):g} times its "
                f"durations; the learners {float(cfg.scale.time_factor):g} times), from {start:,.0f} s to "
                f"{float(theirs.duration_s):,.0f} s, and are compared over their own stable period (from "
                f"{float(theirs.convergence_s):,.0f} s); in the figures over time they are drawn as their "
                "stable-period level.", ""]
    if start <= learner_start:
        return []
    return [f"The baselines ({names}) learn nothing: their trials ran from {start:,.0f} s, "
            f"{float(cfg.baseline_lead_s):,.0f} s before {what} (`baseline_lead_s`), rather than from "
            f"{learner_start:,.0f} s as the learners', to {float(cfg.duration_s):,.0f} s; they are compared with "
            "the learners only after their start.", ""]


def delivery_lines(d: Path, prov: dict) -> list[str]:
    """One sentence where robots delivered nothing: in every trial of the run, or of one of
    its controllers. Counted from the trial records `provenance.json` lists (a damaged one is
    a `TavcError` naming it: call this before writing anything); where they are not all kept
    (results committed without `trials/`), read from the value rates of `trial_stats.csv`
    and `performance.csv` instead."""
    delivered = _delivered_by_records(d, prov)
    if delivered is None:
        return _no_value_lines(d)
    idle = [c for c, done in delivered.items() if not done]
    if not idle:
        return []
    n = {c: sum(1 for t in prov["trials"] if t["controller"] == c) for c in delivered}
    if len(idle) == len(delivered):
        names = [TITLES.get(c, c) for c in idle]
        names = ", ".join(names[:-1]) + " and " + names[-1] if len(names) > 1 else names[0]
        return [f"**No robot delivered anything in any trial of this run** ({_trials(sum(n.values()))} of {names}): "
                "the tables and figures below describe robots that never completed a task, and no claim about "
                "their allocation can be tested on them.", ""]
    return ["No robot delivered anything in any trial of "
            + " or of ".join(f"{TITLES.get(c, c)} ({_trials(n[c])})" for c in idle) + ".", ""]


def _trials(n: int) -> str:
    return f"{n} trial" if n == 1 else f"{n} trials"


def _delivered_by_records(d: Path, prov: dict) -> dict[str, bool] | None:
    """controller -> whether any of its trials has a delivery, from the records provenance.json
    lists (each controller's read until one has); None unless every record is there."""
    trials = prov.get("trials", [])
    if not trials or not all((d / t["file"]).is_file() for t in trials):
        return None

    delivered: dict[str, bool] = {}
    for t in trials:
        c = str(t["controller"])
        if not delivered.get(c):  # each record checked as the run's own (`schema.read_trial`)
            delivered[c] = len(read_trial(d, t).table("deliveries")["t_s"]) > 0
    return delivered


def _no_value_lines(d: Path) -> list[str]:
    """The sentence of `delivery_lines` from the tables: every value rate zero or empty."""
    rates = []
    if (d / "trial_stats.csv").is_file():
        stats = pd.read_csv(d / "trial_stats.csv")
        rates += [stats[c] for c in stats.columns if c.startswith("value_rate_")]
    if (d / "performance.csv").is_file():
        rates.append(pd.read_csv(d / "performance.csv")["mean"])
    values = pd.concat(rates, ignore_index=True).dropna() if rates else pd.Series(dtype=float)
    if not len(values) or (values != 0).any():
        return []
    return ["**Nothing was delivered in any trial of this run**: every value rate in its `trial_stats.csv` and "
            "`performance.csv` is zero (its trial records, which would count the deliveries, are not kept here).",
            ""]
