"""Learners from outside tavc: loading the class ``learner.target`` names, checking its settings,
building it, and guarding what it answers.

A plugin runs arbitrary code by design (docs/security.md). What tavc checks is everything that
comes back from it into a trial:
- its code is part of its trials' keys (`target_digest`): edit the file, and its trials, and only
  its trials, are computed again;
- `PluginLearner` stands between the simulator and the class: an exception, `sys.exit` included,
  becomes one line naming the learner, the method and its arguments; `q_tables()` must have the
  shape the records hold;
- `check_choice` (called where every Python policy's answer enters the simulator) refuses a
  circuit that is not an integer in range;
- `rehearse` drives the learner through a short made-up run twice with the same seed before any
  trial starts: bad answers are refused there, in one line, and a learner whose answers differ
  between the two (it draws from a generator other than the one it is given) is named in a
  warning.
"""

from __future__ import annotations

import hashlib
import importlib
import importlib.util
import inspect
import os
import random
import sys
import zlib
from collections.abc import Mapping
from functools import cache
from pathlib import Path

import numpy as np

from tavc_cli.errors import TavcError
from tavc_cli.learning.parameters import PluginSettings

CONFIG_DIRS_ENV = "TAVC_CONFIG_DIRS"  # folders of the user's own configs and learners (`--config-dir`)
PLUGIN_ARGUMENTS = ("n_robots", "n_circuits", "rng")  # what every learner from outside tavc is built with


def config_dirs() -> list[Path]:
    """The user's config folders, in the order given (`--config-dir`, or the environment
    variable TAVC_CONFIG_DIRS, which worker processes inherit)."""
    return [Path(p) for p in os.environ.get(CONFIG_DIRS_ENV, "").split(os.pathsep) if p]


def target_file(file: str) -> Path:
    """The file of a ``path/to/file.py:Class`` target: relative to a folder given with
    --config-dir (the first that has it), else to the working folder."""
    path = Path(file)
    dirs = config_dirs()
    if not path.is_absolute():
        path = next((d / path for d in dirs if (d / path).is_file()), path)
    if not path.is_file():
        raise TavcError(f"learner.target: no file {file} (looked in {', '.join(map(str, dirs))}"
                        f"{' and ' if dirs else ''}the working folder)")
    return path


def load_target(target: str) -> type:
    """The class ``learner.target`` names: ``package.module.Class`` (importable), or
    ``path/to/file.py:Class`` (`target_file`)."""
    if ":" in target:
        file, _, name = target.rpartition(":")
        path = target_file(file)
        module_name = f"tavc_plugin_{zlib.crc32(str(path.resolve()).encode()):08x}"
        module = sys.modules.get(module_name)
        if module is None:
            spec = importlib.util.spec_from_file_location(module_name, path)
            module = importlib.util.module_from_spec(spec)
            sys.modules[module_name] = module
            try:
                spec.loader.exec_module(module)
            except BaseException as error:  # noqa: BLE001 - the user's file: one line naming it
                del sys.modules[module_name]
                if isinstance(error, KeyboardInterrupt):
                    raise
                raise TavcError(f"learner.target: {path} failed to load: {type(error).__name__}: {error}") from None
    else:
        module_path, _, name = target.rpartition(".")
        try:
            module = importlib.import_module(module_path)
        except KeyboardInterrupt:
            raise
        except BaseException as error:  # noqa: BLE001
            raise TavcError(f"learner.target: cannot import {module_path!r} ({type(error).__name__}: {error}); "
                            "give package.module.Class on the Python path, or path/to/file.py:Class") from None
    cls = getattr(module, name, None)
    if not inspect.isclass(cls):
        raise TavcError(f"learner.target: {target!r} names no class")
    for method in ("choose", "learn"):
        if not callable(getattr(cls, method, None)):
            raise TavcError(f"learner.target: {cls.__name__} has no method {method}(...); a learner chooses a circuit "
                            "(choose(robot, state)) and learns (learn(robot, state, action, reward, next_state))")
    return cls


def target_files(target: str) -> list[Path]:
    """The source files whose code a target's learner runs, as far as tavc can tell: a file
    target's file and the ``.py`` files beside it (modules it may import from its folder); a
    module target's file, or every ``.py`` file of the package it belongs to."""
    if ":" in target:
        path = target_file(target.rpartition(":")[0])
        return [path, *sorted(p for p in path.parent.glob("*.py") if p.name != path.name)]
    module_path = target.rpartition(".")[0]
    try:
        found = importlib.util.find_spec(module_path)
    except (ImportError, ValueError):
        found = None
    if found is None or not found.origin or not Path(found.origin).is_file():
        return []
    if "." not in module_path:
        return [Path(found.origin)]
    top = importlib.util.find_spec(module_path.split(".")[0])
    folders = list(top.submodule_search_locations or []) if top is not None else []
    return sorted(p for folder in folders for p in Path(folder).rglob("*.py"))


@cache
def _file_digest(path: Path, size: int, mtime_ns: int) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


def target_digest(target: str) -> str:
    """Digest of the code `target_files` names (each file's name and bytes, not where the
    folder lies): part of every trial key of the learner, so an edited learner is run again."""
    h = hashlib.sha256(target.encode())
    for path in target_files(target):
        stat = path.stat()
        h.update(path.name.encode())
        h.update(_file_digest(path, stat.st_size, stat.st_mtime_ns).encode())
    return h.hexdigest()[:16]


def check_params(cls: type, params: Mapping) -> None:
    """`params` against the signature of `cls.__init__`: every one a parameter it takes, every
    parameter it needs (beside `PLUGIN_ARGUMENTS`) given. One line naming the key otherwise."""
    signature = inspect.signature(cls.__init__)
    named = {k: p for k, p in list(signature.parameters.items())[1:]}
    takes_any = any(p.kind is inspect.Parameter.VAR_KEYWORD for p in named.values())
    missing = [k for k in PLUGIN_ARGUMENTS if k not in named and not takes_any]
    if missing:
        raise TavcError(f"learner.target: {cls.__name__}.__init__ must take {', '.join(PLUGIN_ARGUMENTS)} (it lacks "
                        f"{missing[0]})")
    known = [k for k, p in named.items() if k not in PLUGIN_ARGUMENTS
             and p.kind in (inspect.Parameter.POSITIONAL_OR_KEYWORD, inspect.Parameter.KEYWORD_ONLY)]
    for key in params:
        if key not in known and not takes_any:
            raise TavcError(f"learner.params.{key}: {cls.__name__} takes no parameter {key!r} "
                            f"(it takes: {', '.join(known) or 'none'})")
    for key in known:
        if named[key].default is inspect.Parameter.empty and key not in params:
            raise TavcError(f"learner.params.{key}: missing; {cls.__name__} needs it")


def check_choice(label: str, robot: int, state: int, answer: object, n_circuits: int) -> int:
    """A learner's `choose()` answer as the circuit it names: an integer (not a bool) from 0 to
    n_circuits - 1; anything else is one line naming the learner, the call and the value."""
    if (isinstance(answer, (int, np.integer)) and not isinstance(answer, bool)
            and 0 <= int(answer) < n_circuits):
        return int(answer)
    raise TavcError(f"learner {label}: choose(robot={robot}, state={state}) returned {answer!r} "
                    f"({type(answer).__name__}); it must return a circuit, an integer from 0 to {n_circuits - 1}")


def _short(value: object) -> str:
    text = repr(value)
    return text if len(text) <= 60 else text[:57] + "..."


class PluginLearner:
    """A learner from outside tavc as the simulator sees it: the class's own `choose` and
    `learn`, with what can go wrong in them turned into one line naming the learner (`TavcError`;
    a `KeyboardInterrupt` is the user's and passes), and its `q_tables()` checked for shape."""

    def __init__(self, learner: object, label: str, n_robots: int, n_circuits: int) -> None:
        """Wrap `learner` (labelled `label` in messages) for `n_robots` robots on `n_circuits`
        circuits; its `n_states` must be a positive integer."""
        self.learner, self.label = learner, label
        n_states = getattr(learner, "n_states", n_circuits)
        if isinstance(n_states, bool) or not isinstance(n_states, (int, np.integer)) or n_states < 1:
            raise TavcError(f"learner {label}: n_states is {_short(n_states)}; it must be a positive integer")
        self.n_states = int(n_states)
        self.shape = (n_robots, self.n_states, n_circuits)
        if callable(getattr(learner, "on_event", None)):  # told of events, as the model's learners are
            self.on_event = lambda alive, values: self._call("on_event", alive, values)

    def _call(self, method: str, *args):
        try:
            return getattr(self.learner, method)(*args)
        except KeyboardInterrupt:
            raise
        except BaseException as error:  # noqa: BLE001 - the learner's own: one line naming it
            called = f"{method}({', '.join(_short(a) for a in args)})"
            raise TavcError(f"learner {self.label}: {called} raised {type(error).__name__}"
                            f"{': ' + str(error) if str(error) else ''}") from None

    def choose(self, robot: int, state: int) -> object:
        """The learner's own `choose`, its errors as one line."""
        return self._call("choose", robot, state)

    def learn(self, robot: int, state: int, action: int, reward: float, next_state: int) -> None:
        """The learner's own `learn`, its errors as one line."""
        self._call("learn", robot, state, action, reward, next_state)

    def q_tables(self) -> np.ndarray | None:
        """The learner's Q-tables, (n_robots, n_states, n_circuits), or None without them."""
        if not callable(getattr(self.learner, "q_tables", None)):
            return None
        q = self._call("q_tables")
        if q is None:
            return None
        try:
            q = np.array(q, dtype=np.float64)
        except (TypeError, ValueError):
            raise TavcError(f"learner {self.label}: q_tables() returned {_short(q)}; it must return an array of "
                            f"numbers of shape {self.shape} (robots, states, circuits), or None") from None
        if q.shape != self.shape:
            raise TavcError(f"learner {self.label}: q_tables() has shape {q.shape}; it must be {self.shape} "
                            "(robots, states, circuits), or None")
        return q


def plugin_policy(spec: PluginSettings, n_robots: int, n_circuits: int, rng: np.random.Generator) -> PluginLearner:
    """A learner from outside tavc: `spec.target` built with `spec.params`, behind `PluginLearner`;
    one without `q_tables` has none to show, one without `n_states` has one state a circuit."""
    cls = load_target(str(spec.target))
    params = dict(spec.params or {})
    check_params(cls, params)
    label = str(spec.name)
    try:
        learner = cls(n_robots=n_robots, n_circuits=n_circuits, rng=rng, **params)
    except KeyboardInterrupt:
        raise
    except BaseException as error:  # noqa: BLE001
        raise TavcError(f"learner {label}: {cls.__name__}(...) raised {type(error).__name__}"
                        f"{': ' + str(error) if str(error) else ''}") from None
    return PluginLearner(learner, label, n_robots, n_circuits)


REHEARSAL_TASKS = 25  # tasks per robot in `rehearse`'s made-up run
REHEARSAL_SEED = 20060101


def _global_states() -> tuple:
    return random.getstate(), np.random.get_state()


def _same_states(a: tuple, b: tuple) -> bool:
    (python_a, numpy_a), (python_b, numpy_b) = a, b
    return python_a == python_b and all(
        np.array_equal(x, y) if isinstance(x, np.ndarray) else x == y for x, y in zip(numpy_a, numpy_b, strict=True))


def rehearse(spec: PluginSettings, n_robots: int, n_circuits: int) -> list[str]:
    """Drive the learner through a short made-up run (each robot `REHEARSAL_TASKS` tasks, rewards
    that depend on the circuit), twice from the same seed, before any trial: an answer a trial
    would refuse is refused here (`TavcError`, one line). Returns warnings: a learner that draws
    from Python's or numpy's global generators, or whose two runs differ, gives trials that differ
    between identical commands. The global generators are left as they were."""
    before = _global_states()
    runs = []
    try:
        for _ in range(2):
            learner = plugin_policy(spec, n_robots, n_circuits, np.random.default_rng(REHEARSAL_SEED))
            state = [robot % n_circuits for robot in range(n_robots)]
            answers = []
            for task in range(REHEARSAL_TASKS):
                for robot in range(n_robots):
                    circuit = check_choice(learner.label, robot, state[robot],
                                           learner.choose(robot, state[robot]), n_circuits)
                    reward = (1.0 + circuit) / (1.0 + (robot + task) % 3)
                    learner.learn(robot, state[robot], circuit, reward, circuit)
                    state[robot] = circuit
                    answers.append(circuit)
            q = learner.q_tables()
            runs.append((answers, None if q is None else q.tobytes()))
        drew = not _same_states(before, _global_states())
    finally:
        random.setstate(before[0])
        np.random.set_state(before[1])
    label = str(spec.name)
    if drew:
        return [f"learner {label} draws from Python's or numpy's global random generator: its trials will differ "
                "between identical commands; draw every random number from the rng it is given"]
    if runs[0] != runs[1]:
        return [f"learner {label} answered the same calls differently from the same seed: its trials will differ "
                "between identical commands; draw every random number from the rng it is given"]
    return []
