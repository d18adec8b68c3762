"""A finished run's claims tested again, and its comparison with the chapter made again, by
today's rules: `tavc report` rewrites a run's `claims.csv` or `comparison.csv` that an older tavc
wrote otherwise, records it in the run's provenance, and leaves alone what is not tavc's, what lies
through a link, and what another command holds."""

import json
import os
import shutil
from dataclasses import replace

import pandas as pd
import pytest
from typer.testing import CliRunner

from tavc_cli import __version__, report
from tavc_cli import retest as R
from tavc_cli.cli import app
from tavc_cli.io import claim_folder, file_digest
from tavc_cli.settings import from_yaml
from tests.helpers import SMOKE_BREAKDOWN

runner = CliRunner()


@pytest.fixture
def one_run(finished_run):
    """A finished breakdown run (shared: only copies are changed), and its claims as this tavc writes them."""
    run = finished_run(*SMOKE_BREAKDOWN, name="breakdown")
    return run, (run / "claims.csv").read_text()


def _as_an_older_tavc_wrote_it(run, today: str) -> str:
    """Give the run a claims.csv in other words, its digest in provenance.json as the run recorded it."""
    older = today.replace("above random", "over random")
    assert older != today
    (run / "claims.csv").write_text(older)
    prov = json.loads((run / "provenance.json").read_text())
    prov["tables"]["claims.csv"] = file_digest(run / "claims.csv")
    (run / "provenance.json").write_text(json.dumps(prov, indent=2))
    return older


def _as_an_older_tavc_compared_it(run) -> tuple[str, str]:
    """Give the run a comparison.csv an older tavc would have written from a reference table one cell
    short, its digest recorded as the run recorded it; returns today's text and the older one."""
    today = (run / "comparison.csv").read_text()
    older = "".join(today.splitlines(keepends=True)[:-1])
    assert older != today and older.startswith("table,state,quantity,chapter,ours,difference\n")
    (run / "comparison.csv").write_text(older)
    prov = json.loads((run / "provenance.json").read_text())
    prov["tables"]["comparison.csv"] = file_digest(run / "comparison.csv")
    (run / "provenance.json").write_text(json.dumps(prov, indent=2))
    return today, older


def _copy(one_run, tmp_path):
    results = tmp_path / "results"
    shutil.copytree(one_run[0], results / "breakdown")
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
    assert "claims and comparisons made again by this tavc's rules: 1 run(s) under breakdown/" in result.output
    assert "now rewritten (1 claims.csv)" in result.output
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
    assert again.exit_code == 0 and "made again" not in again.output
    assert (run / "provenance.json").read_bytes() == record


def test_claims_up_to_date_are_left_as_the_run_wrote_them(one_run, tmp_path):
    results, run = _copy(one_run, tmp_path)
    record = (run / "provenance.json").read_bytes()
    result = runner.invoke(app, ["report", str(results)])
    assert result.exit_code == 0 and "made again" not in result.output
    assert (run / "provenance.json").read_bytes() == record
    assert (run / "claims.csv").read_text() == one_run[1]


def test_a_claims_file_tavc_did_not_write_is_left_alone(one_run, tmp_path):
    results, run = _copy(one_run, tmp_path)
    older = _as_an_older_tavc_wrote_it(run, one_run[1])
    manifest = json.loads((run / ".tavc.json").read_text())
    manifest["files"].remove("claims.csv")
    (run / ".tavc.json").write_text(json.dumps(manifest))
    result = runner.invoke(app, ["report", str(results)])
    assert result.exit_code == 0 and "made again" not in result.output
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
    assert "made again" not in result.output


def test_a_run_another_command_holds_is_left_to_it(one_run, tmp_path):
    results, run = _copy(one_run, tmp_path)
    older = _as_an_older_tavc_wrote_it(run, one_run[1])
    with claim_folder(run):
        result = runner.invoke(app, ["report", str(results)])
    assert result.exit_code == 0, result.output
    assert (run / "claims.csv").read_text() == older
    assert f"claims and comparison of {run} not made again (output_dir: {run} is in use by another tavc run" \
        in result.output
    # once the folder is free, the next report heals it
    assert runner.invoke(app, ["report", str(results)]).exit_code == 0
    assert (run / "claims.csv").read_text() == one_run[1]


def test_a_rewrite_stopped_between_its_two_writes_is_finished_by_the_next_report(one_run, tmp_path, monkeypatch):
    """The record is written first: stopped before the claims are, the run still checks out (the
    file has the digest the record says it had before) and the next report rewrites it."""
    results, run = _copy(one_run, tmp_path)
    older = _as_an_older_tavc_wrote_it(run, one_run[1])
    write = _stopped_at(monkeypatch, 2)  # the record written, the claims not yet
    with pytest.raises(KeyboardInterrupt):
        report.build_report(results)
    assert (run / "claims.csv").read_text() == older
    record = json.loads((run / "provenance.json").read_text())
    assert record["rewritten"]["claims.csv"]["replaced"] == file_digest(run / "claims.csv")
    assert record["tables"]["claims.csv"] != file_digest(run / "claims.csv")
    monkeypatch.setattr(R, "write_text_atomic", write)
    result = runner.invoke(app, ["report", str(results)])
    assert result.exit_code == 0, result.output
    assert (run / "claims.csv").read_text() == one_run[1]
    assert json.loads((run / "provenance.json").read_text())["tables"]["claims.csv"] == file_digest(run / "claims.csv")
    # once finished, the file before the rewrite no longer passes for the run's
    (run / "claims.csv").write_text(older)
    result = runner.invoke(app, ["report", str(results)])
    assert result.exit_code == 1 and "changed since its run wrote it" in result.output


def test_a_run_reached_through_a_link_is_never_written(one_run, tmp_path):
    results = tmp_path / "results"
    outside = tmp_path / "outside"
    shutil.copytree(one_run[0], outside)
    older = _as_an_older_tavc_wrote_it(outside, one_run[1])
    results.mkdir()
    (results / "breakdown").symlink_to(outside)
    before = {p.name: p.read_bytes() for p in outside.iterdir() if p.is_file()}
    assert R.retested_tables(results / "breakdown", results, from_yaml) == {}
    assert R.rewrite_tables(results / "breakdown", results, from_yaml) == []
    assert {p.name: p.read_bytes() for p in outside.iterdir() if p.is_file()} == before
    assert (outside / "claims.csv").read_text() == older
    # the same folder given as the results folder itself is the user's choice of where to write
    assert R.retested_tables(results / "breakdown", results / "breakdown", from_yaml) == {"claims.csv": one_run[1]}
    # a run in the results folder whose provenance.json is a link is not rewritten either
    inside = results / "inside"
    shutil.copytree(outside, inside)
    (inside / "provenance.json").rename(tmp_path / "provenance.json")
    (inside / "provenance.json").symlink_to(tmp_path / "provenance.json")
    assert R.retested_tables(inside, results, from_yaml) == {}


def test_a_run_beside_one_that_did_not_finish_is_left_as_it_is(one_run, tmp_path, monkeypatch):
    """A claim may compare a run with the run of another experiment beside it (claim 7); where that
    run did not finish (a damaged table, no provenance.json), the claims are left as they are,
    neither tested on its table nor as though it were absent. A run beside that no claim of this
    run's compares it with does not matter."""
    results, run = _copy(one_run, tmp_path)
    older = _as_an_older_tavc_wrote_it(run, one_run[1])
    beside = results / "initial_distribution"
    beside.mkdir()
    (beside / "trial_stats.csv").write_text('controller,"trial\n')
    assert R.retested_tables(run, results, from_yaml) == {"claims.csv": one_run[1]}  # compared with none
    # as if a claim about breakdown compared it with initial_distribution
    from tavc_cli import outputs

    compared = [(e, replace(c, against="initial_distribution") if e == "breakdown" else c) for e, c in R.claims()]
    monkeypatch.setattr(R, "claims", lambda: compared)
    monkeypatch.setattr(outputs, "claims", lambda: compared)
    assert R.retested_tables(run, results, from_yaml) == {}
    result = runner.invoke(app, ["report", str(results)])
    assert result.exit_code == 0, result.output
    assert (run / "claims.csv").read_text() == older and "made again" not in result.output
    # the run beside being run again (its settings and plan written, no table yet): not taken as absent
    (beside / "trial_stats.csv").unlink()
    shutil.copy(run / "config.yaml", beside / "config.yaml")
    assert R.retested_tables(run, results, from_yaml) == {}
    # and no folder there at all: a run not made, as tavc run takes it
    shutil.rmtree(beside)
    assert R.retested_tables(run, results, from_yaml) == {"claims.csv": one_run[1]}


def test_a_record_of_rewritten_files_that_is_not_one_is_refused_before_anything_is_written(one_run, tmp_path):
    results, run = _copy(one_run, tmp_path)
    record = json.loads((run / "provenance.json").read_text())
    record["rewritten"] = None
    (run / "provenance.json").write_text(json.dumps(record))
    result = runner.invoke(app, ["report", str(results)])
    assert result.exit_code == 1
    assert result.output.strip() == (f"error: {run / 'provenance.json'}: cannot be read (its rewritten files are not "
                                     "a map of file names to records); rerun its experiment to rewrite it")
    assert sorted(p.name for p in results.iterdir()) == ["breakdown"]


_REPORTING = os.getpid()
_CHECK_RUN = report._check_run


def _dies_in_a_check_process(folder, root):
    if os.getpid() != _REPORTING:
        os._exit(9)
    return _CHECK_RUN(folder, root)


def test_where_a_check_process_dies_the_report_still_finds_the_claims_to_rewrite(one_run, tmp_path, monkeypatch):
    results, run = _copy(one_run, tmp_path)
    _as_an_older_tavc_wrote_it(run, one_run[1])
    monkeypatch.setattr(report, "_check_run", _dies_in_a_check_process)
    result = runner.invoke(app, ["report", str(results)])
    assert result.exit_code == 0, result.output
    assert (run / "claims.csv").read_text() == one_run[1]


def _stopped_at(monkeypatch, n: int):
    """Make the re-test's n-th write (counting from 1) stop the report, as a kill would."""
    write, count = R.write_text_atomic, [0]

    def stopped(path, text, root=None):
        count[0] += 1
        if count[0] == n:
            raise KeyboardInterrupt
        write(path, text, root)

    monkeypatch.setattr(R, "write_text_atomic", stopped)
    return write


def test_a_run_that_had_no_claims_file_and_whose_rewrite_stopped_still_checks_out(one_run, tmp_path, monkeypatch):
    results, run = _copy(one_run, tmp_path)
    (run / "claims.csv").unlink()
    record = json.loads((run / "provenance.json").read_text())
    del record["tables"]["claims.csv"]
    (run / "provenance.json").write_text(json.dumps(record, indent=2))
    write = _stopped_at(monkeypatch, 2)  # the record written, the claims not yet
    with pytest.raises(KeyboardInterrupt):
        report.build_report(results)
    assert not (run / "claims.csv").exists()
    assert json.loads((run / "provenance.json").read_text())["rewritten"]["claims.csv"]["replaced"] is None
    monkeypatch.setattr(R, "write_text_atomic", write)
    result = runner.invoke(app, ["report", str(results)])
    assert result.exit_code == 0, result.output
    assert (run / "claims.csv").read_text() == one_run[1]


def test_a_rewrite_stopped_before_its_last_record_is_finished_by_the_next_report(one_run, tmp_path, monkeypatch):
    results, run = _copy(one_run, tmp_path)
    _as_an_older_tavc_wrote_it(run, one_run[1])
    write = _stopped_at(monkeypatch, 3)  # the claims written, the record not yet told
    with pytest.raises(KeyboardInterrupt):
        report.build_report(results)
    left = run / ".provenance.json.k1ll3d0n.tmp"  # as a kill inside the last write leaves
    left.write_text("{")
    assert (run / "claims.csv").read_text() == one_run[1]
    assert "replaced" in json.loads((run / "provenance.json").read_text())["rewritten"]["claims.csv"]
    monkeypatch.setattr(R, "write_text_atomic", write)
    result = runner.invoke(app, ["report", str(results)])
    assert result.exit_code == 0 and "1 run(s)" in result.output, result.output
    assert "replaced" not in json.loads((run / "provenance.json").read_text())["rewritten"]["claims.csv"]
    assert not left.exists()


def test_claims_that_todays_rules_do_not_know_are_left_as_they_are(one_run, tmp_path):
    """A run of a user's own experiment, reported without its configs: its claims are not today's
    rules' to test, and its file is neither rewritten nor removed."""
    results, run = _copy(one_run, tmp_path)
    theirs = one_run[1].replace("\n6,", "\n99,", 1)
    assert theirs != one_run[1]
    (run / "claims.csv").write_text(theirs)
    record = json.loads((run / "provenance.json").read_text())
    record["tables"]["claims.csv"] = file_digest(run / "claims.csv")
    (run / "provenance.json").write_text(json.dumps(record, indent=2))
    assert R.retested_tables(run, results, from_yaml) == {}
    result = runner.invoke(app, ["report", str(results)])
    assert result.exit_code == 0 and "made again" not in result.output, result.output
    assert (run / "claims.csv").read_text() == theirs


def test_a_comparison_an_older_tavc_wrote_is_made_again_and_rewritten(one_run, tmp_path):
    """The comparison with the chapter's table is made from the run's state_time.csv; one that says
    otherwise is rewritten and recorded as the claims are, the claims (up to date) left as written."""
    results, run = _copy(one_run, tmp_path)
    today, _ = _as_an_older_tavc_compared_it(run)
    claims = (run / "claims.csv").read_bytes()
    assert R.retested_tables(run, results, from_yaml) == {"comparison.csv": today}
    result = runner.invoke(app, ["report", str(results)])
    assert result.exit_code == 0, result.output
    assert "1 run(s) under breakdown/" in result.output and "now rewritten (1 comparison.csv)" in result.output
    assert (run / "comparison.csv").read_text() == today
    assert (run / "claims.csv").read_bytes() == claims
    after = json.loads((run / "provenance.json").read_text())
    assert after["tables"]["comparison.csv"] == file_digest(run / "comparison.csv")
    assert list(after["rewritten"]) == ["comparison.csv"]
    again = runner.invoke(app, ["report", str(results)])
    assert again.exit_code == 0 and "made again" not in again.output


def test_a_comparison_tavc_did_not_write_is_left_while_the_claims_are_rewritten(one_run, tmp_path):
    results, run = _copy(one_run, tmp_path)
    _, older = _as_an_older_tavc_compared_it(run)
    _as_an_older_tavc_wrote_it(run, one_run[1])
    manifest = json.loads((run / ".tavc.json").read_text())
    manifest["files"].remove("comparison.csv")
    (run / ".tavc.json").write_text(json.dumps(manifest))
    assert R.retested_tables(run, results, from_yaml) == {"claims.csv": one_run[1]}
    result = runner.invoke(app, ["report", str(results)])
    assert result.exit_code == 0 and "now rewritten (1 claims.csv)" in result.output, result.output
    assert (run / "comparison.csv").read_text() == older
    assert (run / "claims.csv").read_text() == one_run[1]


def test_a_rewrite_of_both_files_stopped_between_them_is_finished_by_the_next_report(one_run, tmp_path, monkeypatch):
    """Both files recorded first; stopped with the comparison written and the claims not, the run
    checks out (one file as rewritten, the other as the run had it) and the next report finishes it."""
    results, run = _copy(one_run, tmp_path)
    today, _ = _as_an_older_tavc_compared_it(run)
    older = _as_an_older_tavc_wrote_it(run, one_run[1])
    write = _stopped_at(monkeypatch, 3)  # the record and the comparison written, the claims not yet
    with pytest.raises(KeyboardInterrupt):
        report.build_report(results)
    assert (run / "comparison.csv").read_text() == today and (run / "claims.csv").read_text() == older
    assert set(json.loads((run / "provenance.json").read_text())["rewritten"]) == {"comparison.csv", "claims.csv"}
    monkeypatch.setattr(R, "write_text_atomic", write)
    result = runner.invoke(app, ["report", str(results)])
    assert result.exit_code == 0, result.output
    assert "now rewritten (1 comparison.csv, 1 claims.csv)" in result.output
    assert (run / "comparison.csv").read_text() == today and (run / "claims.csv").read_text() == one_run[1]
    record = json.loads((run / "provenance.json").read_text())
    assert all("replaced" not in r for r in record["rewritten"].values())
    assert {record["tables"][n] for n in ("comparison.csv", "claims.csv")} == \
        {file_digest(run / n) for n in ("comparison.csv", "claims.csv")}


def test_a_run_tests_its_claims_against_the_run_beside_it_only_as_that_run_wrote_it(one_run, tmp_path):
    """`tavc run` of breakdown_no_vacancy tests claim 7 on breakdown's trial_stats.csv beside it:
    where that run finished, the table is checked as the report checks it (an edited cell is one
    line naming it, not a number in the claims); a run there that did not finish, whose table may
    be an earlier run's, is no comparison."""
    from tavc_cli import config
    from tavc_cli.errors import TavcError
    from tavc_cli.outputs import _other_experiments

    results, run = _copy(one_run, tmp_path)
    made = _made_by(run)
    cfg = config.settings(config.load_config(["experiment=breakdown_no_vacancy", "scale=smoke"]))
    beside = results / "breakdown_no_vacancy"
    assert _other_experiments(cfg, beside, made)["breakdown"].equals(pd.read_csv(run / "trial_stats.csv"))
    lines = (run / "trial_stats.csv").read_text().splitlines(keepends=True)
    cells = lines[1].split(",")
    cells[3] = "0.9999"  # one score per second, the claim's number
    (run / "trial_stats.csv").write_text("".join([lines[0], ",".join(cells), *lines[2:]]))
    with pytest.raises(TavcError, match=f"^{run / 'trial_stats.csv'}: changed since its run wrote it"):
        _other_experiments(cfg, beside, made)
    (run / "provenance.json").unlink()  # being run again: its table may be the earlier run's
    assert _other_experiments(cfg, beside, made) == {"breakdown": "not finished"}
    (run / "trial_stats.csv").unlink()  # nor is a run there without its table yet
    assert _other_experiments(cfg, beside, made) == {"breakdown": "not finished"}
    os.rename(run / "config.yaml", run / "config.bak")  # no run made there
    assert _other_experiments(cfg, beside, made) == {}
    os.rename(run / "config.bak", run / "config.yaml")
    # a run whose claims compare it with none reads no run beside it, damaged or not
    shutil.copytree(run, results / "heterogeneous")
    breakdown = config.settings(config.load_config(["experiment=breakdown", "scale=smoke"]))
    assert _other_experiments(breakdown, run, made) == {}


def _made_by(run) -> dict:
    """What computed a run's trials, as its provenance.json records it (`runner.made_by`)."""
    from tavc_cli.run_provenance import made_by_of

    return made_by_of(json.loads((run / "provenance.json").read_text()))


def test_a_run_beside_made_otherwise_is_no_comparison_for_claims_7_and_8(one_run, tmp_path):
    """Claim 7 sets breakdown_no_vacancy's trials beside breakdown's, claim 8 value_change's: only
    where the two ran in the same world, team, learner, tasks and horizon, computed by the same
    code. A run beside that differs is named in the claim's parts in place of a comparison, by
    `tavc run` and by the report's retest alike; another seed is another sample of the same."""
    from tavc_cli import config
    from tavc_cli.analysis.claim_rules import claim_7, claim_8, unlike_run
    from tavc_cli.outputs import _other_experiments

    results, run = _copy(one_run, tmp_path)
    beside = results / "breakdown_no_vacancy"
    made = _made_by(run)

    def settings(*overrides):
        return config.settings(config.load_config(["experiment=breakdown_no_vacancy", "scale=smoke", *overrides]))

    def why(*differences):
        return {"breakdown": f"ran with other settings ({'; '.join(differences)})"}

    faster = settings("robot.speed_mps=0.3")
    # the run beside's value, then this one's; each robot of the team takes the robot's speed
    assert _other_experiments(faster, beside, made) == why("robot.speed_mps 0.25 (this run: 0.3)",
                                                           "team.members (other values)")
    assert _other_experiments(settings("seed=5"), beside, made)["breakdown"].equals(
        pd.read_csv(run / "trial_stats.csv"))
    # the horizon, by scale (conf/scale/: smoke 0.02, quick 0.25 of the chapter's durations; breakdown
    # warms up for 18,000 s of the chapter's before its event) or set by hand (5,000 s of its 27,000)
    assert _other_experiments(settings("scale=quick"), beside, made) == why(
        "duration_s (of the chapter's) 0.02 (this run: 0.25)", "convergence_s (of the chapter's) 0.02 (this run: 0.25)",
        "learning before the first event (s) 360.0 (this run: 4500.0)")
    assert _other_experiments(settings("duration_s=5000"), beside, made) == why(
        "duration_s (of the chapter's) 0.02 (this run: 0.185185185)",
        "convergence_s (of the chapter's) 0.02 (this run: 0.185185185)")
    other_code = {**made, "code_digest": "0" * 16}
    assert _other_experiments(settings(), beside, other_code) == why(
        f"the simulator's code {made['code_digest']} (this run: {'0' * 16})")
    plugin = {**made, "learner_code": {"mine.py:Mine": {"digest": "1" * 16, "files": ["mine.py"]}}}
    assert _other_experiments(settings(), beside, plugin) == why("the learner's code (other values)")

    # the report's retest, with this run's own record: a copy of the run beside as breakdown_no_vacancy's
    # at a faster robot's settings, its record of them rewritten to match
    shutil.copytree(run, beside)
    cfg = (beside / "config.yaml").read_text().replace("speed_mps: 0.25", "speed_mps: 0.3")
    (beside / "config.yaml").write_text(cfg.replace("experiment_name: breakdown", "experiment_name: "
                                                    "breakdown_no_vacancy"))
    record = json.loads((beside / "provenance.json").read_text())
    record["tables"]["config.yaml"] = file_digest(beside / "config.yaml")
    (beside / "provenance.json").write_text(json.dumps(record))
    assert R._finished_others(from_yaml(beside / "config.yaml"), beside, from_yaml) == why(
        "robot.speed_mps 0.25 (this run: 0.3)", "team.members (other values)")

    stats = pd.read_csv(run / "trial_stats.csv")
    reason = why("robot.speed_mps 0.25 (this run: 0.3)")["breakdown"]
    for rule, own in ((claim_7, "breakdown_no_vacancy"), (claim_8, "value_change")):
        texts = [p.text() for p in rule({own: stats, "breakdown": unlike_run(reason)})]
        compared = [t for t in texts if "against breakdown's" in t or "the same as breakdown's" in t]
        assert compared and all(f"breakdown beside it {reason}" in t for t in compared), texts


def test_a_reproduce_finishes_the_run_others_compare_with_first(tmp_path):
    """`tavc reproduce` finishes breakdown before the experiments whose claims compare with it,
    whatever order they are named in, so that their claims read it finished."""
    from tavc_cli import api

    results = tmp_path / "results"
    api.reproduce(["scale=smoke", "trials=2", "baselines=[]", "executor.n_jobs=1"],
                  experiments=["breakdown_no_vacancy", "breakdown"], results_dir=results)
    detail = pd.read_csv(results / "breakdown_no_vacancy" / "claims.csv").set_index("claim_id").loc[7, "detail"]
    assert "the same as breakdown's" in detail and "breakdown not" not in detail and "beside it" not in detail, detail


def test_the_reports_claims_compare_two_experiments_runs_only_where_they_were_made_alike(one_run, tmp_path):
    """The report tests claim 7 across its designated runs as each run tests its own: a
    breakdown_no_vacancy run of another exploration rate beside breakdown's is no comparison, in
    the run's claims.csv and in the report's."""
    results, run = _copy(one_run, tmp_path)
    result = runner.invoke(app, ["run", "experiment=breakdown_no_vacancy", *SMOKE_BREAKDOWN[1:], "learner.epsilon=0.5",
                                 f"output_dir={results / 'breakdown_no_vacancy'}"])
    assert result.exit_code == 0, result.output
    reason = "breakdown beside it ran with other settings (learner.epsilon 0.1 (this run: 0.5))"
    assert reason in pd.read_csv(results / "breakdown_no_vacancy" / "claims.csv").set_index("claim_id").loc[7, "detail"]
    result = runner.invoke(app, ["report", str(results)])
    assert result.exit_code == 0, result.output
    assert reason in pd.read_csv(results / "claims.csv").set_index("claim_id").loc[7, "detail"]
