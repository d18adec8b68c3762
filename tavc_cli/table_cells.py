"""A run's table read into rows (`table_rows`), then checked cell by cell against its schema
(`table_schemas.TABLES`): every column the schema names there, numbers where it wants numbers
(`is_number`), no empty cell in its keys, only its choices where it limits a column, no row
repeated in its `unique` columns, and a Q-table's entries (`q_<state>_<action>`) for every state
and action. Each column is checked in one pass where all is well, and row by row only to name the
first line that is not (`run_checks.check_table` runs it, then what needs the run's facts).
`damaged` is the one line for a run's file that cannot be trusted."""

from __future__ import annotations

import csv
import io
import re
from collections import deque
from itertools import product
from pathlib import Path

from tavc_cli.analysis.table_schemas import TableSchema
from tavc_cli.errors import TavcError
from tavc_cli.readers import REWRITE


def damaged(path: Path, what: str) -> TavcError:
    """The one-line error for a file of a run that cannot be trusted."""
    return TavcError(f"{path}: {what}; {REWRITE}")


def unreadable(exc: Exception) -> str:
    """The first line of a parser's error, or its type where it says nothing: what a refusal quotes."""
    text = str(exc).strip()
    return text.splitlines()[0] if text else type(exc).__name__


def table_rows(path: Path, text: str) -> tuple[list[str], list[tuple[int, list[str]]]]:
    """The header of a table's `text` (whole: it ends with a newline) and its rows, each with the
    number of its line, as the csv module reads them. Text the module would read as plain lines of
    comma-separated cells (no quote, carriage return, NUL or blank line, no line longer than the
    module's limit for a cell) is split on newlines and commas, alike at a fraction of the cost; any
    other is read by the module, which refuses what it cannot read in one line naming the line."""
    lines = text[:-1].split("\n")
    if not any(c in text for c in '"\r\0') and "" not in lines and max(map(len, lines)) <= csv.field_size_limit():
        return lines[0].split(","), [(line, cells.split(",")) for line, cells in enumerate(lines[1:], start=2)]
    reader = csv.reader(io.StringIO(text, newline=""), strict=True)
    try:
        header = next(reader)
        return header, [(reader.line_num, row) for row in reader]
    except csv.Error as exc:
        raise damaged(path, f"cannot be read (line {reader.line_num}: {exc})") from None


def check_cells(path: Path, schema: TableSchema, header: list[str], rows: list) -> None:
    """The table at `path` (its `header`, and its `rows` as (line, fields)) against `schema`: one
    line naming the first column missing, or the first line with a cell that is not what its
    column wants (the module's docstring)."""
    missing = [c for c in schema.columns if c not in header]
    if missing:
        raise damaged(path, f"no column {missing[0]!r}")
    entries = {(int(m[1]), int(m[2])) for m in map(_Q_ENTRY.fullmatch, header) if m}
    if entries:  # a Q-table's columns: every state's every action, as many as its largest say
        states, actions = max(s for s, _ in entries) + 1, max(a for _, a in entries) + 1
        lacking = sorted(set(product(range(states), range(actions))) - entries)
        if lacking:
            raise damaged(path, f"no column 'q_{lacking[0][0]}_{lacking[0][1]}' (a Q-table's entry)")
    numbers = [c for c in header if (c in schema.columns and c not in schema.text) or c in schema.optional
               or c.startswith(schema.prefixes)]
    at = {c: k for k, c in enumerate(header)}
    keys = [c for c in schema.keys if c in at]
    columns = list(zip(*(row for _, row in rows), strict=True)) if rows else []
    if not _all_fine(columns, [at[c] for c in keys], [at[c] for c in numbers],
                     {at[c]: allowed for c, allowed in schema.choices.items()}):
        _first_wrong_cell(path, schema, rows, at, keys, numbers)
    _check_unique(path, [at[c] for c in schema.unique], columns, rows)


def _check_unique(path: Path, unique: list[int], columns: list, rows: list) -> None:
    """No two rows the same in the columns at `unique` (a row repeated, say), which a reader takes
    for one: checked at once, and row by row only to name the first line that repeats one."""
    if not unique or len(set(zip(*(columns[k] for k in unique), strict=True))) == len(rows):
        return
    seen: set[tuple] = set()
    for line, row in rows:
        key = tuple(row[k] for k in unique)
        if key in seen:
            raise damaged(path, f"line {line}: a second row for {', '.join(key)}")
        seen.add(key)


def _all_fine(columns: list, keys: list[int], numbers: list[int], choices: dict[int, frozenset]) -> bool:
    """Whether every cell of the `columns` at `keys` is filled, every one at `numbers` empty or a
    number, and every one at `choices` one of its choices: column by column, each column's cells
    checked in one pass (`_first_wrong_cell` finds the first line that is not, in line order)."""
    try:
        for k in numbers:
            deque(map(float, filter(None, columns[k])), maxlen=0)  # a ValueError where one is no number
    except ValueError:
        return False
    if any(_LONG_WHOLE.search("\n".join(columns[k])) for k in numbers):
        return False  # a whole number that may be too long for the tables' integers
    return all("" not in columns[k] for k in keys) and all(set(columns[k]) <= allowed
                                                          for k, allowed in choices.items())


def _first_wrong_cell(path: Path, schema: TableSchema, rows: list, at: dict[str, int], keys: list[str],
                      numbers: list[str]) -> None:
    """One line naming the first line, in the table's order, with a key left empty, a number that
    is none or a cell that is none of its column's choices."""
    for line, row in rows:
        for c in keys:
            if row[at[c]] == "":
                raise damaged(path, f"line {line}: no {c}")
        for c in numbers:
            if row[at[c]] != "" and not is_number(row[at[c]]):
                raise damaged(path, f"line {line}: {c} {_shown(row[at[c]])} is not a number" +
                              (" a table holds (too large a whole number)" if _is_whole(row[at[c]]) else ""))
        for c, allowed in schema.choices.items():
            if row[at[c]] not in allowed:
                raise damaged(path, f"line {line}: {c} {_shown(row[at[c]])} is none of {', '.join(sorted(allowed))}")


def _shown(cell: str, most: int = 40) -> str:
    """A cell as a message quotes it: its first `most` characters, where it is longer."""
    return repr(cell) if len(cell) <= most else repr(cell[:most]) + f"... ({len(cell):,} characters)"


_Q_ENTRY = re.compile(r"q_(\d+)_(\d+)")  # a Q-table's entry: its state, its action
_LONG_WHOLE = re.compile(r"^[ \t]*[+-]?\d{19}", re.M)  # a cell that starts with 19 digits may not fit 64 bits


def is_number(cell: str) -> bool:
    """Whether `cell` is a number a table's reader takes: what `float` reads, and a whole number
    only within 64-bit integers (a longer one is read as a Python integer no array holds)."""
    try:
        float(cell)
    except ValueError:
        return False
    return not _is_whole(cell) or -(2 ** 63) <= int(cell) < 2 ** 63


def _is_whole(cell: str) -> bool:
    digits = cell.strip().removeprefix("-").removeprefix("+")
    return digits.isascii() and digits.isdigit()
