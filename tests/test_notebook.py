"""The example notebook (examples/tavc_api.ipynb) runs from top to bottom at scale=smoke, as a
reader would run it, and is committed without outputs."""

import json
import os
import tempfile
from pathlib import Path

import matplotlib
import pytest

REPO = Path(__file__).resolve().parents[1]
NOTEBOOK = REPO / "examples" / "tavc_api.ipynb"


def _cells(kind: str) -> list[dict]:
    return [c for c in json.loads(NOTEBOOK.read_text())["cells"] if c["cell_type"] == kind]


def test_the_notebook_is_committed_without_outputs():
    for cell in _cells("code"):
        assert cell["outputs"] == [] and cell["execution_count"] is None, "".join(cell["source"])[:60]


def test_the_notebook_runs_from_top_to_bottom(tmp_path, monkeypatch):
    """Every code cell in order, in one namespace, as a kernel would (no cell uses magics)."""
    matplotlib.use("Agg")
    monkeypatch.setenv("TAVC_NOTEBOOK_SCALE", "smoke")
    monkeypatch.setenv("TAVC_REPO", str(REPO))
    monkeypatch.setattr(tempfile, "tempdir", str(tmp_path))  # the notebook's runs go under the test's folder
    monkeypatch.chdir(tmp_path)  # nothing relies on the working folder
    namespace: dict = {}
    for k, cell in enumerate(_cells("code")):
        source = "".join(cell["source"])
        assert not any(line.lstrip().startswith(("%", "!")) for line in source.splitlines()), f"cell {k}"
        exec(compile(source, f"{NOTEBOOK.name}, code cell {k}", "exec"), namespace)
    assert namespace["committed"].not_a_verdict == ""
    assert namespace["mine"].not_a_verdict.startswith("not a verdict: scale=smoke")
    assert namespace["theirs"].config["learner"] == {
        "name": "running_mean", "target": f"{namespace['learner_file']}:RunningMean",
        "params": {"explore": 0.1}}
    scores = namespace["scores"]
    assert set(scores) == {"TAVC, epsilon 0.05", "running mean"} and all(s == s and s > 0 for s in scores.values())
    assert str(namespace["WORK"]).startswith(str(tmp_path)) and os.listdir(namespace["WORK"])


@pytest.mark.parametrize("name", ["SCALE", "REPO", "WORK"])
def test_the_notebook_says_where_it_reads_and_writes(name):
    assert any(name in "".join(c["source"]) for c in _cells("code")[:1])
