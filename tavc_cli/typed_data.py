"""Plain data read straight into a settings dataclass, where it is already of the fields' types.

`settings.from_mapping` builds settings through OmegaConf (a typed schema merged with the data,
then turned into objects), which converts what it can, refuses the rest in one message and
costs about 30 ms a config: the report reads over a hundred. A run's `config.yaml` is written
by tavc and holds every value in its field's type already, so `exact` builds the same objects
directly, and declines (returns `DECLINED`) at the first thing it would have to convert,
resolve, fill in or refuse: a key the class lacks, a field left out whose default is not plain,
a value of another type, an interpolation, ``???``, anything the class's constructor refuses. The
caller then takes OmegaConf's path, which gives its own result or its own message, so a
damaged or hand-edited file reads exactly as before.

What it does as OmegaConf does: a field left out takes its default; an integer in a float
field becomes that float; a ``Dict[str, Any]`` field merges the data over its default (nested
mappings key by key, other values replaced by values that are not mappings); a list replaces
the default; containers are copied, never shared with the data.
"""

from __future__ import annotations

import dataclasses
import typing
from functools import cache
from typing import Any

from omegaconf import MISSING

from tavc_cli.errors import interrupt_behind

DECLINED = object()  # what `exact` returns where it would have to convert, fill in or refuse


class _Decline(Exception):
    """Raised inside `exact` where OmegaConf must decide."""


def exact(cls: type, data: Any) -> Any:
    """An instance of the settings dataclass `cls` from plain data (as YAML gives it) whose
    values are all of their fields' types; `DECLINED` where any is not (see the module)."""
    try:
        return _dataclass(cls, data)
    except _Decline:
        return DECLINED


@cache
def _fields(cls: type) -> tuple[tuple[str, Any, bool], ...]:
    """(name, type, whether it has a default) of each field of `cls` set by its constructor."""
    hints = typing.get_type_hints(cls)
    return tuple((f.name, hints[f.name], _has_default(f)) for f in dataclasses.fields(cls) if f.init)


def _has_default(f: dataclasses.Field) -> bool:
    """Whether the field, left out, takes a default that needs nothing filled in: not ``???``, nor
    a settings class with a mandatory field anywhere inside (the arena's: OmegaConf refuses it)."""
    if f.default is not dataclasses.MISSING:
        return f.default != MISSING
    if f.default_factory is dataclasses.MISSING:
        return False
    return not dataclasses.is_dataclass(f.default_factory) or _complete(f.default_factory)


@cache
def _complete(cls: type) -> bool:
    """Whether every field of the settings class `cls`, and of those its fields' defaults build,
    has a default."""
    return all(has_default for _, _, has_default in _fields(cls))


def _dataclass(cls: type, data: Any) -> Any:
    if not isinstance(data, dict):
        raise _Decline
    fields = _fields(cls)
    names = {name for name, _, _ in fields}
    if any(key not in names for key in data):
        raise _Decline
    kwargs = {}
    for name, kind, has_default in fields:
        if name in data:
            default = _default(cls, name) if typing.get_origin(kind) is dict else None
            kwargs[name] = _value(kind, data[name], default)
        elif not has_default:
            raise _Decline
    try:
        return cls(**kwargs)
    except Exception as error:  # a refusal of the class's own (its __post_init__): as OmegaConf reports it
        if interrupt_behind(error) is not None:
            raise  # a Ctrl-C a library hid behind its own error stays one (`console.user_errors`)
        raise _Decline from None


def _default(cls: type, name: str) -> Any:
    """The default of a ``Dict[str, Any]`` field, which the data is merged over (else None)."""
    f = next(f for f in dataclasses.fields(cls) if f.name == name)
    if f.default_factory is not dataclasses.MISSING:
        made = f.default_factory()
        return made if isinstance(made, dict) else None
    return None


def _value(kind: Any, value: Any, default: Any = None) -> Any:
    origin, args = typing.get_origin(kind), typing.get_args(kind)
    if origin is typing.Union:  # Optional[X]
        if value is None:
            return None
        inner = [a for a in args if a is not type(None)]
        if len(inner) != 1:
            raise _Decline
        return _value(inner[0], value)
    if value is None:
        if kind is Any:
            return None
        raise _Decline
    if kind is Any:
        return _plain(value)
    if dataclasses.is_dataclass(kind):
        return _dataclass(kind, value)
    if origin is list:
        if not isinstance(value, list):
            raise _Decline
        return [_value(args[0] if args else Any, item) for item in value]
    if origin is dict:
        if not isinstance(value, dict) or not all(isinstance(k, str) for k in value) or \
                (args and args[1] is not Any):
            raise _Decline
        return _merged(default or {}, _plain(value))
    return _scalar(kind, value)


def _scalar(kind: Any, value: Any) -> Any:
    if kind is bool:
        if isinstance(value, bool):
            return value
    elif kind is int:
        if isinstance(value, int) and not isinstance(value, bool):
            return value
    elif kind is float:
        if isinstance(value, float):
            return value
        if isinstance(value, int) and not isinstance(value, bool) and abs(value) < 2 ** 1023:
            return float(value)
    elif kind is str:
        if isinstance(value, str) and "${" not in value and value != MISSING:
            return value
    raise _Decline


def _plain(value: Any) -> Any:
    """A copy of plain data, declining anything OmegaConf would resolve or refuse in it."""
    if isinstance(value, dict):
        if not all(isinstance(k, str) for k in value):
            raise _Decline
        return {k: _plain(v) for k, v in value.items()}
    if isinstance(value, list):
        return [_plain(v) for v in value]
    if isinstance(value, str):
        if "${" in value or value == MISSING:
            raise _Decline
        return value
    if value is None or isinstance(value, (bool, int, float)):
        return value
    raise _Decline


def _merged(base: dict, over: dict) -> dict:
    """`over` merged over a copy of `base`: mappings key by key, anything else replaced; a
    mapping over a value that is not one, or the reverse, is OmegaConf's to decide."""
    out = _plain(base)
    for key, value in over.items():
        if key in out and isinstance(out[key], dict) != isinstance(value, dict):
            raise _Decline
        out[key] = _merged(out[key], value) if isinstance(value, dict) and key in out else value
    return out
