"""Damaged results are refused on reading, never reported: a table cut short, a flipped byte,
a truncated config.yaml each give one line naming the file, and `tavc report` writes nothing.
Every finished run of a folder is reported, the claims tested on one per experiment; a run in
which nothing was delivered says so; the API reads only the trials a run lists."""

import csv
import io
import json
import os
import shutil
import tempfile
import time
from pathlib import Path

import pandas as pd
import pytest
from hypothesis import HealthCheck, example, given, settings
from hypothesis import strategies as st
from typer.testing import CliRunner

from tavc_cli import api, report
from tavc_cli.cli import app
from tavc_cli.config import load_config
from tavc_cli.config import settings as to_settings
from tavc_cli.errors import TavcError
from tavc_cli.io import file_digest
from tavc_cli.ownership import TURN_TAKING_FILES, TURN_TAKING_KIND, take
from tavc_cli.pipeline import run_experiment
from tavc_cli.run_checks import RunFacts, check_run, this_code
from tests.helpers import then_interrupted

RESULTS = Path(__file__).resolve().parents[1] / "results"
SMOKE = ["scale=smoke", "duration_s=120", "convergence_s=20", "executor.n_jobs=1"]
BREAKDOWN = ["experiment=breakdown", *SMOKE, "trials=2", "baseline_trials=2", "static_trials=2"]
REWRITE = "; rerun its experiment to rewrite it"
runner = CliRunner()


def _run(folder: Path, *overrides: str) -> Path:
    run_experiment(to_settings(load_config([*overrides, f"output_dir={folder}"])))
    return folder


def _with_digests(folder: Path) -> Path:
    """The run's provenance.json with the digest of every table, as `tavc run` records them
    (added here where the run predates them, so that the tests below do not depend on it)."""
    prov = json.loads((folder / "provenance.json").read_text())
    if "tables" not in prov:
        prov["tables"] = {p.name: file_digest(p) for p in sorted(folder.glob("*.csv"))}
        (folder / "provenance.json").write_text(json.dumps(prov, indent=2))
    return folder


@pytest.fixture(scope="module")
def breakdown(tmp_path_factory):
    """A finished breakdown run (six robots, one breaks down) with its tables' digests."""
    return _with_digests(_run(tmp_path_factory.mktemp("seed0") / "breakdown", *BREAKDOWN))


@pytest.fixture(scope="module")
def breakdown_seed1(tmp_path_factory):
    """The same experiment on other seeds: a second run of it."""
    return _with_digests(_run(tmp_path_factory.mktemp("seed1") / "breakdown", *BREAKDOWN, "seed=1"))


@pytest.fixture(scope="module")
def nothing_delivered(tmp_path_factory):
    """A run whose robots crawl at 1 mm/s: no trial has a delivery."""
    return _run(tmp_path_factory.mktemp("heavy") / "initial_distribution", "experiment=initial_distribution",
                *SMOKE, "trials=1", "baselines=[]", "robot.speed_mps=0.001")


@pytest.fixture(scope="module")
def undamaged_report(breakdown, tmp_path_factory):
    """REPORT.md of a folder holding the breakdown run as it was written."""
    results = _results_with(tmp_path_factory.mktemp("undamaged"), breakdown)
    result = runner.invoke(app, ["report", str(results)])
    assert result.exit_code == 0, result.output
    return (results / "REPORT.md").read_text()


def _results_with(root: Path, *runs: Path, names: tuple[str, ...] = ()) -> Path:
    """A results folder at root/results holding copies of `runs` (named as `names`, else as they are)."""
    results = root / "results"
    for k, run in enumerate(runs):
        shutil.copytree(run, results / (names[k] if names else run.name))
    return results


def _files(folder: Path) -> dict[str, bytes]:
    return {str(p.relative_to(folder)): p.read_bytes() for p in sorted(folder.rglob("*")) if p.is_file()}


def _refused(results: Path, path: Path, what: str | None = None) -> str:
    """Run the report on `results`; assert it refuses in one line naming `path` (saying `what`,
    where given) and writes nothing; return the line."""
    before = _files(results)
    result = runner.invoke(app, ["report", str(results)])
    assert result.exit_code == 1, result.output
    lines = result.output.strip().splitlines()
    assert len(lines) == 1, result.output
    assert lines[0].startswith(f"error: {path}: ") and lines[0].endswith(REWRITE), lines[0]
    if what is not None:
        assert lines[0] == f"error: {path}: {what}{REWRITE}"
    assert _files(results) == before  # no REPORT.md, claims.csv or figure, and no table touched
    return lines[0]


# --- 1. damaged tables -----------------------------------------------------------------------------


def test_claims_4_and_5_are_not_turned_inconclusive_by_a_cut_trial_stats(tmp_path):
    # both claims decided in the committed report (4 holds, 5 fails): a cut table must be refused,
    # never turn either into "inconclusive"
    committed = pd.read_csv(RESULTS / "claims.csv").set_index("claim_id")
    assert committed.loc[[4, 5], "verdict"].tolist() == ["reproduced", "not_reproduced"]
    results = _results_with(tmp_path, RESULTS / "initial_distribution")
    path = results / "initial_distribution" / "trial_stats.csv"
    data = path.read_bytes()
    path.write_bytes(data[:len(data) // 2])
    _refused(results, path, "cut short (its last line has no newline)")
    # cut at the end of a line: the rows it lost are trials provenance.json lists
    path.write_bytes(b"".join(data.splitlines(keepends=True)[:26]))
    line = _refused(results, path)
    assert "no row for random trial 5, which provenance.json lists" in line


def test_a_state_time_cut_at_byte_200_is_refused_not_printed(tmp_path):
    results = _results_with(tmp_path, RESULTS / "initial_distribution")
    path = results / "initial_distribution" / "state_time.csv"
    path.write_bytes(path.read_bytes()[:200])
    _refused(results, path, "cut short (its last line has no newline)")
    # the API refuses it the same way
    with pytest.raises(TavcError, match="cut short") as info:
        _ = api.load(results / "initial_distribution").state_time
    assert str(info.value) == f"{path}: cut short (its last line has no newline){REWRITE}"


def test_a_state_time_cut_at_the_end_of_a_line_is_refused(tmp_path):
    results = _results_with(tmp_path, RESULTS / "breakdown")
    path = results / "breakdown" / "state_time.csv"
    path.write_bytes(b"".join(path.read_bytes().splitlines(keepends=True)[:-2]))  # two theory rows gone
    _refused(results, path, "the theory rows list 4 of the team's 6 states (cut short?)")


def _edit_line(k: int, field: int, value: str):
    """A damage: line k's field set to `value` (lines counted from 1, fields from 0)."""
    def edit(data: bytes) -> bytes:
        lines = data.decode().split("\n")
        rows = list(csv.reader([lines[k - 1]]))[0]
        rows[field] = value
        out = io.StringIO()
        csv.writer(out, lineterminator="").writerow(rows)
        lines[k - 1] = out.getvalue()
        return "\n".join(lines).encode()
    return edit


def _insert_line(k: int, line: str):
    """A damage: `line` inserted as line k."""
    def edit(data: bytes) -> bytes:
        lines = data.decode().split("\n")
        return "\n".join([*lines[:k - 1], line, *lines[k - 1:]]).encode()
    return edit


@pytest.mark.parametrize(("name", "edit", "what"), [
    ("performance.csv", _insert_line(2, "0.0,tavc,0.0,0.0,2,9"), "line 2 has 6 fields, its header 5"),
    ("performance.csv", _edit_line(2, 2, "abc"), "line 2: mean 'abc' is not a number"),
    ("claims.csv", _edit_line(2, 2, "maybe"), "line 2: verdict 'maybe' is none of inconclusive, not_reproduced, "
                                              "reproduced"),
    ("trial_stats.csv", _edit_line(3, 1, "7"), "line 3: tavc trial 7 is not among the trials provenance.json lists"),
    ("trial_stats.csv", _edit_line(3, 1, "1.5"), "line 3: trial '1.5' is not a whole number"),
    # two bad trials: the first line's named, whichever fault it has
    ("trial_stats.csv", lambda data: _edit_line(3, 1, "1.5")(_edit_line(2, 1, "7")(data)),
     "line 2: tavc trial 7 is not among the trials provenance.json lists"),
    ("state_time.csv", _edit_line(4, 0, "4:4"), "line 4: state '4:4' is no state of this experiment's team"),
    ("robots.csv", _edit_line(2, 0, ""), "line 2: no controller"),
    ("q_values.csv", lambda data: b"\n".join(line.rpartition(b",")[0] for line in data.split(b"\n")),
     "no column 'q_1_1' (a Q-table's entry)"),  # the last column gone from every line
    # two lines wrong: the first in the table's order is named, whatever its column and fault
    ("robots.csv", lambda data: _edit_line(3, 0, "")(_edit_line(2, 5, "many")(data)),
     "line 2: n_choices 'many' is not a number"),
    ("robots.csv", lambda data: _edit_line(3, 5, "many")(_edit_line(2, 0, "")(data)), "line 2: no controller"),
])
def test_a_readable_but_malformed_table_is_refused_before_anything_is_written(breakdown, tmp_path, name, edit, what):
    results = _results_with(tmp_path, breakdown)
    path = results / "breakdown" / name
    path.write_bytes(edit(path.read_bytes()))
    _refused(results, path, what)


def test_a_repeated_row_and_a_whole_number_past_64_bits_are_refused(breakdown, tmp_path):
    """Both have a table's shape, and its digest would not say which line is wrong: a reader takes
    a repeated state for one, and reads a whole number of 19 digits or more as no array holds it."""
    results = _results_with(tmp_path, breakdown)
    path = results / "breakdown" / "state_time.csv"
    lines = path.read_text().split("\n")
    path.write_text("\n".join([*lines[:2], lines[1], *lines[2:]]))
    state, controller = lines[1].split(",")[:2]
    _refused(results, path, f"line 3: a second row for {state}, {controller}")
    results = _results_with(tmp_path / "big", breakdown)
    path = results / "breakdown" / "allocation.csv"
    path.write_bytes(_edit_line(2, 4, "9" * 19)(path.read_bytes()))
    _refused(results, path, f"line 2: n_trials '{'9' * 19}' is not a number a table holds (too large a whole number)")
    path.write_bytes(_edit_line(2, 4, "9" * 400)(path.read_bytes()))  # quoted in part: one line, of a line's length
    _refused(results, path, f"line 2: n_trials '{'9' * 40}'... (400 characters) is not a number a table holds (too "
                            "large a whole number)")
    path.write_bytes(_edit_line(2, 4, str(2 ** 63 - 1))(path.read_bytes()))  # the largest that fits: its digest
    _refused(results, path, "changed since its run wrote it (its SHA-256 is not the one provenance.json recorded)")


@pytest.mark.parametrize(("text", "why"), [
    (b"", "cannot be read (Expecting value: line 1 column 1 (char 0))"),
    (b"\xff\xfe", "cannot be read ('utf-8' codec can't decode byte 0xff in position 0: invalid start byte)"),
    (None, "cannot be read (tuple index out of range)"),  # no controller
])
def test_a_damaged_plan_is_refused_before_anything_is_written(breakdown, tmp_path, text, why):
    """A run's plan.json, read for the learner its claims are about: checked with the run, also
    where provenance.json records no digests (a folder of an older tavc, or made by hand)."""
    results = _results_with(tmp_path, breakdown)
    prov = json.loads((results / "breakdown" / "provenance.json").read_text())
    del prov["tables"]
    prov["code_digest"] = "0123456789abcdef"  # an earlier tavc's, which recorded no digests
    (results / "breakdown" / "provenance.json").write_text(json.dumps(prov))
    path = results / "breakdown" / "plan.json"
    if text is None:
        text = json.dumps({**json.loads(path.read_text()), "controllers": []}).encode()
    path.write_bytes(text)
    _refused(results, path, why)


def test_a_changed_number_is_caught_by_its_digest_alone(breakdown, tmp_path):
    results = _results_with(tmp_path, breakdown)
    path = results / "breakdown" / "trial_stats.csv"
    duration = path.read_text().splitlines()[1].split(",")[2]
    path.write_bytes(_edit_line(2, 2, f"{float(duration) + 1:.4f}")(path.read_bytes()))
    _refused(results, path, "changed since its run wrote it (its SHA-256 is not the one provenance.json recorded)")
    # the digests taken out: this tavc's runs always record them, so their absence is refused
    prov = json.loads((results / "breakdown" / "provenance.json").read_text())
    del prov["tables"]
    (results / "breakdown" / "provenance.json").write_text(json.dumps(prov))
    with pytest.raises(TavcError, match="edited .it lists no digests of its tables, which this tavc's runs always"):
        check_run(results / "breakdown")
    # a run of an earlier tavc, written before the digests: such a change has the shape of a table
    prov["code_digest"] = "0123456789abcdef"
    (results / "breakdown" / "provenance.json").write_text(json.dumps(prov))
    check_run(results / "breakdown")


def test_a_trial_listed_without_its_key_or_a_table_named_as_a_path_is_refused(breakdown, breakdown_seed1, tmp_path):
    """A run of this tavc lists every trial's key: without it, another seed's record put in its
    place would be read as the run's. A table is named, never a path to another run's."""
    results = _results_with(tmp_path, breakdown)
    run = results / "breakdown"
    prov = json.loads((run / "provenance.json").read_text())
    for trial in prov["trials"]:
        del trial["key"]
    (run / "provenance.json").write_text(json.dumps(prov))
    shutil.copy(breakdown_seed1 / "trials" / "tavc_000.npz", run / "trials" / "tavc_000.npz")
    with pytest.raises(TavcError, match="edited .a trial is listed without its key, which this tavc's runs always"):
        api.load(run).records("tavc")
    with pytest.raises(TavcError, match=r"no table '\.\./breakdown/state_time'"):
        api.load(breakdown).table("../breakdown/state_time")


def test_a_damaged_trial_record_the_report_reads_is_refused_before_anything_is_written(breakdown, tmp_path):
    results = _results_with(tmp_path, breakdown)
    path = results / "breakdown" / "trials" / "tavc_000.npz"  # read for whether anything was delivered
    path.write_bytes(path.read_bytes()[:100])
    line = _refused(results, path)
    assert line.startswith(f"error: {path}: cannot be read (")
    with pytest.raises(TavcError, match="tavc_000.npz: cannot be read"):
        api.load(results / "breakdown").records()


@pytest.mark.parametrize("where", ["readings/dock-left-two_circuits_parallel/breakdown",
                                   "converged/readings/dock-left-two_circuits_parallel/breakdown"])
def test_a_damaged_table_of_a_run_in_another_reading_is_refused_before_anything_is_written(breakdown, tmp_path,
                                                                                           where):
    # the studies read those runs' tables as a whole (the counterfactuals, the models' check points)
    results = _results_with(tmp_path, breakdown)
    shutil.copytree(breakdown, results / where)
    path = results / where / "state_time.csv"
    path.write_text('state,"controller\n')
    assert _refused(results, path).startswith(f"error: {path}: cannot be read (")


_CHECK_RUN = report._check_run


def _slow_for_todays_world(folder: Path, root: Path) -> bool:
    """The report's check of one run, a second late for a run directly under the results folder."""
    if folder.parent.name == "results":
        time.sleep(1.0)
    return _CHECK_RUN(folder, root)


def test_of_two_damaged_runs_the_first_in_order_is_named_though_they_are_checked_together(breakdown, tmp_path,
                                                                                          monkeypatch):
    """The runs are checked two at a time; the refusal names the first of them in the report's
    order (today's world's before another reading's), though its check ends a second after the
    other's (the check processes are forked with the slowed check)."""
    results = _results_with(tmp_path, breakdown)
    later = results / "readings" / "dock-left-two_circuits_parallel" / "breakdown"
    shutil.copytree(breakdown, later)
    (later / "state_time.csv").write_text('state,"controller\n')
    path = results / "breakdown" / "trial_stats.csv"
    path.write_bytes(path.read_bytes()[:-1])
    monkeypatch.setattr(report, "_check_run", _slow_for_todays_world)
    _refused(results, path, "cut short (its last line has no newline)")


_REPORTING = os.getpid()


def _dies_in_a_check_process(folder: Path, root: Path) -> bool:
    """The report's check of one run, dying (as out of memory would) in a check process."""
    if os.getpid() != _REPORTING:
        os._exit(9)
    return _CHECK_RUN(folder, root)


def test_where_a_check_process_dies_the_runs_are_checked_in_the_report_itself(breakdown, tmp_path, monkeypatch):
    """A check process that dies takes nothing with it: the report checks the runs itself and is
    written; with a damaged run, that run is refused as ever."""
    results = _results_with(tmp_path, breakdown)
    monkeypatch.setattr(report, "_check_run", _dies_in_a_check_process)
    result = runner.invoke(app, ["report", str(results)])
    assert result.exit_code == 0 and (results / "REPORT.md").is_file(), result.output
    path = results / "breakdown" / "trial_stats.csv"
    path.write_bytes(path.read_bytes()[:-1])
    _refused(results, path, "cut short (its last line has no newline)")


def test_a_damaged_prediction_of_the_turn_taking_model_is_refused_before_anything_is_written(breakdown, tmp_path):
    results = _results_with(tmp_path, breakdown)
    path = results / "turn_taking" / "breakdown" / "turn_taking" / "turn_taking.json"
    path.parent.mkdir(parents=True)
    path.write_text('{"regime": "turn-taking", ')
    before = _files(results)
    result = runner.invoke(app, ["report", str(results)])
    assert result.exit_code == 1 and result.output.startswith(f"error: {path}: "), result.output
    assert len(result.output.strip().splitlines()) == 1 and _files(results) == before


@pytest.mark.parametrize("study", ["turn_taking", "stay_switch", "stay_switch_calibrated"])
def test_a_damaged_table_of_the_turn_taking_models_own_learners_is_refused(breakdown, tmp_path, study):
    """The model's own learners' run, set beside the learners' runs seed for seed (at the
    chapter's scenarios, or in a stay/switch study's reading): checked like any run the report
    reads (here: its robots' table without the kinds)."""
    results = _results_with(tmp_path, breakdown)
    where = results / study / "breakdown" / "turn_taking"
    where.mkdir(parents=True)
    take(where, TURN_TAKING_KIND, TURN_TAKING_FILES)  # read as the model's folder, not searched for runs
    shutil.copytree(breakdown, where / "learners")
    (where / "turn_taking.json").write_text(json.dumps({"regime": "turn-taking", "modal_state": "3:2",
                                                        "robots_high": 2.5, "modal_share_pct": 46.0,
                                                        "learners_run": "learners"}))
    path = where / "learners" / "robots.csv"
    pd.read_csv(path).drop(columns="kind").to_csv(path, index=False)
    _refused(results, path, "no column 'kind'")


# --- 2. config.yaml read and checked before anything is written --------------------------------------


@pytest.mark.parametrize(("before", "what"), [
    (b"\nsim:", "cut short (no 'sim' section)"),
    (b"\nduration_s:", "cut short (no 'paper' section)"),
    (b"\ncalibration:", "cut short (no 'calibration' section)"),
    (None, None),  # halfway, wherever that falls
])
def test_a_truncated_config_is_refused_before_any_figure(breakdown, tmp_path, before, what):
    results = _results_with(tmp_path, breakdown)
    path = results / "breakdown" / "config.yaml"
    data = path.read_bytes()
    path.write_bytes(data[:data.index(before) + 1] if before else data[:len(data) // 2])
    _refused(results, path, what)


def _re_signed(run: Path, name: str, old: bytes, new: bytes) -> Path:
    """`run`'s file `name` with `old` replaced by `new` once, and provenance.json's digest of it made
    the edited file's, as a hand could: the digest no longer tells the edit. Returns the file."""
    path = run / name
    data = path.read_bytes()
    assert data.count(old) >= 1
    path.write_bytes(data.replace(old, new, 1))
    prov = json.loads((run / "provenance.json").read_text())
    prov["tables"][name] = file_digest(path)
    (run / "provenance.json").write_text(json.dumps(prov, indent=2))
    return path


TRIALS_PLANNED = "2 trials of tavc, 2 trials of random, 2 trials of static"


@pytest.mark.parametrize(("old", "new", "where", "what"), [
    # a value the trials ran on: every trial's key changes, and the first listed is named
    (b"  - 2200.0\n", b"  - 2300.0\n", "provenance.json",
     "tavc trial 0 is listed under a key its config.yaml and plan.json do not give it (edited after the run?)"),
    # a count the table of runs shows: the plan the config gives is not the one recorded
    (b"\ntrials: 2\n", b"\ntrials: -7\n", "config.yaml", "edited after its run (its controllers and trials, "
     "-7 trials of tavc, 2 trials of random, 2 trials of static, are not those plan.json records)"),
    (b"\nbaselines:\n- random\n", b"\nbaselines:\n", "config.yaml", "edited after its run (its controllers and "
     "trials, 2 trials of tavc, 2 trials of static, are not those plan.json records)"),
    # a team size the trials did not run with
    (b"  n_robots: 6\n", b"  n_robots: 0\n", "config.yaml",
     "edited after its run (team.n_robots is 0, and it lists 6 members, which a run resolves them into)"),
])
def test_settings_edited_after_the_run_are_refused_though_their_digest_was_re_signed(breakdown, tmp_path, old, new,
                                                                                   where, what):
    results = _results_with(tmp_path, breakdown)
    _re_signed(results / "breakdown", "config.yaml", old, new)
    _refused(results, results / "breakdown" / where, what)


@pytest.mark.parametrize("edit", ["twice", "dropped", "other_name"])
def test_a_provenance_listing_other_trials_than_the_plan_is_refused(breakdown, tmp_path, edit):
    results = _results_with(tmp_path, breakdown)
    path = results / "breakdown" / "provenance.json"
    prov = json.loads(path.read_text())
    trials = prov["trials"]
    if edit == "twice":  # the tables' trials are all listed, one of them twice
        trials.append(dict(trials[0]))
    elif edit == "dropped":
        trials.pop()
    else:  # a trial number the plan never gave, its record moved there
        trials[-1] = {**trials[-1], "trial": 7}
    path.write_text(json.dumps(prov, indent=2))
    _refused(results, path, f"its trials are not those config.yaml plans ({TRIALS_PLANNED})")


@pytest.mark.parametrize(("key", "name"), [("experiment_name", "../../ESCAPED"), ("scale", "/tmp")])
def test_a_name_edited_into_a_path_is_refused_and_nothing_is_written_where_it_leads(breakdown, tmp_path, key, name):
    """The report names its figures after a run's experiment: a config.yaml whose name was edited
    into a path (its digest taken out of provenance.json, so that no digest tells) is refused, and
    nothing is written outside the results folder, nor a file of the user's there replaced."""
    results = _results_with(tmp_path, breakdown)
    path = results / "breakdown" / "config.yaml"
    text = path.read_text()
    old = "experiment_name: breakdown\n" if key == "experiment_name" else "scale:\n  name: smoke\n"
    assert old in text
    path.write_text(text.replace(old, old.replace("breakdown" if key == "experiment_name" else "smoke", name)))
    prov = json.loads((results / "breakdown" / "provenance.json").read_text())
    del prov["tables"]["config.yaml"]
    (results / "breakdown" / "provenance.json").write_text(json.dumps(prov, indent=2))
    (tmp_path / "ESCAPED.png").write_text("mine")
    dotted = "experiment_name" if key == "experiment_name" else "scale.name"
    _refused(results, path, f"edited after its run ({dotted} is not a plain name, which a run's always is)")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["ESCAPED.png", "results"]
    assert (tmp_path / "ESCAPED.png").read_text() == "mine"


def test_a_report_of_a_folder_another_command_holds_is_one_line_and_writes_nothing(breakdown, tmp_path):
    """Two reports of one folder at once would write over each other's files (each took the
    other's temporary files for a stranger's): the second is refused while the first holds it."""
    from tavc_cli.io import claim_folder

    results = _results_with(tmp_path, breakdown)
    before = _files(results)
    with claim_folder(results, what="RESULTS_DIR"):
        result = runner.invoke(app, ["report", str(results)])
    assert result.exit_code == 1
    assert result.output.startswith(f"error: RESULTS_DIR: {results} is in use by another tavc run (")
    assert len(result.output.strip().splitlines()) == 1 and _files(results) == before


@pytest.mark.parametrize(("name", "what"), [("config.yaml", "not a regular file, where a finished run keeps one"),
                                           ("robots.csv", "not a regular file, where provenance.json lists a table")])
def test_a_pipe_in_a_finished_runs_file_is_named_for_what_it_is(breakdown, tmp_path, name, what):
    """A named pipe where a finished run keeps a file: said to be one, not taken for a run that did
    not finish or a file that is missing (and never opened: the report would wait on it)."""
    results = _results_with(tmp_path, breakdown)
    path = results / "breakdown" / name
    path.unlink()
    os.mkfifo(path)
    _refused(results, path, what)


def test_a_run_of_other_code_is_reported_as_such(breakdown, undamaged_report, tmp_path):
    assert "Runs of other code" not in undamaged_report
    results = _results_with(tmp_path, breakdown)
    assert api.load(results / "breakdown").other_code is None
    path = results / "breakdown" / "provenance.json"
    prov = json.loads(path.read_text())
    prov["code_digest"] = "0123456789abcdef"  # as a run of an earlier simulator records it
    path.write_text(json.dumps(prov, indent=2))
    assert api.load(results / "breakdown").other_code == "0123456789abcdef"
    result = runner.invoke(app, ["report", str(results)])
    assert result.exit_code == 0, result.output
    assert ("runs of other code: 1 run(s) under breakdown/ were computed by another version of tavc's code "
            "(0123456789abcdef)") in result.output
    text = (results / "REPORT.md").read_text()
    paragraph = next(line for line in text.splitlines() if line.startswith("**Runs of other code.**"))
    assert paragraph.startswith("**Runs of other code.** 1 of the runs this report reads were computed by another "
                                f"version of tavc's code (digest `0123456789abcdef`; this tavc's: {this_code()}): "
                                "`breakdown`. Their numbers are shown as that code made them")


COMMITTED_RUNS = sorted(p.parent for p in RESULTS.rglob("provenance.json"))


def test_the_committed_runs_are_all_there():
    assert len(COMMITTED_RUNS) >= 12  # both horizons, the ladder's rungs, the value-ratio sweep


def test_the_committed_reports_list_only_files_they_hold():
    """A report's .tavc.json lists what it wrote in its folder (`ownership`), which the next report
    replaces or clears: a file listed that is not there is a record an older report left behind."""
    records = [p for p in sorted(RESULTS.rglob(".tavc.json")) if json.loads(p.read_text())["tavc"] == "results"]
    assert len(records) >= 2  # the chapter's durations and 40x
    for path in records:
        missing = [name for name in json.loads(path.read_text())["files"] if not (path.parent / name).exists()]
        assert not missing, f"{path.relative_to(RESULTS)} lists {len(missing)} files it does not hold: {missing[:2]}"


@pytest.mark.parametrize("run", COMMITTED_RUNS, ids=[str(p.relative_to(RESULTS)) for p in COMMITTED_RUNS])
def test_every_committed_run_passes_the_checks(run):
    check_run(run)


def test_the_states_a_team_can_be_in():
    breakdown = RunFacts.of(to_settings(load_config(["experiment=breakdown"])), None, Path("."))
    assert breakdown.valid_state("3:2") and breakdown.valid_state("3:3")  # after the breakdown, and before
    assert not any(map(breakdown.valid_state, ["4:4", "2:2", "3:2:1", "6", "a:b", "", "3:-1", "3:²"]))
    groups = RunFacts.of(to_settings(load_config(["experiment=heterogeneous"])), None, Path("."))
    assert groups.valid_state("3:0") and groups.valid_state("0:3") and groups.valid_state("0:0")
    assert not any(map(groups.valid_state, ["4:0", "0:4", "1:1:1", "6"]))
    one_circuit = RunFacts.of(to_settings(load_config(["experiment=spatiotemporal"])), None, Path("."))
    assert one_circuit.valid_state("5") and not one_circuit.valid_state("4") and not one_circuit.valid_state("5:0")


# --- 3. every run of a folder reported ----------------------------------------------------------------


def test_every_run_of_an_experiment_is_reported(breakdown, breakdown_seed1, tmp_path):
    results = _results_with(tmp_path, breakdown, breakdown_seed1, names=("a", "b"))
    result = runner.invoke(app, ["report", str(results)])
    assert result.exit_code == 0, result.output
    scale, first, second = result.output.splitlines()[:3]
    # smoke runs: the count is what the verdict would be, headed "not a verdict"
    assert scale.startswith("not a verdict: scale=smoke (breakdown: 2 of the chapter's 20 trials")
    assert first.startswith("claims (not a verdict): ") and first.endswith(" of 1 tested would be reproduced "
                                                                          "(breakdown in a)")
    assert second == "also reported, in sections of their own: b (breakdown; its claims tested on a)"
    text = (results / "REPORT.md").read_text()
    assert text.count("\n## breakdown (section") == 1
    assert ("There are 2 runs of breakdown here. The claims are tested on `a` (the first by name; none is named "
            "after it); the others each have a section of their own below: `b`.") in text
    other = text.split("\n### b: another run of breakdown\n")[1].split("\n## ")[0]
    assert "The claims about breakdown are tested on `a`, not on this run, which differs from it in seed 1 (`a`: 0)." \
        in other
    assert "| 3:2 |" in other and "![Figure 1.8, tavc](figures/runs/b/fig_1_8.png)" in other
    assert (results / "figures" / "fig_1_8.png").is_file() and (results / "figures" / "runs" / "b" / "fig_1_8.png")\
        .is_file()
    # the claims are run a's, as its own run tested them
    claims = pd.read_csv(results / "claims.csv")
    own = pd.read_csv(results / "a" / "claims.csv")
    pd.testing.assert_frame_equal(own, claims.loc[claims["claim_id"].isin(own["claim_id"]), list(own.columns)]
                                  .reset_index(drop=True), check_dtype=False)
    assert "delivered anything" not in text


def test_the_run_named_after_its_experiment_is_the_one_tested(breakdown, breakdown_seed1, tmp_path):
    results = _results_with(tmp_path, breakdown_seed1, breakdown, names=("a_first", "breakdown"))
    result = runner.invoke(app, ["report", str(results)])
    assert result.exit_code == 0, result.output
    scale, first, second = result.output.splitlines()[:3]
    assert scale.startswith("not a verdict: scale=smoke (breakdown: ")
    assert first.startswith("claims (not a verdict): ") and first.endswith(" of 1 tested would be reproduced "
                                                                          "(breakdown)")
    assert second == "also reported, in sections of their own: a_first (breakdown; its claims tested on breakdown)"
    text = (results / "REPORT.md").read_text()
    assert "The claims are tested on `breakdown` (the folder named after the experiment)" in text
    assert "\n### a_first: another run of breakdown\n" in text
    claims = pd.read_csv(results / "claims.csv")
    own = pd.read_csv(results / "breakdown" / "claims.csv")
    pd.testing.assert_frame_equal(own, claims.loc[claims["claim_id"].isin(own["claim_id"]), list(own.columns)]
                                  .reset_index(drop=True), check_dtype=False)


# --- 4. a run with no delivery ------------------------------------------------------------------------


def test_a_run_where_no_robot_delivered_says_so(nothing_delivered, tmp_path):
    results = _results_with(tmp_path, nothing_delivered)
    result = runner.invoke(app, ["report", str(results)])
    assert result.exit_code == 0, result.output
    section = (results / "REPORT.md").read_text().split("\n## initial_distribution")[1].split("\n## ")[0]
    assert ("**No robot delivered anything in any trial of this run** (1 trial of TAVC): the tables and figures "
            "below describe robots that never completed a task, and no claim about their allocation can be tested "
            "on them.") in section
    # without the trial records (results committed without trials/), from the tables' value rates
    shutil.rmtree(results / "initial_distribution" / "trials")
    result = runner.invoke(app, ["report", str(results)])
    assert result.exit_code == 0, result.output
    section = (results / "REPORT.md").read_text().split("\n## initial_distribution")[1].split("\n## ")[0]
    assert ("**Nothing was delivered in any trial of this run**: every value rate in its `trial_stats.csv` and "
            "`performance.csv` is zero") in section


# --- 5. the API reads the run's own trials ------------------------------------------------------------


def test_the_api_reads_only_the_trials_provenance_lists(breakdown, breakdown_seed1, tmp_path):
    folder = tmp_path / "breakdown"
    shutil.copytree(breakdown, folder)
    listed = json.loads((folder / "provenance.json").read_text())["trials"]
    shutil.copy(folder / "trials" / "tavc_000.npz", folder / "trials" / "tavc_002.npz")  # left by a larger run
    res = api.load(folder)
    records = res.records()
    assert sorted((r.meta["controller"], int(r.meta["trial"])) for r in records) == sorted(
        (t["controller"], t["trial"]) for t in listed)
    assert len(res.events("deliveries")) == sum(len(r.table("deliveries")["t_s"]) for r in records)
    # a folder without provenance.json (a run that did not finish) reads the trials its plan lists, each
    # under its own name and the key its settings give it: not the copy, nor a record of other settings
    (folder / "provenance.json").unlink()
    assert sorted((r.meta["controller"], int(r.meta["trial"])) for r in api.load(folder).records()) == sorted(
        (t["controller"], t["trial"]) for t in listed)
    shutil.copy(breakdown_seed1 / "trials" / "tavc_000.npz", folder / "trials" / "tavc_000.npz")  # another seed's
    assert sorted((r.meta["controller"], int(r.meta["trial"])) for r in api.load(folder).records()) == sorted(
        (t["controller"], t["trial"]) for t in listed if (t["controller"], t["trial"]) != ("tavc", 0))
    assert [r.meta["controller"] for r in api.load(folder).records("random")] == ["random"] * sum(
        t["controller"] == "random" for t in listed)
    for trial in (folder / "trials").glob("tavc_*.npz"):  # damaged, or an earlier version's: computed anew
        trial.write_bytes(b"not a record")
    with pytest.raises(TavcError, match=f"^{folder}: no trial of its run has finished yet for tavc$"):
        api.load(folder).records("tavc")
    with pytest.raises(TavcError, match=f"^{folder}: no trials of wolf_phc to read$"):  # not in its plan
        api.load(folder).records("wolf_phc")
    (folder / "plan.json").write_text("{bad")
    with pytest.raises(TavcError, match=f"^{folder / 'plan.json'}: cannot be read "):
        api.load(folder).records()


def test_the_api_names_a_listed_trial_file_that_is_gone(breakdown, tmp_path):
    folder = tmp_path / "breakdown"
    shutil.copytree(breakdown, folder)
    (folder / "trials" / "random_001.npz").unlink()
    with pytest.raises(TavcError, match="random_001.npz: missing, though provenance.json lists it"):
        api.load(folder).events("deliveries")


def test_the_api_checks_a_table_as_the_report_does(breakdown, tmp_path):
    folder = tmp_path / "breakdown"
    shutil.copytree(breakdown, folder)
    pd.testing.assert_frame_equal(api.load(folder).table("trial_stats"), pd.read_csv(folder / "trial_stats.csv"))
    path = folder / "trial_stats.csv"
    path.write_bytes(path.read_bytes().replace(b"\ntavc,1,", b"\ntavc,7,", 1))
    with pytest.raises(TavcError) as info:
        api.load(folder).table("trial_stats")
    assert str(info.value) == f"{path}: line 3: tavc trial 7 is not among the trials provenance.json lists{REWRITE}"


def test_the_api_holds_a_runs_settings_to_its_trials_as_the_report_does(breakdown, tmp_path):
    folder = tmp_path / "breakdown"
    shutil.copytree(breakdown, folder)
    _re_signed(folder, "config.yaml", b"\ntrials: 2\n", b"\ntrials: 3\n")
    with pytest.raises(TavcError) as info:
        api.load(folder).table("trial_stats")
    assert str(info.value) == (f"{folder / 'config.yaml'}: edited after its run (its controllers and trials, 3 trials "
                               f"of tavc, 2 trials of random, 2 trials of static, are not those plan.json records)"
                               f"{REWRITE}")


# --- any damage to any table -------------------------------------------------------------------------


@st.composite
def damage(draw, names: list[str]):
    """(table, how, where): cut the table at `where` (a fraction of its length: at 1.0 nothing is
    cut), or flip some bits of its byte there."""
    return (draw(st.sampled_from(names)), draw(st.sampled_from(["cut", "flip"])), draw(st.floats(0.0, 1.0)),
            draw(st.integers(min_value=1, max_value=255)))


@pytest.mark.slow
def test_any_damage_to_any_table_is_refused_or_changes_nothing(breakdown, undamaged_report):
    names = sorted(p.name for p in breakdown.glob("*.csv"))

    @settings(max_examples=60, deadline=None, database=None, derandomize=True,
              suppress_health_check=[HealthCheck.too_slow])
    @given(damage(names))
    @example(("state_time.csv", "cut", 1.0, 1))  # a cut at the end: the same table
    def check(case):
        name, how, where, xor = case
        with tempfile.TemporaryDirectory() as tmp:
            results = _results_with(Path(tmp), breakdown)
            path = results / "breakdown" / name
            data = path.read_bytes()
            if how == "cut":
                damaged = data[:round(where * len(data))]
            else:
                at = min(int(where * len(data)), len(data) - 1)
                damaged = data[:at] + bytes([data[at] ^ xor]) + data[at + 1:]
            path.write_bytes(damaged)
            if damaged == data:
                result = runner.invoke(app, ["report", str(results)])
                assert result.exit_code == 0, result.output
                assert (results / "REPORT.md").read_text() == undamaged_report
            else:
                _refused(results, path)

    check()


def test_a_report_stopped_while_drawing_lists_its_figures_and_the_next_one_heals(breakdown, tmp_path, monkeypatch):
    """Ctrl-C after the figures are drawn and before the report is written: the figures are
    listed as tavc's, so the same command replaces them rather than refusing them, and draws
    the figures an undisturbed report draws, byte for byte."""
    import tavc_cli.report as report

    clean, stopped = tmp_path / "clean", tmp_path / "stopped"
    for folder in (clean, stopped):
        shutil.copytree(breakdown, folder / "breakdown")
    assert runner.invoke(app, ["report", str(clean)]).exit_code == 0
    monkeypatch.setattr(report, "experiment_sections", then_interrupted(report.experiment_sections))
    with pytest.raises(KeyboardInterrupt):
        report.build_report(stopped)
    monkeypatch.undo()
    assert not (stopped / "REPORT.md").exists() and any((stopped / "figures").iterdir())
    result = runner.invoke(app, ["report", str(stopped)])
    assert result.exit_code == 0, result.output

    def figures(folder: Path) -> dict[str, bytes]:
        return {p.relative_to(folder).as_posix(): p.read_bytes() for p in sorted((folder / "figures").rglob("*"))
                if p.is_file()}

    assert figures(stopped) == figures(clean)


def test_a_report_stopped_before_writing_its_files_leaves_them_unclaimed(breakdown, tmp_path, monkeypatch):
    """A report stopped while drawing had listed REPORT.md and claims.csv before writing them;
    they are not there, so they are not tavc's: a REPORT.md the user puts there afterwards is
    refused by the next report, not replaced. A file where figures/ goes is refused before
    anything is written."""
    import tavc_cli.report as report
    from tavc_cli.ownership import read

    stopped = tmp_path / "stopped"
    shutil.copytree(breakdown, stopped / "breakdown")
    monkeypatch.setattr(report, "experiment_sections", then_interrupted(report.experiment_sections))
    with pytest.raises(KeyboardInterrupt):
        report.build_report(stopped)
    monkeypatch.undo()
    assert not {"REPORT.md", "claims.csv"} & read(stopped).files
    (stopped / "REPORT.md").write_text("# my own notes\n")
    result = runner.invoke(app, ["report", str(stopped)])
    assert result.exit_code == 1 and "REPORT.md was not written by tavc" in result.output
    assert (stopped / "REPORT.md").read_text() == "# my own notes\n"

    other = tmp_path / "other"
    shutil.copytree(breakdown, other / "breakdown")
    (other / "figures").write_text("x")
    result = runner.invoke(app, ["report", str(other)])
    assert result.exit_code == 1 and result.output.strip() == (
        f"error: RESULTS_DIR: {other / 'figures'} is a file, where the report draws its figures in a folder of its "
        "own; move it away or choose another folder")
    assert sorted(p.name for p in other.iterdir()) == ["breakdown", "figures"]


def test_links_in_a_results_tree_are_not_followed(breakdown, tmp_path):
    """A link that loops back to the results folder, and one to a run elsewhere: the report
    finds the run that lies in the folder once, and writes nothing through either link."""
    from tavc_cli.report.runs import run_folders

    results, elsewhere = tmp_path / "results", tmp_path / "elsewhere"
    shutil.copytree(breakdown, results / "breakdown")
    shutil.copytree(breakdown, elsewhere / "breakdown_seed9")
    (results / "loop").symlink_to(results, target_is_directory=True)
    (results / "theirs").symlink_to(elsewhere, target_is_directory=True)
    shutil.copytree(breakdown, tmp_path / "deeper" / "set1" / "breakdown")
    (results / "deep").symlink_to(tmp_path / "deeper", target_is_directory=True)  # a run two levels down
    (tmp_path / "empty").mkdir()  # links the search would never have read a run through: not named
    (results / ".cache").symlink_to(tmp_path / "empty", target_is_directory=True)
    (results / "extra").symlink_to(tmp_path / "empty", target_is_directory=True)
    before = {p: p.read_bytes() for p in sorted(elsewhere.rglob("*")) if p.is_file()}
    assert run_folders(results) == [results / "breakdown"]
    result = runner.invoke(app, ["report", str(results)])
    assert result.exit_code == 0, result.output
    assert {p: p.read_bytes() for p in sorted(elsewhere.rglob("*")) if p.is_file()} == before
    assert "breakdown_seed9" not in (results / "REPORT.md").read_text()
    # each link is said to be left out, so that a run reached through one is not taken for a run not made
    said = "a symbolic link, which the report does not follow (it reads each run where it lies)"
    assert [line for line in result.output.splitlines() if line.startswith("left out")] == [
        f"left out {results / name}: {said}" for name in ("deep", "loop", "theirs")]
    report = (results / "REPORT.md").read_text()
    assert all(f"| `{name}` | - | - | - | left out: {said} |" in report for name in ("deep", "loop", "theirs"))


def test_a_hidden_folder_in_a_sweep_is_not_read(breakdown, tmp_path):
    """A copy of a run kept in a hidden folder of the value-ratio sweep (`.backup/`), damaged: the
    report leaves it, as it leaves hidden folders everywhere else, and tests nothing again there."""
    results = tmp_path / "results"
    shutil.copytree(breakdown, results / "breakdown")
    hidden = results / "value_ratio" / ".backup" / "breakdown"
    shutil.copytree(breakdown, hidden)
    (hidden / "trial_stats.csv").write_text("damaged\n")
    before = {p: p.read_bytes() for p in sorted(hidden.rglob("*")) if p.is_file()}
    result = runner.invoke(app, ["report", str(results)])
    assert result.exit_code == 0, result.output
    assert {p: p.read_bytes() for p in sorted(hidden.rglob("*")) if p.is_file()} == before


def test_a_value_ratio_folder_that_is_a_link_is_refused(breakdown, tmp_path):
    """The value-ratio sweep's folder linked from elsewhere: the report would write value_ratio.csv
    through the link, out of the results folder; it refuses in one line and writes nothing anywhere.
    (A longer horizon's folder that is a link is not read as one at all.)"""
    where = "value_ratio"
    results, elsewhere = tmp_path / "results", tmp_path / "elsewhere"
    shutil.copytree(breakdown, results / "breakdown")
    shutil.copytree(breakdown, elsewhere / "breakdown")
    (results / where).symlink_to(elsewhere, target_is_directory=True)
    before = _files(results)
    outside = {p: p.read_bytes() for p in sorted(elsewhere.rglob("*")) if p.is_file()}
    result = runner.invoke(app, ["report", str(results)])
    assert result.exit_code == 1, result.output
    assert result.output.startswith(f"error: RESULTS_DIR: {results / where}") and "link" in result.output
    assert len(result.output.strip().splitlines()) == 1
    assert _files(results) == before
    assert {p: p.read_bytes() for p in sorted(elsewhere.rglob("*")) if p.is_file()} == outside


def test_a_table_larger_than_any_tavc_writes_is_refused_unread(breakdown, tmp_path):
    """A trial_stats.csv of 300 MiB (sparse: no disk used) is refused in one line naming it, without
    being read into memory."""
    from tavc_cli.readers import TABLE_LIMIT

    results = tmp_path / "results"
    shutil.copytree(breakdown, results / "breakdown")
    with open(results / "breakdown" / "trial_stats.csv", "r+b") as fh:
        fh.truncate(TABLE_LIMIT + (44 << 20))
    result = runner.invoke(app, ["report", str(results)])
    assert result.exit_code == 1
    line = result.output.strip().splitlines()[-1]
    assert line.startswith(f"error: {results / 'breakdown' / 'trial_stats.csv'}: cannot be read (")
    assert "bytes, more than the" in line
    assert not (results / "REPORT.md").exists()


def test_a_model_of_other_settings_is_never_set_beside_a_run(finished_run, run_copy, tmp_path):
    """`tavc model ... output_dir=<a run's folder>` puts a model beside a run whatever its settings:
    the report sets its prediction beside the run's states only where the model was measured with
    the run's values, arena, unit of t and robot speed, for a team as large; else it says why."""
    run = run_copy(finished_run("experiment=initial_distribution", *SMOKE, "trials=2", "baseline_trials=2",
                                "static_trials=2", name="initial_distribution"), into="results")
    results = run.parent
    (run / "model").mkdir()
    model = json.loads((Path(__file__).parents[1] / "results" / "initial_distribution" / "model" / "model.json")
                       .read_text())  # the committed model: 2200/2000, two_circuits, ms, 0.25 m/s, six robots
    (run / "model" / "model.json").write_text(json.dumps(model))
    report.build_report(results)
    assert f"predicts **{model['predicted_state']}** for 6 robots" in (results / "REPORT.md").read_text()
    (run / "model" / "model.json").write_text(json.dumps({**model, "values": [8000.0, 2000.0], "n_robots": 4}))
    report.build_report(results)
    text = (results / "REPORT.md").read_text()
    assert "predicts **" not in text
    assert ("The model beside this run (`initial_distribution/model/`) was measured with other settings "
            "(tasks.values [8000.0, 2000.0] (the run: [2200.0, 2000.0]); team sizes up to 4 (the run: 6)): not set "
            "beside it.") in text


def test_the_value_ratio_table_holds_one_run_to_a_cell_and_alike_runs_in_a_column(finished_run, run_copy, tmp_path):
    """The value-ratio table has a cell for each reading, horizon and ratio, and names nothing else
    of its runs: a second run in a cell (it would go unshown), or a run of another team in a column,
    is refused in one line naming both, before anything is written."""
    base = ("experiment=initial_distribution", *SMOKE, "trials=2", "baselines=[]")
    chapter = finished_run(*base, name="initial_distribution")
    root = tmp_path / "results" / "value_ratio" / "paper"
    first = run_copy(chapter, into=root / "a")
    second = run_copy(chapter, into=root / "b")
    result = runner.invoke(app, ["report", str(tmp_path / "results")])
    assert result.exit_code == 1, result.output
    assert result.output.strip() == (
        f"error: {second}: a second run at ratio 1.1, 0.0333333 h, t in ms (the default), beside {first}; the "
        f"value-ratio table has one cell for each: move one of them out of {root.parent}")
    assert not (tmp_path / "results" / "REPORT.md").exists()
    shutil.rmtree(second.parent)
    smaller = run_copy(finished_run(*base, "team.n_robots=4", "tasks.values=[2400,2000]", name="initial_distribution"),
                       into=root / "b")
    result = runner.invoke(app, ["report", str(tmp_path / "results")])
    assert result.exit_code == 1, result.output
    assert result.output.strip() == (
        f"error: {smaller}: its team is not that of {first}, in the same column of the value-ratio table (t in ms "
        f"(the default), 0.0333333 h); move one of them out of {root.parent}, or run it again alike")
