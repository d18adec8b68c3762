"""What tavc owns in a folder, so that a command replaces and deletes only files it wrote.

Every folder a command writes carries ``.tavc.json``, written as soon as the folder is taken
and again whenever the command writes or removes a file there: which command's folder it is
(its kind: a run's, a sweep's, a ladder's, or results with a report on top) and the files tavc
wrote in it. A trial record (``trials/<controller>_<NNN>.npz``) is tavc's by its name and is not
listed. Before a command writes, `take` checks the folder:

- a folder that holds another kind of output (a run aimed at a reproduce root or at a sweep's
  folder, a sweep aimed at a run) is refused;
- a run's folder must be new, empty, or a tavc run's: a folder with anything else in it is
  refused, naming what is there;
- a file the command would write that exists but is not tavc's is refused, naming it;
- a run over a run of another configuration is refused unless ``overwrite=true``, naming the
  settings that differ (`config_differences`).

Folders written before the list existed are recognised by what tavc always writes there (a
run's ``provenance.json``, a report's ``REPORT.md``, a sweep's ``sweep.csv``, a ladder's
``ladder.csv``, a model's ``model.json``, a calibration's ``search.json``, each beginning as
tavc writes it) and their files of tavc's names are taken as tavc's.
"""

from __future__ import annotations

import json
import os
import re
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import yaml

from tavc_cli.analysis.table_schemas import TABLE_NAMES
from tavc_cli.dotted import dotted
from tavc_cli.errors import TavcError
from tavc_cli.io import LOCK_NAME, owned_path, refuse_folder_problem, write_text_atomic
from tavc_cli.readers import load_json, load_yaml

MANIFEST = ".tavc.json"
RUN, SWEEP, LADDER, RESULTS, MODEL, CALIBRATION = "run", "sweep", "ladder", "results", "model", "calibration"
ANIMATION = "animation"
SURROGATE, TASKS, STUDY = "surrogate", "surrogate-tasks", "surrogate-study"
COMPARE = "compare"
READINGS = "readings"
TURN_TAKING_KIND = "turn-taking"
_WHAT = {RUN: "a tavc run's folder", SURROGATE: "a surrogate run's folder (tavc surrogate)",
         TASKS: "the folder of the surrogate's measured tasks (task_times.csv)",
         STUDY: "the folder of the surrogate's study (comparison.csv, phase.csv)",
         COMPARE: "a comparison's folder (tavc compare: compare.csv and runs/)",
         READINGS: "the folder of a study of the readings (tavc stay-switch: stay_switch.csv)",
         TURN_TAKING_KIND: "the folder of the model that knows turn-taking (turn_taking.json and its runs)",
         SWEEP: "a tavc sweep's folder (the jobs' folders and sweep.csv)",
         MODEL: "the folder of a tavc model (model.json)", CALIBRATION: "a tavc calibration's folder (search.csv)",
         ANIMATION: "a folder of tavc animations",
         LADDER: "a horizon ladder's folder (its rungs and ladder.csv)",
         RESULTS: "a results folder with a tavc report on top (REPORT.md)"}
REPORT_TITLE = "# tavc: the reproduction report"

# what each kind of folder holds of tavc's, by name (a run's tables are added by `run_files`)
RUN_FILES = ("config.yaml", "plan.json", "provenance.json", "failures.log")
SWEEP_FILES = ("sweep.csv", "sweep.png", "sweep.svg")
LADDER_FILES = ("ladder.csv", "ladder.png", "ladder.svg")
VALUE_RATIO_DIR = "value_ratio"  # under a results folder: the value-ratio sweep, its table value_ratio.csv in it
READINGS_DIR = "readings"  # under a results folder: the runs and calibration searches in other readings
WORLD_SEARCH_DIR = "calibration/world"  # beside a run's folder: `tavc calibrate`'s search (search.csv)
RESULTS_FILES = ("REPORT.md", "REPORT.html", "claims.csv", "value_ratio.csv")
MODEL_FILES = ("model.csv", "model.json")
COMPARE_FILES = ("compare.csv", "compare_trials.csv", "compare.md", "compare.png", "compare.svg")
TASKS_FILES = ("task_times.csv", "task_times.json", "task_times_summary.csv")
STAY_SWITCH_TABLES = ("stay_switch.csv", "stay_switch_model.csv", "stay_switch_turn_taking.csv")
STAY_SWITCH_FILES = (*STAY_SWITCH_TABLES, "stay_switch.json", "stay_switch.png", "stay_switch.svg")
TURN_TAKING_FILES = ("turn_taking.json",)
CALIBRATION_FILES = tuple(f"{stem}.{ext}" for stem in ("search", "sensitivity") for ext in ("csv", "json")) + tuple(
    f"{stem}.{ext}" for stem in ("sensitivity", "task_times") for ext in ("png", "svg"))
_FILES = {SWEEP: SWEEP_FILES, LADDER: LADDER_FILES, RESULTS: RESULTS_FILES, MODEL: MODEL_FILES,
          CALIBRATION: CALIBRATION_FILES, ANIMATION: (), TASKS: TASKS_FILES,
          STUDY: (), COMPARE: COMPARE_FILES, TURN_TAKING_KIND: TURN_TAKING_FILES}
_WITH_TRIALS = (RUN, MODEL, SURROGATE, TASKS)  # folders whose trials/ holds tavc's records
_SUBFOLDERS = {**dict.fromkeys(_WITH_TRIALS, ("trials",)), RESULTS: ("figures",)}  # tavc's folders in a folder
# kinds whose folder holds nothing but tavc's (trial records named by tavc among them), each with
# what its refusal of a folder of other files says: what else the folder holds, what the kind needs
_A_RUN = ("files tavc did not write", "a run needs a new or empty folder, or one of its own earlier runs")
_NEEDS_ITS_OWN = {RUN: _A_RUN, SURROGATE: _A_RUN,
                  TASKS: ("files that are not the surrogate's measured tasks", "the tasks and the trials they are "
                          "measured from need a new or empty folder, or one they were measured in before")}
# folders of their own a run's folder may hold before the run (`_nested`)
_NESTED = {"model": MODEL, "turn_taking": TURN_TAKING_KIND, "tasks": TASKS}

# settings that decide where and how fast a run goes, and whether it may replace, not what it computes
NOT_RESULTS = ("executor", "output_dir", "overwrite", "force")


_TEMPORARY = re.compile(r"\.(.+)\.[a-z0-9_]{8}\.tmp")  # `tempfile.mkstemp(prefix=".<name>.", suffix=".tmp")`


def run_files() -> tuple[str, ...]:
    """Every file a run may write in its folder, trial records apart."""
    return (*RUN_FILES, *(f"{name}.csv" for name in TABLE_NAMES))


def trial_path(out_dir: Path, controller: str, trial: int) -> Path:
    """Where the record of `controller`'s trial number `trial` is saved below `out_dir`."""
    return out_dir / "trials" / f"{controller}_{trial:03d}.npz"


def is_trial_record(name: str) -> bool:
    """True for a trial record's path relative to its run folder (``trials/random_003.npz``)."""
    parts = name.split("/")
    return len(parts) == 2 and parts[0] == "trials" and parts[1].endswith(".npz") and not parts[1].startswith(".")


@dataclass
class Owned:
    """The files tavc wrote in `folder`, a folder of `kind`; kept in its ``.tavc.json``."""

    folder: Path
    kind: str
    files: set[str] = field(default_factory=set)

    def owns(self, name: str) -> bool:
        """True if tavc wrote `name` (a path relative to the folder) here."""
        return name in self.files or (self.kind in _WITH_TRIALS and is_trial_record(name))

    def wrote(self, *names: str) -> None:
        """Record files written (or about to be written) by tavc."""
        self.files.update(names)
        self.save()

    def remove(self, name: str) -> bool:
        """Remove `name` if tavc wrote it (True if it was); a file of anybody else's stays."""
        if not self.owns(name):
            return False
        owned_path(self.folder, (self.folder / name).parent, folder=True)  # `..` or a link on the way: refused
        existed = (self.folder / name).is_file()
        (self.folder / name).unlink(missing_ok=True)
        self.files.discard(name)
        self.save()
        return existed

    def remove_temporaries(self) -> None:
        """Remove what a killed command left half-written here (`io.atomic_path`'s
        ``.<name>.<8 characters>.tmp`` beside a file tavc owns, in the folder or its trials/):
        nobody else writes here now that the folder is held."""
        for where in (self.folder, self.folder / "trials"):
            for path in where.glob(".*.tmp") if where.is_dir() else ():
                match = _TEMPORARY.fullmatch(path.name)
                name = str(path.relative_to(self.folder).parent / match[1]).removeprefix("./") if match else ""
                if match and (name == MANIFEST or self.owns(name)):
                    path.unlink(missing_ok=True)

    def save(self) -> None:
        """Write the manifest: the kind of folder and the files tavc wrote."""
        write_text_atomic(self.folder / MANIFEST, json.dumps(
            {"tavc": self.kind, "files": sorted(self.files)}, indent=1) + "\n")


MANIFEST_ADVICE = ("move the folder's results elsewhere, or remove this file to have them taken "
                   "as tavc's")  # what to do about a .tavc.json that cannot be read


def read(folder: Path) -> Owned | None:
    """What tavc owns in `folder` by its ``.tavc.json`` or, for a folder an earlier version wrote,
    by what is in it; None where tavc has written nothing recognisable."""
    folder = Path(folder)
    path = owned_path(folder, folder / MANIFEST)
    if path.is_file():
        try:
            data = load_json(path, advice=MANIFEST_ADVICE)
            kind, files = data["tavc"], data["files"]
            if kind not in _WHAT or not isinstance(files, list) or not all(isinstance(f, str) for f in files):
                raise ValueError("not a kind of tavc folder and a list of its files")
            files = set(files)
        except (ValueError, KeyError, TypeError) as exc:
            raise TavcError(f"{path}: cannot be read ({exc}); it lists what tavc wrote in the folder: "
                            f"{MANIFEST_ADVICE}") from None
        return Owned(folder, kind, files)
    kind = _earlier_kind(folder)
    if kind is None:
        return None
    files = {n for n in (run_files() if kind in (RUN, SURROGATE) else _FILES[kind]) if (folder / n).is_file()}
    if kind == RESULTS and (folder / "figures").is_dir():
        files |= {f"figures/{p.name}" for p in (folder / "figures").iterdir() if p.is_file()}
    return Owned(folder, kind, files)


# what marks a folder an earlier tavc wrote: a file and how it begins (tavc's own first line, or
# for JSON the keys only tavc writes)
_MARKS = ((RESULTS, "REPORT.md", REPORT_TITLE), (RESULTS, "claims.csv", "claim_id,claim,verdict,"),
          (RESULTS, "value_ratio.csv", "reading,horizon,ratio,"), (LADDER, "ladder.csv", "factor,duration_s,"),
          (SWEEP, "sweep.csv", "job,"))
_JSON_MARKS = ((RUN, "provenance.json", {"tavc_version", "code_digest", "trials"}),
               (MODEL, "model.json", {"n_robots", "n_circuits", "predicted_state"}),
               (CALIBRATION, "search.json", {"n_points", "n_trials_reused", "chosen"}))


def _earlier_kind(folder: Path) -> str | None:
    """The kind of a folder an earlier tavc wrote without ``.tavc.json``, or None: known by a
    file tavc always writes there, which begins as tavc's does (a file of somebody else's that
    only shares its name is not taken for tavc's)."""
    for kind, name, keys in _JSON_MARKS:
        try:
            if keys <= set(load_json(folder / name)):
                return kind
        except (OSError, ValueError, TypeError):
            pass
    for kind, name, start in _MARKS:
        try:
            with open(folder / name, "rb") as fh:
                if fh.read(len(start)).decode(errors="replace") == start:
                    return kind
        except OSError:
            pass
    return None


def describe(kind: str) -> str:
    """What a folder of `kind` is, as messages name it ("a tavc run's folder")."""
    return _WHAT.get(kind, kind)


def expect(folder: Path, kind: str, what: str = "output_dir") -> None:
    """Refuse, with one line and before anything is run, a folder that holds another kind of
    output than `kind` (a command that writes there at its end checks early with this), and the
    root of the file system (`io.folder_problem`)."""
    refuse_folder_problem(folder, what)
    owned = read(Path(folder)) if Path(folder).is_dir() else None
    if owned is not None and owned.kind != kind:
        raise TavcError(f"{what}: {folder} is {describe(owned.kind)}, not {describe(kind)}; "
                        "choose another folder")


def take(folder: Path, kind: str, writes: Iterable[str], what: str = "output_dir", *, save: bool = True) -> Owned:
    """Check that a command of `kind` may write `writes` (paths relative to `folder`) there, and
    return what tavc owns in it, its ``.tavc.json`` written. Refuses, with one line naming the
    folder or file, a folder of another kind, a run's folder holding anything not tavc's, and a
    file in the way that tavc did not write. The caller holds the folder (`io.claim_folder`)."""
    folder = Path(folder)
    check_inside(folder, kind, writes, what)
    owned = read(folder) if folder.is_dir() else None
    if owned is not None and owned.kind == ANIMATION and kind == RUN:
        owned.kind = RUN  # the animation's default folder is the run's: the run adopts it, its files listed
    else:
        expect(folder, kind, what)
    if owned is None:
        owned = Owned(folder, kind)
        if kind in _NEEDS_ITS_OWN:
            foreign = sorted(p.name + ("/" if p.is_dir() else "") for p in folder.iterdir()
                             if not _ours(p.name) and not _nested(p))
            if foreign:
                shown = ", ".join(foreign[:3]) + (f" and {len(foreign) - 3} more" if len(foreign) > 3 else "")
                holds, needs = _NEEDS_ITS_OWN[kind]
                raise TavcError(f"{what}: {folder} holds {holds} ({shown}); {needs}: choose another folder")
    in_the_way = sorted(n for n in writes if (folder / n).exists() and not owned.owns(n))
    if in_the_way:
        raise TavcError(f"{what}: {folder / in_the_way[0]} was not written by tavc and tavc would write a file of "
                        "that name; move it away or choose another folder")
    if save:  # a caller with checks of its own saves once they pass (`Owned.wrote`)
        owned.save()
        owned.remove_temporaries()
    return owned


def check_inside(folder: Path, kind: str, writes: Iterable[str], what: str = "output_dir") -> None:
    """Refuse, in one line, a link, a pipe or a device where a command of `kind` reads or writes in `folder`.

    Checked before anything there is read (`io.owned_path`): the folder's list, the files the
    command writes, and the folders of tavc's it keeps (a run's trials/, a report's figures/)
    with everything in them.
    """
    for name in (MANIFEST, *writes):
        owned_path(folder, folder / name, what=what)
    for name in _SUBFOLDERS.get(kind, ()):
        owned_path(folder, folder / name, folder=True, what=what)
        below = [folder / name] if (folder / name).is_dir() else []
        while below:  # every level, without recursion (a tree of any depth); a link is listed, not followed
            with os.scandir(below.pop()) as entries:
                for entry in entries:
                    owned_path(folder, Path(entry.path), folder=entry.is_dir(), what=what)
                    if entry.is_dir(follow_symlinks=False):
                        below.append(Path(entry.path))


def _nested(path: Path) -> bool:
    """True for a folder tavc keeps inside a run's (the model `tavc model` measures there, the
    turn-taking model's runs, a surrogate run's measured tasks), which a command may have written
    before the run itself."""
    if not path.is_dir() or path.name not in _NESTED:
        return False
    owned = read(path)
    return owned is not None and owned.kind == _NESTED[path.name]


def _ours(name: str) -> bool:
    """Names tavc itself leaves in a folder it holds: the lock, the list, half-written files."""
    match = _TEMPORARY.fullmatch(name)
    return name in (LOCK_NAME, MANIFEST) or bool(match and match[1] in (MANIFEST, *run_files()))


def config_differences(old_yaml: Path, new_yaml: str, limit: int = 3, ignore: Iterable[str] = ()) -> list[str]:
    """The settings (dotted keys, ``old -> new``) in which the run recorded in `old_yaml` differs
    from the configuration `new_yaml`, leaving out where and how fast it runs (`NOT_RESULTS`),
    the dotted keys in `ignore` and keys only one of them has (a setting a later version of tavc
    added is not another configuration); empty if they would compute the same. At most `limit`
    of them, then how many more."""
    try:
        old = load_yaml(old_yaml)
    except (OSError, UnicodeDecodeError, yaml.YAMLError, TavcError):
        return [f"{Path(old_yaml).name} unreadable"]
    new = yaml.safe_load(new_yaml)
    a, b = dotted(old if isinstance(old, dict) else {}), dotted(new)
    ignore = set(ignore)
    keys = sorted(k for k in set(a) & set(b)
                  if a[k] != b[k] and k.split(".")[0] not in NOT_RESULTS and k not in ignore)
    shown = [f"{k}: {a.get(k)} -> {b.get(k)}" for k in keys[:limit]]
    return [*shown, f"{len(keys) - limit} more"] if len(keys) > limit else shown


def recorded_differences(record: Path, new: dict, limit: int = 3) -> list[str]:
    """The settings (dotted keys, ``old -> new``) in which the JSON `record` a command wrote
    (a model's ``model.json``, a search's ``search.json``) differs from `new`, the same
    settings of the command about to run; keys only one side has are left out, as in
    `config_differences`. Empty when there is no record."""
    record = Path(record)
    if not record.is_file():
        return []
    try:
        old = load_json(record)
    except (OSError, ValueError, TavcError):
        return [f"{record.name} unreadable"]
    a, b = dotted(old if isinstance(old, dict) else {}), dotted(json.loads(json.dumps(new)))
    keys = sorted(k for k in set(a) & set(b) if a[k] != b[k])
    shown = [f"{k}: {a[k]} -> {b[k]}" for k in keys[:limit]]
    return [*shown, f"{len(keys) - limit} more"] if len(keys) > limit else shown


def refuse_other_settings(record: Path, new: dict, what: str, overwrite: bool, *,
                          allow: str = "add overwrite=true to replace it, or choose another output_dir") -> None:
    """Refuse, in one line naming the differences and how to go on, to replace the result
    recorded in `record` by one of other settings (`recorded_differences`), unless `overwrite`."""
    differ = recorded_differences(record, new)
    if differ and not overwrite:
        raise TavcError(f"{what}: {record} was made with other settings ({'; '.join(differ)}); {allow}")


def take_report_folders(results_dir: Path, horizon_dirs: Sequence[Path] = (), page: bool = False,
                        emptied: Sequence[Path] = ()) -> list:
    """Check, before anything is written, that `tavc report` may write its files (`take`):
    REPORT.md, claims.csv and figures/ on top, each longer horizon's claims.csv and figures/,
    the value-ratio table. Refused: a folder that is a run's; a longer horizon's or the value-ratio
    sweep's folder that is a link (the writes would leave the results folder); a file there that
    tavc did not write. With `page`, REPORT.html on top too. In the `emptied` horizons' folders, which
    hold no finished run any more, an earlier report's claims.csv and figures are removed, so that
    none stands as this report's. Returns what tavc owns in the folders whose figures/ the report
    draws."""
    roots = [(results_dir, ("REPORT.md", "claims.csv", *(["REPORT.html"] if page else []))),
             *((d, ("claims.csv",)) for d in horizon_dirs)]
    drawn = len(roots)
    if (results_dir / VALUE_RATIO_DIR).is_dir():
        roots.append((results_dir / VALUE_RATIO_DIR, ("value_ratio.csv",)))
    for folder, _ in roots[1:]:  # tavc's folders in the results folder: none may lead out of it
        owned_path(results_dir, folder, folder=True, what="RESULTS_DIR")
    for folder, files in roots:
        check_inside(folder, RESULTS, files, what="RESULTS_DIR")
    for folder, _ in roots[:drawn]:
        if (folder / "figures").exists() and not (folder / "figures").is_dir():
            raise TavcError(f"RESULTS_DIR: {folder / 'figures'} is a file, where the report draws its figures in a "
                            "folder of its own; move it away or choose another folder")
        owned = read(folder)
        figures = sorted(p for p in (folder / "figures").rglob("*") if p.is_file()) if (
            folder / "figures").is_dir() else []
        foreign = [p for p in figures if owned is None or not owned.owns(p.relative_to(folder).as_posix())]
        if foreign:
            raise TavcError(f"RESULTS_DIR: {foreign[0]} was not written by tavc, and the report draws its figures "
                            f"in {folder / 'figures'}; move it away or choose another folder")
    cleared = []  # the emptied horizons' report files, each checked to lie inside its folder
    for folder in emptied:
        owned = read(owned_path(results_dir, folder, folder=True, what="RESULTS_DIR"))
        for name in sorted(owned.files) if owned is not None and owned.kind == RESULTS else ():
            cleared.append((owned, owned_path(folder, folder / name, what="RESULTS_DIR")))
    taken = []
    for folder, files in roots:
        taken.append(take(folder, RESULTS, files, what="RESULTS_DIR"))
        taken[-1].wrote(*files)
    for owned, path in cleared:
        owned.remove(path.relative_to(owned.folder).as_posix())
    return taken[:drawn]


def list_figures(taken: list) -> None:
    """Record the figures `tavc report` drew as tavc's, and forget the files it listed before
    writing them that are not there (a report stopped first): a file of the user's put there
    later is the user's."""
    for owned in taken:
        owned.files -= {name for name in owned.files if not (owned.folder / name).exists()}
        if (owned.folder / "figures").is_dir():
            owned.wrote(*(p.relative_to(owned.folder).as_posix() for p in (owned.folder / "figures").rglob("*")
                          if p.is_file()))
        else:
            owned.save()
