"""tavc: a reproduction of task allocation through vacancy chains in multi-robot transportation."""

from __future__ import annotations

import os

# Nothing more is imported here: `python -m tavc_cli` and the `tavc` script import this package
# before the entry point installs its Ctrl-C handler, so what loads here is a window in which an
# interrupt would print a traceback. The functions below load what they need when called.
TYPE_CHECKING = False
if TYPE_CHECKING:
    from collections.abc import Sequence
    from pathlib import Path

__version__ = "0.2.0"

# The packages whose source compiled (numba) code is made from: the kernels themselves and
# the modules whose constants and record layouts they freeze in when compiled.
COMPILED_SOURCES = ("kernel.py", "vocabulary.py", "sim", "behaviours", "learning", "experiments")


def source_digest(root: Path, parts: Sequence[str]) -> str:
    """Digest of the source files `parts` under `root` (a part not ending in .py is a package
    folder and stands for every .py file in it), their paths relative to `root` included."""
    import hashlib  # deferred: kept out of the package's import (above)

    h = hashlib.sha256()
    for part in parts:
        path = root / part
        for f in [path] if path.suffix == ".py" else sorted(path.rglob("*.py")):
            h.update(f.relative_to(root).as_posix().encode())
            h.update(f.read_bytes())
    return h.hexdigest()[:16]


def meaning_digest(root: Path, parts: Sequence[str]) -> str:
    """Digest of what the source files `parts` under `root` compute (as `source_digest` names
    them): each file's syntax tree without its docstrings, comments or layout, its path relative
    to `root` included. Rewording a docstring or rewrapping a line leaves it as it is; any change
    to the code changes it. The tree is Python's own, so the digest is that of one minor version
    of Python."""
    import ast  # deferred: only for a digest, not on the command line's path before its interrupt handler
    import hashlib  # deferred: kept out of the package's import (above)

    h = hashlib.sha256()
    for part in parts:
        path = root / part
        for f in [path] if path.suffix == ".py" else sorted(path.rglob("*.py")):
            tree = ast.parse(f.read_bytes(), filename=str(f))
            for node in ast.walk(tree):
                body = getattr(node, "body", None)
                if (isinstance(node, (ast.Module, ast.ClassDef, ast.FunctionDef, ast.AsyncFunctionDef)) and body
                        and isinstance(body[0], ast.Expr) and isinstance(body[0].value, ast.Constant)
                        and isinstance(body[0].value.value, str)):
                    node.body = body[1:] or [ast.Pass()]
            h.update(f.relative_to(root).as_posix().encode())
            h.update(ast.dump(tree, include_attributes=False).encode())
    return h.hexdigest()[:16]


def compiled_code_digest(root: Path) -> str:
    """Digest of every source file under `root`'s `COMPILED_SOURCES` packages."""
    return source_digest(root, COMPILED_SOURCES)


def compiled_code_cache(root: Path, home: Path) -> Path:
    """The folder under `home` for the compiled kernels of the source under `root`, named by
    `compiled_code_digest`."""
    return home / compiled_code_digest(root)


def compiled_code_home(root: Path) -> Path:
    """Where the compiled kernels of the source under `root` are kept, one folder per version of
    that source: beside the source, or in the user's cache for an installed, read-only copy."""
    from pathlib import Path  # deferred: kept out of the package's import (above)

    if os.access(root, os.W_OK):
        return root / "__pycache__" / "numba"
    return Path(os.environ.get("XDG_CACHE_HOME", Path.home() / ".cache")) / "tavc" / "numba"


def prune_compiled_code(root: Path, home: Path) -> None:
    """Remove the folders under `home` of other versions of the source under `root` (the command
    line does it when it starts; nothing does it on import)."""
    import shutil  # deferred: kept out of the package's import (above)

    keep = compiled_code_cache(root, home)
    if home.is_dir():
        for old in home.iterdir():
            if old != keep:
                shutil.rmtree(old, ignore_errors=True)
