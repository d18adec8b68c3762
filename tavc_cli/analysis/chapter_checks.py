"""The claims' tests applied to the chapter's own printed tables (from their means, stds and
trial counts): does the chapter's table pass the test tavc applies to ours? A claim has such a
check where its registry entry names one (`Claim.on_tables`: `claim_3` ... `claim_9` here; the
chapter's own claims only, as the tables are the chapter's); each
row is `claim_id,test,statistic,p_value,holds`, and `observation` marks what is reported beside
a claim rather than tested for it. Each check reads the state table of its claim's experiment
and, for a claim that compares two experiments (`Claim.against`), the other's, with the trial
counts their entries give (`Experiment.chapter_trials`).

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
    holm_some_differ,
    welch_error,
)
from tavc_cli.chapter import EXPERIMENTS, claims
from tavc_cli.reference import chapter_table

# trials behind each of the chapter's state tables: (TAVC, random; 0 where it prints no random column)
CHAPTER_TRIALS = {e.state_table: e.chapter_trials for e in EXPERIMENTS.own().values() if e.state_table is not None}


def _tables_of(claim_id: int) -> tuple[str, str | None]:
    """The chapter's state table of the claim's experiment, and of the experiment it is compared with
    (the chapter's own claims only: its tables are the chapter's)."""
    name, found = next((name, c) for name, c in claims(own=True) if c.id == claim_id)
    return EXPERIMENTS[name].state_table, EXPERIMENTS[found.against].state_table if found.against else None


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


def claim_3() -> list[dict]:
    """Claim 3 on its table: time in 3:3, TAVC above random."""
    return [_above_random(3, _tables_of(3)[0], "3:3")]


def claim_4() -> list[dict]:
    """Claim 4 on its table (1.2): the random row close to the theory row (Cohen's w), and, beside it,
    whether random differs from the theory row in some state, Holm-corrected (the chapter: it does)."""
    table_id = _tables_of(4)[0]
    t = _table(table_id)
    n = CHAPTER_TRIALS[table_id][1]
    close = close_to(f"Table {table_id}: random's mean distribution close to the theory row",
                     t["random_mean_pct"].to_dict(), t["theory_pct"].to_dict(), CLOSE_W)
    tests = []
    for state, r in t.iterrows():
        se = r["random_std_pct"] / math.sqrt(n)
        tt = (r["random_mean_pct"] - r["theory_pct"]) / se if se > 0 else math.nan
        p = float(2 * stats.t.sf(abs(tt), n - 1)) if math.isfinite(tt) else math.nan
        tests.append((state, (lambda tt=tt, p=p: (tt, p))))
    return [_from_part(4, close),
            _from_part(4, holm_some_differ(f"Table {table_id}: random differs from the theory row in some state",
                                           tests), True)]


def claim_6() -> list[dict]:
    """Claim 6 on its table: time in 3:2, TAVC above random."""
    return [_above_random(6, _tables_of(6)[0], "3:2")]


def claim_7() -> list[dict]:
    """Claim 7's distribution part: its table (1.4) the same as the TAVC rows of the table it is
    compared with (1.3), state by state within STATE_MARGIN_PCT (Welch TOST from the tables'
    means and stds)."""
    own, other = _tables_of(7)
    nv, bd = _table(own), _table(other)
    n_nv, n_bd = CHAPTER_TRIALS[own][0], CHAPTER_TRIALS[other][0]
    parts, differ = [], []
    for st in nv.index:
        a, b = nv.loc[st], bd.loc[st]
        se, df = welch_error(a["tavc_std_pct"], n_nv, b["tavc_std_pct"], n_bd)
        parts.append((st, equivalence(st, float(a["tavc_mean_pct"] - b["tavc_mean_pct"]), se, df,
                                      STATE_MARGIN_PCT, test="Welch TOST")))
        differ.append((st, (lambda a=a, b=b: _welch(a, n_nv, b, n_bd, "tavc", "tavc", "two-sided"))))
    return [_from_part(7, equivalent_family(f"Table {own} the same as Table {other}'s TAVC distribution", parts,
                                            differ, STATE_MARGIN_PCT))]


def claim_8() -> list[dict]:
    """Claim 8 on its table (1.5): 3:2 and 4:1 above the TAVC rows of the table it is compared
    with (1.3); then each state against that table's random column. Table 1.5 prints no random
    column; the only random run the chapter prints for five robots is Table 1.3's."""
    own, other = _tables_of(8)
    vc, bd = _table(own), _table(other)
    n_vc, (n_bd, n_r) = CHAPTER_TRIALS[own][0], CHAPTER_TRIALS[other]
    out = []
    for st in ("3:2", "4:1"):
        t, p = _welch(vc.loc[st], n_vc, bd.loc[st], n_bd, "tavc", "tavc", "greater")
        out.append(_row(8, f"Table {own} against Table {other}'s TAVC: time in {st} above (Welch one-sided)", t, p,
                        bool(p < ALPHA)))
    for st in vc.index:
        above = st == "3:2"
        t, p = _welch(vc.loc[st], n_vc, bd.loc[st], n_r, "tavc", "random", "greater" if above else "less")
        out.append(_row(8, f"Table {own} against Table {other}'s random: time in {st}, TAVC "
                           f"{'above' if above else 'below'} random (Welch one-sided)", t, p, bool(p < ALPHA)))
    return out


def claim_9() -> list[dict]:
    """Claim 9 on its table (1.6): time in 3:0 above random; and, a comparison of means, the
    relative increase over the theory row largest in 3:0."""
    table_id = _tables_of(9)[0]
    t = _table(table_id)
    rel = (t["tavc_mean_pct"] - t["theory_pct"]) / t["theory_pct"]
    return [_above_random(9, table_id, "3:0"),
            _row(9, f"Table {table_id}: relative increase over the theory row largest in 3:0 (largest: "
                    f"{rel.idxmax()}, {rel.max():.3g}; a comparison of means)", float(rel["3:0"]), math.nan,
                 bool(rel.idxmax() == "3:0"))]


def chapter_checks() -> list[dict]:
    """Every check the chapter's claims name (`Claim.on_tables`), claim by claim."""
    return [row for _, found in claims(own=True) if (check := found.table_check()) is not None for row in check()]
