"""The chapter's experiments, one module each: what the chapter says of an experiment, in one place.

An experiment is its config file (``conf/experiment/<name>.yaml``: what it runs) and its module
here (``chapter/<name>.py``: its section, tables, figures, claims, trial counts, its place in the
report, and which studies serve it). The report, ``tavc compare``, the surrogate's study, the
horizon ladder and the chapter's checks read `EXPERIMENTS` rather than lists of their own. An
experiment of the user's own joins them from a ``chapter/`` folder of a config folder given
with ``--config-dir`` (a module defining ``EXPERIMENT``, as those here do), or from code
(`register`).

This package is data: it imports no statistics, and nothing of the report, ``tavc compare``,
the surrogate, the command line or the pipeline.
"""

from __future__ import annotations

from tavc_cli.chapter.registry import Claim, Experiment, Registry
from tavc_cli.errors import TavcError

__all__ = ["EXPERIMENTS", "SERVICES", "Claim", "Experiment", "base_case", "claim", "claims", "experiment_of",
           "order_key", "register", "served_by", "state_table_id"]

EXPERIMENTS = Registry(__name__)  # name -> Experiment, in the report's order
register = EXPERIMENTS.register
SERVICES = ("compare", "surrogate", "vacancy")  # the studies an entry says serve it (`Experiment`'s flags)


def served_by(service: str, own: bool = False) -> tuple[str, ...]:
    """The experiments `service` (one of `SERVICES`) serves, in the report's order: the chapter's
    and, read when asked, those of the user's config folders (the chapter's only, if `own`)."""
    if service not in SERVICES:
        raise TavcError(f"chapter: no service {service!r} ({', '.join(SERVICES)})")
    experiments = EXPERIMENTS.own() if own else EXPERIMENTS
    return tuple(name for name, e in experiments.items() if getattr(e, service))


def claims(own: bool = False) -> list[tuple[str, Claim]]:
    """Every claim (the chapter's own only, if `own`), by number, with the experiment it is about."""
    experiments = EXPERIMENTS.own().values() if own else EXPERIMENTS.values()
    return sorted(((e.name, c) for e in experiments for c in e.claims), key=lambda pair: pair[1].id)


def claim(claim_id: int) -> tuple[str, Claim]:
    """Claim `claim_id` with the experiment it is about."""
    for name, found in claims():
        if found.id == claim_id:
            return name, found
    raise TavcError(f"chapter: no claim {claim_id}")


def experiment_of(claim_id: int) -> str:
    """The experiment claim `claim_id` is about."""
    return claim(claim_id)[0]


def base_case() -> Experiment:
    """The chapter's base case (`Experiment.base_case`): exactly one of its experiments is."""
    found = [e for e in EXPERIMENTS.own().values() if e.base_case]
    if len(found) != 1:
        raise TavcError(f"chapter: one experiment is the base case, found {len(found)}")
    return found[0]


def state_table_id(name: str) -> str | None:
    """The chapter's table of the time in each state of an experiment ("1.2"), None where it prints none."""
    found = EXPERIMENTS.get(name)
    return found.state_table if found is not None else None


def order_key(name: str) -> tuple[int, str]:
    """Where an experiment's section goes in the report: the registry's order, any other after them by name."""
    order = list(EXPERIMENTS)
    return (order.index(name) if name in order else len(order), name)
