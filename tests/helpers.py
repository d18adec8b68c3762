"""What several test modules need: the repository's root, the command line in a process of its
own, a folder's files by digest, and the settings of a small run."""

from __future__ import annotations

import hashlib
import subprocess
import sys
from collections.abc import Mapping, Sequence
from pathlib import Path

from tavc_cli.config import load_config, settings
from tavc_cli.settings import TavcConfig

REPO = Path(__file__).resolve().parent.parent


def tavc(*args: str, cwd: Path = REPO, env: Mapping[str, str] | None = None,
         timeout: float | None = None) -> subprocess.CompletedProcess:
    """`python -m tavc_cli ARGS` in a process of its own, run in `cwd`; its output captured as text."""
    return subprocess.run([sys.executable, "-m", "tavc_cli", *args], cwd=cwd, env=env, capture_output=True,
                          text=True, timeout=timeout)


def file_digests(folder: Path) -> dict[str, str]:
    """Every file under `folder` by its path, with its SHA-256."""
    return {p.relative_to(folder).as_posix(): hashlib.sha256(p.read_bytes()).hexdigest()
            for p in sorted(folder.rglob("*")) if p.is_file()}


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
