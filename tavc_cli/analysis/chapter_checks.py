"""The claims' tests applied to the chapter's own printed tables (from their means, stds and
trial counts): does the chapter's table pass the test tavc applies to ours? Claims 3, 4, 6,
7, 8 and 9 have such a check; each row is `claim_id,test,statistic,p_value,holds`, and
`observation` marks what is reported beside a claim rather than tested for it.

The chapter gives no count of random trials for Tables 1.3-1.5; they are read as Table 1.2's 20."""

from __future__ import annotations

import math

import pandas as pd
from scipy import stats

from tavc_cli.analysis.claim_rules import CLOSE_W, STATE_MARGIN_PCT
from tavc_cli.analysis.significance import (
    ALPHA,
    Part,
    close_to,
    equivalence,
    equivalent_family,
    holm_none_differ,
    welch_error,
)
from tavc_cli.chapter import EXPERIMENTS
from tavc_cli.reference import chapter_table

# trials behind each of the chapter's state tables: (TAVC, random; 0 where it prints no random column)
CHAPTER_TRIALS = {e.state_table: e.chapter_trials for e in EXPERIMENTS.own().values() if e.state_table is not None}


def _table(table_id: str) -> pd.DataFrame:
    return chapter_table(table_id).set_index("state")


def _welch(a: pd.Series, n_a: int, b: pd.Series, n_b: int, a_col: str, b_col: str,
           alternative: str) -> tuple[float, float]:
    """Welch's t-test from two table rows' `<col>_mean_pct` and `<col>_std_pct`."""
    res = stats.ttest_ind_from_stats(a[f"{a_col}_mean_pct"], a[f"{a_col}_std_pct"], n_a,
                                     b[f"{b_col}_mean_pct"], b[f"{b_col}_std_pct"], n_b,
                                     equal_var=False, alternative=alternative)
    return float(res.statistic), float(res.pvalue)


def _row(claim_id: int, test: str, statistic: float, p_value: float, holds: bool | None,
         observation: bool = False) -> dict:
    return {"claim_id": claim_id, "test": test, "statistic": statistic, "p_value": p_value, "holds": holds,
            "observation": observation}


def _from_part(claim_id: int, part: Part, observation: bool = False) -> dict:
    return _row(claim_id, part.what, part.statistic, part.p_value, part.holds, observation)


def _above_random(claim_id: int, table_id: str, state: str) -> dict:
    t = _table(table_id)
    n_t, n_r = CHAPTER_TRIALS[table_id]
    stat, p = _welch(t.loc[state], n_t, t.loc[state], n_r, "tavc", "random", "greater")
    return _row(claim_id, f"Table {table_id}: time in {state}, TAVC above random (Welch one-sided)", stat, p,
                bool(p < ALPHA))


def _random_against_theory() -> list[dict]:
    """Claim 4 on Table 1.2: the random row close to the theory row (Cohen's w), and, beside it,
    each state's random share against the theory row, Holm-corrected (the chapter: significant)."""
    t = _table("1.2")
    n = CHAPTER_TRIALS["1.2"][1]
    close = close_to("Table 1.2: random's mean distribution close to the theory row",
                     t["random_mean_pct"].to_dict(), t["theory_pct"].to_dict(), CLOSE_W)
    tests = []
    for state, r in t.iterrows():
        se = r["random_std_pct"] / math.sqrt(n)
        tt = (r["random_mean_pct"] - r["theory_pct"]) / se if se > 0 else math.nan
        p = float(2 * stats.t.sf(abs(tt), n - 1)) if math.isfinite(tt) else math.nan
        tests.append((state, (lambda tt=tt, p=p: (tt, p))))
    return [_from_part(4, close),
            _from_part(4, holm_none_differ("Table 1.2: random against the theory row, each state", tests), True)]


def _no_vacancy_against_breakdown() -> dict:
    """Claim 7's distribution part: Table 1.4 the same as Table 1.3's TAVC rows, state by state
    within STATE_MARGIN_PCT (Welch TOST from the tables' means and stds)."""
    nv, bd = _table("1.4"), _table("1.3")
    n_nv, n_bd = CHAPTER_TRIALS["1.4"][0], CHAPTER_TRIALS["1.3"][0]
    parts, differ = [], []
    for st in nv.index:
        a, b = nv.loc[st], bd.loc[st]
        se, df = welch_error(a["tavc_std_pct"], n_nv, b["tavc_std_pct"], n_bd)
        parts.append((st, equivalence(st, float(a["tavc_mean_pct"] - b["tavc_mean_pct"]), se, df,
                                      STATE_MARGIN_PCT, test="Welch TOST")))
        differ.append((st, (lambda a=a, b=b: _welch(a, n_nv, b, n_bd, "tavc", "tavc", "two-sided"))))
    return _from_part(7, equivalent_family("Table 1.4 the same as Table 1.3's TAVC distribution", parts, differ,
                                           STATE_MARGIN_PCT))


def _value_change_against_breakdown() -> list[dict]:
    """Claim 8's first parts: Table 1.5's 3:2 and 4:1 above Table 1.3's TAVC rows."""
    vc, bd = _table("1.5"), _table("1.3")
    n_vc, n_bd = CHAPTER_TRIALS["1.5"][0], CHAPTER_TRIALS["1.3"][0]
    out = []
    for st in ("3:2", "4:1"):
        t, p = _welch(vc.loc[st], n_vc, bd.loc[st], n_bd, "tavc", "tavc", "greater")
        out.append(_row(8, f"Table 1.5 against Table 1.3's TAVC: time in {st} above (Welch one-sided)", t, p,
                        bool(p < ALPHA)))
    return out


def _value_change_against_random() -> list[dict]:
    """Claim 8's state parts against random. Table 1.5 prints no random column; the only random
    run the chapter prints for five robots is Table 1.3's, used here."""
    vc, rnd = _table("1.5"), _table("1.3")
    n_vc, n_r = CHAPTER_TRIALS["1.5"][0], CHAPTER_TRIALS["1.3"][1]
    out = []
    for st in vc.index:
        above = st == "3:2"
        t, p = _welch(vc.loc[st], n_vc, rnd.loc[st], n_r, "tavc", "random", "greater" if above else "less")
        out.append(_row(8, f"Table 1.5 against Table 1.3's random: time in {st}, TAVC "
                           f"{'above' if above else 'below'} random (Welch one-sided)", t, p, bool(p < ALPHA)))
    return out


def _largest_relative_increase() -> dict:
    """Claim 9's comparison of means on Table 1.6: the relative increase over the theory row."""
    t = _table("1.6")
    rel = (t["tavc_mean_pct"] - t["theory_pct"]) / t["theory_pct"]
    return _row(9, f"Table 1.6: relative increase over the theory row largest in 3:0 (largest: {rel.idxmax()}, "
                   f"{rel.max():.3g}; a comparison of means)", float(rel["3:0"]), math.nan, bool(rel.idxmax() == "3:0"))


def chapter_checks() -> list[dict]:
    """Every check, claim by claim."""
    return [_above_random(3, "1.2", "3:3"), *_random_against_theory(), _above_random(6, "1.3", "3:2"),
            _no_vacancy_against_breakdown(), *_value_change_against_breakdown(), *_value_change_against_random(),
            _above_random(9, "1.6", "3:0"), _largest_relative_increase()]
