"""A finished run's derived tables made again by today's rules from the tables it wrote, and
rewritten where they come out otherwise: `tavc report` does it for every run it reads.

Two of a run's files are functions of its other tables and of rules that change more often than
the trials do: `comparison.csv` (the chapter's state table beside the run's `state_time.csv`,
`analysis.comparison`) and `claims.csv` (of its `trial_stats.csv` and the tables the claims read,
`analysis.claims.CLAIM_TABLES`, its settings and plan, and the `trial_stats.csv` of a finished run
of the experiment a claim compares it with beside it: claims 7 and 8). So they can be made again
without the trials (`retested_tables`), and a change of the rules or of the chapter's reference
tables, or the run beside run again, never leaves a run's folder saying what no tavc would write
from its tables today.

A rewrite (`rewrite_tables`) holds the run's folder as a run does, writes only files that tavc
wrote (never removing one, nor touching a `claims.csv` with claims today's rules do not know),
never through a link nor outside the results folder it was given, and records it in the run's
`provenance.json` (``tables``: each file's new digest; ``rewritten``: which tavc rewrote it). The
record is written first, naming the digest each file has before (``replaced``; None where there
was none), and again once the files are written, without it: a rewrite stopped between them
leaves each file as the run had it or as rewritten, which the checks accept (`run_checks`), and
the next report finishes the rewrite.
"""

from __future__ import annotations

import csv
import hashlib
import io
import json
from collections.abc import Callable
from pathlib import Path

import pandas as pd

from tavc_cli import __version__, ownership
from tavc_cli.analysis.alike import unlike
from tavc_cli.analysis.experiment import experiment_claims
from tavc_cli.chapter import claims
from tavc_cli.errors import TavcError
from tavc_cli.experiments.plan import read_plan
from tavc_cli.io import claim_folder, file_digest, owned_path, write_text_atomic
from tavc_cli.outputs import claims_text, comparison_text, other_experiments
from tavc_cli.readers import load_json
from tavc_cli.run_checks import check_table, run_facts
from tavc_cli.run_provenance import read_provenance, unfinished_rewrites
from tavc_cli.settings import TavcConfig

CLAIMS = "claims.csv"
COMPARISON = "comparison.csv"
DERIVED = (COMPARISON, CLAIMS)  # the files a rewrite may write, in the order it writes them
PROVENANCE = "provenance.json"


def retested_tables(folder: Path, root: Path, read_config: Callable[[Path], TavcConfig]) -> dict[str, str]:
    """The derived files (`DERIVED`) today's rules give the finished run in `folder` (under `root`,
    the results folder), made on the tables it wrote, where that is not what the folder holds or
    where a rewrite of the file was stopped before its end (`_pending`): file name -> text. Empty
    where there is nothing to make again or nothing tavc may rewrite: no `trial_stats.csv` or
    `provenance.json`; a folder not a run's; a link on the way to any of them from `root`. A file
    is left out where tavc did not write it (`_writable`), where today's rules give none (a file
    is never removed), and as `_comparison` and `_claims` say. `read_config(path)` reads a
    `config.yaml`."""
    try:  # nothing on the way from root to the files a rewrite writes may be a link
        for name in (*DERIVED, PROVENANCE):
            owned_path(root, folder / name)
    except TavcError:
        return {}
    owned = ownership.read(folder)
    if owned is None or owned.kind not in (ownership.RUN, ownership.SURROGATE):
        return {}
    if not (folder / PROVENANCE).is_file() or not (folder / "trial_stats.csv").is_file():
        return {}
    cfg = read_config(folder / "config.yaml")
    makers = {COMPARISON: lambda: _comparison(folder, cfg), CLAIMS: lambda: _claims(folder, cfg, read_config)}
    made = {name: make() for name, make in makers.items() if _writable(folder, name, owned)}
    pending = _pending(folder)
    return {name: text for name, text in made.items()
            if text is not None and (text != _text(folder / name) or name in pending)}


def _writable(folder: Path, name: str, owned: ownership.Owned) -> bool:
    """Whether a rewrite may write the file `name` of the run: not there, or a file tavc wrote."""
    path = folder / name
    return not path.exists() or (owned.owns(name) and path.is_file())


def _text(path: Path) -> str:
    return path.read_text() if path.is_file() else ""


def _comparison(folder: Path, cfg: TavcConfig) -> str | None:
    """The run's `comparison.csv` from its `state_time.csv` (`outputs.comparison_text`); None where
    it has no such table or its experiment no chapter state table."""
    if not (folder / "state_time.csv").is_file():
        return None
    return comparison_text(str(cfg.experiment_name or ""), pd.read_csv(folder / "state_time.csv", dtype={"state": str}))


def _claims(folder: Path, cfg: TavcConfig, read_config: Callable[[Path], TavcConfig]) -> str | None:
    """The run's `claims.csv` tested on its tables; None where it cannot be tested as a run would
    test it now, or may not be rewritten: a claim in its file that today's rules do not know (a
    user's own experiment, its configs not given), no claim they know of the run's experiment, a
    plan that cannot be read, a run it is compared with (`_finished_others`) that did not finish or
    whose table does not check out."""
    if not _known(_text(folder / CLAIMS)):
        return None
    others = _finished_others(cfg, folder, read_config)
    if others is None:
        return None
    try:
        plan = read_plan(folder, cfg)
    except (TavcError, ValueError):  # refused where the report reads the plan; here, left as it is
        return None
    # deferred: loads scipy
    from tavc_cli.analysis.claims import CLAIM_TABLES

    tables = {"trial_stats": pd.read_csv(folder / "trial_stats.csv")}
    tables.update({t: pd.read_csv(folder / f"{t}.csv") for t in CLAIM_TABLES if (folder / f"{t}.csv").is_file()})
    claims = experiment_claims(cfg, plan, tables, others)
    return claims_text(claims) if len(claims) else None


def _known(text: str) -> bool:
    """Whether every claim in a `claims.csv` text is one today's rules know (by its id)."""
    known = {str(c.id) for _, c in claims()}
    return all(row[0] in known for row in list(csv.reader(io.StringIO(text)))[1:] if row)


def _pending(folder: Path) -> set[str]:
    """The files whose rewrite the run's `provenance.json` records as stopped before its end
    (`run_provenance.unfinished_rewrites`)."""
    try:
        return set(unfinished_rewrites(read_provenance(folder / PROVENANCE)))
    except TavcError:
        return set()


def _finished_others(cfg: TavcConfig, folder: Path, read_config) -> dict[str, pd.DataFrame | str] | None:
    """The `trial_stats.csv` of the runs beside `folder` its claims compare it with (`Claim.against`:
    claims 7 and 8), where `tavc run` reads them (`outputs.other_experiments`), each from a finished
    run that checks out. None where such a run's folder is there but the run did not finish (no
    `provenance.json` or `trial_stats.csv`: being run again, say) or its table does not check out
    (`run_checks.check_table`): the claims cannot be tested as a run would test them now. A folder
    that is not there is a run not made, as `tavc run` takes it; a run made with other settings
    than this one's gives why in its table's place (`unlike`), as it does there."""
    others: dict[str, pd.DataFrame | str] = {}
    compared = other_experiments(cfg, folder)
    try:  # what computed this run's trials, to be what computed theirs
        ours = run_facts(folder, read_config).made_by if compared else {}
    except TavcError:
        return None
    for name, path in compared.items():
        if not (path.parent.exists() or path.parent.is_symlink()):
            continue
        if not (path.parent / PROVENANCE).is_file() or not path.is_file():
            return None
        try:  # the table the claims read, as that run wrote it (its digest, columns, trials, states)
            facts = run_facts(path.parent, read_config)
            check_table(path, facts)
        except TavcError:
            return None
        others[name] = unlike(cfg, ours, facts.cfg, facts.made_by) or pd.read_csv(path)
    return others


def rewrite_tables(folder: Path, root: Path, read_config: Callable[[Path], TavcConfig]) -> list[str]:
    """Hold the run's folder and, for the derived files still not what today's rules give
    (`retested_tables`, made again here, where no other tavc command writes), record the rewrite in
    its `provenance.json`, then write them, then record that it is done, having removed what an
    earlier one killed inside a write left there; returns the files written. A run another tavc
    command holds is refused (`io.claim_folder`: one line naming it)."""
    try:  # the folder is held by a lock file in it: not through a link, nor a folder made anew
        owned_path(root, folder / CLAIMS)
    except TavcError:
        return []
    if not folder.is_dir():
        return []
    with claim_folder(folder):
        texts = retested_tables(folder, root, read_config)
        record = _restamped(folder, texts) if texts else None
        if record is None:
            return []
        owned = ownership.read(folder)
        owned.remove_temporaries()  # what a rewrite killed inside a write left
        owned.wrote(*texts)
        write_text_atomic(folder / PROVENANCE, json.dumps(record, indent=2, default=str), root)
        for name, text in texts.items():
            write_text_atomic(folder / name, text, root)
        for name in texts:  # done: the files before no longer pass for the run's
            del record["rewritten"][name]["replaced"]
        write_text_atomic(folder / PROVENANCE, json.dumps(record, indent=2, default=str), root)
        return list(texts)


def _restamped(folder: Path, texts: dict[str, str]) -> dict | None:
    """The run's `provenance.json` once each file named in `texts` holds its text: the file's
    digest in ``tables`` where the record keeps digests, and under ``rewritten`` the tavc that
    rewrote it and, until it is written, the digest the file has now (``replaced``; None: there was
    none); None where the record is not one tavc can extend. Everything else in it stays as the
    run wrote it."""
    # deferred: the runner loads the simulator's kernels, which importing the report must not
    from tavc_cli.experiments.runner import git_commit

    try:
        record = load_json(folder / PROVENANCE)
    except (OSError, ValueError, TavcError):
        return None
    rewritten = record.get("rewritten", {}) if isinstance(record, dict) else None
    tables = record.get("tables") if isinstance(record, dict) else None
    if not isinstance(rewritten, dict) or not isinstance(tables, dict | None):
        return None
    commit = git_commit()
    for name, text in texts.items():
        if tables is not None:
            tables[name] = hashlib.sha256(text.encode()).hexdigest()
        before = folder / name
        rewritten[name] = {"tavc_version": __version__, "git_commit": commit,
                           "replaced": file_digest(before) if before.is_file() else None}
    if tables is not None:
        record["tables"] = dict(sorted(tables.items()))
    record["rewritten"] = rewritten
    return record
