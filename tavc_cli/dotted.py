"""Settings as dotted keys (`robot.dock.dwell_s`), the one form in which tavc compares two
configurations: a run's against the one already in its folder, a run's against the runs its
claims compare it with, a run's against the one its report sets beside it; and typed settings as
the plain data they are written from (`plain`). Like `vocabulary`, it imports nothing of tavc's,
so any layer may use it."""

from __future__ import annotations

import dataclasses


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
    as: each dataclass a mapping of its fields in their order, lists for lists and tuples, the
    rest as it is. Without OmegaConf, whose round trip (`settings.to_yaml`, then a YAML loader)
    gives the same and takes a fifth of a second."""
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        return {f.name: plain(getattr(value, f.name)) for f in dataclasses.fields(value)}
    if isinstance(value, dict):
        return {k: plain(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [plain(v) for v in value]
    return value
