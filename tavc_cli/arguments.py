"""The Python API's arguments checked as the command line's parser checks its own: a value of the
wrong kind is one line naming the argument (`TavcError`), never a `TypeError` from deep inside,
and a string where a list belongs is never taken a character at a time."""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from numbers import Real
from pathlib import Path

from tavc_cli.errors import TavcError
from tavc_cli.io import path_of, refuse_folder_problem
from tavc_cli.override_keys import setting


def _items(value: object, kinds: type | tuple[type, ...]) -> list | None:
    """`value`'s items as a list where it is an iterable (never a string, which would be taken a
    character at a time) of `kinds` only (never a bool for a number); else None."""
    if isinstance(value, str | bytes) or not isinstance(value, Iterable):
        return None
    given = list(value)  # once: a generator is used up by reading it
    return given if all(isinstance(v, kinds) and not isinstance(v, bool) for v in given) else None


def overrides_of(overrides: object) -> list[str]:
    """The caller's overrides as a list of strings (any iterable of them)."""
    given = _items(overrides, str)
    if given is None:
        raise TavcError(f"overrides: a list of strings such as ['scale=smoke', 'seed=3'], not {overrides!r:.80}")
    return given


def names_of(names: object, what: str) -> list[str] | None:
    """The caller's experiment or learner names as a list (None: the default; one string: that one
    name)."""
    if names is None or isinstance(names, str):
        return None if names is None else [names]
    given = _items(names, str)
    if given is None:
        raise TavcError(f"{what}: a name or a list of names, not {names!r:.80}")
    return given


def factors_of(factors: object) -> list[float] | None:
    """The horizon ladder's factors as a list (any iterable of real numbers, numpy's included), or
    None (the ladder checks their values)."""
    if factors is None:
        return None
    given = _items(factors, Real)
    if given is None:
        raise TavcError(f"ladder: a list of multiples of the chapter's durations, e.g. [1, 4, 40], not {factors!r:.80}")
    return [float(f) for f in given]


def echo_of(echo: object) -> None:
    """The function a command prints its lines through (`print` by default)."""
    if not callable(echo):
        raise TavcError(f"echo: a function that takes a line of text, such as print, not {echo!r:.80}")


def share_of(value: object, what: str) -> float:
    """A share of each trial, from 0 up to but not including 1."""
    if not isinstance(value, Real) or isinstance(value, bool) or not 0 <= float(value) < 1:
        raise TavcError(f"{what}: a share of each trial from 0 up to but not including 1, such as 0.5, not "
                        f"{value!r:.80}")
    return float(value)


def folder_of(value: object, what: str) -> None:
    """A folder the caller gives, or None: one line where it is no path (`io.path_of`)."""
    if value is not None:
        path_of(value, what)


def mapping_of(value: object, what: str) -> None:
    """A mapping the caller gives (learner to folder), or None."""
    if value is not None and not isinstance(value, Mapping):
        raise TavcError(f"{what}: a mapping of learner to folder such as {{'tavc': 'results'}}, not {value!r:.80}")


def folder_setting(output_dir: object) -> list[str]:
    """The override that sets ``output_dir`` to the folder the caller named (none where it named
    none), taken as named: one line where it is no path, empty (``Path("")`` is the working
    folder), the root of the file system, or holds ``${``."""
    if output_dir is None:
        return []
    path_of(output_dir, "output_dir")
    refuse_folder_problem(output_dir, "output_dir", in_setting=True)
    return [setting("output_dir", Path(output_dir))]
