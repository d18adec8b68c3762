"""The check a reader runs on a table before trusting it: `tavc report` on every table of every
run it reads, `api.Results.table` on the one it returns (the tables' columns: `table_schemas`).

A table tavc wrote is complete text: a header, one line per row, a newline at the end (a
file cut short lacks it), as many fields in every row as in the header. Beyond that, each
table has its columns (`TABLES`), some of them numbers, some never empty; its `trial`
values are trials the run's `provenance.json` lists (for the row's controller), its
`state` values states the experiment's team can be in (robots per circuit, or per speed
group on the high-value circuit: `analysis.states`), and where `provenance.json` recorded
each table's SHA-256 (its ``tables`` map, `io.file_digest`) the file must still have it.
That digest is the only check that catches every change; the others catch damage that
breaks a table's shape, which is what a file cut short or a flipped byte mostly does, in
runs written before the digests were.

A table that fails raises `TavcError("<path>: <what is wrong>; rerun its experiment to
rewrite it")`.

A trial record a reader takes from a run (`read_trial`: `api.Results.records`, the report's
count of deliveries) must be one `provenance.json` lists, there, readable, and this run's own:
its ``meta["key"]`` (a digest of everything that fixes the trial's outcome) is the key
provenance.json lists for that controller and trial, so a record copied in from another
configuration or seed is refused, naming the file.
"""

from __future__ import annotations

import math
import os
import re
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from functools import cached_property
from itertools import product
from pathlib import Path

from tavc_cli.analysis.table_schemas import TABLE_NAMES, TABLES, TableSchema
from tavc_cli.errors import TavcError
from tavc_cli.experiments.plan import PLAN_FILE, RunPlan, read_plan
from tavc_cli.experiments.records import TrialRecord
from tavc_cli.experiments.spec import code_digest
from tavc_cli.io import file_digest, plain_name
from tavc_cli.notation import column_state, counts_of, join_counts, state_counts
from tavc_cli.readers import RECORD_LIMIT, TABLE_LIMIT, YAML_LIMIT, read_bounded, record_size
from tavc_cli.run_provenance import check_planned, made_by_of, read_provenance, unfinished_rewrites
from tavc_cli.settings import TavcConfig, from_yaml
from tavc_cli.surrogate.digest import engine_code, surrogate_code_digest
from tavc_cli.table_cells import check_cells, damaged, table_rows, unreadable

SECTIONS = ("arena", "robot", "team", "learner", "scale", "executor", "paper", "tasks", "events", "sim", "analysis",
            "model", "calibration")


@dataclass(frozen=True)
class RunFacts:
    """What a run's tables are checked against: the trials its `provenance.json` lists
    ((controller, trial) pairs; None where it lists none, or there is none), the digests it
    recorded (None without), and the states its team can be in: `scheme` (`analysis.state`), the robots per
    `groups` fastest first (one group for the circuits scheme), the circuits, and the
    fewest robots working at once (after every breakdown)."""

    folder: Path
    digests: dict[str, str] | None
    scheme: str
    groups: tuple[int, ...]
    n_circuits: int
    fewest: int
    # a file whose rewrite by tavc was stopped before its end -> its digest before (None: it was not there)
    replaced: dict[str, str | None] = field(default_factory=dict)
    cfg: TavcConfig | None = None  # the run's settings, its plan.json read against them
    # provenance.json's trials in its order, (controller, trial, key or None), and the digest of the
    # simulator's code that ran them (None where it records none)
    listed: tuple[tuple[str, int, str | None], ...] = ()
    recorded_code: str | None = None
    # what computed them, as provenance.json records it (`TrialSpec.engine`; None where it does not)
    engine: str | None = None
    # the code of the learners from outside tavc that ran them, by target ({} where none is recorded)
    learner_code: dict = field(default_factory=dict)

    @classmethod
    def of(cls, cfg: TavcConfig, provenance: dict | None, folder: Path) -> RunFacts:
        """The facts of the run in `folder` from its config and its `provenance.json` (None where it
        has none)."""
        # deferred: loads pandas
        from tavc_cli.analysis.states import group_order

        members = cfg.team.members or []
        names = [str(m.group) for m in members] or ["all"] * int(cfg.team.n_robots)
        speeds = [float(m.speed_mps) for m in members] or [float(cfg.robot.speed_mps)] * len(names)
        scheme = str(cfg.analysis.state)
        sizes = tuple(names.count(g) for g in group_order(names, speeds)) if scheme == "groups" else (len(names),)
        digests = None
        replaced, listed = {}, ()
        if provenance is not None:
            listed = tuple((str(t["controller"]), int(t["trial"]), t.get("key")) for t in provenance["trials"])
            digests = provenance.get("tables")
            replaced = unfinished_rewrites(provenance)
        made = made_by_of(provenance)
        return cls(folder, digests, scheme, sizes, len(cfg.arena.circuits),
                   len(names) - len(cfg.events.breakdowns), replaced, cfg, listed,
                   made["code_digest"], made["engine"], made["learner_code"])

    @cached_property
    def trials(self) -> frozenset[tuple[str, int]] | None:
        """The (controller, trial) pairs provenance.json lists; None where it lists none (a folder
        made by hand gives none to check against) or there is none."""
        return frozenset((c, j) for c, j, _ in self.listed) or None

    @property
    def other_code(self) -> str | None:
        """The digest of tavc's code that computed the run's trials where it is not this tavc's: the
        simulator's (provenance.json's ``code_digest``), or, for a run on the surrogate, the
        surrogate's (named in its ``engine``, "<digest> (the surrogate's)"); None where both are
        this tavc's, or where none is recorded."""
        if self.recorded_code not in (None, code_digest()):
            return self.recorded_code
        surrogate = engine_code(self.engine or "")
        return f"{surrogate} (the surrogate's)" if surrogate not in (None, surrogate_code_digest()) else None

    @property
    def made_by(self) -> dict:
        """What computed the run's trials, as `provenance.json` records it (`runner.made_by`)."""
        return {"code_digest": self.recorded_code, "engine": self.engine, "learner_code": self.learner_code}

    def valid_state(self, label: str) -> bool:
        """Whether `label` is a state of this team: robots per circuit (high-value circuit
        first) adding up to the robots working, or robots of each group on the high-value
        circuit, none more than the group has."""
        counts = state_counts(label)
        if counts is None:
            return False
        if self.scheme == "groups":
            return len(counts) == len(self.groups) and all(c <= g for c, g in zip(counts, self.groups, strict=True))
        return len(counts) == self.n_circuits and self.fewest <= sum(counts) <= sum(self.groups)

    def team_states(self, theory: set[str]) -> set[str]:
        """Every state of the team at the end of the run, as `analysis.states.all_states`
        lists them (the theory rows list them all): the configured team where no robot
        breaks down, else the team the theory rows are for (for circuits, as many robots
        as the first has; for groups, each group's largest count among them)."""
        counts = [counts_of(s) for s in theory]
        whole = self.fewest == sum(self.groups)
        if self.scheme == "groups":
            sizes = self.groups if whole else [max(c[k] for c in counts) for k in range(len(self.groups))]
            return {join_counts(c) for c in product(*(range(g + 1) for g in sizes))}
        n = sum(self.groups) if whole else sum(counts[0])
        return {join_counts(c) for c in product(range(n + 1), repeat=self.n_circuits) if sum(c) == n}


def this_code() -> str:
    """This tavc's code, as `RunFacts.other_code` is set against it: its simulator's digest and its
    surrogate's."""
    return f"simulator {code_digest()}, surrogate {surrogate_code_digest()}"


def read_config(path: Path, digests: dict[str, str] | None = None,
                load: Callable[[Path], TavcConfig] = from_yaml) -> TavcConfig:
    """A run's `config.yaml` read by `load`, checked: its digest where `provenance.json`
    recorded one, then whole (a newline at its end, every section of the settings there: a
    file cut short loses its last, `calibration`), of the settings' types, with the durations
    and the team's members a finished run resolved. A cut inside the last section's last list
    leaves a file that passes without a digest; the report reads nothing there. Whether its
    settings are those its trials ran on is `run_provenance.check_planned`'s to say."""
    path = Path(path)
    try:
        raw = read_bounded(path, YAML_LIMIT)
        cfg = load(path)
    except TavcError:
        raise  # a refusal naming the file already
    except Exception as exc:  # any parser's or the schema's error: the file is damaged, whatever the library
        raise damaged(path, f"cannot be read ({unreadable(exc)})") from None
    if not raw.endswith(b"\n"):
        raise damaged(path, "cut short (no newline at its end)")
    keys = set(re.findall(rb"^([A-Za-z_]\w*):", raw, re.M))  # the top level of a block mapping, as to_yaml writes
    missing = [s for s in SECTIONS if s.encode() not in keys]
    if missing:
        raise damaged(path, f"cut short (no {missing[0]!r} section)")
    if cfg.duration_s is None or cfg.convergence_s is None:
        raise damaged(path, "cut short or edited (no duration_s or convergence_s, which a run always writes)")
    named = next((k for k, v in (("experiment_name", cfg.experiment_name), ("scale.name", cfg.scale.name))
                  if not plain_name(str(v))), None)  # a name the report gives its files: never a path
    if named is not None:
        raise damaged(path, f"edited after its run ({named} is not a plain name, which a run's always is)")
    if cfg.team.n_robots != len(cfg.team.members):
        raise damaged(path, f"edited after its run (team.n_robots is {cfg.team.n_robots}, and it lists "
                      f"{len(cfg.team.members)} members, which a run resolves them into)")
    _check_digest(path, digests)
    return cfg


def run_facts(folder: Path, load: Callable[[Path], TavcConfig] = from_yaml) -> RunFacts:
    """The facts a run folder's tables are checked against, its `provenance.json` and
    `config.yaml` (read by `load`) checked on the way; without a provenance.json, no trials
    or digests to check against."""
    folder = Path(folder)
    prov = read_provenance(folder / "provenance.json") if (folder / "provenance.json").is_file() else None
    cfg = read_config(folder / "config.yaml", prov.get("tables") if prov is not None else None, load)
    return RunFacts.of(cfg, prov, folder)


def check_run(folder: Path, load: Callable[[Path], TavcConfig] = from_yaml) -> RunFacts:
    """Check a run folder as a reader will take it: `provenance.json`, `config.yaml` (read by
    `load`), every table it holds of those a run writes, and every table its provenance
    lists being there."""
    facts = checked_facts(folder, load)
    for name in TABLE_NAMES:
        if (facts.folder / f"{name}.csv").is_file():
            check_table(facts.folder / f"{name}.csv", facts)
    return facts


def checked_facts(folder: Path, load: Callable[[Path], TavcConfig] = from_yaml) -> RunFacts:
    """`run_facts`, with the run's files besides its tables checked: every file `provenance.json`
    lists there, its `plan.json` by digest and as a plan of its config, and its settings held to
    its trials (`run_provenance.check_planned`)."""
    facts = run_facts(folder, load)
    for name in sorted(facts.digests or {}):
        if not (facts.folder / name).is_file() and not (name in facts.replaced and facts.replaced[name] is None):
            raise damaged(facts.folder / name, "not a regular file, where provenance.json lists a table"
                          if os.path.lexists(facts.folder / name) else "missing, though provenance.json lists it")
    plan = facts.folder / PLAN_FILE
    if plan.is_file() and facts.digests is not None:
        if PLAN_FILE not in facts.digests:
            raise damaged(plan, "not among the files provenance.json lists (left by another run?)")
        _check_digest(plan, facts.digests)
    if facts.cfg is not None:
        check_planned(facts, checked_plan(plan, facts.cfg))
    return facts


def checked_plan(path: Path, cfg: TavcConfig) -> RunPlan:
    """The run's `plan.json` read as the report reads it (`plan.read_plan`; without one, the plan its
    config gives): one line naming it where it is no plan of the config beside it, not JSON, or
    lists no controller."""
    try:
        return read_plan(path.parent, cfg)
    except TavcError:
        raise  # a refusal naming the file already
    except Exception as exc:  # noqa: BLE001 - JSON's, a codec's, an empty list's: the file is damaged
        raise damaged(path, f"cannot be read ({unreadable(exc)})") from None


def load_record(path: Path) -> TrialRecord:
    """The trial record at `path`; a damaged file, or one declaring more arrays than a record of
    tavc's holds (`readers.RECORD_LIMIT`), is one line naming it."""
    try:
        size = record_size(path)
        if size > RECORD_LIMIT:
            raise damaged(path, f"declares {size / 2**30:,.1f} GiB of arrays, more than a trial record of tavc's "
                                f"holds ({RECORD_LIMIT >> 30} GiB at the most)")
        return TrialRecord.load(path)
    except TavcError:
        raise
    except Exception as exc:  # numpy's or zipfile's error: the file is damaged, whatever the library
        raise damaged(path, f"cannot be read ({type(exc).__name__}: {exc})") from None


def read_trial(folder: Path, trial: Mapping) -> TrialRecord:
    """The record of `trial`, an entry of the ``trials`` of `folder`'s `provenance.json` (as
    `read_provenance` checks them), checked as the module's docstring says: missing, damaged
    or another run's, it is one line naming the file."""
    path = Path(folder) / trial["file"]
    if not path.is_file():
        raise damaged(path, "missing, though provenance.json lists it")
    record = load_record(path)
    listed = trial.get("key")
    if listed is not None and record.meta.get("key") != listed:  # a provenance.json without keys gives none
        raise TavcError(f"{path} is not this run's trial (its key differs from provenance.json); rerun `tavc run` "
                        "on the folder to recompute it")
    return record


def check_table(path: Path, facts: RunFacts | None = None) -> None:
    """Check one table file of a run (see the module's docstring); `facts` as `run_facts`
    gives them, read and checked from the table's folder when not given (`checked_facts`)."""
    path = Path(path)
    if facts is None:
        facts = checked_facts(path.parent)
    try:
        text = read_bounded(path, TABLE_LIMIT).decode()
    except UnicodeDecodeError:
        raise damaged(path, "cannot be read (not UTF-8 text)") from None
    if not text:
        raise damaged(path, "empty")
    if not text.endswith("\n"):
        raise damaged(path, "cut short (its last line has no newline)")
    header, rows = table_rows(path, text)
    if len(set(header)) < len(header):
        raise damaged(path, "a column named twice in its header")
    for line, row in rows:
        if len(row) != len(header):
            raise damaged(path, f"line {line} has {len(row)} fields, its header {len(header)}")
    schema = TABLES.get(path.stem)
    if schema is not None and not rows and not schema.empty_ok:
        raise damaged(path, "no rows under its header (a run writes this table only with rows)")
    if schema is not None:
        _check_columns(path, schema, header, rows, facts)
    # last: what is wrong, where the shape says, first
    _check_digest(path, facts.digests, table=True, before=facts.replaced.get(path.name))


def _check_columns(path: Path, schema: TableSchema, header: list[str], rows: list, facts: RunFacts) -> None:
    check_cells(path, schema, header, rows)
    _check_trials(path, header, rows, facts)
    _check_states(path, header, rows, facts)


def _check_trials(path: Path, header: list[str], rows: list, facts: RunFacts) -> None:
    """Every trial is one the run ran (for its controller, where the table has one); the
    trials' own table has a row for each of them. Each (trial, controller) pair of cells is judged
    once, and the rows walked only to name the first line of one that fails."""
    if "trial" not in header or facts.trials is None:
        return
    at_trial, at_ctrl = header.index("trial"), header.index("controller") if "controller" in header else None
    numbers = {n for _, n in facts.trials}

    def pair(row: list[str]) -> tuple[str, str | None]:
        return row[at_trial], (row[at_ctrl] if at_ctrl is not None else None)

    def problem(cells: tuple[str, str | None]) -> str | None:
        text, controller = cells
        trial = float(text)
        if not math.isfinite(trial) or trial != int(trial):
            return f"trial {text!r} is not a whole number"
        if (controller, int(trial)) not in facts.trials if controller is not None else int(trial) not in numbers:
            which = f"{controller} trial {int(trial)}" if controller is not None else f"trial {int(trial)}"
            return f"{which} is not among the trials provenance.json lists"
        return None

    judged = {cells: problem(cells) for cells in {pair(row) for _, row in rows}}
    if any(judged.values()):
        line, what = next((line, judged[pair(row)]) for line, row in rows if judged[pair(row)])
        raise damaged(path, f"line {line}: {what}")
    seen = {(controller, int(float(text))) for text, controller in judged}
    if path.stem == "trial_stats" and at_ctrl is not None and seen != facts.trials:
        controller, trial = sorted(facts.trials - seen)[0]
        raise damaged(path, f"no row for {controller} trial {trial}, which provenance.json lists")


def _check_states(path: Path, header: list[str], rows: list, facts: RunFacts) -> None:
    """Every state (a `state` value, a trial_stats column's) is one this team can be in;
    in `state_time`, the theory rows list every state of one team, and every controller
    has a row for each of them (a table cut at the end of a line loses the theory's last)."""
    if path.stem == "comparison":
        return
    for c in header:
        state = column_state(c)
        if state is not None and path.stem == "trial_stats" and not facts.valid_state(state):
            raise damaged(path, f"column {c!r}: {state!r} is no state of this experiment's team")
    if "state" not in header:
        return
    at = header.index("state")
    invalid = {state for state in {row[at] for _, row in rows} if not facts.valid_state(state)}
    if invalid:  # each state judged once, the rows walked only to name the first line of one that is none
        line, state = next((line, row[at]) for line, row in rows if row[at] in invalid)
        raise damaged(path, f"line {line}: state {state!r} is no state of this experiment's team")
    if path.stem != "state_time" or not rows:
        return
    by_ctrl: dict[str, set[str]] = {}
    for _, row in rows:
        by_ctrl.setdefault(row[header.index("controller")], set()).add(row[at])
    theory = by_ctrl.get("theory")
    if theory is None:
        raise damaged(path, "no theory rows (they come last: cut short?)")
    full = facts.team_states(theory)
    if theory != full:
        raise damaged(path, f"the theory rows list {len(theory)} of the team's {len(full)} states (cut short?)")
    for controller, states in by_ctrl.items():
        if not full <= states:
            raise damaged(path, f"{controller} has no row for state {sorted(full - states)[0]}")


def _check_digest(path: Path, digests: dict[str, str] | None, table: bool = False, before: str | None = None) -> None:
    """The file's SHA-256 against the one provenance.json recorded for it, where it did. A
    table of a run's kind that the record leaves out was not written by that run. A file whose
    rewrite from the run's tables (`retest.rewrite_tables`) was stopped before its end passes with
    the digest it had `before` as well: the record names the new one before the file is replaced,
    so a rewrite stopped between the two leaves the file as the run had it (or, where there was
    none, none: `check_run`), and the next report rewrites it."""
    if digests is None:
        return
    if before is not None and path.is_file() and file_digest(path) == before:
        return
    recorded = digests.get(path.name)
    if recorded is None:
        if table and path.stem in TABLE_NAMES:
            raise damaged(path, "not among the tables provenance.json lists (left by another run?)")
        return
    if not path.is_file():
        raise damaged(path, "missing, though provenance.json lists it")
    if file_digest(path) != recorded:
        raise damaged(path, "changed since its run wrote it (its SHA-256 is not the one provenance.json recorded)")
