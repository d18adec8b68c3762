"""An experiment's outputs written: its tables, the comparison with the chapter and its claims,
computed by `analysis.experiment` from the run's records and written into its folder (the one
module of a run's analysis that touches files)."""

from __future__ import annotations

import io
from collections.abc import Mapping
from pathlib import Path

import pandas as pd

from tavc_cli.analysis.alike import unlike
from tavc_cli.analysis.comparison import experiment_comparison
from tavc_cli.analysis.experiment import analyse, experiment_claims
from tavc_cli.analysis.table_schemas import TABLE_NAMES
from tavc_cli.chapter import claims
from tavc_cli.experiments.plan import RunPlan
from tavc_cli.experiments.records import TrialRecord
from tavc_cli.io import write_text_atomic
from tavc_cli.ownership import Owned
from tavc_cli.run_checks import check_table, run_facts
from tavc_cli.settings import TavcConfig


def write_analysis(cfg: TavcConfig, plan: RunPlan, out_dir: Path, records: list[TrialRecord], made_by: Mapping,
                   owned: Owned | None = None) -> tuple[dict[str, pd.DataFrame], pd.DataFrame]:
    """Compute and write (atomically) every table, the comparison with the chapter and the
    claims, and remove the tables of an earlier run in the folder that this one does not
    write (another experiment's, or one without the event), where `owned` says tavc wrote
    them; return the tables and the claims. `made_by`: what computed the trials, as the run's
    `provenance.json` records it (`runner.made_by`)."""
    tables = analyse(cfg, plan, records)
    if owned is not None:  # listed before they are written: a run stopped midway still owns them
        owned.wrote(*(f"{name}.csv" for name in [*tables, "comparison", "claims"]))
    written_tables = {}
    for name, df in tables.items():
        # Q-values span the reward's scale (about 0.05 per task with t in ms, 50 with t in s): significant digits
        fmt = "%.6g" if name == "q_values" else "%.4f"
        text = df.to_csv(index=False, float_format=fmt)
        write_text_atomic(out_dir / f"{name}.csv", text)
        # the comparison and the claims are made from the tables as written, which is what
        # `tavc report` reads back: both then give the same numbers
        written_tables[name] = pd.read_csv(io.StringIO(text), dtype={"state": str} if name == "state_time" else None)

    comparison = comparison_text(str(cfg.experiment_name or ""), written_tables["state_time"])
    if comparison is not None:
        write_text_atomic(out_dir / "comparison.csv", comparison)
    claims = experiment_claims(cfg, plan, written_tables, _other_experiments(cfg, out_dir, made_by))
    if len(claims):
        write_text_atomic(out_dir / "claims.csv", claims_text(claims))
    written = {*tables, *(["comparison"] if comparison is not None else []), *(["claims"] if len(claims) else [])}
    for name in sorted(set(TABLE_NAMES) - written):
        if owned is not None:
            owned.remove(f"{name}.csv")
    return tables, claims


def _other_experiments(cfg: TavcConfig, out_dir: Path, made_by: Mapping) -> dict[str, pd.DataFrame | str]:
    """The `trial_stats.csv` of each other experiment of the chapter's claims beside this run's
    folder (claim 7 compares breakdown_no_vacancy with breakdown), of a run that finished there,
    checked as the report checks it (`run_checks.check_table`: a table edited or cut is one line
    naming it). In its place, why it is no comparison for this run's trials: a run there not
    finished (its table may be an earlier run's), or one made otherwise than this one (`unlike`;
    `made_by`: what computed this run's trials, as its `provenance.json` will record it)."""
    others: dict[str, pd.DataFrame | str] = {}
    for other, path in other_experiments(cfg, out_dir).items():
        if not (path.parent / "config.yaml").is_file():  # no run made there
            continue
        if not (path.parent / "provenance.json").is_file() or not path.is_file():
            others[other] = "not finished"
            continue
        facts = run_facts(path.parent)
        check_table(path, facts)
        others[other] = unlike(cfg, made_by, facts.cfg, facts.made_by) or pd.read_csv(path)
    return others


def other_experiments(cfg: TavcConfig, out_dir: Path) -> dict[str, Path]:
    """Where the `trial_stats.csv` of each experiment this run's claims compare it with
    (`Claim.against`: claims 7 and 8) would be beside its folder (`out_dir`), by experiment name."""
    name = str(cfg.experiment_name or "")
    compared = {c.against for own, c in claims() if own == name and c.against and c.against != name}
    return {other: out_dir.parent / other / "trial_stats.csv" for other in sorted(compared)}


def comparison_text(experiment: str, state_time: pd.DataFrame) -> str | None:
    """`comparison.csv` as tavc writes it from the run's `state_time.csv` (read with its states as
    text); None for an experiment the chapter reports in no state table."""
    comparison = experiment_comparison(experiment, state_time)
    return None if comparison is None else comparison.to_csv(index=False, float_format="%.4f")


def claims_text(claims: pd.DataFrame) -> str:
    """`claims.csv` as tavc writes it."""
    return claims.to_csv(index=False, float_format="%.6g")
