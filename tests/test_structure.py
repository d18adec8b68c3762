"""The layering the code promises: Hydra stays at the front doors, analysis above the runner."""

import ast
from pathlib import Path

PACKAGE = Path(__file__).resolve().parent.parent / "tavc_cli"
FRONT_DOORS = {"cli.py", "api.py", "__main__.py"}


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
