"""The chapter's claims 1-9 as tests on per-trial numbers (`trial_stats.csv`; for section 1.4,
the traversal and target-time samples, the learned policies and the lane offsets).

Every test is the chapter's kind, a t-test at 90 % confidence (alpha = 0.10), written
down here before any verdict was looked at and never tuned to one:

- "A is significantly above B" between controllers (independent trials of unequal
  spread): Welch's t-test, one-sided, because the claim names a direction;
- "state X is the most frequent": within the same trials, a paired one-sided t-test of
  X's share against every other state's, and all must hold (an intersection of one-sided
  tests needs no correction for their number);
- "not significantly different" over several states: two-sided tests, one per state,
  Holm-corrected so that the family's error rate is alpha; the claim holds if none rejects.
  A single "not different" comparison is one two-sided test.

- "state X has the largest relative increase": the chapter compares means here, over the
  binomial theory row, with no test, and so does this (claim 9).

A claim is `reproduced` when every one of its parts holds, `not_reproduced` when a part
is decided against it, and `inconclusive` (read: not testable) when no part fails but some
part could not be tested: fewer than two trials a side ("one trial"), no spread at all in
the numbers a t statistic divides by ("no spread in either sample"), or a run missing. Such
a part says why; it never becomes a t of plus or minus infinity with p = 0.

Which part decides a verdict, and so which p a report shows for the claim, is `deciding`.
Whether a run's verdicts are verdicts at all, given its trial count and duration beside the
chapter's, is `scale_shortfall`.
"""

from __future__ import annotations

import math
import warnings
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass

import numpy as np
import pandas as pd
from scipy import stats

from tavc_cli.analysis.trial_stats import Q_GAP_PREFIX, STATE_PREFIX, states_of

ALPHA = 0.10
CLAIMS = {
    1: ("spatiotemporal", "After learning, the mean traversal time per robot and the mean group target time are "
                          "significantly lower than at the start, at every row of Table 1.1."),
    2: ("spatiotemporal", "Learned policies are dominated by direct approach with a significant share of wall "
                          "following; robots keep to one side of the axis (two lanes); the yellow stop-rate is "
                          "significantly below the red, green and front stop-rates."),
    3: ("initial_distribution", "The learners spend significantly more time in 3:3 than random allocation, "
                                "and 3:3 is significantly their most frequent state."),
    4: ("initial_distribution", "Random allocation's state distribution is close to the binomial theory row."),
    5: ("initial_distribution", "The learners' group performance is significantly above random allocation's."),
    6: ("breakdown", "After a high-circuit robot breaks down the learners prefer 3:2, significantly more than "
                     "random; their performance beats random and a static allocation tuned for six robots."),
    7: ("breakdown_no_vacancy", "With a low-circuit robot broken down the distribution does not differ "
                                "significantly from breakdown's; performance stays above random; convergence "
                                "and stable periods do not differ significantly."),
    8: ("value_change", "After the values swap, 3:2 is significantly above random and every other state "
                        "significantly below; performance returns to a level not significantly different "
                        "from before the change."),
    9: ("heterogeneous", "Fast robots end up on the high-value circuit: time in 3:0 (the chapter's text says "
                         "0:3, its table 3:0) is significantly above random and has the largest relative "
                         "increase over the theory row; performance is above random; fast robots' "
                         "Q(high) - Q(low) is larger than slow robots'."),
}
COLUMNS = ["claim_id", "claim", "verdict", "statistic", "p_value", "detail"]
# tables besides trial_stats.csv that claims read, as `<experiment>/<table>` in `runs`
CLAIM_TABLES = ("traversals", "target_times", "policy", "lanes")


@dataclass(frozen=True)
class Part:
    """One test of a claim: what it asked, its statistic and p-value, and whether it holds
    (None: could not be tested, and `reason` says why). `name` is the question alone, without
    the numbers `what` adds; `kind` says which way the test decides: `differs` holds when
    p < alpha (a difference in the named direction), `same` holds when p >= alpha (no
    significant difference), `means` is a comparison of means with no p."""

    what: str
    statistic: float
    p_value: float
    holds: bool | None
    reason: str = ""
    name: str = ""
    kind: str = "differs"

    @property
    def question(self) -> str:
        return self.name or self.what

    def text(self) -> str:
        if self.holds is None:
            return f"{self.what}: not testable" + (f" ({self.reason})" if self.reason else "")
        if not math.isfinite(self.p_value):  # a comparison of means, not a test
            return f"{self.what}: {self.statistic:.4g} ({'holds' if self.holds else 'fails'})"
        return f"{self.what}: t = {self.statistic:.3f}, p = {self.p_value:.4g} ({'holds' if self.holds else 'fails'})"


def _clean(x) -> np.ndarray:
    a = np.asarray(x, dtype=float)
    return a[np.isfinite(a)]


def untestable(*samples: np.ndarray) -> str:
    """Why a t-test cannot be computed on `samples` (finite values only), or "" if it can: a
    sample with no trials or one trial, or no spread in any sample (the t statistic would
    divide by a standard error of zero)."""
    sizes = [len(s) for s in samples]
    if min(sizes) == 0:
        return "no trials" if len(samples) == 1 else "no trials in one sample"
    if min(sizes) == 1:
        return "one trial"
    if all(np.ptp(s) == 0 for s in samples):
        return "no spread in the sample" if len(samples) == 1 else "no spread in either sample"
    return ""


def _testable(*samples: np.ndarray) -> bool:
    return not untestable(*samples)


def _not_testable(what: str, reason: str, kind: str = "differs") -> Part:
    return Part(what, math.nan, math.nan, None, reason, what, kind)


def _one_sided(what: str, a, b, alternative: str) -> Part:
    a, b = _clean(a), _clean(b)
    if not _testable(a, b):
        return _not_testable(what, untestable(a, b))
    t, p = stats.ttest_ind(a, b, equal_var=False, alternative=alternative)
    return Part(f"{what} ({a.mean():.4g} vs {b.mean():.4g}, Welch one-sided)", float(t), float(p), bool(p < ALPHA),
                name=what)


def greater(what: str, a, b) -> Part:
    """a's mean significantly above b's: Welch's t-test, one-sided."""
    return _one_sided(what, a, b, "greater")


def less(what: str, a, b) -> Part:
    """a's mean significantly below b's: Welch's t-test, one-sided."""
    return _one_sided(what, a, b, "less")


def _differences(a, b) -> np.ndarray:
    a, b = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
    ok = np.isfinite(a) & np.isfinite(b)
    return a[ok] - b[ok]


def paired_greater(what: str, a, b) -> Part:
    """Within the same trials, a significantly above b: paired t-test, one-sided."""
    d = _differences(a, b)
    if not _testable(d):
        return _not_testable(what, untestable(d).replace("the sample", "the differences"))
    t, p = stats.ttest_1samp(d, 0.0, alternative="greater")
    return Part(f"{what} (mean difference {d.mean():.4g}, paired one-sided)", float(t), float(p), bool(p < ALPHA),
                name=what)


def not_different(what: str, a, b, paired: bool = False) -> Part:
    """No significant difference between a and b: two-sided t-test (Welch, or paired)."""
    if paired:
        d = _differences(a, b)
        if not _testable(d):
            return _not_testable(what, untestable(d).replace("the sample", "the differences"), "same")
        t, p = stats.ttest_1samp(d, 0.0)
        label = f"{what} (mean difference {d.mean():.4g}, paired two-sided)"
    else:
        a, b = _clean(a), _clean(b)
        if not _testable(a, b):
            return _not_testable(what, untestable(a, b), "same")
        t, p = stats.ttest_ind(a, b, equal_var=False)
        label = f"{what} ({a.mean():.4g} vs {b.mean():.4g}, Welch two-sided)"
    return Part(label, float(t), float(p), bool(p >= ALPHA), name=what, kind="same")


def holm_none_differ(what: str, tests: Sequence[tuple[str, Callable[[], tuple]]]) -> Part:
    """Several two-sided tests (name, () -> (t, p) or (t, p, why not testable)), Holm-corrected
    over those that could be computed: holds if none rejects. Reported: the test with the
    smallest p, and its Holm-adjusted p.

    A state whose two samples are each constant and equal (`IDENTICAL`: every trial 0 % on both
    sides, say) has nothing that could differ: it is no test, and does not count in the family.
    Any other state that cannot be tested leaves the family not testable, unless a state that
    could be tested already rejects: "none differ" cannot be shown while one state is unknown."""
    results, identical, untested = [], [], []
    for name, run in tests:
        t, p, *why = run()
        if math.isfinite(p):
            results.append((p, t, name))
        elif why and why[0] == IDENTICAL:
            identical.append(name)
        else:
            untested.append((name, why[0] if why and why[0] else "not testable"))
    aside = f", {len(identical)} identical in every trial, no test" if identical else ""
    if not results:
        reason = _grouped(untested) if untested else "every state identical in every trial"
        return _not_testable(what, reason, "same")
    results.sort()
    m = len(results)
    adjusted, running = [], 0.0
    for k, (p, _, _) in enumerate(results):
        running = max(running, min(1.0, (m - k) * p))
        adjusted.append(running)
    p0, t0, name0 = results[0]
    label = f"{what} (most different: {name0}, raw p {p0:.4g}, Holm over {m} states{aside})"
    if any(a < ALPHA for a in adjusted):
        return Part(label, float(t0), float(adjusted[0]), False, name=what, kind="same")
    if untested:  # the family's verdict is unknown, and so is its t: the tested states' are in `label`
        return Part(label, math.nan, math.nan, None, "no tested state differs, but " + _grouped(untested), what,
                    "same")
    return Part(label, float(t0), float(adjusted[0]), True, name=what, kind="same")


def _grouped(untested: Sequence[tuple[str, str]]) -> str:
    """States that could not be tested, by reason: "one trial (0:6, 1:5)"."""
    by_reason: dict[str, list[str]] = {}
    for name, why in untested:
        by_reason.setdefault(why, []).append(name)
    return "; ".join(f"{why} ({', '.join(names)})" for why, names in by_reason.items())


# a state of a "none differ" family whose samples are constant and the same: nothing to test
IDENTICAL = "identical in every trial"


def _one_sample(x, mu: float) -> tuple[float, float, str]:
    """Two-sided one-sample test of x against mu: (t, p, ""), or (nan, nan, why not testable)."""
    x = _clean(x)
    if len(x) >= 2 and np.ptp(x) == 0:
        # no spread at all: the t statistic divides by zero. Exactly mu is nothing to test;
        # anything else cannot be tested (a t of infinity would claim a certainty no test gives)
        return (math.nan, math.nan, IDENTICAL if x[0] == mu else f"no spread in the sample (every trial {x[0]:.4g} "
                f"against {mu:.4g})")
    if not _testable(x):
        return math.nan, math.nan, untestable(x)
    t, p = stats.ttest_1samp(x, mu)
    return float(t), float(p), ""


def _welch(a, b) -> tuple[float, float, str]:
    """Welch's two-sided test: (t, p, ""), or (nan, nan, why not testable)."""
    a, b = _clean(a), _clean(b)
    if len(a) >= 2 and len(b) >= 2 and np.ptp(a) == 0 and np.ptp(b) == 0:
        return (math.nan, math.nan, IDENTICAL if a[0] == b[0] else f"no spread in either sample (every trial "
                f"{a[0]:.4g} against {b[0]:.4g})")
    if not _testable(a, b):
        return math.nan, math.nan, untestable(a, b)
    t, p = stats.ttest_ind(a, b, equal_var=False)
    return float(t), float(p), ""


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
    tests = [(st, (lambda st=st: _one_sample(_share(rnd, st), theory[st]))) for st in states_of(s)]
    return [holm_none_differ("random's share of each state against the binomial theory row", tests)]


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
            *_most_frequent(tavc, "3:2", who(learner)),
            greater(f"score per second, {who(learner)} above random", tavc["value_rate_stable"],
                    rnd["value_rate_stable"]),
            greater(f"score per second, {who(learner)} above the static allocation tuned for six",
                    tavc["value_rate_stable"], static["value_rate_stable"])]


def claim_7(runs: Mapping[str, pd.DataFrame], learner: str = LEARNER) -> list[Part]:
    s = runs.get("breakdown_no_vacancy")
    if s is None:
        return [_missing("breakdown_no_vacancy not run")]
    tavc, rnd = _ctrl(s, learner), _ctrl(s, "random")
    parts = []
    b = runs.get("breakdown")
    if b is None:
        parts.append(_missing("distribution against breakdown's: breakdown not run"))
    else:
        bt = _ctrl(b, learner)
        tests = [(st, (lambda st=st: _welch(_share(tavc, st), _share(bt, st)))) for st in states_of(s)]
        parts.append(holm_none_differ(f"{who(learner)}'s share of each state, against breakdown's", tests))
    parts.append(greater(f"score per second, {who(learner)} above random", tavc["value_rate_stable"],
                         rnd["value_rate_stable"]))
    parts.append(not_different(f"{who(learner)} score per second, convergence against stable period",
                               tavc["value_rate_convergence"], tavc["value_rate_stable"], paired=True))
    return parts


def claim_8(runs: Mapping[str, pd.DataFrame], learner: str = LEARNER) -> list[Part]:
    s = runs.get("value_change")
    if s is None:
        return [_missing("value_change not run")]
    tavc, rnd = _ctrl(s, learner), _ctrl(s, "random")
    parts = [greater(f"time in 3:2, {who(learner)} above random (%)", _share(tavc, "3:2"), _share(rnd, "3:2"))]
    parts += [less(f"time in {st}, {who(learner)} below random (%)", _share(tavc, st), _share(rnd, st))
              for st in states_of(s) if st != "3:2"]
    parts.append(not_different(f"{who(learner)} score per second, after the change against before it",
                               tavc["value_rate_stable"], tavc["value_rate_before"], paired=True))
    return parts


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
        parts.append(paired_greater(f"final Q(high) - Q(low), {gaps[0][len(Q_GAP_PREFIX):]} robots above "
                                    f"{gaps[-1][len(Q_GAP_PREFIX):]}", tavc[gaps[0]], tavc[gaps[-1]]))
    else:
        parts.append(_missing("final Q(high) - Q(low) by speed group: no Q gaps recorded"))
    return parts


def one_sample(what: str, x, mu: float, alternative: str) -> Part:
    """x's mean against mu: a one-sample t-test, `greater` (one-sided) or `two-sided`."""
    x = _clean(x)
    if not _testable(x):
        return _not_testable(what, untestable(x))
    t, p = stats.ttest_1samp(x, mu, alternative=alternative)
    sides = "one-sided" if alternative != "two-sided" else "two-sided"
    return Part(f"{what} (mean {x.mean():.4g}, one-sample {sides} against {mu:g})", float(t), float(p),
                bool(p < ALPHA), name=what)


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
                       late, 0.0, "two-sided"),
            *(paired_greater(f"{c} stop-rate above the yellow stop-rate", pol[f"stop_rate_{c}"],
                             pol["stop_rate_yellow"]) for c in ("red", "green", "front"))]


TESTS: dict[int, Callable[..., list[Part]]] = {
    1: claim_1, 2: claim_2, 3: claim_3, 4: claim_4, 5: claim_5, 6: claim_6, 7: claim_7, 8: claim_8, 9: claim_9,
}


def verdict(parts: Sequence[Part]) -> str:
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
    - not testable (`inconclusive`): the first part that could not be tested; it has no p.

    A "none differ" family over states (`holm_none_differ`) is one part, its p the Holm-
    adjusted p of its most different state: within it that state decides."""
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
HOLDS_IF = {"differs": f"p < {ALPHA:g}", "same": f"p >= {ALPHA:g}", "means": "a comparison of means, no test"}


def claim_table(runs: Mapping[str, pd.DataFrame], only_experiment: str | None = None,
                learner: str = LEARNER) -> pd.DataFrame:
    """COLUMNS, then DECIDING_COLUMNS: for claims 1-9 (those of one experiment if given), the
    verdict and every part (`claim_rows`), and the part that decides the verdict (`deciding`):
    its question, statistic and p-value, and why the claim could not be tested, if it could
    not. `runs` as `claim_rows` takes them."""
    rows = []
    for cid, test in TESTS.items():
        experiment, text = CLAIMS[cid]
        if only_experiment is not None and experiment != only_experiment:
            continue
        with warnings.catch_warnings():
            # scipy warns when samples are nearly identical (a state never visited in any trial);
            # the test's result says as much, and a run's output stays free of library noise
            warnings.filterwarnings("ignore", "Precision loss occurred", RuntimeWarning)
            parts = test(runs, learner=learner)
        decider = deciding(parts)
        v = verdict(parts)
        rows.append({"claim_id": cid, "claim": text, "verdict": v,
                     "statistic": parts[0].statistic, "p_value": parts[0].p_value,
                     "detail": "; ".join(p.text() for p in parts),
                     "deciding_test": decider.question if decider is not None else "",
                     "deciding_statistic": decider.statistic if decider is not None else math.nan,
                     "deciding_p_value": decider.p_value if decider is not None else math.nan,
                     "deciding_holds_if": HOLDS_IF[decider.kind] if decider is not None else "",
                     "not_testable_because": (f"{decider.question}: {decider.reason}" if decider.reason
                                              else decider.question) if v == "inconclusive" else ""})
    return pd.DataFrame(rows, columns=[*COLUMNS, *DECIDING_COLUMNS])


def claim_rows(runs: Mapping[str, pd.DataFrame], only_experiment: str | None = None,
               learner: str = LEARNER) -> pd.DataFrame:
    """`claim_id,claim,verdict,statistic,p_value,detail` for claims 1-9 (those of one
    experiment if given): the table a run writes as its `claims.csv`. `runs` maps an
    experiment's name to its `trial_stats.csv` and `<experiment>/<table>` to its other tables
    the claims read (CLAIM_TABLES). statistic and p_value are the first part's (the claim's
    headline comparison); `detail` lists every part. The part that decides each verdict
    (`claim_table`'s DECIDING_COLUMNS) rides along in the frame's ``attrs["deciding"]``
    (claim_id -> those columns), which a file written from the frame does not hold."""
    table = claim_table(runs, only_experiment, learner)
    frame = table[COLUMNS].copy()
    frame.attrs["deciding"] = {int(r["claim_id"]): {c: r[c] for c in DECIDING_COLUMNS}
                               for r in table.to_dict("records")}
    return frame


VERDICT_WORDS = {"reproduced": "reproduced", "not_reproduced": "not reproduced", "inconclusive": "not testable"}


def verdict_words(v: str, verdict_scale: bool = True) -> str:
    """A verdict as a reader reads it (`inconclusive` is "not testable"); for a run below the
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
