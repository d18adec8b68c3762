"""What the command line shows when things go wrong, and what a run's summary must not hide.

Every failure a user or the machine causes ends in one line ``error: ...`` and a non-zero exit
status (`user_errors`): tavc's own `TavcError`, any `OSError` (a full disk, a folder without
write permission: the file, the system's reason and what to do), memory running out, Ctrl-C and
SIGTERM. Only a bug keeps its traceback. A run's trials are saved one by one as they finish
(`experiments.store`), so whatever stops a run, rerunning it resumes from what was kept.

The summary of `tavc run` says what the tables cannot: that no robot delivered anything, and
that one trial has no spread (its std is shown as nan, not 0).
"""

from __future__ import annotations

import errno
import math
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any, Optional

import typer

from tavc_cli.errors import TavcError, Terminated, interrupt_behind, sigterm_raises
from tavc_cli.settings import from_yaml

RESUME = "finished trials are kept: rerun the same command to resume"
# what to do about an OSError, by its errno
_REMEDIES = {
    errno.ENOSPC: "free some space on that disk or choose another output_dir",
    errno.EDQUOT: "free some of your disk quota or choose another output_dir",
    errno.EACCES: "make the folder writable for you or choose another output_dir",
    errno.EPERM: "make the folder writable for you or choose another output_dir",
    errno.EROFS: "that file system is read-only; choose another output_dir",
    errno.EMFILE: "raise the limit of open files (ulimit -n)",
    errno.ENFILE: "raise the system's limit of open files",
    errno.EPIPE: "whatever read tavc's output stopped reading it",
}


@contextmanager
def user_errors(folder: Optional[Callable[[], Any]] = None) -> Iterator[None]:
    """Turn a ``TavcError`` or an ``OSError`` into one line and exit 1, running out of memory
    into one line and exit 1, Ctrl-C into exit 130, SIGTERM into 143, also where a library's
    error hides them (`errors.interrupt_behind`). `folder` gives the folder the command writes
    to, for an OSError that names no file."""
    try:
        with sigterm_raises():
            yield
    except TavcError as error:
        _stopped(interrupt_behind(error))
        _fail(str(error), 1)
    except OSError as error:
        _stopped(interrupt_behind(error))
        _fail(os_error_text(error, folder), 1)
    except MemoryError as error:
        _stopped(interrupt_behind(error))
        _fail(f"out of memory; use fewer trials per process (executor.batch_size) or fewer processes "
              f"(executor.n_jobs); {RESUME}", 1)
    except KeyboardInterrupt as stop:
        _stopped(stop)
    except (typer.Exit, typer.Abort):
        raise  # the command's own way out (an inner user_errors' one line, say), never read again
    except Exception as error:  # a bug keeps its traceback, unless it is a library's that hid an interrupt
        _stopped(interrupt_behind(error))
        raise


def _stopped(stop: KeyboardInterrupt | None) -> None:
    """Ctrl-C (exit 130) or SIGTERM (143) as one line, however deep it was caught: none if `stop`
    is None."""
    if stop is not None:
        terminated = isinstance(stop, Terminated)
        _fail("terminated" if terminated else "interrupted", 143 if terminated else 130)


# the line `user_errors` printed last, if any (`__main__` then prints none of its own)
shown: list[str] = []


def _fail(message: str, code: int) -> None:
    line = f"error: {' '.join(message.split())}"
    shown.append(line)
    typer.echo(line, err=True)
    raise typer.Exit(code=code) from None


def os_error_text(error: OSError, folder: Optional[Callable[[], Any]] = None) -> str:
    """``<file>: <the system's reason>; <what to do> (<that a rerun resumes>)``.

    A temporary file (written beside its result and renamed over it) is named by its folder; an
    error without a file, as one from a worker process can be, by the command's `folder`.
    """
    name = error.filename if error.filename is not None else _folder_of(folder)
    if isinstance(name, bytes):
        name = name.decode(errors="replace")
    if name is not None and Path(str(name)).name.startswith(".") and str(name).endswith(".tmp"):
        # renaming the temporary over its result failed: the result is what cannot be written;
        # making the temporary failed: its folder
        name = error.filename2 if error.filename2 is not None else Path(str(name)).parent
    reason = error.strerror or str(error) or type(error).__name__
    remedy = _REMEDIES.get(error.errno, "fix the cause")
    return f"{name or 'tavc'}: {reason}; {remedy} ({RESUME})"


def _folder_of(folder: Optional[Callable[[], Any]]) -> Any:
    if folder is None:
        return None
    try:
        return folder()
    except Exception:  # the folder is only a better name for the message; none is fine too
        return None


def summary_text(summary: dict[str, Any]) -> str:
    """`analysis.summary.run_summary_text` for `tavc run`, its std over one trial shown as nan
    (one trial has no spread), its claims headed "not a verdict" where the run is below the
    chapter's scale (its `config.yaml` beside the chapter's trials and duration:
    `analysis.claims.not_a_verdict`), and a line when no robot delivered anything."""
    # deferred: loads pandas
    from tavc_cli.analysis.summary import run_summary_text

    tables = dict(summary.get("tables") or {})
    state_time = tables.get("state_time")
    if state_time is not None and len(state_time) and "n_trials" in state_time:
        state_time = state_time.copy()
        single = (state_time["n_trials"] < 2) & (state_time["controller"] != "theory")
        state_time.loc[single, "std_pct"] = math.nan
        tables["state_time"] = state_time
    short = ""
    settings_path = Path(summary["output_dir"]) / "config.yaml"
    if settings_path.is_file():
        # deferred: loads scipy and pandas
        from tavc_cli.analysis.claims import not_a_verdict

        try:
            short = not_a_verdict(from_yaml(settings_path))
        except Exception:  # the settings the run just wrote; one that cannot be read `tavc report` names
            short = ""
    text = run_summary_text({**summary, "tables": tables, "not_a_verdict": short})
    silent = undelivered(summary.get("delivered", {}), int(summary.get("n_trials", 0)))
    if silent:
        text += "\n\n" + silent
    return text


def undelivered(delivered: dict[str, int], n_trials: int) -> str:
    """A line saying that no robot delivered anything in any of the `n_trials` trials of a run,
    or naming the controllers of which none did; empty when every controller delivered.
    `delivered`: the run's deliveries per controller (`pipeline.delivered`)."""
    idle = [label for label, count in delivered.items() if count == 0]
    if not idle:
        return ""
    why = ("can the robots move and reach the targets? (robot.speed_mps, robot.mass_kg, robot.drive_force_n, "
           "arena.walls)")
    if len(idle) == len(delivered):
        return (f"warning: nothing was delivered: no robot delivered anything in any of the {n_trials} trials, so "
                f"no claim could be tested; {why}")
    return f"warning: no robot of {', '.join(idle)} delivered anything in any of its trials; {why}"
