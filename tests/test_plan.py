"""The run plan: worked out once, written as plan.json before any trial, read back by the analysis,
the report and the API; a plan.json that is not the run's is refused."""

import json
import shutil
from pathlib import Path

import pytest
from typer.testing import CliRunner

from tavc_cli import api
from tavc_cli.cli import app
from tavc_cli.config import load_config
from tavc_cli.config import settings as to_settings
from tavc_cli.errors import TavcError
from tavc_cli.experiments.build import trial_specs
from tavc_cli.experiments.plan import PLAN_FILE, plan_run, read_plan

SMOKE = ["experiment=breakdown", "scale=smoke", "executor.n_jobs=1", "trials=2", "baseline_trials=2", "static_trials=1"]
runner = CliRunner()


@pytest.fixture
def finished(finished_run):
    """A finished smoke run of breakdown (the learner, random and static), shared: tests change copies."""
    return finished_run(*SMOKE, name="breakdown")


def test_the_plan_is_written_beside_the_run_and_vouched_for_by_provenance(finished):
    plan = json.loads((finished / PLAN_FILE).read_text())
    # by hand: the learner first, then the baselines as listed; seed codes tavc 0, random 1, static 2
    assert [(c["label"], c["trials"], c["seed_code"]) for c in plan["controllers"]] == [
        ("tavc", 2, 0), ("random", 2, 1), ("static", 1, 2)]
    assert plan["controllers"][0]["learner"]["name"] == "tavc_egreedy"
    assert plan["controllers"][2]["learner"] == {"name": "static", "allocation": [3, 3]}
    provenance = json.loads((finished / "provenance.json").read_text())
    assert PLAN_FILE in provenance["tables"]
    # the trials the run made are the plan's: controllers, seeds and counts
    seeds = sorted(tuple(t["seed"]) for t in provenance["trials"])
    assert seeds == sorted((0, c["seed_code"], j) for c in plan["controllers"] for j in range(c["trials"]))


def test_the_plan_read_back_is_the_plan_worked_out_and_gives_the_trials(finished):
    cfg = to_settings(load_config([*SMOKE, f"output_dir={finished}"]))
    plan = read_plan(finished, cfg)
    assert plan == plan_run(cfg) == api.load(finished).plan
    assert [s.key() for s in trial_specs(cfg, plan)] == [s.key() for s in trial_specs(cfg)]


def test_a_folder_without_a_plan_reads_the_plan_its_config_gives(finished, tmp_path):
    old = tmp_path / "old"
    shutil.copytree(finished, old)
    (old / PLAN_FILE).unlink()
    cfg = to_settings(load_config([*SMOKE, f"output_dir={finished}"]))
    assert read_plan(old, cfg) == plan_run(cfg)


def test_a_plan_of_another_run_or_not_a_plan_is_refused(finished, tmp_path):
    cfg = to_settings(load_config([*SMOKE, f"output_dir={finished}"]))
    other = tmp_path / "other"
    shutil.copytree(finished, other)
    data = json.loads((finished / PLAN_FILE).read_text())
    (other / PLAN_FILE).write_text(json.dumps({**data, "seed": 7}))
    with pytest.raises(TavcError, match="is not the plan of the config.yaml beside it"):
        read_plan(other, cfg)
    (other / PLAN_FILE).write_text(json.dumps({"version": 1, "controllers": "none"}))
    with pytest.raises(TavcError, match="not a plan tavc wrote"):
        read_plan(other, cfg)


def test_the_report_refuses_a_run_whose_plan_was_edited(finished, tmp_path):
    results = tmp_path / "results"
    shutil.copytree(finished, results / "breakdown")
    path: Path = results / "breakdown" / PLAN_FILE
    data = json.loads(path.read_text())
    data["controllers"][1]["schedule"]["convergence_s"] += 1.0
    path.write_text(json.dumps(data, indent=2))
    result = runner.invoke(app, ["report", str(results)])
    assert result.exit_code == 1 and "plan.json" in result.output, result.output
    assert not (results / "REPORT.md").exists()
