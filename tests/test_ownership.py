"""A command writes, replaces and deletes only what tavc wrote (`tavc_cli.ownership`): a folder
with somebody else's files, another command's output or another configuration's run is
refused with one line, and nothing in it changes."""

import json
import shutil
from functools import partial

import pytest
from typer.testing import CliRunner

from tavc_cli.cli import app
from tavc_cli.config import load_config, settings
from tavc_cli.errors import TavcError
from tavc_cli.io import LOCK_NAME
from tavc_cli.ownership import MANIFEST, REPORT_TITLE, config_differences, read
from tavc_cli.pipeline import run_experiment, write_ladder, write_sweep
from tests.helpers import run_settings

SMOKE = ["scale=smoke", "duration_s=60", "convergence_s=20", "arena=two_circuits", "learner=random",
         "executor.n_jobs=1", "trials=1"]


_cfg = partial(run_settings, SMOKE)  # the settings of a smoke run into a folder, then more overrides


def _snapshot(folder):
    """Every file under `folder` with its bytes."""
    return {str(p.relative_to(folder)): p.read_bytes() for p in sorted(folder.rglob("*")) if p.is_file()}


@pytest.fixture
def finished(finished_run):
    """A finished run, shared: each test that changes it changes a copy (`run_copy`)."""
    return finished_run(*SMOKE)


def test_a_run_lists_what_it_wrote(finished):
    manifest = json.loads((finished / MANIFEST).read_text())
    assert manifest["tavc"] == "run"
    tables = sorted(p.name for p in finished.glob("*.csv"))
    assert set(manifest["files"]) >= {"config.yaml", "plan.json", "provenance.json", *tables}
    provenance = json.loads((finished / "provenance.json").read_text())
    # every table, the config and the plan, each with its digest
    assert sorted(provenance["tables"]) == sorted([*tables, "config.yaml", "plan.json"])
    assert all(len(d) == 64 for d in provenance["tables"].values())


def test_a_folder_of_somebody_elses_files_is_refused_and_left_as_it_was(tmp_path):
    (tmp_path / "policy.csv").write_text("my policy\n")
    (tmp_path / "traversals.csv").write_text("my traversals\n")
    before = _snapshot(tmp_path)
    result = CliRunner().invoke(app, ["run", *SMOKE, f"output_dir={tmp_path}"])
    assert result.exit_code == 1
    assert result.output.strip().splitlines() == [
        f"error: output_dir: {tmp_path} holds files tavc did not write (policy.csv, traversals.csv); a run needs "
        "a new or empty folder, or one of its own earlier runs: choose another folder"]
    assert _snapshot(tmp_path) == before  # nothing deleted, nothing added (not even the lock)


def test_a_run_aimed_at_a_report_folder_is_refused(tmp_path):
    (tmp_path / "REPORT.md").write_text(f"{REPORT_TITLE}\n\nclaims...\n")
    (tmp_path / "claims.csv").write_text("claim_id,claim,verdict\n1,x,reproduced\n")
    before = _snapshot(tmp_path)
    with pytest.raises(TavcError, match=r"is a results folder with a tavc report on top \(REPORT.md\), not a "
                                        r"tavc run's folder; choose another folder$"):
        run_experiment(_cfg(tmp_path))
    assert _snapshot(tmp_path) == before


def test_a_run_aimed_at_a_sweeps_folder_and_a_sweep_at_a_run_are_refused(tmp_path, finished):
    (tmp_path / "sweep").mkdir()
    (tmp_path / "sweep" / "sweep.csv").write_text("job,seed\n")
    with pytest.raises(TavcError, match=r"is a tavc sweep's folder"):
        run_experiment(_cfg(tmp_path / "sweep"))
    with pytest.raises(TavcError, match=r"is a tavc run's folder, not a tavc sweep's folder"):
        write_sweep([{"seed": "1"}, {"seed": "2"}], [finished / "a", finished / "b"])


def test_a_file_of_a_tables_name_added_to_a_run_folder_is_never_overwritten_or_deleted(finished, run_copy):
    out = run_copy(finished)
    (out / "policy.csv").write_text("mine\n")  # a table section 1.4 writes, which this run would remove
    with pytest.raises(TavcError, match=r"policy.csv was not written by tavc and tavc would write a file of that "
                                        r"name; move it away or choose another folder$"):
        run_experiment(_cfg(out))
    assert (out / "policy.csv").read_text() == "mine\n"


def test_another_configuration_is_refused_unless_overwrite_and_then_only_tavcs_files_go(finished, run_copy):
    out = run_copy(finished)
    (out / "notes.txt").write_text("mine\n")
    before = _snapshot(out)
    with pytest.raises(TavcError, match=r"holds a finished run of another configuration \(seed: 0 -> 7\); add "
                                        r"overwrite=true to replace it, or choose another output_dir$"):
        run_experiment(_cfg(out, "seed=7"))
    assert _snapshot(out) == before
    # settings of where and how fast are not another configuration
    run_experiment(_cfg(out, "executor.batch_size=3"))
    run_experiment(settings(load_config(["experiment=breakdown", "scale=smoke", "duration_s=60",
                                         "convergence_s=20", "trials=1", "executor.n_jobs=1",
                                         f"output_dir={out}", "overwrite=true"])))
    assert (out / "notes.txt").read_text() == "mine\n"
    assert "experiment_name: breakdown" in (out / "config.yaml").read_text()


def test_the_settings_that_differ_are_named_at_most_three(tmp_path):
    old = "seed: 0\nexecutor:\n  n_jobs: 1\nlearner:\n  alpha: 0.1\n  gamma: 0.95\ntrials: 2\nretired: 1\n"
    (tmp_path / "config.yaml").write_text(old)
    new = "seed: 1\nexecutor:\n  n_jobs: 2\nlearner:\n  alpha: 0.2\n  gamma: 0.9\ntrials: 3\nadded: 0\n"
    # where it runs (executor) and keys only one version has are not another configuration
    assert config_differences(tmp_path / "config.yaml", new) == [
        "learner.alpha: 0.1 -> 0.2", "learner.gamma: 0.95 -> 0.9", "seed: 0 -> 1", "1 more"]
    assert config_differences(tmp_path / "config.yaml", old.replace("n_jobs: 1", "n_jobs: 8")) == []


def test_a_folder_an_earlier_version_wrote_is_taken_as_tavcs(finished, run_copy):
    out = run_copy(finished)
    (out / MANIFEST).unlink()  # as before the list existed: provenance.json says it is a run
    (out / "vacancy.csv").write_text("an earlier experiment's table\n")
    (out / "notes.txt").write_text("mine\n")
    owned = read(out)
    assert owned.kind == "run" and "vacancy.csv" in owned.files and "notes.txt" not in owned.files
    run_experiment(_cfg(out))
    assert not (out / "vacancy.csv").exists()  # tavc's by its name in a tavc run: removed as stale
    assert (out / "notes.txt").read_text() == "mine\n"
    assert json.loads((out / MANIFEST).read_text())["tavc"] == "run"


def test_a_damaged_list_is_one_line_naming_it(finished, run_copy):
    out = run_copy(finished)
    (out / MANIFEST).write_text("{not json")
    with pytest.raises(TavcError, match=rf"{MANIFEST}: cannot be read"):
        run_experiment(_cfg(out))


def test_a_single_job_sweep_removes_the_previous_sweeps_table(tmp_path):
    base = ["run", "-m", *SMOKE, f"output_dir={tmp_path}"]
    assert CliRunner().invoke(app, [*base, "seed=1,2"]).exit_code == 0
    assert (tmp_path / "sweep.csv").is_file()
    assert CliRunner().invoke(app, [*base, "seed=3"]).exit_code == 0
    assert not (tmp_path / "sweep.csv").exists() and not (tmp_path / "sweep.png").exists()
    assert json.loads((tmp_path / MANIFEST).read_text()) == {"tavc": "sweep", "files": []}


def test_a_ladder_never_replaces_a_table_it_did_not_write(tmp_path, finished):
    (tmp_path / "ladder.csv").write_text("mine\n")
    (tmp_path / MANIFEST).write_text(json.dumps({"tavc": "ladder", "files": []}))
    with pytest.raises(TavcError, match=r"ladder.csv was not written by tavc"):
        write_ladder(tmp_path, [finished])
    assert (tmp_path / "ladder.csv").read_text() == "mine\n"
    assert not (tmp_path / LOCK_NAME).exists()


def test_a_report_or_reproduce_aimed_at_a_run_folder_is_refused_before_anything_runs(finished, tmp_path, run_copy):
    from tavc_cli.api import reproduce_summaries
    from tavc_cli.report import build_report

    out = run_copy(finished)
    before = _snapshot(out)
    with pytest.raises(TavcError, match=r"--results: .* is a tavc run's folder, not a results folder"):
        reproduce_summaries(["scale=smoke"], experiments=["breakdown"], results_dir=out)
    assert _snapshot(out) == before
    (tmp_path / "mine").mkdir()
    shutil.copytree(finished, tmp_path / "mine" / "initial_distribution")
    (tmp_path / "mine" / "REPORT.md").write_text("my own report\n")
    with pytest.raises(TavcError, match=r"REPORT.md was not written by tavc"):
        build_report(tmp_path / "mine")
    assert (tmp_path / "mine" / "REPORT.md").read_text() == "my own report\n"


def test_a_folder_that_only_looks_like_a_run_is_not_taken_for_one(tmp_path):
    """A config.yaml and trials/ of somebody else's, a sweep.csv or model.json of theirs: tavc's
    earlier folders are known by how tavc's files begin, not by their names."""
    (tmp_path / "trials").mkdir()
    (tmp_path / "config.yaml").write_text("model:\n  lr: 0.001\n")
    before = _snapshot(tmp_path)
    with pytest.raises(TavcError, match=r"holds files tavc did not write \(config.yaml, trials/\)"):
        run_experiment(_cfg(tmp_path))
    assert _snapshot(tmp_path) == before
    (tmp_path / "sweep").mkdir()
    (tmp_path / "sweep" / "sweep.csv").write_text("lr,acc\n0.1,0.9\n")
    assert read(tmp_path / "sweep") is None
    result = CliRunner().invoke(app, ["run", "-m", *SMOKE, "seed=1,2", f"output_dir={tmp_path / 'sweep'}"])
    assert result.exit_code == 1 and "sweep.csv was not written by tavc" in result.output
    assert (tmp_path / "sweep" / "sweep.csv").read_text() == "lr,acc\n0.1,0.9\n"


def test_only_tavcs_own_half_written_files_are_removed(finished, tmp_path, run_copy):
    out = run_copy(finished)
    for name in (".notes.tmp", "trials/.keep.tmp", ".state_time.csv.abcd1234.tmp",
                 "trials/.random_000.npz.x1y2z3_4.tmp"):
        (out / name).write_text("half\n")
    run_experiment(_cfg(out))
    assert (out / ".notes.tmp").is_file() and (out / "trials/.keep.tmp").is_file()  # somebody else's
    assert not (out / ".state_time.csv.abcd1234.tmp").exists()  # a killed run's, beside tavc's own files
    assert not (out / "trials/.random_000.npz.x1y2z3_4.tmp").exists()
    (tmp_path / "new").mkdir()
    (tmp_path / "new" / ".draft.tmp").write_text("mine\n")
    with pytest.raises(TavcError, match=r"holds files tavc did not write \(.draft.tmp\)"):
        run_experiment(_cfg(tmp_path / "new"))
    assert (tmp_path / "new" / ".draft.tmp").read_text() == "mine\n"


@pytest.mark.parametrize("damage", ["remove", "empty", "cut"])
def test_a_finished_run_without_its_config_is_not_replaced_silently(finished, damage, run_copy):
    out = run_copy(finished)
    config = out / "config.yaml"
    text = config.read_text()
    if damage == "remove":
        config.unlink()
    else:
        config.write_text("" if damage == "empty" else "".join(text.splitlines(keepends=True)[:40]))
    before = _snapshot(out)
    with pytest.raises(TavcError, match=r"holds a finished run whose config.yaml (is missing|differs from what its "
                                        r"run wrote), so it may be of another configuration; add overwrite=true"):
        run_experiment(_cfg(out, "seed=5"))
    assert _snapshot(out) == before
    run_experiment(_cfg(out, "seed=5", "overwrite=true"))
    assert "seed: 5" in (out / "config.yaml").read_text()


def test_somebody_elses_failures_log_in_a_run_folder_is_kept(finished, run_copy):
    out = run_copy(finished)
    (out / "failures.log").write_text("my failures\n")
    with pytest.raises(TavcError, match=r"failures.log was not written by tavc"):
        run_experiment(_cfg(out))
    assert (out / "failures.log").read_text() == "my failures\n"


@pytest.mark.parametrize("text", ['{"tavc": null, "files": []}', '{"tavc": "run", "files": "abc"}', "[]"])
def test_a_list_of_another_shape_is_one_line_naming_it(finished, text, run_copy):
    out = run_copy(finished)
    (out / MANIFEST).write_text(text)
    with pytest.raises(TavcError, match=rf"{MANIFEST}: cannot be read"):
        run_experiment(_cfg(out))


def test_the_api_says_when_a_run_did_not_finish_or_its_config_is_damaged(finished, run_copy):
    from tavc_cli import api

    out = run_copy(finished)
    (out / "provenance.json").unlink()  # as an interrupted overwrite=true run leaves it
    with pytest.raises(TavcError, match=r"its run did not finish \(no provenance.json\), so its tables may be "
                                        r"another run's"):
        _ = api.load(out).state_time
    (out / "config.yaml").write_text("seed: [0\n")
    with pytest.raises(TavcError, match=r"config.yaml: cannot be read \("):
        _ = api.load(out).config


def test_the_report_never_replaces_a_figure_it_did_not_draw(finished, tmp_path):
    from tavc_cli.report import build_report

    shutil.copytree(finished, tmp_path / "initial_distribution")
    (tmp_path / "figures").mkdir()
    (tmp_path / "figures" / "fig_1_6.png").write_bytes(b"my figure")
    before = _snapshot(tmp_path)
    with pytest.raises(TavcError, match=r"fig_1_6.png was not written by tavc, and the report draws its figures in"):
        build_report(tmp_path)
    assert _snapshot(tmp_path) == before
    (tmp_path / "figures" / "fig_1_6.png").unlink()
    build_report(tmp_path)
    drawn = sorted(p.relative_to(tmp_path).as_posix() for p in (tmp_path / "figures").rglob("*") if p.is_file())
    assert drawn and set(drawn) <= set(json.loads((tmp_path / MANIFEST).read_text())["files"])
    build_report(tmp_path)  # its own figures: drawn again


def test_a_refused_run_writes_nothing_even_in_a_folder_an_earlier_version_wrote(finished, run_copy):
    out = run_copy(finished)
    (out / MANIFEST).unlink()
    before = _snapshot(out)
    with pytest.raises(TavcError, match=r"of another configuration \(seed: 0 -> 9\)"):
        run_experiment(_cfg(out, "seed=9"))
    assert _snapshot(out) == before  # not even the list
