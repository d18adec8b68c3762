"""The report's fixed prose: how the claims are tested, the same tests applied to the chapter's
own tables, and how the chapter's gaps are read. Worded once here, for every report."""

from __future__ import annotations

import math

from tavc_cli.analysis.chapter_checks import chapter_checks
from tavc_cli.report.text import fmt


def method_lines() -> list[str]:
    """How the claims are tested: the tests, the margins, which part's p is shown."""
    return ["", "Tests: t-tests at 90 % (alpha 0.10), each part reading a phrase of the chapter (quoted in the "
            "claim, and in docs/claims.md). Welch's one-sided for \"significantly higher\"/\"lower\" between "
            "controllers, experiments, or early and late samples (section 1.4's traversal and target times), "
            "paired one-sided within the same trials (a state against another, a period against another); "
            "\"not significantly different\" as equivalence, two one-sided tests (TOST) within the smallest "
            "difference of the same kind the chapter calls significant (2.5 points of a state's share; 3.8 % of "
            "performance), which holds when both reject, fails when a two-sided test finds a difference, and is "
            "undecided otherwise; claim 4's \"closely aligned\" as Cohen's w below 0.3, with the chapter's "
            "\"though the differences are statistically significant\" reported beside it; claim 9's relative "
            "increase and utilities compare means without a test, as the chapter does. What a claim's reading "
            "needs and the chapter does not state as a finding is reported beside the verdict, never in it. A "
            "claim holds only if every part does; the p shown is that of the part that decides the verdict, "
            "named beside it: of a claim not reproduced, the failing part furthest from holding, of a claim "
            "reproduced, the part closest to failing (where that part is a comparison of means, the value it "
            "compares, marked as a value). A part whose t cannot be computed (one trial, no spread "
            "in either sample) or an equivalence the trials show neither way leaves its claim inconclusive, "
            "unless another part decides against it. Each claim is tested on one run of its experiment: the "
            "folder named after it, else the first by name (*The runs in this folder* lists every run). The "
            "rules are in `tavc_cli/analysis/claim_rules.py`, applied by `tavc_cli/analysis/claims.py`.", ""]


def chapter_check_lines() -> list[str]:
    """The report's tests applied to the chapter's printed means, stds and trial counts."""
    lines = ["## The same tests on the chapter's own tables", "",
              "Applied to the chapter's printed means, stds and trial counts (20 TAVC and 20 random trials "
              "for Table 1.2; 20 TAVC trials for Tables 1.3-1.5 and, for Table 1.3's random column, whose count "
              "the chapter does not give, Table 1.2's 20; claim 8 is tested against Table 1.3's random, the only "
              "five-robot random run printed; 15 and 15 for Table 1.6), the tests above say whether the "
              "chapter's own numbers carry its claims (observations, reported beside a claim and not tested "
              "for it, are marked):", ""]
    for c in chapter_checks():
        verdict = "holds" if c["holds"] else ("fails" if c["holds"] is False else
                                              "undecided" if math.isfinite(c["p_value"]) else "not testable")
        numbers = (f"t = {fmt(c['statistic'], '.2f')}, p = {fmt(c['p_value'], '.3g')}"
                   if math.isfinite(c["p_value"]) else f"{c['statistic']:.3g}")
        aside = "observation, " if c.get("observation") else ""
        lines.append(f"- claim {c['claim_id']}, {aside}{c['test']}: {numbers}, **{verdict}**")
    return lines


def gaps_lines() -> list[str]:
    """How the report reads what the chapter leaves unsaid."""
    return ["## How the chapter's gaps are read", "",
            "- Layout: the sources on one long wall, the sinks in the opposite order on the other, so the two "
            "circuits cross mid-arena (a reading of the lost Figure 1.5's labels).",
            "- Unit of t in r = w / t: milliseconds (`tasks.time_unit`).",
            "- Docking: reconstructed and chosen by `tavc calibrate` from static allocations only "
            "(`conf/world/calibrated.yaml` records the choice and the search behind it).",
            "- Runs that start from a converged state learn it within the same trial first (`sim.warmup_s`).",
            "- Section 1.4 prints no learning parameters: its learners use sections 1.5/1.6's (alpha 0.1, "
            "gamma 0.95, initial Q in [-0.1, 0.1], softmax tau 0.005) with the task value 2000 and t in ms; "
            "the first bit is any bar-code in the laser's view; the state is read every control tick and a "
            "behaviour chosen when it changes (`learner.decide_on_change`).",
            "- Traversal (sink to source to sink) and target time (between arrivals at either kind of "
            "target) as section 1.4 defines them, though its Table 1.1 fits one arrival per traversal.",
            "- Table 1.6's difference columns are computed against the theory row, as every printed row is "
            "(its header names the random runs); claim 9's relative increase likewise. Its text's optimal "
            "state 0:3 is read as its table's 3:0 (all fast robots on the high-value circuit).",
            ""]
