"""The TAVC model on hand-made tables, and one small real measurement end to end."""

import json
import math

import pandas as pd
import pytest
from typer.testing import CliRunner

from tavc_cli.cli import app
from tavc_cli.config import load_config, settings
from tavc_cli.experiments.store import Executor
from tavc_cli.model import core, world_search
from tavc_cli.model.api import run_model


def table_from(c_and_t: dict) -> core.CTable:
    """{split: ((c_0, t_0), (c_1, t_1))} -> CTable."""
    table = core.CTable(2)
    for n, cells in c_and_t.items():
        table.cells[n] = tuple(core.Cell(c=c, t=t) for c, t in cells)
    return table


INF = math.inf
# Two robots, equal values. Circuit 0 crowds badly: two robots on it deliver 0.12/s
# together (each robot's cycle 2 / 0.12 = 16.67 s), one alone 0.1/s (10 s). Circuit 1
# is slow: one robot 0.05/s (20 s), two 0.06/s (33.3 s).
TRAGEDY = table_from({
    (1, 0): ((0.10, 10.0), (0.0, INF)),
    (0, 1): ((0.0, INF), (0.05, 20.0)),
    (2, 0): ((0.12, 2 / 0.12), (0.0, INF)),
    (1, 1): ((0.10, 10.0), (0.05, 20.0)),
    (0, 2): ((0.0, INF), (0.06, 2 / 0.06)),
})


def test_slot_values_follow_equation_1_2():
    w = [1.0, 1.0]
    # s_0((1,0)) = w_0 (c_0(2,0) - c_0(1,0)) = 0.12 - 0.10 = 0.02
    assert core.slot_value(TRAGEDY, (1, 0), 0, w) == pytest.approx(0.02)
    # s_1((1,0)) = w_1 (c_1(1,1) - c_1(1,0)) = 0.05 - 0 = 0.05
    assert core.slot_value(TRAGEDY, (1, 0), 1, w) == pytest.approx(0.05)
    # scaled by the value: w_0 = 10 -> 0.2
    assert core.slot_value(TRAGEDY, (1, 0), 0, [10.0, 1.0]) == pytest.approx(0.2)
    # a split beyond the table has no slot value
    assert math.isnan(core.slot_value(TRAGEDY, (2, 0), 0, w))


def test_optimum_and_individual_equilibrium_differ_when_crowding_pays_individually():
    w = [1.0, 1.0]
    # total value: (2,0) 0.12, (1,1) 0.10 + 0.05 = 0.15, (0,2) 0.06 -> optimum (1,1)
    assert core.optimal_split(TRAGEDY, 2, w) == (1, 1)
    assert core.slot_fill(TRAGEDY, 2, w) == (1, 1)
    # in (1,1) the robot on circuit 1 earns 1/20 = 0.05 and would earn 1/16.67 = 0.06 on
    # circuit 0, so it moves; in (2,0) a robot moving to circuit 1 would drop to 1/20
    assert not core.is_equilibrium(TRAGEDY, (1, 1), w)
    assert core.is_equilibrium(TRAGEDY, (2, 0), w)
    assert core.equilibria(TRAGEDY, 2, w) == [(2, 0)]
    assert core.predicted_split(TRAGEDY, 2, w) == (2, 0)


def test_state_label_puts_the_high_value_circuit_first():
    assert core.state_label((2, 4), [2200, 2000]) == "2:4"
    assert core.state_label((2, 4), [2000, 2200]) == "4:2"
    assert core.intended_split(6, [2200, 2000]) == (3, 3)
    assert core.intended_split(5, [2200, 2000]) == (3, 2)
    assert core.intended_split(5, [2000, 2200]) == (2, 3)


def crowding_table(n_max: int) -> core.CTable:
    """Task time grows with the robots on the same circuit only: t(k) = 60 (1 + 0.3 (k - 1))."""
    def t(k):
        return 60.0 * (1 + 0.3 * (k - 1))

    table = core.CTable(2)
    for n in core.splits_up_to(n_max, 2):
        table.cells[n] = tuple(core.Cell(c=(k / t(k) if k else 0.0), t=(t(k) if k else INF), t_lo=t(k) * 0.99,
                                         t_hi=t(k) * 1.01) for k in n)
    return table


def test_calibration_makes_3_3_and_3_2_the_equilibria_and_meets_1_3_and_1_4():
    table = crowding_table(6)
    # t(2)=78, t(3)=96, t(4)=114. With rho = w_high / w_low:
    # 6 robots at 3:3: high stays iff rho/96 >= 1/114 (rho >= 0.842); low stays iff rho <= 114/96 = 1.1875
    # 5 robots at 3:2: high stays iff rho/96 >= 1/96 (rho >= 1); low stays iff rho <= 114/78 = 1.4615
    # feasible [1, 1.1875]; geometric middle sqrt(1.1875) = 1.0897 -> w_high = round(2000 * 1.0897) = 2179
    cal = core.calibrate(table, [(6, (3, 3)), (5, (3, 2))], low_value=2000.0)
    assert cal["feasible"]
    assert cal["ratio_interval"] == pytest.approx([1.0, 114 / 96])
    assert cal["values"] == [2179, 2000.0]
    w = cal["values"]
    assert core.equilibria(table, 6, w) == [(3, 3)]
    assert core.predicted_split(table, 5, w) == (3, 2)
    assert core.constraint_1_3(table, 6, w, 3)["holds"]
    assert core.constraint_1_4(table, 5, w, 3, preferred=0)["holds"]
    # the chapter's literal 2200/2000 (rho 1.1) also lies inside; 2400/2000 (rho 1.2) does not
    assert core.constraint_1_3(table, 6, [2200, 2000], 3)["holds"]
    assert not core.constraint_1_3(table, 6, [2400, 2000], 3)["holds"]


def test_calibration_reports_infeasible_targets():
    table = crowding_table(6)
    # 4:2 and 3:3 cannot both be equilibria of six robots: at 4:2 a high robot stays only
    # if rho / t(4) >= 1 / t(3), rho >= 114/96; at 3:3 a low robot stays only if
    # 1 / t(3) >= rho / t(4), rho <= 114/96. The interval shrinks to a point: no margin.
    cal = core.calibrate(table, [(6, (4, 2)), (6, (3, 3))], low_value=2000.0)
    assert not cal["feasible"]
    assert math.isnan(cal["ratio"])


def test_a_measurement_that_delivered_nothing_calibrates_nothing():
    """Every task time infinite (no robot delivered in the measurement): each bound on the ratio
    is infinite over infinite, unknown, so no values are calibrated, and none called robust."""
    nothing = table_from({n: ((0.0, INF), (0.0, INF)) for n in [(3, 3), (4, 2), (2, 4), (3, 2), (4, 1), (2, 3)]})
    assert all(math.isnan(b) for b in core.ratio_bounds(nothing, [(6, (3, 3)), (5, (3, 2))]))
    cal = core.calibrate(nothing, [(6, (3, 3)), (5, (3, 2))], low_value=2000.0)
    assert not cal["feasible"] and not cal["robust"] and math.isnan(cal["values"][0])


def test_model_smoke_measurement_end_to_end(tmp_path):
    cfg = settings(load_config(["arena=two_circuits", "team.n_robots=3", "scale=smoke", f"output_dir={tmp_path}",
                                "model.trials_per_split=2", "model.measure_s=3000", "tasks.values=[2200,2000]"]))
    result = run_model(cfg)
    model_json = json.loads((tmp_path / "model" / "model.json").read_text())
    assert model_json["n_robots"] == 3
    assert model_json["predicted_state"] in {"3:0", "2:1", "1:2", "0:3"}
    assert set(model_json["by_team_size"]) == {"3"}
    csv = (tmp_path / "model" / "model.csv").read_text().splitlines()
    assert csv[0].startswith("split,state,n_robots,circuit,n_on_circuit,c_per_s")
    # splits of 1..3 robots over 2 circuits: 2 + 3 + 4 = 9 splits, 2 rows each
    assert len(csv) - 1 == 18
    # a rerun measures nothing again
    again = run_model(cfg)
    assert again["n_reused"] == 9 * 2
    assert again["model"]["predicted_state"] == result["model"]["predicted_state"]


# --- measurement: stuck robots count -----------------------------------------------------------


def _record(deliveries: list[tuple[float, int]], n_arrivals: int = 0):
    """A trial record with deliveries (t_s, circuit) of 60 s tasks spent driving."""
    from tavc_cli.experiments.records import TableBuilder, TrialRecord

    rows = TableBuilder()
    for t, circuit in deliveries:
        rows.add("deliveries", t, 0, circuit, 60.0, 1.0, 1.0, 1.0, 60.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0)
    for k in range(n_arrivals):
        rows.add("arrivals", 100.0 + k, 0, 0, 0, 0)
    return TrialRecord(meta={}, tables=rows.build())


def test_task_time_counts_a_trial_whose_robots_delivered_nothing():
    from tavc_cli.model.measure import cells_for

    # split (2, 0), window 1000 s after 0 s: trial A delivers 20 times, trial B (stuck) never
    a = _record([(10.0 + 40 * k, 0) for k in range(20)])
    b = _record([])
    (cell, empty) = cells_for([a, b], (2, 0), 0.0, 1000.0, 0.9)
    # c = mean(20 / 1000, 0) = 0.01 per s; t = n / c = 2 / 0.01 = 200 s, not the 60 s of the
    # tasks that were completed (dropping trial B would have said 2 / 0.02 = 100 s)
    assert cell.c == pytest.approx(0.01)
    assert cell.t == pytest.approx(200.0)
    assert cell.t_delivered == pytest.approx(60.0)
    # two trials: half-width t(0.95, 1) * std / sqrt(2) = 6.314 * 0.01414 / 1.414 = 0.06314 > c,
    # so the interval's lower end is below zero and t's upper end is infinite
    assert cell.c_lo < 0 and cell.t_hi == INF
    assert cell.budget[0] == pytest.approx(60.0)  # all of it driving
    assert empty.c == 0.0 and empty.t == INF
    # one trial: no interval at all, on c nor on t
    (single, _) = cells_for([a], (2, 0), 0.0, 1000.0, 0.9)
    assert single.t == pytest.approx(100.0) and math.isnan(single.t_lo) and math.isnan(single.t_hi)


def test_arrivals_per_hour_average_over_trials():
    from tavc_cli.model.measure import arrivals_per_hour

    # 30 and 10 arrivals in a 1800 s window: 20 per half hour on average, 40 per hour
    assert arrivals_per_hour([_record([], 30), _record([], 10)], 0.0, 1800.0) == pytest.approx(40.0)


# --- the world search's selection rule ----------------------------------------------------------


def _row(arrivals, feasible, robust, rays=31):
    return {"arrivals_per_5h": arrivals, "feasible": feasible, "robust": robust, "robot.laser.n_rays": rays}


def test_world_search_prefers_robust_then_most_arrivals_then_fewer_rays():
    from tavc_cli.model.world_search import choose

    # a feasible point with more arrivals loses to a robust one
    assert choose([_row(2500, True, False), _row(2000, True, True)]) == (1, True)
    # among robust points the most arrivals wins; on a tie the cheaper laser
    assert choose([_row(2000, True, True), _row(2200, True, True, 61), _row(2200, True, True, 31)]) == (2, True)
    # no robust point: the best feasible one, flagged as not robust
    assert choose([_row(1800, True, False), _row(1900, True, False), _row(3000, False, False)]) == (1, False)
    # nothing feasible: nothing chosen; a point with no arrivals measured is never chosen
    assert choose([_row(3000, False, False)]) == (None, False)
    assert choose([_row(math.nan, True, True), _row(1000, True, True)]) == (1, True)


def test_world_search_measures_the_splits_the_constraints_need():
    from tavc_cli.model.world_search import needed_splits

    # six robots: 3:3 and its one-robot moves; five: 3:2 and its moves; one robot alone
    assert needed_splits(6, [2200.0, 2000.0]) == [(1, 0), (2, 3), (3, 2), (4, 1), (2, 4), (3, 3), (4, 2)]


def test_sensitivity_varies_one_setting_of_the_chosen_world_at_a_time():
    from tavc_cli.model.world_search import one_axis_variants
    from tavc_cli.settings import GridAxis

    axes = [GridAxis(key="a", values=[1, 2]), GridAxis(key="b", values=[0.0, 5.0, 10.0])]
    assert one_axis_variants(axes, {"a": 2, "b": 5.0}) == [
        ("chosen", {"a": 2, "b": 5.0}), ("a", {"a": 1, "b": 5.0}),
        ("b", {"a": 2, "b": 0.0}), ("b", {"a": 2, "b": 10.0}),
    ]


@pytest.mark.slow
def test_sensitivity_end_to_end_writes_task_times_per_world_and_a_figure(tmp_path):
    from tavc_cli.model.report import sensitivity_text
    from tavc_cli.model.world_search import point_id, run_sensitivity
    from tavc_cli.viz.sensitivity import task_time_figure

    base = ["arena=two_circuits", "team.n_robots=3", "scale=smoke", f"output_dir={tmp_path}", "learner=static",
            "tasks.values=[2200,2000]"]
    variants = [(varied, point, settings(load_config([*base, f"robot.dock.dwell_s={point['robot.dock.dwell_s']}"])))
                for varied, point in [("chosen", {"robot.dock.dwell_s": 5.0}),
                                      ("robot.dock.dwell_s", {"robot.dock.dwell_s": 0.0})]]
    sens = run_sensitivity(variants, tmp_path, n_robots=3, trials=2, warmup_s=10.0, measure_s=300.0, confidence=0.9,
                           executor=Executor(n_jobs=1, batch_size=8), progress=False)
    frame = sens["table"]
    # two worlds x two circuits x n = 1..3 robots on the circuit
    assert len(frame) == 2 * 2 * 3
    assert list(dict.fromkeys(frame["world"])) == ["chosen", "dwell_s=0"]
    worlds = sens["result"]["worlds"]
    # each world's trials are the search's own: named by the grid point's id, and a rerun runs nothing
    assert [w["point"] for w in worlds] == [point_id(p) for _, p, _ in variants]
    again = run_sensitivity(variants, tmp_path, n_robots=3, trials=2, warmup_s=10.0, measure_s=300.0,
                            confidence=0.9, executor=Executor(n_jobs=1, batch_size=8), progress=False)
    pd.testing.assert_frame_equal(again["table"], frame)
    # a task is two dock visits: standing 5 s at each makes it longer than standing not at all
    t3 = frame[(frame["circuit"] == 0) & (frame["n_on_circuit"] == 3)].set_index("world")["task_time_s"]
    assert t3["chosen"] > t3["dwell_s=0"]
    text = sensitivity_text(sens)
    assert "chosen" in text and "dwell_s=0" in text and "3->" in text
    paths = task_time_figure(tmp_path / "sensitivity.csv", tmp_path / "sensitivity.json", tmp_path / "task_times")
    assert [p.suffix for p in paths] == [".png", ".svg"] and all(p.stat().st_size > 0 for p in paths)


def test_a_circuit_that_delivered_nothing_is_left_for_one_that_pays():
    # a measurement too short for circuit 1 to finish a task with two robots on it: t infinite
    table = table_from({(2, 0): ((0.1, 20.0), (0.0, INF)), (1, 1): ((0.08, 12.5), (0.05, 20.0)),
                        (0, 2): ((0.0, INF), (0.0, INF))})
    values = [1.0, 1.0]
    # out of 1:1: from circuit 0 (1/12.5 per s) to 0:2, which pays nothing (-100 %); from circuit 1
    # (1/20 per s) to 2:0, which pays 1/20 too (no gain)
    assert core.deviation_gains(table, (1, 1), values) == [(0, 1, -1.0), (1, 0, 0.0)]
    # out of 0:2, where nothing is delivered: 1:1 pays, an infinite gain; never a division by zero
    assert core.deviation_gains(table, (0, 2), values) == [(1, 0, INF)]
    assert not core.is_equilibrium(table, (0, 2), values)


def test_a_calibration_search_records_the_world_it_was_asked_beside_its_choice(tmp_path):
    """`tavc calibrate` with the dwell set to 2.5 s, off its grid over the dwell, writes the world
    as asked (`configured`) in search.json, the report's way to judge a reading as configured. Into
    the folder of an earlier search (overwrite=true) it leaves none of that one's tables and figures
    beside its own (a grid over the dwell alone draws no sensitivity figure), and its .tavc.json
    lists the files it holds."""
    from tavc_cli.ownership import CALIBRATION_FILES

    folder = tmp_path / "calibration" / "world"
    folder.mkdir(parents=True)
    for name in CALIBRATION_FILES:  # an earlier search's, each marked as such
        (folder / name).write_text("earlier")
    (folder / ".tavc.json").write_text(json.dumps({"tavc": "calibration", "files": sorted(CALIBRATION_FILES)}))
    (folder / "search.json").write_text(json.dumps({"n_points": 48}))
    args = ["calibrate", "scale=smoke", "robot.dock.dwell_s=2.5", "calibration.grid=[{key:robot.dock.dwell_s,values:"
            "[0.0,5.0]}]", f"output_dir={tmp_path}"]
    result = CliRunner().invoke(app, args)  # refused as a search of other settings: nothing removed
    assert result.exit_code == 1 and "was made with other settings (n_points: 48 -> 2)" in result.output
    assert all((folder / name).is_file() for name in CALIBRATION_FILES)
    result = CliRunner().invoke(app, [*args, "overwrite=true"])
    assert result.exit_code == 0, result.output
    record = json.loads((folder / "search.json").read_text())
    assert record["configured"] == {"robot.dock.dwell_s": 2.5} and record["n_points"] == 2
    held = sorted(name for name in CALIBRATION_FILES if (folder / name).is_file())
    assert "search.csv" in held and "sensitivity.png" not in held
    assert all((folder / name).read_bytes() != b"earlier" for name in held)
    assert json.loads((folder / ".tavc.json").read_text())["files"] == held


def test_a_calibration_search_writes_into_its_output_dir_and_nowhere_beside_it(tmp_path, monkeypatch):
    """`tavc calibrate output_dir=X` writes X/calibration/world/: a file named as X is one line,
    with nothing written next to it."""
    (tmp_path / "notes.txt").write_text("mine")
    result = CliRunner().invoke(app, ["calibrate", "scale=smoke", f"output_dir={tmp_path / 'notes.txt'}",
                                      "calibration.grid=[{key:robot.dock.dwell_s,values:[0.0]}]"])
    assert result.exit_code == 1
    assert result.output.strip() == f"error: output_dir: {tmp_path / 'notes.txt'} is a file; name a folder"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["notes.txt"]
    # an experiment's folder, which the search once took to write beside: refused, naming the folder above it
    run = tmp_path / "runs" / "initial_distribution"
    run.mkdir(parents=True)
    (run / ".tavc.json").write_text('{"tavc": "run", "files": []}')
    result = CliRunner().invoke(app, ["calibrate", "scale=smoke", f"output_dir={run}",
                                      "calibration.grid=[{key:robot.dock.dwell_s,values:[0.0]}]"])
    assert result.exit_code == 1
    assert result.output.strip() == (f"error: output_dir: {run} is a tavc run's folder; the search goes into "
                                     f"{run / 'calibration' / 'world'}: name the folder that holds it "
                                     f"({run.parent}), or another")
    assert sorted(p.name for p in run.iterdir()) == [".tavc.json"]
    monkeypatch.chdir(run)  # the folder above it is named as it lies, not as `.`'s parent (`.`)
    result = CliRunner().invoke(app, ["calibrate", "scale=smoke", "output_dir=.",
                                      "calibration.grid=[{key:robot.dock.dwell_s,values:[0.0]}]"])
    assert result.exit_code == 1 and result.output.strip().endswith(f"name the folder that holds it "
                                                                     f"({run.resolve().parent}), or another")


def test_a_calibration_search_is_refused_before_its_grid_is_composed(tmp_path, monkeypatch):
    """Composing the grid's points takes the better part of a minute; a link where the search
    writes, a run's folder, a file where a folder goes, and `--save` over a world searched
    otherwise are each refused before a single point is composed."""
    def composed(point):
        raise AssertionError(f"grid point {point} composed before the refusal")

    monkeypatch.setattr(world_search, "point_overrides", composed)
    sibling = tmp_path / "sibling"
    sibling.mkdir()
    named = tmp_path / "named"
    (named / "calibration").mkdir(parents=True)
    (named / "calibration" / "world").symlink_to(sibling, target_is_directory=True)
    run = tmp_path / "run"
    run.mkdir()
    (run / ".tavc.json").write_text('{"tavc": "run", "files": []}')
    (tmp_path / "notes.txt").write_text("mine")
    (tmp_path / "filed" / "calibration").mkdir(parents=True)
    (tmp_path / "filed" / "calibration" / "world").write_text("mine")
    for args, words in [([f"output_dir={named}"], "is a symbolic link to"),
                        ([f"output_dir={run}"], "is a tavc run's folder"),
                        ([f"output_dir={tmp_path / 'notes.txt'}"], "notes.txt is a file; name a folder"),
                        ([f"output_dir={tmp_path / 'filed'}"], "calibration/world is a file; name a folder"),
                        (["--save", f"output_dir={tmp_path / 'fresh'}"], "was made with other settings")]:
        result = CliRunner().invoke(app, ["calibrate", "scale=smoke", *args])
        assert result.exit_code == 1 and len(result.output.strip().splitlines()) == 1, result.output
        assert result.output.startswith("error: ") and words in result.output, result.output
    assert not (tmp_path / "fresh").exists() and list(sibling.iterdir()) == []
