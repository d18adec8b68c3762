"""The chapter's claims as tests on per-trial numbers: each verdict, on synthetic trials
whose outcome is plain by construction, and the statistics against hand computation."""

import math
import re

import numpy as np
import pandas as pd
import pytest
from scipy import stats

from tavc_cli.analysis import claims as C
from tavc_cli.analysis import significance as S
from tavc_cli.analysis.chapter_checks import chapter_checks
from tavc_cli.analysis.states import theory_pct

STATES6 = ["0:6", "1:5", "2:4", "3:3", "4:2", "5:1", "6:0"]
STATES5 = ["0:5", "1:4", "2:3", "3:2", "4:1", "5:0"]


def _trials(controller, shares, rate=0.3, n=6, jitter=1.0, **rates):
    """n trials of one controller: state shares (%) around `shares` with a small seeded
    jitter that sums to zero (each trial still sums to 100), and value rates around `rate`."""
    rows = []
    for j in range(n):
        noise = np.random.default_rng(j).normal(0.0, jitter, len(shares))
        noise -= noise.mean()
        row = {"controller": controller, "trial": j, "value_rate_stable": rate + 0.001 * (j % 3),
               "value_rate_convergence": rates.get("convergence", rate) + 0.001 * ((j + 1) % 3),
               "value_rate_before": rates.get("before", rate) + 0.001 * ((j + 2) % 3)}
        row.update({f"pct_{k}": v + e for (k, v), e in zip(shares.items(), noise, strict=True)})
        rows.append(row)
    return pd.DataFrame(rows)


def _peaked(states, peak, height):
    rest = (100.0 - height) / (len(states) - 1)
    return {s: (height if s == peak else rest) for s in states}


def test_welch_statistic_matches_hand_computation():
    # a: mean 2, variance 1; b: mean 1/3, variance 1/3; se = sqrt(1/3 + 1/9) = 2/3, t = (5/3)/(2/3) = 2.5
    part = C.greater("x", [1, 2, 3], [0, 0, 1])
    assert part.statistic == pytest.approx(2.5)
    assert part.holds is True
    # the same test the other way round names the opposite direction
    assert C.less("x", [1, 2, 3], [0, 0, 1]).holds is False


def test_holm_correction_decides_not_different_families():
    def fixed(p):
        return lambda: (1.0, p)

    # raw p 0.01, 0.04, 0.3 -> Holm 0.03, 0.08, 0.3: the smallest rejects at 0.10
    part = C.holm_none_differ("f", [("a", fixed(0.04)), ("b", fixed(0.01)), ("c", fixed(0.3))])
    assert part.holds is False and part.p_value == pytest.approx(0.03) and "most different: b" in part.what
    # raw 0.04, 0.2, 0.5 -> Holm 0.12, 0.4, 0.5: none rejects, though 0.04 alone would have
    part = C.holm_none_differ("f", [("a", fixed(0.04)), ("b", fixed(0.2)), ("c", fixed(0.5))])
    assert part.holds is True and part.p_value == pytest.approx(0.12)
    # nothing testable: no verdict
    assert C.holm_none_differ("f", [("a", fixed(math.nan))]).holds is None


def test_some_differ_is_the_same_holm_family_read_the_other_way():
    def fixed(p, why=""):
        return lambda: (1.0, p, why)

    # raw p 0.01, 0.04, 0.3 -> Holm 0.03 for the smallest: some state differs
    part = C.holm_some_differ("f", [("a", fixed(0.04)), ("b", fixed(0.01)), ("c", fixed(0.3))])
    assert part.holds is True and part.p_value == pytest.approx(0.03) and "most different: b" in part.what
    # raw 0.04, 0.2, 0.5 -> 0.12: none differs after the correction, though 0.04 alone would have
    part = C.holm_some_differ("f", [("a", fixed(0.04)), ("b", fixed(0.2)), ("c", fixed(0.5))])
    assert part.holds is False and part.p_value == pytest.approx(0.12)
    # a state that cannot be tested: unknown while no tested state differs, decided once one does
    # (Holm over the two tested: 2 * 0.01 = 0.02)
    unknown = fixed(math.nan, "one trial")
    part = C.holm_some_differ("f", [("a", fixed(0.3)), ("b", unknown)])
    assert part.holds is None and "one trial (b)" in part.reason
    part = C.holm_some_differ("f", [("a", fixed(0.01)), ("b", unknown), ("c", fixed(0.5))])
    assert part.holds is True and part.p_value == pytest.approx(0.02)
    # a state identical to its reference in every trial is no test and not counted: Holm over one
    part = C.holm_some_differ("f", [("a", fixed(0.06)), ("b", fixed(math.nan, C.IDENTICAL))])
    assert part.holds is True and part.p_value == pytest.approx(0.06) and "1 identical in every trial" in part.what


def test_claim_3_reproduced_when_learners_concentrate_on_3_3():
    runs = {"initial_distribution": pd.concat([
        _trials("tavc", _peaked(STATES6, "3:3", 50.0)), _trials("random", theory_pct(6, 2, "circuits"))])}
    rows = C.claim_rows(runs, only_experiment="initial_distribution").set_index("claim_id")
    assert list(rows.index) == [3, 4, 5]
    assert rows.loc[3, "verdict"] == "reproduced"
    # the headline is the TAVC-against-random comparison of 3:3: 50 % against 31.25 %
    assert rows.loc[3, "statistic"] > 0 and rows.loc[3, "p_value"] < 0.10


def test_claim_3_not_reproduced_when_another_state_is_as_frequent():
    shares = _peaked(STATES6, "3:3", 40.0)
    shares["2:4"], shares["0:6"] = 40.0, shares["0:6"] - (40.0 - shares["2:4"])
    rnd = _trials("random", _peaked(STATES6, "3:3", 31))
    runs = {"initial_distribution": pd.concat([_trials("tavc", shares), rnd])}
    row = C.claim_rows(runs, "initial_distribution").set_index("claim_id").loc[3]
    assert row["verdict"] == "not_reproduced"
    assert "3:3 above 2:4" in row["detail"] and "(fails)" in row["detail"]


def test_claims_are_inconclusive_with_one_trial_or_a_missing_run():
    runs = {"initial_distribution": pd.concat([_trials("tavc", _peaked(STATES6, "3:3", 50.0), n=1),
                                               _trials("random", _peaked(STATES6, "3:3", 31.0), n=1)])}
    rows = C.claim_rows(runs).set_index("claim_id")
    assert rows.loc[3, "verdict"] == "inconclusive" and math.isnan(rows.loc[3, "p_value"])
    # breakdown, breakdown_no_vacancy and value_change were not run
    assert (rows.loc[[6, 7, 8], "verdict"] == "inconclusive").all()


def test_claim_4_is_closeness_to_the_binomial_row_with_the_significance_beside_it():
    theory = theory_pct(6, 2, "circuits")
    near = {"initial_distribution": _trials("random", theory)}
    row = C.claim_rows(near, "initial_distribution").set_index("claim_id").loc[4]
    assert row["verdict"] == "reproduced" and "Cohen's w" in row["detail"]
    # the per-state tests are reported beside the verdict, never inside it
    assert "differs from the binomial theory row in some state" in row["observations"] and "Holm" not in row["detail"]
    # a random row 1.5 points off in every state, with so little spread that every state differs
    # significantly: still close (the chapter's own reading: close, "though the differences are
    # statistically significant")
    off = dict(theory)
    off["3:3"] += 3.0
    off["0:6"] -= 1.5
    off["6:0"] -= 1.5
    sig = {"initial_distribution": _trials("random", off, jitter=0.01)}
    row = C.claim_rows(sig, "initial_distribution").set_index("claim_id").loc[4]
    assert row["verdict"] == "reproduced" and "(holds)" in row["observations"]
    far = {"initial_distribution": _trials("random", _peaked(STATES6, "3:3", 60.0))}
    assert C.claim_rows(far, "initial_distribution").set_index("claim_id").loc[4, "verdict"] == "not_reproduced"


def test_cohens_w_by_hand():
    # Table 1.2's random row against its theory row: sum((p - q)^2 / q) over the states, in proportions
    # 0.6^2/1.6 + 2^2/9.4 + 1.1^2/23.4 + 2.5^2/31.2 + 1.9^2/23.4 + 0.1^2/9.4 + 0.6^2/1.6 = 1.28215 (in %^2 / %)
    observed = {"0:6": 1.0, "1:5": 7.4, "2:4": 22.3, "3:3": 33.7, "4:2": 25.3, "5:1": 9.3, "6:0": 1.0}
    expected = {"0:6": 1.6, "1:5": 9.4, "2:4": 23.4, "3:3": 31.2, "4:2": 23.4, "5:1": 9.4, "6:0": 1.6}
    by_hand = math.sqrt((0.36 / 1.6 + 4 / 9.4 + 1.21 / 23.4 + 6.25 / 31.2 + 3.61 / 23.4 + 0.01 / 9.4 + 0.36 / 1.6)
                        / 100)
    assert S.cohens_w(observed, expected) == pytest.approx(by_hand, rel=1e-12)
    assert by_hand == pytest.approx(0.1132, abs=1e-4)
    assert S.cohens_w(expected, expected) == 0.0


def test_equivalence_two_one_sided_tests_by_hand():
    # a = [1, 2, 3], b = [1, 2, 3] + 0.1: difference -0.1; se = sqrt(1/3 + 1/3) = 0.8165, Welch df = 4
    a, b = [1.0, 2.0, 3.0], [1.1, 2.1, 3.1]
    se = math.sqrt(2 / 3)
    part = S.equivalent("x", a, b, margin=3.0)
    # the test further from rejecting is the upper one: t = (-0.1 - 3) / se, p = P(T_4 > -...) ... the lower:
    t_low, t_high = (-0.1 + 3.0) / se, (-0.1 - 3.0) / se
    p_low, p_high = stats.t.sf(t_low, 4), stats.t.cdf(t_high, 4)
    assert part.p_value == pytest.approx(max(p_low, p_high), rel=1e-9)
    assert part.statistic == pytest.approx(t_low if p_low >= p_high else t_high, rel=1e-9)
    assert part.holds is True  # both below 0.10: p_low = P(T_4 > 3.55) = 0.012
    # a margin of 0.5 the same trials cannot show, nor any difference: undecided
    small = S.equivalent("x", a, b, margin=0.5)
    assert small.holds is None and "neither" in small.reason and "undecided" in small.text()
    # a clear difference beyond the margin: fails
    far = S.equivalent("x", [10.0, 10.5, 11.0], [1.0, 1.5, 2.0], margin=0.5)
    assert far.holds is False and "differ" in far.reason
    # relative margins scale with the reference's mean; paired tests use the differences
    rel = S.equivalent("x", [1.00, 1.01, 0.99, 1.00], [1.0, 1.0, 1.0, 1.01], margin=0.05, paired=True,
                       relative=True)
    assert rel.holds is True and "paired TOST" in rel.what and "5 % of" in rel.what


def test_the_margins_are_the_smallest_differences_the_chapter_calls_significant():
    from tavc_cli.reference import chapter_table

    t13, t15 = chapter_table("1.3").set_index("state"), chapter_table("1.5").set_index("state")
    # Table 1.5 against Table 1.3: "significantly higher values for states 3 : 2 and 4 : 1"
    smallest = min(t15.loc[st, "tavc_mean_pct"] - t13.loc[st, "tavc_mean_pct"] for st in ("3:2", "4:1"))
    assert C.STATE_MARGIN_PCT == pytest.approx(smallest)
    # section 1.6.3: 0.81e-2 against 0.78e-2 value per second, "significantly higher"
    assert C.PERFORMANCE_MARGIN == pytest.approx(0.03 / 0.78)


def test_claim_5_tests_performance_in_the_stable_period():
    runs = {"initial_distribution": pd.concat([_trials("tavc", _peaked(STATES6, "3:3", 50), rate=0.40),
                                               _trials("random", _peaked(STATES6, "3:3", 31), rate=0.35)])}
    assert C.claim_rows(runs, "initial_distribution").set_index("claim_id").loc[5, "verdict"] == "reproduced"
    runs["initial_distribution"].loc[runs["initial_distribution"].controller == "tavc", "value_rate_stable"] -= 0.1
    assert C.claim_rows(runs, "initial_distribution").set_index("claim_id").loc[5, "verdict"] == "not_reproduced"


def test_claim_6_needs_3_2_and_performance_above_random_and_static():
    tavc = _trials("tavc", _peaked(STATES5, "3:2", 50), rate=0.40)
    rnd = _trials("random", _peaked(STATES5, "3:2", 31), rate=0.35)
    static = _trials("static", _peaked(STATES5, "2:3", 90), rate=0.38)
    runs = {"breakdown": pd.concat([tavc, rnd, static])}
    assert C.claim_rows(runs, "breakdown").iloc[0]["verdict"] == "reproduced"
    # the static allocation tuned for six does better: the claim's last part fails
    runs = {"breakdown": pd.concat([tavc, rnd, static.assign(value_rate_stable=0.45)])}
    row = C.claim_rows(runs, "breakdown").iloc[0]
    assert row["verdict"] == "not_reproduced" and "static allocation" in row["detail"]


def test_claim_6_reports_3_2_as_the_most_frequent_state_beside_the_verdict():
    # 3:2 above random, but 2:3 as frequent as 3:2: the chapter states no test of 3:2 against the
    # other states, so the verdict stands and the comparison is reported beside it
    shares = _peaked(STATES5, "3:2", 40)
    shares["2:3"], shares["0:5"] = 40.0, shares["0:5"] - (40.0 - shares["2:3"])
    tavc = _trials("tavc", shares, rate=0.40)
    rnd = _trials("random", _peaked(STATES5, "3:2", 31), rate=0.35)
    static = _trials("static", _peaked(STATES5, "2:3", 90), rate=0.38)
    row = C.claim_rows({"breakdown": pd.concat([tavc, rnd, static])}, "breakdown").iloc[0]
    assert row["verdict"] == "reproduced"
    assert "3:2 above 2:3" in row["observations"] and "3:2 above 2:3" not in row["detail"]


def _no_vacancy(convergence=0.40, before=0.45, breakdown_rate=0.40, breakdown_shares=None):
    shares = _peaked(STATES5, "3:2", 46)
    no_vac = pd.concat([_trials("tavc", shares, rate=0.40, convergence=convergence, before=before, jitter=0.2),
                        _trials("random", _peaked(STATES5, "3:2", 31), rate=0.35)])
    breakdown = _trials("tavc", breakdown_shares or shares, rate=breakdown_rate, jitter=0.2)
    return {"breakdown_no_vacancy": no_vac, "breakdown": breakdown}


def test_claim_7_needs_the_same_distribution_a_fall_and_the_same_performance_after():
    row = C.claim_rows(_no_vacancy(), "breakdown_no_vacancy").iloc[0]
    assert row["verdict"] == "reproduced", row["detail"]
    assert "Welch TOST" in row["detail"] and "paired TOST" in row["detail"]
    # without breakdown's trials the comparison cannot be made
    no_vac = _no_vacancy()["breakdown_no_vacancy"]
    assert C.claim_rows({"breakdown_no_vacancy": no_vac}, "breakdown_no_vacancy").iloc[0]["verdict"] == "inconclusive"
    # no fall when the robot was removed: fails
    row = C.claim_rows(_no_vacancy(before=0.40), "breakdown_no_vacancy").iloc[0]
    assert row["verdict"] == "not_reproduced" and "before the breakdown" in row["detail"]
    # a convergence period far below the stable one: they differ
    assert C.claim_rows(_no_vacancy(convergence=0.30), "breakdown_no_vacancy").iloc[0]["verdict"] == "not_reproduced"
    # breakdown's stable performance 10 % higher, beyond the 3.8 % margin: fails
    row = C.claim_rows(_no_vacancy(breakdown_rate=0.44), "breakdown_no_vacancy").iloc[0]
    assert row["verdict"] == "not_reproduced" and "the same as breakdown's" in row["detail"]


def test_claim_7_is_inconclusive_where_the_trials_show_neither_sameness_nor_a_difference():
    # the two distributions 1 point apart in two states with spreads of several points: no state differs,
    # but 6 trials cannot show them within 2.5 points
    runs = _no_vacancy()
    wide = _trials("tavc", _peaked(STATES5, "3:2", 46), rate=0.40, jitter=4.0)
    runs["breakdown"] = wide
    row = C.claim_rows(runs, "breakdown_no_vacancy").iloc[0]
    assert row["verdict"] == "inconclusive" and "not shown inside it" in row["detail"]


def test_claim_8_needs_every_other_state_below_random_and_performance_back():
    rnd = _trials("random", theory_pct(5, 2, "circuits"), rate=0.35)
    breakdown = _trials("tavc", _peaked(STATES5, "3:2", 40), rate=0.40, jitter=0.3)
    breakdown["pct_4:1"] = 1.0
    # 3:2 at 90 %, every other state at 2 %: below each binomial share (the least is 3.1 %), 4:1 above breakdown's 1 %
    tavc = _trials("tavc", _peaked(STATES5, "3:2", 90), rate=0.40, before=0.40, convergence=0.30, jitter=0.3)
    runs = {"value_change": pd.concat([tavc, rnd]), "breakdown": breakdown}
    assert C.claim_rows(runs, "value_change").iloc[0]["verdict"] == "reproduced"
    lower = _trials("tavc", _peaked(STATES5, "3:2", 90), rate=0.40, before=0.48, convergence=0.30, jitter=0.3)
    row = C.claim_rows({"value_change": pd.concat([lower, rnd]), "breakdown": breakdown}, "value_change").iloc[0]
    assert row["verdict"] == "not_reproduced" and "before it" in row["detail"]
    # no fall after the change: fails
    flat = _trials("tavc", _peaked(STATES5, "3:2", 90), rate=0.40, before=0.40, jitter=0.3)
    row = C.claim_rows({"value_change": pd.concat([flat, rnd]), "breakdown": breakdown}, "value_change").iloc[0]
    assert row["verdict"] == "not_reproduced" and "below the period before the change" in row["detail"]
    # 3:2 and 4:1 are tested against breakdown's: without breakdown's trials the claim is not decided
    row = C.claim_rows({"value_change": pd.concat([tavc, rnd])}, "value_change").iloc[0]
    assert row["verdict"] == "inconclusive" and "breakdown not run" in row["detail"]


def test_section_1_4s_claims_say_whether_their_experiment_ran_without_the_behaviour_learner():
    """Claims 1 and 2 read tables only a learner of behaviours' trials give: a spatiotemporal run
    of another learner is said to be one, not said not to have run."""
    for claim_id in (1, 2):
        row = C.claim_rows({}, "spatiotemporal").set_index("claim_id").loc[claim_id]
        assert row["verdict"] == "inconclusive" and "spatiotemporal not run" in row["detail"]
        ran = {"spatiotemporal": _trials("random", _peaked(STATES5, "3:2", 90), rate=0.3)}
        row = C.claim_rows(ran, "spatiotemporal").set_index("claim_id").loc[claim_id]
        assert row["verdict"] == "inconclusive" and "not run" not in row["detail"]
        assert "spatiotemporal ran no behaviour learner" in row["detail"]


def test_claims_csv_columns_follow_the_contract():
    frame = C.claim_rows({})
    # the contract's columns first, then the observations beside each verdict
    assert list(frame.columns) == ["claim_id", "claim", "verdict", "statistic", "p_value", "detail", "observations"]
    assert frame["claim_id"].tolist() == [1, 2, 3, 4, 5, 6, 7, 8, 9]
    assert set(frame["verdict"]) == {"inconclusive"}
    assert np.isnan(frame["statistic"]).all()


def test_a_share_with_no_spread_leaves_a_not_different_family_not_testable():
    # random always exactly 0 % in 0:6 where theory says 1.5625 %: no t can be computed (it would
    # be infinite), so the family beside claim 4 cannot show that no state differs, and nothing says one does
    shares = dict(theory_pct(6, 2, "circuits"))
    rnd = _trials("random", shares)
    rnd["pct_0:6"] = 0.0
    row = C.claim_rows({"initial_distribution": rnd}, "initial_distribution").set_index("claim_id").loc[4]
    assert "inf" not in row["observations"]
    assert "not testable (no tested state differs, but no spread in the sample (every trial 0 against 1.562) (0:6))" \
        in row["observations"]
    # a state that can be tested and differs still decides the family
    rnd["pct_3:3"] = rnd["pct_3:3"] + 20.0
    row = C.claim_rows({"initial_distribution": rnd}, "initial_distribution").set_index("claim_id").loc[4]
    assert "most different: 3:3" in row["observations"]


def _by_test(checks, claim_id, contains):
    [hit] = [c for c in checks if c["claim_id"] == claim_id and contains in c["test"]]
    return hit


def test_chapter_checks_apply_the_same_tests_to_the_chapter_tables():
    checks = chapter_checks()
    # claim 3 on Table 1.2: (44.5 - 33.7) / sqrt(6.0^2/20 + 2.2^2/20) = 10.8 / 1.4290 = 7.558
    c3 = _by_test(checks, 3, "3:3")
    assert c3["statistic"] == pytest.approx(10.8 / math.sqrt(36 / 20 + 4.84 / 20), rel=1e-9)
    assert c3["holds"] is True
    # claim 8, 3:2 of Table 1.5 (20 trials) above Table 1.3's random (20 trials, Table 1.2's count: the
    # chapter gives none): (48.7 - 32.9) / sqrt(6.1^2/20 + 2.3^2/20) = 15.8 / 1.4577 = 10.839
    c8 = _by_test(checks, 8, "random: time in 3:2")
    assert c8["statistic"] == pytest.approx(15.8 / math.sqrt(6.1 ** 2 / 20 + 2.3 ** 2 / 20), rel=1e-9)
    assert c8["holds"] is True
    # 2:3 is not below random in the chapter's own numbers: (30.3 - 31.0) / sqrt(5.2^2/20 + 2.2^2/20) = -0.55
    c8_23 = _by_test(checks, 8, "time in 2:3")
    assert c8_23["statistic"] == pytest.approx(-0.7 / math.sqrt(5.2 ** 2 / 20 + 2.2 ** 2 / 20), rel=1e-9)
    assert c8_23["holds"] is False and c8_23["p_value"] > 0.1
    # nor is 3:2 above Table 1.3's in them: (48.7 - 46.2) / sqrt(6.1^2/20 + 8.6^2/20) = 1.060
    c8_bd = _by_test(checks, 8, "TAVC: time in 3:2 above")
    assert c8_bd["statistic"] == pytest.approx(2.5 / math.sqrt((6.1 ** 2 + 8.6 ** 2) / 20), rel=1e-9)
    assert c8_bd["holds"] is False
    # claim 7: Tables 1.4 and 1.3 differ by at most 1.1 points in any state, nothing differs, but with
    # stds of 9 points 20 trials a side cannot show 2:3 and 3:2 within 2.5 points: undecided
    c7 = _by_test(checks, 7, "Table 1.4")
    assert c7["holds"] is None and "2:3, 3:2" in c7["test"]
    # claim 4: Cohen's w of Table 1.2's random row 0.113, close; its states differ, beside the claim
    c4 = _by_test(checks, 4, "close to")
    assert c4["statistic"] == pytest.approx(0.1132, abs=1e-4) and c4["holds"] is True and not c4["observation"]
    # and beside it, the chapter's "the differences are statistically significant" on its own table: 1:5 at
    # 7.4 +- 1.6 over 20 trials against 9.4, t = -2 / (1.6 / sqrt(20)) = -5.590, Holm over the 7 states
    c4_some = _by_test(checks, 4, "differs from the theory row in some state")
    assert c4_some["observation"] is True and c4_some["holds"] is True
    assert c4_some["statistic"] == pytest.approx(-2 / (1.6 / math.sqrt(20)), rel=1e-9)
    assert c4_some["p_value"] == pytest.approx(7 * 2 * stats.t.sf(2 / (1.6 / math.sqrt(20)), 19), rel=1e-9)
    # one check per state of Table 1.5 against random and two against Table 1.3, plus claims 3, 4, 6, 7 and 9
    assert len([c for c in checks if c["claim_id"] == 8]) == 8
    assert {c["claim_id"] for c in checks} == {3, 4, 6, 7, 8, 9}
    # claim 9 on Table 1.6 (15 trials each): 3:0 at 2.7 +- 4.1 against 1.7 +- 0.6:
    # t = 1.0 / sqrt(4.1^2/15 + 0.6^2/15) = 0.935, p about 0.18: not significant in the chapter's own numbers,
    # while (2.7 - 1.5) / 1.5 = 0.8 is the largest relative increase over its theory row (printed 0.78;
    # 2:0 next, 2.3 / 4.7 = 0.49)
    c9 = _by_test(checks, 9, "TAVC above random")
    assert c9["statistic"] == pytest.approx(1.0 / math.sqrt((4.1 ** 2 + 0.6 ** 2) / 15), rel=1e-9)
    assert c9["holds"] is False
    c9_rel = _by_test(checks, 9, "relative increase")
    assert c9_rel["statistic"] == pytest.approx(1.2 / 1.5) and c9_rel["holds"] is True


STATES_FS = [f"{f}:{s}" for f in range(4) for s in range(4)]


def _hetero(tavc_peak=30.0, gap_fast=0.05, gap_slow=-0.02, tavc_rate=0.40):
    theory = theory_pct(6, 2, "groups", [3, 3])
    tavc = _trials("tavc", _peaked(STATES_FS, "3:0", tavc_peak), rate=tavc_rate)
    tavc["q_gap_fast"] = gap_fast + 0.001 * np.arange(len(tavc))
    tavc["q_gap_slow"] = gap_slow + 0.002 * (np.arange(len(tavc)) % 2)
    rnd = _trials("random", theory, rate=0.35, jitter=0.0)  # random's means are the binomial row exactly
    return {"heterogeneous": pd.concat([tavc, rnd])}


def test_claim_9_reproduced_when_fast_robots_take_the_high_circuit():
    runs = _hetero()
    row = C.claim_rows(runs, "heterogeneous").iloc[0]
    assert row["claim_id"] == 9 and row["verdict"] == "reproduced", row["detail"]
    # 3:0 near 30 % against the theory row's 1.5625 % (3 fast of 3 high, 0 slow of 3: 100 / 64): (mu - T) / T
    s = runs["heterogeneous"]
    mu = s.loc[s.controller == "tavc", "pct_3:0"].mean()
    assert f"largest: 3:0, {(mu - 1.5625) / 1.5625:.3g}" in row["detail"]


def test_claim_9_parts_fail_one_at_a_time():
    # slow robots with the larger gap between high and low
    row = C.claim_rows(_hetero(gap_fast=0.02, gap_slow=0.05), "heterogeneous").iloc[0]
    assert row["verdict"] == "not_reproduced" and "fast robots above slow" in row["detail"]
    # slow robots that rate the high-value circuit higher too: "the slow robots have higher estimated
    # utilities for servicing the low-value circuit" fails, though the fast robots' gap is larger
    row = C.claim_rows(_hetero(gap_fast=0.05, gap_slow=0.02), "heterogeneous").iloc[0]
    assert row["verdict"] == "not_reproduced"
    assert re.search(r"slow robots below zero [^;]*\(fails\)", row["detail"])
    # performance below random
    assert C.claim_rows(_hetero(tavc_rate=0.30), "heterogeneous").iloc[0]["verdict"] == "not_reproduced"
    # 3:0 at 4 % is above the theory row's 1.56 % but the other states (96/15 = 6.4 % each) rise more
    # relative to theirs where the binomial share is 1.56 % (0:0, 0:3, 3:3): not the largest increase
    row = C.claim_rows(_hetero(tavc_peak=4.0), "heterogeneous").iloc[0]
    assert row["verdict"] == "not_reproduced" and "largest: 3:0" not in row["detail"]


def test_claim_9_is_not_tested_on_a_team_of_three_speed_groups():
    # a member given a group of its own: states are f:m:s, which the claim (3:0) does not speak of
    runs = _hetero()
    s = runs["heterogeneous"].rename(columns=lambda c: c.replace("pct_3:0", "pct_2:0:1"))
    row = C.claim_rows({"heterogeneous": s}, "heterogeneous").iloc[0]
    assert row["verdict"] == "inconclusive"
    assert "compares two speed groups, this team has 2, 3" in row["detail"]


def test_the_claims_about_learning_test_the_learner_they_are_told():
    # a run of another learner: its trials concentrate on 3:3, TAVC's (in the same table) do not
    runs = {"initial_distribution": pd.concat([
        _trials("wolf_phc", _peaked(STATES6, "3:3", 50.0), rate=0.4),
        _trials("tavc", _peaked(STATES6, "0:6", 50.0), rate=0.2),
        _trials("random", theory_pct(6, 2, "circuits"), rate=0.3)])}
    theirs = C.claim_rows(runs, "initial_distribution", learner="wolf_phc").set_index("claim_id")
    assert theirs.loc[3, "verdict"] == "reproduced" and theirs.loc[5, "verdict"] == "reproduced"
    assert "wolf_phc above random" in theirs.loc[5, "detail"] and "TAVC" not in theirs.loc[3, "detail"]
    # TAVC, the default, is tested on its own trials only
    ours = C.claim_rows(runs, "initial_distribution").set_index("claim_id")
    assert ours.loc[3, "verdict"] == "not_reproduced" and ours.loc[5, "verdict"] == "not_reproduced"
    assert "TAVC above random" in ours.loc[5, "detail"]


def test_a_relative_increase_over_no_trials_is_missing_without_a_warning():
    """A learner with no trial of a state (compare's random runs, say) gives no mean and says
    so: no `Mean of empty slice` warning leaks into the command's output."""
    import warnings

    import pandas as pd

    from tavc_cli.analysis.claim_rules import largest_relative_increase

    empty = pd.DataFrame({"controller": pd.Series([], dtype=str), "pct_3:0": pd.Series([], dtype=float),
                          "pct_2:1": pd.Series([], dtype=float)})
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        part = largest_relative_increase(empty, {"3:0": 12.5, "2:1": 37.5}, "3:0")
    assert part.holds is False or part.holds is None
