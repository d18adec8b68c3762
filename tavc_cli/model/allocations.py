"""The vacancy-chain model's output (``learner.model_file``, `tavc model`'s ``model.json``) as the
model's controllers read it: robots per circuit for every team size the model predicts.

The file may come from another folder or another person, so it is read bounded
(`readers.load_json`) and checked whole before any trial runs: a team size that is a positive
integer, a predicted state of one non-negative count per circuit summing to that size. Anything
else is one line naming the file, the entry and what to do, and nothing is written, so the same
command runs once the file is fixed.
"""

from __future__ import annotations

import reprlib
from collections.abc import Mapping
from pathlib import Path

from tavc_cli.errors import TavcError
from tavc_cli.notation import state_counts
from tavc_cli.readers import load_json

# tavc model's largest model.json is 6 KB; 1 MiB is room for many more team sizes
MODEL_LIMIT = 1 << 20
REMAKE = "run `tavc model` to write it, or name another with learner.model_file"


def _bad(path: Path, what: str) -> TavcError:
    return TavcError(f"learner.model_file: {path} {what}; {REMAKE}")


def _counts(path: Path, size: str, prediction: object, n_circuits: int | None) -> list[int]:
    """One team size's predicted state as robots per circuit, most valuable circuit first."""
    state = prediction.get("predicted_state") if isinstance(prediction, dict) else None
    counts = state_counts(state)
    if counts is None:
        raise _bad(path, f"has no predicted state of counts for {size} robots (by_team_size.{size}.predicted_state "
                         f"is {reprlib.repr(state)}, not like '3:3')")
    if n_circuits is not None and len(counts) != n_circuits:
        raise _bad(path, f"predicts {state} for {size} robots: {len(counts)} circuits, where the arena has "
                         f"{n_circuits}")
    if sum(counts) != int(size):
        raise _bad(path, f"predicts {state} for {size} robots: {sum(counts)} robots, not {size}")
    return list(counts)


def model_file_path(value: object) -> Path:
    """The file ``learner.model_file`` names: a path, or a number Hydra read from one
    (``learner.model_file=3``); anything else (null, empty, a list) is one line."""
    if isinstance(value, (int, float)) and not isinstance(value, bool):
        value = str(value)
    if not isinstance(value, (str, Path)) or str(value) == "":
        shown = ("null" if value is None else str(value).lower() if isinstance(value, bool)
                 else repr(value) if isinstance(value, str) else str(value))
        raise TavcError(f"learner.model_file: must be the path of a model.json (`tavc model` writes one), got {shown}")
    return Path(value)


def model_differences(model: dict, world: dict[str, object]) -> list[str]:
    """The settings in which a `model.json` (`model`) was measured otherwise than a run's `world`
    (``{"arena": name, "tasks.values": [...], "tasks.time_unit": unit, "robot.speed_mps": speed}``),
    as far as the model records them (`model.api.model_identity`; one it does not record is not
    compared): ``key value (the run: value)``."""
    speed = model.get("measurement", {}).get("robot_speed_mps") if isinstance(model.get("measurement"), dict) else None
    recorded = {"arena": model.get("arena"), "tasks.values": model.get("values"),
                "tasks.time_unit": model.get("time_unit"), "robot.speed_mps": speed}
    return [f"{key} {recorded[key]} (the run: {ours})" for key, ours in world.items()
            if recorded.get(key) is not None and recorded[key] != ours]


def model_world(cfg) -> dict[str, object]:
    """The settings of a run (`cfg`: its settings, or the composed config they are read from) a
    model must have been measured with to stand for it (`model_differences`)."""
    tasks = cfg.tasks
    values = tasks["values"] if isinstance(tasks, Mapping) else tasks.values  # on a config, .values is a method
    return {"arena": str(cfg.arena.name), "tasks.values": [float(v) for v in values],
            "tasks.time_unit": str(tasks.time_unit), "robot.speed_mps": float(cfg.robot.speed_mps)}


def model_allocations(path: object, n_circuits: int | None = None,
                      world: dict[str, object] | None = None) -> dict[str, list[int]]:
    """Robots per circuit, the most valuable circuit first, for every team size the model file
    predicts (``by_team_size``): e.g. ``{"5": [3, 2], "6": [3, 3]}`` (the model writes its states
    most valuable circuit first, `analysis.states.split_label`). `n_circuits`, when given, is the
    number of circuits every state must have; `world`, when given, the run's settings the model
    must have been measured with (`model_differences`)."""
    path = model_file_path(path)
    try:
        model = load_json(path, MODEL_LIMIT, REMAKE)
    except FileNotFoundError:
        raise TavcError(f"learner.model_file: no model at {path}; run `tavc model` first, "
                        "or name its model.json") from None
    except OSError as error:
        raise _bad(path, f"cannot be read ({error.strerror or error})") from None
    except ValueError as error:
        raise _bad(path, f"is not a model.json ({error})") from None
    sizes = model.get("by_team_size") if isinstance(model, dict) else None
    if not isinstance(sizes, dict) or not sizes:
        raise _bad(path, "has no `by_team_size`; is it tavc model's model.json?")
    differ = model_differences(model, world or {})
    if differ:
        raise TavcError(f"learner.model_file: {path} was measured with other settings than this run's "
                        f"({'; '.join(differ)}); run `tavc model` at this run's settings and name its model.json")
    for size in sizes:
        if not (isinstance(size, str) and size.isdigit() and int(size) >= 1):
            raise _bad(path, f"has a team size {size!r} in by_team_size (not a whole number of robots)")
    return {size: _counts(path, size, prediction, n_circuits) for size, prediction in sizes.items()}
