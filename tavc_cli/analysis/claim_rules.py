"""The rules that test the chapter's claims 1-9 on per-trial numbers (`trial_stats.csv`; for
section 1.4, the traversal and target-time samples, the learned policies and the lane offsets).

Each claim quotes the phrases of the chapter its parts test (its entry in `tavc_cli.chapter`;
docs/claims.md by part), and its side, test and margin follow that phrase; all were fixed here
before any verdict was looked at, and none is tuned to one (the statistics are
`analysis.significance`'s):

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

A rule reads the run of the experiment its claim is about, and of the one it compares that with
(`Claim.against`), from `runs` by the names the registry gives them; a run missing makes a part
that says so.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping

import numpy as np
import pandas as pd

from tavc_cli import chapter
from tavc_cli.analysis.significance import (
    Part,
    _one_sample,
    all_equivalent,
    as_observation,
    close_to,
    equivalent,
    greater,
    holm_some_differ,
    less,
    one_sample,
    paired_greater,
    paired_less,
)
from tavc_cli.analysis.states import theory_pct
from tavc_cli.analysis.table_schemas import Q_GAP_PREFIX
from tavc_cli.analysis.trial_stats import states_of
from tavc_cli.learning.registry import LEARNS_NOTHING
from tavc_cli.notation import STATE_PREFIX, counts_of

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


LEARNER = "tavc"  # the controller whose trials the claims about learning test, unless told another


def learner_under_test(labels: Iterable[str]) -> str:
    """The learner the claims about learning test among the task learners of some runs: the one
    they all share, unless it learns nothing (random, the static allocations, the model's: the
    claims compare a learner with those), else TAVC."""
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



def _run(runs: Mapping[str, pd.DataFrame], claim_id: int, table: str | None = None) -> tuple[str, pd.DataFrame | None]:
    """The name of the experiment claim `claim_id` is about, and its run in `runs` (`trial_stats.csv`,
    or its `table`), None where it was not run."""
    name, _ = chapter.claim(claim_id)
    return name, runs.get(name if table is None else f"{name}/{table}")


def _against(runs: Mapping[str, pd.DataFrame], claim_id: int) -> tuple[str, pd.DataFrame | None, str]:
    """The experiment claim `claim_id` compares its own with (`Claim.against`), its run (None where
    there is none to compare with) and, for that case, why: not run, or a run beside that is no
    comparison (`unlike_run`: not finished, made otherwise)."""
    other = chapter.claim(claim_id)[1].against
    b = runs.get(other)
    if b is not None and b.attrs.get(UNLIKE):
        return other, None, f"{other} beside it {b.attrs[UNLIKE]}"
    return other, b, f"{other} not run"


UNLIKE = "unlike"  # the attrs key of `unlike_run`'s stand-in


def unlike_run(why: str) -> pd.DataFrame:
    """What stands in a claim's `runs` for the run of the experiment it compares with, where that
    run is no comparison for this one's (`why`, as "<experiment> beside it" goes on: "not
    finished", "ran with other settings (...)"): no trials to compare."""
    frame = pd.DataFrame()
    frame.attrs[UNLIKE] = why
    return frame


def claim_3(runs: Mapping[str, pd.DataFrame], learner: str = LEARNER) -> list[Part]:
    """Claim 3's parts, read from the runs of its experiment (`chapter` names it and quotes
    the chapter's words), each on `learner`'s trials."""
    name, s = _run(runs, 3)
    if s is None:
        return [_missing(f"{name} not run")]
    tavc, rnd = _ctrl(s, learner), _ctrl(s, "random")
    return [greater(f"time in 3:3, {who(learner)} above random (%)", _share(tavc, "3:3"), _share(rnd, "3:3")),
            *_most_frequent(tavc, "3:3", who(learner))]


def claim_4(runs: Mapping[str, pd.DataFrame], theory: Mapping[str, float] | None = None,
            learner: str = LEARNER) -> list[Part]:
    """Claim 4's parts, read from the runs of its experiment (`chapter` names it and quotes
    the chapter's words), each on `learner`'s trials."""
    name, s = _run(runs, 4)
    if s is None:
        return [_missing(f"{name} not run")]
    rnd = _ctrl(s, "random")
    if theory is None:
        n = len(states_of(s)) - 1
        theory = theory_pct(n, 2, "circuits")
    means = {st: _mean(_share(rnd, st)) for st in states_of(s)}
    tests = [(st, (lambda st=st: _one_sample(_share(rnd, st), theory[st]))) for st in states_of(s)]
    return [close_to("random's mean distribution close to the binomial theory row", means, theory, CLOSE_W),
            as_observation(holm_some_differ("random's share differs from the binomial theory row in some state "
                                            "(the chapter: \"the differences are statistically significant\")",
                                            tests))]


def claim_5(runs: Mapping[str, pd.DataFrame], learner: str = LEARNER) -> list[Part]:
    """Claim 5's parts, read from the runs of its experiment (`chapter` names it and quotes
    the chapter's words), each on `learner`'s trials."""
    name, s = _run(runs, 5)
    if s is None:
        return [_missing(f"{name} not run")]
    return [greater(f"score per second in the stable period, {who(learner)} above random",
                    _ctrl(s, learner)["value_rate_stable"], _ctrl(s, "random")["value_rate_stable"])]


def claim_6(runs: Mapping[str, pd.DataFrame], learner: str = LEARNER) -> list[Part]:
    """Claim 6's parts, read from the runs of its experiment (`chapter` names it and quotes
    the chapter's words), each on `learner`'s trials."""
    name, s = _run(runs, 6)
    if s is None:
        return [_missing(f"{name} not run")]
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
    """Claim 7's parts, read from the runs of its experiment (`chapter` names it and quotes
    the chapter's words), each on `learner`'s trials."""
    name, s = _run(runs, 7)
    if s is None:
        return [_missing(f"{name} not run")]
    tavc, rnd = _ctrl(s, learner), _ctrl(s, "random")
    other, b, absent = _against(runs, 7)
    bt = _ctrl(b, learner) if b is not None else None
    parts = []
    if bt is None:
        parts.append(_missing(f"distribution against {other}'s: {absent}"))
    else:
        parts.append(all_equivalent(f"{who(learner)}'s share of each state, the same as {other}'s (%)",
                                    [(st, _share(tavc, st), _share(bt, st)) for st in states_of(s)],
                                    STATE_MARGIN_PCT))
    parts.append(paired_less(f"{who(learner)} score per second, convergence period below the period before the "
                             f"breakdown", tavc["value_rate_convergence"], tavc["value_rate_before"]))
    parts.append(greater(f"score per second, {who(learner)} above random", tavc["value_rate_stable"],
                         rnd["value_rate_stable"]))
    if bt is None:
        parts.append(_missing(f"stable-period score per second against {other}'s: {absent}"))
    else:
        parts.append(equivalent(f"{who(learner)} score per second in the stable period, the same as {other}'s",
                                tavc["value_rate_stable"], bt["value_rate_stable"], PERFORMANCE_MARGIN,
                                relative=True))
    parts.append(equivalent(f"{who(learner)} score per second, convergence period the same as the stable period",
                            tavc["value_rate_convergence"], tavc["value_rate_stable"], PERFORMANCE_MARGIN,
                            paired=True, relative=True))
    return parts


def claim_8(runs: Mapping[str, pd.DataFrame], learner: str = LEARNER) -> list[Part]:
    """Claim 8's parts, read from the runs of its experiment (`chapter` names it and quotes
    the chapter's words), each on `learner`'s trials."""
    name, s = _run(runs, 8)
    if s is None:
        return [_missing(f"{name} not run")]
    tavc, rnd = _ctrl(s, learner), _ctrl(s, "random")
    other, b, absent = _against(runs, 8)
    parts = []
    for st in ("3:2", "4:1"):
        if b is None:
            parts.append(_missing(f"time in {st} against {other}'s: {absent}"))
        else:
            parts.append(greater(f"time in {st}, {who(learner)} above {other}'s (%)", _share(tavc, st),
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
        share = np.asarray(_share(tavc, st), dtype=float)
        # no trial of the learner with this state (none at all, or all NaN): no mean, and no warning
        mu_t = float(np.nanmean(share)) if np.isfinite(share).any() else math.nan
        t = theory.get(st, math.nan)
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
    pairs = [counts_of(st) for st in states_of(stats_)]
    sizes = [max(f for f, _ in pairs), max(s for _, s in pairs)]
    return theory_pct(sum(sizes), 2, "groups", sizes)


def claim_9(runs: Mapping[str, pd.DataFrame], learner: str = LEARNER) -> list[Part]:
    """Claim 9's parts, read from the runs of its experiment (`chapter` names it and quotes
    the chapter's words), each on `learner`'s trials."""
    name, s = _run(runs, 9)
    if s is None:
        return [_missing(f"{name} not run")]
    n_groups = {len(counts_of(st)) for st in states_of(s)}
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


def _no_behaviours(runs: Mapping[str, pd.DataFrame], claim_id: int) -> str:
    """Why a claim of section 1.4 has none of its tables: its experiment not run, or run without
    the learner of behaviours, whose trials alone section 1.4's tables are of."""
    name, run = _run(runs, claim_id)
    if run is None:
        return f"{name} not run"
    return f"{name} ran no behaviour learner (section 1.4's tables are of its trials)"


def claim_1(runs: Mapping[str, pd.DataFrame], learner: str = LEARNER) -> list[Part]:
    """Claim 1's parts, read from the runs of its experiment (`chapter` names it and quotes
    the chapter's words), each on `learner`'s trials."""
    # deferred: loads the simulator's compiled kernels
    from tavc_cli.analysis.spatiotemporal import ARRIVAL_ROWS, TRAVERSAL_ROWS

    (_, trav), (_, targ) = _run(runs, 1, "traversals"), _run(runs, 1, "target_times")
    if trav is None or targ is None:
        return [_missing(_no_behaviours(runs, 1))]
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
    """Claim 2's parts, read from the runs of its experiment (`chapter` names it and quotes
    the chapter's words), each on `learner`'s trials."""
    (_, pol), (_, lanes) = _run(runs, 2, "policy"), _run(runs, 2, "lanes")
    if pol is None or lanes is None:
        return [_missing(_no_behaviours(runs, 2))]
    late = lanes.loc[lanes["window"] == "late", "mean_left_m"]
    return [paired_greater("robots' share of states whose best behaviour is direct approach, above wall following",
                           pol["share_direct"], pol["share_wall"]),
            paired_greater("direct approach above stop", pol["share_direct"], pol["share_stop"]),
            one_sample("share of wall following", pol["share_wall"], 0.0, "greater"),
            one_sample("offset left of the direction of travel in the last tenth of the run, per trial (m)",
                       late, 0.0, "greater"),
            *(paired_greater(f"{c} stop-rate above the yellow stop-rate", pol[f"stop_rate_{c}"],
                             pol["stop_rate_yellow"]) for c in ("red", "green", "front"))]
