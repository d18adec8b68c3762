"""Reading a run's files for the report: each `config.yaml` parsed once per version of the
file (the report reads every run's settings several times), a file no library can parse
refused in one line naming it; telling folders apart: a run's, a longer horizon's; and the files
of the studies the report reads as a whole (a ladder, the model's, the stay/switch studies', the
turn-taking predictions), each read bounded and checked for what the report takes from it."""

from __future__ import annotations

import os
import re
from functools import lru_cache
from pathlib import Path

import pandas as pd

from tavc_cli.analysis.ladder import LADDER_COLUMNS
from tavc_cli.analysis.matched import ROBOT_COLUMNS, TABLE_COLUMNS, first_tables, kinds, matched_robots
from tavc_cli.analysis.stay_switch import parse_reading, reading_folder
from tavc_cli.errors import TavcError
from tavc_cli.io import plain_name
from tavc_cli.model.allocations import model_differences, model_world
from tavc_cli.ownership import READINGS_DIR, STAY_SWITCH_TABLES, VALUE_RATIO_DIR
from tavc_cli.readers import REWRITE, TableSpec, load_json, read_table
from tavc_cli.run_tables import MODEL_REWRITE, in_hidden_folder, model_rows
from tavc_cli.settings import TavcConfig, from_yaml


def config_of(path: Path) -> TavcConfig:
    """A run's settings from its `config.yaml`, read once per version of the file (its
    resolved path, modification time and size). The settings are shared between callers:
    read them, never change them."""
    stat = path.stat()
    return _config_of(str(path.resolve()), stat.st_mtime_ns, stat.st_size)


@lru_cache(maxsize=1024)  # a results folder holds hundreds of runs (425 today), each read by several sections
def _config_of(path: str, mtime_ns: int, size: int) -> TavcConfig:
    return from_yaml(Path(path))


def read_or_refuse(path: Path, read, advice: str = REWRITE):
    """`read(path)`, with any failure to read or parse the file as one line naming it and `advice`,
    what to do."""
    try:
        return read(path)
    except TavcError:
        raise
    except Exception as exc:  # any library's parse error: the file is damaged, whatever the library
        detail = exc.strerror if isinstance(exc, OSError) and exc.strerror else \
            (str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__)
        raise TavcError(f"{path}: cannot be read ({detail}); {advice}") from None


CONVERGED_DIR = "converged"  # `make reproduce-converged`'s horizon
# a longer horizon's folder directly under the results folder: `converged/`, or `x<factor>/` (`x10`,
# `x2.5`) as the horizon ladder names its rungs, holding that horizon's run folders
_HORIZON_NAME = re.compile(r"x\d+(\.\d+)?")


def is_horizon_folder(d: Path) -> bool:
    """Whether `d`, directly under a results folder, holds a longer horizon's runs: named
    `converged` or `x<factor>`, a folder (not a link) that is not itself a run's."""
    return (d.name == CONVERGED_DIR or _HORIZON_NAME.fullmatch(d.name) is not None) and d.is_dir() \
        and not d.is_symlink() and not is_run_folder(d)


def horizon_folders(results_dir: Path) -> list[Path]:
    """The folders of the longer horizons directly under results_dir (`is_horizon_folder`), in
    natural order of their names."""
    return sorted((d for d in results_dir.iterdir() if is_horizon_folder(d)), key=lambda p: natural(p.name))


def is_run_folder(d: Path) -> bool:
    """Whether `d` is a run's folder, finished or not: what `tavc run` writes first (its
    `config.yaml`, its `trials/`) or last (its tables) is there."""
    return (d / "config.yaml").is_file() or (d / "state_time.csv").is_file() or (d / "trials").is_dir()


def run_in(d: Path, experiment: str) -> Path:
    """The run in `d`: `d` itself, or, where `d` holds the runs of several experiments as `tavc
    reproduce --results` writes them, its run of `experiment` (if there is one)."""
    return d if is_run_folder(d) or not (d / experiment).is_dir() else d / experiment


def model_learners(where: Path, predicted: dict) -> Path | None:
    """The folder of a prediction's own learners' run (`learners_run` in `turn_taking.json`,
    beside it in `where`); None where the name is not one folder's."""
    return _model_run(where, str(predicted.get("learners_run", "learners")))


def model_alternators(where: Path, predicted: dict) -> Path | None:
    """The folder of the static alternators' run a prediction takes its modal state from
    (`alternators_run`, where `modal_from` says so); None where it takes it from its learners, or
    the name is not one folder's."""
    if predicted.get("modal_from") != "alternators":
        return None
    return _model_run(where, str(predicted.get("alternators_run", "alternators")))


def _model_run(where: Path, name: str) -> Path | None:
    return where / name if plain_name(name) else None


def sweep_runs(results_dir: Path, folder: str) -> list[Path]:
    """The runs of the sweep in `results_dir/folder` (`SWEEPS`, or a horizon's readings), finished or
    not: every folder with a `config.yaml` at any depth but in hidden folders (`run_tables.in_hidden_folder`), in
    natural order of their paths."""
    root = results_dir / folder
    if not root.is_dir() or root.is_symlink():
        return []
    found = (p.parent for p in root.rglob("config.yaml") if not in_hidden_folder(p.parent, root))
    return sorted(found, key=lambda p: natural(p.as_posix()))


def natural(text: str) -> list:
    """A sort key that orders "2_seed=3" before "10_seed=11"."""
    return [int(part) if part.isdigit() else part for part in re.split(r"(\d+)", text)]


def seed_for_seed_cell(base: Path | None, other: Path | None) -> str:
    """"same of matched (chance)" for two runs of one experiment (`analysis.matched`); "" where
    either run, or its robots' or Q-values' table, is missing; "none matched" where no robot
    starts from the same table in both. A table without the columns that needs is refused in
    one line naming it."""
    if base is None or other is None:
        return ""
    paths = [d / f"{name}.csv" for d in (base, other) for name in ("robots", "q_values")]
    if not all(p.is_file() for p in paths):
        return ""
    matched = matched_robots(*(_seed_table(p) for p in paths))
    return "none matched" if matched is None else f"{matched.same} of {matched.robots} ({matched.chance:.0f})"


def _seed_table(path: Path) -> pd.Series | pd.DataFrame:
    """A run's robots' kinds (`matched.kinds`) or first Q-tables (`matched.first_tables`), from its
    `robots.csv` or `q_values.csv`, read once per version of the file (a run is set beside several
    others); refused in one line naming it where a column `analysis.matched` needs is missing.
    Shared between callers: never changed."""
    stat = path.stat()
    return _seed_table_of(str(path), stat.st_mtime_ns, stat.st_size, path.name == "q_values.csv")  # named as given


@lru_cache(maxsize=1024)  # two tables a run, for every run a prediction is set beside
def _seed_table_of(path: str, mtime_ns: int, size: int, q_values: bool) -> pd.Series | pd.DataFrame:
    table = read_or_refuse(Path(path), read_table)
    missing = [c for c in (TABLE_COLUMNS if q_values else ROBOT_COLUMNS) if c not in table.columns]
    if missing:
        raise TavcError(f"{path}: cannot be read (no column {missing[0]!r}); rerun its experiment to rewrite it")
    return first_tables(table) if q_values else kinds(table)


STAY_SWITCH_REWRITE = "run its `tavc stay-switch` again to rewrite it"
# a stay/switch study's tables as the report reads them, in the order of `ownership.STAY_SWITCH_TABLES`
_STAY_SWITCH_SPECS = (
    TableSpec(columns=("reading", "high_stayers", "low_stayers", "alternators", "ratio_low", "threshold_low",
                       "stay_pays_low", "stay_pays_low_source"),
              numbers=("high_stayers", "low_stayers", "alternators", "ratio_low", "threshold_low"),
              filled=("reading", "high_stayers", "low_stayers", "alternators", "threshold_low"),
              counts=("high_stayers", "low_stayers", "alternators"), flags=("stay_pays_low", "stay_pays_low_source")),
    TableSpec(columns=("reading", "regime", "basin", "robots_high"), numbers=("basin", "robots_high"),
              filled=("reading", "regime", "basin", "robots_high")),
    TableSpec(columns=("reading", "regime", "robots_high", "modal_state", "modal_share_pct"),
              numbers=("robots_high", "modal_share_pct"), text=("modal_state",), filled=("reading", "regime"),
              unique=("reading",)),
)


def there(path: Path) -> bool:
    """Whether anything is at `path`: a file, a folder, a link (one that leads nowhere too), which a
    reader then reads or refuses, rather than taking it for a file not written."""
    return os.path.lexists(path)


def read_stay_switch(folder: Path) -> tuple[pd.DataFrame | None, ...] | None:
    """A stay/switch study's tables in `folder` (its table, drift model and turn-taking model, each
    None where not written) and its record ({} where none), each read bounded and checked
    (`readers.read_table`, `read_record`: one line naming a damaged one); None where the study
    wrote no table there."""
    if not there(folder / STAY_SWITCH_TABLES[0]):
        return None
    tables = tuple(read_table(folder / name, spec, STAY_SWITCH_REWRITE) if there(folder / name) else None
                   for name, spec in zip(STAY_SWITCH_TABLES, _STAY_SWITCH_SPECS, strict=True))
    for name, table in zip(STAY_SWITCH_TABLES, tables, strict=True):  # a reading names a folder of its runs
        folders = (reading_folder(parse_reading(str(r))) for r in (table["reading"] if table is not None else ()))
        bad = next((f for f in folders if f and not plain_name(f)), None)
        if bad is not None:
            raise TavcError(f"{folder / name}: cannot be read (a reading whose runs' folder leads elsewhere: {bad}); "
                            f"{STAY_SWITCH_REWRITE}")
    path = folder / "stay_switch.json"
    record = read_record(path, STAY_SWITCH_REWRITE) if there(path) else {}
    readings = record.get("readings", {})
    if not isinstance(readings, dict) or not all(
            isinstance(r, dict) and isinstance(r.get("calibrated", []), list)
            and all(isinstance(o, str) for o in r.get("calibrated", [])) for r in readings.values()):
        raise TavcError(f"{path}: cannot be read (its readings are not each reading's settings); "
                        f"{STAY_SWITCH_REWRITE}")
    return (*tables, record)


_MEASURED = ("trials_per_makeup", "measure_s", "warmup_s")  # numbers in a study's record, where it has them


def read_record(path: Path, advice: str) -> dict:
    """A study's JSON record (`stay_switch.json`, the surrogate's `task_times.json`), read bounded
    (`readers.load_json`), its ``measurement`` a map whose trials and times are numbers; one line
    naming the file and `advice` otherwise."""
    record = read_or_refuse(path, load_json, advice)
    measurement = record.get("measurement", {}) if isinstance(record, dict) else None
    if not isinstance(measurement, dict) or any(not _is_number(v) for k, v in measurement.items() if k in _MEASURED):
        raise TavcError(f"{path}: cannot be read (not a record of the study's measurement); {advice}")
    return record


def _is_number(value: object) -> bool:
    return isinstance(value, int | float) and not isinstance(value, bool)


LADDER_REWRITE = "run its `tavc ladder` again to rewrite it"
_LADDER = TableSpec(columns=tuple(LADDER_COLUMNS), numbers=("factor", "duration_s", "mean", "std", "n_trials"),
                    text=("controller", "quantity"), filled=("factor", "controller", "quantity"), counts=("n_trials",),
                    unique=("factor", "controller", "quantity"), rows=True)


def read_ladder(path: Path) -> pd.DataFrame:
    """A horizon ladder's `ladder.csv` (`analysis.ladder.LADDER_COLUMNS`), read bounded and checked
    (`readers.read_table`: one line naming a damaged one)."""
    return read_table(path, _LADDER, LADDER_REWRITE)


# a team the report predicts for from a model file: far more robots than any arena of tavc's starts
# with (the chapter's six), few enough that every split of them is quick to go through
MAX_MODEL_ROBOTS = 1000


def check_model(folder: Path) -> None:
    """A run's model (`model/model.json` and `model/model.csv`, `tavc model`), where it has one,
    checked for what the report reads of it: the team size (at most `MAX_MODEL_ROBOTS`),
    prediction and measurement, each team size's prediction, the world's time budget, and a table
    (`run_tables.model_rows`) with every split of the team; one line naming what is wrong
    (`readers.load_json`: read bounded)."""
    path, table, n_robots = folder / "model" / "model.json", folder / "model" / "model.csv", None
    if there(path):
        model = read_or_refuse(path, load_json, MODEL_REWRITE)
        why = _model_fault(model)
        if why:
            raise TavcError(f"{path}: cannot be read ({why}); {MODEL_REWRITE}")
        n_robots = model["n_robots"]
    if there(table):
        model_rows(table, n_robots)


def model_misfit(model_json: Path, cfg: TavcConfig) -> str:
    """Why the model at `model_json` (a `check_model`-checked `model.json`) is no model of the run
    of `cfg`, in the settings its file records (`model.api.model_identity`: a setting it does not
    record is not compared): another arena, task values, unit of t or robot speed, or a team
    smaller than the run's; "" where it is one."""
    model = load_json(model_json)
    differ = model_differences(model, model_world(cfg))
    if int(model["n_robots"]) < int(cfg.team.n_robots):
        differ.append(f"team sizes up to {model['n_robots']} (the run: {cfg.team.n_robots})")
    return "; ".join(differ)


def _model_fault(model: object) -> str:
    if not isinstance(model, dict):
        return "not a JSON object"
    n, world = model.get("n_robots"), model.get("world", {})
    whole = isinstance(n, int) and not isinstance(n, bool) and 1 <= n <= MAX_MODEL_ROBOTS  # NaN, infinity: no team
    if not whole or not isinstance(model.get("predicted_state"), str):
        return f"no team size of 1 to {MAX_MODEL_ROBOTS:,} robots and prediction, n_robots and predicted_state"
    measurement = model.get("measurement")
    if not isinstance(measurement, dict) or not _is_number(measurement.get("trials_per_split")):
        return "no record of its measurement, trials_per_split"
    sizes = model.get("by_team_size", {})
    if not isinstance(sizes, dict) or not all(str(k).isascii() and str(k).isdigit() and isinstance(v, dict)
                                              and isinstance(v.get("predicted_state"), str) for k, v in sizes.items()):
        return "by_team_size is not a prediction for each team size"
    budget = world.get("time_budget", []) if isinstance(world, dict) else None
    if not isinstance(budget, list) or not all(isinstance(b, dict) and isinstance(b.get("split"), str)
                                               and _is_number(b.get("task_time_s")) for b in budget):
        return "world.time_budget is not a task time for each split and circuit"
    return ""


PREDICTION_REWRITE = "run its `tavc model --turn-taking` again to rewrite it"
_PREDICTED_TEXT = ("regime", "modal_state")  # what a prediction always names
_PREDICTED_NAMES = ("modal_from", "learners_run", "alternators_run", "switches")  # text or null, where there


def read_prediction(path: Path) -> dict:
    """A turn-taking prediction (`turn_taking.json`), read bounded (`readers.load_json`) and checked
    for what the report reads of it: its regime and modal state, its robots on the high-value
    circuit and the modal state's share as numbers, the names of its runs as text (or null); one
    line naming the file otherwise."""
    predicted = read_or_refuse(path, load_json, PREDICTION_REWRITE)
    fine = isinstance(predicted, dict) and all(isinstance(predicted.get(k), str) for k in _PREDICTED_TEXT) \
        and all(_is_number(predicted.get(k)) for k in ("robots_high", "modal_share_pct")) \
        and all(isinstance(predicted.get(k), str | None) for k in _PREDICTED_NAMES)
    if not fine:
        raise TavcError(f"{path}: cannot be read (not a prediction: a regime and modal state, robots_high and "
                        f"modal_share_pct); {PREDICTION_REWRITE}")
    return predicted


TURN_TAKING_RUNS = "turn_taking"  # under the results folder: the turn-taking model at the chapter's scenarios
TEAM_SIZE_DIR = "team_size"  # under the results folder: the learners at other team sizes (`make team-size-checks`)
# the sweeps under the results folder the report reads as studies, not run by run, each with where
# it is read: a prediction of the turn-taking model is set beside their runs at 40x in its world
SWEEPS = {VALUE_RATIO_DIR: "the value-ratio sweep, in *Learning values and time*",
          TEAM_SIZE_DIR: "the team-size sweep, in *The readings* (the turn-taking model's check points)"}
READINGS_RUNS = READINGS_DIR  # under a results or horizon folder: runs in a reading, <arrival>-<passing>-<arena>


def prediction_files(results_dir: Path, under: str = TURN_TAKING_RUNS) -> list[Path]:
    """Every turn-taking prediction under results_dir/`under` (`<name>/turn_taking/turn_taking.json`;
    by default the model's at the chapter's scenarios, a stay/switch study's folder for its
    readings'), in natural order of its name; a folder or a dangling link in a prediction's place
    too, for its reader (`read_prediction`) to refuse."""
    root = results_dir / under
    folders = root.glob("*/turn_taking") if root.is_dir() else ()
    return sorted((d / "turn_taking.json" for d in folders if there(d / "turn_taking.json")),
                  key=lambda p: natural(p.as_posix()))
