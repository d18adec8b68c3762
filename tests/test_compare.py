"""`tavc compare`: the four numbers read per trial, their tests, what each controller's runs
add to the user's settings, and the command end to end."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
import yaml
from typer.testing import CliRunner

from tavc_cli import api
from tavc_cli import config as tavc_config  # `config` below builds a run's settings
from tavc_cli.cli import app
from tavc_cli.compare.metrics import (
    above,
    comparison_table,
    cut_fill_delays,
    fast_share,
    predicted_state,
    rank_test,
    trial_metrics,
)
from tavc_cli.compare.run import controller_overrides, parse_reuse
from tavc_cli.errors import TavcError
from tests.helpers import tavc, tavc_here

REPO = Path(__file__).resolve().parent.parent
SAME = [{"speed_mps": 0.25, "group": "all"}] * 6
MIXED = [{"speed_mps": 0.3, "group": "fast"}] * 3 + [{"speed_mps": 0.2, "group": "slow"}] * 3


def config(members, breakdowns=0, state="circuits"):
    return {"team": {"members": members}, "events": {"breakdowns": [{}] * breakdowns},
            "analysis": {"state": state}, "scale": {"time_factor": 1.0}}


def test_the_predicted_state_is_the_models_for_the_team_left():
    allocations = {"5": [3, 2], "6": [3, 3]}
    assert predicted_state(config(SAME), allocations) == "3:3"
    assert predicted_state(config(SAME, breakdowns=1), allocations) == "3:2"
    assert predicted_state(config(SAME, breakdowns=2), allocations) is None  # no prediction for four
    # by group: the model's three on the high circuit, fastest first
    assert predicted_state(config(MIXED, state="groups"), allocations) == "3:0"
    assert predicted_state(config(MIXED, state="groups"), {"6": [4, 2]}) == "3:1"


def test_fast_share_by_hand():
    # half the time all three fast robots high (3:0), half the time one (1:2): (3 + 1) / 2 / 3
    stats_ = pd.DataFrame({"pct_3:0": [50.0, 0.0], "pct_1:2": [50.0, 0.0], "pct_0:3": [0.0, 100.0]})
    assert fast_share(stats_, 3) == pytest.approx([2 / 3, 0.0])


def test_rank_test_by_hand():
    # no overlap between three and three: U = 0, exact two-sided p = 2 / C(6, 3) = 0.1
    assert rank_test(np.array([1.0, 2, 3]), np.array([4.0, 5, 6])) == pytest.approx(0.1)
    assert math.isnan(rank_test(np.array([1.0]), np.array([4.0, 5, 6])))
    assert rank_test(np.array([2.0, 2]), np.array([2.0, 2])) == 1.0
    # 3 of the 4 pairs above, one tie: (3 + 0.5) / 4
    assert above(np.array([2.0, 3]), np.array([1.0, 2])) == pytest.approx(0.875)


class _NoAliases(yaml.SafeDumper):
    def ignore_aliases(self, data):
        return True


def write_run(folder: Path, members, controller, stats_rows, vacancy_rows=None, breakdowns=0, state="circuits"):
    folder.mkdir(parents=True)
    # written as tavc writes a config.yaml, with no YAML aliases (a folder's config with one is refused)
    (folder / "config.yaml").write_text(yaml.dump(config(members, breakdowns, state), Dumper=_NoAliases))
    pd.DataFrame(stats_rows).assign(controller=controller).to_csv(folder / "trial_stats.csv", index=False)
    if vacancy_rows is not None:
        pd.DataFrame(vacancy_rows).assign(controller=controller).to_csv(folder / "vacancy.csv", index=False)


def test_trial_metrics_read_a_breakdown_run(tmp_path):
    stats_rows = [{"trial": j, "duration_s": 1000.0, "value_rate_stable": 0.3 + j / 10, "pct_3:2": 40.0 * j,
                   "pct_2:3": 100 - 40.0 * j} for j in range(2)]
    # the vacancy opens 200 s in: trial 0's is filled 120 s after, trial 1's never (800 s left)
    vacancy = [{"trial": 0, "event_t_s": 200.0, "filled": True, "fill_delay_s": 120.0},
               {"trial": 1, "event_t_s": 200.0, "filled": False, "fill_delay_s": float("nan")}]
    write_run(tmp_path / "b", SAME, "mine", stats_rows, vacancy, breakdowns=1)
    frame = trial_metrics(tmp_path / "b", "breakdown", "mine", "mine", {"5": [3, 2], "6": [3, 3]})
    values = frame.set_index(["metric", "trial"])["value"]
    assert values[("score_per_s", 1)] == pytest.approx(0.4)
    assert values[("predicted_state_pct", 1)] == pytest.approx(40.0)
    assert values[("fill_delay_s", 0)] == 120.0 and values[("fill_delay_s", 1)] == math.inf
    assert values[("fill_window_s", 0)] == 800.0
    # another controller ran only 100 s after its event: every delay is cut at that window
    other = pd.DataFrame([{"experiment": "breakdown", "controller": "short", "trial": 0, "metric": m, "value": v}
                          for m, v in (("fill_delay_s", 50.0), ("fill_window_s", 100.0))])
    cut = cut_fill_delays(pd.concat([frame, other], ignore_index=True)).set_index(["controller", "metric", "trial"])
    assert cut.loc[("mine", "fill_delay_s", 0), "value"] == 100.0  # 120 s: not within the 100 s window
    assert cut.loc[("mine", "fill_delay_s", 1), "value"] == 100.0
    assert cut.loc[("short", "fill_delay_s", 0), "value"] == 50.0
    assert cut.loc[("mine", "filled_pct", 0), "value"] == 0.0 and cut.loc[("short", "filled_pct", 0), "value"] == 100
    assert "fill_window_s" not in set(cut.index.get_level_values("metric"))
    # trials of another label are not this controller's: named in one line
    with pytest.raises(TavcError, match="holds no trials of tavc_egreedy .label tavc; it holds mine"):
        trial_metrics(tmp_path / "b", "breakdown", "tavc_egreedy", "tavc", {"5": [3, 2]})


def test_the_table_tests_against_tavc_and_random_never_against_itself():
    trials = pd.DataFrame([{"experiment": "e", "metric": "score_per_s", "controller": c, "trial": j, "value": v}
                           for c, vs in {"tavc": [1, 2, 3], "random": [4, 5, 6], "mine": [7, 8, 9]}.items()
                           for j, v in enumerate(vs)])
    table = comparison_table(trials, {"tavc": 40.0, "random": 1.0, "mine": 40.0}).set_index("controller")
    assert math.isnan(table.loc["tavc", "p_vs_tavc"]) and math.isnan(table.loc["random", "p_vs_random"])
    assert table.loc["mine", "p_vs_tavc"] == pytest.approx(0.1)
    assert table.loc["tavc", "p_vs_random"] == pytest.approx(0.1)
    assert table.loc["mine", "mean"] == 8 and table.loc["mine", "std"] == 1 and table.loc["random", "time_factor"] == 1


def test_what_each_controllers_runs_add():
    converged = {"name": "converged", "time_factor": 40.0, "baseline_time_factor": 1.0}
    assert controller_overrides("tavc", converged) == ["baselines=[]"]
    assert controller_overrides("wolf_phc", converged) == ["learner=wolf_phc", "baselines=[]"]
    # what learns nothing runs the baselines' schedule, as every run's baselines do
    assert controller_overrides("informed", converged) == ["learner=informed", "baselines=[]", "scale.time_factor=1.0"]
    paper = {"name": "paper", "time_factor": 1.0, "baseline_time_factor": 1.0}
    assert controller_overrides("random", paper) == ["learner=random", "baselines=[]"]


def test_reuse_pairs_are_checked(tmp_path):
    assert parse_reuse([f"tavc={tmp_path}"]) == {"tavc": tmp_path}
    with pytest.raises(TavcError, match="is not CONTROLLER=FOLDER"):
        parse_reuse(["tavc"])
    with pytest.raises(TavcError, match="no folder"):
        parse_reuse([f"tavc={tmp_path / 'nowhere'}"])


@pytest.mark.slow
def test_compare_end_to_end_reruns_nothing_and_reuses_runs(tmp_path):
    out = tmp_path / "cmp"
    args = ["compare", "scale=smoke", "--learners", "tavc,random,informed", "--experiments", "breakdown",
            "--results", str(out), "--no-progress"]
    result = tavc(*args)
    assert result.returncode == 0, result.stderr
    table = pd.read_csv(out / "compare.csv")
    assert set(table["controller"]) == {"tavc", "random", "informed"}
    assert set(table["metric"]) == {"score_per_s", "predicted_state_pct", "fill_delay_s", "filled_pct"}
    informed = table[(table["controller"] == "informed") & (table["metric"] == "predicted_state_pct")]
    assert informed["mean"].iloc[0] == pytest.approx(100.0)  # it hands the team the model's 3:2 at once
    for name in ("compare.md", "compare_trials.csv", "compare.png", "compare.svg"):
        assert (out / name).is_file()
    trials = sorted((out / "runs").rglob("*.npz"))
    assert len(trials) == 6  # two trials for each of the three controllers
    stamps, written = [p.stat().st_mtime_ns for p in trials], (out / "compare.csv").read_bytes()
    assert tavc(*args).returncode == 0
    assert [p.stat().st_mtime_ns for p in trials] == stamps  # every trial reused
    assert (out / "compare.csv").read_bytes() == written
    # TAVC's runs taken from another folder instead of run again
    again = tmp_path / "again"
    result = tavc("compare", "scale=smoke", "--learners", "tavc,random", "--experiments", "breakdown",
                  "--results", str(again), "--reuse", f"tavc={out / 'runs' / 'tavc'}", "--no-progress")
    assert result.returncode == 0, result.stderr
    assert not (again / "runs" / "tavc").exists()
    reused = pd.read_csv(again / "compare.csv").set_index(["controller", "metric"])
    assert reused.loc[("tavc", "score_per_s"), "mean"] == pytest.approx(
        table.set_index(["controller", "metric"]).loc[("tavc", "score_per_s"), "mean"])


def test_compare_refuses_a_run_folder_and_an_unknown_learner_in_one_line(tmp_path):
    run = tmp_path / "run"
    run.mkdir()
    (run / ".tavc.json").write_text('{"tavc": "run", "files": []}')  # a run's folder, as tavc marks it
    result = tavc_here("compare", "scale=smoke", "--results", str(run))
    assert result.returncode == 1 and "is a tavc run's folder, not a comparison's folder" in result.stderr
    result = tavc_here("compare", "scale=smoke", "--learners", "tavc,nobody", "--results", str(tmp_path / "c"))
    assert result.returncode == 1 and "nobody" in result.stderr and "Traceback" not in result.stderr
    assert len(result.stderr.strip().splitlines()) == 1
    result = tavc_here("compare", "scale=smoke", "--learners", ",", "--results", str(tmp_path / "c"))
    assert result.returncode == 1 and "--learners: name each learner once" in result.stderr
    # a model file that is not there, and a folder to reuse without runs: refused before anything runs
    result = tavc_here("compare", "scale=smoke", "--learners", "tavc,random", "learner.model_file=/nowhere/model.json",
                       "--results", str(tmp_path / "d"))
    assert result.returncode == 1 and "learner.model_file: no model at /nowhere/model.json" in result.stderr
    # the model the predicted states come from is one of the comparison's world, whoever is compared
    result = tavc_here("compare", "scale=smoke", "--learners", "tavc,random", "arena=two_circuits_parallel",
                       f"learner.model_file={REPO / 'results/initial_distribution/model/model.json'}",
                       "--results", str(tmp_path / "d"))
    assert result.returncode == 1 and "(arena two_circuits (the run: two_circuits_parallel))" in result.stderr
    result = tavc_here("compare", "scale=smoke", "--learners", "tavc,random", "--reuse", f"tavc={tmp_path}",
                       "--results", str(tmp_path / "e"))
    assert result.returncode == 1 and "--reuse:" in result.stderr and "holds no finished run" in result.stderr
    assert not (tmp_path / "d" / "runs").exists() and not (tmp_path / "e" / "runs").exists()
    # an experiment compare does not serve: refused before its runs, which it could not compare
    result = tavc_here("compare", "scale=smoke", "--experiments", "spatiotemporal", "--learners", "tavc",
                       "--results", str(tmp_path / "f"))
    assert result.returncode == 1 and len(result.stderr.strip().splitlines()) == 1
    assert result.stderr.startswith("error: --experiments: 'spatiotemporal' is not a scenario compare serves")
    assert not (tmp_path / "f").exists()


@pytest.mark.parametrize(("learners", "reuse", "line"), [
    (["tavc", "nobody"], {}, "--learners: nobody: learner=nobody: no such option; choose tavc (each scenario's own) "
                             "or one of alternate, behaviour_softmax, informed, model, plugin, random, static, "
                             "tavc_egreedy, tavc_softmax, threshold, wolf_phc"),
    (["tavc", "random"], {"wolf_phc": "."}, "--reuse: wolf_phc is not one of the controllers compared (tavc, random)"),
    (["tavc", "random"], {"random": "."}, "--reuse: initial_distribution: holds no finished run of "
                                          "initial_distribution (no provenance.json)"),
])
def test_a_learner_or_a_folder_to_reuse_the_comparison_cannot_take_is_refused_before_it_composes(
        learners, reuse, line, tmp_path, monkeypatch):
    """Composing every controller's settings for every scenario takes seconds; what needs none of
    them (a learner with no config, a controller reused but not compared, a folder to reuse with
    no finished run) is refused first."""
    def composed(*args, **kwargs):
        raise AssertionError("composed before refusing")

    monkeypatch.chdir(tmp_path)
    monkeypatch.setattr(tavc_config, "load_config", composed)
    monkeypatch.setattr(tavc_config, "load_experiments", composed)
    with pytest.raises(TavcError) as refused:
        api.compare_summary(["scale=smoke"], learners=learners, experiments=["initial_distribution", "breakdown"],
                            results_dir=tmp_path / "c", reuse=reuse)
    assert str(refused.value).startswith(line)
    assert not (tmp_path / "c").exists()


@pytest.mark.parametrize(("override", "line"), [
    ("~learner.model_file", "error: learner.model_file: every run reads it, so ~ cannot remove it (the schema's "
                            "default would take its place); set it (learner.model_file=<value>)"),
    ("learner.model_file", "error: learner.model_file: not an override (key=value); to set a key, write "
                           "learner.model_file=<value>"),
    ("learner.model_file=null", "error: learner.model_file: must be the path of a model.json (`tavc model` writes "
                                "one), got null"),
    ("learner.model_file='/nowhere/m.json'", "error: learner.model_file: no model at /nowhere/m.json; run `tavc "
                                             "model` first, or name its model.json"),
    ("learner.model_file=a.json,b.json", "error: learner.model_file: a sweep needs -m/--multirun (to set a list, "
                                         "write learner.model_file=[a,b])"),
])
def test_the_comparisons_model_file_is_read_as_a_model_learners_run_reads_it(override, line, tmp_path):
    """The comparison takes learner.model_file out of the overrides its controllers share (only the
    model's read it), so it reads that one override as a model learner's run does: quotes and all,
    never ~ (a traceback once), never null (`no model at None`) and never a sweep."""
    result = CliRunner().invoke(app, ["compare", "scale=smoke", "--learners", "tavc,random", "--results",
                                      str(tmp_path / "c"), override])
    assert result.exit_code == 1 and result.output.strip() == line
    assert not (tmp_path / "c").exists()


def test_the_report_section_marks_differences_from_tavc_by_hand(tmp_path):
    from tavc_cli.report.compare import compare_lines

    rows = []
    for metric in ("score_per_s", "fill_delay_s"):
        rows += [{"experiment": "breakdown", "metric": metric, "controller": "tavc", "time_factor": 40.0,
                  "n_trials": 8, "mean": 1.0, "std": 0.1, "median": 1.0, "p_vs_tavc": math.nan, "p_vs_random": 0.01,
                  "above_tavc": math.nan, "above_random": 0.9},
                 {"experiment": "breakdown", "metric": metric, "controller": "mine", "time_factor": 40.0,
                  "n_trials": 8, "mean": 2.0, "std": 0.1, "median": 2.0, "p_vs_tavc": 0.05, "p_vs_random": 0.5,
                  "above_tavc": 0.8, "above_random": 0.6}]
    (tmp_path / "compare" / "converged").mkdir(parents=True)
    pd.DataFrame(rows).to_csv(tmp_path / "compare" / "converged" / "compare.csv", index=False)
    text = "\n".join(compare_lines(tmp_path))
    assert "## Other learners on the chapter's scenarios" in text
    assert "### converged: tavc at 40x (8 trials), mine at 40x (8 trials)" in text
    # a higher score is better (▲), a longer wait for the vacancy worse (▼); p 0.5 against random: ◇
    assert "| mine | 2 ± 0.1 ▲ ◇ |" in text and "| mine | 2 ± 0 ▼ ◇ |" in text
    assert "| tavc | 1 ± 0.1 |" in text  # TAVC differs from random (p 0.01): no mark
    assert "mine: better than TAVC in 1, worse in 1, not told apart in 0 of 2 numbers." in text
    # the sentences: the best mean, higher for a score, lower for a wait; TAVC against random
    assert "breakdown: highest mean mine (2); TAVC differs from random (p = 0.01)." in text
    assert "breakdown: lowest mean tavc (1); TAVC differs from random (p = 0.01)." in text
    assert compare_lines(tmp_path / "nothing") == []
    # a damaged comparison is one line naming it: a column missing, text where a number belongs
    table = tmp_path / "compare" / "converged" / "compare.csv"
    pd.DataFrame(rows).drop(columns="controller").to_csv(table, index=False)
    with pytest.raises(TavcError, match=r"compare\.csv: cannot be read \(no column controller\); run `tavc compare`"):
        compare_lines(tmp_path)
    pd.DataFrame(rows).assign(p_vs_tavc="small").to_csv(table, index=False)
    with pytest.raises(TavcError, match=r"cannot be read \(column p_vs_tavc holds something other than numbers\)"):
        compare_lines(tmp_path)


def test_a_comparison_table_edited_apart_from_its_trials_is_refused(tmp_path):
    """The report reads compare.csv only while it is what compare_trials.csv beside it gives: the
    committed comparison as written passes; one mean edited (0.33 -> 0.93) is one line."""
    import shutil

    from tavc_cli.errors import TavcError
    from tavc_cli.report.compare import check_compare_tables

    committed = Path(__file__).resolve().parent.parent / "results" / "compare" / "paper"
    shutil.copytree(committed, tmp_path / "compare" / "paper")
    check_compare_tables(tmp_path)
    path = tmp_path / "compare" / "paper" / "compare.csv"
    lines = path.read_text().splitlines(keepends=True)
    cells = lines[1].split(",")
    cells[5] = str(float(cells[5]) + 0.6)  # the mean of the first row
    path.write_text("".join([lines[0], ",".join(cells), *lines[2:]]))
    with pytest.raises(TavcError, match=r"compare.csv: not what compare_trials.csv beside it gives \(one of them"):
        check_compare_tables(tmp_path)
    (tmp_path / "compare" / "paper" / "compare_trials.csv").unlink()
    with pytest.raises(TavcError, match=r"compare_trials.csv: missing, though compare.csv beside it is drawn"):
        check_compare_tables(tmp_path)
