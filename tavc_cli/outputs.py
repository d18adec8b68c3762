"""An experiment's outputs written: its tables, the comparison with the chapter and its claims,
computed by `analysis.experiment` from the run's records and written into its folder (the one
module of a run's analysis that touches files).

A run's claims are tested on the tables it wrote, so a finished run's `claims.csv` can be tested
again without its trials: `retested_claims` gives what today's rules write there where that is
not what the folder holds, and `rewrite_claims` writes it (`tavc report` does both, so a change
of the rules never leaves a run's claims as an older tavc tested them)."""

from __future__ import annotations

import io
from pathlib import Path

import pandas as pd

from tavc_cli import ownership
from tavc_cli.analysis.comparison import experiment_comparison
from tavc_cli.analysis.experiment import analyse, experiment_claims
from tavc_cli.analysis.table_schemas import TABLE_NAMES
from tavc_cli.chapter import claims
from tavc_cli.experiments.plan import RunPlan, read_plan
from tavc_cli.experiments.records import TrialRecord
from tavc_cli.io import claim_folder, write_text_atomic
from tavc_cli.ownership import Owned
from tavc_cli.settings import TavcConfig


def write_analysis(cfg: TavcConfig, plan: RunPlan, out_dir: Path, records: list[TrialRecord],
                   owned: Owned | None = None) -> tuple[dict[str, pd.DataFrame], pd.DataFrame]:
    """Compute and write (atomically) every table, the comparison with the chapter and the
    claims, and remove the tables of an earlier run in the folder that this one does not
    write (another experiment's, or one without the event), where `owned` says tavc wrote
    them; return the tables and the claims."""
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

    comparison = experiment_comparison(str(cfg.experiment_name or ""), written_tables["state_time"])
    if comparison is not None:
        write_text_atomic(out_dir / "comparison.csv", comparison.to_csv(index=False, float_format="%.4f"))
    claims = experiment_claims(cfg, plan, written_tables, _other_experiments(cfg, out_dir))
    if len(claims):
        write_text_atomic(out_dir / "claims.csv", claims_text(claims))
    written = {*tables, *(["comparison"] if comparison is not None else []), *(["claims"] if len(claims) else [])}
    for name in sorted(set(TABLE_NAMES) - written):
        if owned is not None:
            owned.remove(f"{name}.csv")
    return tables, claims




def _other_experiments(cfg: TavcConfig, out_dir: Path) -> dict[str, pd.DataFrame]:
    """The `trial_stats.csv` of each other experiment of the chapter's claims beside this run's
    folder, where there is one (claim 7 compares breakdown_no_vacancy with breakdown)."""
    name = str(cfg.experiment_name or "")
    paths = {other: out_dir.parent / other / "trial_stats.csv" for other in {e for e, _ in claims()} - {name}}
    return {other: pd.read_csv(path) for other, path in paths.items() if path.is_file()}


def claims_text(claims: pd.DataFrame) -> str:
    """`claims.csv` as tavc writes it."""
    return claims.to_csv(index=False, float_format="%.6g")


def retested_claims(folder: Path, read_config) -> str | None:
    """The `claims.csv` today's rules give the finished run in `folder` (its `provenance.json`
    written), tested on the tables it wrote, where that differs from the folder's (an empty text:
    no claim to write); None where the folder holds it already, has no `trial_stats.csv`, or
    where its claims file is not tavc's to replace (not in the folder's list of tavc's files, or a
    link). `read_config(path)` reads its `config.yaml`."""
    owned = ownership.read(folder)
    if owned is None or owned.kind not in (ownership.RUN, ownership.SURROGATE):
        return None
    if not (folder / "provenance.json").is_file() or not (folder / "trial_stats.csv").is_file():
        return None
    path = folder / "claims.csv"
    if (path.is_symlink() or path.exists()) and (not owned.owns("claims.csv") or path.is_symlink()
                                                 or not path.is_file()):
        return None  # not tavc's: somebody else's file, or a link, which tavc never writes through
    # deferred: loads scipy
    from tavc_cli.analysis.claims import CLAIM_TABLES

    cfg = read_config(folder / "config.yaml")
    tables = {"trial_stats": pd.read_csv(folder / "trial_stats.csv")}
    tables.update({t: pd.read_csv(folder / f"{t}.csv") for t in CLAIM_TABLES if (folder / f"{t}.csv").is_file()})
    claims = experiment_claims(cfg, read_plan(folder, cfg), tables, _other_experiments(cfg, folder))
    text = claims_text(claims) if len(claims) else ""
    return None if text == (path.read_text() if path.is_file() else "") else text


def rewrite_claims(folder: Path, read_config) -> bool:
    """Hold the run's folder and, if its claims are still not what today's rules give
    (`retested_claims`, tested again here, where nothing else writes), write them and record
    their digest in its `provenance.json`, with the tavc that tested them again; True if written."""
    # deferred: the runner loads the simulator's kernels, which importing the package must not
    from tavc_cli.experiments.runner import restamp_provenance

    with claim_folder(folder):
        text = retested_claims(folder, read_config)
        if text is None:
            return False
        owned = ownership.read(folder)
        if text:
            owned.wrote("claims.csv")
            write_text_atomic(folder / "claims.csv", text)
        else:
            owned.remove("claims.csv")
        restamp_provenance(folder, "claims.csv")
        return True
