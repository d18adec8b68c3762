"""The tables of studies the report reads as a whole (a ladder, the model's table, a comparison,
the surrogate's and the stay/switch studies'): read bounded (`readers.read_table`), and a damaged
one is one line naming the file and the command that rewrites it, never a traceback."""

import os

import pandas as pd
import pytest

from tavc_cli.errors import TavcError
from tavc_cli.readers import read_table
from tavc_cli.report.files import read_ladder
from tavc_cli.run_tables import model_rows


def _refusal(read, path) -> str:
    with pytest.raises(TavcError) as refused:
        read(path)
    return str(refused.value)


def test_a_table_is_read_whole_as_pandas_reads_it(tmp_path):
    path = tmp_path / "t.csv"
    path.write_text("state,mean\n3:3,1.5\n4:2,\n")
    table = read_table(path, ("state", "mean"), ("mean",), dtype={"state": str})
    pd.testing.assert_frame_equal(table, pd.read_csv(path, dtype={"state": str}))
    assert list(table["state"]) == ["3:3", "4:2"] and table["mean"].isna().tolist() == [False, True]
    # a column of numbers left empty throughout is no text
    path.write_text("state,mean\n3:3,\n")
    assert read_table(path, numbers=("mean",))["mean"].isna().all()


@pytest.mark.parametrize(("text", "why"), [
    (b"", "No columns to parse from file"),
    (b'a,b\n1,"2\n', "Error tokenizing data. C error: EOF inside string starting at row 1"),
    (b"a,b\n\xff\xfe,1\n", "'utf-8' codec can't decode byte 0xff in position 0: invalid start byte"),
    (b"a,c\n1,2\n", "no column b"),
    (b"a,b\n1,many\n", "column b holds something other than numbers"),
])
def test_a_damaged_table_is_one_line_naming_it(tmp_path, text, why):
    path = tmp_path / "t.csv"
    path.write_bytes(text)
    assert _refusal(lambda p: read_table(p, ("a", "b"), ("b",), "do it again"), path) == \
        f"{path}: cannot be read ({why}); do it again"


def test_a_table_too_large_or_not_a_file_is_never_read(tmp_path):
    path = tmp_path / "t.csv"
    path.write_text("a\n" + "1\n" * 100)
    assert _refusal(lambda p: read_table(p, limit=100), path) == \
        f"{path}: cannot be read (202 bytes, more than the 100 tavc reads of it); rerun its experiment to rewrite it"
    fifo = tmp_path / "fifo.csv"
    os.mkfifo(fifo)
    assert "it is a named pipe (FIFO), not a file" in _refusal(read_table, fifo)  # and never blocks


def test_a_damaged_ladder_names_the_command_that_rewrites_it(tmp_path):
    path = tmp_path / "ladder.csv"
    path.write_text("factor,duration_s,quantity,mean,std,n_trials\n1,18000,pct_3:3,30,10,20\n")
    assert _refusal(read_ladder, path) == \
        f"{path}: cannot be read (no column controller); run its `tavc ladder` again to rewrite it"
    path.write_text("factor,duration_s,controller,quantity,mean,std,n_trials\nx1,18000,tavc,pct_3:3,30,10,20\n")
    assert "(column factor holds something other than numbers)" in _refusal(read_ladder, path)


def test_a_damaged_model_table_names_the_command_that_rewrites_it(tmp_path):
    path = tmp_path / "model.csv"
    header = "split,state,circuit,c_per_s,task_time_s\n"
    path.write_text(header + "1:0,1:0,0,0.0123,81.4\n1:0,1:0,1,0,\n")
    assert list(model_rows(path)["split"]) == ["1:0", "1:0"]
    for rows, why in (("1:0,1:0,,0.01,81\n", "a row without its circuit"),
                      ("one,1:0,0,0.01,81\n", "a split that is not one: one"),
                      ("1:0,1:0,0,fast,81\n", "column c_per_s holds something other than numbers")):
        path.write_text(header + rows)
        assert _refusal(model_rows, path) == f"{path}: cannot be read ({why}); run `tavc model` again to rewrite it"


def test_a_model_file_without_what_the_report_reads_of_it_is_one_line(tmp_path):
    import json

    from tavc_cli.report.files import check_model

    good = {"n_robots": 6, "predicted_state": "3:3", "measurement": {"trials_per_split": 12},
            "by_team_size": {"5": {"predicted_state": "3:2"}},
            "world": {"time_budget": [{"split": "3:3", "circuit": 0, "task_time_s": 90.0}]}}
    path = tmp_path / "model.json"
    path.write_text(json.dumps(good))
    check_model(path)
    for change, why in (({"n_robots": "six"}, "no team size and prediction, n_robots and predicted_state"),
                        ({"measurement": None}, "no record of its measurement"),
                        ({"by_team_size": {"five": {"predicted_state": "3:2"}}},
                         "by_team_size is not a prediction for each team size"),
                        ({"world": {"time_budget": [{"split": "3:3"}]}},
                         "world.time_budget is not a task time for each split and circuit")):
        path.write_text(json.dumps({**good, **change}))
        assert _refusal(check_model, path) == f"{path}: cannot be read ({why}); run `tavc model` again to rewrite it"
    path.write_text("[1, 2]")
    assert "(not a JSON object)" in _refusal(check_model, path)
