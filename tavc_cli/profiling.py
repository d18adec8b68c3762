"""Where the robot loop's time goes: `tavc bench --profile`.

Linux's `perf` samples the whole process, C libraries and compiled kernels alike, but
numba's code sits in anonymous memory that perf cannot name. Here the kernels are compiled
afresh in this process (numba's cache is bypassed: code loaded from it keeps no symbols),
every function of the engine's two entry points (`tick.run_ticks` and
`tick.sense_decide_command`, with the kernels linked into them) is written to perf's map of
this process (`/tmp/perf-PID.map`, which perf reads for code it found no file for), and
perf records only while the batch runs, not while it compiles. The samples are then
summed by what they do: the laser, the behaviours, physics and so on.
"""

from __future__ import annotations

import os
import re
import shutil
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from tavc_cli.errors import TavcError
from tavc_cli.experiments import tick

# (share of the samples, symbol) rows are grouped by the first rule that matches their object
# file or their function's qualified name
GROUPS = (
    ("laser", r"sim\.sensors\.(cast_laser|_exit_wall|ray_)"),
    ("camera", r"sim\.sensors\.(camera_nearest|markings_visible)"),
    ("odometry", r"sim\.sensors\.odometry_update"),
    ("behaviours", r"tavc_cli\.behaviours\.(motion|docking|navigation\.behave)"),
    ("kernel glue (tick, control_tick)", r"tavc_cli\.(experiments\.tick|behaviours\.navigation\.control_tick)"),
    ("reading and writing the bodies", r"tavc_cli\.sim\.world|cpBodyGet|cpBodySet|cpBodyActivate|pmFloatArray|"
                                       r"pmSpaceBody|cpSpaceEachBody"),
    ("Chipmunk (stepping)", r"_chipmunk"),
    ("C maths library (sin, cos, atan2, fmod)", r"libm\.so|numba_fmod|libm-"),
    ("other compiled kernels", r"tavc_cli\."),
    ("Python, numpy and random draws", r"libpython|_multiarray|_generator|_pcg64|python3"),
)


def readable(mangled: str) -> str:
    """numba's mangled name `_ZN8tavc_cli3sim7sensors10cast_laserB2v7...` as
    `tavc_cli.sim.sensors.cast_laser` (the qualified Python name it encodes)."""
    if not mangled.startswith("_ZN"):
        return mangled
    parts, i = [], 3
    while i < len(mangled) and mangled[i].isdigit():
        j = i
        while j < len(mangled) and mangled[j].isdigit():
            j += 1
        n = int(mangled[i:j])
        parts.append(mangled[j:j + n])
        i = j + n
    return ".".join(parts) or mangled


def _tavc_dispatchers() -> list:
    """Every compiled kernel (numba dispatcher) of the loaded tavc modules."""
    # deferred: loads the simulator's compiled kernels
    from numba.core.dispatcher import Dispatcher

    found = {}
    for name, module in list(sys.modules.items()):
        if name.startswith("tavc_cli.") and module is not None:
            for value in vars(module).values():
                if isinstance(value, Dispatcher):
                    found[id(value)] = value
    return list(found.values())


def compile_afresh() -> None:
    """Make every tavc kernel not compiled yet in this process compile here instead of loading
    from numba's cache (and leave the cache as it is)."""
    # deferred: loads the simulator's compiled kernels
    from numba.core.caching import NullCache

    for dispatcher in _tavc_dispatchers():
        dispatcher._cache = NullCache()


def write_perf_map(dispatchers, pid: int | None = None) -> tuple[Path, int]:
    """Write perf's map for this process: every function defined in the compiled overloads of
    `dispatchers`, by address, with its readable name (a function's extent runs to the next
    one's start). Returns the map's path and how many functions it names."""
    entries: dict[int, str] = {}
    for dispatcher in dispatchers:
        for cres in dispatcher.overloads.values():
            library = cres.library
            module = getattr(library, "_final_module", None)
            for fn in (module.functions if module is not None else []):
                if fn.is_declaration:
                    continue
                try:
                    address = library.get_pointer_to_function(fn.name)
                except Exception:  # noqa: BLE001 - a function the engine cannot hand out is left unnamed
                    continue
                if address:
                    entries.setdefault(address, readable(fn.name))
    path = Path(tempfile.gettempdir()) / f"perf-{pid or os.getpid()}.map"
    starts = sorted(entries)
    with open(path, "w") as out:
        for start, end in zip(starts, [*starts[1:], None], strict=False):  # the last has no next
            size = min((end or start + 65536) - start, 1 << 20)
            out.write(f"{start:x} {size:x} {entries[start]}\n")
    return path, len(starts)


def group_of(dso: str, symbol: str) -> str:
    """The `GROUPS` name of the first pattern matching the library and symbol, else ``other``."""
    where = f"{dso} {symbol}"
    for name, pattern in GROUPS:
        if re.search(pattern, where):
            return name
    return "other"


def parse_report(text: str) -> list[tuple[float, str, str]]:
    """(percent, object, symbol) rows of `perf report --stdio -t ,` output."""
    rows = []
    for line in text.splitlines():
        fields = [f.strip() for f in line.split(",")]
        if len(fields) < 3 or not fields[0].endswith("%"):
            continue
        try:
            share = float(fields[0].rstrip("%"))
        except ValueError:
            continue
        symbol = ",".join(fields[2:]).removeprefix("[.]").removeprefix("[k]").strip()
        dso = "compiled kernel" if fields[1].startswith("[JIT]") else fields[1]
        rows.append((share, dso, symbol))
    return rows


def run_profile(specs, perf: str | None = None) -> dict:
    """Profile one batch of trials (`specs`, sharing arena and robot model) with perf; return
    its simulated seconds per wall second, the share of the samples per group (`GROUPS`) and
    the top functions. Names only kernels this process has not compiled yet: call it in a
    process of its own, as `tavc bench --profile` is."""
    perf = perf or shutil.which("perf")
    if perf is None:
        raise TavcError("--profile: needs Linux's perf on the PATH (Debian: apt-get install linux-perf)")
    # deferred: loads the simulator's compiled kernels
    from tavc_cli.experiments.engine import BatchEngine

    compile_afresh()
    engine = BatchEngine(specs).compile()
    map_path, n_named = write_perf_map([tick.run_ticks, tick.sense_decide_command])
    with tempfile.TemporaryDirectory() as tmp:
        data = Path(tmp) / "perf.data"
        recorder = subprocess.Popen([perf, "record", "-q", "-F", "999", "-p", str(os.getpid()), "-o", str(data)],
                                    stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
        time.sleep(0.5)  # perf attaches
        start = time.perf_counter()
        engine.run()
        wall = time.perf_counter() - start
        recorder.send_signal(signal.SIGINT)
        _, err = recorder.communicate(timeout=60)
        if not data.is_file():
            raise TavcError(f"--profile: perf recorded nothing ({' '.join(err.split()) or 'no message'})")
        report = subprocess.run([perf, "report", "-i", str(data), "--stdio", "--no-children", "-g", "none",
                                 "--sort", "dso,sym", "-t", ","], capture_output=True, text=True, check=False)
    map_path.unlink(missing_ok=True)
    rows = parse_report(report.stdout)
    if not rows:
        raise TavcError(f"--profile: perf's report was empty ({' '.join(report.stderr.split()) or 'no message'})")
    total = sum(r[0] for r in rows)
    groups: dict[str, float] = {}
    for share, dso, symbol in rows:
        key = group_of(dso, symbol)
        groups[key] = groups.get(key, 0.0) + 100.0 * share / total
    return {
        "sim_seconds_per_wall_second": round(sum(s.span_s for s in specs) / wall, 1),
        "functions_named": n_named,
        "groups_pct": {k: round(v, 1) for k, v in sorted(groups.items(), key=lambda kv: -kv[1])},
        "top": [{"pct": round(100.0 * share / total, 2), "object": dso, "function": symbol}
                for share, dso, symbol in sorted(rows, reverse=True)[:15]],
    }
