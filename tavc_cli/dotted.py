"""Settings as dotted keys (`robot.dock.dwell_s`), the one form in which tavc compares two
configurations: a run's against the one already in its folder, a run's against the runs its
claims compare it with, a run's against the one its report sets beside it; and typed settings as
the plain data they are written from (`plain`). Like `vocabulary`, it imports nothing of tavc's,
so any layer may use it."""

from __future__ import annotations

import dataclasses
import typing
from functools import cache
from pathlib import PurePath


def dotted(tree, prefix: str = "", keep_empty: bool = True) -> dict[str, object]:
    """A nested mapping as ``{dotted key: value}``; lists stay whole (`tasks.values`). An empty
    mapping is a value of its own where `keep_empty` (so that ``{}`` and ``None`` differ at a key),
    else it gives no key (so that ``{}`` and ``{"x": 1}`` differ at ``x`` alone)."""
    if isinstance(tree, dict):
        out: dict[str, object] = {}
        for key, value in tree.items():
            out.update(dotted(value, f"{prefix}{key}.", keep_empty))
        return out or ({prefix.rstrip("."): {}} if keep_empty else {})
    return {prefix.rstrip("."): tree}


def plain(value):
    """Typed settings (a tree of dataclasses) as the plain data their ``config.yaml`` reads back
    as: each dataclass a mapping of its fields in their order, lists for lists and tuples, a path
    as its text, a whole number in a field of floats (or a list of them) as that float, the rest
    as it is. Without OmegaConf, whose round trip (its structured copy, its YAML, a YAML loader)
    gives the same and takes a fifth of a second."""
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        floats = _float_fields(type(value))
        return {f.name: _as_float(plain(getattr(value, f.name))) if f.name in floats else plain(getattr(value, f.name))
                for f in dataclasses.fields(value)}
    if isinstance(value, dict):
        return {k: plain(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [plain(v) for v in value]
    return str(value) if isinstance(value, PurePath) else value


@cache
def _float_fields(cls: type) -> frozenset[str]:
    """The fields of the dataclass `cls` declared a float, an optional float or a list of floats."""
    floats = (float, typing.Optional[float], typing.List[float], typing.Optional[typing.List[float]])
    return frozenset(name for name, hint in typing.get_type_hints(cls).items() if hint in floats)


def _as_float(value):
    """A whole number (not a truth value) as the float its field holds; a list of them element by element."""
    if isinstance(value, list):
        return [_as_float(v) for v in value]
    return float(value) if isinstance(value, int) and not isinstance(value, bool) else value
