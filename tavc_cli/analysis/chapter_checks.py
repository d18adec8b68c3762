"""The claims' tests applied to the chapter's own printed tables (from their means, stds and
trial counts): does the chapter's table pass the test tavc applies to ours? Claims 3, 4, 6,
7, 8 and 9 have such a check; each row is `claim_id,test,statistic,p_value,holds`."""

from __future__ import annotations

import math

import pandas as pd
from scipy import stats

from tavc_cli.analysis.claims import ALPHA, Part, holm_none_differ
from tavc_cli.reference import chapter_table

# trials behind each of the chapter's state tables: (TAVC, random; 0 where it prints no random column)
CHAPTER_TRIALS = {"1.2": (20, 20), "1.3": (20, 5), "1.4": (20, 0), "1.5": (20, 0), "1.6": (15, 15)}


def _table(table_id: str) -> pd.DataFrame:
    return chapter_table(table_id).set_index("state")


def _welch(a: pd.Series, n_a: int, b: pd.Series, n_b: int, a_col: str, b_col: str,
           alternative: str) -> tuple[float, float]:
    """Welch's t-test from two table rows' `<col>_mean_pct` and `<col>_std_pct`."""
    res = stats.ttest_ind_from_stats(a[f"{a_col}_mean_pct"], a[f"{a_col}_std_pct"], n_a,
                                     b[f"{b_col}_mean_pct"], b[f"{b_col}_std_pct"], n_b,
                                     equal_var=False, alternative=alternative)
    return float(res.statistic), float(res.pvalue)


def _row(claim_id: int, test: str, statistic: float, p_value: float, holds: bool | None) -> dict:
    return {"claim_id": claim_id, "test": test, "statistic": statistic, "p_value": p_value, "holds": holds}


def _from_part(claim_id: int, part: Part) -> dict:
    return _row(claim_id, part.what, part.statistic, part.p_value, part.holds)


def _above_random(claim_id: int, table_id: str, state: str) -> dict:
    t = _table(table_id)
    n_t, n_r = CHAPTER_TRIALS[table_id]
    stat, p = _welch(t.loc[state], n_t, t.loc[state], n_r, "tavc", "random", "greater")
    return _row(claim_id, f"Table {table_id}: time in {state}, TAVC above random (Welch one-sided)", stat, p,
                bool(p < ALPHA))


def _random_against_theory() -> dict:
    """Claim 4 on Table 1.2: each state's random share against the theory row, Holm-corrected."""
    t = _table("1.2")
    n = CHAPTER_TRIALS["1.2"][1]
    tests = []
    for state, r in t.iterrows():
        se = r["random_std_pct"] / math.sqrt(n)
        tt = (r["random_mean_pct"] - r["theory_pct"]) / se if se > 0 else math.nan
        p = float(2 * stats.t.sf(abs(tt), n - 1)) if math.isfinite(tt) else math.nan
        tests.append((state, (lambda tt=tt, p=p: (tt, p))))
    return _from_part(4, holm_none_differ("Table 1.2: random against the theory row", tests))


def _no_vacancy_against_breakdown() -> dict:
    """Claim 7's distribution part: Table 1.4 against Table 1.3's TAVC rows."""
    nv, bd = _table("1.4"), _table("1.3")
    n_nv, n_bd = CHAPTER_TRIALS["1.4"][0], CHAPTER_TRIALS["1.3"][0]
    tests = [(st, (lambda st=st: _welch(nv.loc[st], n_nv, bd.loc[st], n_bd, "tavc", "tavc", "two-sided")))
             for st in nv.index]
    return _from_part(7, holm_none_differ("Table 1.4 against Table 1.3's TAVC distribution, Welch two-sided", tests))


def _value_change_against_random() -> list[dict]:
    """Claim 8's state parts. Table 1.5 prints no random column; the only random run the chapter
    prints for five robots is Table 1.3's (5 trials), used here."""
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
    return [_above_random(3, "1.2", "3:3"), _above_random(6, "1.3", "3:2"), _random_against_theory(),
            _no_vacancy_against_breakdown(), *_value_change_against_random(), _above_random(9, "1.6", "3:0"),
            _largest_relative_increase()]
