"""The chapter's claims 1-9 as verdicts: each claim's rule (`analysis.claim_rules`) applied to the
runs, its parts made one verdict, and the part that decides it; the tables a run and the report
write of them.

The claims themselves (their experiment, the chapter's words, the rule) are entries of the
chapter's registry (`tavc_cli.chapter`); `CLAIMS` and `TESTS` hold the chapter's own, by number.

A claim is `reproduced` when every one of its parts holds, `not_reproduced` when a part
is decided against it, and `inconclusive` when no part fails but some part could not be
decided: an equivalence the trials show neither way, fewer than two trials a side, no spread
at all in the numbers a t divides by, or a run missing. Such a part says why; it never becomes
a t of plus or minus infinity with p = 0.

Which part decides a verdict, and so which p a report shows for the claim, is `deciding`.
Whether a run's verdicts are verdicts at all, given its trial count and duration beside the
chapter's, is `scale_shortfall`.
"""

from __future__ import annotations

import math
import warnings
from collections.abc import Callable, Mapping, Sequence

import pandas as pd

from tavc_cli import chapter
from tavc_cli.analysis.claim_rules import (
    CLOSE_W,
    LEARNER,
    PERFORMANCE_MARGIN,
    STATE_MARGIN_PCT,
    claim_1,
    claim_2,
    claim_3,
    claim_4,
    claim_5,
    claim_6,
    claim_7,
    claim_8,
    claim_9,
    largest_relative_increase,
    learner_under_test,
    mean_above,
    unlike_run,
)
from tavc_cli.analysis.significance import (
    ALPHA,
    IDENTICAL,
    Part,
    equivalent,
    greater,
    holm_none_differ,
    holm_some_differ,
    less,
    not_different,
    one_sample,
    paired_greater,
    paired_less,
    untestable,
)

__all__ = ["ALPHA", "CLOSE_W", "IDENTICAL", "LEARNER", "PERFORMANCE_MARGIN", "Part", "STATE_MARGIN_PCT", "claim_1",
           "claim_2", "claim_3", "claim_4", "claim_5", "claim_6", "claim_7", "claim_8", "claim_9", "equivalent",
           "greater", "holm_none_differ", "holm_some_differ", "largest_relative_increase", "learner_under_test", "less",
           "mean_above", "not_different", "one_sample", "paired_greater", "paired_less", "untestable"]

# claim id -> (experiment, the chapter's words), and claim id -> its rule, for the chapter's own
# claims (`claim_table` reads every claim of the registry, each with its rule here if it has one)
CLAIMS = {c.id: (name, c.text) for name, c in chapter.claims(own=True)}
TESTS: dict[int, Callable[..., list[Part]]] = {c.id: c.test() for _, c in chapter.claims(own=True)}
COLUMNS = ["claim_id", "claim", "verdict", "statistic", "p_value", "detail"]
# what a run's claims.csv and the report's add after COLUMNS: the observations beside each verdict
OBSERVATION_COLUMNS = ["observations"]
# tables besides trial_stats.csv that claims read, as `<experiment>/<table>` in `runs`
CLAIM_TABLES = ("traversals", "target_times", "policy", "lanes")


def verdict(parts: Sequence[Part]) -> str:
    """`reproduced`, `not_reproduced` or `inconclusive`, from the parts that are not observations."""
    parts = [p for p in parts if not p.observation]
    if any(p.holds is False for p in parts):
        return "not_reproduced"
    if any(p.holds is None for p in parts):
        return "inconclusive"
    return "reproduced"


def _distance(part: Part) -> float:
    """How far a part's p lies from the line alpha draws, on a log scale: how much its data
    would have to change to turn its result over."""
    return abs(math.log(max(part.p_value, 1e-300) / ALPHA))


def deciding(parts: Sequence[Part]) -> Part | None:
    """The part that decides the claim's verdict: the one whose statistic and p a report shows.

    A claim holds only when every part holds (an intersection), so:

    - not reproduced: each failing part alone decides it; shown is the failing part furthest
      from holding, the one whose result is hardest to turn over. For a part that needs
      p < alpha (a difference in a named direction) that is the largest p; for one that needs
      p >= alpha (no difference) the smallest; across the two kinds, the larger distance of p
      from alpha on a log scale (`_distance`). A comparison of means (no p) is shown only
      where no failing part has a p.
    - reproduced: every part is needed; shown is the one closest to failing (the largest p of
      the parts that need p < alpha, the smallest of those that need p >= alpha; the smaller
      distance across kinds), the weakest link. A comparison of means only if no part has a p.
    - `inconclusive`: the first part that could not be tested or decided (an equivalence the
      trials show neither way has the p of its two one-sided tests; an untestable part none).

    A "none differ" family over states (`holm_none_differ`) is one part, its p the Holm-
    adjusted p of its most different state: within it that state decides. Observations
    never decide."""
    parts = [p for p in parts if not p.observation]
    if not parts:
        return None
    failing = [p for p in parts if p.holds is False]
    if failing:
        tested = [p for p in failing if math.isfinite(p.p_value)]
        return max(tested, key=_distance) if tested else failing[0]
    unknown = [p for p in parts if p.holds is None]
    if unknown:
        return unknown[0]
    tested = [p for p in parts if math.isfinite(p.p_value)]
    return min(tested, key=_distance) if tested else parts[0]


# columns the report's claims.csv adds to COLUMNS (a run's own claims.csv keeps COLUMNS alone)
DECIDING_COLUMNS = ["deciding_test", "deciding_statistic", "deciding_p_value", "deciding_holds_if",
                    "not_testable_because"]
# what a part needs to hold, by its kind (`Part.kind`)
HOLDS_IF = {"differs": f"p < {ALPHA:g}", "same": f"p >= {ALPHA:g}", "means": "a comparison of means, no test",
            "equivalent": f"p < {ALPHA:g} in both one-sided tests of the margin (TOST)"}


def claim_table(runs: Mapping[str, pd.DataFrame], only_experiment: str | None = None,
                learner: str = LEARNER, apart: Mapping[int, str] | None = None) -> pd.DataFrame:
    """COLUMNS, DECIDING_COLUMNS, then OBSERVATION_COLUMNS: for claims 1-9 (those of one experiment if given), the
    verdict and every part (`claim_rows`), and the part that decides the verdict (`deciding`):
    its question, statistic and p-value, and why the claim could not be decided, if it could
    not; and the observations reported beside the verdict. `runs` as `claim_rows` takes them;
    `apart`: for a claim that compares two experiments' runs (`Claim.against`) by its id, why the
    other's run in `runs` is no comparison for its own (`alike.unlike`)."""
    rows = []
    for experiment, claim in chapter.claims():
        if only_experiment is not None and experiment != only_experiment:
            continue
        cid, text = claim.id, claim.text
        test = TESTS[cid] if cid in TESTS else claim.test()  # a claim of an experiment of the user's own
        read = {**runs, claim.against: unlike_run(apart[cid])} if apart and cid in apart else runs
        with warnings.catch_warnings():
            # scipy warns when samples are nearly identical (a state never visited in any trial);
            # the test's result says as much, and a run's output stays free of library noise
            warnings.filterwarnings("ignore", "Precision loss occurred", RuntimeWarning)
            found = test(read, learner=learner)
        parts = [p for p in found if not p.observation]
        decider = deciding(parts)
        v = verdict(parts)
        rows.append({"claim_id": cid, "claim": text, "verdict": v,
                     "statistic": parts[0].statistic, "p_value": parts[0].p_value,
                     "detail": "; ".join(p.text() for p in parts),
                     "observations": "; ".join(p.text() for p in found if p.observation),
                     "deciding_test": decider.question if decider is not None else "",
                     "deciding_statistic": decider.statistic if decider is not None else math.nan,
                     "deciding_p_value": decider.p_value if decider is not None else math.nan,
                     "deciding_holds_if": HOLDS_IF[decider.kind] if decider is not None else "",
                     "not_testable_because": (f"{decider.question}: {decider.reason}" if decider.reason
                                              else decider.question) if v == "inconclusive" else ""})
    return pd.DataFrame(rows, columns=[*COLUMNS, *DECIDING_COLUMNS, *OBSERVATION_COLUMNS])


def claim_rows(runs: Mapping[str, pd.DataFrame], only_experiment: str | None = None,
               learner: str = LEARNER, apart: Mapping[int, str] | None = None) -> pd.DataFrame:
    """`claim_id,claim,verdict,statistic,p_value,detail,observations` for claims 1-9 (those of one
    experiment if given): the table a run writes as its `claims.csv`. `runs` maps an
    experiment's name to its `trial_stats.csv` and `<experiment>/<table>` to its other tables
    the claims read (CLAIM_TABLES). statistic and p_value are the first part's (the claim's
    headline comparison); `detail` lists every part, `observations` what is reported beside
    the verdict (`Part.observation`). The part that decides each verdict
    (`claim_table`'s DECIDING_COLUMNS) rides along in the frame's ``attrs["deciding"]``
    (claim_id -> those columns), which a file written from the frame does not hold."""
    table = claim_table(runs, only_experiment, learner, apart)
    frame = table[[*COLUMNS, *OBSERVATION_COLUMNS]].copy()
    frame.attrs["deciding"] = {int(r["claim_id"]): {c: r[c] for c in DECIDING_COLUMNS}
                               for r in table.to_dict("records")}
    return frame


VERDICT_WORDS = {"reproduced": "reproduced", "not_reproduced": "not reproduced", "inconclusive": "inconclusive"}


def verdict_words(v: str, verdict_scale: bool = True) -> str:
    """A verdict as a reader reads it; for a run below the
    chapter's scale (`verdict_scale` False), what the verdict would be: "would be: ..."."""
    words = VERDICT_WORDS.get(v, str(v).replace("_", " "))
    return words if verdict_scale or v == "inconclusive" else f"would be: {words}"


def scale_shortfall(cfg) -> str:
    """Where a run falls below the chapter's scale for its experiment, in words ("6 of the
    chapter's 20 trials, 0.25 of its duration"), or "" where it does not: fewer trials than
    the chapter ran (the learners', and each baseline's where the chapter gives their own
    count), or a shorter trial (in traversals where the chapter ends its trials with them,
    section 1.4; else in seconds). Longer trials (scale=converged) are not below it; a baseline
    the run does not have is not counted. `cfg` is a run's settings (`settings.TavcConfig`)."""
    paper, out = cfg.paper, []
    baselines = [str(name) for name in cfg.baselines or []]
    for ours, theirs, who, ran in ((cfg.trials, paper.trials, "", True),
                                   (cfg.baseline_trials, paper.baseline_trials, " baseline",
                                    any(name != "static" for name in baselines)),
                                   (cfg.static_trials, paper.static_trials, " static", "static" in baselines)):
        if ran and ours is not None and theirs is not None and int(ours) < int(theirs):
            out.append(f"{int(ours)} of the chapter's {int(theirs)}{who} trials")
    if paper.deliveries is not None and cfg.deliveries is not None:
        if int(cfg.deliveries) < int(paper.deliveries):
            out.append(f"{int(cfg.deliveries)} of the chapter's {int(paper.deliveries)} traversals a trial")
    elif paper.duration_s and cfg.duration_s is not None and float(cfg.duration_s) < float(paper.duration_s):
        out.append(f"{float(cfg.duration_s) / float(paper.duration_s):.2g} of its duration")
    return ", ".join(out)


def not_a_verdict(cfg) -> str:
    """"not a verdict: scale=<name> (<shortfall>)" for a run below the chapter's scale
    (`scale_shortfall`), or ""."""
    short = scale_shortfall(cfg)
    return f"not a verdict: scale={cfg.scale.name} ({short})" if short else ""
