"""The surrogate's measured tasks are drawn from only when their record vouches for them (the same
settings, today's code, the bytes it was written with); anything else is named in one note and
measured again by the same command, and the surrogate's own code is in its trials' keys."""

from __future__ import annotations

import hashlib
import json
import shutil
from pathlib import Path

import pytest

from tavc_cli import config
from tavc_cli.errors import TavcError
from tavc_cli.io import file_digest
from tavc_cli.run_checks import check_run
from tavc_cli.surrogate import digest as surrogate_digest
from tavc_cli.surrogate import run as surrogate_run
from tavc_cli.surrogate.run import measure_tasks, run_surrogate, surrogate_code_digest, surrogate_specs
from tests.helpers import modules_reached

# two robots at the smoke scale: 6 make-ups, 2 static trials of 66 s each (about two seconds)
OVERRIDES = ["experiment=initial_distribution", "scale=smoke", "team.n_robots=2"]


def settings(tasks_dir: Path, *more: str):
    return config.settings(config.load_config([*OVERRIDES, f"surrogate.tasks_dir={tasks_dir}", *more]))


def sha(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


@pytest.fixture(scope="module")
def clean(tmp_path_factory) -> Path:
    """A folder of tasks measured once, undisturbed: what every healed folder must equal."""
    folder = tmp_path_factory.mktemp("clean") / "tasks"
    said: list[str] = []
    measure_tasks(settings(folder), echo=said.append)
    assert len(said) == 1 and said[0].startswith("surrogate: measuring 6 make-ups")  # no note on a new folder
    return folder


@pytest.fixture
def copy(clean, tmp_path) -> Path:
    """The clean folder copied (its trials/ and .tavc.json too), with a sibling folder and a file
    of somebody else's beside the tasks, which no healing may touch."""
    folder = tmp_path / "tasks"
    shutil.copytree(clean, folder)
    (tmp_path / "sibling").mkdir()
    (tmp_path / "sibling" / "task_times.csv").write_text("somebody's table\n")
    (folder / "notes.txt").write_text("somebody's notes\n")
    return folder


def _rows(folder: Path) -> list[str]:
    return (folder / "task_times.csv").read_text().splitlines(keepends=True)


def cut_to_whole_rows(folder: Path) -> None:
    rows = _rows(folder)
    (folder / "task_times.csv").write_text("".join(rows[:len(rows) // 2]))


def cut_mid_row(folder: Path) -> None:
    rows = _rows(folder)
    cut = len("".join(rows[:3])) + len(rows[3]) // 2  # halfway through the third task
    (folder / "task_times.csv").write_text("".join(rows)[:cut])


def edit_a_time(folder: Path) -> None:
    rows = _rows(folder)
    fields = rows[1].split(",")
    fields[5] = str(float(fields[5]) * 2)  # task_time_s of the first task, doubled
    (folder / "task_times.csv").write_text("".join([rows[0], ",".join(fields), *rows[2:]]))


def remove_the_record(folder: Path) -> None:
    (folder / "task_times.json").unlink()


def garbage_table(folder: Path) -> None:
    (folder / "task_times.csv").write_bytes(b"\x00\xff not a table,\n\"unterminated")


def garbage_record(folder: Path) -> None:
    (folder / "task_times.json").write_text("{ not json")


def _edit_record(folder: Path, **changes) -> None:
    record = json.loads((folder / "task_times.json").read_text())
    for key, value in changes.items():
        if value is None:
            record.pop(key)
        else:
            record[key] = value
    (folder / "task_times.json").write_text(json.dumps(record, indent=2))


def other_code(folder: Path) -> None:
    _edit_record(folder, code_digest="0" * 16)


def other_surrogate_code(folder: Path) -> None:
    _edit_record(folder, surrogate_code_digest="0" * 16)


def record_without_digests(folder: Path) -> None:
    _edit_record(folder, code_digest=None, surrogate_code_digest=None, task_times_sha256=None)


def wrong_columns_vouched_for(folder: Path) -> None:
    """A table of other columns whose digest the record was edited to match."""
    (folder / "task_times.csv").write_text("team,makeup\nall:2@0.25,all:0-0-2\n")
    _edit_record(folder, task_times_sha256=sha(folder / "task_times.csv"))


# each damage, and what its note says after the file it names
DAMAGES = [
    (cut_to_whole_rows, "task_times.csv does not match the digest task_times.json recorded (edited or cut)"),
    (cut_mid_row, "task_times.csv does not match the digest task_times.json recorded (edited or cut)"),
    (edit_a_time, "task_times.csv does not match the digest task_times.json recorded (edited or cut)"),
    (garbage_table, "task_times.csv does not match the digest task_times.json recorded (edited or cut)"),
    (remove_the_record, "task_times.csv has no task_times.json beside it"),
    (garbage_record, "task_times.json cannot be read as the record of the measured tasks"),
    (other_code, "task_times.json records another code_digest (0000000000000000; "),
    (other_surrogate_code, "task_times.json records another surrogate_code_digest (0000000000000000; "),
    (record_without_digests, "task_times.json records no code_digest: its tasks were measured by other code"),
    (wrong_columns_vouched_for, "task_times.csv cannot be read as measured tasks"),
]


@pytest.mark.parametrize("damage, why", DAMAGES, ids=[d.__name__ for d, _ in DAMAGES])
def test_a_damaged_or_stale_cache_heals_with_one_note(clean, copy, damage, why):
    others = [copy.parent / "sibling" / "task_times.csv", copy / "notes.txt"]
    before = [sha(p) for p in others]
    damage(copy)
    said: list[str] = []
    times = measure_tasks(settings(copy), echo=said.append)
    notes = [line for line in said if line.startswith("note:")]
    assert len(notes) == 1 and notes[0].startswith(f"note: {copy}/{why}")  # one note, naming the file and why
    assert notes[0].endswith("; measuring the tasks again")
    assert len(said) == 2 and said[1].startswith("surrogate: measuring 6 make-ups")
    assert (copy / "task_times.csv").read_bytes() == (clean / "task_times.csv").read_bytes()
    assert (copy / "task_times_summary.csv").read_bytes() == (clean / "task_times_summary.csv").read_bytes()
    assert (copy / "task_times.json").read_bytes() == (clean / "task_times.json").read_bytes()
    assert len(times.frame) == len(_rows(clean)) - 1
    again: list[str] = []
    measure_tasks(settings(copy), echo=again.append)
    assert again == []  # healed: read as it is
    assert [sha(p) for p in others] == before


def test_a_table_larger_than_tavc_reads_is_measured_again_with_one_note(clean, copy, monkeypatch):
    size = (copy / "task_times.csv").stat().st_size
    monkeypatch.setattr(surrogate_run, "TABLE_LIMIT", size - 1)  # as a table past 256 MiB is, without writing one
    said: list[str] = []
    measure_tasks(settings(copy), echo=said.append)
    assert said[0] == (f"note: {copy}/task_times.csv: cannot be read ({size} bytes, more than the {size - 1} tavc "
                       "reads of it); measuring the tasks again")
    assert (copy / "task_times.csv").read_bytes() == (clean / "task_times.csv").read_bytes()


def test_a_record_without_its_table_is_measured_again_quietly(clean, copy):
    """As results/ keeps them: the record and the summary, not the table; nothing to draw from."""
    (copy / "task_times.csv").unlink()
    record_without_digests(copy)
    said: list[str] = []
    measure_tasks(settings(copy), echo=said.append)
    assert len(said) == 1 and said[0].startswith("surrogate: measuring 6 make-ups")
    assert (copy / "task_times.csv").read_bytes() == (clean / "task_times.csv").read_bytes()
    assert (copy / "task_times.json").read_bytes() == (clean / "task_times.json").read_bytes()


def test_the_record_names_the_code_and_the_tables_bytes(clean):
    from tavc_cli.experiments.spec import code_digest

    record = json.loads((clean / "task_times.json").read_text())
    assert record["code_digest"] == code_digest()
    assert record["surrogate_code_digest"] == surrogate_code_digest()
    assert record["task_times_sha256"] == sha(clean / "task_times.csv")


def test_tasks_of_other_settings_are_still_refused_in_one_line(copy):
    before = {p.name: sha(p) for p in copy.iterdir() if p.is_file()}
    with pytest.raises(TavcError, match="other settings") as refused:
        measure_tasks(settings(copy, "surrogate.measure_s=2000"), echo=print)
    assert "\n" not in str(refused.value) and "overwrite=true" in str(refused.value)
    assert {p.name: sha(p) for p in copy.iterdir() if p.is_file()} == before


def test_a_table_tavc_did_not_write_is_refused_not_replaced(copy):
    manifest = json.loads((copy / ".tavc.json").read_text())
    manifest["files"].remove("task_times.csv")
    (copy / ".tavc.json").write_text(json.dumps(manifest))
    remove_the_record(copy)
    mine = sha(copy / "task_times.csv")
    with pytest.raises(TavcError, match="task_times.csv was not written by tavc"):
        measure_tasks(settings(copy), echo=print)
    assert sha(copy / "task_times.csv") == mine


def test_a_folder_of_other_files_or_another_runs_trials_is_refused_before_anything_is_measured(tmp_path):
    mine = tmp_path / "mine"
    mine.mkdir()
    (mine / "notes.txt").write_text("somebody's notes\n")
    trials = tmp_path / "run" / "trials"  # another run's records
    trials.mkdir(parents=True)
    for name in ("random_000.npz", "tavc_000.npz"):
        (trials / name).write_bytes(b"a record\n")
    for folder, shown in ((mine, "notes.txt"), (trials, "random_000.npz, tavc_000.npz")):
        before = {p.name: sha(p) for p in folder.iterdir()}
        said: list[str] = []
        with pytest.raises(TavcError) as refused:
            measure_tasks(settings(folder), echo=said.append)
        assert str(refused.value) == (
            f"surrogate.tasks_dir: {folder} holds files that are not the surrogate's measured tasks ({shown}); the "
            "tasks and the trials they are measured from need a new or empty folder, or one they were measured in "
            "before: choose another folder")
        assert said == [] and {p.name: sha(p) for p in folder.iterdir()} == before  # no lock, list or trials/ left


@pytest.mark.parametrize(("tasks", "where"), [
    ("run", "is the run's folder (output_dir)"),
    (".", "holds the run's folder (output_dir)"),
    ("run/trials", "is inside the run's folder (output_dir), where only its tasks/ may be"),
])
def test_tasks_that_would_share_the_runs_folder_are_refused_before_anything_is_measured(tmp_path, tasks, where,
                                                                                          monkeypatch):
    monkeypatch.chdir(tmp_path)
    cfg = config.settings(config.load_config([*OVERRIDES, "output_dir=run", f"surrogate.tasks_dir={tasks}"]))
    with pytest.raises(TavcError) as refused:
        run_surrogate(cfg, echo=print)
    assert str(refused.value) == (f"surrogate.tasks_dir: {tasks} {where}; the measured tasks need a folder of their "
                                  f"own: leave it unset ({tmp_path / 'run' / 'tasks'}) or name one outside "
                                  f"{tmp_path / 'run'}")
    assert list(tmp_path.iterdir()) == []  # nothing measured, nothing made


def test_the_surrogates_code_is_in_its_digest_and_its_trials_keys(clean, tmp_path, monkeypatch):
    digest = surrogate_code_digest.__wrapped__  # uncached: the same folder is digested again after an edit
    package = Path(surrogate_run.__file__).resolve().parent.parent
    for edit, text in (("none", ""), ("engine.py", "_EDITED = 1\n"), ("tasks.py", "_EDITED = 1\n"),
                       ("compare.py", "_EDITED = 1\n"), ("engine.py", "# a comment, which computes nothing\n")):
        root = tmp_path / f"{edit}{len(text)}"
        shutil.copytree(package / "surrogate", root / "surrogate", ignore=shutil.ignore_patterns("__pycache__"))
        (root / "experiments").mkdir()
        shutil.copy(package / "experiments" / "plan.py", root / "experiments" / "plan.py")
        if text:
            with open(root / "surrogate" / edit, "a") as fh:
                fh.write(text)
        # code in engine.py and tasks.py decides a drawn trial; compare.py only reads finished runs
        unchanged = edit in ("none", "compare.py") or text.startswith("#")
        assert (digest(root) == surrogate_code_digest()) == unchanged, (edit, text)
    cfg = settings(clean)
    times = measure_tasks(cfg, echo=print)
    keys = [s.key() for s in surrogate_specs(cfg, times)]
    monkeypatch.setattr(surrogate_run, "surrogate_code_digest", lambda: "0" * 16)
    edited_keys = [s.key() for s in surrogate_specs(cfg, times)]
    assert len(keys) > 0 and all(a != b for a, b in zip(keys, edited_keys, strict=True))


def test_a_surrogate_trial_drawn_by_other_surrogate_code_is_drawn_again(copy, tmp_path, monkeypatch):
    from tavc_cli.experiments.records import TrialRecord

    cfg = settings(copy, "trials=1", f"output_dir={tmp_path / 'run'}")
    run_surrogate(cfg, echo=lambda _: None)
    records = sorted((tmp_path / "run" / "trials").glob("*.npz"))
    drawn = {p.name: TrialRecord.load(p).meta["key"] for p in records}
    monkeypatch.setattr(surrogate_run, "surrogate_code_digest", lambda: "0" * 16)
    run_surrogate(cfg, echo=lambda _: None)
    again = {p.name: TrialRecord.load(p).meta["key"] for p in records}
    assert len(drawn) > 0 and drawn.keys() == again.keys() and all(drawn[n] != again[n] for n in drawn)
    assert all(TrialRecord.load(p).meta["engine"].endswith(":" + "0" * 16) for p in records)


def test_a_surrogate_run_is_held_to_its_trials_keys_and_its_code_named(copy, tmp_path):
    run = tmp_path / "run"
    run_surrogate(settings(copy, "trials=1", f"output_dir={run}"), echo=lambda _: None)
    prov = json.loads((run / "provenance.json").read_text())
    assert prov["engine"].startswith("surrogate:") and prov["engine"].endswith(":" + surrogate_code_digest())
    assert check_run(run).other_code is None
    # the settings edited after the run, the digest written again: the keys tell
    config_yaml = run / "config.yaml"
    original = config_yaml.read_bytes()
    config_yaml.write_bytes(original.replace(b"  - 2200.0\n", b"  - 2300.0\n", 1))
    prov["tables"]["config.yaml"] = file_digest(config_yaml)
    (run / "provenance.json").write_text(json.dumps(prov, indent=2))
    with pytest.raises(TavcError, match=r"provenance.json: tavc trial 0 is listed under a key its config.yaml and "
                                        r"plan.json do not give it"):
        check_run(run)
    # drawn by other surrogate code: said so, its keys not held to this code's
    config_yaml.write_bytes(original)
    prov["tables"]["config.yaml"] = file_digest(config_yaml)
    prov["engine"] = prov["engine"].rsplit(":", 1)[0] + ":" + "0" * 16
    (run / "provenance.json").write_text(json.dumps(prov, indent=2))
    assert check_run(run).other_code == "0" * 16 + " (the surrogate's)"


def test_the_surrogate_digest_covers_every_module_its_engine_runs():
    """As the simulator's trial key covers every module its engine reaches (test_structure), the
    surrogate's trials' keys cover every module its engine reaches: the simulator's code
    (`code_digest`) or the surrogate's own (`surrogate_code_digest`)."""
    from tavc_cli import COMPILED_SOURCES
    from tavc_cli.experiments.spec import _OUTCOME_CODE

    root = Path(surrogate_run.__file__).resolve().parent.parent
    covered = {p for p in (*_OUTCOME_CODE, *surrogate_digest._SURROGATE_CODE) if p.endswith(".py")}
    covered.add("experiments/build.py")  # builds specs from settings (tasks.py's measuring trials): keyed as specs
    dirs = [p for p in _OUTCOME_CODE if not p.endswith(".py")]
    seen = modules_reached(root, "surrogate/engine.py", (*COMPILED_SOURCES, "surrogate"))
    missing = sorted(p for p in seen if p not in covered and not any(p.startswith(d + "/") for d in dirs))
    assert "surrogate/tasks.py" in seen and not missing, f"modules a surrogate trial runs, in no digest: {missing}"
