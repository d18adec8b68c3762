"""A finished run's claims tested again by today's rules: `tavc report` rewrites a run's
`claims.csv` that an older tavc wrote in other words, records it in the run's provenance, and
leaves alone what is not tavc's or what another command holds."""

import json
import shutil

import pandas as pd
import pytest
from typer.testing import CliRunner

from tavc_cli import __version__
from tavc_cli.cli import app
from tavc_cli.io import claim_folder, file_digest

runner = CliRunner()


@pytest.fixture(scope="module")
def one_run(tmp_path_factory):
    """A results folder holding one finished breakdown run, and its claims as this tavc writes them."""
    results = tmp_path_factory.mktemp("results")
    result = runner.invoke(app, ["run", "experiment=breakdown", "scale=smoke", "trials=2", "baseline_trials=2",
                                 f"output_dir={results / 'breakdown'}"])
    assert result.exit_code == 0, result.output
    return results, (results / "breakdown" / "claims.csv").read_text()


def _as_an_older_tavc_wrote_it(run, today: str) -> str:
    """Give the run a claims.csv in other words, its digest in provenance.json as the run recorded it."""
    older = today.replace("above random", "over random")
    assert older != today
    (run / "claims.csv").write_text(older)
    prov = json.loads((run / "provenance.json").read_text())
    prov["tables"]["claims.csv"] = file_digest(run / "claims.csv")
    (run / "provenance.json").write_text(json.dumps(prov, indent=2))
    return older


def _copy(one_run, tmp_path):
    results = tmp_path / "results"
    shutil.copytree(one_run[0], results)
    return results, results / "breakdown"


def test_claims_an_older_tavc_wrote_are_tested_again_and_rewritten(one_run, tmp_path):
    results, run = _copy(one_run, tmp_path)
    _as_an_older_tavc_wrote_it(run, one_run[1])
    others = {p.name: p.read_bytes() for p in run.iterdir() if p.is_file() and p.name not in (
        "claims.csv", "provenance.json", ".tavc.json")}
    before = json.loads((run / "provenance.json").read_text())
    result = runner.invoke(app, ["report", str(results)])
    assert result.exit_code == 0, result.output
    assert (run / "claims.csv").read_text() == one_run[1]
    assert "claims tested again by this tavc's rules: 1 run(s) under breakdown/" in result.output
    after = json.loads((run / "provenance.json").read_text())
    assert after["tables"]["claims.csv"] == file_digest(run / "claims.csv")
    assert after["rewritten"]["claims.csv"]["tavc_version"] == __version__
    # the rest of the record, and every other file of the run, as the run wrote them
    assert {k: v for k, v in after.items() if k not in ("tables", "rewritten")} == \
        {k: v for k, v in before.items() if k != "tables"}
    assert {k: v for k, v in after["tables"].items() if k != "claims.csv"} == \
        {k: v for k, v in before["tables"].items() if k != "claims.csv"}
    assert {p.name: p.read_bytes() for p in run.iterdir() if p.name in others} == others
    # the report on top tests the same claims: the run's file and the report's say the same
    cols = ["claim_id", "verdict", "detail"]
    own = pd.read_csv(run / "claims.csv")[cols]
    top = pd.read_csv(results / "claims.csv").set_index("claim_id").loc[own["claim_id"]].reset_index()[cols]
    assert own.equals(top)
    # a second report finds nothing to test again and touches nothing in the run
    record = (run / "provenance.json").read_bytes()
    again = runner.invoke(app, ["report", str(results)])
    assert again.exit_code == 0 and "tested again" not in again.output
    assert (run / "provenance.json").read_bytes() == record


def test_claims_up_to_date_are_left_as_the_run_wrote_them(one_run, tmp_path):
    results, run = _copy(one_run, tmp_path)
    record = (run / "provenance.json").read_bytes()
    result = runner.invoke(app, ["report", str(results)])
    assert result.exit_code == 0 and "tested again" not in result.output
    assert (run / "provenance.json").read_bytes() == record
    assert (run / "claims.csv").read_text() == one_run[1]


def test_a_claims_file_tavc_did_not_write_is_left_alone(one_run, tmp_path):
    results, run = _copy(one_run, tmp_path)
    older = _as_an_older_tavc_wrote_it(run, one_run[1])
    manifest = json.loads((run / ".tavc.json").read_text())
    manifest["files"].remove("claims.csv")
    (run / ".tavc.json").write_text(json.dumps(manifest))
    result = runner.invoke(app, ["report", str(results)])
    assert result.exit_code == 0 and "tested again" not in result.output
    assert (run / "claims.csv").read_text() == older
    assert "rewritten" not in json.loads((run / "provenance.json").read_text())


def test_a_claims_file_that_is_a_link_is_never_written_through(one_run, tmp_path):
    results, run = _copy(one_run, tmp_path)
    older = _as_an_older_tavc_wrote_it(run, one_run[1])
    elsewhere = tmp_path / "elsewhere.csv"
    (run / "claims.csv").rename(elsewhere)
    (run / "claims.csv").symlink_to(elsewhere)
    result = runner.invoke(app, ["report", str(results)])
    assert result.exit_code == 0, result.output
    assert (run / "claims.csv").is_symlink() and elsewhere.read_text() == older
    assert "tested again" not in result.output


def test_a_run_another_command_holds_is_left_to_it(one_run, tmp_path):
    results, run = _copy(one_run, tmp_path)
    older = _as_an_older_tavc_wrote_it(run, one_run[1])
    with claim_folder(run):
        result = runner.invoke(app, ["report", str(results)])
    assert result.exit_code == 0, result.output
    assert (run / "claims.csv").read_text() == older
    assert f"claims of {run} not tested again (output_dir: {run} is in use by another tavc run" in result.output
    # once the folder is free, the next report heals it
    assert runner.invoke(app, ["report", str(results)]).exit_code == 0
    assert (run / "claims.csv").read_text() == one_run[1]
