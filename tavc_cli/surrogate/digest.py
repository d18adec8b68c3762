"""What names the surrogate's code in a trial's key, importing none of it: the digest of that code
(`surrogate_code_digest`) and the engine a drawn trial's spec names (`surrogate_engine`), which
holds it and a reader of a run can take it back from (`engine_code`)."""

from __future__ import annotations

from functools import cache
from pathlib import Path

from tavc_cli import meaning_digest

# below tavc_cli/: `surrogate_code_digest` (the plan decides a drawn trial's seeds and schedule)
_SURROGATE_CODE = ("surrogate/engine.py", "surrogate/tasks.py", "experiments/plan.py")
_TAVC_CLI = Path(__file__).resolve().parent.parent


@cache
def surrogate_code_digest(root: Path = _TAVC_CLI) -> str:
    """Digest of the surrogate's own code (`meaning_digest`), `_SURROGATE_CODE` under `root` (tavc_cli/): the engine
    that draws a trial (`engine.py`) and the tasks it measures and draws them from (`tasks.py`).
    The rest a drawn trial runs on (learners, events, the trial's book-keeping) is the
    simulator's and in `experiments.spec.code_digest`. Named in every surrogate trial's engine
    (`run.surrogate_specs`), so an edit draws the trials again, and recorded in `task_times.json`,
    so an edit measures the tasks again (`run.kept_tasks`)."""
    return meaning_digest(root, _SURROGATE_CODE)


SURROGATE_ENGINE = "surrogate"  # the first field of a surrogate trial's engine


def surrogate_engine(calibration: str, tasks: str, code: str) -> str:
    """The engine of a trial the surrogate draws (`TrialSpec.engine`, in its key): the calibration,
    the digest of the tasks it draws from (`run.tasks_digest`) and of the surrogate's code."""
    return f"{SURROGATE_ENGINE}:{calibration}:{tasks}:{code}"


def engine_code(engine: str) -> str | None:
    """The digest of the surrogate's code a trial's engine names (`surrogate_engine`); None for the
    physical simulator's."""
    fields = engine.split(":")
    return fields[-1] if fields[0] == SURROGATE_ENGINE and len(fields) == 4 else None
