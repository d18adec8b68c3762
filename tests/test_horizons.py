"""scale=converged, the horizon ladder and the report's second horizon.

Configs compose at 40 times the chapter's durations (expected values multiplied by hand), the
baselines keep the chapter's schedule, the ladder's table is read from its rungs' tables,
and a report over two horizons gives both verdicts: synthetic tables where claim 3 fails
at the chapter's durations and holds at the long horizon are reported as such."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from tavc_cli import config
from tavc_cli.errors import TavcError
from tavc_cli.experiments.build import trial_specs
from tavc_cli.experiments.plan import plan_run
from tavc_cli.settings import to_yaml

# experiment -> (duration, convergence, warm-up, lead, event times) at the chapter's scale
CHAPTER = {
    "initial_distribution": (18000.0, 4500.0, 0.0, None, []),
    "breakdown": (27000.0, 9000.0, 18000.0, 1800.0, [0.0]),
    "breakdown_no_vacancy": (27000.0, 9000.0, 18000.0, 1800.0, [0.0]),
    "value_change": (18000.0, 3000.0, 36000.0, 1800.0, [-18000.0, 0.0]),
    "heterogeneous": (72000.0, 54000.0, 0.0, 1800.0, []),
}


def _times(cfg) -> tuple:
    events = sorted(float(e.time_s) for e in [*cfg.events.breakdowns, *cfg.events.value_changes])
    lead = None if cfg.baseline_lead_s is None else float(cfg.baseline_lead_s)
    return float(cfg.duration_s), float(cfg.convergence_s), float(cfg.sim.warmup_s), lead, events


@pytest.mark.parametrize("name", sorted(CHAPTER))
def test_converged_multiplies_every_time_by_40_and_keeps_the_chapters_trial_counts(name):
    cfg = config.settings(config.load_config([f"experiment={name}", "scale=converged"]))
    duration, conv, warm, lead, events = CHAPTER[name]
    # by hand: 18000 * 40 = 720000, 27000 * 40 = 1080000, 4500 * 40 = 180000, 1800 * 40 = 72000 ...
    assert _times(cfg) == (duration * 40, conv * 40, warm * 40, None if lead is None else lead * 40,
                           [t * 40 for t in events])
    paper = config.settings(config.load_config([f"experiment={name}", "scale=paper"]))
    assert (cfg.trials, cfg.baseline_trials, cfg.static_trials) == (paper.trials, paper.baseline_trials,
                                                                    paper.static_trials)
    # the baselines run the chapter's own schedule: the same times as scale=paper's
    assert _times(_baselines(cfg)) == _times(paper)


def test_converged_values_by_hand():
    cfg = config.settings(config.load_config(["experiment=value_change", "scale=converged"]))
    assert cfg.duration_s == 720_000.0 and cfg.sim.warmup_s == 1_440_000.0
    assert [b.time_s for b in cfg.events.breakdowns] == [-720_000.0]
    theirs = _baselines(cfg)
    assert theirs.duration_s == 18_000.0 and theirs.sim.warmup_s == 36_000.0 and theirs.baseline_lead_s == 1800.0
    assert [b.time_s for b in theirs.events.breakdowns] == [-18_000.0]
    # the window before the swap is not a time the scale multiplies: 9000 s for both
    assert theirs.analysis.before_s == 9000.0 and cfg.analysis.before_s == 9000.0


def test_section_1_4_runs_ten_times_the_chapters_traversals_at_converged():
    cfg = config.settings(config.load_config(["experiment=spatiotemporal", "scale=converged"]))
    assert cfg.deliveries == 10_000  # the chapter's 1000 traversals, times 10
    assert cfg.duration_s == 200_000.0 * 40  # the longest a trial may run
    assert config.settings(config.load_config(["experiment=spatiotemporal", "scale=paper"])).deliveries == 1000


def test_converged_baselines_are_the_paper_scales_trials():
    """Same seeds and schedule: a converged run's random and static trials are scale=paper's,
    spec for spec, so they are the same trials."""
    conv = trial_specs(config.settings(config.load_config(["experiment=breakdown", "scale=converged"])))
    paper = trial_specs(config.settings(config.load_config(["experiment=breakdown", "scale=paper"])))
    base_conv = [s for s in conv if s.controller != "tavc"]
    base_paper = [s for s in paper if s.controller != "tavc"]
    assert len(base_conv) == 40 and [s.key() for s in base_conv] == [s.key() for s in base_paper]
    learner = [s for s in conv if s.controller == "tavc"]
    assert {(s.duration_s, s.warmup_s) for s in learner} == {(1_080_000.0, 720_000.0)}


def test_the_plan_gives_every_controller_the_learners_schedule_where_the_factors_agree():
    cfg = config.settings(config.load_config(["experiment=breakdown", "scale=paper"]))
    plan = plan_run(cfg)
    assert plan.shared_schedule and plan.settings_for(cfg, "tavc") is cfg
    assert _times(plan.settings_for(cfg, "random")) == _times(cfg)
    # the learners warm up 18000 s; the baselines start 1800 s before the breakdown at 0 (baseline_lead_s)
    random = plan.controller("random").schedule
    assert (random.start_s, random.trial_warmup_s, random.starts_at) == (0.0, 1800.0, "the first event")
    assert (plan.controllers[0].schedule.start_s, plan.controllers[0].schedule.trial_warmup_s) == (0.0, 18000.0)


@pytest.mark.parametrize(("override", "key"), [("scale.baseline_time_factor=0", "scale.baseline_time_factor"),
                                               ("scale.deliveries_factor=-1", "scale.deliveries_factor")])
def test_a_factor_that_is_not_positive_is_refused_naming_the_key(override, key):
    with pytest.raises(TavcError, match=key.replace(".", r"\.")):
        config.load_config(["experiment=breakdown", override])


def test_the_ladders_rungs_are_initial_distribution_at_each_factor(tmp_path):
    results = tmp_path / "a, b's [c]=d"  # characters of the override grammar: a folder's name, taken as written
    rungs = config.load_ladder([1, 4, 40], [], results)
    assert [(c.scale.time_factor, c.duration_s, c.convergence_s) for c in rungs] == [
        (1.0, 18000.0, 4500.0), (4.0, 72000.0, 18000.0), (40.0, 720000.0, 180000.0)]
    assert [Path(c.output_dir) for c in rungs] == [results / "ladder" / f"x{f}" for f in (1, 4, 40)]
    # every rung's random trials are the same trials: the chapter's schedule
    specs = [trial_specs(config.settings(c)) for c in rungs]
    assert len({tuple(s.key() for s in sp if s.controller == "random") for sp in specs}) == 1


@pytest.mark.parametrize(("factors", "overrides"), [([1, 1], []), ([0], []), ([1], ["scale.time_factor=2"]),
                                                    ([1], ["experiment=breakdown"])])
def test_a_bad_ladder_is_one_error(tmp_path, factors, overrides):
    with pytest.raises(TavcError):
        config.load_ladder(factors, overrides, tmp_path)


# --- synthetic results: a claim that fails at the chapter's durations and holds at 40x -----------

STATES = ["0:6", "1:5", "2:4", "3:3", "4:2", "5:1", "6:0"]


RANGE_LEFT_PARALLEL = ("arrival=range", "passing=left", "arena=two_circuits_parallel")  # a reading's overrides


def _run_folder(folder: Path, scale: str, factor: float, pct_33_tavc: float, seed: int, *overrides: str) -> None:
    """A finished initial_distribution run folder with hand-made tables: 20 TAVC trials whose
    share of 3:3 is about `pct_33_tavc` (the rest spread evenly), 20 random trials at the
    binomial shares; TAVC delivers more per second than random at the long horizon only.
    `overrides`: settings besides (a reading's world)."""
    rng = np.random.default_rng(seed)
    cfg = config.settings(config.load_config(["experiment=initial_distribution", f"scale={scale}",
                                              f"scale.time_factor={factor!r}", *overrides, f"output_dir={folder}"]))
    folder.mkdir(parents=True)
    (folder / "config.yaml").write_text(to_yaml(cfg))
    (folder / "provenance.json").write_text(json.dumps({"trials": [], "wall_time_s": 1.0}))
    rows = []
    theory = [1.6, 9.4, 23.4, 31.2, 23.4, 9.4, 1.6]
    for controller, centre, rate in (("tavc", pct_33_tavc, 0.40 if factor > 1 else 0.33), ("random", None, 0.35)):
        for j in range(20):
            if centre is None:
                shares = np.array(theory) + rng.normal(0, 1.0, 7)
            else:
                rest = (100.0 - centre) / 6
                shares = np.array([rest, rest, rest, centre, rest, rest, rest]) + rng.normal(0, 1.0, 7)
            shares = np.clip(shares, 0, None)
            shares = 100 * shares / shares.sum()
            row = {"controller": controller, "trial": j, "duration_s": float(cfg.duration_s),
                   "value_rate_stable": rate + rng.normal(0, 0.01), "value_rate_convergence": math.nan,
                   "value_rate_before": math.nan, "settle_s": math.nan, "policy_settle_s": math.nan,
                   "policy_changes": math.nan}
            row.update({f"pct_{s}": v for s, v in zip(STATES, shares, strict=True)})
            rows.append(row)
    stats = pd.DataFrame(rows)
    stats.to_csv(folder / "trial_stats.csv", index=False)
    st = []
    for controller, g in stats.groupby("controller", sort=False):
        for s in STATES:
            x = g[f"pct_{s}"]
            st.append({"state": s, "controller": controller, "mean_pct": x.mean(), "std_pct": x.std(ddof=1),
                       "n_trials": len(x)})
    st += [{"state": s, "controller": "theory", "mean_pct": v, "std_pct": 0.0, "n_trials": 0}
           for s, v in zip(STATES, theory, strict=True)]
    pd.DataFrame(st).to_csv(folder / "state_time.csv", index=False)


@pytest.fixture(scope="module")
def two_horizons(tmp_path_factory):
    results = tmp_path_factory.mktemp("results")
    _run_folder(results / "initial_distribution", "paper", 1.0, 20.0, seed=1)      # 3:3 rarer than 2:4 ...
    _run_folder(results / "converged" / "initial_distribution", "converged", 40.0, 60.0, seed=2)
    for k, (factor, pct) in enumerate([(1.0, 20.0), (40.0, 60.0)]):
        _run_folder(results / "converged" / "ladder" / f"x{factor:g}", "converged", factor, pct, seed=10 + k)
    from tavc_cli.pipeline import write_ladder

    write_ladder(results / "converged" / "ladder",
                 [results / "converged" / "ladder" / "x1", results / "converged" / "ladder" / "x40"])
    return results


def test_the_ladder_table_holds_each_rungs_states_and_claims(two_horizons):
    table = pd.read_csv(two_horizons / "converged" / "ladder" / "ladder.csv")
    share = table[(table["controller"] == "tavc") & (table["quantity"] == "pct_3:3")].set_index("factor")["mean"]
    assert share[1.0] == pytest.approx(20.0, abs=1.0) and share[40.0] == pytest.approx(60.0, abs=1.0)
    assert (two_horizons / "converged" / "ladder" / "ladder.png").is_file()


def test_a_ladder_table_that_is_not_what_its_rungs_give_now_is_refused(two_horizons, tmp_path):
    """The report sets the ladder's numbers beside its rungs' claims: a rung run again since the
    table was written (another seed, here) would put one run's claims beside another's numbers."""
    import shutil

    from typer.testing import CliRunner

    from tavc_cli.cli import app
    from tavc_cli.pipeline import write_ladder

    results = tmp_path / "results"
    shutil.copytree(two_horizons, results)
    # a rung whose factor ladder.csv rounds (x0.123456 is 0.1235 there) is found all the same
    ladder = results / "converged" / "ladder"
    _run_folder(ladder / "x0.123456", "converged", 0.123456, 20.0, seed=12)
    write_ladder(ladder, [ladder / "x0.123456", ladder / "x1", ladder / "x40"])
    # a user's hidden copy of a rung and a rung the table does not list (one being run) are not its rungs
    shutil.copytree(ladder / "x1", ladder / ".backup_x1")
    (ladder / "x3").mkdir()
    shutil.copy(ladder / "x1" / "config.yaml", ladder / "x3" / "config.yaml")
    # the claims' rows are never read from the table: a verdict edited there is not the report's
    text = (ladder / "ladder.csv").read_text()
    duration = next(line.split(",")[1] for line in text.splitlines() if line.startswith("0.1235,"))
    forged = [f"0.1235,{duration},tavc,claim3_p,0.0001,,0", f"0.1235,{duration},tavc,claim3_reproduced,1.0000,,0"]
    (ladder / "ladder.csv").write_text(text + "\n".join(forged) + "\n")
    assert CliRunner().invoke(app, ["report", str(results)]).exit_code == 0
    assert "(0.0001)" not in (results / "REPORT.md").read_text()
    shutil.rmtree(ladder / "x3")
    shutil.rmtree(ladder / ".backup_x1")
    shutil.rmtree(results / "converged" / "ladder" / "x1")
    _run_folder(results / "converged" / "ladder" / "x1", "converged", 1.0, 30.0, seed=99)
    result = CliRunner().invoke(app, ["report", str(results)])
    assert result.exit_code == 1
    assert result.output.strip() == (f"error: {results / 'converged' / 'ladder' / 'ladder.csv'}: not what its "
                                     "rungs give now (one of them run again since it was written?); run its "
                                     "`tavc ladder` again to rewrite it")


def test_a_rung_the_ladder_table_does_not_list_is_named_as_left_out(two_horizons, tmp_path):
    """A ladder run again with fewer factors leaves the dropped rung's folder: the report lists
    only the rungs `ladder.csv` lists as the ladder's, names the others beside them as left out,
    each with why, and does not read them (a damaged table there is no refusal), but for a run
    whose config.yaml cannot be read, which could be any rung and is checked."""
    import shutil

    from tavc_cli.report import build_report

    results = tmp_path / "results"
    shutil.copytree(two_horizons, results)
    ladder = results / "converged" / "ladder"
    _run_folder(ladder / "x4", "converged", 4.0, 40.0, seed=13)  # an earlier ladder's rung at 4x
    (ladder / "x4" / "trial_stats.csv").write_text("not,a\ntable")
    result = build_report(results)
    assert result["studies"]["the horizon ladder, in *The time scale*"] == ["converged/ladder/x1",
                                                                           "converged/ladder/x40"]
    rows = [line for line in (results / "REPORT.md").read_text().splitlines() if line.startswith("| `converged/ladder")]
    assert len(rows) == 2
    assert rows[0].startswith("| `converged/ladder/x4` | initial_distribution | converged |")
    assert rows[0].endswith("| left out: not a rung the `ladder.csv` beside it lists (one of an earlier ladder, or "
                            "one still running); `tavc ladder` with its factor among the others reads it |")
    assert rows[1].startswith("| `converged/ladder/`: `x1`, `x40` |") and "x4`," not in rows[1]
    # a second run at a listed factor, and a link to a rung kept elsewhere: named, neither read
    shutil.copytree(ladder / "x40", ladder / "x40_again")
    (ladder / "x40_again" / "trial_stats.csv").write_text("not,a\ntable")
    shutil.copytree(ladder / "x1", tmp_path / "kept_x1")
    (ladder / "x1_linked").symlink_to(tmp_path / "kept_x1")
    build_report(results)
    text = (results / "REPORT.md").read_text()
    assert ("| `converged/ladder/x40_again` | initial_distribution | converged | 20 | left out: a second run at 40 "
            "times the chapter's durations, beside the rung the ladder's table is held to, `x40` |") in text
    assert "| `converged/ladder/x1_linked` | - | - | - | left out: a symbolic link" in text
    # a run there whose config.yaml cannot be read could be any rung: the run checks name it
    shutil.rmtree(ladder / "x40_again")
    (ladder / "x4" / "config.yaml").write_text("scale: [unclosed\n")
    with pytest.raises(TavcError, match=r"x4/config.yaml: cannot be read"):
        build_report(results)


def test_a_damaged_ladder_table_in_a_horizon_without_runs_is_refused_before_anything_is_written(two_horizons,
                                                                                                 tmp_path):
    import shutil

    from tavc_cli.report import build_report

    results = tmp_path / "results"
    shutil.copytree(two_horizons, results)
    shutil.rmtree(results / "converged" / "initial_distribution")  # the horizon keeps only its ladder
    (results / "converged" / "ladder" / "ladder.csv").write_text("garbage\n")
    with pytest.raises(TavcError, match="ladder.csv"):
        build_report(results)
    assert not (results / "REPORT.md").exists() and not (results / "figures").exists()


def test_a_claim_that_fails_at_1x_and_holds_at_40x_is_reported_as_such(two_horizons):
    # the rungs' own claims.csv are not written by hand: the report tests both horizons itself
    from tavc_cli.report import build_report

    result = build_report(two_horizons)
    assert result["n_tested"] == 3 and result["n_tested_long"] == 3 and result["factor"] == 40.0
    long = result["claims_long"].set_index("claim_id")
    assert long.loc[3, "verdict"] == "reproduced" and long.loc[5, "verdict"] == "reproduced"
    base = result["claims"].set_index("claim_id")
    assert base.loc[3, "verdict"] == "not_reproduced" and base.loc[5, "verdict"] == "not_reproduced"
    report = (two_horizons / "REPORT.md").read_text()
    assert result["n_reproduced_long"] == result["n_reproduced"] + 2  # claims 3 and 5 besides
    assert (f"**Claims reproduced: {result['n_reproduced']} of 3 at the chapter's durations; "
            f"{result['n_reproduced_long']} of 3 at 40 times them") in report
    row = next(line for line in report.splitlines() if line.startswith("| 3 | initial_distribution |"))
    assert row.split("|")[3].strip() == "not reproduced" and row.split("|")[5].strip() == "reproduced"
    assert (two_horizons / "converged" / "claims.csv").is_file()


def test_without_a_long_horizon_the_report_has_one_count(two_horizons, tmp_path):
    import shutil

    from tavc_cli.report import build_report

    shutil.copytree(two_horizons / "initial_distribution", tmp_path / "initial_distribution")
    build_report(tmp_path)
    report = (tmp_path / "REPORT.md").read_text()
    assert "**Claims reproduced: " in report and " of 3 tested**" in report and "times them" not in report


def test_every_horizon_folder_is_reported_in_order_of_its_factor(two_horizons, tmp_path):
    """A third horizon beside the second (`x10/`, made as `converged/` is, at 10x): three counts,
    three verdicts per claim, a subsection of each experiment at each horizon, a claims.csv in
    each horizon's folder; the horizons ordered by factor, so x10 is the second and converged/
    the third; a folder named like a horizon that holds a run is a run, not a horizon."""
    import shutil

    from tavc_cli.report import build_report

    results = tmp_path / "results"
    shutil.copytree(two_horizons, results, ignore=shutil.ignore_patterns("REPORT.md", "claims.csv", "figures",
                                                                         ".tavc.json", ".tavc.lock"))
    _run_folder(results / "x10" / "initial_distribution", "converged", 10.0, 60.0, seed=3)
    result = build_report(results)
    assert [(h["folder"], h["factor"]) for h in result["horizons"]] == [("x10", 10.0), ("converged", 40.0)]
    assert result["factor"] == 10.0  # the first longer horizon keeps the keys a second horizon had
    report = (results / "REPORT.md").read_text()
    # claim 3 fails at 1x (3:3 at 20 %) and holds at both longer horizons (3:3 at 60 %)
    row = next(line for line in report.splitlines() if line.startswith("| 3 | initial_distribution |"))
    cells = [c.strip() for c in row.split("|")[1:-1]]
    assert (cells[2], cells[4], cells[7]) == ("not reproduced", "reproduced", "reproduced")
    assert len(cells) == 10  # claim, experiment, then verdict and p at 1x; verdict, p and how at 10x and 40x
    assert f"; {result['horizons'][0]['n_reproduced']} of 3 at 10 times them (" in report
    assert f"; {result['horizons'][1]['n_reproduced']} of 3 at 40 times them (" in report
    for words in ("### initial_distribution at 10 times the chapter's durations",
                  "### initial_distribution at 40 times the chapter's durations",
                  "### The second horizon", "### The third horizon",
                  "the claims about initial_distribution at the third horizon are tested on it"):
        assert words in report, words
    assert report.index("at 10 times the chapter's durations") < report.index("at 40 times the chapter's durations")
    assert (results / "x10" / "claims.csv").is_file() and (results / "converged" / "claims.csv").is_file()
    assert (results / "figures" / "horizons_initial_distribution_x10.png").is_file()
    assert (results / "figures" / "horizons_initial_distribution.png").is_file()
    assert any((results / "x10" / "figures").iterdir())
    # x10's run made unfinished (a rerun of other settings stopped): x10 is no horizon any more, its run is
    # named as left out, and the earlier report's claims and figures there are gone, not left as this one's
    (results / "x10" / "initial_distribution" / "provenance.json").unlink()
    # its figures/ a link to a folder elsewhere: refused, and nothing there or in x10/ removed
    shutil.move(results / "x10" / "figures", tmp_path / "elsewhere")
    (results / "x10" / "figures").symlink_to(tmp_path / "elsewhere")
    kept = sorted(p.name for p in (tmp_path / "elsewhere").iterdir())
    with pytest.raises(TavcError, match="figures is a symbolic link to .*elsewhere"):
        build_report(results)
    assert sorted(p.name for p in (tmp_path / "elsewhere").iterdir()) == kept
    assert (results / "x10" / "claims.csv").is_file()
    (results / "x10" / "figures").unlink()
    shutil.move(tmp_path / "elsewhere", results / "x10" / "figures")
    result = build_report(results)
    assert [h["folder"] for h in result["horizons"]] == ["converged"]
    assert str(results / "x10" / "initial_distribution") in result["unfinished"]
    assert not (results / "x10" / "claims.csv").exists()
    assert not [p for p in (results / "x10" / "figures").rglob("*") if p.is_file()]


def test_a_folder_named_like_a_horizon_that_holds_a_run_is_a_run(tmp_path):
    from tavc_cli.report.files import horizon_folders
    from tavc_cli.report.runs import finished_runs

    results = tmp_path / "results"
    _run_folder(results / "initial_distribution", "paper", 1.0, 20.0, seed=1)
    _run_folder(results / "x4", "paper", 1.0, 20.0, seed=4)  # a run someone named x4
    assert horizon_folders(results) == []
    assert [d.name for d in finished_runs(results)[0]["initial_distribution"]] == ["initial_distribution", "x4"]


def test_runs_in_another_reading_of_the_world_are_never_a_horizons_claims(two_horizons, tmp_path):
    """A horizon's `readings/` holds the base case in other worlds, read as a whole by the
    readings' section: a folder `x80/` holding only such a run is no horizon with claims, and
    under `converged/` such a run is not another run of the experiment; both are listed as
    read as a whole."""
    import shutil

    from tavc_cli.report import build_report

    results = tmp_path / "results"
    shutil.copytree(two_horizons, results, ignore=shutil.ignore_patterns("REPORT.md", "claims.csv", "figures",
                                                                         ".tavc.json", ".tavc.lock"))
    _run_folder(results / "x80" / "readings" / "range-left-two_circuits_parallel", "converged", 80.0, 10.0, 5,
                *RANGE_LEFT_PARALLEL)
    _run_folder(results / "converged" / "readings" / "dock-nearest-two_circuits_parallel", "converged", 40.0, 10.0,
                6, "arena=two_circuits_parallel")
    result = build_report(results)
    assert [h["folder"] for h in result["horizons"]] == ["converged"]
    report = (results / "REPORT.md").read_text()
    assert "another run of initial_distribution" not in report and not (results / "x80" / "claims.csv").exists()
    listed = [line for line in report.splitlines() if "read as a whole: runs in other readings of the world" in line]
    assert len(listed) == 2 and "`x80/readings/`" in listed[1] and "`converged/readings/`" in listed[0]


def test_the_chapters_experiments_in_another_reading_are_counterfactual_rows_never_the_headline(
        two_horizons, tmp_path):
    """initial_distribution run in another reading (`readings/<reading>/initial_distribution`,
    3:3 at 60 % where today's world has it at 20 %): its claims get rows of their own, with
    the reading in words; the headline counts and claims.csv stay today's world's."""
    import shutil

    from tavc_cli.report import build_report

    results = tmp_path / "results"
    shutil.copytree(two_horizons, results, ignore=shutil.ignore_patterns("REPORT.md", "claims.csv", "figures",
                                                                         ".tavc.json", ".tavc.lock"))
    before = build_report(results)
    _run_folder(results / "readings" / "range-left-two_circuits_parallel" / "initial_distribution", "paper", 1.0,
                60.0, 7, *RANGE_LEFT_PARALLEL)
    after = build_report(results)
    assert after["n_reproduced"] == before["n_reproduced"] and after["n_reproduced_long"] == before["n_reproduced_long"]
    pd.testing.assert_frame_equal(after["claims"], before["claims"])
    report = (results / "REPORT.md").read_text()
    start = report.index("## In other readings of the world: counterfactuals")
    section = report[start:report.index("\n## ", start)]
    rows = [[c.strip() for c in line.strip("|").split("|")] for line in section.splitlines()
            if line.startswith("| 3 | initial_distribution |")]
    assert [r[2] for r in rows] == ["today's world (1x, the headline)",
                                    "arrival=range passing=left arena=two_circuits_parallel (1x, "
                                    "`readings/range-left-two_circuits_parallel`)"]
    assert [r[3] for r in rows] == ["not reproduced", "reproduced"]
    # only the claims of experiments some reading ran get rows: initial_distribution's 3, 4 and 5
    assert {line.split("|")[1].strip() for line in section.splitlines() if line.startswith("| ")} - {"claim", "---"} \
        == {"3", "4", "5"}
    assert "another run of initial_distribution" not in report
    # the reading's calibration search beside its runs says whether the world they used meets the chapter's facts
    search = results / "readings" / "range-left-two_circuits_parallel" / "calibration" / "world"
    search.mkdir(parents=True)
    pd.DataFrame({"point": ["a", "b"], "robot.dock.dwell_s": [0.0, 5.0], "lone_leg_s": [20.0, 25.0],
                  "arrivals_per_5h": [3000, 2900], "crowding_ratio_6": [1.05, 1.2],
                  "feasible": [False, True], "robust": [False, True], "chosen": [False, True]}).to_csv(
        search / "search.csv", index=False)
    # and the reading at 40x too: today's world at 40x comes before it, after the rows at 1x
    _run_folder(results / "converged" / "readings" / "range-left-two_circuits_parallel" / "initial_distribution",
                "converged", 40.0, 60.0, 8, *RANGE_LEFT_PARALLEL)
    build_report(results)
    report = (results / "REPORT.md").read_text()
    note = next(line for line in report.splitlines()
                if line.startswith("- `readings/range-left-two_circuits_parallel`: the world these runs used"))
    assert "(robot.dock.dwell_s 0) does not meet the chapter's facts" in note
    assert note.endswith("its rule chooses robot.dock.dwell_s 5.")
    start = report.index("## In other readings of the world: counterfactuals")
    worlds = [line.split("|")[3].strip() for line in report[start:report.index("\n## ", start)].splitlines()
              if line.startswith("| 3 | initial_distribution |")]
    reading = "arrival=range passing=left arena=two_circuits_parallel"
    assert [w.split(" (")[0] for w in worlds] == ["today's world", reading, "today's world", reading]
    assert "(40x, `converged`)" in worlds[2]
    assert "(40x, `converged/readings/range-left-two_circuits_parallel`)" in worlds[3]


def test_a_readings_folder_holds_only_runs_made_in_the_reading_its_name_says(two_horizons, tmp_path):
    """A run under `readings/<reading>/` is reported under that reading's name: one of today's world
    there, or one of another robot beside the others of a reading's variant, is refused in one
    line naming it, before anything is written."""
    import shutil

    from tavc_cli.errors import TavcError
    from tavc_cli.report import build_report

    results = tmp_path / "results"
    shutil.copytree(two_horizons, results, ignore=shutil.ignore_patterns("REPORT.md", "claims.csv", "figures",
                                                                         ".tavc.json", ".tavc.lock"))
    reading = results / "readings" / "range-left-two_circuits_parallel"
    _run_folder(reading / "initial_distribution", "paper", 1.0, 60.0, 7)  # today's world
    with pytest.raises(TavcError) as info:
        build_report(results)
    assert str(info.value) == (f"{reading / 'initial_distribution'}: made in the reading arrival=dock passing=nearest "
                               "arena=two_circuits, not in the one its folder names (arrival=range passing=left "
                               "arena=two_circuits_parallel); move it, or run it again in that reading")
    assert not (results / "REPORT.md").exists()
    shutil.rmtree(reading)
    _run_folder(reading, "paper", 1.0, 60.0, 7)  # a reading's folder that is itself a run, a models' check point
    with pytest.raises(TavcError, match=f"^{reading}: made in the reading arrival=dock passing=nearest "):
        build_report(results)
    shutil.rmtree(reading)
    variant = results / "readings" / "range-left-two_circuits_parallel-calibrated"
    _run_folder(variant / "a" / "initial_distribution", "paper", 1.0, 60.0, 7, *RANGE_LEFT_PARALLEL)
    _run_folder(variant / "b" / "initial_distribution", "paper", 1.0, 60.0, 8, *RANGE_LEFT_PARALLEL,
                "robot.dock.dwell_s=5.0")
    with pytest.raises(TavcError) as info:
        build_report(results)
    assert str(info.value) == (f"{variant / 'b' / 'initial_distribution'}: its robot settings are not those of "
                               f"{variant / 'a' / 'initial_distribution'} beside it, in one reading's folder; move it, "
                               "or run it again in that world")


def test_the_turn_taking_models_and_a_calibrations_folders_are_never_runs_of_the_report(tmp_path):
    """A finished run inside the turn-taking model's folder (its learners) is not another run of
    the experiment, and a calibration's folder with its trials is not an unfinished run."""
    import json

    from tavc_cli.report.runs import finished_runs

    results = tmp_path / "results"
    _run_folder(results / "initial_distribution", "paper", 1.0, 20.0, seed=1)
    model = results / "turn_taking" / "initial_distribution" / "turn_taking"
    _run_folder(model / "learners", "converged", 40.0, 60.0, seed=2)
    (model / ".tavc.json").write_text(json.dumps({"tavc": "turn-taking", "files": ["turn_taking.json"]}))
    search = results / "calibration" / "world"
    (search / "trials").mkdir(parents=True)
    (search / ".tavc.json").write_text(json.dumps({"tavc": "calibration", "files": ["search.csv"]}))
    found, unfinished = finished_runs(results)
    assert [d.name for d in found["initial_distribution"]] == ["initial_distribution"] and unfinished == []


@pytest.mark.parametrize(("args", "message"), [
    (["ladder", "--factors", "1,x"], "error: ladder factors: '1,x' is not a comma-separated list of numbers"),
    (["ladder", "--factors", "1,1"], "error: ladder factors: a factor is given twice"),
    (["ladder", "--factors", "0,4"], "error: ladder factors: each must be a number above 0"),
    (["reproduce", "scale.time_factor=3", "--ladder", "1,4"], "error: scale.time_factor: set by the ladder"),
])
def test_a_bad_ladder_on_the_command_line_is_one_line(tmp_path, args, message):
    from typer.testing import CliRunner

    from tavc_cli.cli import app

    result = CliRunner().invoke(app, [*args, "--results", str(tmp_path / "out")])
    assert result.exit_code == 1
    lines = result.output.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith(message)
    assert not (tmp_path / "out").exists()


@pytest.mark.slow
def test_tavc_ladder_end_to_end_at_smoke_scale(tmp_path):
    """Two rungs in one job: ladder.csv and its figure; the rungs' random trials, on the chapter's
    schedule at both, are one trial written twice, byte for byte."""
    from typer.testing import CliRunner

    from tavc_cli.cli import app

    result = CliRunner().invoke(app, ["ladder", "scale=smoke", "scale.baseline_time_factor=0.01", "--factors",
                                      "0.01,0.02", "--results", str(tmp_path)])
    assert result.exit_code == 0, result.output
    table = pd.read_csv(tmp_path / "ladder" / "ladder.csv")
    assert sorted(set(table["factor"])) == [0.01, 0.02]
    assert {"pct_3:3", "claim3_p", "q_drift", "n_alternators"} <= set(table["quantity"])
    assert (tmp_path / "ladder" / "ladder.png").is_file()
    a, b = (tmp_path / "ladder" / f"x{f}" / "trials" / "random_000.npz" for f in ("0.01", "0.02"))
    assert a.read_bytes() == b.read_bytes()
    durations = table[table["quantity"] == "pct_3:3"].groupby("factor")["duration_s"].first()
    assert durations.to_dict() == {0.01: 180.0, 0.02: 360.0}  # 18000 s times each factor
    # run again with a factor left out: its rung stays, named, and the table lists the other only
    again = CliRunner().invoke(app, ["ladder", "scale=smoke", "scale.baseline_time_factor=0.01", "--factors",
                                     "0.01", "--results", str(tmp_path)])
    assert again.exit_code == 0, again.output
    assert again.output.strip().endswith(f"note: {tmp_path / 'ladder' / 'x0.02'} is no rung of this ladder; kept, "
                                         "and named by the report as left out")
    assert set(pd.read_csv(tmp_path / "ladder" / "ladder.csv")["factor"]) == {0.01} and b.is_file()


def test_the_stable_window_at_40x_is_the_chapters_length_at_the_end():
    from tavc_cli.analysis.trial_stats import stable_from
    from tavc_cli.report.horizons import window_words

    # initial_distribution: 5 h with 1.25 h to converge, so 3.75 h = 13,500 s of stable period; at 40x
    # the trial ends at 720,000 s and its window starts 13,500 s before
    conv = config.settings(config.load_config(["experiment=initial_distribution", "scale=converged"]))
    assert (conv.scale.stable_window, stable_from(conv)) == ("chapter", 720_000.0 - 13_500.0)
    assert window_words(conv) == "its last 3.75 h, the length of the chapter's stable period"
    # at the chapter's durations the window is the whole stable period, as it always was
    paper = config.settings(config.load_config(["experiment=initial_distribution", "scale=paper"]))
    assert stable_from(paper) == 4_500.0 and window_words(paper) == "all of it, 3.75 h"
    # breakdown: 7.5 h after the event with 2.5 h to converge: the last 5 h of 300 h
    bd = config.settings(config.load_config(["experiment=breakdown", "scale=converged"]))
    assert stable_from(bd) == 1_080_000.0 - 18_000.0
    # a baseline on the chapter's schedule inside a 40x run: its stable period is the chapter's already
    assert stable_from(_baselines(bd)) == 9_000.0
    # anything else is refused naming the key
    with pytest.raises(TavcError, match=r"scale\.stable_window"):
        config.load_config(["experiment=breakdown", "scale.stable_window=last"])


def _baselines(cfg):
    """The settings the run's plan gives its random baseline."""
    return plan_run(cfg).settings_for(cfg, "random")


def test_a_longer_horizon_below_the_chapters_scale_is_named_in_the_not_a_verdict_line(tmp_path):
    """The chapter's durations at paper scale (a verdict), the longer horizon at scale=quick (not
    one): the report's first words name the longer horizon's run by its folder."""
    from tavc_cli.report import build_report

    _run_folder(tmp_path / "initial_distribution", "paper", 1.0, 20.0, seed=1)
    _run_folder(tmp_path / "converged" / "initial_distribution", "quick", 40.0, 60.0, seed=2)
    build_report(tmp_path)
    first = next(line for line in (tmp_path / "REPORT.md").read_text().splitlines() if "not a verdict" in line)
    assert "initial_distribution in converged:" in first


def test_a_folders_runs_at_two_horizons_are_refused_as_one_horizon(tmp_path):
    """A horizon's claims and its label are one horizon's: runs at 1x and 40x among a folder's
    designated runs are refused in one line naming both, before anything is written."""
    from tavc_cli.errors import TavcError
    from tavc_cli.report.horizons import read_horizon

    _run_folder(tmp_path / "a", "paper", 1.0, 20.0, seed=1)
    _run_folder(tmp_path / "b", "converged", 40.0, 60.0, seed=2)
    with pytest.raises(TavcError) as info:
        read_horizon(tmp_path, {"initial_distribution": [tmp_path / "a"], "breakdown": [tmp_path / "b"]}, [])
    assert str(info.value) == (f"{tmp_path}: its runs are at 1 and 40 times the chapter's durations ({tmp_path / 'a'}, "
                               f"{tmp_path / 'b'}); a folder's runs are tested as one horizon: move one of them into "
                               "the folder of its horizon (converged/, x<factor>/)")
