"""`tavc report`: REPORT.md and claims.csv from saved results only, the chapter's tables
beside ours cell by cell."""

import shutil

import pandas as pd
import pytest
from typer.testing import CliRunner

from tavc_cli.analysis.comparison import compare, experiment_comparison
from tavc_cli.cli import app
from tavc_cli.reference import chapter_table
from tests.helpers import SMOKE_BREAKDOWN

runner = CliRunner()
EXPERIMENTS = ["initial_distribution", "breakdown", "breakdown_no_vacancy", "value_change"]


def _long(table_id: str) -> pd.DataFrame:
    """A chapter table rewritten as our state_time.csv (rows per state and controller)."""
    rows = []
    for r in chapter_table(table_id).itertuples(index=False):
        for ctrl in ("tavc", "random"):
            if hasattr(r, f"{ctrl}_mean_pct"):
                rows.append({"state": r.state, "controller": ctrl, "mean_pct": getattr(r, f"{ctrl}_mean_pct"),
                             "std_pct": getattr(r, f"{ctrl}_std_pct"), "n_trials": 20})
        if hasattr(r, "theory_pct"):
            rows.append({"state": r.state, "controller": "theory", "mean_pct": r.theory_pct, "std_pct": 0.0,
                         "n_trials": 0})
    return pd.DataFrame(rows)


@pytest.mark.parametrize("table_id", ["1.2", "1.3", "1.4", "1.5"])
def test_the_chapters_own_table_compares_equal_to_itself(table_id):
    cmp = compare(_long(table_id), table_id)
    chapter = chapter_table(table_id)
    # one row per printed cell
    assert len(cmp) == len(chapter) * (len(chapter.columns) - 1)
    assert (cmp["difference"].abs() < 1e-12).all()


def test_comparison_differences_are_ours_minus_the_chapters():
    ours = _long("1.2")
    ours.loc[(ours.state == "3:3") & (ours.controller == "tavc"), "mean_pct"] = 50.0  # chapter: 44.5
    ours = ours[ours.controller != "random"]
    cmp = compare(ours, "1.2").set_index(["state", "quantity"])
    assert cmp.loc[("3:3", "tavc_mean_pct"), "difference"] == pytest.approx(5.5)
    # a controller we did not run leaves our cells empty, not zero
    assert cmp.loc[("3:3", "random_mean_pct"), "ours"] != cmp.loc[("3:3", "random_mean_pct"), "ours"]


def test_table_1_6_differences_are_recomputed_from_our_means():
    ours = _long("1.6")
    cmp = compare(ours, "1.6").set_index(["state", "quantity"])
    # the differences are over the theory row (here the chapter's own, 14.1 for 2:1):
    # 19.4 - 14.1 = 5.3 as printed (over random it would be 3.7), relative 5.3 / 14.1 = 0.3759
    assert cmp.loc[("2:1", "diff_pct"), "ours"] == pytest.approx(5.3)
    assert cmp.loc[("2:1", "rel_diff"), "ours"] == pytest.approx(0.37589, abs=1e-4)
    assert cmp.loc[("2:1", "diff_pct"), "chapter"] == pytest.approx(5.3)


def test_report_refuses_a_folder_without_runs(tmp_path):
    result = runner.invoke(app, ["report", str(tmp_path)])
    assert result.exit_code == 1
    assert result.output.strip().startswith("error: RESULTS_DIR")
    assert not (tmp_path / "REPORT.md").exists()


@pytest.mark.slow
def test_smoke_runs_of_the_four_experiments_through_report(tmp_path):
    for name in EXPERIMENTS:
        result = runner.invoke(app, ["run", f"experiment={name}", "scale=smoke", "trials=2", "baseline_trials=2",
                                     f"output_dir={tmp_path / name}"])
        assert result.exit_code == 0, result.output
        assert "the chapter's claims about this experiment" in result.output
        assert (tmp_path / name / "comparison.csv").is_file()
        stats = pd.read_csv(tmp_path / name / "trial_stats.csv")
        # every trial's stable-period shares sum to 100 % (each written to 4 decimals)
        shares = stats[[c for c in stats.columns if c.startswith("pct_")]].sum(axis=1)
        assert ((shares - 100.0).abs() < 1e-3).all()
    # a one-run value-ratio sweep, made from the initial_distribution run
    shutil.copytree(tmp_path / "initial_distribution", tmp_path / "value_ratio" / "paper" / "0", dirs_exist_ok=True)
    result = runner.invoke(app, ["report", str(tmp_path)])
    assert result.exit_code == 0, result.output
    claims = pd.read_csv(tmp_path / "claims.csv")
    assert claims["claim_id"].tolist() == [1, 2, 3, 4, 5, 6, 7, 8, 9]
    assert set(claims["verdict"]) <= {"reproduced", "not_reproduced", "inconclusive"}
    # each run made its comparison and tested its claims on its tables as written, the numbers
    # the report reads back
    for name in EXPERIMENTS:
        state_time = pd.read_csv(tmp_path / name / "state_time.csv", dtype={"state": str})
        again = experiment_comparison(name, state_time).to_csv(index=False, float_format="%.4f")
        assert again == (tmp_path / name / "comparison.csv").read_text(), name
        own = pd.read_csv(tmp_path / name / "claims.csv")
        assert len(own)
        pd.testing.assert_frame_equal(own, claims.loc[claims["claim_id"].isin(own["claim_id"]), list(own.columns)]
                                      .reset_index(drop=True), check_dtype=False)
    text = (tmp_path / "REPORT.md").read_text()
    for name in EXPERIMENTS:
        assert f"## {name}" in text
    assert "Table 1.3 beside ours" in text and "of 6 tested" in text
    # Q-values of trial 0 for every TAVC run, and the sweep's table and figure
    for name in EXPERIMENTS:
        assert (tmp_path / "figures" / f"q_values_{name}.png").is_file()
    assert "Greedy policies" in text
    assert "## Learning values and time" in text and (tmp_path / "figures" / "value_ratio.png").is_file()
    points = pd.read_csv(tmp_path / "value_ratio" / "value_ratio.csv")
    assert points["ratio"].tolist() == [pytest.approx(1.1)] and points["n_trials"].tolist() == [2]
    # the sweep's run moved away: its table and figure go with the section, none left of runs not there
    shutil.move(tmp_path / "value_ratio" / "paper", tmp_path / "elsewhere")
    result = runner.invoke(app, ["report", str(tmp_path)])
    assert result.exit_code == 0, result.output
    assert "## Learning values and time" not in (tmp_path / "REPORT.md").read_text()
    assert not (tmp_path / "value_ratio" / "value_ratio.csv").exists()
    assert not (tmp_path / "figures" / "value_ratio.png").exists()


@pytest.mark.slow
def test_smoke_run_of_the_heterogeneous_experiment_through_report(tmp_path):
    result = runner.invoke(app, ["run", "experiment=heterogeneous", "scale=smoke", "trials=2",
                                 f"output_dir={tmp_path / 'heterogeneous'}"])
    assert result.exit_code == 0, result.output
    stats = pd.read_csv(tmp_path / "heterogeneous" / "trial_stats.csv")
    # 16 f:s states for 3 fast and 3 slow robots, and a Q gap per speed group, fast first
    assert len([c for c in stats.columns if c.startswith("pct_")]) == 16
    assert [c for c in stats.columns if c.startswith("q_gap_")] == ["q_gap_fast", "q_gap_slow"]
    spec = pd.read_csv(tmp_path / "heterogeneous" / "specialisation.csv")
    assert set(spec["group"]) == {"fast", "slow"} and set(spec["controller"]) == {"tavc", "random"}
    assert spec["mean_share_high"].dropna().between(0.0, 1.0).all()
    result = runner.invoke(app, ["report", str(tmp_path)])
    assert result.exit_code == 0, result.output
    claims = pd.read_csv(tmp_path / "claims.csv").set_index("claim_id")
    assert claims.loc[9, "verdict"] in {"reproduced", "not_reproduced", "inconclusive"}
    text = (tmp_path / "REPORT.md").read_text()
    assert "of 1 tested" in text and "Table 1.6 beside ours" in text
    for stem in ("fig_1_12", "fig_1_13", "fig_1_13_relative", "specialisation_heterogeneous"):
        assert (tmp_path / "figures" / f"{stem}.png").is_file()


@pytest.mark.slow
def test_smoke_run_of_the_spatiotemporal_experiment_through_report(tmp_path):
    result = runner.invoke(app, ["run", "experiment=spatiotemporal", "scale=smoke", "trials=2",
                                 f"output_dir={tmp_path / 'spatiotemporal'}"])
    assert result.exit_code == 0, result.output
    out = tmp_path / "spatiotemporal"
    table = pd.read_csv(out / "table_1_1.csv")
    assert table["n_traversals"].tolist() == [0, 25, 50, 75, 100, 150, 200]
    # five robots in each of two trials made a first traversal
    assert table.loc[0, "n_robots"] == 10 and table.loc[0, "mean_traversal_s"] > 0
    policy = pd.read_csv(out / "policy.csv")
    assert len(policy) == 10
    shares = policy[["share_direct", "share_wall", "share_stop"]].sum(axis=1)
    assert (abs(shares - 1.0) < 1e-3).all()
    assert set(pd.read_csv(out / "lanes.csv")["window"]) == {"early", "late"}
    result = runner.invoke(app, ["report", str(tmp_path)])
    assert result.exit_code == 0, result.output
    claims = pd.read_csv(tmp_path / "claims.csv").set_index("claim_id")
    assert {1, 2} <= set(claims.index)
    text = (tmp_path / "REPORT.md").read_text()
    assert "of 2 tested" in text and "Table 1.1 beside ours" in text
    for stem in ("fig_1_4", "lanes_spatiotemporal"):
        assert (tmp_path / "figures" / f"{stem}.png").is_file()


def test_a_run_that_did_not_finish_is_left_out_and_named(tmp_path):
    from tavc_cli.report.runs import finished_runs

    (tmp_path / "killed" / "trials").mkdir(parents=True)  # trials, no tables yet
    failed = tmp_path / "failed"  # the tables of an earlier run, but this run wrote no provenance.json
    failed.mkdir()
    (failed / "state_time.csv").write_text("state,controller,mean_pct,std_pct,n_trials\n")
    (failed / "config.yaml").write_text("experiment_name: failed\n")
    (tmp_path / "figures").mkdir()  # not a run at all
    found, unfinished = finished_runs(tmp_path)
    assert found == {}
    assert unfinished == [failed, tmp_path / "killed"]


@pytest.fixture
def one_run(finished_run):
    """A folder holding one finished breakdown run (shared: only copies are changed)."""
    return finished_run(*SMOKE_BREAKDOWN, name="breakdown").parent


@pytest.mark.parametrize(("name", "damage"), [
    ("allocation.csv", b't_s,controller\n"0.0,tavc\n'),   # an unterminated quote
    ("trial_stats.csv", b"\xff\xfe\x00garbage\x81"),       # not text
    ("config.yaml", b"seed: [1, 2\n"),                     # not YAML
    ("config.yaml", b"seed: banana\n"),                    # YAML of the wrong type
    ("provenance.json", b"nope"),
])
def test_a_damaged_file_is_one_line_and_the_report_writes_nothing(one_run, tmp_path, name, damage):
    results = tmp_path / "results"
    shutil.copytree(one_run, results)
    (results / "breakdown" / name).write_bytes(damage)
    result = runner.invoke(app, ["report", str(results)])
    assert result.exit_code == 1
    lines = result.output.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith(f"error: {results / 'breakdown' / name}: cannot be read (")
    assert sorted(p.name for p in results.iterdir()) == ["breakdown"]  # no REPORT.md, claims.csv or figures


def test_a_report_path_taken_by_a_folder_is_one_line(one_run, tmp_path):
    results = tmp_path / "results"
    shutil.copytree(one_run, results)
    (results / "REPORT.md").mkdir()
    result = runner.invoke(app, ["report", str(results)])
    assert result.exit_code == 1
    assert result.output.strip() == (f"error: RESULTS_DIR: {results / 'REPORT.md'} is a directory; "
                                     "the report writes a file there")
    assert sorted(p.name for p in results.iterdir()) == ["REPORT.md", "breakdown"]


def test_a_run_folder_given_for_the_results_folder_says_which_to_give(one_run):
    result = runner.invoke(app, ["report", str(one_run / "breakdown")])
    assert result.exit_code == 1
    assert result.output.strip() == (f"error: RESULTS_DIR: {one_run / 'breakdown'} is one run's folder; give the "
                                     f"folder that holds the runs ({one_run}: every run under it is read), or move it "
                                     "into a folder of its own (<folder>/breakdown) and give that folder to report it "
                                     "alone")


def test_the_report_says_when_the_baselines_started_late():
    from tavc_cli.config import load_config, settings
    from tavc_cli.experiments.plan import plan_run
    from tavc_cli.report.text import late_start_lines

    def lines(*overrides):
        cfg = settings(load_config(list(overrides)))
        return late_start_lines(cfg, plan_run(cfg))

    (line, blank) = lines("experiment=heterogeneous", "scale=paper")
    assert "(random)" in line and "from 52,200 s, 1,800 s before the stable period" in line and "to 72,000 s" in line
    assert "rather than from 0 s" in line
    assert lines("experiment=heterogeneous", "baseline_lead_s=null") == []
    assert lines("experiment=initial_distribution") == []
    (line, _) = lines("experiment=breakdown", "scale=paper")
    assert "(random and static)" in line and "from -1,800 s, 1,800 s before the first event" in line
    assert "rather than from -18,000 s" in line


def test_one_trial_has_no_spread_in_its_table_nor_in_the_report(tmp_path):
    """A single trial's std is not 0: state_time.csv leaves it empty and the report says the
    number comes from one trial."""
    from tavc_cli.config import load_config, settings
    from tavc_cli.pipeline import run_experiment
    from tavc_cli.report import build_report

    out = tmp_path / "initial_distribution"
    run_experiment(settings(load_config(["experiment=initial_distribution", "scale=smoke", "duration_s=120",
                                         "convergence_s=20", "executor.n_jobs=1", "trials=1", "baseline_trials=1",
                                         f"output_dir={out}"])))
    table = pd.read_csv(out / "state_time.csv", dtype={"state": str})
    tavc = table[table["controller"] == "tavc"]
    assert (tavc["n_trials"] == 1).all() and tavc["std_pct"].isna().all()
    build_report(tmp_path)
    report = (tmp_path / "REPORT.md").read_text()
    row = next(line for line in report.splitlines() if line.startswith("| 3:3 |"))
    assert f"{tavc.set_index('state').loc['3:3', 'mean_pct']:.1f} (one trial)" in row
    assert "± |" not in report and "± nan" not in report


def test_the_report_says_what_it_is_doing_when_asked_and_is_quiet_otherwise(tmp_path):
    from typer.testing import CliRunner

    from tavc_cli.cli import app
    from tavc_cli.config import load_config, settings
    from tavc_cli.pipeline import run_experiment

    run_experiment(settings(load_config(["experiment=initial_distribution", "scale=smoke", "trials=1",
                                         "baseline_trials=1", f"output_dir={tmp_path / 'initial_distribution'}"])))
    shown = CliRunner().invoke(app, ["report", str(tmp_path), "--progress"])
    assert shown.exit_code == 0, shown.output
    stages = [line.split(" ")[1] for line in shown.stderr.splitlines()]
    assert stages == ["reading", "drawing", "written"], shown.stderr
    quiet = CliRunner().invoke(app, ["report", str(tmp_path)])  # not a terminal: no progress by default
    assert quiet.exit_code == 0 and quiet.stderr == "", quiet.stderr
    assert quiet.stdout.splitlines()[-1] == str(tmp_path / "REPORT.md")


def test_a_runs_settings_that_differ_from_the_chapters_name_a_reading_of_the_world_other_than_todays():
    """The headline's world is today's reading (dock, nearest, the crossing circuits); a run in
    another is said to be, and section 1.4's one circuit, an arena of its own, is no reading."""
    from tavc_cli.config import load_config
    from tavc_cli.config import settings as to_settings
    from tavc_cli.report.text import differences

    def said(*overrides):
        return differences(to_settings(load_config(["scale=paper", *overrides])))

    assert said("experiment=initial_distribution") == []
    assert said("experiment=initial_distribution", "passing=left", "arena=two_circuits_parallel") == [
        "the world read as arrival=dock passing=left arena=two_circuits_parallel (today's: arrival=dock "
        "passing=nearest arena=two_circuits; docs/readings.md)"]
    assert said("experiment=spatiotemporal") == []
    assert said("experiment=spatiotemporal", "arrival=range") == [
        "the world read as arrival=range passing=nearest (today's: arrival=dock passing=nearest; docs/readings.md)"]
