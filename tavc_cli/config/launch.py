"""A sweep's jobs run through a Hydra launcher.

``tavc run -m`` expands and validates every job first (``loading.load_sweep``), so a bad job
stops the sweep before anything is written. The jobs then go to the launcher that
``hydra/launcher=`` names: ``basic`` (one after another, in this process) by default, or any
installed launcher plugin such as ``joblib`` (``pip install hydra-joblib-launcher``: jobs in
parallel processes). Each job gets the folder the validated config chose, passed to Hydra as
``hydra.sweep.dir`` and ``hydra.sweep.subdir``; Hydra composes the job's config, and the task
types, checks and resolves it exactly as ``tavc run`` does for a single run.

Overrides of Hydra's own config (``hydra/launcher=joblib``, ``hydra.launcher.n_jobs=2``) go to
the launcher; every other override is the experiment's.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from contextlib import nullcontext
from pathlib import Path
from typing import Any

from hydra._internal.callbacks import Callbacks
from hydra.core.global_hydra import GlobalHydra
from hydra.core.hydra_config import HydraConfig
from hydra.core.plugins import Plugins
from hydra.types import HydraContext, RunMode
from omegaconf import DictConfig

from tavc_cli.config.loading import complete, initialize_conf, plan_sweep, search_overrides
from tavc_cli.config.messages import hydra_errors
from tavc_cli.config.overrides import is_hydra_override
from tavc_cli.errors import TavcError
from tavc_cli.io import claim_folder, owned_path
from tavc_cli.override_keys import setting
from tavc_cli.ownership import SWEEP, SWEEP_FILES, take

# Hydra writes nothing of its own into a job's folder (config.yaml and provenance.json are
# tavc's record), changes no directory and leaves logging alone.
_QUIET = ("hydra/job_logging=none", "hydra/hydra_logging=none", "hydra.output_subdir=null", "hydra.job.chdir=false")


def launch_sweep(overrides: Sequence[str], task: Callable[[DictConfig], Any],
                 finish: Callable[[list[Any]], None] | None = None) -> list[Any]:
    """Validate every job of a sweep, then run ``task`` on each job's resolved config through
    the Hydra launcher the overrides choose.

    Args:
        overrides: The command line's overrides, sweeps (``a=1,2``) and Hydra's included.
        task: Called once per job with its read-only, resolved config; must be picklable for
            launchers that run jobs in other processes.
        finish: Called with what the tasks returned, while the sweep's folder is still held
            (a sweep holds the folder its jobs' folders are in, as a run holds its own: two
            sweeps never write one folder at once; `ownership.take` checks it is a sweep's
            folder or a new one).

    Returns:
        What ``task`` returned for each job, in sweep order.

    Raises:
        TavcError: If a job's config is invalid (before any job runs), the launcher is unknown,
            or a job failed (after the others have run).
    """
    ours = [o for o in overrides if not is_hydra_override(o)]
    theirs = [o for o in overrides if is_hydra_override(o)]
    plan = plan_sweep(ours)
    # a job's folder is named below the sweep's output_dir: a link there is refused, not followed
    folders = [owned_path(Path(cfg.output_dir).parent, Path(cfg.output_dir), folder=True, what="output_dir")
               for _, cfg in plan]
    common = _common_parent(folders)
    jobs = [[*search_overrides(), *job, setting("hydra.sweep.dir", folder.parent),
             setting("hydra.sweep.subdir", folder.name)] for (job, _), folder in zip(plan, folders, strict=True)]
    with hydra_errors(theirs), initialize_conf():
        hydra = GlobalHydra.instance().hydra
        assert hydra is not None
        master = hydra.compose_config("config", overrides=[*_QUIET, *search_overrides(), *theirs,
                                                           setting("hydra.sweep.dir", common)],
                                      run_mode=RunMode.MULTIRUN)
        launcher = Plugins.instance().instantiate_launcher(
            hydra_context=HydraContext(config_loader=hydra.config_loader, callbacks=Callbacks(master)),
            task_function=_Job(task), config=master)
        # held once the launcher is known good: a refused launcher writes nothing
        with claim_folder(Path(common)) if common != "." else nullcontext():
            if common != ".":  # the jobs' folder is a sweep's, or new: never a run's or a report's
                take(Path(common), SWEEP, SWEEP_FILES)
            returns = launcher.launch(jobs, initial_job_idx=0)
            done = [r.return_value for r in returns]  # a failed job's exception is raised here
            if finish is not None:
                finish(done)
    return done


class _Job:
    """Hydra's task function: type, check and resolve the job's config, then run the task."""

    def __init__(self, task: Callable[[DictConfig], Any]):
        self.task = task

    def __call__(self, cfg: DictConfig) -> Any:
        hydra = HydraConfig.get()
        resolved = complete(cfg, job_dir=str(hydra.sweep.subdir))
        if Path(resolved.output_dir).resolve() != Path(hydra.runtime.output_dir).resolve():
            raise TavcError(f"job {hydra.job.num}: Hydra's folder {hydra.runtime.output_dir} is not the job's "
                            f"output_dir {resolved.output_dir}")
        return self.task(resolved)


def _common_parent(folders: Sequence[Path]) -> str:
    parents = {str(folder.parent) for folder in folders}
    return parents.pop() if len(parents) == 1 else "."
