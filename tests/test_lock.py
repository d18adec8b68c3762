"""The locked environment: requirements.lock pins every package tavc and its tests need, at
versions pyproject.toml allows, and the environment the tests run in is that one."""

import re
import tomllib
from importlib import metadata
from pathlib import Path

import pytest
from packaging.requirements import Requirement
from packaging.utils import canonicalize_name

ROOT = Path(__file__).resolve().parent.parent
# the packages whose versions decide the committed tables' bytes
NUMERICAL = ("numpy", "numba", "llvmlite", "pymunk", "scipy", "pandas", "matplotlib")


def _locked() -> dict[str, str]:
    pins = {}
    for line in (ROOT / "requirements.lock").read_text().splitlines():
        if line.strip() and not line.startswith("#"):
            name, _, version = line.partition("==")
            assert version and re.fullmatch(r"[\w.+!-]+", version), f"not an exact pin: {line!r}"
            pins[canonicalize_name(name)] = version
    return pins


def _required() -> list[Requirement]:
    project = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]
    return [Requirement(r) for r in [*project["dependencies"], *project["optional-dependencies"]["test"]]]


def test_the_lock_pins_every_requirement_at_a_version_pyproject_allows():
    pins = _locked()
    for requirement in _required():
        name = canonicalize_name(requirement.name)
        assert name in pins, f"{requirement.name} is not in requirements.lock"
        assert requirement.specifier.contains(pins[name], prereleases=True), (
            f"requirements.lock pins {requirement.name}=={pins[name]}, outside {requirement.specifier}")


@pytest.mark.parametrize("package", NUMERICAL)
def test_the_numerical_packages_installed_are_the_locked_ones(package):
    assert metadata.version(package) == _locked()[canonicalize_name(package)], (
        f"{package} {metadata.version(package)} is installed; the committed tables were made with the locked "
        "version (`make venv` installs it)")
