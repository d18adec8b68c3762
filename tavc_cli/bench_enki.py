"""The Enki reference benchmark behind `tavc bench --against enki`.

Compiles ``bench/enki/enki_bench.cpp`` (the `two_circuits` scenario written for Enki, a C++ 2D
robot simulator) once into a cache folder, runs it and returns the JSON line it prints.
"""

from __future__ import annotations

import hashlib
import json
import os
import re
import shutil
import subprocess
from pathlib import Path

from tavc_cli.errors import TavcError

SOURCE = Path(__file__).resolve().parents[1] / "bench" / "enki" / "enki_bench.cpp"
FLAGS = ["-O2", "-std=c++17"]
LIBS = ["-lenki"]
INSTALL_HINT = "apt-get install -y libenki-dev"


def _cache_dir() -> Path:
    base = os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache"
    return Path(base) / "tavc" / "enki"


def _compiler() -> str:
    for name in ("c++", "g++"):
        found = shutil.which(name)
        if found:
            return found
    raise TavcError("no C++ compiler on PATH (c++ or g++) to build the Enki benchmark: apt-get install -y g++")


def build_enki_bench() -> Path:
    """Compile the Enki benchmark unless a binary of the same source and flags is cached.

    Returns:
        The path of the compiled ``enki_bench`` binary.

    Raises:
        TavcError: The source is missing (e.g. an installed wheel), or no compiler, no Enki
            headers or no Enki library was found, or the compilation failed.
    """
    if not SOURCE.is_file():
        raise TavcError(f"the Enki benchmark source {SOURCE} is not here (it ships with the repository, "
                        "not the installed package): run from a checkout of tavc")
    compiler = _compiler()
    key = hashlib.sha256(SOURCE.read_bytes() + " ".join([compiler, *FLAGS, *LIBS]).encode()).hexdigest()[:16]
    binary = _cache_dir() / f"enki_bench-{key}"
    if binary.is_file():
        return binary
    binary.parent.mkdir(parents=True, exist_ok=True)
    tmp = binary.with_name(f"{binary.name}.tmp{os.getpid()}")
    proc = subprocess.run([compiler, *FLAGS, str(SOURCE), *LIBS, "-o", str(tmp)], capture_output=True, text=True)
    if proc.returncode != 0:
        tmp.unlink(missing_ok=True)
        err = proc.stderr
        missing = re.search(r"(enki/[\w/.-]+\.h): No such file", err)
        if missing:
            raise TavcError(f"Enki is not installed (no header {missing.group(1)}): {INSTALL_HINT}")
        if "-lenki" in err:
            raise TavcError(f"Enki is not installed (the linker cannot find libenki): {INSTALL_HINT}")
        first = next((line for line in err.splitlines() if "error" in line), err.strip()[-300:])
        raise TavcError(f"compiling {SOURCE.name} failed: {first}")
    os.replace(tmp, binary)
    return binary


def run_enki(duration_s: float, repeats: int, n_robots: int = 6) -> dict:
    """Run the Enki benchmark: one 30 s warm-up, then `repeats` timed runs of `duration_s`.

    Args:
        duration_s: Simulated seconds per timed run.
        repeats: Number of timed runs, each in a fresh world; the figure is their median.
        n_robots: Robots in the arena.

    Returns:
        The benchmark's JSON object, with ``sim_seconds_per_wall_second`` (one world, one core),
        ``runs`` and ``arrivals`` (a sanity check that the robots did go round their circuits).

    Raises:
        TavcError: Building or running the benchmark failed, or an argument is out of range.
    """
    if duration_s <= 0 or repeats < 1 or n_robots < 1:
        raise TavcError(f"enki bench: need duration_s > 0, repeats >= 1, n_robots >= 1; "
                        f"got {duration_s}, {repeats}, {n_robots}")
    binary = build_enki_bench()
    proc = subprocess.run([str(binary), f"{duration_s:g}", str(int(repeats)), str(int(n_robots))],
                          capture_output=True, text=True)
    if proc.returncode != 0:
        msg = proc.stderr.strip() or f"exit status {proc.returncode}"
        if "libenki" in msg:
            raise TavcError(f"Enki's shared library is missing at run time: {INSTALL_HINT}")
        raise TavcError(f"the Enki benchmark failed: {msg.splitlines()[-1]}")
    try:
        return json.loads(proc.stdout.strip().splitlines()[-1])
    except (IndexError, json.JSONDecodeError) as exc:
        raise TavcError(f"the Enki benchmark printed no JSON: {proc.stdout.strip()[:200]!r}") from exc
