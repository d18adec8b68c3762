"""How tavc reads the files of a folder it did not necessarily write: bounded.

A results folder may come from somebody else, and its `provenance.json`, `.tavc.json` and
`config.yaml` are read before anything in them is trusted. Each is read here: only a regular
file (a named pipe never blocks, a device such as ``/dev/zero`` is never read), at most a stated
size, JSON at most `MAX_DEPTH` levels deep, and YAML without aliases (tavc's own files never use
them; a document of nested aliases would expand without end), parsed by libyaml where PyYAML has
it (a results folder's hundreds of config.yaml files are what `tavc report` spends most on). A
refusal is one `TavcError` line naming the file and what to do, worded as `table_cells.damaged`
words its own.
"""

from __future__ import annotations

import errno
import io
import json
import math
import os
import re
import stat
import zipfile
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import yaml

from tavc_cli.errors import TavcError

if TYPE_CHECKING:
    import pandas as pd

try:  # libyaml's parser, where PyYAML was built with it (its wheels are)
    from yaml._yaml import CParser
except ImportError:  # pure-Python PyYAML: its own parser reads the same documents, slower
    CParser = None

REWRITE = "rerun its experiment to rewrite it"  # what to do about a damaged file of a run (as `run_checks`)

# tavc's largest provenance.json is 13 KB (results/breakdown: it lists every trial and table) and
# its largest .tavc.json 1.6 KB; 4 MiB is some 300 times the first, room for runs of many more trials
JSON_LIMIT = 4 << 20
# tavc's largest config.yaml is 3.7 KB (results/value_change); 1 MiB is some 280 times that
YAML_LIMIT = 1 << 20
# tavc's JSON and YAML nest at most 4 levels (provenance.json: trials, a trial, its fields);
# 64 is far more than any of its files needs, and far less than Python's recursion limit
MAX_DEPTH = 64
# tavc's config.yaml files use no YAML aliases (`to_yaml` writes none): any is refused
MAX_ALIASES = 0
# tavc's largest table is 3.4 MB (a nine-robot turn-taking prediction's task_times.csv); 256 MiB is
# some 75 times that: a table is read whole, only a regular file (`read_bounded`) and at most this
TABLE_LIMIT = 256 << 20
# tavc's largest trial record holds 43 MB of arrays (a trial of 40 times the chapter's duration);
# a record declaring more than 100 times that is not read: its arrays would be unpacked into
# memory, and a file of a few kilobytes can declare gigabytes
RECORD_LIMIT = 4 << 30


class _Refusal(Exception):
    """What the bounded YAML loader refuses, named by `load_yaml` with the file's path."""


def _refused(path: Path, why: str, advice: str) -> TavcError:
    return TavcError(f"{path}: cannot be read ({why}); {advice}")


def read_bounded(path: Path, limit: int, advice: str = REWRITE) -> bytes:
    """The bytes of the regular file `path`, refused (`TavcError`, naming `path` and `advice`,
    what to do) when it is larger than `limit` bytes or not a regular file. At most `limit`+1
    bytes are read, so a file growing meanwhile never fills memory, and the file is opened
    without blocking, so a named pipe never hangs the reader. A missing or unreadable file
    raises `OSError`, as `Path.read_bytes` does."""
    path = Path(path)
    fd = os.open(path, os.O_RDONLY | os.O_NONBLOCK | os.O_CLOEXEC)
    try:
        st = os.fstat(fd)
        if not stat.S_ISREG(st.st_mode):
            kind = ("a named pipe (FIFO)" if stat.S_ISFIFO(st.st_mode) else "a folder" if stat.S_ISDIR(st.st_mode)
                    else "a device" if stat.S_ISCHR(st.st_mode) or stat.S_ISBLK(st.st_mode) else "not a file")
            raise _refused(path, f"it is {kind}, not a file", advice)
        if st.st_size > limit:
            raise _refused(path, f"{st.st_size} bytes, more than the {limit} tavc reads of it", advice)
        chunks, left = [], limit + 1
        while left > 0:
            chunk = os.read(fd, min(left, 1 << 20))
            if not chunk:
                break
            chunks.append(chunk)
            left -= len(chunk)
    finally:
        os.close(fd)
    data = b"".join(chunks)
    if len(data) > limit:
        raise _refused(path, f"more than the {limit} bytes tavc reads of it", advice)
    return data


def read_text(path: Path, limit: int, advice: str = REWRITE) -> str:
    """`read_bounded`, decoded as UTF-8 (a `UnicodeDecodeError`, a `ValueError`, where it is not)."""
    return read_bounded(path, limit, advice).decode("utf-8")


_STRING = re.compile(r'"(?:[^"\\]|\\.)*"', re.S)
_NOT_BRACKET = re.compile(r"[^\[\]{}]+")


def json_depth(text: str) -> int:
    """How deep the arrays and objects of the JSON `text` nest (brackets inside strings left out)."""
    brackets = _NOT_BRACKET.sub("", _STRING.sub("", text))
    depth = deepest = 0
    for opening in brackets.translate(str.maketrans("[{]}", "(())")).split(")"):
        depth += len(opening)
        deepest = max(deepest, depth)
        depth -= 1
    return deepest


@dataclass(frozen=True)
class TableSpec:
    """What a reader takes from a table it reads whole (a study's, the model's): the `columns` it
    reads, which of them hold numbers (or nothing), which are read as text whatever they hold (a
    state such as ``3:3``), which are never empty (and, where they hold numbers, finite), which
    count something (whole numbers from 0, where there), which hold True, False or nothing, which
    together name a row once at most (`unique`), and whether it is written only with rows. A run's
    own tables are checked by `run_checks` against `analysis.table_schemas` instead."""

    columns: tuple[str, ...] = ()
    numbers: tuple[str, ...] = ()
    text: tuple[str, ...] = ()
    filled: tuple[str, ...] = ()
    counts: tuple[str, ...] = ()
    flags: tuple[str, ...] = ()
    unique: tuple[str, ...] = ()
    rows: bool = False

    def fault(self, table: pd.DataFrame) -> str:
        """What is wrong with `table` by this spec ("" where nothing)."""
        import pandas as pd  # deferred: most of what reads a folder's files reads no table

        missing = [c for c in self.columns if c not in table.columns]
        if missing:
            return f"no column {', '.join(missing)}"
        if self.rows and not len(table):
            return "no rows under its header"
        for column in (c for c in self.filled if c in table.columns):
            if table[column].isna().any():
                return f"an empty cell in column {column}"
        for column in (c for c in dict.fromkeys((*self.numbers, *self.counts)) if c in table.columns):
            if not (pd.api.types.is_numeric_dtype(table[column]) or table[column].isna().all()):
                return f"column {column} holds something other than numbers"
            if column in self.filled and not table[column].map(math.isfinite).all():  # a count, a factor
                return f"column {column} holds a number that is not finite"
            if column in self.counts and not table[column].dropna().map(_is_count).all():
                return f"column {column} holds something other than a count (0, 1, 2, ...)"
        for column in (c for c in self.flags if c in table.columns):
            if not set(table[column].dropna().astype(str)) <= {"True", "False"}:
                return f"column {column} holds something other than True or False"
        if self.unique and table.duplicated(subset=list(self.unique)).any():
            return f"two rows of the same {', '.join(self.unique)}"
        return ""


def _is_count(value: float) -> bool:
    """A whole number from 0 that a float holds exactly (below 2**53)."""
    return 0 <= value < 2**53 and float(value).is_integer()


def read_table(path: Path, spec: TableSpec = TableSpec(), advice: str = REWRITE,
               limit: int = TABLE_LIMIT) -> pd.DataFrame:
    """The CSV table `path` as a DataFrame, read by `read_bounded`, the columns `spec` names as text
    read as text. A table that cannot be read (not there, not a file, empty, not UTF-8 CSV) or that
    `spec` finds at fault is refused: one `TavcError` line naming the file, what is wrong and
    `advice`, what to do."""
    import pandas as pd  # deferred: most of what reads a folder's files reads no table

    try:
        data = read_bounded(path, limit, advice)
    except OSError as exc:  # gone, or a link that leads nowhere
        raise _refused(path, exc.strerror or type(exc).__name__, advice) from None
    if not data.strip():
        raise _refused(path, "empty", advice)
    try:
        table = pd.read_csv(io.BytesIO(data), dtype=dict.fromkeys(spec.text, str))
    except ValueError as exc:  # pandas' parser errors, text that is not UTF-8
        detail = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
        raise _refused(path, detail, advice) from None
    fault = spec.fault(table)
    if fault:
        raise _refused(path, fault, advice)
    return table


def load_json(path: Path, limit: int = JSON_LIMIT, advice: str = REWRITE) -> Any:
    """The JSON file `path`, read by `read_bounded`, refused when nested deeper than `MAX_DEPTH`.
    Malformed JSON raises `ValueError` (`json.JSONDecodeError`), as `json.loads` does."""
    text = read_text(path, limit, advice)
    if json_depth(text) > MAX_DEPTH:
        raise _refused(path, f"nested more than {MAX_DEPTH} levels deep", advice)
    try:
        return json.loads(text)
    except RecursionError:
        raise _refused(path, f"nested more than {MAX_DEPTH} levels deep", advice) from None


def _bounded_loader(base: type, max_aliases: float = MAX_ALIASES) -> type:
    """A subclass of the YAML loader `base` that refuses an alias (more than `max_aliases`) and
    nesting deeper than `MAX_DEPTH`, as it composes the document, before anything expands."""

    class Bounded(base):
        _aliases = 0
        _depth = 0

        def compose_node(self, parent, index):
            if self.check_event(yaml.AliasEvent):
                self._aliases += 1
                if self._aliases > max_aliases:
                    raise _Refusal(f"a YAML alias, *{self.peek_event().anchor}, on line "
                                   f"{self.peek_event().start_mark.line + 1}; tavc's files use none")
            self._depth += 1
            if self._depth > MAX_DEPTH:
                raise _Refusal(f"nested more than {MAX_DEPTH} levels deep")
            try:
                return super().compose_node(parent, index)
            finally:
                self._depth -= 1

    Bounded.__name__ = f"Bounded{base.__name__}"
    return Bounded


def _on_libyaml(base: type) -> type:
    """The YAML loader `base` (a subclass of `yaml.SafeLoader`) reading libyaml's events: the same
    documents, parsed about four times faster, composed by PyYAML's own composer (not libyaml's),
    so that `_bounded_loader`'s checks still see every node, and constructed by `base`'s own
    constructor and resolvers. `base` itself where PyYAML has no libyaml."""
    if CParser is None:
        return base

    class OnLibyaml(CParser, base):
        def __init__(self, stream):
            CParser.__init__(self, stream)
            yaml.composer.Composer.__init__(self)
            yaml.constructor.SafeConstructor.__init__(self)
            yaml.resolver.Resolver.__init__(self)

    for name in ("check_node", "get_node", "get_single_node"):  # PyYAML's composer, not libyaml's
        setattr(OnLibyaml, name, getattr(yaml.composer.Composer, name))
    OnLibyaml.__name__ = f"{base.__name__}OnLibyaml"
    return OnLibyaml


# a run's config.yaml is read this way; a results folder holds hundreds, which the report reads whole
_SAFE = _bounded_loader(_on_libyaml(yaml.SafeLoader))
# a user's config is counted this way: aliases allowed (`yaml_nodes` counts what they expand to), depth bounded
_ALIASED = _bounded_loader(_on_libyaml(yaml.SafeLoader), max_aliases=math.inf)


def load_yaml(path: Path, limit: int = YAML_LIMIT, advice: str = REWRITE, loader: type | None = None) -> Any:
    """The YAML file `path` as `yaml.safe_load` reads it (on libyaml's parser where there is one;
    or as `loader`, a subclass of `yaml.SafeLoader`, does), read by `read_bounded`; an alias, or
    nesting deeper than `MAX_DEPTH`, is refused in one line naming the file. Malformed YAML raises
    `yaml.YAMLError`, as `yaml.safe_load` does."""
    text = read_text(path, limit, advice)
    try:
        bounded = _SAFE if loader is None else _bounded_loader(_on_libyaml(loader))
        return yaml.load(text, Loader=bounded)  # noqa: S506 (a safe loader)
    except _Refusal as exc:
        raise _refused(path, str(exc), advice) from None
    except RecursionError:
        raise _refused(path, f"nested more than {MAX_DEPTH} levels deep", advice) from None
    except yaml.YAMLError as exc:
        if "maximum nesting depth" in str(exc):  # libyaml's own bound (deeper than MAX_DEPTH), met first
            raise _refused(path, f"nested more than {MAX_DEPTH} levels deep", advice) from None
        raise


def yaml_nodes(path: Path, limit: int = YAML_LIMIT, advice: str = REWRITE) -> int:
    """How many nodes the YAML file `path` (read by `read_bounded`) holds with its aliases expanded,
    as a loader that copies what an alias names builds them (OmegaConf does). Counted on the
    composed document, where an alias is the node it names, shared: a few lines of nested aliases
    that expand to billions of nodes are counted as fast as they are read. Refused in one line
    naming the file when nested deeper than `MAX_DEPTH` or when an alias names a node that holds
    it (expanding it never ends). Malformed YAML raises `yaml.YAMLError`, as `yaml.safe_load` does."""
    text = read_text(path, limit, advice)
    try:
        root = yaml.compose(text, Loader=_ALIASED)
    except _Refusal as exc:
        raise _refused(path, str(exc), advice) from None
    except RecursionError:
        raise _refused(path, f"nested more than {MAX_DEPTH} levels deep", advice) from None
    sizes: dict[int, int] = {}
    open_nodes: set[int] = set()  # the nodes whose children are being counted: the current one's ancestors
    stack = [] if root is None else [(root, False)]
    while stack:
        node, closing = stack.pop()
        children = [n for pair in node.value for n in pair] if isinstance(node, yaml.MappingNode) else \
            node.value if isinstance(node, yaml.SequenceNode) else []
        if closing:
            open_nodes.discard(id(node))
            sizes[id(node)] = 1 + sum(sizes[id(child)] for child in children)
        elif id(node) in open_nodes:
            raise _refused(path, f"the node on line {node.start_mark.line + 1} holds an alias of itself", advice)
        elif id(node) not in sizes:
            open_nodes.add(id(node))
            stack.append((node, True))
            stack.extend((child, False) for child in children)
    return 0 if root is None else sizes[id(root)]


def record_size(path: Path) -> int:
    """Bytes of arrays the trial record (a NumPy archive) at `path` declares, read from its
    directory without unpacking anything.

    Raises:
        OSError, zipfile.BadZipFile: The file is missing, not a regular file (a pipe, which a
            read would wait on for ever, a device), or no archive.
    """
    fd = os.open(path, os.O_RDONLY | os.O_NONBLOCK | os.O_CLOEXEC)  # a pipe never blocks the open
    with os.fdopen(fd, "rb") as fh:
        if not stat.S_ISREG(os.fstat(fh.fileno()).st_mode):
            raise OSError(errno.EINVAL, "not a regular file")
        with zipfile.ZipFile(fh) as archive:
            return sum(member.file_size for member in archive.infolist())
