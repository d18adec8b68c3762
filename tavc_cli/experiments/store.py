"""One results folder's trial records: which are done, running the rest, loading them.

`TrialStore` is what `tavc run`, `tavc model` and `tavc calibrate` all run trials through.
Given trial specs it
1. reuses every trial whose file exists whole (every byte read and checked against the
   archive's checksums) with a matching key (a digest of everything that fixes its outcome,
   seed included); a damaged file is named and its trial run again;
2. groups the rest into batches (`build.make_batches`) and runs them on the executor
   (`Executor`: a local process pool, or a Dask or Ray cluster, `executors`), each
   trial's file written atomically as its batch finishes (a stopped run loses at most
   the batches in flight);
3. reports progress over the simulated seconds (`pool`, which also runs the local process pool);
4. contains failures: a trial that goes wrong (a pose that is not a number, a robot outside
   the walls, an exception in its simulation) is named with its seed and left out, every
   other trial finishes and is kept, and the run then stops with one line naming it
   (`failures.log` in the folder holds the details). Rerunning computes only what is missing.
"""

from __future__ import annotations

import json
import time
import zipfile
from collections.abc import Callable, Iterable, Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from tavc_cli.confine import confinement
from tavc_cli.errors import TavcError
from tavc_cli.experiments.build import Batch, foreign, make_batches
from tavc_cli.experiments.contained import BatchResult, TrialFailure, simulate_contained
from tavc_cli.experiments.executors import probe, run_on_cluster
from tavc_cli.experiments.pool import Progress, run_pool
from tavc_cli.experiments.records import ARRAY_FIELDS, TABLES, TrialRecord
from tavc_cli.experiments.spec import TrialSpec
from tavc_cli.io import owned_path, write_text_atomic
from tavc_cli.ownership import trial_path
from tavc_cli.readers import RECORD_LIMIT
from tavc_cli.settings import ExecutorConfig

FAILURES_LOG = "failures.log"


@dataclass(frozen=True)
class Executor:
    """Where trials run: `backend` local (processes), dask or ray; `n_jobs` workers of a local
    pool or cluster; `batch_size` trials advanced together in one process; `address` of an
    existing cluster (none: a local one is started); `confine` whether a learner from outside
    tavc runs held to its run's folder (`executor.confine`)."""

    backend: str = "local"
    n_jobs: int = 1
    batch_size: int = 8
    address: str | None = None
    confine: str = "auto"

    @classmethod
    def from_config(cls, executor: ExecutorConfig) -> Executor:
        """From the resolved `executor` settings."""
        return cls(str(executor.backend), int(executor.n_jobs), int(executor.batch_size), executor.address,
                   str(executor.confine))

    def confine_to(self, specs: Iterable[TrialSpec], folders: Sequence[Path]) -> list[Path]:
        """The folders the processes running these trials are held to (`pool.run_pool`):
        `folders` where a trial runs a learner from outside tavc and `confine` asks for it where
        this system can (`confine.confinement`), else none."""
        return list(folders) if foreign(specs) and confinement(self.confine, self.backend) else []

    def check(self) -> None:
        """Stop with one line, before anything is written, if the cluster at `address` does not
        answer."""
        if self.backend != "local":
            probe(self.backend, self.address)


class TrialStore:
    """The trial records of one results folder (`<folder>/trials/<controller>_<trial>.npz`)."""

    def __init__(self, folder: Path, executor: Executor) -> None:
        """A store over `folder`, running trials on `executor`."""
        self.folder = Path(folder)
        self.executor = executor

    def path(self, spec: TrialSpec) -> Path:
        """Where the record of `spec`'s trial is saved."""
        return trial_path(self.folder, spec.controller, spec.trial)

    def done(self, spec: TrialSpec) -> bool:
        """True if the trial's file exists and was made from this exact spec and seed."""
        return trial_done(self.folder, spec)

    def run(self, specs: Sequence[TrialSpec], progress: bool = False, announce: bool = False) -> int:
        """Run every trial of `specs` that is not done; return how many were reused."""
        ex = self.executor
        self.check_paths(specs)
        pending, n_reused, redone = pending_batches(self.folder, list(specs), ex.batch_size, ex.n_jobs)
        if announce:
            self.announce(len(specs), n_reused, redone)
        if ex.backend == "local":
            confine_to = ex.confine_to(trials_of(pending), [self.folder])
            failures = execute(pending, self.folder, ex.n_jobs, progress, confine_to)
        else:
            failures = _execute_on_cluster(ex, pending, self.folder, progress)
        self.settle(failures, len(specs))
        return n_reused

    def check_paths(self, specs: Sequence[TrialSpec]) -> None:
        """Stop with one line, before any record is read or written, if anything is in the way.

        In the way: a file or folder where a trial's record goes, or a link, a pipe or a device
        as trials/ or a record (`io.owned_path`): records are read and written only inside the
        results folder.
        """
        trials, records = self.folder / "trials", list(map(self.path, specs))
        if trials.is_file() and not trials.is_symlink():
            raise _stands(trials, "file")
        owned_path(self.folder, trials, folder=True)
        for path in records:
            if path.is_dir() and not path.is_symlink():
                raise _stands(path, "folder")
            owned_path(self.folder, path)

    def announce(self, n_specs: int, n_reused: int, redone: dict[str, list[str]]) -> None:
        """Say how many finished trials are reused, and which files are there but run again:
        because they could not be read whole, or were made with other settings or another
        version of the simulator (`pending_batches`)."""
        if n_reused:
            print(f"reusing {n_reused} of {n_specs} finished trials in {self.folder / 'trials'}", flush=True)
        for why, names in redone.items():
            if names:
                print(f"note: {len(names)} trial files in {self.folder / 'trials'} {why} ({', '.join(names[:3])}"
                      f"{', ...' if len(names) > 3 else ''}); running those trials again", flush=True)

    def settle(self, failures: list[TrialFailure], n_specs: int) -> None:
        """Record the failed trials in `failures.log` and stop with one line naming the first.
        With none, the log an earlier run left is removed by whoever knows it is tavc's: the
        pipeline, through `ownership`."""
        log = self.folder / FAILURES_LOG
        if not failures:
            return
        failures = sorted(failures, key=lambda f: (f.controller, f.trial))  # not the order batches finished in
        write_text_atomic(log, "\n\n".join(f.report() for f in failures) + "\n")
        first = failures[0]
        what = f"trial {first.name} (seed {list(first.seed)}) failed"
        if len(failures) > 1:
            what = f"{len(failures)} trials failed, the first {first.name} (seed {list(first.seed)})"
        raise TavcError(f"{what}: {first.message}; the other {n_specs - len(failures)} trials are kept in "
                        f"{self.folder / 'trials'} and a rerun computes only the missing ones (details: {log})")

    def load(self, specs: Sequence[TrialSpec]) -> list[TrialRecord]:
        """The records of trials that are done, each read only once its key is the spec's and its
        arrays, as it declares them, at most `RECORD_LIMIT` bytes (`_stored_key`): a record
        put in its place since it was written (by the code that ran the trial) is one line."""
        self.check_paths(specs)  # read nothing through a link either
        for spec in specs:
            if _stored_key(self.path(spec), limited=True) != spec.key():
                raise _not_its_record(self.path(spec), "another trial's, damaged, or larger than tavc reads")
        return [_checked_record(self.path(s), s) for s in specs]


def _not_its_record(path: Path, why: str) -> TavcError:
    return TavcError(f"{path} is not the record its trial wrote ({why}); run the same command again to compute it anew")


def _checked_record(path: Path, spec: TrialSpec) -> TrialRecord:
    """The record at `path` of `spec`'s trial, every array a record holds there, each a flat
    array of numbers, its indices never negative and its robots and circuits the trial's (the
    analysis reads nothing else): one line naming the file otherwise."""
    try:
        rec = TrialRecord.load(path)
    except Exception as error:  # noqa: BLE001 - numpy's or zipfile's: the file is not a whole record
        raise _not_its_record(path, f"{type(error).__name__}: {error}") from None
    columns = [a for table in rec.tables.values() for a in table.values()]
    arrays = [getattr(rec, name) for name in ARRAY_FIELDS]
    if not all(isinstance(a, np.ndarray) and a.dtype.kind in "biuf" for a in (*columns, *arrays)) \
            or not all(a.ndim == 1 for a in columns):
        raise _not_its_record(path, "an array that is not of numbers, or a column that is not flat")
    bounds = {"robot": spec.n_robots, "circuit": len(spec.values)}
    for table in rec.tables.values():
        for name, a in table.items():
            if a.dtype.kind in "iu" and len(a) and (a.min() < 0 or a.max() >= bounds.get(name, np.inf)):
                raise _not_its_record(path, f"a {name} that is no {name} of its trial")
    return rec


def _stands(path: Path, what: str) -> TavcError:
    return TavcError(f"{path}: a {what} stands where tavc writes its trial records; move it away")


# the members every trial record holds (`TrialRecord.save`)
_MEMBERS = frozenset({"meta.npy", *(f"{name}.npy" for name in ARRAY_FIELDS),
                      *(f"{name}__{col}.npy" for name, cols in TABLES.items() for col in cols)})


def _stored_key(path: Path, whole: bool = False, limited: bool = False) -> str | None:
    """The key a trial record was made with; None if the file is missing or cannot be read.
    With `whole`, every byte of the record is read and checked against the checksums the
    archive keeps of each array (zip's CRC-32), every array a record holds must be there, and
    every member must read as an array (one can be whole to zip yet not an array), at most
    `RECORD_LIMIT` bytes of them: a file damaged anywhere, not only in its header, gives None.
    With `limited`, only the last: its arrays, as the archive declares them, within the limit."""
    try:
        with zipfile.ZipFile(path) as archive:
            members = archive.infolist()
            if (whole or limited) and sum(m.file_size for m in members) > RECORD_LIMIT:
                return None
            if whole and (not _MEMBERS <= {m.filename for m in members} or archive.testzip() is not None):
                return None
        with np.load(path, allow_pickle=False) as data:
            key = json.loads(str(data["meta"])).get("key")
            if whole and not all(isinstance(data[name], np.ndarray) for name in data.files):
                return None  # a member that is not an array (NumPy hands its bytes back as they are)
            return key
    except Exception:  # missing, truncated, damaged or foreign: the trial is simply run again
        return None


def trial_done(out_dir: Path, spec: TrialSpec) -> bool:
    """True if the trial's file exists, is whole, and was made from this exact spec and seed."""
    return _stored_key(trial_path(out_dir, spec.controller, spec.trial), whole=True) == spec.key()


DAMAGED, OTHER = "are damaged or unreadable", "were made with other settings or another version of the simulator"


def pending_batches(out_dir: Path, specs: list[TrialSpec], batch_size: int,
                    workers: int = 1) -> tuple[list[Batch], int, dict[str, list[str]]]:
    """Batches of the trials still to run, how many finished trials are reused, and the names
    of the files among those to run that are there, by why they are run again (`DAMAGED`:
    they could not be read whole; `OTHER`: their key is not the spec's). Each file is read
    once, to its last byte: a reused trial is one the analysis can read."""
    todo, redone = [], {DAMAGED: [], OTHER: []}
    for spec in specs:
        path = trial_path(out_dir, spec.controller, spec.trial)
        key = _stored_key(path, whole=True)
        if key == spec.key():
            continue
        todo.append(spec)
        if path.exists():
            redone[DAMAGED if key is None else OTHER].append(path.name)
    return make_batches(todo, batch_size, workers), len(specs) - len(todo), redone


def run_batch(batch: Batch, out_dir: str | Path,
              report: Callable[[float], None] | None = None) -> tuple[float, list[TrialFailure]]:
    """Simulate one batch and write the files of its trials that finished; returns the wall
    time (s) and the trials that failed."""
    start = time.perf_counter()
    failures = save_result(simulate_contained(batch.specs, report), out_dir)
    return time.perf_counter() - start, failures


def save_result(result: BatchResult, out_dir: str | Path) -> list[TrialFailure]:
    """Write a batch's finished trial files into out_dir, each atomically; return its failures."""
    done, failures = result
    for spec, rec in done:
        save_record(rec, spec, out_dir)
    return failures


def save_record(rec: TrialRecord, spec: TrialSpec, out_dir: str | Path) -> None:
    """Write a trial's record atomically into `out_dir`'s trials/ (`TrialRecord.save`).

    Never through a link there: trials/ and the record are checked below `out_dir` (`io.owned_path`).
    """
    rec.save(owned_path(Path(out_dir), trial_path(Path(out_dir), spec.controller, spec.trial)))


def trials_of(batches: Iterable[Batch]) -> Iterator[TrialSpec]:
    """Every trial the batches start as."""
    return (spec for b in batches for spec in b.specs)


def execute(pending: list[Batch], out_dir: Path, n_jobs: int, shown: bool,
            confine_to: Sequence[Path] = ()) -> list[TrialFailure]:
    """Run pending batches in this process (n_jobs 1 or a single batch) or a process pool,
    held to `confine_to` where it names folders (`pool.run_pool`); return the trials that failed."""
    return run_pool([(b, run_batch, (b, str(out_dir))) for b in pending], n_jobs, shown, confine_to)


def _execute_on_cluster(ex: Executor, pending: list[Batch], out_dir: Path, shown: bool) -> list[TrialFailure]:
    """Run pending batches on a Dask or Ray cluster (`executors`); this process writes the files.
    Returns the trials that failed."""
    if not pending:
        return []
    prog = Progress(pending, shown)
    failures: list[TrialFailure] = []

    def save(batch: Batch, result: BatchResult) -> None:
        failures.extend(save_result(result, out_dir))
        prog.update((batch.controller, batch.index), 1.0)

    try:
        run_on_cluster(ex.backend, pending, save, ex.n_jobs, ex.address)
    finally:
        prog.close()
    return failures
