"""Fixtures the test modules share: finished runs, each made once per test process and kept as
it was written, and copies of them for the tests that damage, rerun or move a run.

Plain helpers (the command line in a process of its own, settings, hand-made tables) are in
`tests/helpers.py` and hand-made trial records in `tests/records.py`."""

from __future__ import annotations

import shutil
from collections.abc import Callable, Iterator
from pathlib import Path

import pytest

from tests.helpers import changed_files, file_digests, run_settings


@pytest.fixture(scope="session")
def finished_run(tmp_path_factory) -> Iterator[Callable[..., Path]]:
    """`finished_run(*overrides, name="run")`: the folder of a finished run of those overrides
    (`pipeline.run_experiment`, as `tavc run` computes it), written into a folder called `name`.
    It is made the first time a test asks for it and shared with every later test that asks for
    the same; read it, and change only a copy (`run_copy`). At the end of the session every file
    is checked against what the run wrote: a shared run that a test changed fails the session there,
    naming the files (reported as an error of the last test to use the fixture, not necessarily
    the one that changed it), since the tests that compare with the run would otherwise compare
    with its damage. The same overrides in another order make a run of their own."""
    # deferred: loads the simulator and scipy, which a session without a finished run does not need
    from tavc_cli.pipeline import run_experiment

    made: dict[tuple[str, ...], tuple[Path, dict[str, str]]] = {}

    def finished(*overrides: str, name: str = "run") -> Path:
        key = (name, *overrides)
        if key not in made:
            folder = tmp_path_factory.mktemp("finished") / name
            run_experiment(run_settings(overrides, folder))
            made[key] = folder, file_digests(folder)
        return made[key][0]

    yield finished
    changed = {folder: files for folder, before in made.values() if (files := changed_files(before, folder))}
    if changed:
        pytest.fail("a shared finished run was changed by a test: "
                    + "; ".join(f"{folder}: {', '.join(files)}" for folder, files in changed.items()))


@pytest.fixture
def run_copy(tmp_path) -> Callable[..., Path]:
    """`run_copy(run, into=None)`: a copy of the run folder `run` under this test's own folder (in
    `into`, below it, when given), with the run's folder name; the copy's path."""
    def copy(run: Path, into: str | None = None) -> Path:
        parent = tmp_path / into if into else tmp_path
        parent.mkdir(parents=True, exist_ok=True)
        return Path(shutil.copytree(run, parent / run.name))

    return copy
