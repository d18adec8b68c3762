"""The tables of studies the report reads as a whole (a ladder, the model's table, a comparison,
the surrogate's and the stay/switch studies'): read bounded (`readers.read_table`), and a damaged
one is one line naming the file and the command that rewrites it, never a traceback."""

import os

import pandas as pd
import pytest

from tavc_cli.errors import TavcError
from tavc_cli.readers import TableSpec, read_table
from tavc_cli.report.files import read_ladder
from tavc_cli.run_tables import model_rows


def _refusal(read, path) -> str:
    with pytest.raises(TavcError) as refused:
        read(path)
    return str(refused.value)


def test_a_table_is_read_whole_as_pandas_reads_it(tmp_path):
    path = tmp_path / "t.csv"
    path.write_text("state,mean\n3:3,1.5\n4:2,\n")
    table = read_table(path, TableSpec(columns=("state", "mean"), numbers=("mean",), text=("state",)))
    pd.testing.assert_frame_equal(table, pd.read_csv(path, dtype={"state": str}))
    assert list(table["state"]) == ["3:3", "4:2"] and table["mean"].isna().tolist() == [False, True]
    # a column of numbers left empty throughout is no text
    path.write_text("state,mean\n3:3,\n")
    assert read_table(path, TableSpec(numbers=("mean",)))["mean"].isna().all()


@pytest.mark.parametrize(("text", "why"), [
    (b"", "empty"),
    (b"\n\n", "empty"),
    (b'a,b,c\n1,"2\n', "Error tokenizing data. C error: EOF inside string starting at row 1"),
    (b"a,b,c\n\xff\xfe,1,True\n", "'utf-8' codec can't decode byte 0xff in position 0: invalid start byte"),
    (b"a,c\n1,True\n", "no column b"),
    (b"a,b,c\n1,many,True\n", "column b holds something other than numbers"),
    (b"a,b,c\n,2,True\n", "an empty cell in column a"),
    (b"a,b,c\ninf,2,True\n", "column a holds a number that is not finite"),
    (b"a,b,c\n1,2,maybe\n", "column c holds something other than True or False"),
])
def test_a_damaged_table_is_one_line_naming_it(tmp_path, text, why):
    spec = TableSpec(columns=("a", "b"), numbers=("a", "b"), filled=("a",), flags=("c",))
    path = tmp_path / "t.csv"
    path.write_bytes(text)
    assert _refusal(lambda p: read_table(p, spec, "do it again"), path) == \
        f"{path}: cannot be read ({why}); do it again"
    # what the spec allows: empty numbers and flags, True and False
    path.write_text("a,b,c\n1,,\n2,3,True\n3,,False\n")
    assert list(read_table(path, spec)["a"]) == [1, 2, 3]


def test_a_table_too_large_or_not_a_file_is_never_read(tmp_path):
    path = tmp_path / "t.csv"
    path.write_text("a\n" + "1\n" * 100)
    assert _refusal(lambda p: read_table(p, limit=100), path) == \
        f"{path}: cannot be read (202 bytes, more than the 100 tavc reads of it); rerun its experiment to rewrite it"
    fifo = tmp_path / "fifo.csv"
    os.mkfifo(fifo)
    assert "it is a named pipe (FIFO), not a file" in _refusal(read_table, fifo)  # and never blocks
    assert _refusal(read_table, tmp_path) == \
        f"{tmp_path}: cannot be read (it is a folder, not a file); rerun its experiment to rewrite it"
    (tmp_path / "gone.csv").symlink_to(tmp_path / "nowhere.csv")
    assert _refusal(read_table, tmp_path / "gone.csv") == \
        f"{tmp_path / 'gone.csv'}: cannot be read (No such file or directory); rerun its experiment to rewrite it"


def test_a_damaged_ladder_names_the_command_that_rewrites_it(tmp_path):
    path = tmp_path / "ladder.csv"
    path.write_text("factor,duration_s,quantity,mean,std,n_trials\n1,18000,pct_3:3,30,10,20\n")
    assert _refusal(read_ladder, path) == \
        f"{path}: cannot be read (no column controller); run its `tavc ladder` again to rewrite it"
    path.write_text("factor,duration_s,controller,quantity,mean,std,n_trials\nx1,18000,tavc,pct_3:3,30,10,20\n")
    assert "(column factor holds something other than numbers)" in _refusal(read_ladder, path)
    path.write_text("factor,duration_s,controller,quantity,mean,std,n_trials\n")
    assert "(no rows under its header)" in _refusal(read_ladder, path)


def test_a_prediction_without_what_the_report_reads_of_it_is_one_line(tmp_path):
    import json

    from tavc_cli.report.files import read_prediction

    good = {"regime": "turn-taking", "robots_high": 2.5, "modal_state": "3:2", "modal_share_pct": 45.0,
            "modal_from": "alternators", "learners_run": "learners", "alternators_run": None}
    path = tmp_path / "turn_taking.json"
    path.write_text(json.dumps(good))
    assert read_prediction(path) == good
    for change in ({"modal_state": None}, {"robots_high": "2.5"}, {"modal_share_pct": None}, {"learners_run": 3}):
        path.write_text(json.dumps({**good, **change}))
        assert _refusal(read_prediction, path) == (
            f"{path}: cannot be read (not a prediction: a regime and modal state, robots_high and modal_share_pct); "
            "run its `tavc model --turn-taking` again to rewrite it")
    path.write_text("[1]")
    assert "(not a prediction" in _refusal(read_prediction, path)


def test_a_damaged_model_table_names_the_command_that_rewrites_it(tmp_path):
    path = tmp_path / "model.csv"
    header = "split,state,circuit,c_per_s,task_time_s\n"
    path.write_text(header + "1:0,1:0,0,0.0123,81.4\n1:0,1:0,1,0,\n")
    assert list(model_rows(path)["split"]) == ["1:0", "1:0"]
    once = "a split without a row for each of its circuits, once"
    for rows, why in (("1:0,1:0,,0.01,81\n", "an empty cell in column circuit"),
                      ("1:0,1:0,-1,0.01,81\n", "column circuit holds something other than a count (0, 1, 2, ...)"),
                      ("1:0,1:0,30,0.01,81\n", once), ("1:0,1:0,0,0.01,81\n1:0,1:0,0,0.01,81\n", once),
                      ("1:0,1:0,0,0.01,81\n1:0,1:0,1,0,\n1:0:0,1:0:0,0,0.01,81\n", "splits over different numbers of "
                                                                                 "circuits"),
                      ("one,1:0,0,0.01,81\n", "a split that is not one: one"),
                      ("1:0,1:0,0,fast,81\n", "column c_per_s holds something other than numbers")):
        path.write_text(header + rows)
        assert _refusal(model_rows, path) == f"{path}: cannot be read ({why}); run `tavc model` again to rewrite it"
    # with its team: every split of two robots over two circuits, 2:0, 1:1 and 0:2 (3 = C(3, 1))
    path.write_text(header + "".join(f"{s},{s},{c},0.01,81\n" for s in ("2:0", "1:1", "0:2") for c in (0, 1)))
    assert len(model_rows(path, 2)) == 6
    path.write_text(header + "".join(f"{s},{s},{c},0.01,81\n" for s in ("2:0", "1:1") for c in (0, 1)))
    assert "(not every split of its team of 2)" in _refusal(lambda p: model_rows(p, 2), path)


def test_a_model_without_what_the_report_reads_of_it_is_one_line(tmp_path):
    import json

    from tavc_cli.report.files import check_model

    good = {"n_robots": 1, "predicted_state": "1:0", "measurement": {"trials_per_split": 12},
            "by_team_size": {"1": {"predicted_state": "1:0"}},
            "world": {"time_budget": [{"split": "1:0", "circuit": 0, "task_time_s": 90.0}]}}
    path = tmp_path / "model" / "model.json"
    path.parent.mkdir()
    path.write_text(json.dumps(good))
    (path.parent / "model.csv").write_text("split,state,circuit,c_per_s,task_time_s\n1:0,1:0,0,0.01,81\n1:0,1:0,1,0,\n"
                                           "0:1,0:1,0,0,\n0:1,0:1,1,0.01,81\n")
    check_model(tmp_path)
    team = "no team size of 1 to 1,000 robots and prediction, n_robots and predicted_state"
    for change, why in (({"n_robots": "six"}, team), ({"n_robots": float("nan")}, team), ({"n_robots": 100_000}, team),
                        ({"measurement": {}}, "no record of its measurement, trials_per_split"),
                        ({"by_team_size": {"five": {"predicted_state": "3:2"}}},
                         "by_team_size is not a prediction for each team size"),
                        ({"by_team_size": {"\u00b2": {"predicted_state": "3:2"}}},
                         "by_team_size is not a prediction for each team size"),
                        ({"world": {"time_budget": [{"split": "3:3"}]}},
                         "world.time_budget is not a task time for each split and circuit")):
        path.write_text(json.dumps({**good, **change}))
        assert _refusal(check_model, tmp_path) == \
            f"{path}: cannot be read ({why}); run `tavc model` again to rewrite it"
    path.write_text("[1, 2]")
    assert "(not a JSON object)" in _refusal(check_model, tmp_path)
    path.write_text(json.dumps({**good, "n_robots": 2, "by_team_size": {}}))  # a team its table has no splits of
    assert _refusal(check_model, tmp_path) == (f"{path.parent / 'model.csv'}: cannot be read (not every split of its "
                                               "team of 2); run `tavc model` again to rewrite it")


@pytest.mark.parametrize(("where", "text", "why", "advice"), [
    ("compare/paper/compare.csv", "experiment,metric\nbreakdown,score_per_s\n", "no column controller, time_factor, "
     "n_trials, mean, std, median, p_vs_tavc, p_vs_random, above_tavc, above_random", "run `tavc compare` again"),
    ("stay_switch/stay_switch.csv", "reading,high_stayers,low_stayers,alternators,ratio_low,threshold_low,"
     "stay_pays_low,stay_pays_low_source\narrival=dock,1,1,,1.1,1.05,True,False\n", "an empty cell in column "
     "alternators", "run its `tavc stay-switch` again"),
    ("stay_switch/stay_switch.json", '{"readings": []}', "its readings are not each reading's settings",
     "run its `tavc stay-switch` again"),
    ("surrogate/comparison.csv", None, "it is a folder, not a file", "run `tavc surrogate --study` again"),
])
def test_the_report_refuses_a_damaged_study_before_it_writes_anything(finished_run, tmp_path, where, text, why,
                                                                     advice):
    """Every study the report reads as a whole is checked with the runs, before the first write."""
    import shutil

    from typer.testing import CliRunner

    from tavc_cli.cli import app
    from tests.helpers import SMOKE_BREAKDOWN

    results = tmp_path / "results"
    shutil.copytree(finished_run(*SMOKE_BREAKDOWN, name="breakdown"), results / "breakdown")
    path = results / where
    path.parent.mkdir(parents=True)
    if where.startswith("stay_switch/") and not where.endswith(".csv"):  # a record beside a table that reads
        (path.parent / "stay_switch.csv").write_text("reading,high_stayers,low_stayers,alternators,ratio_low,"
                                                     "threshold_low,stay_pays_low,stay_pays_low_source\n")
    if text is None:
        path.mkdir()
    else:
        path.write_text(text)
    before = {p: p.read_bytes() for p in results.rglob("*") if p.is_file()}
    result = CliRunner().invoke(app, ["report", str(results)])
    assert result.exit_code == 1
    assert result.output.strip() == f"error: {path}: cannot be read ({why}); {advice} to rewrite it"
    assert {p: p.read_bytes() for p in results.rglob("*") if p.is_file()} == before


def test_a_reading_never_leads_the_report_out_of_the_results_folder(tmp_path):
    from tavc_cli.report.files import read_stay_switch

    (tmp_path / "stay_switch.csv").write_text("reading,high_stayers,low_stayers,alternators,ratio_low,threshold_low,"
                                              "stay_pays_low,stay_pays_low_source\n")
    (tmp_path / "stay_switch_model.csv").write_text("reading,regime,basin,robots_high\n"
                                                    "arrival=../../elsewhere,mixed,1,2\n")
    assert _refusal(read_stay_switch, tmp_path) == (
        f"{tmp_path / 'stay_switch_model.csv'}: cannot be read (a reading whose runs' folder leads elsewhere: "
        "../../elsewhere); run its `tavc stay-switch` again to rewrite it")
    (tmp_path / "stay_switch_model.csv").write_text("reading,regime,basin,robots_high\narrival=dock,mixed,1,2\n")
    assert read_stay_switch(tmp_path)[1]["reading"].tolist() == ["arrival=dock"]


def test_tables_repeating_a_row_or_miscounting_are_one_line(tmp_path):
    from tavc_cli.report.compare import compare_tables

    folder = tmp_path / "compare" / "paper"
    folder.mkdir(parents=True)
    row = "breakdown,score_per_s,tavc,1,8,1.0,0.1,1.0,,0.01,,0.9\n"
    header = ("experiment,metric,controller,time_factor,n_trials,mean,std,median,p_vs_tavc,p_vs_random,above_tavc,"
              "above_random\n")
    (folder / "compare.csv").write_text(header + row + row)
    assert "(two rows of the same experiment, metric, controller)" in _refusal(compare_tables, tmp_path)
    (folder / "compare.csv").write_text(header + row.replace(",8,", ",2.5,"))
    assert "(column n_trials holds something other than a count (0, 1, 2, ...))" in _refusal(compare_tables, tmp_path)
    (folder / "compare.csv").write_text(header + row.replace("tavc", "7"))  # a controller named by digits is text
    assert compare_tables(tmp_path)[folder]["controller"].tolist() == ["7"]
