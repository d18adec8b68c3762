"""Trials run so that one that fails is named and the others finish: a fault pinned on one
trial drops it (`TrialFault`), any other exception runs each trial alone to find the ones at
fault, and each failure keeps its seed, its message and, for an exception, its traceback."""

from __future__ import annotations

import traceback
from collections.abc import Callable, Sequence
from dataclasses import dataclass

from tavc_cli.confined import plain
from tavc_cli.errors import TavcError
from tavc_cli.experiments.engine import run_trials
from tavc_cli.experiments.records import TrialRecord
from tavc_cli.experiments.spec import TrialSpec
from tavc_cli.experiments.trial import TrialFault


@dataclass(frozen=True)
class TrialFailure:
    """A trial that stopped with an error: which one, its seed, what went wrong and, for an
    exception, its traceback."""

    controller: str
    trial: int
    seed: tuple[int, ...]
    message: str
    detail: str = ""
    folder: str = ""  # the results folder, where trials of several are run together

    @classmethod
    def of(cls, spec: TrialSpec, message: str, detail: str = "") -> TrialFailure:
        """The failure of `spec`'s trial, its message on one line."""
        return cls(spec.controller, spec.trial, tuple(spec.seed), " ".join(message.split()), detail)

    @classmethod
    def from_data(cls, data: object) -> TrialFailure:
        """A failure as a worker process sent it (`dataclasses.asdict`, through JSON), checked
        field by field: anything else is one `TavcError` line."""
        fields = {"controller": str, "trial": int, "seed": list, "message": str, "detail": str, "folder": str}
        if (not isinstance(data, dict) or set(data) != set(fields)
                or not all(type(data[k]) is kind for k, kind in fields.items())
                or not all(type(x) is int for x in data["seed"])):
            raise TavcError("a worker process sent a failed trial tavc does not know")
        return cls(**{**data, "seed": tuple(data["seed"]), "controller": plain(data["controller"]),
                      "message": plain(data["message"]), "detail": plain(data["detail"]),
                      "folder": plain(data["folder"])})

    @property
    def name(self) -> str:
        """The trial's name, as its record file is named: ``<controller>_<trial>``."""
        return f"{self.controller}_{self.trial:03d}"

    def report(self) -> str:
        """The failure as it goes into `failures.log`."""
        return f"trial {self.name} (seed {list(self.seed)}): {self.message}" + (
            f"\n{self.detail.rstrip()}" if self.detail else "")


BatchResult = tuple[list[tuple[TrialSpec, TrialRecord]], list[TrialFailure]]


def simulate_contained(specs: Sequence[TrialSpec], report: Callable[[float], None] | None = None) -> BatchResult:
    """Run trials side by side; a trial that fails is named and left out, the others finish.

    A fault the engine pins on one trial (`TrialFault`) drops that trial and the others run
    again without it; any other exception runs each trial alone to find the ones at fault.
    The others' records are those of an uneventful run: a trial computes the same alone as
    in any batch.
    """
    try:
        return list(zip(specs, run_trials(specs, report), strict=True)), []
    except TrialFault as fault:
        failures = [TrialFailure.of(specs[fault.index], str(fault))]
        groups = [[s for k, s in enumerate(specs) if k != fault.index]]
    except Exception as exc:
        if len(specs) == 1:
            said = str(exc) if isinstance(exc, TavcError) else f"{type(exc).__name__}: {exc}"  # a learner's, named
            return [], [TrialFailure.of(specs[0], said, traceback.format_exc())]
        failures, groups = [], [[s] for s in specs]
    done: list[tuple[TrialSpec, TrialRecord]] = []
    for group in groups:
        if group:
            ok, failed = simulate_contained(group)
            done += ok
            failures += failed
    return done, failures
