"""A run of an experiment on the surrogate: its tasks measured (or reused), its trials drawn, and
the same tables, claims and provenance as `tavc run` writes, in a folder of its own kind."""

from __future__ import annotations

import hashlib
import json
import multiprocessing as mp
import os
import time
from collections.abc import Callable, Sequence
from concurrent.futures import ProcessPoolExecutor
from concurrent.futures.process import BrokenProcessPool
from dataclasses import asdict, is_dataclass, replace
from pathlib import Path

import pandas as pd

from tavc_cli.confined import run_units
from tavc_cli.errors import TavcError
from tavc_cli.experiments.build import trial_specs
from tavc_cli.experiments.plan import RunPlan, plan_run
from tavc_cli.experiments.pool import stop_workers, worker_start
from tavc_cli.experiments.runner import Run
from tavc_cli.experiments.spec import code_digest
from tavc_cli.experiments.store import Executor, TrialStore, _stored_key
from tavc_cli.io import claim_folder, default_root, write_bytes_atomic, write_text_atomic
from tavc_cli.ownership import SURROGATE, TASKS, TASKS_FILES, refuse_other_settings, take, trial_path
from tavc_cli.pipeline import CAN_FORK, _finish, check_run_folder, take_run_folder
from tavc_cli.readers import TABLE_LIMIT, load_json, read_bounded
from tavc_cli.settings import TavcConfig
from tavc_cli.settings_studies import ALTERNATORS, EXPLORERS
from tavc_cli.surrogate.digest import surrogate_code_digest, surrogate_engine
from tavc_cli.surrogate.engine import run_trial
from tavc_cli.surrogate.explorers import (
    explore_trials,
    explorer_record,
    explorer_specs,
    explorer_tasks,
    explorers_code,
    with_explorers,
)
from tavc_cli.surrogate.tasks import (
    COLUMNS,
    TaskTimes,
    Team,
    makeups,
    measurement,
    measurement_specs,
    roles_of,
    tasks_of,
    teams_needed,
)


def tasks_dir(cfg: TavcConfig) -> Path:
    """Where the measured tasks are kept: `surrogate.tasks_dir`; else, for a run in its default
    folder (runs/<scale>/surrogate/<experiment>), runs/<scale>/surrogate/tasks, shared by the
    scale's runs there; else `tasks/` in the run's own folder, so that a run in a folder the user
    named writes nothing outside it."""
    given = cfg.surrogate.tasks_dir
    if given:
        return Path(given)
    shared = default_root(cfg.scale.name) / "surrogate"
    out = Path(cfg.output_dir)
    return shared / "tasks" if out == shared / cfg.experiment_name else out / "tasks"


def check_tasks_place(cfg: TavcConfig) -> None:
    """Refuse, before anything is measured, measured tasks that would share a folder with the run:
    they go in the run's own ``tasks/`` (`tasks_dir`'s default) or outside the run's folder, never
    in the run's folder itself, elsewhere inside it, or in a folder that holds it."""
    run, tasks = (Path(os.path.abspath(p)) for p in (cfg.output_dir, tasks_dir(cfg)))
    where = ("is the run's folder (output_dir)" if tasks == run
             else "holds the run's folder (output_dir)" if tasks in run.parents
             else "is inside the run's folder (output_dir), where only its tasks/ may be" if run in tasks.parents
             and tasks != run / "tasks" else None)
    if where:
        raise TavcError(f"surrogate.tasks_dir: {tasks_dir(cfg)} {where}; the measured tasks need a folder of their "
                        f"own: leave it unset ({run / 'tasks'}) or name one outside {run}")


def surrogate_supports(cfg: TavcConfig) -> None:
    """Refuse, in one line, what the surrogate does not model."""
    if len(cfg.arena.circuits) != 2:
        raise TavcError("surrogate: models task choices between two circuits; this arena has "
                        f"{len(cfg.arena.circuits)} (section 1.4's experiment learns behaviours, not tasks)")
    if cfg.tasks.time_from != "choice":
        raise TavcError("surrogate: draws whole tasks and rewards them over the whole task (tasks.time_from=choice); "
                        f"tasks.time_from={cfg.tasks.time_from} is not modelled")
    if cfg.learner.name == "behaviour_softmax":
        raise TavcError("surrogate: learner behaviour_softmax learns behaviours, not tasks; the surrogate draws "
                        "whole tasks")


def measurement_record(cfg: TavcConfig) -> dict:
    """What `task_times.json` records of how the tasks were measured: a table of other
    settings is not extended or mixed, but refused (`overwrite=true` replaces it)."""
    trials, warmup_s, measure_s = measurement(cfg)
    taken = {"trials_per_makeup": trials, "warmup_s": warmup_s, "measure_s": measure_s, "seed": int(cfg.seed)}
    if cfg.surrogate.switches == EXPLORERS:  # a table of the alternators alone records nothing of them
        taken.update(explorer_record(cfg))
    return {"measurement": taken, "world": {"arena": cfg.arena.name, "robot": _plain(cfg.robot)}}


def _plain(obj) -> object:
    return json.loads(json.dumps(asdict(obj) if is_dataclass(obj) else obj, default=str))


def measure_tasks(cfg: TavcConfig, teams: list[Team] | None = None, *, progress: bool = False,
                  echo: Callable[[str], None] = print) -> TaskTimes:
    """Measure (or reuse) every make-up of the teams the experiment can have (`teams`: these
    instead) in `tasks_dir`, and return the table of the tasks of those teams. The folder's
    `task_times.csv` keeps the tasks of every team measured there with the same settings and
    code (`kept_tasks`); a table that cannot be trusted is measured again."""
    if teams is None:
        team = Team.of(tuple(m.group for m in cfg.team.members), tuple(m.speed_mps for m in cfg.team.members))
        teams = teams_needed(team, len(cfg.events.breakdowns))
    folder = tasks_dir(cfg)
    plan = measurement_specs(cfg, teams)
    explorers = explorer_specs(cfg, teams) if cfg.surrogate.switches == EXPLORERS else {}
    trials, warmup_s, measure_s = measurement(cfg)
    record = measurement_record(cfg)
    # in the run's own folder (`tasks_dir`), a link there is refused, not followed
    inside = None if cfg.surrogate.tasks_dir or folder.parent != Path(cfg.output_dir) else folder.parent
    with claim_folder(folder, within=inside):
        # every file of TASKS_FILES already there is tavc's: `take` refuses one it did not write
        owned = take(folder, TASKS, TASKS_FILES, "surrogate.tasks_dir", save=False)
        kept = kept_tasks(folder, record, overwrite=cfg.overwrite, echo=echo)
        wanted = {t.name for t in teams}
        have = set(kept["team"].unique()) if len(kept) else set()
        if wanted <= have:
            return TaskTimes(kept[kept["team"].isin(wanted)].reset_index(drop=True))
        owned.wrote(*TASKS_FILES)
        owned.remove_temporaries()
        specs = [s for group in (*plan.values(), *explorers.values()) for s in group]
        n_makeups = len(plan)
        echo(f"surrogate: measuring {n_makeups} make-ups of {len(teams)} team(s) in the simulator, {trials} static "
             f"trials of {warmup_s + measure_s:g} s each"
             + (f", and {len(explorers)} allocations of stayers with explorers, {explore_trials(cfg)} trials each"
                if explorers else "") + f", into {folder}")
        executor = Executor.from_config(cfg.executor)
        store = TrialStore(folder, executor)
        store.run(specs, progress)
        frames = []
        by_name = {t.name: t for t in teams}
        for (team_name, makeup), group in plan.items():
            team = by_name[team_name]
            _, _, roles = roles_of(team, makeup)
            for rec in store.load(group):
                frames.append(tasks_of(rec, team, makeup, roles, warmup_s, measure_s))
        fresh = pd.concat(frames, ignore_index=True)
        if explorers:
            exploring = pd.concat([explorer_tasks(rec, by_name[team_name], warmup_s, measure_s)
                                   for (team_name, _), group in explorers.items() for rec in store.load(group)],
                                  ignore_index=True)
            fresh = with_explorers(fresh, exploring, int(cfg.surrogate.explore_min_tasks))
        table = pd.concat([kept[~kept["team"].isin(wanted)], fresh], ignore_index=True) if len(kept) else fresh
        write_tasks(folder, table, record, teams)
        written = TaskTimes.read(folder / "task_times.csv").frame
        return TaskTimes(written[written["team"].isin(wanted)].reset_index(drop=True))


def write_tasks(folder: Path, table: pd.DataFrame, record: dict, teams: list[Team]) -> None:
    """Write the measured tasks in `folder`, each file atomically: `task_times.csv`, its summary,
    then `task_times.json` last, which records the settings (`record`), the code that measured
    them (the simulator's `code_digest`, the surrogate's `surrogate_code_digest`) and the
    SHA-256 of the `task_times.csv` written, so that a table edited, cut, or left beside the
    record of another measurement is told from the one tavc wrote (`kept_tasks`)."""
    data = table.to_csv(index=False, float_format="%.6g").encode()
    write_bytes_atomic(folder / "task_times.csv", data)
    write_text_atomic(folder / "task_times_summary.csv", task_summary(table).to_csv(index=False, float_format="%.4f"))
    write_text_atomic(folder / "task_times.json", json.dumps(
        {**record, "code_digest": code_digest(), "surrogate_code_digest": surrogate_code_digest(),
         **({"explorers_code": explorers_code()} if _switches(record) == EXPLORERS else {}),
         "task_times_sha256": hashlib.sha256(data).hexdigest(), "teams": sorted(table["team"].unique().tolist()),
         "makeups": {t.name: len(makeups(t)) for t in teams}}, indent=2))


class _Untrusted(Exception):
    """Why the tasks a folder keeps are not drawn from (`kept_tasks`): the reason, in a few words."""


def kept_tasks(folder: Path, record: dict, *, overwrite: bool, echo: Callable[[str], None] = print) -> pd.DataFrame:
    """The tasks `folder` keeps that may be drawn from, else an empty table (none kept, or
    `overwrite`). A record of other settings than `record` is refused in one line (unless
    `overwrite`); a table that cannot be trusted (`_trusted_table`) is named in one `note:` line
    through `echo` and not used, so that the tasks are measured again."""
    empty = pd.DataFrame(columns=list(COLUMNS))
    if overwrite:
        return empty
    try:
        return _trusted_table(folder, record)
    except _Untrusted as why:
        echo(f"note: {why}; measuring the tasks again")
        return empty


def _trusted_table(folder: Path, record: dict) -> pd.DataFrame:
    """The table of `task_times.csv` in `folder` (empty where there is none), once its record
    says it was measured with these settings (else refused) and today's code, and its bytes are
    the ones that record was written with; raises `_Untrusted` naming the file and why otherwise."""
    table_path, record_path = folder / "task_times.csv", folder / "task_times.json"
    if not table_path.is_file() and not record_path.is_file():
        return pd.DataFrame(columns=list(COLUMNS))
    if not record_path.is_file():
        raise _Untrusted(f"{table_path} has no task_times.json beside it to say how and by which code it was measured")
    try:
        kept = load_json(record_path)
    except (OSError, ValueError, TavcError):
        kept = None
    if not isinstance(kept, dict):
        raise _Untrusted(f"{record_path} cannot be read as the record of the measured tasks")
    allow = "add overwrite=true to measure them again, or choose another surrogate.tasks_dir"
    refuse_other_settings(record_path, record, "surrogate.tasks_dir", False, allow=allow)
    # a key only one record has is no difference there: the alternators' tables record no `switches`
    had, want = (_switches(r) for r in (kept, record))
    if had != want:
        raise TavcError(f"surrogate.tasks_dir: {record_path} was made with other settings (measurement.switches: "
                        f"{had} -> {want}); {allow}")
    if not table_path.is_file():
        return pd.DataFrame(columns=list(COLUMNS))  # a record alone (results/ keeps no table): nothing to draw from
    digests = [("code_digest", code_digest()), ("surrogate_code_digest", surrogate_code_digest())]
    if want == EXPLORERS:
        digests.append(("explorers_code", explorers_code()))
    for key, today in digests:
        recorded = kept.get(key)
        if recorded != today:
            said = f"no {key}" if recorded is None else f"another {key} ({recorded}; this tavc's is {today})"
            raise _Untrusted(f"{record_path} records {said}: its tasks were measured by other code")
    try:  # a regular file no larger than any table tavc reads
        data = read_bounded(table_path, TABLE_LIMIT)
    except TavcError as error:  # its path and why, without the advice: the note gives its own
        raise _Untrusted(str(error).rpartition("; ")[0]) from None
    except OSError as error:
        raise _Untrusted(f"{table_path} cannot be read ({error.strerror})") from None
    if hashlib.sha256(data).hexdigest() != kept.get("task_times_sha256"):
        raise _Untrusted(f"{table_path} does not match the digest task_times.json recorded (edited or cut)")
    try:
        return TaskTimes.read(table_path).frame
    except TavcError:
        raise _Untrusted(f"{table_path} cannot be read as measured tasks") from None


def _switches(record: dict) -> str:
    """How a record's lone switchers were measured (`surrogate.switches`; none recorded: alternators)."""
    measured = record.get("measurement")
    return str(measured.get("switches", ALTERNATORS)) if isinstance(measured, dict) else ALTERNATORS


def task_summary(table: pd.DataFrame) -> pd.DataFrame:
    """Per cell of the measured tasks (team, make-up, group, kind, circuit): how many, the mean,
    spread and deciles of their times, and the mean seconds of each activity."""
    keys = ["team", "makeup", "group", "kind", "circuit"]
    grouped = table.groupby(keys, sort=False)
    out = grouped["task_time_s"].agg(n="size", mean_s="mean", std_s="std")
    for q in (0.1, 0.5, 0.9):
        out[f"p{int(q * 100)}_s"] = grouped["task_time_s"].quantile(q)
    means = grouped[[c for c in table.columns if c.endswith("_s") and c != "task_time_s"]].mean()
    return out.join(means.add_prefix("mean_")).reset_index()


def tasks_digest(times: TaskTimes) -> str:
    """A digest of the tasks a run draws from: part of its trials' keys."""
    text = times.frame.to_csv(index=False, float_format="%.6g")
    return hashlib.sha256(text.encode()).hexdigest()[:12]


def surrogate_specs(cfg: TavcConfig, times: TaskTimes, plan: RunPlan | None = None) -> list:
    """The experiment's trials (`trial_specs` of its `plan`: the same controllers, seeds and events), computed
    by the surrogate: their engine names the calibration, the tasks drawn from and the
    surrogate's code (`surrogate_code_digest`), all three in each trial's key."""
    engine = surrogate_engine(str(cfg.surrogate.calibration), tasks_digest(times), surrogate_code_digest())
    return [replace(s, engine=engine) for s in trial_specs(cfg, plan)]


def run_surrogate(cfg: TavcConfig, *, times: TaskTimes | None = None, progress: bool = False,
                  echo: Callable[[str], None] = print) -> dict:
    """An experiment on the surrogate into `cfg.output_dir`: tasks measured or reused (or `times`,
    measured for another run's settings: each trial's key holds their digest), trials drawn (a
    finished one of the same key reused), then the tables, claims and provenance of `tavc run`.
    Returns the run's summary, as `pipeline.run_experiment` does."""
    surrogate_supports(cfg)
    folder = Path(cfg.output_dir)
    if times is None:
        check_tasks_place(cfg)
        if folder.exists() or folder.is_symlink():  # checked before its tasks are measured, into it or elsewhere
            with claim_folder(folder):
                check_run_folder(cfg, SURROGATE)
        times = measure_tasks(cfg, progress=progress, echo=echo)
    plan = plan_run(cfg)
    specs = surrogate_specs(cfg, times, plan)
    stayers = cfg.surrogate.calibration == "stayers"
    with claim_folder(folder):
        owned = take_run_folder(cfg, plan, SURROGATE)
        start = time.perf_counter()
        paths = [trial_path(folder, spec.controller, spec.trial) for spec in specs]
        pending = [(spec, path) for spec, path in zip(specs, paths, strict=True)
                   if _stored_key(path, whole=True) != spec.key()]
        executor = Executor.from_config(cfg.executor)
        _draw_trials(pending, times, stayers, executor.n_jobs, executor.confine_to((s for s, _ in pending), [folder]))
        records = TrialStore(folder, executor).load(specs)  # each under its key, as the simulator's are read back
        run = Run(folder, plan, specs, records, len(specs) - len(pending), time.perf_counter() - start)
        summary = _finish(cfg, run, owned)
    return {**summary, "engine": f"the surrogate (surrogate.calibration={cfg.surrogate.calibration}, "
                                 f"surrogate.switches={cfg.surrogate.switches}; "
                                 f"tasks measured in the simulator: {tasks_dir(cfg)})"}


_SHARED: dict = {}  # what forked workers draw trials with (`_draw_trials`)


def _draw_one(k: int) -> None:
    spec, path = _SHARED["pending"][k]
    rec = run_trial(spec, _SHARED["times"], stayers=_SHARED["stayers"])
    rec.meta["engine"] = spec.engine
    rec.save(path)


def _draw_trials(pending: list, times: TaskTimes, stayers: bool, n_jobs: int, confine_to: Sequence[Path] = ()) -> None:
    """Draw and save the pending trials: in this process, or in `n_jobs` forked ones where
    the system forks and there are trials for more than one (each trial is its own seed's, so
    the processes change nothing but the time); where `confine_to` names folders, always in
    forked ones (one at least) that can write only beneath them and answer in JSON
    (`confined.run_units`)."""
    _SHARED.update(pending=pending, times=times, stayers=stayers)
    try:
        if confine_to:
            run_units(len(pending), n_jobs, confine_to, lambda k, report: _draw_one(k), lambda k, frac: None,
                      lambda k: pending[k][1].stem)  # a trial named as its record is
            return
        if n_jobs <= 1 or len(pending) <= 1 or not CAN_FORK:
            for k in range(len(pending)):
                _draw_one(k)
            return


        pool = ProcessPoolExecutor(max_workers=min(n_jobs, len(pending)), mp_context=mp.get_context("fork"),
                                   initializer=worker_start)
        try:
            for future in [pool.submit(_draw_one, k) for k in range(len(pending))]:
                future.result()
        except BaseException as error:
            stop_workers(pool)
            if isinstance(error, BrokenProcessPool):
                raise TavcError("a worker process died while drawing the surrogate's trials (a learner that exits or "
                                "crashes, or out of memory); the trials finished before are kept and a rerun draws "
                                "only the missing ones") from None
            raise
        pool.shutdown(wait=True)
    finally:
        _SHARED.clear()
