"""The report's section on the surrogate and the study's figures, from synthetic study tables."""

from __future__ import annotations

import math

import pandas as pd
import pytest

from tavc_cli.errors import TavcError
from tavc_cli.report.surrogate import surrogate_lines
from tavc_cli.viz.surrogate import study_figures


def _comparison() -> pd.DataFrame:
    base = {"experiment": "initial_distribution", "n_trials": 20, "n_mixed": 0.0, "q_drift": 0.01,
            "policy_changed_share": 0.0, "value_rate_stable": 0.4}
    return pd.DataFrame([
        {**base, "horizon": "40x", "engine": "simulator", "largest_diff_pts": 0.0, "at_state": "", "modal_state": "3:3",
         "pct_modal": 60.0, "n_stayers_high": 0.0, "n_stayers_low": 0.0, "n_alternators": 6.0, "switch_share": 0.94,
         "regime": "turn-taking", "converged": True, "claims": "3:yes 5:yes"},
        {**base, "horizon": "40x", "engine": "surrogate_makeup", "largest_diff_pts": 23.0, "at_state": "3:3",
         "modal_state": "3:3", "pct_modal": 37.0, "n_stayers_high": 0.0, "n_stayers_low": 0.0, "n_alternators": 6.0,
         "switch_share": 0.93, "regime": "turn-taking", "converged": True, "claims": "3:yes 5:yes"},
        {**base, "horizon": "40x", "engine": "surrogate_stayers", "largest_diff_pts": 18.0, "at_state": "4:2",
         "modal_state": "3:3", "pct_modal": 50.0, "n_stayers_high": 0.3, "n_stayers_low": 0.7, "n_alternators": 0.1,
         "switch_share": 0.26, "regime": "mixed", "converged": False, "claims": "3:yes 5:no"},
    ])


def _phase() -> pd.DataFrame:
    rows = []
    for horizon in ("1x", "40x"):
        for n in (2, 3):
            for ratio in (1.0, 2.0):
                rows.append({"engine": "surrogate", "horizon": horizon, "n_robots": n, "ratio": ratio, "n_trials": 8,
                             "high_share": 0.5 if ratio == 1.0 else 0.8, "modal_state": f"{n - 1}:1",
                             "pct_modal": 40.0, "n_alternators": 1.0 if horizon == "40x" else 0.0,
                             "n_stayers_high": 0.0, "n_stayers_low": 0.0, "switch_share": 0.5,
                             "regime": "turn-taking" if horizon == "40x" else "persistence", "converged": True,
                             "model_state": f"{n - 1}:1", "model_high_share": (n - 1) / n})
    rows.append({**rows[-1], "engine": "simulator", "n_trials": 20, "high_share": 0.7})
    return pd.DataFrame(rows)


def _study(tmp_path):
    root = tmp_path / "surrogate"
    root.mkdir()
    _comparison().to_csv(root / "comparison.csv", index=False)
    _phase().to_csv(root / "phase.csv", index=False)
    pd.DataFrame([{"parameter": "chapter", "value": math.nan, "factor": f, "converged": f >= 20, "horizon": 20.0}
                  for f in (1.0, 20.0, 40.0)] +
                 [{"parameter": "alpha", "value": 0.05, "factor": f, "converged": False, "horizon": math.inf}
                  for f in (1.0, 20.0, 40.0)] +
                 [{"parameter": "chapter", "value": math.nan, "factor": f, "converged": f >= 40, "horizon": 40.0,
                   "engine": "simulator"} for f in (1.0, 20.0, 40.0)]).to_csv(root / "horizon.csv", index=False)
    pd.DataFrame([{"engine": "surrogate", "experiment": "x", "scale": "paper", "sim_s_per_wall_s": 600000.0},
                  {"engine": "simulator", "experiment": "x", "scale": "paper", "sim_s_per_wall_s": 10000.0}]).to_csv(
        root / "speed.csv", index=False)
    return root


def test_the_section_names_where_the_surrogate_and_the_simulator_part(tmp_path):
    _study(tmp_path)
    text = "\n".join(surrogate_lines(tmp_path))
    assert "## The surrogate: the learning dynamics on measured tasks" in text
    # the same make-up, states apart: the phases
    assert "**initial_distribution at 40x, surrogate (make-up)**: the make-up agrees" in text
    assert "differ by 23.0 points in 3:3" in text
    # the stayers-only surrogate makes the group differently: the traffic decides
    assert "**initial_distribution at 40x, surrogate (stayers alone)**: the group is made differently (mixed" in text
    assert "claims 5:no against the simulator's 5:yes" in text
    # the horizons: converged from 20x, or not within the ladder
    assert "| chapter | the chapter's | 20x |" in text and "| alpha | 0.05 | not within 40x |" in text
    assert "| chapter, the physical simulator (its ladder) | the chapter's | 40x |" in text
    # speed by hand: 600,000 / 10,000 = 60 times; 720,000 s of a 200 h trial in 1.2 s against 72 s
    assert "60 times faster" in text and "takes 1.2 s against 72 s" in text
    # the checked point beside its surrogate cell
    assert "checked, 3 robots, ratio 2, 40x: share on the high-value circuit 0.70" in text


def test_no_study_no_section(tmp_path):
    assert surrogate_lines(tmp_path) == []


def test_the_study_figures_say_what_they_show_with_a_colour_bar_per_heat_map(tmp_path):
    import matplotlib.pyplot as plt

    root = _study(tmp_path)
    made = []
    original = plt.Figure.savefig

    def keep(fig, *args, **kwargs):
        made.append(fig)
        return original(fig, *args, **kwargs)

    plt.Figure.savefig = keep
    try:
        written = study_figures(root)
    finally:
        plt.Figure.savefig = original
    assert {p.name for p in written} >= {"comparison.png", "phase.png", "horizon.png"}
    phase = next(f for f in made if "Phase diagram" in f._suptitle.get_text())
    assert "8 trials a cell" in phase._suptitle.get_text()
    heat_maps = [ax for ax in phase.axes if ax.images]
    colour_bars = [ax for ax in phase.axes if ax.get_label() == "<colorbar>"]
    assert len(heat_maps) == 4 and len(colour_bars) == 4


@pytest.mark.slow
def test_a_surrogate_run_is_reported_as_such_and_never_in_the_simulators_place(tmp_path, monkeypatch):
    from typer.testing import CliRunner

    from tavc_cli.cli import app

    monkeypatch.chdir(tmp_path)
    runner = CliRunner()
    assert runner.invoke(app, ["surrogate", "experiment=breakdown", "scale=smoke", "--no-progress",
                               "output_dir=runs/smoke/breakdown_surrogate"]).exit_code == 0
    # a run in a folder of the user's keeps its measured tasks there, not in the scale's shared folder
    assert (tmp_path / "runs/smoke/breakdown_surrogate/tasks/task_times.csv").is_file()
    assert sorted(p.name for p in (tmp_path / "runs/smoke").iterdir()) == ["breakdown_surrogate"]
    # another configuration into the same folder: refused before any task is measured, anywhere
    other = runner.invoke(app, ["surrogate", "experiment=breakdown", "scale=smoke", "--no-progress", "seed=5",
                                "surrogate.tasks_dir=elsewhere", "output_dir=runs/smoke/breakdown_surrogate"])
    assert other.exit_code == 1 and "holds a finished run of another configuration" in other.output
    assert not (tmp_path / "elsewhere").exists()
    alone = runner.invoke(app, ["report", "runs/smoke"])
    assert alone.exit_code == 0
    text = (tmp_path / "runs/smoke/REPORT.md").read_text()
    assert "computed by the surrogate of the learning dynamics, not the physical simulator" in text
    assert runner.invoke(app, ["run", "experiment=breakdown", "scale=smoke", "--no-progress",
                               "output_dir=runs/smoke/zz_breakdown"]).exit_code == 0
    assert runner.invoke(app, ["report", "runs/smoke"]).exit_code == 0
    text = (tmp_path / "runs/smoke/REPORT.md").read_text()
    # the simulator's run is the one the claims are tested on, though the surrogate's comes first by name
    assert "The claims are tested on `zz_breakdown`" in text
    assert "### breakdown_surrogate: another run of breakdown, on the surrogate" in text
    assert "not the simulator" in text and "(on the surrogate)" in text


@pytest.mark.parametrize(("name", "text", "says"), [
    ("comparison.csv", 'experiment,engine\nx,"surrogate\n',
     "cannot be read (Error tokenizing data. C error: EOF inside string starting at row 1)"),
    ("phase.csv", "engine,horizon\nsurrogate,40x\n", "cannot be read (no column n_robots, ratio, n_trials, high_share, "
                                                      "modal_state, model_state, regime)"),
    ("speed.csv", "engine,sim_s_per_wall_s\nsurrogate,fast\n", "cannot be read (column sim_s_per_wall_s holds "
                                                               "something other than numbers)"),
    ("tasks/task_times.json", '{"measurement": [1, 2]}', "cannot be read (not a record of the study's measurement)"),
    ("tasks/task_times.json", '{"measurement": {"warmup_s": "x"}}',
     "cannot be read (not a record of the study's measurement)"),
    ("phase.csv", "engine,horizon,n_robots,ratio,n_trials,high_share,modal_state,model_state,regime\n"
                  "surrogate,40x,3,1.1,,0.5,2:1,2:1,mixed\n", "cannot be read (an empty cell in column n_trials)"),
    ("tasks/task_times.json", "{", "cannot be read (Expecting property name enclosed in double quotes: line 1 "
                                   "column 2 (char 1))"),
])
def test_a_damaged_file_of_the_study_is_one_line_naming_it(tmp_path, name, text, says):
    root = _study(tmp_path)
    (root / "tasks").mkdir()
    pd.DataFrame([{"team": "all:6", "makeup": "all:0-0-6", "n": 5}]).to_csv(root / "tasks/task_times_summary.csv",
                                                                            index=False)
    (root / "tasks/task_times.json").write_text('{"measurement": {"trials_per_makeup": 4}}')
    assert "4 static trials each" in "\n".join(surrogate_lines(tmp_path))
    (root / name).write_text(text)
    with pytest.raises(TavcError) as refused:
        surrogate_lines(tmp_path)
    assert str(refused.value) == f"{root / name}: {says}; run `tavc surrogate --study` again to rewrite it"


def test_the_report_refuses_a_damaged_study_table_before_it_writes_anything(finished_run, tmp_path):
    """The study's tables are checked with the runs, before the first write: one line, nothing written."""
    import shutil

    from typer.testing import CliRunner

    from tavc_cli.cli import app
    from tests.helpers import SMOKE_BREAKDOWN

    results = tmp_path / "results"
    shutil.copytree(finished_run(*SMOKE_BREAKDOWN, name="breakdown"), results / "breakdown")
    _study(results)
    (results / "surrogate" / "ladder.csv").write_text("horizon,engine\n40x\n")
    result = CliRunner().invoke(app, ["report", str(results)])
    assert result.exit_code == 1
    assert result.output.strip() == (f"error: {results / 'surrogate' / 'ladder.csv'}: cannot be read (no column "
                                     "modal_state, at_state, converged, pct_modal, n_alternators, largest_diff_pts); "
                                     "run `tavc surrogate --study` again to rewrite it")
    assert sorted(p.name for p in results.iterdir()) == ["breakdown", "surrogate"]
