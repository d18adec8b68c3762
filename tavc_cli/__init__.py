"""tavc: a reproduction of task allocation through vacancy chains in multi-robot transportation."""

import _signal  # the interpreter's own: `signal` itself takes long enough to load to be interrupted
import os
import sys


def _interrupted_while_loading(signum, frame) -> None:
    """Ctrl-C or SIGTERM before the command line has loaded: nothing is written yet, so one
    line and out."""
    terminated = signum == _signal.SIGTERM
    os.write(2, b"error: terminated\n" if terminated else b"error: interrupted\n")
    os._exit(143 if terminated else 130)


# Started as the command line (`tavc`, `python -m tavc_cli`): Ctrl-C and SIGTERM are one line from
# here on, until `__main__.main` (Ctrl-C) and each command (SIGTERM, `console.user_errors`) take over.
if os.path.basename(sys.argv[0] if sys.argv else "") == "tavc" or getattr(sys, "orig_argv", [])[1:3] == [
        "-m", "tavc_cli"]:
    _signal.signal(_signal.SIGINT, _interrupted_while_loading)
    _signal.signal(_signal.SIGTERM, _interrupted_while_loading)

import hashlib  # noqa: E402 - after the handler: an interrupt while these load is one line too
import shutil  # noqa: E402
from collections.abc import Sequence  # noqa: E402
from pathlib import Path  # noqa: E402

__version__ = "0.1.0"

# The packages whose source compiled (numba) code is made from: the kernels themselves and
# the modules whose constants and record layouts they freeze in when compiled.
COMPILED_SOURCES = ("sim", "behaviours", "learning", "experiments")


def source_digest(root: Path, parts: Sequence[str]) -> str:
    """Digest of the source files `parts` under `root` (a part not ending in .py is a package
    folder and stands for every .py file in it), their paths relative to `root` included."""
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
    import ast  # only for a digest: not on the command line's path to its first output

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
    `compiled_code_digest`; the folders of other versions of the source are removed."""
    where = home / compiled_code_digest(root)
    if home.is_dir():
        for old in home.iterdir():
            if old != where:
                shutil.rmtree(old, ignore_errors=True)
    return where


def _use_compiled_code_cache() -> None:
    """Point numba's cache of compiled kernels at `compiled_code_cache`.

    numba checks a cached function against its own file only. A kernel that inlined a
    function, or froze a constant, from another file would otherwise be loaded from the
    cache unchanged after that file changed, and run the old code. With one folder per
    version of the source, any change compiles everything afresh. A NUMBA_CACHE_DIR set
    by the user is left alone.
    """
    if os.environ.get("NUMBA_CACHE_DIR"):
        return
    root = Path(__file__).resolve().parent
    home = root / "__pycache__" / "numba"
    if not os.access(root, os.W_OK):  # an installed, read-only copy
        home = Path(os.environ.get("XDG_CACHE_HOME", Path.home() / ".cache")) / "tavc" / "numba"
    where = str(compiled_code_cache(root, home))
    os.environ["NUMBA_CACHE_DIR"] = where
    if "numba.core.config" in sys.modules:  # numba came first and has read its settings already
        sys.modules["numba.core.config"].CACHE_DIR = where


_use_compiled_code_cache()
