"""Statistical tests at 90 % confidence (alpha = 0.10), the chapter's level, on per-trial
numbers, each giving a `Part`: what it asked, its statistic and p-value, and whether it holds.

- "A is significantly above B" between controllers (independent trials of unequal spread):
  Welch's t-test, one-sided (`greater`, `less`); within the same trials, a paired one
  (`paired_greater`, `paired_less`); against a number, a one-sample test (`one_sample`).
- "not significantly different": an equivalence test (`equivalent`, two one-sided tests against
  a stated margin, TOST), which holds when both one-sided tests reject at alpha, fails when the
  two-sided test finds a difference, and is undecided when the trials can show neither; over
  several states (`all_equivalent`), every state must be equivalent (an intersection-union
  test, which needs no correction), and the family fails when a Holm-corrected two-sided
  test finds any state different.
- "no state differs" as a plain failure to reject (`holm_none_differ`), kept for reports of
  what differs, not as a test of sameness; "some state differs" (`holm_some_differ`), the same
  Holm-corrected family read the other way, where the chapter states that differences are
  significant.
- "close to" a distribution: Cohen's w (`cohens_w`), a comparison of means with no p.

A part that cannot be tested (fewer than two trials a side, no spread at all where a t divides
by it) says why; it never becomes a t of plus or minus infinity with p = 0.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass

import numpy as np
from scipy import stats

ALPHA = 0.10


@dataclass(frozen=True)
class Part:
    """One test of a claim: what it asked, its statistic and p-value, and whether it holds
    (None: could not be tested or decided, and `reason` says why). `name` is the question
    alone, without the numbers `what` adds; `kind` says which way the test decides: `differs`
    holds when p < alpha (a difference in the named direction), `equivalent` holds when
    p < alpha in both one-sided tests of a margin (TOST), `same` holds when p >= alpha (no
    significant difference found), `means` is a comparison of means with no p. An
    `observation` is reported beside a claim's verdict, never inside it: a statement the
    chapter makes without a test, or a part of the claim's reading that its words do not state."""

    what: str
    statistic: float
    p_value: float
    holds: bool | None
    reason: str = ""
    name: str = ""
    kind: str = "differs"
    observation: bool = False

    @property
    def question(self) -> str:
        """The claim's part this outcome answers: its `name`, else what was compared."""
        return self.name or self.what

    def text(self) -> str:
        """One line for the report: the statistic, p and the verdict (or why there is none)."""
        if self.holds is None and math.isfinite(self.p_value):  # tested, but the trials decide nothing
            return (f"{self.what}: t = {self.statistic:.3f}, p = {self.p_value:.4g} (undecided"
                    + (f": {self.reason})" if self.reason else ")"))
        if self.holds is None:
            return f"{self.what}: not testable" + (f" ({self.reason})" if self.reason else "")
        if not math.isfinite(self.p_value):  # a comparison of means, not a test
            return f"{self.what}: {self.statistic:.4g} ({'holds' if self.holds else 'fails'})"
        outcome = "holds" if self.holds else (f"fails: {self.reason}" if self.reason else "fails")
        return f"{self.what}: t = {self.statistic:.3f}, p = {self.p_value:.4g} ({outcome})"


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


def _paired(what: str, a, b, alternative: str) -> Part:
    d = _differences(a, b)
    if not _testable(d):
        return _not_testable(what, untestable(d).replace("the sample", "the differences"))
    t, p = stats.ttest_1samp(d, 0.0, alternative=alternative)
    return Part(f"{what} (mean difference {d.mean():.4g}, paired one-sided)", float(t), float(p), bool(p < ALPHA),
                name=what)


def paired_greater(what: str, a, b) -> Part:
    """Within the same trials, a significantly above b: paired t-test, one-sided."""
    return _paired(what, a, b, "greater")


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
    family = _holm(what, tests)
    if isinstance(family, Part):
        return Part(family.what, family.statistic, family.p_value, family.holds, family.reason, what, "same")
    label, t0, p0, untested = family
    if p0 < ALPHA:
        return Part(label, t0, p0, False, name=what, kind="same")
    if untested:  # the family's verdict is unknown, and so is its t: the tested states' are in `label`
        return Part(label, math.nan, math.nan, None, "no tested state differs, but " + _grouped(untested), what,
                    "same")
    return Part(label, t0, p0, True, name=what, kind="same")


def holm_some_differ(what: str, tests: Sequence[tuple[str, Callable[[], tuple]]]) -> Part:
    """The same family as `holm_none_differ`, on the other side: holds if some test rejects
    after Holm's correction (the smallest p, adjusted, below `ALPHA`). A state that cannot be
    tested leaves it not testable unless a tested state already rejects: "some differ" cannot be
    denied while one state is unknown."""
    family = _holm(what, tests)
    if isinstance(family, Part):
        return family
    label, t0, p0, untested = family
    if p0 < ALPHA:
        return Part(label, t0, p0, True, name=what)
    if untested:
        return Part(label, math.nan, math.nan, None, "no tested state differs, but " + _grouped(untested), what)
    return Part(label, t0, p0, False, name=what)


def _holm(what: str, tests: Sequence[tuple[str, Callable[[], tuple]]]) -> Part | tuple[str, float, float, list]:
    """A family of two-sided tests over states, Holm-corrected: (its label, naming the most different
    state and its raw p; that state's t; its Holm-adjusted p, the family's; the states that could not
    be tested, with why), or a not-testable part where no state could be tested. Holm's step-down
    rejects some state exactly when the smallest p times the family's size is below `ALPHA`."""
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
        return _not_testable(what, reason)
    p0, t0, name0 = sorted(results)[0]
    label = f"{what} (most different: {name0}, raw p {p0:.4g}, Holm over {len(results)} states{aside})"
    return label, float(t0), float(min(1.0, len(results) * p0)), untested


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


def one_sample(what: str, x, mu: float, alternative: str) -> Part:
    """x's mean against mu: a one-sample t-test, `greater` (one-sided) or `two-sided`."""
    x = _clean(x)
    if not _testable(x):
        return _not_testable(what, untestable(x))
    t, p = stats.ttest_1samp(x, mu, alternative=alternative)
    sides = "one-sided" if alternative != "two-sided" else "two-sided"
    return Part(f"{what} (mean {x.mean():.4g}, one-sample {sides} against {mu:g})", float(t), float(p),
                bool(p < ALPHA), name=what)


def paired_less(what: str, a, b) -> Part:
    """Within the same trials, a significantly below b: paired t-test, one-sided."""
    return _paired(what, a, b, "less")


def as_observation(part: Part) -> Part:
    """`part`, reported beside a claim's verdict rather than inside it."""
    return Part(part.what, part.statistic, part.p_value, part.holds, part.reason, part.name, part.kind, True)


def _difference_and_error(a, b, paired: bool) -> tuple[float, float, float, float, str]:
    """(mean difference a - b, its standard error, degrees of freedom, b's mean, why not
    testable or ""): paired over trials, or Welch's for independent samples."""
    if paired:
        d = _differences(a, b)
        why = untestable(d).replace("the sample", "the differences")
        if why:
            return math.nan, math.nan, math.nan, math.nan, why
        b_mean = float(np.asarray(b, dtype=float)[np.isfinite(np.asarray(a, dtype=float))
                                                  & np.isfinite(np.asarray(b, dtype=float))].mean())
        return float(d.mean()), float(d.std(ddof=1) / math.sqrt(len(d))), float(len(d) - 1), b_mean, ""
    a, b = _clean(a), _clean(b)
    why = untestable(a, b)
    if why:
        return math.nan, math.nan, math.nan, math.nan, why
    se, df = welch_error(a.std(ddof=1), len(a), b.std(ddof=1), len(b))
    return float(a.mean() - b.mean()), se, df, float(b.mean()), ""


def welch_error(sd_a: float, n_a: int, sd_b: float, n_b: int) -> tuple[float, float]:
    """The standard error of a difference of two means and its Welch-Satterthwaite degrees of
    freedom, from each sample's standard deviation and size."""
    va, vb = sd_a ** 2 / n_a, sd_b ** 2 / n_b
    df = (va + vb) ** 2 / ((va ** 2 / (n_a - 1) if va else 0.0) + (vb ** 2 / (n_b - 1) if vb else 0.0))
    return float(math.sqrt(va + vb)), float(df)


def equivalent(what: str, a, b, margin: float, *, paired: bool = False, relative: bool = False) -> Part:
    """a and b the same within +-`margin` (of b's mean if `relative`): two one-sided t-tests
    (TOST; Welch's, or paired), each at alpha. Holds when both reject (the difference's
    1 - 2 alpha interval lies inside the margin); fails when the two-sided test finds a
    difference (p < alpha) that is not shown to lie inside the margin; otherwise the trials
    decide neither, and the part is undecided (holds None, its p the TOST's). The statistic
    and p are those of the one-sided test further from rejecting."""
    diff, se, df, b_mean, why = _difference_and_error(a, b, paired)
    if why:
        return _not_testable(what, why, "equivalent")
    return equivalence(what, diff, se, df, margin * abs(b_mean) if relative else margin,
                       f"+-{100 * margin:.3g} % of {b_mean:.4g}" if relative else "",
                       "paired TOST" if paired else "Welch TOST")


def equivalence(what: str, diff: float, se: float, df: float, margin: float, margin_text: str = "",
                test: str = "TOST") -> Part:
    """`equivalent` from a difference of means, its standard error and degrees of freedom (as
    a table of means and standard deviations gives them), against an absolute `margin`."""
    t_low, t_high = (diff + margin) / se, (diff - margin) / se
    p_low, p_high = float(stats.t.sf(t_low, df)), float(stats.t.cdf(t_high, df))
    t, p = (t_low, p_low) if p_low >= p_high else (t_high, p_high)
    p_differ = float(2 * stats.t.sf(abs(diff / se), df))
    half = float(stats.t.ppf(1 - ALPHA, df)) * se
    label = f"{what} (difference {diff:.4g}, {100 * (1 - 2 * ALPHA):.0f} % interval [{diff - half:.4g}, " \
            f"{diff + half:.4g}], margin {margin_text or f'+-{margin:.4g}'}, {test})"
    if p < ALPHA:
        return Part(label, float(t), p, True, name=what, kind="equivalent")
    if p_differ < ALPHA:
        return Part(label, float(t), p, False, f"they differ (two-sided p {p_differ:.4g})", name=what,
                    kind="equivalent")
    return Part(label, float(t), p, None, "the trials show neither a difference nor one inside the margin",
                name=what, kind="equivalent")


def all_equivalent(what: str, samples: Sequence[tuple[str, object, object]], margin: float) -> Part:
    """Every state's shares (name, a, b) the same within +-`margin` (`equivalent`, Welch's):
    `equivalent_family` over the states. A state constant and equal in both samples
    (`IDENTICAL`) is the same by construction and needs no test."""
    parts, identical = [], []
    for name, a, b in samples:
        ca, cb = _clean(a), _clean(b)
        if len(ca) >= 2 and len(cb) >= 2 and np.ptp(ca) == 0 and np.ptp(cb) == 0 and ca[0] == cb[0]:
            identical.append(name)
            continue
        parts.append((name, equivalent(name, a, b, margin)))
    differ = [(name, (lambda a=a, b=b: _welch(a, b))) for name, a, b in samples]
    return equivalent_family(what, parts, differ, margin, len(identical))


def equivalent_family(what: str, parts: Sequence[tuple[str, Part]], differ: Sequence[tuple[str, Callable]],
                      margin: float, n_identical: int = 0) -> Part:
    """Several equivalence parts (one a state) as one: holds when every one holds (an
    intersection-union test, no correction needed); fails when a Holm-corrected family of
    two-sided tests (`differ`, as `holm_none_differ` takes them) finds any state different;
    otherwise undecided. The statistic and p shown are those of the state least sure to be
    inside the margin."""
    aside = f", {n_identical} identical in every trial" if n_identical else ""
    if not parts:
        return _not_testable(what, "every state identical in every trial" if n_identical else "no states",
                             "equivalent")
    name, worst = max(parts, key=lambda np_: np_[1].p_value if math.isfinite(np_[1].p_value) else 1.0)
    label = f"{what} (margin +-{margin:g}; least sure: {name}, TOST over {len(parts)} states{aside}"
    if all(p.holds is True for _, p in parts):
        return Part(label + ")", worst.statistic, worst.p_value, True, name=what, kind="equivalent")
    found = holm_none_differ(what, differ)
    if found.holds is False:
        return Part(f"{label}; {found.what[len(what) + 2:-1]})", worst.statistic, worst.p_value, False,
                    f"a state differs (Holm-adjusted two-sided p {found.p_value:.4g})", name=what, kind="equivalent")
    open_ = ", ".join(n for n, p in parts if p.holds is not True)
    return Part(f"{label}; not shown inside it: {open_})", worst.statistic, worst.p_value, None,
                "the trials show no state different, nor every state inside the margin", name=what,
                kind="equivalent")


def cohens_w(observed_pct: Mapping[str, float], expected_pct: Mapping[str, float]) -> float:
    """Cohen's w of a distribution against an expected one (both in % over the same states):
    sqrt(sum((p - q)^2 / q)) over the states, p and q as proportions."""
    total = 0.0
    for state, q in expected_pct.items():
        p = float(observed_pct.get(state, 0.0)) / 100.0
        q = float(q) / 100.0
        total += (p - q) ** 2 / q
    return math.sqrt(total)


def close_to(what: str, observed_pct: Mapping[str, float], expected_pct: Mapping[str, float],
             bound: float) -> Part:
    """A distribution of means close to an expected one: Cohen's w below `bound`. A comparison of
    means, with no test."""
    if not observed_pct or any(not math.isfinite(float(v)) for v in observed_pct.values()):
        return Part(what, math.nan, math.nan, None, "no trials", what, "means")
    w = cohens_w(observed_pct, expected_pct)
    return Part(f"{what} (Cohen's w {w:.3g}, close below {bound:g})", w, math.nan, bool(w < bound), name=what,
                kind="means")
