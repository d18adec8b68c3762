"""Reading a run's table into rows (tavc_cli.table_cells.table_rows): what the csv module reads,
whichever way it is read."""

import csv
import io
from pathlib import Path

import pytest
from hypothesis import example, given
from hypothesis import strategies as st

from tavc_cli.errors import TavcError
from tavc_cli.table_cells import table_rows

PATH = Path("run/robots.csv")


def _as_csv_reads_it(text: str):
    """The header and numbered rows as the csv module gives them, or its error: the reference."""
    reader = csv.reader(io.StringIO(text, newline=""), strict=True)
    try:
        return next(reader), [(reader.line_num, row) for row in reader]
    except csv.Error as exc:
        return f"line {reader.line_num}: {exc}"


@given(st.text(alphabet='ab1.-,"\r\n\0 ', max_size=60).map(lambda text: text + "\n"))
@example("a,b\n1,2\n3,\n")
@example("a\n\n1\n")  # a blank line: a row of no cells
@example('a,b\n"1,5",2\n')  # a quoted cell holding a comma
@example("a,b\r\n1,2\r\n")
@example("\n")
def test_any_text_is_read_as_the_csv_module_reads_it(text):
    expected = _as_csv_reads_it(text)
    if isinstance(expected, str):
        with pytest.raises(TavcError) as info:
            table_rows(PATH, text)
        assert str(info.value).startswith(f"{PATH}: cannot be read ({expected})")
    else:
        assert table_rows(PATH, text) == expected


def test_plain_lines_are_split_into_numbered_rows():
    assert table_rows(PATH, "trial,controller\n1,tavc\n2,\n") == (["trial", "controller"],
                                                                  [(2, ["1", "tavc"]), (3, ["2", ""])])
    assert table_rows(PATH, "a\n\n1\n") == (["a"], [(2, []), (3, ["1"])])  # a blank line has no cells


def test_a_cell_longer_than_the_csv_modules_limit_is_refused_naming_its_line():
    long = "9" * (csv.field_size_limit() + 1)
    with pytest.raises(TavcError, match=r"robots.csv: cannot be read \(line 3: field larger than field limit"):
        table_rows(PATH, f"a,b\n1,2\n3,{long}\n")
    assert table_rows(PATH, f"a\n{long[1:]}\n")[1] == [(2, [long[1:]])]  # at the limit: read
