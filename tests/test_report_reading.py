"""What a reader of the chapter sees in the report and the console: runs below the chapter's
scale are headed "not a verdict", a statistic that cannot be computed is "not testable" with
its reason (never t = -inf), the p shown is the part that decides the verdict, every run of a
sweep is reported, heat maps have colour bars and error bars of a share stay within 0-100 %.

The runs are hand-made tables (no simulation): initial_distribution folders whose config.yaml
is composed at the scale asked, with per-trial shares chosen so each outcome is plain."""

from __future__ import annotations

import json
import math
import re
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pandas as pd
import pytest

from tavc_cli import config
from tavc_cli.analysis import claims as C
from tavc_cli.report.text import p_cell
from tavc_cli.settings import to_yaml

STATES = ["0:6", "1:5", "2:4", "3:3", "4:2", "5:1", "6:0"]
THEORY = [1.5625, 9.375, 23.4375, 31.25, 23.4375, 9.375, 1.5625]  # 100 * C(6, k) / 64


def _run(folder: Path, *overrides: str, trials: int = 6, spread: float = 1.0, seed: int = 0) -> Path:
    """A finished initial_distribution run folder of hand-made tables: `trials` TAVC and random
    trials around the binomial shares, TAVC with more 3:3; `spread` 0 makes every trial the same."""
    cfg = config.settings(config.load_config(["experiment=initial_distribution", *overrides,
                                              f"output_dir=\"{folder}\""]))
    folder.mkdir(parents=True)
    (folder / "config.yaml").write_text(to_yaml(cfg))
    (folder / "provenance.json").write_text(json.dumps({"trials": [], "wall_time_s": 1.0}))
    rng = np.random.default_rng(seed)
    rows = []
    for controller, lift, rate in (("tavc", 10.0, 0.40), ("random", 0.0, 0.35)):
        for j in range(trials):
            shares = np.array(THEORY) + np.array([0, 0, 0, lift, 0, 0, 0]) + rng.normal(0, spread, 7)
            shares = 100 * np.clip(shares, 0, None) / np.clip(shares, 0, None).sum()
            row = {"controller": controller, "trial": j, "duration_s": float(cfg.duration_s),
                   "value_rate_stable": rate + spread * 0.01 * rng.normal(), "value_rate_convergence": math.nan,
                   "value_rate_before": math.nan, "settle_s": math.nan, "policy_settle_s": math.nan,
                   "policy_changes": math.nan}
            row.update({f"pct_{s}": v for s, v in zip(STATES, shares, strict=True)})
            rows.append(row)
    stats = pd.DataFrame(rows)
    stats.to_csv(folder / "trial_stats.csv", index=False)
    table = [{"state": s, "controller": c, "mean_pct": g[f"pct_{s}"].mean(), "std_pct": g[f"pct_{s}"].std(ddof=1),
              "n_trials": len(g)} for c, g in stats.groupby("controller", sort=False) for s in STATES]
    table += [{"state": s, "controller": "theory", "mean_pct": v, "std_pct": 0.0, "n_trials": 0}
              for s, v in zip(STATES, THEORY, strict=True)]
    pd.DataFrame(table).to_csv(folder / "state_time.csv", index=False)
    return folder


def _report(root: Path) -> tuple[str, list[str]]:
    from tavc_cli.report import build_report, summary_lines

    result = build_report(root)
    return (root / "REPORT.md").read_text(), summary_lines(result)


# --- 1. runs below the chapter's scale are not verdicts -------------------------------------------


def _settings(*overrides: str):
    return config.settings(config.load_config(["experiment=initial_distribution", *overrides]))


def test_what_falls_short_of_the_chapter_by_hand():
    # quick: 6 trials of the chapter's 20, a quarter of its 18000 s (4500 / 18000 = 0.25)
    assert C.not_a_verdict(_settings("scale=quick")) == ("not a verdict: scale=quick (6 of the chapter's 20 trials, "
                                                         "0.25 of its duration)")
    # the chapter's own scale, and forty times its durations at its trial counts, are verdicts
    assert C.not_a_verdict(_settings("scale=paper")) == ""
    assert C.not_a_verdict(_settings("scale=converged")) == ""
    # ten times the durations but 8 trials: fewer trials is below the chapter, however long they run
    assert C.not_a_verdict(_settings("scale=long")) == "not a verdict: scale=long (8 of the chapter's 20 trials)"
    # the chapter's scale with fewer trials asked for is below it too
    assert C.scale_shortfall(_settings("scale=paper", "trials=19")) == "19 of the chapter's 20 trials"


@pytest.mark.parametrize(("baselines", "short"), [
    ("[random,static]", "6 of the chapter's 20 baseline trials, 6 of the chapter's 20 static trials, "),
    ("[random]", "6 of the chapter's 20 baseline trials, "),
    ("[static]", "6 of the chapter's 20 static trials, "),
    ("[]", ""),
])
def test_only_the_baselines_a_run_has_fall_short(baselines, short):
    """breakdown at quick: 6 trials of each controller where the chapter ran 20; a baseline the run
    does not have ran no trials, and is not said to have run too few."""
    cfg = config.settings(config.load_config(["experiment=breakdown", "scale=quick", f"baselines={baselines}"]))
    assert C.scale_shortfall(cfg) == f"6 of the chapter's 20 trials, {short}0.25 of its duration"


@pytest.mark.parametrize("scale", ["smoke", "quick"])
def test_a_report_of_runs_below_the_chapters_scale_is_headed_not_a_verdict(tmp_path, scale):
    _run(tmp_path / "initial_distribution", f"scale={scale}")
    text, console = _report(tmp_path)
    head = text.split("\n## ")[0]
    assert f"not a verdict: scale={scale}" in head
    # the heading comes before any count of claims, and the count is not read as a verdict
    assert head.index(f"not a verdict: scale={scale}") < head.index("Claims (not a verdict)")
    assert "Claims reproduced" not in text
    rows = [line for line in head.splitlines() if re.match(r"\| [345] \|", line)]
    assert len(rows) == 3 and all("| would be: " in row or "| not testable |" in row for row in rows)
    assert console[0].startswith(f"not a verdict: scale={scale} (initial_distribution: ")
    # the experiment's own claims table says the same
    section = text.split("\n## initial_distribution")[1]
    assert f"This run is not a verdict: scale={scale}" in section and "**would be: " in section


def test_a_report_of_runs_at_the_chapters_scale_is_a_verdict(tmp_path):
    _run(tmp_path / "initial_distribution", "scale=paper", trials=20)
    text, console = _report(tmp_path)
    assert "not a verdict" not in text and "would be" not in text
    assert text.split("\n## ")[0].count("**Claims reproduced: ") == 1
    assert console[0].startswith("claims reproduced: ")


def test_the_run_summary_of_a_quick_run_is_headed_not_a_verdict(tmp_path):
    from tavc_cli.console import summary_text

    folder = _run(tmp_path / "initial_distribution", "scale=quick")
    claims = C.claim_rows({"initial_distribution": pd.read_csv(folder / "trial_stats.csv")}, "initial_distribution")
    text = summary_text({"output_dir": str(folder), "n_trials": 12, "n_reused": 0, "wall_time_s": 1.0,
                         "tables": {}, "claims": claims})
    assert "not a verdict: scale=quick (6 of the chapter's 20 trials, 0.25 of its duration)" in text
    assert re.search(r"^claim 3: would be: ", text, re.M) and not re.search(r"^claim \d: reproduced", text, re.M)


# --- 2. no t = -inf: what cannot be computed is not testable, with its reason ---------------------


def test_zero_spread_is_not_testable_with_its_reason_in_the_report_and_the_console(tmp_path):
    from tavc_cli.console import summary_text

    folder = _run(tmp_path / "initial_distribution", "scale=paper", trials=20, spread=0.0)
    text, console = _report(tmp_path)
    claims = pd.read_csv(tmp_path / "claims.csv").set_index("claim_id")
    # every TAVC trial the same and every random trial the same: no t can be computed for claim 3's
    # comparison with random nor for claim 5's; claim 4's random shares never move off the theory row,
    # which is as close as a distribution gets (Cohen's w 0)
    for cid in (3, 5):
        assert claims.loc[cid, "verdict"] == "inconclusive"
        assert "not testable" in claims.loc[cid, "detail"]
    assert claims.loc[4, "verdict"] == "reproduced" and "Cohen's w 0," in claims.loc[4, "detail"]
    assert "time in 3:3, TAVC above random (%): not testable (no spread in either sample)" in claims.loc[3, "detail"]
    assert claims.loc[5, "not_testable_because"] == ("score per second in the stable period, TAVC above random: "
                                                     "no spread in either sample")
    row = next(line for line in text.splitlines() if line.startswith("| 5 | initial_distribution |"))
    assert "| inconclusive | (inconclusive: score per second in the stable period, TAVC above random: no spread " \
           "in either sample) |" in row
    frame = C.claim_rows({"initial_distribution": pd.read_csv(folder / "trial_stats.csv")}, "initial_distribution")
    run_text = summary_text({"output_dir": str(folder), "n_trials": 40, "n_reused": 0, "wall_time_s": 1.0,
                             "tables": {}, "claims": frame})
    assert "claim 5: inconclusive (score per second in the stable period, TAVC above random: no spread in either " \
           "sample)" in run_text
    for words in (text, "\n".join(console), run_text, (tmp_path / "claims.csv").read_text()):
        assert "-inf" not in words and not re.search(r"\binf\b", words)


def test_a_constant_share_against_the_theory_row_is_not_an_infinite_t():
    # every random trial 0 % in 6:0, the theory row 1.5625 %: the old rule gave t = -inf, p = 0
    rnd = pd.DataFrame([{"controller": "random", "trial": j, "value_rate_stable": 0.3,
                         **{f"pct_{s}": v + (0.5 * (-1) ** j if s in ("2:4", "4:2") else 0.0)
                            for s, v in zip(STATES, THEORY, strict=True)}} for j in range(4)])
    rnd["pct_6:0"] = 0.0
    part = C.claim_4({"initial_distribution": rnd})[1]  # the per-state tests, beside claim 4's verdict
    assert part.observation
    assert part.holds is None and math.isnan(part.statistic) and math.isnan(part.p_value)
    assert "no spread in the sample (every trial 0 against 1.562) (6:0)" in part.reason


# --- 3. the p shown is the part that decides -----------------------------------------------------


def _fixed(parts):
    return lambda runs, learner="tavc": parts


def test_the_p_shown_is_the_failing_part_not_the_first(monkeypatch, tmp_path):
    from tavc_cli.report.text import claims_table, p_cell

    holds = C.Part("sub-test 1 (numbers)", 2.0, 0.05, True, name="sub-test 1")
    fails = C.Part("sub-test 2 (numbers)", -0.3, 0.6, False, name="sub-test 2")
    assert C.deciding([holds, fails]) is fails
    monkeypatch.setitem(C.TESTS, 5, _fixed([holds, fails]))
    row = C.claim_table({}, "initial_distribution").set_index("claim_id").loc[5]
    # by hand: claim 5 fails because sub-test 2 does; its p is 0.6, the first part's 0.05 decides nothing
    assert row["verdict"] == "not_reproduced"
    assert row["deciding_p_value"] == 0.6 and row["deciding_test"] == "sub-test 2"
    assert row["p_value"] == 0.05  # claims.csv's p_value stays the headline part's, as every run writes it
    table = C.claim_table({}, "initial_distribution")
    line = next(x for x in claims_table(table[table["claim_id"] == 5]) if x.startswith("| 5:"))
    assert "| -0.30 | 0.6 | sub-test 2 |" in line
    assert p_cell(next(table[table["claim_id"] == 5].itertuples())) == "0.6 (sub-test 2)"


def test_a_comparison_of_means_shows_its_value_under_p_named_as_a_value():
    """A part with no test (claim 4's Cohen's w) shows the value it compares where the others show
    their p, said to be a value, so that it is not read as a p."""
    row = SimpleNamespace(verdict="reproduced", p_value=math.nan, deciding_p_value=math.nan,
                          deciding_statistic=0.0916443, deciding_test="close to the theory row",
                          deciding_holds_if="a comparison of means, no test")
    assert p_cell(row) == "value 0.0916 (close to the theory row (a comparison of means, no test))"


def test_the_deciding_part_by_hand():
    a = C.Part("a", 1.0, 0.01, True, name="a")
    b = C.Part("b", 1.0, 0.08, True, name="b")
    # every part holds: the one closest to failing, the largest p of those needing p < 0.10
    assert C.deciding([a, b]) is b
    c = C.Part("c", 1.0, 0.3, False, name="c")
    d = C.Part("d", 1.0, 0.9, False, name="d")
    # two fail: the one furthest from holding, the largest p
    assert C.deciding([a, c, d]) is d
    # a "not different" part fails on a small p: 0.001 lies further from 0.10 (a factor 100) than 0.3 (3)
    same = C.Part("s", 4.0, 0.001, False, name="s", kind="same")
    assert C.deciding([c, same]) is same
    # nothing fails but something cannot be tested: that part, with no p
    unknown = C.Part("u", math.nan, math.nan, None, "one trial", "u")
    assert C.deciding([a, unknown]) is unknown


def test_a_holding_claim_shows_its_weakest_part_in_the_report(tmp_path):
    _run(tmp_path / "initial_distribution", "scale=paper", trials=20)
    text, _ = _report(tmp_path)
    claims = pd.read_csv(tmp_path / "claims.csv").set_index("claim_id")
    parts = C.claim_3({"initial_distribution": pd.read_csv(tmp_path / "initial_distribution" / "trial_stats.csv")})
    assert all(p.holds for p in parts)
    weakest = max(parts, key=lambda p: p.p_value)
    assert claims.loc[3, "deciding_p_value"] == pytest.approx(weakest.p_value, rel=1e-5)
    row = next(line for line in text.splitlines() if line.startswith("| 3 | initial_distribution |"))
    assert f"{weakest.p_value:.3g} ({weakest.question})" in row


# --- 4. every run of a sweep is reported -----------------------------------------------------------


def test_a_sweeps_jobs_two_levels_down_are_all_reported(tmp_path):
    sweep = tmp_path / "initial_distribution"
    jobs = [_run(sweep / f"{k}_seed={k + 1}", "scale=paper", f"seed={k + 1}", trials=20, seed=k) for k in range(3)]
    (sweep / "sweep.csv").write_text("job,seed\n0,1\n1,2\n2,3\n")
    text, console = _report(tmp_path)
    # the claims on the first job by name (none is named after the experiment), each other job a section
    assert "The claims are tested on `initial_distribution/0_seed=1` (the first by name" in text
    for job in jobs[1:]:
        name = job.relative_to(tmp_path).as_posix()
        assert f"\n### {name}: another run of initial_distribution\n" in text
        assert (tmp_path / "figures" / "runs" / name / "fig_1_6.png").is_file()
    runs = text.split("\n## The runs in this folder\n")[1].split("\n## ")[0]
    for job in jobs:
        assert f"| `{job.relative_to(tmp_path).as_posix()}` | initial_distribution | paper | 20 |" in runs
    assert "| 3 | initial_distribution (`initial_distribution/0_seed=1`) |" in text
    assert ("also reported, in sections of their own: initial_distribution/1_seed=2, initial_distribution/2_seed=3 "
            "(initial_distribution; its claims tested on initial_distribution/0_seed=1)") in console


def test_two_runs_of_one_experiment_side_by_side_are_both_reported(tmp_path):
    _run(tmp_path / "cmp" / "initial_distribution", "scale=paper", "seed=2", trials=20, seed=2)
    _run(tmp_path / "alone", "scale=paper", trials=20, seed=1)
    text, _ = _report(tmp_path)
    assert "The claims are tested on `cmp/initial_distribution` (the folder named after the experiment)" in text
    assert "\n### alone: another run of initial_distribution\n" in text


# --- 5. figures: colour bars on heat maps, error bars and bands within a share's range ------------


def test_the_lane_heat_map_has_a_colour_bar_for_every_panel():
    from tavc_cli.viz.spatial import lane_fig, plt

    cells = [{"window": w, "direction": d, "x_m": x, "y_m": y, "count": 1 + x + y}
             for w in ("early", "late") for d in ("to_sink", "to_source") for x in (0.5, 1.0, 1.5) for y in (0.5, 1.0)]
    fig = lane_fig(pd.DataFrame(cells), (0.5, 0.5), (1.5, 1.0), "lanes")
    try:
        panels = [ax for ax in fig.axes if ax.get_images()]
        bars = [ax for ax in fig.axes if ax.get_label() == "<colorbar>"]
        assert len(panels) == 4 and len(bars) == 4  # two windows by two directions, each scaled on its own
    finally:
        plt.close(fig)


def test_error_bars_of_a_share_stay_between_0_and_100():
    from tavc_cli.viz.figures import clipped_band, clipped_err, plt, state_fig

    # by hand: 1 % +- 5 reaches down to 0, not -4; 98 % +- 5 up to 100, not 103; 50 % +- 5 both ways
    err = clipped_err([1.0, 98.0, 50.0], [5.0, 5.0, 5.0], 0.0, 100.0)
    assert err.tolist() == [[1.0, 5.0, 5.0], [5.0, 2.0, 5.0]]
    lo, hi = clipped_band(np.array([0.1, 0.9]), np.array([0.3, 0.3]), 0.0, 1.0)
    assert lo.tolist() == pytest.approx([0.0, 0.6]) and hi.tolist() == pytest.approx([0.4, 1.0])
    table = pd.DataFrame([{"state": s, "controller": c, "mean_pct": m, "std_pct": sd, "n_trials": 20}
                          for s, m, sd in (("0:2", 1.0, 5.0), ("1:1", 98.0, 5.0), ("2:0", 1.0, 0.5))
                          for c in ("tavc", "random")])
    fig = state_fig(table, None, "shares")
    try:
        ax = fig.axes[0]
        ends = [seg[:, 1] for c in ax.containers if getattr(c, "errorbar", None) is not None
                for seg in c.errorbar.lines[2][0].get_segments()]
        assert ends and min(e.min() for e in ends) == 0.0 and max(e.max() for e in ends) == 100.0
        # each legend entry says what the bars are and over how many trials
        assert {t.get_text() for t in ax.get_legend().get_texts()} == {"TAVC: mean ± std over 20 trials",
                                                                      "random: mean ± std over 20 trials"}
    finally:
        plt.close(fig)


def test_the_model_summary_marks_an_interval_below_zero():
    from tavc_cli.model.report import model_text

    # a rate over few trials, 0.01 +- 0.02 per s: its lower bound -0.01 is no rate a robot could have
    table = pd.DataFrame([{"n_robots": 2, "state": "1:1", "circuit": c, "n_on_circuit": 1, "c_per_s": 0.01,
                           "c_lo": lo, "c_hi": 0.03, "task_time_s": 100.0, "reward_per_task": 0.02,
                           "slot_value": 0.02} for c, lo in ((0, -0.01), (1, 0.002))])
    model = {"arena": "two_circuits", "n_robots": 2, "values": [2200, 2000], "time_unit": "ms", "equilibria": ["1:1"],
             "predicted_state": "1:1", "optimal_state": "1:1", "slot_fill_state": "1:1", "predictions_differ": False,
             "by_team_size": {}}
    text = model_text({"model": model, "table": table, "output_dir": "out", "n_reused": 0})
    assert "[0*, 0.03]" in text and "[0.002, 0.03]" in text and "-0.01" not in text
    assert "* interval below 0: too few trials" in text


def test_the_report_tests_the_claims_on_the_learner_its_runs_are_of():
    from types import SimpleNamespace

    from tavc_cli.report.horizons import under_test as _under_test

    def plans(*learners):  # each run's plan, its learner (the first controller) labelled as its trials are
        return [SimpleNamespace(controllers=(SimpleNamespace(label=label),)) for label in learners]

    # TAVC's runs (e-greedy and softmax share the label), section 1.4's behaviour learners aside
    assert _under_test(plans("tavc", "tavc", "behaviour")) == "tavc"
    assert _under_test(plans("wolf_phc", "wolf_phc")) == "wolf_phc"
    assert _under_test(plans("wolf_phc", "threshold")) == "tavc"  # mixed: the chapter's learner
    # a controller that learns nothing is what the claims compare learners with, not a learner under test
    assert _under_test(plans("random")) == "tavc" and _under_test(plans("informed")) == "tavc"


def test_a_model_measured_below_its_own_settings_is_headed_not_a_verdict():
    from tavc_cli.model.report import measurement_shortfall, model_text

    # scale=smoke: at most 2 trials per split (its scale.trials), times x 0.02 (its time_factor): 3000 s -> 60 s
    short = measurement_shortfall({"trials_per_split": 2, "measure_s": 60.0}, 12, 3000.0, "smoke")
    assert short == "scale=smoke measures 2 of 12 static trials per split, 60 of 3,000 s each"
    assert measurement_shortfall({"trials_per_split": 12, "measure_s": 3000.0}, 12, 3000.0, "paper") == ""
    assert measurement_shortfall({"trials_per_split": 12, "measure_s": 120000.0}, 12, 3000.0, "converged") == ""
    table = pd.DataFrame([{"n_robots": 2, "state": "1:1", "circuit": c, "n_on_circuit": 1, "c_per_s": 0.01,
                           "c_lo": 0.005, "c_hi": 0.03, "task_time_s": 100.0, "reward_per_task": 0.02,
                           "slot_value": 0.02} for c in (0, 1)])
    model = {"arena": "two_circuits", "n_robots": 2, "values": [2200, 2000], "time_unit": "ms", "equilibria": ["1:1"],
             "predicted_state": "1:1", "optimal_state": "1:1", "slot_fill_state": "1:1", "predictions_differ": False,
             "by_team_size": {}}
    result = {"model": model, "table": table, "output_dir": "out", "n_reused": 0}
    assert model_text(result, short).splitlines()[0].startswith("not a verdict: scale=smoke measures 2 of 12")
    assert model_text(result).splitlines()[0].startswith("TAVC model:")


def test_a_runs_line_in_the_report_holds_what_decides_its_numbers_and_nothing_a_rerun_changes():
    """The report's line under a run names its command, seed, trial count and the digests of the
    code its trials were computed by (tavc's, and a learner's from outside tavc); two runs of the
    same code and settings that differ in version, commit, wall time and trials reused (a rerun,
    another checkout) give the same line."""
    from tavc_cli.report.text import run_lines

    cfg = config.settings(config.load_config(["experiment=initial_distribution", "scale=paper"]))
    same = {"command_line": ["tavc", "run", "experiment=initial_distribution"], "root_seed": 0,
            "trials": [{}] * 40, "code_digest": "8ccb620951251eec"}
    first = {**same, "tavc_version": "0.1.0", "git_commit": "aaa", "wall_time_s": 290.0, "n_trials_reused": 0}
    again = {**same, "tavc_version": "0.2.0", "git_commit": "bbb-dirty", "wall_time_s": 31.0, "n_trials_reused": 40}
    none = pd.DataFrame({"claim_id": []})
    line = [x for x in run_lines("initial_distribution", Path("."), cfg, first, none, {}) if x.startswith("Run:")]
    assert line == [x for x in run_lines("initial_distribution", Path("."), cfg, again, none, {}) if
                    x.startswith("Run:")]
    assert line == ["Run: `tavc run experiment=initial_distribution`; root seed 0; 40 trials, by tavc's code of "
                    "digest `8ccb620951251eec` (tavc's version and commit, the machine and the wall time: the run's "
                    "`provenance.json`)."]
    plugin = {**first, "learner_code": {"/x/mine.py:Mine": {"digest": "abc123", "files": ["mine.py"]}}}
    assert [x for x in run_lines("initial_distribution", Path("."), cfg, plugin, none, {}) if x.startswith("Run:")] \
        == [line[0].replace("`8ccb620951251eec`", "`8ccb620951251eec`, /x/mine.py:Mine's of digest `abc123`")]


def test_a_figure_an_earlier_report_drew_and_this_one_does_not_is_removed_and_nothing_else(tmp_path):
    """A run's figures in figures/runs/<folder>/ that an earlier report drew are removed, with
    the folders they leave empty (and no other), once the run is gone and the report is written
    again; every figure the report draws again stays, and the manifest no longer lists what went."""
    from tavc_cli.ownership import read

    _run(tmp_path / "initial_distribution", "scale=paper", trials=20)
    _report(tmp_path)
    kept = sorted(p.relative_to(tmp_path) for p in (tmp_path / "figures").rglob("*") if p.is_file())
    assert kept
    old = tmp_path / "figures" / "runs" / "gone" / "state_distribution.png"
    old.parent.mkdir(parents=True)
    old.write_bytes(b"drawn by an earlier report")
    read(tmp_path).wrote("figures/runs/gone/state_distribution.png")
    (tmp_path / "figures" / "empty_before").mkdir()  # a folder no removal empties stays
    _report(tmp_path)
    assert not old.exists() and not (tmp_path / "figures" / "runs").exists()  # nothing else was in runs/
    assert (tmp_path / "figures" / "empty_before").is_dir()
    assert sorted(p.relative_to(tmp_path) for p in (tmp_path / "figures").rglob("*") if p.is_file()) == kept
    assert "figures/runs/gone/state_distribution.png" not in read(tmp_path).files
