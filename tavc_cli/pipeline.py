"""`tavc run` and `tavc reproduce` below the CLI: an experiment's trials (`experiments.runner`),
then its tables and claims (`analysis.experiment`), then its provenance, with the output
folder held by this run alone for the whole time."""

from __future__ import annotations

import multiprocessing as mp
from collections.abc import Iterator
from concurrent.futures import ProcessPoolExecutor
from contextlib import ExitStack, contextmanager
from pathlib import Path

from tavc_cli.analysis.claims import not_a_verdict
from tavc_cli.chapter import claims
from tavc_cli.errors import TavcError
from tavc_cli.experiments.build import trial_specs
from tavc_cli.experiments.joint import CAN_FORK
from tavc_cli.experiments.plan import PLAN_FILE, RunPlan, plan_run, write_plan
from tavc_cli.experiments.pool import stop_workers, worker_start
from tavc_cli.experiments.runner import (
    Run,
    load_records,
    made_by,
    run_experiment_trials,
    run_trials_together,
    write_provenance,
)
from tavc_cli.experiments.store import FAILURES_LOG, Executor, TrialStore
from tavc_cli.io import claim_folder, file_digest, write_text_atomic
from tavc_cli.outputs import write_analysis
from tavc_cli.ownership import LADDER, LADDER_FILES, RUN, SWEEP, SWEEP_FILES, Owned, config_differences, run_files, take
from tavc_cli.pictured import animation_differences
from tavc_cli.readers import YAML_LIMIT, load_json, read_text
from tavc_cli.run_checks import SECTIONS
from tavc_cli.run_tables import ladder_table, summary_text, sweep_table
from tavc_cli.settings import TavcConfig, from_yaml, to_yaml


def run_experiment(cfg: TavcConfig, *, progress: bool = False) -> dict:
    """Run (or reuse) every trial of the experiment and write all its outputs; return a summary
    with the tables and claims."""
    Executor.from_config(cfg.executor).check()
    with claim_folder(cfg.output_dir):
        plan = plan_run(cfg)
        owned = take_run_folder(cfg, plan)
        with _failures_listed([owned]):
            run = run_experiment_trials(cfg, plan, progress=progress)
        return _finish(cfg, run, owned)


def check_run_folder(cfg: TavcConfig, kind: str = RUN, plan: RunPlan | None = None) -> tuple[Owned, list[str]]:
    """What `take_run_folder` checks, writing nothing: the folder new, empty or tavc's, nothing of
    anybody else's in the way, not another configuration's run, nor (where no run is there) an
    animation of other settings (`pictured`), unless ``overwrite``; with `plan`, nothing where its
    trial records go (`TrialStore.check_paths`). Returns what tavc owns there and how a run or
    animation there differs from `cfg` (empty: none, or the same settings)."""
    folder = Path(cfg.output_dir)
    owned = take(folder, kind, run_files(), save=False)
    if plan is not None:
        TrialStore(folder, Executor.from_config(cfg.executor)).check_paths(trial_specs(cfg, plan))
    unknown, ran = recorded_config_problem(folder), (folder / "config.yaml").is_file()
    differ = config_differences(folder / "config.yaml", to_yaml(cfg)) if ran and not unknown else []
    if not ran and not unknown:  # no run there: what the animations there picture (`tavc animate`'s), if any
        unknown, differ = animation_differences(owned, to_yaml(cfg))
    differ = [unknown] if unknown else differ
    if differ and not cfg.overwrite:
        state = ("a finished run" if (folder / "provenance.json").is_file() else
                 "an unfinished run" if ran else "an animation")
        what = (f"whose {unknown}, so it may be of another configuration" if unknown else
                f"of another configuration ({'; '.join(differ)})")
        raise TavcError(f"output_dir: {folder} holds {state} {what}; add overwrite=true to replace it, or choose "
                        "another output_dir")
    return owned, differ


def take_run_folder(cfg: TavcConfig, plan: RunPlan, kind: str = RUN) -> Owned:
    """Check that the run may write its folder (`ownership.take`: new, empty or tavc's, nothing
    of anybody else's in the way, not another configuration's run unless ``overwrite``; nothing
    where its records go, `TrialStore.check_paths`) and write its `config.yaml` and its
    `plan.json`; return what tavc owns there. Replacing another configuration's
    run, the folder stops being a finished run (its `provenance.json` goes) and loses what tavc
    wrote there of that run beside its own files (an animation of it) before anything of the
    new one is written; so does a folder of animations of other settings."""
    folder = Path(cfg.output_dir)
    owned, differ = check_run_folder(cfg, kind, plan)
    text = to_yaml(cfg)
    owned.wrote("config.yaml", PLAN_FILE)
    owned.remove_temporaries()
    if differ or _recorded_text(folder / "config.yaml") != text:
        # the folder is a finished run only while its provenance.json vouches for the config.yaml
        # beside it: a rerun that changes even where or how fast it runs (`executor.*`, the
        # folder) first makes it an unfinished run, so that one stopped before its new
        # provenance.json leaves a folder the same command resumes, not one it refuses
        owned.remove("provenance.json")
    for name in sorted(owned.files - set(run_files())) if differ else ():
        owned.remove(name)  # what pictured other settings than this run's (`tavc animate`)
    write_text_atomic(folder / "config.yaml", text)
    write_plan(plan, folder)
    return owned


def _recorded_text(path: Path) -> str | None:
    """The text of a run's `config.yaml`, or None if there is none or it cannot be read."""
    try:
        return read_text(path, YAML_LIMIT)
    except (OSError, UnicodeDecodeError, TavcError):
        return None


def recorded_config_problem(folder: Path) -> str | None:
    """Why a finished run's `config.yaml` cannot say which configuration the run was (missing,
    changed since the run wrote it, cut short), or None if it can or the folder holds no
    finished run."""
    if not (folder / "provenance.json").is_file():
        return None
    path = folder / "config.yaml"
    if not path.is_file():
        return "config.yaml is missing"
    try:
        recorded = load_json(folder / "provenance.json").get("tables", {}).get("config.yaml")
    except (ValueError, AttributeError):
        recorded = None
    if recorded is not None:
        return None if file_digest(path) == recorded else "config.yaml differs from what its run wrote"
    text = path.read_text(errors="replace")
    missing = [name for name in SECTIONS if f"\n{name}:" not in f"\n{text}"]
    return f"config.yaml lacks its section {missing[0]}" if missing else None


def run_experiments(cfgs: list[TavcConfig], *, progress: bool = False) -> list[dict]:
    """Run several experiments' trials together, so that the history their trials share is
    simulated once (`experiments.joint`), then write each one's outputs as `run_experiment`
    would; return their summaries. Every folder is held from the start to the end."""
    folders = [str(cfg.output_dir) for cfg in cfgs]
    if len(set(folders)) != len(folders):
        raise TavcError("output_dir: two experiments would write to the same folder")
    for cfg in cfgs:
        Executor.from_config(cfg.executor).check()
    with ExitStack() as held:
        for cfg in cfgs:
            held.enter_context(claim_folder(cfg.output_dir))
        plans = [plan_run(cfg) for cfg in cfgs]
        for cfg, plan in zip(cfgs, plans, strict=True):  # every folder checked before any is changed
            check_run_folder(cfg, plan=plan)
        owned = [take_run_folder(cfg, plan) for cfg, plan in zip(cfgs, plans, strict=True)]
        with _failures_listed(owned):
            runs = run_trials_together(cfgs, plans, progress=progress)
        return _finish_all(cfgs, runs, owned)


@contextmanager
def _failures_listed(owned: list[Owned]) -> Iterator[None]:
    """Within the block trials run: a `failures.log` the store wrote is listed as tavc's when
    they fail, and tavc's own is removed when they all finish (one of anybody else's stays)."""
    try:
        yield
    except TavcError:
        for o in owned:
            if (o.folder / FAILURES_LOG).is_file():
                o.wrote(FAILURES_LOG)
        raise
    for o in owned:
        o.remove(FAILURES_LOG)


def _finish_all(cfgs: list[TavcConfig], runs: list[Run], owned: list[Owned]) -> list[dict]:
    """`_finish` for every experiment: in forked processes on the cores the executor was given,
    where the system forks and there is more than one, else one after another. The experiments
    other experiments' claims compare with (`Claim.against`: breakdown, for claims 7 and 8) are
    finished first, so that those claims read their finished runs beside them."""
    n_jobs = min(len(cfgs), Executor.from_config(cfgs[0].executor).n_jobs if cfgs else 1)
    jobs = list(zip(cfgs, runs, owned, strict=True))
    compared = {c.against for _, c in claims() if c.against}
    waves = [[k for k, cfg in enumerate(cfgs) if (str(cfg.experiment_name) in compared) == first]
             for first in (True, False)]
    done: dict[int, dict] = {}
    if n_jobs <= 1 or not CAN_FORK:
        for k in [*waves[0], *waves[1]]:
            done[k] = _finish_loaded(*jobs[k])
        return [done[k] for k in range(len(jobs))]

    pool = ProcessPoolExecutor(max_workers=n_jobs, mp_context=mp.get_context("fork"), initializer=worker_start)
    try:
        for wave in waves:
            futures = {k: pool.submit(_finish_loaded, *jobs[k]) for k in wave}
            done.update({k: f.result() for k, f in futures.items()})
    except BaseException:
        # Ctrl-C, SIGTERM or an error: the workers stop now (each table they wrote is whole,
        # and provenance.json comes last), rather than the run waiting for them to finish
        stop_workers(pool)
        raise
    pool.shutdown(wait=True)
    return [done[k] for k in range(len(jobs))]


def _finish_loaded(cfg: TavcConfig, run: Run, owned: Owned) -> dict:
    return _finish(cfg, load_records(cfg, run), owned)


def _finish(cfg: TavcConfig, run: Run, owned: Owned) -> dict:
    """An experiment's tables, claims and provenance from its trials; its summary."""
    tables, claims = write_analysis(cfg, run.plan, run.output_dir, run.records, made_by(run.specs), owned)
    owned.wrote("provenance.json")
    written = [n for n in owned.files if n.endswith(".csv") or n in ("config.yaml", PLAN_FILE)]
    write_provenance(cfg, run, sorted(n for n in written if (run.output_dir / n).is_file()))
    return {"output_dir": str(run.output_dir), "n_trials": len(run.specs), "n_reused": run.n_reused,
            "wall_time_s": run.wall_time_s, "tables": tables, "claims": claims, "delivered": delivered(run)}


def delivered(run: Run) -> dict[str, int]:
    """Deliveries per controller over the run's trials, from the records its tables were made of."""
    counts: dict[str, int] = {}
    for spec, rec in zip(run.specs, run.records, strict=True):
        counts[spec.controller] = counts.get(spec.controller, 0) + len(rec.table("deliveries")["t_s"])
    return counts


def write_sweep(values: list[dict[str, str]], folders: list[Path]) -> list[Path]:
    """sweep.csv (and its figure) beside a sweep's job folders: every job's states side by side.
    `values[k]` are job k's swept keys and values. Returns the files written: sweep.csv first
    (none for a single job, or jobs without state tables, and then an earlier sweep's
    sweep.csv and figure there are removed: they would describe jobs this sweep did not run)."""
    # deferred: loads matplotlib
    from tavc_cli.viz.figures import marked
    from tavc_cli.viz.sweep import sweep_figure

    parent = folders[0].parent
    owned = take(parent, SWEEP, SWEEP_FILES, what="the sweep's folder")
    table = sweep_table(list(zip(values, folders, strict=True))) if len(folders) > 1 else None
    if table is None or table.empty:
        for name in SWEEP_FILES:
            owned.remove(name)
        return []
    owned.wrote(*SWEEP_FILES)
    write_text_atomic(parent / "sweep.csv", summary_text(table))
    # the jobs' scale is one (a sweep over scale= would mix verdicts): the first job's says it
    with marked(not_a_verdict(from_yaml(folders[0] / "config.yaml"))):
        return [parent / "sweep.csv", *sweep_figure(table, next(iter(values[0])), parent / "sweep")]


def write_ladder(ladder_dir: Path, folders: list[Path]) -> list[Path]:
    """`ladder.csv` and its figure (`ladder.png`, `.svg`) in `ladder_dir`, from the horizon
    ladder's rung folders; returns the paths written, the table first."""
    # deferred: loads matplotlib
    from tavc_cli.viz.ladder import ladder_figure

    owned = take(Path(ladder_dir), LADDER, LADDER_FILES, what="the ladder's folder")
    table = ladder_table(folders)
    owned.wrote(*LADDER_FILES)
    path = Path(ladder_dir) / "ladder.csv"
    write_text_atomic(path, summary_text(table))
    return [path, *ladder_figure(table, Path(ladder_dir) / "ladder")]
