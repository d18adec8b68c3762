"""Reading a results folder from Python: one run's (`Results`, `load`) or a sweep's (`Sweep`,
`load_sweep`), its tables as pandas DataFrames, its records, plan and settings, each checked as
`tavc report` checks it. Never simulates; `tavc_cli.api` offers these beside the functions that run."""

from __future__ import annotations

from functools import cached_property
from pathlib import Path

import pandas as pd
import yaml

from tavc_cli.errors import TavcError
from tavc_cli.estimates import physical_memory
from tavc_cli.experiments.plan import PLAN_FILE, RunPlan
from tavc_cli.experiments.records import TABLES, TrialRecord
from tavc_cli.io import path_of, plain_name
from tavc_cli.ownership import SURROGATE, trial_path
from tavc_cli.ownership import read as read_owned
from tavc_cli.readers import load_yaml, record_size
from tavc_cli.run_checks import check_table, checked_plan, load_record, read_trial, run_facts
from tavc_cli.run_provenance import digest_now, keys_of, read_provenance
from tavc_cli.run_tables import checked_sweep, job_folder
from tavc_cli.settings import from_yaml
from tavc_cli.table_cells import damaged, unreadable


class Results:
    """One experiment's results folder (as `tavc run` writes it), read lazily."""

    def __init__(self, path: str | Path) -> None:
        """Open the folder at `path`; fails in one line unless it holds a run's `config.yaml`."""
        self.path = path_of(path, "path")
        if not (self.path / "config.yaml").is_file():
            if (self.path / "sweep.csv").is_file():
                raise TavcError(f"{self.path}: a sweep's folder (sweep.csv, one folder per job): open it with "
                                "api.load_sweep, or one job's folder with api.load")
            raise TavcError(f"{self.path}: not a results folder of tavc run (no config.yaml in it)")

    def __repr__(self) -> str:
        """``Results('<path>')``."""
        return f"Results({str(self.path)!r})"

    def table(self, name: str) -> pd.DataFrame:
        """The run's table `name`.csv (state_time, performance, trial_stats, claims, ...), checked
        as `tavc report` checks it first (`run_checks.check_table`: a damaged table is one
        line naming it)."""
        path = self.path / f"{name}.csv"
        if not plain_name(str(name)) or not path.is_file():  # a name, never a path to another run's table
            have = ", ".join(sorted(p.stem for p in self.path.glob("*.csv"))) or "none"
            raise TavcError(f"{self.path}: no table {name!r} (tables here: {have})")
        if not (self.path / "provenance.json").is_file():  # its tables may be an earlier run's
            raise TavcError(f"{self.path}: its run did not finish (no provenance.json), so its tables may be "
                            "another run's; run it again to complete it")
        check_table(path)
        return pd.read_csv(path)

    @property
    def tables(self) -> list[str]:
        """Names of the tables in the folder."""
        return sorted(p.stem for p in self.path.glob("*.csv"))

    state_time = property(lambda self: self.table("state_time"), doc="% of the stable period in each state.")
    performance = property(lambda self: self.table("performance"), doc="Score delivered per second over time.")
    trial_stats = property(lambda self: self.table("trial_stats"), doc="One row per trial.")

    @cached_property
    def config(self) -> dict:
        """The composed config the run used (a damaged config.yaml is one line naming it)."""
        path = self.path / "config.yaml"
        try:
            config = load_yaml(path)
        except (OSError, yaml.YAMLError) as exc:
            raise TavcError(f"{path}: cannot be read ({str(exc).splitlines()[0]}); rerun its experiment to rewrite "
                            "it") from None
        if not isinstance(config, dict):
            raise TavcError(f"{path}: holds no settings; rerun its experiment to rewrite it")
        return config

    @cached_property
    def not_a_verdict(self) -> str:
        """Why the run's claims are no verdict ("not a verdict: scale=quick (...)": fewer trials or
        less time than the chapter's), or "" for a run at the chapter's scale or beyond. `claims`
        carries the same in its column ``not_a_verdict``."""
        # deferred: loads scipy
        from tavc_cli.analysis.claims import not_a_verdict

        return not_a_verdict(from_yaml(self.path / "config.yaml"))

    @cached_property
    def other_code(self) -> str | None:
        """The digest of tavc's code that computed the run's trials (its `provenance.json` records
        it: the simulator's, or the surrogate's, "<digest> (the surrogate's)") where it is not this
        tavc's: the run's numbers are that code's, and running it again gives this code's. None
        where it is this tavc's, or where the run records none."""
        return run_facts(self.path).other_code

    @property
    def claims(self) -> pd.DataFrame:
        """Every part of the chapter's claims, tested (claims.csv), with the column ``not_a_verdict``:
        why these verdicts are none, or "" where they are."""
        return self.table("claims").assign(not_a_verdict=self.not_a_verdict)

    @cached_property
    def plan(self) -> RunPlan:
        """The run's plan (`plan.json`): each controller's label, learner settings, trial count, seed
        code and schedule (its periods on the record's clock, when its trials start)."""
        return checked_plan(self.path / PLAN_FILE, from_yaml(self.path / "config.yaml"))

    def records(self, controller: str | None = None) -> list[TrialRecord]:
        """The raw record of every trial of the run (or of `controller`'s only), in file-name
        order: the files its `provenance.json` lists (a rerun with fewer trials leaves the
        others' files in `trials/`, and they are not this run's), each checked to be this run's
        own (`run_checks.read_trial`: a record missing, damaged, or of another configuration or
        seed is one line naming it). Of a run that did not finish (no `provenance.json`), the
        trials finished so far: each record in `trials/` of a trial its `config.yaml` and
        `plan.json` plan, under its own file name and the key this tavc's code gives it (a record
        of other settings or code, which resuming the run computes anew, is left out; a learner
        from outside tavc enters its keys by its code as it is now, where its files are found
        from here (`run_provenance.digest_now`); where they are not, and on the surrogate, whose
        keys hold the tasks it drew, every planned trial's file is taken as it is; a file that
        cannot be read is left out too). Records
        that declare more arrays together than this machine has memory are refused: of a finished
        run before any is read; of one that did not finish, whose files are known to be its own
        only once read, as soon as those it keeps and the next would."""
        if not (self.path / "provenance.json").is_file():
            return self._finished_so_far(controller)
        listed = sorted(read_provenance(self.path / "provenance.json")["trials"], key=lambda t: t["file"])
        if controller is not None:
            listed = [t for t in listed if t["controller"] == controller]
            if not listed:
                raise TavcError(f"{self.path}: no trials of {controller} to read")
        if not any((self.path / t["file"]).is_file() for t in listed):  # a folder kept without trials/
            raise TavcError(_NO_RECORDS.format(self.path))
        _check_memory(self.path, [self.path / t["file"] for t in listed], controller)
        return [read_trial(self.path, t) for t in listed]

    def _finished_so_far(self, controller: str | None) -> list[TrialRecord]:
        """`records` of a run that did not finish (see there)."""
        present = sorted((self.path / "trials").glob("*.npz"))
        if not present:
            raise TavcError(_NO_RECORDS.format(self.path))
        owned, plan = read_owned(self.path), self.plan
        try:  # a surrogate run's keys hold the digest of the tasks it drew, which its folder does not keep
            surrogate = owned is not None and owned.kind == SURROGATE
            keys = None if surrogate else keys_of(from_yaml(self.path / "config.yaml"), plan, None, digest_now)
        except TavcError:
            raise
        except Exception as exc:  # noqa: BLE001 - settings no run was made with: whatever fails in planning them
            raise damaged(self.path / "config.yaml", f"plans no run ({unreadable(exc)})") from None
        if controller is not None and controller not in [c.label for c in plan.controllers]:
            raise TavcError(f"{self.path}: no trials of {controller} to read")
        planned = {trial_path(self.path, c.label, j): (c.label, j) for c in plan.controllers
                   for j in range(c.trials) if controller in (None, c.label)}
        memory, held, records = physical_memory(), 0, []
        for path in (f for f in present if f in planned):
            size = _declared(path)
            if held + size > memory:  # counting only the records kept: one of other settings is not
                _refuse_memory(self.path, len(records) + 1, held + size, memory, controller)
            try:
                record = load_record(path)
            except TavcError:  # damaged, or of an earlier version's format: resuming the run computes it anew
                continue
            trial = planned[path]
            if (record.meta.get("controller"), record.meta.get("trial")) == trial and (
                    keys is None or record.meta.get("key") == keys[trial]):
                records.append(record)
                held += size
        if not records:
            raise TavcError(f"{self.path}: no trial of its run has finished yet"
                            + (f" for {controller}" if controller is not None else ""))
        return records

    def events(self, kind: str, controller: str | None = None) -> pd.DataFrame:
        """Every event of one kind (arrivals, deliveries, choices, breakdowns) of every trial (or of
        `controller`'s only) `records` gives, with the trial's controller and number as the first
        columns."""
        if kind not in TABLES:
            raise TavcError(f"events: no kind {kind!r}; one of {', '.join(TABLES)}")
        frames = []
        for rec in self.records(controller):
            frame = pd.DataFrame(rec.table(kind))
            frame.insert(0, "trial", rec.meta["trial"])
            frame.insert(0, "controller", rec.meta["controller"])
            frames.append(frame)
        return pd.concat(frames, ignore_index=True)


_NO_RECORDS = "{}: no trial records in trials/ (tables only: rerun with tavc run to get the events)"


def _check_memory(folder: Path, files: list[Path], controller: str | None) -> None:
    """Refuse records whose arrays, as their archives declare them, would not fit in this
    machine's memory together."""
    total = sum(_declared(path) for path in files)
    if total > physical_memory():
        _refuse_memory(folder, len(files), total, physical_memory(), controller)


def _declared(path: Path) -> int:
    """Bytes of arrays the record at `path` declares (`readers.record_size`); a file that cannot
    be read counts for nothing here: reading it is `load_record`'s to refuse."""
    try:
        return record_size(path)
    except Exception:  # noqa: BLE001 - missing or damaged: `load_record` names it
        return 0


def _refuse_memory(folder: Path, count: int, total: int, memory: float, controller: str | None) -> None:
    """One line: `count` of `folder`'s records declare `total` bytes of arrays, more than `memory`."""
    advice = ("read one controller's at a time (records(controller), events(kind, controller))"
              if controller is None else "read them on a machine with more")
    raise TavcError(f"{folder}: its {count} trial records{'' if controller is None else ' of ' + controller} "
                    f"declare {total / 2**30:,.1f} GiB of arrays, more than this machine's "
                    f"{memory / 2**30:,.1f} GiB of memory; {advice}")


def load(path: str | Path) -> Results:
    """Open a results folder (one experiment's, as `tavc run` writes it)."""
    return Results(path)


class Sweep:
    """A sweep's folder (as `tavc run -m` writes it): its table `sweep.csv` and each job's results."""

    def __init__(self, path: str | Path) -> None:
        """Open the sweep at `path`; fails in one line unless it holds a `sweep.csv`."""
        self.path = path_of(path, "path")
        if not (self.path / "sweep.csv").is_file():
            raise TavcError(f"{self.path}: not a sweep's folder of tavc run -m (no sweep.csv in it)")

    def __repr__(self) -> str:
        """``Sweep('<path>')``."""
        return f"Sweep({str(self.path)!r})"

    @cached_property
    def table(self) -> pd.DataFrame:
        """`sweep.csv`: one row per job and state: the job's index, its swept values, its folder
        (`output_dir`), its time in each state and its score; checked against its jobs' own tables
        (`run_tables.checked_sweep`: a job run again since, or the table edited, is one line)."""
        return checked_sweep(self.path / "sweep.csv")

    @property
    def jobs(self) -> dict[str, Results]:
        """Each job's results, by its folder's name (``0_learner.epsilon=0.05`` ...), in sweep order."""
        recorded = list(dict.fromkeys(str(folder) for folder in self.table["output_dir"]))
        return {Path(r).name: Results(job_folder(self.path / "sweep.csv", r)) for r in recorded}


def load_sweep(path: str | Path) -> Sweep:
    """Open a sweep's folder (`tavc run -m`): `Sweep.table` is its sweep.csv, `Sweep.jobs` each job's results."""
    return Sweep(path)
