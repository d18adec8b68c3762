"""What several test modules need: the repository's root, the command line in a process of its
own or in this one, a folder's files by digest and those changed since, the settings of a small
run, and a run's robots' and Q-values' tables made by hand."""

from __future__ import annotations

import hashlib
import os
import subprocess
import sys
from collections.abc import Mapping, Sequence
from pathlib import Path

import pandas as pd

from tavc_cli.config import load_config, settings
from tavc_cli.settings import TavcConfig

REPO = Path(__file__).resolve().parent.parent


def tavc(*args: str, cwd: Path = REPO, env: Mapping[str, str] | None = None,
         timeout: float | None = None) -> subprocess.CompletedProcess:
    """`python -m tavc_cli ARGS` in a process of its own, run in `cwd`; its output captured as text."""
    return subprocess.run([sys.executable, "-m", "tavc_cli", *args], cwd=cwd, env=env, capture_output=True,
                          text=True, timeout=timeout)


def tavc_here(*args: str) -> subprocess.CompletedProcess:
    """`tavc ARGS` in this process, run in the repository's folder as `tavc` is, answered as `tavc`
    answers (a refusal or a short command needs no process of its own, and saves one's start); an
    exception tavc lets out is raised here, as the traceback its process would print."""
    # deferred: the command line loads its commands' modules
    from typer.testing import CliRunner

    from tavc_cli.cli import app

    here = os.getcwd()
    os.chdir(REPO)
    try:
        result = CliRunner().invoke(app, list(args), catch_exceptions=False)
    finally:
        os.chdir(here)
    return subprocess.CompletedProcess(["tavc", *args], result.exit_code, result.stdout, result.stderr)


def file_digests(folder: Path) -> dict[str, str]:
    """Every file under `folder` by its path, with its SHA-256."""
    return {p.relative_to(folder).as_posix(): hashlib.sha256(p.read_bytes()).hexdigest()
            for p in sorted(folder.rglob("*")) if p.is_file()}


def changed_files(before: dict[str, str], folder: Path) -> list[str]:
    """The files of `folder` added, removed or changed since `before` (`file_digests`)."""
    after = file_digests(folder)
    return sorted(name for name in before.keys() | after.keys() if before.get(name) != after.get(name))


# a breakdown run at smoke scale, two trials a controller: the finished run the report's tests read
SMOKE_BREAKDOWN = ("experiment=breakdown", "scale=smoke", "trials=2", "baseline_trials=2")


def run_settings(overrides: Sequence[str], out_dir: Path | str, *extra: str) -> TavcConfig:
    """The settings of `overrides`, the run written into `out_dir`, then `extra` overrides."""
    return settings(load_config([*overrides, f"output_dir={out_dir}", *extra]))


def modules_reached(root: Path, start: str, packages: Sequence[str]) -> set[str]:
    """Every module (a path below `root`, tavc_cli/) that `start` reaches through its `from
    tavc_cli... import` lines, following only modules of `packages` (top-level folders)."""
    import ast

    seen, todo = set(), [start]
    while todo:
        rel = todo.pop()
        if rel in seen:
            continue
        seen.add(rel)
        for node in ast.walk(ast.parse((root / rel).read_text())):
            if isinstance(node, ast.ImportFrom) and (node.module or "").startswith("tavc_cli."):
                path = node.module.removeprefix("tavc_cli.").replace(".", "/") + ".py"
                if path.split("/")[0] in packages:
                    todo.append(path)
    return seen


def then_interrupted(fn):
    """`fn` that, once done, raises KeyboardInterrupt: Ctrl-C right after it."""
    def done_then_stop(*args, **kwargs):
        fn(*args, **kwargs)
        raise KeyboardInterrupt

    return done_then_stop


# two runs' robots, trial 0's robots 0-3, as (kind, circuit): the same kind for robots 0, 2 and 3
KINDS_A = [("stayer", 0), ("stayer", 0), ("stayer", 1), ("alternator", -1)]
KINDS_B = [("stayer", 0), ("stayer", 1), ("stayer", 1), ("alternator", -1)]


def robots_table(kinds: list[tuple[str, int]], controller: str = "tavc", trial: int = 0) -> pd.DataFrame:
    """robots.csv rows for a trial's robots 0, 1, ...: (kind, circuit)."""
    return pd.DataFrame([{"controller": controller, "trial": trial, "robot": i, "kind": k, "circuit": c,
                          "n_choices": 50, "share_main": 1.0, "switch_rate": 0.0} for i, (k, c) in enumerate(kinds)])


def q_table(values: list[float], t_s: float = 0.0, controller: str = "tavc", trial: int = 0) -> pd.DataFrame:
    """q_values.csv rows at `t_s` for a trial's robots, robot i's table all `values[i]`."""
    return pd.DataFrame([{"controller": controller, "trial": trial, "robot": i, "t_s": t_s, "q_0_0": v, "q_0_1": v,
                          "q_1_0": v, "q_1_1": v} for i, v in enumerate(values)])
