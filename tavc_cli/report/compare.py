"""The report's section on other learners (`tavc compare`, `make compare`), from each comparison's
`compare.csv` under ``RESULTS/compare/<scale>/``: per number, a table of controllers by scenario
with TAVC's difference marked where the rank test finds one, and the sentences read from it."""

from __future__ import annotations

import io
import math
from pathlib import Path

import numpy as np
import pandas as pd

from tavc_cli.analysis.claims import ALPHA
from tavc_cli.compare.metrics import METRICS, TABLE_COLUMNS, comparison_table, order
from tavc_cli.errors import TavcError
from tavc_cli.readers import TABLE_LIMIT, TableSpec, read_table, read_text
from tavc_cli.report.files import there
from tavc_cli.report.text import fmt
from tavc_cli.table_cells import damaged, unreadable

COMPARE_DIR = "compare"
SCALES = ("paper", "converged")  # read first, in this order; any other comparison after them
HIGHER_IS_BETTER = {"score_per_s": True, "predicted_state_pct": True, "fill_delay_s": False, "filled_pct": True,
                    "fast_high_share": True}
REWRITE = "run `tavc compare` again to rewrite it"
_TEXT = ("experiment", "metric", "controller")  # compare.csv's other columns hold numbers
_COMPARE = TableSpec(columns=tuple(TABLE_COLUMNS), numbers=tuple(c for c in TABLE_COLUMNS if c not in _TEXT),
                     text=_TEXT, filled=(*_TEXT, "time_factor", "n_trials"), counts=("n_trials",), unique=_TEXT)


def compare_tables(results_dir: Path) -> dict[Path, pd.DataFrame]:
    """Each comparison's `compare.csv` under results_dir/compare/<name>/, by folder in the order the
    section takes them, read bounded and checked (`readers.read_table`: one line naming a damaged one)."""
    root = Path(results_dir) / COMPARE_DIR
    if not root.is_dir():
        return {}
    found = sorted((d for d in root.iterdir() if there(d / "compare.csv")),
                   key=lambda d: (SCALES.index(d.name) if d.name in SCALES else len(SCALES), d.name))
    return {d: read_table(d / "compare.csv", _COMPARE, REWRITE) for d in found}


def check_compare_tables(results_dir: Path) -> None:
    """Each comparison's `compare.csv` checked (`compare_tables`) and held to its trials
    (`as_its_trials_give`), as the report reads them."""
    for folder, table in compare_tables(results_dir).items():
        as_its_trials_give(folder, table)


def as_its_trials_give(folder: Path, table: pd.DataFrame) -> pd.DataFrame:
    """`table`, `folder`'s compare.csv, once it is what `compare_trials.csv` beside it gives
    (`compare.metrics.comparison_table`, each controller at the multiple of the chapter's
    durations the table gives it, which the trials do not record), within what rounding both to
    six significant digits moves (a relative 2e-5; tavc's own differ by under 5e-6): one line where
    either was edited alone, or the trials are missing."""
    path = folder / "compare_trials.csv"
    if not there(path):
        raise TavcError(f"{path}: missing, though compare.csv beside it is drawn from it; {REWRITE}")
    try:
        trials = pd.read_csv(io.StringIO(read_text(path, TABLE_LIMIT)))
        factors = table.groupby("controller", sort=False)["time_factor"].first().to_dict()
        fresh = order(comparison_table(trials, factors), list(dict.fromkeys(table["experiment"])),
                      list(dict.fromkeys(table["controller"])))[list(TABLE_COLUMNS)].reset_index(drop=True)
    except (OSError, ValueError, KeyError, TypeError) as exc:
        raise damaged(path, f"cannot be read ({unreadable(exc)})") from None
    numbers = [c for c in TABLE_COLUMNS if c not in _TEXT]
    same = len(fresh) == len(table) and (fresh[list(_TEXT)].to_numpy() == table[list(_TEXT)].to_numpy()).all() \
        and np.allclose(fresh[numbers].to_numpy(float), table[numbers].to_numpy(float), rtol=2e-5, atol=1e-9,
                        equal_nan=True)
    if not same:
        raise TavcError(f"{folder / 'compare.csv'}: not what compare_trials.csv beside it gives (one of them "
                        f"edited?); {REWRITE}")
    return table


def compare_lines(results_dir: Path) -> list[str]:
    """The section, if a comparison was written into results_dir/compare/<name>."""
    found = compare_tables(results_dir)
    if not found:
        return []
    lines = ["## Other learners on the chapter's scenarios", "",
             "Each controller ran the five scenarios with no other controller beside it (`tavc compare`): TAVC "
             "(e-greedy; softmax with fast and slow robots), random allocation, the model's allocation "
             "pre-programmed (`model`: the allocation `tavc model` predicts for the starting team, robots drawn "
             "onto it at random, kept after events), the same handed the model's allocation for the new team "
             "after every event (`informed`), WoLF-PHC and a fixed response-threshold allocator "
             "(docs/plugins.md). Cells: mean ± std over trials; ▲ / ▼: better / worse than TAVC by the "
             f"two-sided Mann-Whitney U test at p < {ALPHA:g} (the side its trials are more likely on); ◇: not "
             "different from random allocation at that level. A vacancy's fill time is cut at the shortest "
             "period after the event any controller ran (the chapter's). "
             "Controllers that learn nothing run on the baselines' schedule (at 40x the chapter's "
             "durations: their distribution does not depend on the horizon); each heading gives the "
             "multiple each controller ran at.", ""]
    for folder, table in found.items():
        lines += _scale_lines(folder, table, Path(results_dir))
    return lines


def _scale_lines(folder: Path, table: pd.DataFrame, results_dir: Path) -> list[str]:
    factors = table.groupby("controller", sort=False)["time_factor"].first()
    n = table.groupby("controller", sort=False)["n_trials"].max()
    ran = ", ".join(f"{c} at {f:g}x ({int(n[c])} trials)" for c, f in factors.items())
    lines = [f"### {folder.name}: {ran}", "", *_glance(table), ""]
    for metric, rows in table.groupby("metric", sort=False):
        experiments = list(dict.fromkeys(rows["experiment"]))
        lines += [f"**{METRICS.get(metric, metric)}**", "",
                  "| controller | " + " | ".join(e.replace("_", " ") for e in experiments) + " |",
                  "|---" * (1 + len(experiments)) + "|"]
        for controller, mine in rows.groupby("controller", sort=False):
            by = mine.set_index("experiment")
            cells = [_cell(by.loc[e], metric) if e in by.index else "" for e in experiments]
            lines.append(f"| {controller} | " + " | ".join(cells) + " |")
        lines += ["", *_reading(rows, metric), ""]
    figure = folder / "compare.png"
    if figure.is_file():
        lines += [f"![Learners compared at scale {folder.name}]({figure.relative_to(results_dir).as_posix()})", "",
                  f"*Learners compared at scale {folder.name}: mean ± std over trials (n in the legend); "
                  "bars cut at 0.*", ""]
    return lines


def _cell(row: pd.Series, metric: str) -> str:
    spec = ".3g" if metric in ("score_per_s", "fast_high_share") else ".0f"
    text = fmt(float(row["mean"]), spec)
    if not math.isnan(float(row["std"])):
        text += f" ± {fmt(float(row['std']), spec)}"
    p_tavc, p_random = float(row["p_vs_tavc"]), float(row["p_vs_random"])
    if not math.isnan(p_tavc) and p_tavc < ALPHA:
        # the side the rank test found: a trial of this controller more likely above one of TAVC's
        above = float(row["above_tavc"]) > 0.5
        text += " ▲" if above == HIGHER_IS_BETTER.get(metric, True) else " ▼"
    if not math.isnan(p_random) and p_random >= ALPHA:
        text += " ◇"
    return text


def _glance(table: pd.DataFrame) -> list[str]:
    """Per controller, of every number in every scenario: how often it is better than TAVC, worse,
    or not told apart (the marks of the tables below)."""
    out = []
    for controller, mine in table[table["controller"] != "tavc"].groupby("controller", sort=False):
        tested = mine[mine["p_vs_tavc"].notna()]
        differs = tested[tested["p_vs_tavc"] < ALPHA]
        better = sum((float(r["above_tavc"]) > 0.5) == HIGHER_IS_BETTER.get(r["metric"], True)
                     for r in differs.to_dict("records"))
        out.append(f"{controller}: better than TAVC in {better}, worse in {len(differs) - better}, not told apart in "
                   f"{len(tested) - len(differs)} of {len(tested)} numbers.")
    return [" ".join(out)] if out else []


def _reading(rows: pd.DataFrame, metric: str) -> list[str]:
    """Which controller has the best mean in each scenario, and how TAVC stands against random."""
    out = []
    better = HIGHER_IS_BETTER.get(metric, True)
    for experiment, mine in rows.groupby("experiment", sort=False):
        mine = mine.dropna(subset=["mean"])
        if mine.empty:
            continue
        best = mine.loc[(mine["mean"] if better else -mine["mean"]).idxmax()]
        tavc = mine[mine["controller"] == "tavc"]
        against = ""
        if len(tavc) and not math.isnan(float(tavc["p_vs_random"].iloc[0])):
            p = float(tavc["p_vs_random"].iloc[0])
            against = (f"; TAVC {'differs from' if p < ALPHA else 'is not told apart from'} random (p = {p:.2g})")
        out.append(f"{experiment.replace('_', ' ')}: {'highest' if better else 'lowest'} mean {best['controller']} "
                   f"({fmt(float(best['mean']), '.3g')})"
                   f"{against}.")
    return [" ".join(out)]
