"""The Python API (tavc_cli.api) as the README shows it, and its one-line errors."""

import re
from pathlib import Path

import pandas as pd
import pytest

from tavc_cli import api
from tavc_cli.errors import TavcError

README = Path(__file__).resolve().parents[1] / "README.md"


def _readme_example() -> str:
    text = README.read_text()
    match = re.search(r"<!-- api-example[^>]*-->\s*```python\n(.*?)```", text, re.S)
    assert match, "the README's API example is missing"
    return match.group(1)


def test_the_readme_example_runs(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(README.parent)  # it reads the committed results/ by relative path
    code = _readme_example().replace("/tmp/tavc-demo", str(tmp_path / "demo"))
    exec(compile(code, "README.md", "exec"), {})
    out = capsys.readouterr().out
    assert "state_time" in out and "claim_id" in out


def test_results_read_back_what_the_run_wrote(tmp_path):
    run = api.run(["experiment=breakdown", "scale=smoke"], output_dir=tmp_path / "b")
    written = pd.read_csv(tmp_path / "b" / "state_time.csv")
    pd.testing.assert_frame_equal(run.state_time, written)
    deliveries = run.events("deliveries")
    # every trial of every controller contributes, and each row is one delivery of its record
    records = run.records()
    assert len(deliveries) == sum(len(r.table("deliveries")["t_s"]) for r in records)
    assert set(deliveries["controller"]) == {r.meta["controller"] for r in records}
    assert run.config["experiment_name"] == "breakdown"
    # reading again reuses every finished trial and gives the same tables
    again = api.run(["experiment=breakdown", "scale=smoke"], output_dir=tmp_path / "b")
    pd.testing.assert_frame_equal(again.state_time, run.state_time)


def test_errors_are_one_line(tmp_path):
    with pytest.raises(TavcError, match="not a results folder"):
        api.load(tmp_path)
    (tmp_path / "config.yaml").write_text("seed: 0\n")
    res = api.load(tmp_path)
    with pytest.raises(TavcError, match="no table 'state_time'"):
        _ = res.state_time
    with pytest.raises(TavcError, match="no trial records"):
        res.events("deliveries")
    with pytest.raises(TavcError, match="no kind 'crashes'"):
        res.events("crashes")
    with pytest.raises(TavcError, match="team.n_robots"):
        api.run(["team.n_robots=-1"], output_dir=tmp_path / "x")


def test_reproduce_opens_each_experiments_results(tmp_path):
    together = api.reproduce(["scale=smoke", "trials=1", "baselines=[]"],
                             experiments=["breakdown_no_vacancy", "initial_distribution"], results_dir=tmp_path)
    assert sorted(together) == ["breakdown_no_vacancy", "initial_distribution"]
    for name, res in together.items():
        assert res.path == tmp_path / name and res.config["experiment_name"] == name
        assert len(res.records()) == 1
    with pytest.raises(TavcError, match="no experiment 'nope'"):
        api.reproduce(["scale=smoke"], experiments=["nope"], results_dir=tmp_path / "x")
    assert not (tmp_path / "x").exists()
