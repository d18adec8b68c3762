"""A finished run's claims tested again by today's rules, and its `claims.csv` rewritten where
they come out otherwise: `tavc report` does it for every run it reads.

A run's claims are a function of the tables it wrote (its `trial_stats.csv` and the tables the
claims read, `analysis.claims.CLAIM_TABLES`), of its settings and plan, of the `trial_stats.csv`
of a finished run of the experiment a claim compares it with beside it (claims 7 and 8), and of
the rules that test them, which change more often than the trials do. So they can be tested
again without the trials (`retested_claims`), and a change of the rules, or the run beside run
again, never leaves a run's `claims.csv` saying what no tavc would write from its tables today.

A rewrite (`rewrite_claims`) holds the run's folder as a run does, writes only a `claims.csv`
that tavc wrote (never removing one, nor touching one with claims today's rules do not know),
never through a link nor outside the results folder it was given, and records it in the run's
`provenance.json` (``tables``: the file's new digest; ``rewritten``: which tavc rewrote it). The
record is written first, naming the digest the file has before (``replaced``; None where there
was none), and again once the file is written, without it: a rewrite stopped between them leaves
the file as the run had it, which the checks accept (`run_checks`), and the next report finishes
the rewrite.
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
from tavc_cli.analysis.experiment import experiment_claims
from tavc_cli.chapter import claims
from tavc_cli.errors import TavcError
from tavc_cli.experiments.plan import read_plan
from tavc_cli.io import claim_folder, file_digest, owned_path, write_text_atomic
from tavc_cli.outputs import claims_text, other_experiments
from tavc_cli.readers import load_json
from tavc_cli.run_checks import check_table, read_provenance, run_facts, unfinished_rewrites
from tavc_cli.settings import TavcConfig

CLAIMS = "claims.csv"
PROVENANCE = "provenance.json"


def retested_claims(folder: Path, root: Path, read_config: Callable[[Path], TavcConfig]) -> str | None:
    """The `claims.csv` today's rules give the finished run in `folder` (under `root`, the results
    folder), tested on the tables it wrote, where that is not what the folder holds, or where a
    rewrite of it was stopped before its end (`_pending`). None where there is nothing to test or
    nothing tavc may rewrite: no `trial_stats.csv` or `provenance.json`; a folder not a run's; a
    claims file tavc did not write, or a link on the way to it from `root`; a plan that cannot be
    read; no claim that today's rules know of the run's experiment, or a claim in its file that they
    do not know (a user's own experiment, its configs not given: a file is never removed); a run it
    is compared with (`_finished_others`) that did not finish or whose table does not check out.
    `read_config(path)` reads a `config.yaml`."""
    try:  # nothing on the way from root to the files a rewrite writes may be a link
        for name in (CLAIMS, PROVENANCE):
            owned_path(root, folder / name)
    except TavcError:
        return None
    owned = ownership.read(folder)
    if owned is None or owned.kind not in (ownership.RUN, ownership.SURROGATE):
        return None
    if not (folder / PROVENANCE).is_file() or not (folder / "trial_stats.csv").is_file():
        return None
    path = folder / CLAIMS
    if path.exists() and not (owned.owns(CLAIMS) and path.is_file()):
        return None
    now = path.read_text() if path.is_file() else ""
    if not _known(now):
        return None
    cfg = read_config(folder / "config.yaml")
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
    if not len(claims):
        return None
    text = claims_text(claims)
    return text if text != now or _pending(folder) else None


def _known(text: str) -> bool:
    """Whether every claim in a `claims.csv` text is one today's rules know (by its id)."""
    known = {str(c.id) for _, c in claims()}
    return all(row[0] in known for row in list(csv.reader(io.StringIO(text)))[1:] if row)


def _pending(folder: Path) -> bool:
    """Whether the run's `provenance.json` records a rewrite of its claims that was stopped before
    its end (`run_checks.unfinished_rewrites`)."""
    try:
        return CLAIMS in unfinished_rewrites(read_provenance(folder / PROVENANCE))
    except TavcError:
        return False


def _finished_others(cfg: TavcConfig, folder: Path, read_config) -> dict[str, pd.DataFrame] | None:
    """The `trial_stats.csv` of the runs beside `folder` its claims compare it with (`Claim.against`:
    claims 7 and 8), where `tavc run` reads them (`outputs.other_experiments`), each from a finished
    run that checks out. None where such a run's folder is there but the run did not finish (no
    `provenance.json` or `trial_stats.csv`: being run again, say) or its table does not check out
    (`run_checks.check_table`): the claims cannot be tested as a run would test them now. A folder
    that is not there is a run not made, as `tavc run` takes it."""
    own = str(cfg.experiment_name or "")
    compared = {c.against for name, c in claims() if name == own and c.against}
    others = {}
    for name, path in other_experiments(cfg, folder).items():
        if name not in compared or not (path.parent.exists() or path.parent.is_symlink()):
            continue
        if not (path.parent / PROVENANCE).is_file() or not path.is_file():
            return None
        try:  # the table the claims read, as that run wrote it (its digest, columns, trials, states)
            check_table(path, run_facts(path.parent, read_config))
        except TavcError:
            return None
        others[name] = pd.read_csv(path)
    return others


def rewrite_claims(folder: Path, root: Path, read_config: Callable[[Path], TavcConfig]) -> bool:
    """Hold the run's folder and, if its claims are still not what today's rules give
    (`retested_claims`, tested again here, where no other tavc command writes), record the
    rewrite in its `provenance.json`, then write them, then record that it is done, having removed
    what an earlier one killed inside a write left there; True if written. A run another tavc
    command holds is refused (`io.claim_folder`: one line naming it)."""
    try:  # the folder is held by a lock file in it: not through a link, nor a folder made anew
        owned_path(root, folder / CLAIMS)
    except TavcError:
        return False
    if not folder.is_dir():
        return False
    with claim_folder(folder):
        text = retested_claims(folder, root, read_config)
        record = None if text is None else _restamped(folder, text)
        if record is None:
            return False
        owned = ownership.read(folder)
        owned.remove_temporaries()  # what a rewrite killed inside a write left
        owned.wrote(CLAIMS)
        write_text_atomic(folder / PROVENANCE, json.dumps(record, indent=2, default=str), root)
        write_text_atomic(folder / CLAIMS, text, root)
        del record["rewritten"][CLAIMS]["replaced"]  # done: the file before no longer passes for the run's
        write_text_atomic(folder / PROVENANCE, json.dumps(record, indent=2, default=str), root)
        return True


def _restamped(folder: Path, text: str) -> dict | None:
    """The run's `provenance.json` once its `claims.csv` holds `text`: the file's digest in
    ``tables`` where the record keeps digests, and under ``rewritten`` the tavc that rewrote it and,
    until it is written, the digest the file has now (``replaced``; None: there was none); None
    where the record is not one tavc can extend. Everything else in it stays as the run wrote it."""
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
    if tables is not None:
        tables[CLAIMS] = hashlib.sha256(text.encode()).hexdigest()
        record["tables"] = dict(sorted(tables.items()))
    before = folder / CLAIMS
    rewritten[CLAIMS] = {"tavc_version": __version__, "git_commit": git_commit(),
                         "replaced": file_digest(before) if before.is_file() else None}
    record["rewritten"] = rewritten
    return record
