"""The layering the code promises: Hydra stays at the front doors, analysis above the runner."""

import ast
import os
import shutil
import subprocess
import sys
from pathlib import Path

from tests.helpers import modules_reached

PACKAGE = Path(__file__).resolve().parent.parent / "tavc_cli"
FRONT_DOORS = {"cli.py", "commands.py", "api.py", "__main__.py"}  # commands.py: what each command of cli.py does


def _imports(path: Path) -> set[str]:
    names = set()
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.Import):
            names.update(alias.name for alias in node.names)
        elif isinstance(node, ast.ImportFrom) and node.module:
            names.add(node.module)
            names.update(f"{node.module}.{alias.name}" for alias in node.names)
    return names


def _library_modules():
    for path in sorted(PACKAGE.rglob("*.py")):
        rel = path.relative_to(PACKAGE)
        if rel.parts[0] == "config" or str(rel) in FRONT_DOORS:
            continue
        yield rel, _imports(path)


def test_nothing_below_the_front_doors_imports_the_config_package_or_hydra():
    offenders = [str(rel) for rel, names in _library_modules()
                 if any(n == "tavc_cli.config" or n.startswith(("tavc_cli.config.", "hydra")) for n in names)]
    assert offenders == []


def test_the_runner_does_not_analyse():
    names = _imports(PACKAGE / "experiments" / "runner.py")
    assert not any(n.startswith("tavc_cli.analysis") for n in names)


def test_compiled_kernels_are_cached_per_version_of_their_source(tmp_path):
    """numba's own cache would keep a kernel compiled against an older copy of a function it
    inlined from another file; tavc keeps one cache folder per version of the compiled source."""
    import tavc_cli
    import tavc_cli.kernel  # noqa: F401 - sets numba's cache folder before its first kernel
    from tavc_cli import compiled_code_cache, compiled_code_digest, prune_compiled_code

    here = Path(tavc_cli.__file__).resolve().parent
    assert os.environ["NUMBA_CACHE_DIR"].endswith(compiled_code_digest(here))
    root = tmp_path / "src"
    for part in ("sim", "report"):
        shutil.copytree(here / part, root / part, ignore=shutil.ignore_patterns("__pycache__"))
    for part in ("kernel.py", "vocabulary.py"):
        shutil.copy(here / part, root / part)
    home = tmp_path / "cache"
    first = compiled_code_cache(root, home)
    first.mkdir(parents=True)
    (root / "report" / "text.py").write_text("# a file no kernel is made from\n")
    assert compiled_code_cache(root, home) == first and first.is_dir()
    sensors = root / "sim" / "sensors.py"
    sensors.write_text(sensors.read_text() + "\n# changed\n")
    second = compiled_code_cache(root, home)
    assert second != first and first.exists()  # finding the folder removes nothing
    prune_compiled_code(root, home)
    assert not first.exists()  # the old version's kernels are gone when the command line starts


def test_the_trial_key_covers_every_module_a_trial_runs():
    """A stored trial is reused while its key is unchanged, and the key digests the source
    that decides outcomes: every tavc module the engine reaches (through its imports, within
    the packages trials run in) must be in that digest."""
    from tavc_cli import COMPILED_SOURCES
    from tavc_cli.experiments.spec import _OUTCOME_CODE

    root = Path(__file__).resolve().parent.parent / "tavc_cli"
    covered = {p for p in _OUTCOME_CODE if p.endswith(".py")}
    dirs = [p for p in _OUTCOME_CODE if not p.endswith(".py")]
    seen = modules_reached(root, "experiments/engine.py", COMPILED_SOURCES)
    missing = sorted(p for p in seen if p not in covered and not any(p.startswith(d + "/") for d in dirs))
    assert not missing, f"modules a trial runs but its key does not digest: {missing}"


def test_the_trial_keys_code_digest_follows_code_not_words(tmp_path):
    """Rewording a docstring, a comment or the layout of the code that decides trials keeps every
    trial's key (and so every finished trial); changing one constant of it does not."""
    import tavc_cli
    from tavc_cli import meaning_digest
    from tavc_cli.experiments.spec import _OUTCOME_CODE, code_digest

    here = Path(tavc_cli.__file__).resolve().parent
    assert meaning_digest(here, _OUTCOME_CODE) == code_digest()
    root = tmp_path / "src"
    shutil.copytree(here / "sim", root / "sim", ignore=shutil.ignore_patterns("__pycache__"))
    base = meaning_digest(root, ("sim",))
    arena = root / "sim" / "arena.py"
    text = arena.read_text()
    reworded = text.replace('"""', '"""Reworded. ', 1) + "\n# a comment\n"
    arena.write_text(reworded.replace("\n\n\n", "\n\n\n\n", 1))
    assert meaning_digest(root, ("sim",)) == base
    arena.write_text(text + "\n_EXTRA = 1\n")
    assert meaning_digest(root, ("sim",)) != base


def test_importing_the_package_changes_nothing_in_the_process():
    """`import tavc_cli` (and its settings and API) installs no signal handler, sets no
    environment variable and removes no cache folder: the command line does those when it starts,
    numba's cache folder is set when the first kernel module loads."""
    script = ("import os, signal, sys; env = dict(os.environ); "
              "handlers = [signal.getsignal(s) for s in (signal.SIGINT, signal.SIGTERM)]; "
              "import tavc_cli, tavc_cli.settings, tavc_cli.api, tavc_cli.learning.registry; "
              "assert dict(os.environ) == env, set(os.environ) ^ set(env); "
              "assert [signal.getsignal(s) for s in (signal.SIGINT, signal.SIGTERM)] == handlers; "
              "assert 'numba' not in sys.modules; print('ok')")
    env = {k: v for k, v in os.environ.items() if k != "NUMBA_CACHE_DIR"}
    done = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, env=env, timeout=120)
    assert done.stdout.strip() == "ok", done.stderr


def _module_graph() -> dict[str, set[str]]:
    """tavc's modules and the modules of tavc each imports, wherever in the file (inside functions
    too), but for the imports only a type checker reads (`if TYPE_CHECKING:`)."""
    def name(path: Path) -> str:
        parts = list(path.relative_to(PACKAGE.parent).with_suffix("").parts)
        return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)

    modules = {name(p): p for p in PACKAGE.rglob("*.py")}

    def known(dotted: str) -> str:
        while dotted not in modules:
            dotted = dotted.rpartition(".")[0]
        return dotted

    graph = {}
    for module, path in modules.items():
        tree = ast.parse(path.read_text())
        typing_only = {id(n) for node in ast.walk(tree) if isinstance(node, ast.If)
                       and "TYPE_CHECKING" in ast.dump(node.test) for n in ast.walk(node)}
        deps = set()
        for node in ast.walk(tree):
            if id(node) in typing_only:
                continue
            if isinstance(node, ast.Import):
                deps.update(known(a.name) for a in node.names if a.name.startswith("tavc_cli"))
            elif isinstance(node, ast.ImportFrom) and (node.module or "").startswith("tavc_cli"):
                deps.update(known(f"{node.module}.{a.name}") for a in node.names)
        graph[module] = deps - {module}
    return graph


def test_no_module_imports_its_way_back_to_itself():
    graph = _module_graph()

    def reaches(start: str) -> set[str]:
        seen, todo = set(), list(graph[start])
        while todo:
            module = todo.pop()
            if module not in seen:
                seen.add(module)
                todo.extend(graph[module])
        return seen

    circles = sorted(m for m in graph if m in reaches(m))
    assert circles == []


def test_each_layer_imports_only_the_layers_below_it():
    """The vocabulary, the reader of its notation and of an override's key import nothing of tavc's; the compiled
    kernels' set-up only the package's digests; the simulator and behaviours no learner or trial
    code; the learners no simulator internals; the analysis no simulator; the model no analysis."""
    forbidden = {
        "tavc_cli.vocabulary": ("tavc_cli",),
        "tavc_cli.notation": ("tavc_cli",),
        "tavc_cli.override_keys": ("tavc_cli",),
        "tavc_cli.kernel": ("tavc_cli.",),
        "tavc_cli.sim": ("tavc_cli.learning", "tavc_cli.experiments", "tavc_cli.settings", "tavc_cli.analysis"),
        "tavc_cli.behaviours": ("tavc_cli.learning", "tavc_cli.experiments", "tavc_cli.settings"),
        "tavc_cli.learning": ("tavc_cli.sim", "tavc_cli.experiments", "tavc_cli.settings", "tavc_cli.analysis"),
        "tavc_cli.analysis": ("tavc_cli.sim",),
        "tavc_cli.model": ("tavc_cli.analysis",),
    }
    broken = []
    for module, deps in _module_graph().items():
        for layer, below in forbidden.items():
            if module == layer or module.startswith(layer + "."):
                broken += [f"{module} -> {d}" for d in deps
                           if any(d == b or d.startswith(b if b.endswith(".") else b + ".") for b in below)]
    assert broken == []


def test_the_analysis_reads_and_writes_no_file():
    """analysis/ works on the records and tables it is handed: a run's files are read by
    run_checks.py and run_tables.py (and the report, the pipeline), never below them; the chapter's
    own tables, package data, come through `reference`."""
    io_calls = {"open", "read_csv", "to_csv", "read_text", "write_text", "read_bytes", "write_bytes", "from_yaml",
                "load_json", "load_yaml", "read_bounded", "glob", "rglob", "is_file", "is_dir", "exists", "load",
                "save", "savez", "savez_compressed"}
    io_modules = ("tavc_cli.io", "tavc_cli.readers", "tavc_cli.run_checks", "tavc_cli.run_tables", "tavc_cli.outputs")
    found = [f"{path.relative_to(PACKAGE)}: imports {name}" for path in sorted((PACKAGE / "analysis").rglob("*.py"))
             for name in _imports(path) if name.startswith(io_modules)]
    for path in sorted((PACKAGE / "analysis").rglob("*.py")):
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.Call):
                name = node.func.attr if isinstance(node.func, ast.Attribute) else getattr(node.func, "id", "")
                if name in io_calls:
                    found.append(f"{path.relative_to(PACKAGE)}:{node.lineno}: {name}")
    assert found == []


def test_the_simulation_core_imports_neither_hydra_nor_omegaconf():
    """The core reads typed settings only: the config's machinery stays above it."""
    core = ("sim", "behaviours", "learning", "model", "analysis")
    found = [f"{path.relative_to(PACKAGE)}: {name}" for part in core for path in sorted((PACKAGE / part).rglob("*.py"))
             for name in _imports(path) if name.split(".")[0] in ("hydra", "omegaconf")]
    assert found == []



def test_no_module_is_over_400_lines():
    """A module past 400 lines holds more than one idea: split it where the ideas part."""
    long = {p.relative_to(PACKAGE).as_posix(): n for p in PACKAGE.rglob("*.py")
            if (n := len(p.read_text().splitlines())) > 400}
    assert long == {}


def _reasoned(lines: list[str], i: int) -> bool:
    """Whether the import on line i (0-based) says why it is inside a function: a `# deferred:`
    comment on it, or above it or above the run of imports it belongs to."""
    if "# deferred:" in lines[i]:
        return True
    j = i - 1
    while j >= 0:
        text = lines[j].strip()
        if text.startswith("#"):
            return text.startswith("# deferred:")
        if not text or text.startswith(("from ", "import ")) or text.endswith(",") or text == ")":
            j -= 1
            continue
        return False
    return False


def test_every_import_inside_a_function_says_why_it_is_there():
    """An import belongs at the top of its module unless an optional dependency or the cost of
    loading it says otherwise (`# deferred: loads matplotlib`); each one inside a function says so."""
    silent = []
    for path in sorted(PACKAGE.rglob("*.py")):
        lines = path.read_text().splitlines()
        for fn in ast.walk(ast.parse("\n".join(lines))):
            if isinstance(fn, (ast.FunctionDef, ast.AsyncFunctionDef)):
                silent += [f"{path.relative_to(PACKAGE)}:{node.lineno}" for node in ast.walk(fn)
                           if isinstance(node, (ast.Import, ast.ImportFrom)) and not _reasoned(lines, node.lineno - 1)]
    assert sorted(set(silent)) == []


def test_the_package_loads_no_more_than_it_needs_before_the_interrupt_handler():
    """`python -m tavc_cli` imports the package before its entry point installs the Ctrl-C
    handler: that import stays small (nothing but `os`, which the interpreter has loaded already:
    no `pathlib`, `shutil` or `hashlib`, let alone `numpy`; nothing of tavc's but itself), so an
    interrupt in the first hundredths of a second lands under the handler."""
    code = "import sys; before = set(sys.modules); import tavc_cli; print(sorted(set(sys.modules) - before))"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    loaded = set(ast.literal_eval(out))
    assert not loaded & {"pathlib", "shutil", "hashlib", "ast", "numpy", "pandas", "inspect", "typing"}
    assert {m for m in loaded if m.startswith("tavc_cli")} == {"tavc_cli"}
