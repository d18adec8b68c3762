"""A run's `provenance.json` as a reader takes it: read and checked (`read_provenance`), the rewrites
tavc stopped midway it records (`unfinished_rewrites`), and its trials held against the run's
settings (`check_planned`): the trials its `config.yaml` and `plan.json` plan, each under the key
they give it. A table or record that fails is one line naming the file (`table_cells.damaged`)."""

from __future__ import annotations

import hashlib
import json
from collections.abc import Callable, Mapping
from dataclasses import asdict, replace
from typing import TYPE_CHECKING

from tavc_cli.errors import TavcError
from tavc_cli.experiments.build import trial_specs
from tavc_cli.experiments.plan import PLAN_FILE, RunPlan, plan_run
from tavc_cli.experiments.spec import _jsonable, code_digest
from tavc_cli.learning.parameters import PluginSettings
from tavc_cli.learning.plugins import target_digest, target_files
from tavc_cli.ownership import SURROGATE
from tavc_cli.ownership import read as read_owned
from tavc_cli.readers import load_json
from tavc_cli.table_cells import damaged, unreadable

if TYPE_CHECKING:
    from pathlib import Path

    from tavc_cli.experiments.spec import TrialSpec
    from tavc_cli.run_checks import RunFacts
    from tavc_cli.settings import TavcConfig


def unfinished_rewrites(provenance: dict) -> dict[str, str | None]:
    """The files of a run whose rewrite by tavc from the run's tables (`retest.rewrite_tables`) was
    stopped before its end, as its `provenance.json` records them: each with its digest before the
    rewrite (None: there was no file)."""
    return {name: r["replaced"] for name, r in (provenance.get("rewritten") or {}).items() if "replaced" in r}


def made_by_of(provenance: Mapping | None) -> dict:
    """What computed a run's trials, as its `provenance.json` records it (`runner.made_by`): tavc's
    simulator (``code_digest``) and the engine (None where it records none, or a value of another
    kind), and the code of learners from outside tavc ({} where none)."""
    record = provenance or {}
    code, engine, learners = record.get("code_digest"), record.get("engine"), record.get("learner_code")
    return {"code_digest": code if isinstance(code, str) else None,
            "engine": engine if isinstance(engine, str) else None,
            "learner_code": learners if isinstance(learners, dict) else {}}


def read_provenance(path: Path) -> dict:
    """A run's `provenance.json`, checked: a JSON object listing its trials, each with its
    controller, number and file."""
    try:
        prov = load_json(path)
    except (OSError, UnicodeDecodeError, ValueError) as exc:
        raise damaged(path, f"cannot be read ({unreadable(exc)})") from None
    trials = prov.get("trials") if isinstance(prov, dict) else None
    if not isinstance(trials, list):
        raise damaged(path, "cannot be read (no list of trials in it)")
    for t in trials:
        if not (isinstance(t, dict) and isinstance(t.get("controller"), str) and isinstance(t.get("trial"), int)
                and isinstance(t.get("file"), str)):
            raise damaged(path, f"cannot be read (a trial without its controller, number and file: {t!r:.60})")
    tables = prov.get("tables")
    if tables is not None and not (isinstance(tables, dict) and all(isinstance(v, str) for v in tables.values())):
        raise damaged(path, "cannot be read (its tables are not a map of file names to digests)")
    if prov.get("code_digest") == code_digest():  # this tavc's code writes both; without them nothing would be checked
        if not isinstance(tables, dict):
            raise damaged(path, "edited (it lists no digests of its tables, which this tavc's runs always record)")
        if any(not isinstance(t.get("key"), str) for t in trials):
            raise damaged(path, "edited (a trial is listed without its key, which this tavc's runs always record)")
    rewritten = prov.get("rewritten")
    if "rewritten" in prov and not (isinstance(rewritten, dict) and all(
            isinstance(r, dict) and isinstance(r.get("replaced", ""), str | None) for r in rewritten.values())):
        raise damaged(path, "cannot be read (its rewritten files are not a map of file names to records)")
    return prov


def check_planned(facts: RunFacts, plan: RunPlan) -> None:
    """The trials `provenance.json` lists are those the run's `config.yaml` and `plan.json` plan:
    the controllers and trial counts the config gives, each trial listed once, and, where this
    tavc's code computed them (`RunFacts.other_code` is None), each under the key its settings
    give it (`TrialSpec.key`: everything that fixes its outcome, with the engine provenance.json
    records, and for a learner from outside tavc the digest of its code it records). So a
    config.yaml edited after its run is refused even where its digest was re-signed or never
    recorded. A run on the surrogate where provenance.json records no engine (runs written before
    it did), or of a learner from outside tavc whose code's digest it does not record, is checked
    for its trials but not their keys: those hold the digest of the tasks the run drew from, or of
    the learner's files, which the run's folder does not keep."""
    cfg, path = facts.cfg, facts.folder / "provenance.json"
    try:
        given = [(c.label, c.trials) for c in plan_run(cfg).controllers]
    except Exception as exc:  # noqa: BLE001 - settings no run was made with: whatever fails in planning them
        raise damaged(facts.folder / "config.yaml",
                      f"edited after its run (it plans no run: {unreadable(exc)})") from None
    if [(c.label, c.trials) for c in plan.controllers] != given:
        raise damaged(facts.folder / "config.yaml", "edited after its run (its controllers and trials, "
                      f"{_counts(given)}, are not those {PLAN_FILE} records)")
    if not facts.listed:  # no provenance.json, or one listing no trial: nothing to check against
        return
    planned = [(c.label, j) for c in plan.controllers for j in range(c.trials)]
    if sorted((c, j) for c, j, _ in facts.listed) != sorted(planned):
        raise damaged(path, f"its trials are not those config.yaml plans ({_counts(given)})")
    if facts.other_code is not None or facts.recorded_code is None:  # keys of other code, or none known
        return
    owned = read_owned(facts.folder) if facts.engine is None else None
    if owned is not None and owned.kind == SURROGATE:  # its engine not recorded: the tasks it drew are unknown
        return
    planned_keys = keys_of(cfg, plan, facts.engine, recorded_digests(facts))
    if planned_keys is None:
        return
    listed_keys = {(c, j): key for c, j, key in facts.listed}
    for (controller, trial), key in planned_keys.items():
        listed = listed_keys[controller, trial]
        if listed is not None and listed != key:
            raise damaged(path, f"{controller} trial {trial} is listed under a key its config.yaml and "
                          f"{PLAN_FILE} do not give it (edited after the run?)")


def keys_of(cfg: TavcConfig, plan: RunPlan, engine: str | None = None,
            learner_digest: Callable[[str], str | None] | None = None) -> dict[tuple[str, int], str] | None:
    """The key this tavc's code gives each trial `cfg` and `plan` plan (`TrialSpec.key`, on
    `engine` where the run records one), by controller and trial. A learner from outside tavc
    enters its trials' keys by the digest of its code (`plugins.target_digest`), which the run's
    folder does not keep: `learner_digest` gives it by target (as `provenance.json` records it,
    or `digest_now`); None where it gives none."""
    specs = trial_specs(cfg, plan)
    if engine is not None:
        specs = [replace(s, engine=engine) for s in specs]
    keys = {}
    for s in specs:
        if isinstance(s.policy, PluginSettings):
            digest = learner_digest(str(s.policy.target)) if learner_digest is not None else None
            if not isinstance(digest, str):
                return None
            keys[s.controller, s.trial] = key_with_learner(s, digest)
        else:
            keys[s.controller, s.trial] = s.key()
    return keys


def key_with_learner(spec: TrialSpec, digest: str) -> str:
    """`spec.key()` of a trial of a learner from outside tavc, with `digest` standing for the
    digest of the learner's code (`TrialSpec.key` computes it from the files as they are now)."""
    blob = json.dumps(asdict(spec), sort_keys=True, default=_jsonable) + code_digest() + digest
    return hashlib.sha256(blob.encode()).hexdigest()[:20]


def recorded_digests(facts: RunFacts) -> Callable[[str], str | None]:
    """The digest of a learner from outside tavc by its target, as the run's `provenance.json`
    records it (`learner_code`; None where it records none)."""
    def digest(target: str) -> str | None:
        entry = facts.learner_code.get(target)
        return entry.get("digest") if isinstance(entry, dict) else None

    return digest


def digest_now(target: str) -> str | None:
    """The digest of a learner from outside tavc from its code as it is now
    (`plugins.target_digest`), where its files are found from here (a file target relative to a
    config folder only while that folder is searched); None where they are not."""
    try:
        return target_digest(target) if target_files(target) else None
    except TavcError:  # its file is not where the target says, from here
        return None


def _counts(controllers: list[tuple[str, int]]) -> str:
    return ", ".join(f"{n} trials of {label}" for label, n in controllers)
