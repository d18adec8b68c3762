"""What an entry of the chapter's registry holds (`Experiment`, `Claim`), and the registry itself.

An entry is data: the chapter's numbers for tables, figures and sections, its claims' words, and
which of tavc's studies serve the experiment. A claim names the rule that tests it as
``package.module:function`` and the rule is imported only when the claim is tested, so reading the
registry costs no statistics library (``tavc list`` and the command line's help stay fast).
"""

from __future__ import annotations

import importlib
import importlib.util
import pkgutil
import sys
import zlib
from collections.abc import Callable, Iterator, Mapping
from dataclasses import dataclass
from pathlib import Path

from tavc_cli.errors import TavcError

LEARNS = ("tasks", "behaviours")  # what an experiment's robots learn: which task next, or which behaviour
USER_FOLDER = "chapter"  # the folder of a user's config folder (`--config-dir`) that holds registry modules


@dataclass(frozen=True)
class Claim:
    """One of the chapter's claims: its number, the chapter's words its parts test (quoted), and
    its rule, a function ``(runs, learner=...) -> list[Part]`` given as ``package.module:function``
    or as the function itself. `against` names the other experiment whose run the rule compares
    this one's with, if it compares two. `on_tables`, where the chapter prints the numbers for it,
    is the same test applied to the chapter's own tables: a function ``() -> list[dict]`` of rows
    ``claim_id, test, statistic, p_value, holds, observation``, given the same way."""

    id: int
    text: str
    rule: str | Callable
    against: str | None = None
    on_tables: str | Callable | None = None

    def test(self) -> Callable:
        """The rule, imported where it is given by name."""
        return self._function(self.rule)

    def table_check(self) -> Callable | None:
        """The check on the chapter's tables (`on_tables`), imported where it is given by name; None without one."""
        return None if self.on_tables is None else self._function(self.on_tables)

    def _function(self, given: str | Callable) -> Callable:
        if callable(given):
            return given
        module, _, name = given.partition(":")
        found = getattr(importlib.import_module(module), name, None)
        if not callable(found):
            raise TavcError(f"claim {self.id}: {given!r} names no function")
        return found


@dataclass(frozen=True)
class Experiment:
    """One experiment of the chapter, as the chapter reports it and as tavc serves it.

    Attributes:
        name: Its config, ``conf/experiment/<name>.yaml`` (what ``experiment=`` takes), and its
            run's folder.
        section: The chapter's section that reports it (the config's ``section`` too).
        order: Its place in the report, the chapter's order (smaller first).
        state_table: The chapter's table of the time in each state ("1.2"), if it prints one.
        time_table: The chapter's table of traversal and target times (section 1.4's "1.1").
        state_figure: The chapter's state histogram of it ("1.6"), which the report redraws.
        performance_figure: The chapter's performance over time ("1.7"), which the report redraws.
        kind_figures: The chapter's figures the report draws the kind of for every run like it
            (section 1.4's target times, fast and slow robots' grids).
        claims: The chapter's claims about it, by number.
        chapter_trials: The trials behind `state_table` as (TAVC, random), 0 where it prints no
            random column; the same tests are applied to the printed table with these counts.
        learns: "tasks" (which circuit next: sections 1.5 and 1.6) or "behaviours" (section 1.4).
        base_case: The chapter's base case: the horizon ladder climbs it, the model is measured in
            its world, the surrogate's phase diagram varies it, the report's arithmetic of the
            learning rule reads its run.
        compare: `tavc compare` runs it.
        surrogate: `tavc surrogate --study` checks the surrogate on it.
        vacancy: Its event opens a vacancy on the high-value circuit (a breakdown there, a swap of
            the values): `tavc compare` times how soon it is filled.
    """

    name: str
    section: str
    order: int
    state_table: str | None = None
    time_table: str | None = None
    state_figure: str | None = None
    performance_figure: str | None = None
    kind_figures: tuple[str, ...] = ()
    claims: tuple[Claim, ...] = ()
    chapter_trials: tuple[int, int] | None = None
    learns: str = "tasks"
    base_case: bool = False
    compare: bool = False
    surrogate: bool = False
    vacancy: bool = False

    def __post_init__(self) -> None:
        """Refuse, in one line, a declaration that contradicts itself."""
        if self.learns not in LEARNS:
            raise TavcError(f"chapter: {self.name}.learns must be one of {', '.join(LEARNS)}, got {self.learns!r}")
        if (self.state_table is None) != (self.chapter_trials is None):
            raise TavcError(f"chapter: {self.name} gives chapter_trials only with a state_table, and both together")

    @property
    def tables(self) -> tuple[str, ...]:
        """The chapter's tables of it."""
        return tuple(t for t in (self.time_table, self.state_table) if t is not None)

    @property
    def figures(self) -> tuple[str, ...]:
        """The chapter's figures of it."""
        return tuple(f for f in (self.state_figure, self.performance_figure) if f is not None) + self.kind_figures


class Registry(Mapping[str, Experiment]):
    """name -> `Experiment`, in the report's order (`Experiment.order`, then the name): the
    package's modules (each defines ``EXPERIMENT``), the experiments registered from code
    (`register`), and those of the ``chapter/*.py`` modules in the user's config folders
    (``--config-dir``; read while the folder is given, each module once).

    What other modules fix when they are imported (compare's scenarios, the ladder's experiment)
    is read from the chapter's own experiments (`own`): a config folder is given after those
    imports, and a module of the user's that fails to load is then one error line of the command
    that reads it."""

    def __init__(self, package: str) -> None:
        """A registry of the experiment modules of `package`, read when first asked."""
        self._package = package
        self._own: dict[str, Experiment] | None = None
        self._registered: dict[str, Experiment] = {}
        self._from_folders: dict[Path, list[Experiment]] = {}

    def register(self, experiment: Experiment) -> Experiment:
        """Add an experiment; a name or a claim number already registered for another is refused,
        and so is a second base case (the chapter's is its own)."""
        self._check(experiment, self._entries(), added=True)
        self._registered[experiment.name] = experiment
        return experiment

    def own(self) -> dict[str, Experiment]:
        """The chapter's experiments, the package's modules', in the report's order."""
        if self._own is None:
            self._own = {}
            for found in _package_modules(self._package):
                self._own[self._check(found, self._own).name] = found
        return dict(sorted(self._own.items(), key=lambda kv: (kv[1].order, kv[0])))

    def __getitem__(self, name: str) -> Experiment:
        """The experiment named `name`."""
        return self._entries()[name]

    def __iter__(self) -> Iterator[str]:
        """The experiments' names, in the report's order."""
        entries = self._entries()
        return iter(sorted(entries, key=lambda name: (entries[name].order, name)))

    def __len__(self) -> int:
        """How many experiments there are."""
        return len(self._entries())

    def _entries(self) -> dict[str, Experiment]:
        entries = {**self.own(), **self._registered}
        for folder in _user_folders():
            if folder not in self._from_folders:
                self._from_folders[folder] = [_module_experiment(path) for path in sorted(folder.glob("*.py"))
                                              if not path.name.startswith("_")]
            for found in self._from_folders[folder]:
                entries[self._check(found, entries, added=True).name] = found
        return entries

    @staticmethod
    def _check(experiment: Experiment, entries: Mapping[str, Experiment], added: bool = False) -> Experiment:
        known = entries.get(experiment.name)
        if known is not None and known != experiment:
            raise TavcError(f"chapter: experiment {experiment.name!r} is registered twice")
        if added and experiment.base_case:
            raise TavcError(f"chapter: {experiment.name} cannot be the base case; the chapter's is "
                            f"{next((e.name for e in entries.values() if e.base_case), 'its own')}")
        ids = [c.id for c in experiment.claims]
        taken = {c.id: e.name for e in entries.values() if e.name != experiment.name for c in e.claims}
        clash = sorted({i for i in ids if i in taken or ids.count(i) > 1})
        if clash:
            raise TavcError(f"chapter: {experiment.name} claims number {clash[0]}, which "
                            f"{taken.get(clash[0], experiment.name)} has already")
        return experiment


def _package_modules(package: str) -> list[Experiment]:
    """The ``EXPERIMENT`` of every module of the package but this one."""
    found = []
    for info in pkgutil.iter_modules(importlib.import_module(package).__path__):
        if info.name != __name__.rpartition(".")[2] and not info.name.startswith("_"):
            found.append(_experiment_of(importlib.import_module(f"{package}.{info.name}"), info.name))
    return found


def _user_folders() -> list[Path]:
    """The ``chapter/`` folders of the user's config folders, where there are any."""
    # deferred: loads numpy
    from tavc_cli.learning.plugins import config_dirs

    return [d / USER_FOLDER for d in config_dirs() if (d / USER_FOLDER).is_dir()]


def _module_experiment(path: Path) -> Experiment:
    """The ``EXPERIMENT`` of a registry module in a user's config folder, loaded as a module of its own."""
    name = f"tavc_chapter_{zlib.crc32(str(path.resolve()).encode()):08x}"
    module = sys.modules.get(name)
    if module is None:
        spec = importlib.util.spec_from_file_location(name, path)
        module = importlib.util.module_from_spec(spec)
        sys.modules[name] = module
        try:
            spec.loader.exec_module(module)
        except BaseException as error:  # noqa: BLE001 - the user's file: one line naming it
            del sys.modules[name]
            if isinstance(error, KeyboardInterrupt):
                raise
            raise TavcError(f"chapter: {path} failed to load: {type(error).__name__}: {error}") from None
    return _experiment_of(module, str(path))


def _experiment_of(module, where: str) -> Experiment:
    experiment = getattr(module, "EXPERIMENT", None)
    if not isinstance(experiment, Experiment):
        raise TavcError(f"chapter: {where} defines no EXPERIMENT (a tavc_cli.chapter.Experiment)")
    return experiment
