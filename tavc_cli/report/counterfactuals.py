"""The chapter's experiments in other readings of the world: labelled counterfactuals beside the
headline, never in its place.

A reading's runs sit in `readings/<arrival>-<passing>-<arena>/` under the results folder (at the
chapter's durations) or under a longer horizon's folder, one folder per experiment as
`tavc reproduce --results` writes them. Each such folder is read as a horizon is
(`horizons.read_horizon`), its claims tested on its runs, and every claim gets a row per
reading beside its verdict in today's world at the same horizon: the verdict, the p of the
deciding part and how the group was made (the regime and its robots), so that a verdict is read
with its mechanism.
"""

from __future__ import annotations

from functools import lru_cache
from operator import attrgetter
from pathlib import Path

import numpy as np
import pandas as pd

from tavc_cli import chapter
from tavc_cli.analysis.claims import verdict_words
from tavc_cli.analysis.stay_switch import reading_name, reading_of, split_folder
from tavc_cli.errors import TavcError
from tavc_cli.ownership import WORLD_SEARCH_DIR
from tavc_cli.readers import load_json, read_table
from tavc_cli.report.files import (
    READINGS_RUNS,
    config_of,
    horizon_folders,
    is_run_folder,
    natural,
    read_or_refuse,
    seed_for_seed_cell,
)
from tavc_cli.report.horizons import Horizon, mechanism_cell, read_horizon
from tavc_cli.report.runs import finished_runs
from tavc_cli.report.text import p_cell


def reading_words(folder_name: str) -> str:
    """A reading's folder name in the report's words: ``arrival=range passing=left arena=...``,
    a variant after the arena in brackets (``... arena=two_circuits_parallel (calibrated)``)."""
    split = split_folder(folder_name)
    if split is None:
        return folder_name
    reading, variant = split
    return f"{reading_name(reading)} ({variant})" if variant else reading_name(reading)


def reading_horizons(results_dir: Path) -> list[tuple[str, Horizon]]:
    """(where, the reading's runs read as a horizon) for every folder of a reading holding
    finished runs of the chapter's experiments: `readings/<reading>/` under the results folder
    and under each longer horizon's, in natural order (a reading's folder that is itself a run,
    a check point of the models, is read by the readings' section instead)."""
    return [(d.relative_to(results_dir).as_posix(), read_horizon(d, found, unfinished))
            for d, found, unfinished in _reading_folders(results_dir)]


def check_readings(results_dir: Path) -> None:
    """Refuse a reading's folder whose runs were not all made in the reading its name says
    (`_check_reading`), before the report writes anything: a folder of the experiments' runs, or
    a reading's folder that is itself a run (a check point of the models)."""
    for d, found, _ in _reading_folders(results_dir):
        _check_reading(d, [run for folders in found.values() for run in folders])
    for top in (results_dir, *horizon_folders(results_dir)):
        base = top / READINGS_RUNS
        for d in sorted(base.iterdir()) if base.is_dir() else []:
            if d.is_dir() and not d.is_symlink() and not d.name.startswith(".") and is_run_folder(d) \
                    and (d / "config.yaml").is_file():  # a link or a hidden copy is no run of the report's
                _check_reading(d, [d])


def _reading_folders(results_dir: Path) -> list[tuple[Path, dict[str, list[Path]], list[Path]]]:
    """(the folder, its finished runs by experiment, its unfinished ones) for every reading's folder
    `reading_horizons` reads."""
    out = []
    for top in (results_dir, *horizon_folders(results_dir)):
        base = top / READINGS_RUNS
        if not base.is_dir():
            continue
        for d in sorted((p for p in base.iterdir() if p.is_dir() and not is_run_folder(p)),
                        key=lambda p: natural(p.name)):
            found, unfinished = finished_runs(d)
            if found:
                out.append((d, found, unfinished))
    return out


def _check_reading(d: Path, runs: list[Path]) -> None:
    """Refuse a reading's folder `d` whose `runs` were not all made in one world, the reading its
    name says (`split_folder`: arrival, passing, arena) and, where the name adds a variant, one and
    the same robot and arena: their verdicts go under its name."""
    split = split_folder(d.name)
    first = None
    for run in runs:
        cfg = config_of(run / "config.yaml")
        if split is not None and reading_of(cfg) != split[0]:
            raise TavcError(f"{run}: made in the reading {reading_name(reading_of(cfg))}, not in the one its folder "
                            f"names ({reading_name(split[0])}); move it, or run it again in that reading")
        if first is None:
            first = (run, cfg)
        elif (cfg.robot, cfg.arena) != (first[1].robot, first[1].arena):
            group = "robot" if cfg.robot != first[1].robot else "arena"
            raise TavcError(f"{run}: its {group} settings are not those of {first[0]} beside it, in one reading's "
                            "folder; move it, or run it again in that world")


def counterfactual_lines(base: Horizon, results_dir: Path, longer: list[Horizon] = ()) -> list[str]:
    """The section: every claim whose experiment ran in another reading, a row per world it was
    tested in: today's world at the chapter's durations, each reading's runs at their horizon,
    and today's world at each longer horizon a reading ran at (from `longer`) before that
    reading's rows; the verdict, the p of the deciding part and how the group was made. None
    without such runs."""
    found = reading_horizons(results_dir)
    if not found:
        return []
    factors = sorted({h.factor for _, h in found if h.read})
    today = [("today's world (1x, the headline)", base),
             *((f"today's world ({h.factor:g}x, `{h.folder.relative_to(results_dir).as_posix()}`)", h)
               for h in longer if h.read and h.factor in factors and h.factor != base.factor)]
    worlds = sorted([*today, *((f"{reading_words(Path(where).name)} "
                                f"({f'{h.factor:g}x' if h.read else '?'}, `{where}`)", h) for where, h in found)],
                    key=lambda w: (w[1].factor if w[1].read else float("inf"), not w[0].startswith("today")))
    lines = ["## In other readings of the world: counterfactuals", "",
             "The chapter's experiments run in worlds that read what the chapter leaves unsaid otherwise "
             "(docs/readings.md): labelled counterfactuals, never the headline. For every claim whose experiment "
             "ran in another reading, a row per world: the verdict on that world's own runs, the p of the part that "
             "decides it, and how the learners' group was made there (the chapter's mechanism is persistence: robots "
             "that keep to a circuit, a vacancy filled by one robot that moves and stays). Today's world comes first "
             "at each horizon a reading ran at.", "",
             "| claim | experiment | world (horizon, runs) | verdict | p (the deciding part) | how the group is made |",
             "|---|---|---|---|---|---|"]
    notes = [n for where, h in found for n in calibration_words(results_dir, where, h)]
    skipped = []
    for r in base.claims.itertuples():
        exp = chapter.experiment_of(r.claim_id)
        if not any(exp in h.runs for _, h in found):
            skipped.append(str(r.claim_id))
            continue
        for words, h in worlds:
            row = next((c for c in h.claims.itertuples() if int(c.claim_id) == int(r.claim_id)), None)
            ran = row is not None and exp in h.runs
            cells = [verdict_words(row.verdict, h.verdicts), p_cell(row),
                     mechanism_cell(h, exp, int(r.claim_id), row)] if ran else ["not run", "", ""]
            lines.append(f"| {r.claim_id} | {exp} | {words} | {' | '.join(cells)} |")
    if skipped:
        lines += ["", f"Claims {', '.join(skipped)}: their experiment ran in no other reading." if len(skipped) > 1
                  else f"Claim {skipped[0]}: its experiment ran in no other reading."]
    return [*lines, *(["", *notes] if notes else []), *seed_for_seed_lines(today, found), ""]


def seed_for_seed_lines(today: list[tuple[str, Horizon]], found: list[tuple[str, Horizon]]) -> list[str]:
    """Each reading's runs set beside today's world's runs of the same experiment at the same time
    factor, robot by robot (`analysis.matched`): a row per reading and horizon, a cell per
    experiment with the learners' robots of the same kind in both worlds, of those matched, and
    the number chance gives. [] where no reading's run has one of today's to be set beside."""
    experiments = sorted({e for _, h in found for e in h.experiments}, key=chapter.order_key)
    rows = []
    for where, h in found:
        cells = [seed_for_seed_cell(_today_at(today, e, _factor(h, e)), h.experiments[e]) if e in h.read else ""
                 for e in experiments]
        if any(cells):
            rows.append(f"| {reading_words(Path(where).name)} ({h.factor:g}x, `{where}`) | {' | '.join(cells)} |")
    if not rows:
        return []
    return ["", "Seed for seed: trial j of a reading's run starts from the same random initial Q-tables and first "
            "circuits as trial j of today's world's run of the same experiment at the same horizon (robots are "
            "matched only where their first Q snapshots are the same in both). Each cell: the learners' robots whose "
            "kind at the end (`robots.csv`: a stayer on circuit 0 or 1, an alternator, mixed, idle) is the same in "
            "both worlds, of those matched, and in brackets the number chance gives: robot by robot, its kinds over "
            "the trials in each world drawn independently (`analysis/matched.py`). Far above that number, what the "
            "robots did was their initial tables' and the world hardly mattered; near it, the world decided.", "",
            "| world (horizon, runs) | " + " | ".join(experiments) + " |", "|---|" + "---|" * len(experiments),
            *rows]


def _factor(h: Horizon, experiment: str) -> float:
    """The time factor `experiment`'s run in `h` ran at (its own settings')."""
    return float(h.read[experiment][0].scale.time_factor)


def _today_at(today: list[tuple[str, Horizon]], experiment: str, factor: float) -> Path | None:
    """Today's world's run of `experiment` at time factor `factor`, if there is one."""
    return next((h.experiments[experiment] for _, h in today
                 if experiment in h.read and _factor(h, experiment) == factor), None)


def calibration_words(results_dir: Path, where: str, h: Horizon) -> list[str]:
    """Whether the world a reading's runs used meets the chapter's facts, by the reading's own
    calibration search beside them (`calibration/world/search.csv`, `tavc calibrate`): the grid
    point of its settings (from its first run's config), and the point the rule chose."""
    table = results_dir / where / WORLD_SEARCH_DIR / "search.csv"
    if not table.is_file() or not h.read:
        return []
    search, keys, _ = read_search(table)
    cfg = next(iter(h.read.values()))[0]
    used = {k: float(attrgetter(k)(cfg)) for k in keys}
    setting = ", ".join(f"{k} {v:g}" for k, v in used.items())
    rel = table.relative_to(results_dir).as_posix()
    return [f"- `{where}`: the world these runs used ({setting}) {_verdict(search, keys, used)}, by the reading's "
            f"calibration search (`{rel}`); its rule chooses {_pick(search, keys, long=False)}."]


def calibration_tables(results_dir: Path) -> list[tuple[str, Path]]:
    """(its name in words, its search.csv) for today's world's calibration search
    (`calibration/world/`, `tavc calibrate scale=paper`) and each reading's
    (`readings/<reading>/calibration/world/`, `make calibrate-readings`), in that order."""
    today = results_dir / WORLD_SEARCH_DIR / "search.csv"
    base = results_dir / READINGS_RUNS
    tables = sorted(base.glob(f"*/{WORLD_SEARCH_DIR}/search.csv"), key=lambda p: natural(p.parents[2].name)) \
        if base.is_dir() else []
    return [*([("today's world", today)] if today.is_file() else []),
            *((reading_words(t.parents[2].name), t) for t in tables)]


def read_search(table: Path) -> tuple[pd.DataFrame, list[str], dict]:
    """A world search's table, its grid's keys (the columns between the point's id and
    `lone_leg_s`) and its record (`search.json` beside it, empty where there is none); a table
    or record that cannot be read, or does not say what it must, refused in one line. Read once
    per version of the two files (the report checks them all before it writes, then reads them
    again): the table is shared between callers, read it, never change it."""
    record = table.with_suffix(".json")
    versions = tuple((p.stat().st_mtime_ns, p.stat().st_size) if p.is_file() else None for p in (table, record))
    return _read_search(str(table), str(table.resolve()), versions)


@lru_cache(maxsize=32)
def _read_search(given: str, resolved: str, versions: tuple) -> tuple[pd.DataFrame, list[str], dict]:
    table = Path(given)
    search = read_or_refuse(table, read_table)
    record = table.with_suffix(".json")
    facts = read_or_refuse(record, load_json) if record.is_file() else {}
    needed = {"lone_leg_s", "arrivals_per_5h", "crowding_ratio_6", "feasible", "robust", "chosen"}
    if not needed <= set(search.columns) or not isinstance(facts, dict):
        missing = sorted(needed - set(search.columns))
        raise TavcError(f"{table if missing else record}: cannot be read (" + (
            f"no column {missing[0]}" if missing else "not a JSON object") + "); rerun its `tavc calibrate`")
    keys = list(search.columns[1:search.columns.get_loc("lone_leg_s")])
    try:
        search[keys].astype(float)
    except (TypeError, ValueError):
        raise TavcError(f"{table}: cannot be read (a grid setting that is not a number); rerun its `tavc calibrate`"
                        ) from None
    return search, keys, facts


def _verdict(search: pd.DataFrame, keys: list[str], settings: dict | None) -> str:
    """Whether the grid point of `settings` meets the chapter's facts, in words: "?" where the
    settings are not known, "is not on its grid" where no point has them."""
    if settings is None or any(k not in settings for k in keys):
        return "?"
    mine = search
    for key in keys:
        mine = mine[np.isclose(mine[key].astype(float), float(settings[key]), rtol=1e-6, atol=0.0)]
    if mine.empty:
        return "is not on its grid"
    row = mine.iloc[0]
    if not bool(row["feasible"]):
        return "does not meet the chapter's facts"
    return "meets the chapter's facts robustly" if bool(row["robust"]) else "meets the chapter's facts, not robustly"


def _pick(search: pd.DataFrame, keys: list[str], long: bool = True) -> str:
    """The point the search's rule chose, in words (with its arrivals and crowding, `long`)."""
    chosen = search[search["chosen"].astype(bool)]
    if chosen.empty:
        return "none"
    row = chosen.iloc[0]
    words = ", ".join(f"{k.rsplit('.', 1)[-1] if long else k} {float(row[k]):g}" for k in keys)
    if long:
        words += (f"; {row['arrivals_per_5h']:.0f} arrivals per 5 h, t(4 on a circuit) / t(3) "
                  f"{row['crowding_ratio_6']:.2f}" + ("" if bool(row["robust"]) else " (not robust)"))
    return words


def calibration_lines(results_dir: Path) -> list[str]:
    """Each calibration search (`calibration_tables`), a row each: how many points of its grid
    meet the chapter's facts (the intended split the equilibrium of six and of five robots,
    constraints (1.3) and (1.4)), robustly and at all; whether the world the search was asked
    about does (`search.json`'s ``configured``: a reading's defaults); and the point its rule
    chooses, with its arrivals per 5 h and crowding ratio."""
    rows, levels = [], set()
    for words, table in calibration_tables(results_dir):
        search, keys, facts = read_search(table)
        measurement = facts.get("measurement")
        levels.add(measurement.get("confidence") if isinstance(measurement, dict) else None)
        configured = facts.get("configured")
        grid = "; ".join(f"{k.rsplit('.', 1)[-1]} " + ", ".join(f"{v:g}" for v in sorted(set(search[k].astype(float))))
                         for k in keys)
        rows.append(f"| {words} | {grid} | {int(search['robust'].astype(bool).sum())} / "
                    f"{int(search['feasible'].astype(bool).sum())} of {len(search)} | "
                    f"{_verdict(search, keys, configured if isinstance(configured, dict) else None)} | "
                    f"{_pick(search, keys)} |")
    if not rows:
        return []
    level = next(iter(levels)) if len(levels) == 1 and None not in levels else None
    robust = f"robustly to the {100 * float(level):g} % intervals" if level is not None else \
        "robustly to the intervals of its measurement"
    return ["## The readings calibrated against the chapter's facts", "",
            "Each reading's own search of what the chapter leaves unsaid (`make calibrate-readings`: `tavc "
            "calibrate` with the reading's groups, `scale=paper`, into `readings/<reading>/calibration/world/`; "
            "grids fixed before the runs), under the rule that chose today's world (`calibration/world/`): of the "
            "points that meet the chapter's facts (the intended split the equilibrium of six and of five robots, "
            f"constraints (1.3) and (1.4)) {robust}, the one with the most arrivals per 5 h. Whether the world as "
            "configured (a reading's defaults, the world its runs used unless said) meets them, and what the rule "
            "chooses.", "",
            "| reading | grid | points meeting the facts: robustly / at all | the world as configured | the rule "
            "chooses |", "|---|---|---|---|---|", *rows, ""]
