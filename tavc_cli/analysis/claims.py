"""The chapter's claims 1-9 as tests on per-trial numbers (`trial_stats.csv`; for section 1.4,
the traversal and target-time samples, the learned policies and the lane offsets).

Each claim quotes the phrases of the chapter its parts test (`CLAIMS`; docs/claims.md by part), and
its side, test and margin follow that phrase; all were fixed here before any verdict was looked
at, and none is tuned to one (the statistics are `analysis.significance`'s):

- "significantly higher / lower / larger" between controllers or experiments: Welch's t-test,
  one-sided, the side the chapter names; within the same trials (a period against another, a
  state against another) a paired one-sided test;
- "not significantly different", "no significant difference": an equivalence test, two
  one-sided tests against a margin (TOST), never a failure to reject. The margins are the
  smallest differences of the same kind the chapter itself calls significant:
  `STATE_MARGIN_PCT` for a state's share, `PERFORMANCE_MARGIN` for performance;
- "closely aligned with this theoretical estimate" (claim 4): Cohen's w of the mean
  distribution against the binomial row below `CLOSE_W`; the chapter adds that the differences
  are significant, which is reported beside the verdict and required neither way;
- "stands out as the state with the highest relative increase", "on average, have higher
  estimated utilities" (claim 9): comparisons of means, with no test, as the chapter makes them.

Statements the claim's reading needs but the chapter does not make as findings (3:2 the most
frequent state after a breakdown; a sharp drop at the breakdown) are observations: reported
beside the verdict, never inside it.

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
from collections.abc import Callable, Iterable, Mapping, Sequence

import numpy as np
import pandas as pd

from tavc_cli.analysis.significance import (
    ALPHA,
    IDENTICAL,
    Part,
    _one_sample,
    all_equivalent,
    as_observation,
    close_to,
    equivalent,
    greater,
    holm_none_differ,
    less,
    not_different,
    one_sample,
    paired_greater,
    paired_less,
    untestable,
)
from tavc_cli.analysis.trial_stats import Q_GAP_PREFIX, STATE_PREFIX, states_of

__all__ = ["ALPHA", "IDENTICAL", "Part", "equivalent", "greater", "holm_none_differ", "less", "not_different",
           "one_sample", "paired_greater", "paired_less", "untestable"]

# The margin within which two shares of a state (% of the stable period) are the same: the smallest
# difference between two of the chapter's learners' tables that it calls significant (3:2 in Table
# 1.5 against Table 1.3, 48.7 - 46.2 points). A "not significantly different" cannot admit a
# difference the chapter elsewhere counts as one.
STATE_MARGIN_PCT = 2.5
# The same for performance, relative to the reference's mean: the one performance gain the chapter
# prints with its test, 0.81e-2 against 0.78e-2 value per second (section 1.6.3).
PERFORMANCE_MARGIN = (0.81 - 0.78) / 0.78
# "closely aligned": Cohen's w of the random runs' mean distribution against the binomial row below
# the boundary between a small and a medium departure in Cohen's (1988) convention.
CLOSE_W = 0.3

CLAIMS = {
    1: ("spatiotemporal", "all mean traversal and target times are \"lower than the ones produced by the initial "
                          "random behavior application ... by a statistically significant amount\", at every row "
                          "of Table 1.1."),
    2: ("spatiotemporal", "learned policies are \"dominated by the direct target approach behavior, but with "
                          "significant portions of the wall-following behavior\"; robots keep \"to the left "
                          "side\"; the yellow stop-rates are \"significantly lower\" than the stop-rate for "
                          "robots seen from the front and than the red and green stop-rates."),
    3: ("initial_distribution", "\"the increase in the amount of time spent in state 3 : 3 is statistically "
                                "significant\" (over random), and the time in 3:3 is \"significantly higher than "
                                "the time spent in any of the other states\"."),
    4: ("initial_distribution", "the random controllers' distribution is \"closely aligned with this theoretical "
                                "estimate\" (the binomial row), \"though the differences are statistically "
                                "significant\"."),
    5: ("initial_distribution", "the learners' performance is \"significantly higher than the performance of "
                                "random allocation\"."),
    6: ("breakdown", "after a high-circuit robot breaks down the learners keep 3:2 \"for a significantly larger "
                     "amount of time than a group of five random controllers\", and their performance is "
                     "\"significantly higher\" than random's and than a static allocation \"optimized for six "
                     "robots\"."),
    7: ("breakdown_no_vacancy", "with a low-circuit robot removed the distribution \"was not significantly "
                                "different\" from breakdown's; performance \"fell significantly when the robot "
                                "was removed\" and \"remained significantly higher\" than random's, with \"no "
                                "significant difference\" from breakdown's stable period nor between the "
                                "convergence and stable periods."),
    8: ("value_change", "after the values swap 3:2 and 4:1 are \"significantly higher\" than after breakdown; "
                        "against random the learners have \"a significantly higher value for state 3 : 2 and "
                        "significantly lower values for all other states\"; performance \"fell "
                        "significantly\", then came back to a level \"not significantly different from the "
                        "initial level\"."),
    9: ("heterogeneous", "fast robots take the high-value circuit: \"the difference in time spent in state 0 : 3 "
                         "is statistically significant\" (3:0 by the chapter's table) and it \"stands out as the "
                         "state with the highest relative increase\"; performance is \"significantly higher\" "
                         "than random's; fast robots \"have higher estimated utilities\" for the high-value "
                         "circuit, slow ones for the low, and the mean difference is \"greater for the fast "
                         "robots\"."),
}
COLUMNS = ["claim_id", "claim", "verdict", "statistic", "p_value", "detail"]
# what a run's claims.csv and the report's add after COLUMNS: the observations beside each verdict
OBSERVATION_COLUMNS = ["observations"]
# tables besides trial_stats.csv that claims read, as `<experiment>/<table>` in `runs`
CLAIM_TABLES = ("traversals", "target_times", "policy", "lanes")


LEARNER = "tavc"  # the controller whose trials the claims about learning test, unless told another


def learner_under_test(labels: Iterable[str]) -> str:
    """The learner the claims about learning test among the task learners of some runs: the one
    they all share, unless it learns nothing (random, the static allocations, the model's: the
    claims compare a learner with those), else TAVC."""
    from tavc_cli.learning.registry import LEARNS_NOTHING

    found = set(labels) - {"behaviour"}
    if len(found) == 1 and not found & set(LEARNS_NOTHING):
        return found.pop()
    return LEARNER


def who(learner: str) -> str:
    """The learner under test as the claims' parts name it: TAVC, else its label."""
    return "TAVC" if learner == LEARNER else learner


def _ctrl(stats_: pd.DataFrame, controller: str) -> pd.DataFrame:
    return stats_[stats_["controller"] == controller]


def _share(frame: pd.DataFrame, state: str) -> np.ndarray:
    col = STATE_PREFIX + state
    return frame[col].to_numpy(float) if col in frame else np.full(len(frame), np.nan)


def _mean(x) -> float:
    """The mean of the finite values in x, or NaN where there are none."""
    x = np.asarray(x, dtype=float)
    x = x[np.isfinite(x)]
    return float(x.mean()) if len(x) else math.nan


def _missing(what: str) -> Part:
    return Part(what, math.nan, math.nan, None)


def _most_frequent(frame: pd.DataFrame, state: str, label: str) -> list[Part]:
    return [paired_greater(f"{label}: {state} above {s}", _share(frame, state), _share(frame, s))
            for s in states_of(frame) if s != state]


def claim_3(runs: Mapping[str, pd.DataFrame], learner: str = LEARNER) -> list[Part]:
    s = runs.get("initial_distribution")
    if s is None:
        return [_missing("initial_distribution not run")]
    tavc, rnd = _ctrl(s, learner), _ctrl(s, "random")
    return [greater(f"time in 3:3, {who(learner)} above random (%)", _share(tavc, "3:3"), _share(rnd, "3:3")),
            *_most_frequent(tavc, "3:3", who(learner))]


def claim_4(runs: Mapping[str, pd.DataFrame], theory: Mapping[str, float] | None = None,
            learner: str = LEARNER) -> list[Part]:
    s = runs.get("initial_distribution")
    if s is None:
        return [_missing("initial_distribution not run")]
    rnd = _ctrl(s, "random")
    if theory is None:
        from tavc_cli.analysis.states import theory_pct

        n = len(states_of(s)) - 1
        theory = theory_pct(n, 2, "circuits")
    means = {st: _mean(_share(rnd, st)) for st in states_of(s)}
    tests = [(st, (lambda st=st: _one_sample(_share(rnd, st), theory[st]))) for st in states_of(s)]
    return [close_to("random's mean distribution close to the binomial theory row", means, theory, CLOSE_W),
            as_observation(holm_none_differ("random's share of each state against the binomial theory row "
                                            "(the chapter: the differences are significant)", tests))]


def claim_5(runs: Mapping[str, pd.DataFrame], learner: str = LEARNER) -> list[Part]:
    s = runs.get("initial_distribution")
    if s is None:
        return [_missing("initial_distribution not run")]
    return [greater(f"score per second in the stable period, {who(learner)} above random",
                    _ctrl(s, learner)["value_rate_stable"], _ctrl(s, "random")["value_rate_stable"])]


def claim_6(runs: Mapping[str, pd.DataFrame], learner: str = LEARNER) -> list[Part]:
    s = runs.get("breakdown")
    if s is None:
        return [_missing("breakdown not run")]
    tavc, rnd, static = _ctrl(s, learner), _ctrl(s, "random"), _ctrl(s, "static")
    return [greater(f"time in 3:2, {who(learner)} above random (%)", _share(tavc, "3:2"), _share(rnd, "3:2")),
            greater(f"score per second, {who(learner)} above random", tavc["value_rate_stable"],
                    rnd["value_rate_stable"]),
            greater(f"score per second, {who(learner)} above the static allocation tuned for six",
                    tavc["value_rate_stable"], static["value_rate_stable"]),
            *(as_observation(p) for p in _most_frequent(tavc, "3:2", who(learner))),
            as_observation(paired_less(f"{who(learner)} score per second, convergence period below the period "
                                       f"before the breakdown", tavc["value_rate_convergence"],
                                       tavc["value_rate_before"]))]


def claim_7(runs: Mapping[str, pd.DataFrame], learner: str = LEARNER) -> list[Part]:
    s = runs.get("breakdown_no_vacancy")
    if s is None:
        return [_missing("breakdown_no_vacancy not run")]
    tavc, rnd = _ctrl(s, learner), _ctrl(s, "random")
    b = runs.get("breakdown")
    bt = _ctrl(b, learner) if b is not None else None
    parts = []
    if bt is None:
        parts.append(_missing("distribution against breakdown's: breakdown not run"))
    else:
        parts.append(all_equivalent(f"{who(learner)}'s share of each state, the same as breakdown's (%)",
                                    [(st, _share(tavc, st), _share(bt, st)) for st in states_of(s)],
                                    STATE_MARGIN_PCT))
    parts.append(paired_less(f"{who(learner)} score per second, convergence period below the period before the "
                             f"breakdown", tavc["value_rate_convergence"], tavc["value_rate_before"]))
    parts.append(greater(f"score per second, {who(learner)} above random", tavc["value_rate_stable"],
                         rnd["value_rate_stable"]))
    if bt is None:
        parts.append(_missing("stable-period score per second against breakdown's: breakdown not run"))
    else:
        parts.append(equivalent(f"{who(learner)} score per second in the stable period, the same as breakdown's",
                                tavc["value_rate_stable"], bt["value_rate_stable"], PERFORMANCE_MARGIN,
                                relative=True))
    parts.append(equivalent(f"{who(learner)} score per second, convergence period the same as the stable period",
                            tavc["value_rate_convergence"], tavc["value_rate_stable"], PERFORMANCE_MARGIN,
                            paired=True, relative=True))
    return parts


def claim_8(runs: Mapping[str, pd.DataFrame], learner: str = LEARNER) -> list[Part]:
    s = runs.get("value_change")
    if s is None:
        return [_missing("value_change not run")]
    tavc, rnd = _ctrl(s, learner), _ctrl(s, "random")
    b = runs.get("breakdown")
    parts = []
    for st in ("3:2", "4:1"):
        if b is None:
            parts.append(_missing(f"time in {st} against breakdown's: breakdown not run"))
        else:
            parts.append(greater(f"time in {st}, {who(learner)} above breakdown's (%)", _share(tavc, st),
                                 _share(_ctrl(b, learner), st)))
    parts.append(greater(f"time in 3:2, {who(learner)} above random (%)", _share(tavc, "3:2"), _share(rnd, "3:2")))
    parts += [less(f"time in {st}, {who(learner)} below random (%)", _share(tavc, st), _share(rnd, st))
              for st in states_of(s) if st != "3:2"]
    parts.append(paired_less(f"{who(learner)} score per second, convergence period below the period before the "
                             f"change", tavc["value_rate_convergence"], tavc["value_rate_before"]))
    parts.append(equivalent(f"{who(learner)} score per second, after the change the same as before it",
                            tavc["value_rate_stable"], tavc["value_rate_before"], PERFORMANCE_MARGIN, paired=True,
                            relative=True))
    return parts


def mean_above(what: str, a, b, below: bool = False) -> Part:
    """a's mean over trials above b's (below it, if `below`; either may be a number): a
    comparison of means, with no test, where the chapter states a difference of means without
    one. The statistic is the difference of the means, a's minus b's."""
    ma = _mean(a) if np.ndim(a) else float(a)
    mb = _mean(b) if np.ndim(b) else float(b)
    if not (math.isfinite(ma) and math.isfinite(mb)):
        return Part(what, math.nan, math.nan, None, "no trials", what, "means")
    holds = ma < mb if below else ma > mb
    return Part(f"{what} ({ma:.4g} against {mb:.4g}, means)", ma - mb, math.nan, holds, name=what, kind="means")


def largest_relative_increase(tavc: pd.DataFrame, theory: Mapping[str, float], state: str) -> Part:
    """`state` has the largest (mu_TAVC - T) / T of all states, T the binomial theory row (eq. 1.7):
    the chapter's Table 1.6 computes its relative differences against T (every printed row does,
    though the header names the random runs' mean), which its text calls the underlying random
    distribution. A comparison of means, as the chapter's, with no test; the statistic is state's."""
    rel = {}
    for st in states_of(tavc):
        mu_t, t = np.nanmean(_share(tavc, st)), theory.get(st, math.nan)
        if np.isfinite(mu_t) and np.isfinite(t) and t > 0:
            rel[st] = (mu_t - t) / t
    what = f"relative increase over the theory row (mu_TAVC - T) / T largest in {state}"
    if state not in rel:
        return _missing(what)
    top = max(rel, key=rel.get)
    return Part(f"{what} (largest: {top}, {rel[top]:.3g})", rel[state], math.nan, top == state, name=what,
                kind="means")


def _group_theory(stats_: pd.DataFrame) -> dict[str, float]:
    """Eq. 1.7 for the f:s states of a trial_stats table (group sizes: the largest f and s)."""
    from tavc_cli.analysis.states import theory_pct

    pairs = [tuple(int(x) for x in st.split(":")) for st in states_of(stats_)]
    sizes = [max(f for f, _ in pairs), max(s for _, s in pairs)]
    return theory_pct(sum(sizes), 2, "groups", sizes)


def claim_9(runs: Mapping[str, pd.DataFrame], learner: str = LEARNER) -> list[Part]:
    s = runs.get("heterogeneous")
    if s is None:
        return [_missing("heterogeneous not run")]
    n_groups = {len(st.split(":")) for st in states_of(s)}
    if n_groups != {2}:
        return [_missing(f"the claim compares two speed groups, this team has {', '.join(map(str, n_groups))}")]
    tavc, rnd = _ctrl(s, learner), _ctrl(s, "random")
    parts = [greater(f"time in 3:0 (every fast robot high, every slow one low), {who(learner)} above random (%)",
                     _share(tavc, "3:0"), _share(rnd, "3:0")),
             largest_relative_increase(tavc, _group_theory(s), "3:0"),
             greater(f"score per second, {who(learner)} above random", tavc["value_rate_stable"],
                     rnd["value_rate_stable"])]
    gaps = [c for c in s.columns if c.startswith(Q_GAP_PREFIX)]  # fastest group first
    if len(gaps) >= 2:
        fast, slow = gaps[0][len(Q_GAP_PREFIX):], gaps[-1][len(Q_GAP_PREFIX):]
        parts += [mean_above(f"final Q(high) - Q(low) of the {fast} robots above zero", tavc[gaps[0]], 0.0),
                  mean_above(f"final Q(high) - Q(low) of the {slow} robots below zero", tavc[gaps[-1]], 0.0,
                             below=True),
                  mean_above(f"final Q(high) - Q(low), {fast} robots above {slow}", tavc[gaps[0]], tavc[gaps[-1]])]
    else:
        parts.append(_missing("final Q(high) - Q(low) by speed group: no Q gaps recorded"))
    return parts



def claim_1(runs: Mapping[str, pd.DataFrame], learner: str = LEARNER) -> list[Part]:
    from tavc_cli.analysis.spatiotemporal import ARRIVAL_ROWS, TRAVERSAL_ROWS

    trav, targ = runs.get("spatiotemporal/traversals"), runs.get("spatiotemporal/target_times")
    if trav is None or targ is None:
        return [_missing("spatiotemporal not run")]
    parts = []
    first = trav.loc[trav["traversal"] == 0, "time_s"]
    for n in TRAVERSAL_ROWS[1:]:
        parts.append(less(f"traversal time after {n} traversals below the first's (s)",
                          trav.loc[trav["traversal"] == n, "time_s"], first))
    first = targ.loc[targ["arrival"] == 0, "time_s"]
    for m in ARRIVAL_ROWS[1:]:
        parts.append(less(f"group target time after {m} arrivals below the first's (s)",
                          targ.loc[targ["arrival"] == m, "time_s"], first))
    return parts


def claim_2(runs: Mapping[str, pd.DataFrame], learner: str = LEARNER) -> list[Part]:
    pol, lanes = runs.get("spatiotemporal/policy"), runs.get("spatiotemporal/lanes")
    if pol is None or lanes is None:
        return [_missing("spatiotemporal not run")]
    late = lanes.loc[lanes["window"] == "late", "mean_left_m"]
    return [paired_greater("robots' share of states whose best behaviour is direct approach, above wall following",
                           pol["share_direct"], pol["share_wall"]),
            paired_greater("direct approach above stop", pol["share_direct"], pol["share_stop"]),
            one_sample("share of wall following", pol["share_wall"], 0.0, "greater"),
            one_sample("offset left of the direction of travel in the last tenth of the run, per trial (m)",
                       late, 0.0, "greater"),
            *(paired_greater(f"{c} stop-rate above the yellow stop-rate", pol[f"stop_rate_{c}"],
                             pol["stop_rate_yellow"]) for c in ("red", "green", "front"))]


TESTS: dict[int, Callable[..., list[Part]]] = {
    1: claim_1, 2: claim_2, 3: claim_3, 4: claim_4, 5: claim_5, 6: claim_6, 7: claim_7, 8: claim_8, 9: claim_9,
}


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
                learner: str = LEARNER) -> pd.DataFrame:
    """COLUMNS, DECIDING_COLUMNS, then OBSERVATION_COLUMNS: for claims 1-9 (those of one experiment if given), the
    verdict and every part (`claim_rows`), and the part that decides the verdict (`deciding`):
    its question, statistic and p-value, and why the claim could not be decided, if it could
    not; and the observations reported beside the verdict. `runs` as `claim_rows` takes them."""
    rows = []
    for cid, test in TESTS.items():
        experiment, text = CLAIMS[cid]
        if only_experiment is not None and experiment != only_experiment:
            continue
        with warnings.catch_warnings():
            # scipy warns when samples are nearly identical (a state never visited in any trial);
            # the test's result says as much, and a run's output stays free of library noise
            warnings.filterwarnings("ignore", "Precision loss occurred", RuntimeWarning)
            found = test(runs, learner=learner)
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
               learner: str = LEARNER) -> pd.DataFrame:
    """`claim_id,claim,verdict,statistic,p_value,detail,observations` for claims 1-9 (those of one
    experiment if given): the table a run writes as its `claims.csv`. `runs` maps an
    experiment's name to its `trial_stats.csv` and `<experiment>/<table>` to its other tables
    the claims read (CLAIM_TABLES). statistic and p_value are the first part's (the claim's
    headline comparison); `detail` lists every part, `observations` what is reported beside
    the verdict (`Part.observation`). The part that decides each verdict
    (`claim_table`'s DECIDING_COLUMNS) rides along in the frame's ``attrs["deciding"]``
    (claim_id -> those columns), which a file written from the frame does not hold."""
    table = claim_table(runs, only_experiment, learner)
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
    section 1.4; else in seconds). Longer trials (scale=converged) are not below it.
    `cfg` is a run's settings (`settings.TavcConfig`)."""
    paper, out = cfg.paper, []
    for ours, theirs, who in ((cfg.trials, paper.trials, ""),
                              (cfg.baseline_trials, paper.baseline_trials, " baseline"),
                              (cfg.static_trials, paper.static_trials, " static")):
        if ours is not None and theirs is not None and int(ours) < int(theirs):
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
