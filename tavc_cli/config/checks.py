"""The primitives every validation rule is written with: each raises one
``TavcError("<key>: <problem>")`` line."""

import math
from collections.abc import Sequence
from typing import Any, NoReturn

from omegaconf import OmegaConf

from tavc_cli.errors import TavcError


def fail(key: str, problem: str) -> NoReturn:
    """Stop with one line naming `key` and what is wrong with its value."""
    raise TavcError(f"{key}: {problem}")


def check(ok: bool, key: str, problem: str) -> None:
    """Fail with `problem` unless `ok`."""
    if not ok:
        fail(key, problem)


def positive(key: str, value: float) -> None:
    """`value` must be a finite number above 0."""
    check(math.isfinite(value) and value > 0, key,
          f"must be {'a finite number ' if math.isinf(value) else ''}> 0, got {value!r}")


def at_least(key: str, value: float, low: float) -> None:
    """`value` must be a finite number of at least `low`."""
    check(math.isfinite(value) and value >= low, key,
          f"must be {'a finite number ' if math.isinf(value) else ''}>= {low}, got {value!r}")


def finite(key: str, value: float) -> None:
    """`value` must be a finite number."""
    check(math.isfinite(value), key, f"must be a finite number, got {value!r}")


def unit(key: str, value: float) -> None:
    """`value` must lie in [0, 1]."""
    check(0 <= value <= 1, key, f"must be in [0, 1], got {value!r}")


def angle(key: str, value: float, high: float) -> None:
    """`value` must lie in (0, `high`]."""
    check(0 < value <= high, key, f"must be in (0, {high:g}], got {value!r}")


def one_of(key: str, value: Any, choices: Sequence[str]) -> None:
    """`value` must be one of `choices`."""
    check(value in choices, key, f"must be one of {', '.join(choices)}; got {value!r}")


def per_circuit(key: str, values: Sequence[Any], n_circuits: int, what: str) -> None:
    """`values` must hold one `what` per circuit."""
    check(
        len(values) == n_circuits,
        key,
        f"needs one {what} per circuit ({n_circuits}), got {len(values)}",
    )


def unique(key: str, values: Sequence[Any], what: str) -> None:
    """No value may appear twice in `values` (each one a `what`)."""
    seen = set()
    for value in values:
        check(value not in seen, key, f"{what} {value!r} appears more than once")
        seen.add(value)


def plain(value: Any) -> Any:
    """A config node as builtin types, for messages."""
    return OmegaConf.to_container(value) if OmegaConf.is_config(value) else value
