"""Runs' saved tables read for the studies that gather runs: the horizon ladder's rungs, a sweep's
jobs, the value-ratio sweep's points and the model's table. What is read here is handed to
`analysis` (`analysis.ladder`, `analysis.sweep`, `analysis.value_ratio`), which works the numbers
out without touching a file."""

from __future__ import annotations

import io
import math
from collections.abc import Iterable, Mapping, Sequence
from pathlib import Path

import pandas as pd

from tavc_cli.analysis import ladder, sweep, value_ratio
from tavc_cli.errors import TavcError
from tavc_cli.notation import state_counts
from tavc_cli.readers import TableSpec, read_table, read_text
from tavc_cli.run_checks import check_run
from tavc_cli.settings import from_yaml

SUMMARY_LIMIT = 64 * 2**20  # a study's table of its runs (ladder.csv, sweep.csv), read bounded as every table is

STATES = {"state": str}  # a state column read as text ("3:3"), never as a number or a time
_RUNG_TABLES = ("claims", "convergence", "mechanism")  # a rung's tables the ladder reads where the run wrote them
MODEL_REWRITE = "run `tavc model` again to rewrite it"
_MODEL = TableSpec(columns=("split", "circuit", "c_per_s", "task_time_s"),
                   numbers=("circuit", "c_per_s", "task_time_s"), text=("split", "state"), filled=("split", "circuit"),
                   counts=("circuit",))


def read_rung(folder: Path) -> ladder.Rung:
    """One rung of the ladder as its folder holds it: its factor and duration (`config.yaml`), its
    state table and per-trial statistics, and its claims, convergence and mechanism tables where it has them."""
    check_run(folder)  # read back as the report reads a run: bounded, whole, its own
    cfg = from_yaml(folder / "config.yaml")
    tables = {"state_time": pd.read_csv(folder / "state_time.csv", dtype=STATES),
              "trial_stats": pd.read_csv(folder / "trial_stats.csv")}
    tables.update({name: pd.read_csv(folder / f"{name}.csv") for name in _RUNG_TABLES
                   if (folder / f"{name}.csv").is_file()})
    return ladder.Rung(float(cfg.scale.time_factor), float(cfg.duration_s), tables)


def ladder_table(folders: Sequence[Path]) -> pd.DataFrame:
    """`ladder.csv` from the rungs' folders, the shortest horizon first (`analysis.ladder.ladder_table`)."""
    return ladder.ladder_table([read_rung(f) for f in folders])


def summary_text(table: pd.DataFrame) -> str:
    """A table of a study's runs side by side (`ladder.csv`, `sweep.csv`) as tavc writes it."""
    return table.to_csv(index=False, float_format="%.4f")


def rung_folders(ladder_dir: Path, factors: Iterable[float]) -> dict[float, Path]:
    """The rung of each of `factors` (as `ladder.csv` gives them, rounded to four places) among the
    folders in `ladder_dir`: the one whose `config.yaml` holds that multiple of the chapter's
    durations. Hidden folders (a user's copies) are passed over, as everywhere in a results tree."""
    wanted = {f"{float(f):.4f}": float(f) for f in factors}
    found: dict[float, Path] = {}
    for d in sorted(ladder_dir.iterdir(), key=lambda p: p.name):
        if d.name.startswith(".") or d.is_symlink() or not (d / "config.yaml").is_file():
            continue
        factor = rung_factor(d)  # its settings as a run keeps them, or it is no rung of this table
        if factor in wanted:
            found.setdefault(wanted[factor], d)
    return found


def rung_factor(folder: Path) -> str | None:
    """The multiple of the chapter's durations the run in `folder` was made at, as `ladder.csv`
    gives it (four places), or None where its `config.yaml` cannot be read (the run checks name
    it, where the run is read)."""
    try:
        return f"{float(from_yaml(folder / 'config.yaml').scale.time_factor):.4f}"
    except Exception:  # noqa: BLE001 - whatever is wrong with it, it says no factor
        return None


def check_ladder(path: Path) -> None:
    """One line where `ladder.csv` at `path` is not what its rungs (`rung_folders`) give now
    (`ladder_table`, row for row): a rung run again since would put its claims beside another
    run's numbers. The claims' rows are left out: the report tests every rung's claims again by
    today's rules, on the rungs themselves."""
    stored = pd.read_csv(io.StringIO(read_text(path, SUMMARY_LIMIT)), dtype=str, keep_default_na=False)
    factors = sorted({float(f) for f in stored["factor"]})
    rungs = rung_folders(path.parent, factors)
    if missing := [f for f in factors if f not in rungs]:
        raise TavcError(f"{path}: lists a rung at {missing[0]:g} times the chapter's durations that is not beside "
                        "it; run its `tavc ladder` again to rewrite it")
    fresh = pd.read_csv(io.StringIO(summary_text(ladder_table([rungs[f] for f in factors]))), dtype=str,
                        keep_default_na=False)

    def compared(t: pd.DataFrame) -> pd.DataFrame:
        return t[~t["quantity"].str.startswith("claim")].reset_index(drop=True)

    if not compared(fresh).equals(compared(stored)):
        raise TavcError(f"{path}: not what its rungs give now (one of them run again since it was written?); "
                        "run its `tavc ladder` again to rewrite it")


def sweep_table(jobs: Sequence[tuple[Mapping[str, str], Path]]) -> pd.DataFrame:
    """`sweep.csv`: one row per job, controller and state (`analysis.sweep.job_rows`), from each job's
    `state_time.csv` and `trial_stats.csv`. Jobs without a state table (one-circuit runs) give no rows."""
    return pd.DataFrame([row for index, (values, folder) in enumerate(jobs)
                         for row in _job_rows(index, values, Path(folder), str(folder))])


def _job_rows(index: int, values: Mapping[str, str], folder: Path, shown: str) -> list[dict]:
    """Job `index`'s rows of `sweep.csv` from its folder, named there as `shown`."""
    states, stats = folder / "state_time.csv", folder / "trial_stats.csv"
    if not states.is_file():
        return []
    check_run(folder)  # read back as the report reads a run: bounded, whole, its own
    return sweep.job_rows(index, values, shown, pd.read_csv(states), pd.read_csv(stats) if stats.is_file() else None)


def job_folder(path: Path, recorded: str) -> Path:
    """The folder of a job `sweep.csv` at `path` records as `recorded`: beside the table (wherever
    the sweep now lies), else, for a sweep over output_dir whose jobs lie apart, the recorded path
    (a relative one read from the table's folder or a folder above it, as the sweep was run from
    one of them); one line where it is in none of these places."""
    given = Path(recorded)
    tried = [path.parent / given.name, *([given] if given.is_absolute() else
                                         [a / given for a in (path.parent, *path.parent.parents)])]
    found = next((folder for folder in tried if folder.is_dir()), None)
    if found is None:
        raise TavcError(f"{path}: a job's folder, {recorded}, is not there, nor beside it")
    return found


def checked_sweep(path: Path) -> pd.DataFrame:
    """A sweep's `sweep.csv`, once it is what its jobs' own tables give now (each job's folder beside
    it, by the name the table gives it, else where the table says the sweep put it; the swept
    values compared as the text the table holds): one line where a job was run again since, its
    folder is gone, or the table edited."""
    text = read_text(path, SUMMARY_LIMIT)
    table = pd.read_csv(io.StringIO(text), dtype=str, keep_default_na=False)
    columns = list(table.columns)
    if columns[:1] != ["job"] or "output_dir" not in columns:
        raise TavcError(f"{path}: cannot be read (no job and output_dir columns); run the sweep again to rewrite it")
    swept = columns[1:columns.index("output_dir")]
    rows = []
    for job, group in table.groupby("job", sort=False):
        first = group.iloc[0]
        rows += _job_rows(int(job), {c: first[c] for c in swept}, job_folder(path, first["output_dir"]),
                          first["output_dir"])
    if summary_text(pd.DataFrame(rows)) != text:
        raise TavcError(f"{path}: not what its jobs give now (one of them run again since it was written, or the "
                        "table edited); run the sweep again to rewrite it")
    return pd.read_csv(io.StringIO(text))


def in_hidden_folder(folder: Path, root: Path) -> bool:
    """Whether `folder` is, or lies in, a hidden folder below `root` (`.backup/`): a user's copy, not
    a run of the study in `root`, which the studies and the report leave as the report's search
    for runs does (`report.runs.run_folders`)."""
    return any(part.startswith(".") for part in folder.relative_to(root).parts)


def ratio_points(root: Path, controller: str = "tavc") -> pd.DataFrame:
    """One row per finished run below `root` with two circuits (`analysis.value_ratio.ratio_point`):
    `reading,horizon,ratio,values,mean,std,n_trials,...`, each run named relative to `root`. A run
    without its `provenance.json` has not finished (a rerun that stopped may have left the earlier
    run's tables beside its own settings) and gives no row."""
    root = Path(root)
    runs = sorted(p.parent for p in root.rglob("trial_stats.csv")
                  if (p.parent / "config.yaml").is_file() and (p.parent / "provenance.json").is_file()
                  and not in_hidden_folder(p.parent, root))
    points, cells, columns = [], {}, {}
    for d in runs:
        cfg = from_yaml(d / "config.yaml")
        point = value_ratio.ratio_point(cfg, pd.read_csv(d / "trial_stats.csv"), str(d.relative_to(root)), controller)
        if point is None:
            continue
        # a cell holds one run, and a column (a reading) runs alike in what its label does not name
        cell = (point["reading"], point["horizon"], point["ratio"])
        if cell in cells:
            raise TavcError(f"{d}: a second run at ratio {point['ratio']:g}, {point['horizon']}, "
                            f"{point['reading']}, beside {cells[cell]}; the value-ratio table has one cell for each: "
                            f"move one of them out of {root}")
        cells[cell] = d
        first = columns.setdefault(cell[:2], (d, value_ratio.unnamed_settings(cfg)))
        differ = sorted(k for k, v in value_ratio.unnamed_settings(cfg).items() if first[1].get(k) != v)
        if differ:
            raise TavcError(f"{d}: its {differ[0]} is not that of {first[0]}, in the same column of the value-ratio "
                            f"table ({point['reading']}, {point['horizon']}); move one of them out of {root}, or "
                            "run it again alike")
        points.append(point)
    return value_ratio.points_table(points)


def model_rows(model_csv: Path, n_robots: int | None = None) -> pd.DataFrame:
    """A `model.csv` as `tavc model` wrote it, its split and state columns as text, read bounded and
    checked for what its readers take from it (`model.api.table_from_rows`): every split over the
    same circuits, with a row for each of its circuits once, and with `n_robots`, every split of
    that team; one line naming it where it is damaged."""
    rows = read_table(model_csv, _MODEL, MODEL_REWRITE)
    why = _model_rows_fault(rows, n_robots)
    if why:
        raise TavcError(f"{model_csv}: cannot be read ({why}); {MODEL_REWRITE}")
    return rows


def _model_rows_fault(rows: pd.DataFrame, n_robots: int | None) -> str:
    counts = [state_counts(s) for s in rows["split"]]
    bad = next((str(s) for s, c in zip(rows["split"], counts, strict=True) if c is None), None)
    if bad is not None:
        return f"a split that is not one: {bad}"
    if len({len(c) for c in counts}) > 1:
        return "splits over different numbers of circuits"
    k = len(counts[0]) if counts else 0
    if any(sorted(int(c) for c in g) != list(range(k)) for _, g in rows.groupby("split", sort=False)["circuit"]):
        return "a split without a row for each of its circuits, once"
    of_team = {c for c in counts if sum(c) == n_robots}
    if n_robots is not None and k and len(of_team) != math.comb(n_robots + k - 1, k - 1):
        return f"not every split of its team of {n_robots}"
    return ""
