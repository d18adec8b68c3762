"""Short text renderings of result tables for the terminal."""

from __future__ import annotations

from typing import Any

import pandas as pd


def run_summary_text(summary: dict[str, Any]) -> str:
    """What `tavc run` prints after a run (`pipeline.run_experiment`'s summary): where results
    went, how many trials ran, the state (or Table 1.1), performance and claims."""
    n_trials, n_reused = summary["n_trials"], summary["n_reused"]
    lines = [f"results: {summary['output_dir']}",
             f"trials: {n_trials} ({n_reused} reused) in {summary['wall_time_s']:.1f} s wall time"]
    tables = summary.get("tables") or {}
    if "table_1_1" in tables:  # one circuit: the group's state says nothing; Table 1.1 does
        lines += ["\ntraversal time after n traversals (over robots), target time after m arrivals (over trials)",
                  tables["table_1_1"].to_string(index=False, float_format=lambda x: f"{x:.1f}")]
    elif "state_time" in tables and len(tables["state_time"]):
        lines += ["\n% of the stable period in each state (mean +- std over trials)",
                  state_table_text(tables["state_time"])]
    if "performance" in tables and len(tables["performance"]):
        perf = tables["performance"].groupby("controller", sort=False)["mean"].mean()
        lines.append("\nscore value delivered per second, whole run: "
                     + ", ".join(f"{c} {v:.4f}" for c, v in perf.items()))
    claims = summary.get("claims")
    if claims is not None and len(claims):
        lines += ["\nthe chapter's claims about this experiment (t-tests at 90 %; claims.csv has every part)",
                  claims_text(claims)]
    return "\n".join(lines)


def state_table_text(state_time: pd.DataFrame) -> str:
    """One row per state, one column per controller: 'mean +- std' (theory: mean only)."""
    controllers = list(dict.fromkeys(state_time["controller"]))
    states = list(dict.fromkeys(state_time["state"]))
    cell = {(r.state, r.controller): r for r in state_time.itertuples()}
    widths = [max(5, max(len(s) for s in states))] + [max(13, len(c)) for c in controllers]
    lines = ["  ".join(h.rjust(w) for h, w in zip(["state", *controllers], widths, strict=True))]
    for s in states:
        parts = [s.rjust(widths[0])]
        for c, w in zip(controllers, widths[1:], strict=True):
            r = cell.get((s, c))
            if r is None:
                text = "-"
            elif c == "theory":
                text = f"{r.mean_pct:.1f}"
            else:
                text = f"{r.mean_pct:.1f} +- {r.std_pct:.1f}"
            parts.append(text.rjust(w))
        lines.append("  ".join(parts))
    return "\n".join(lines)


def claims_text(claims: pd.DataFrame) -> str:
    """One line per claim: id, verdict, the headline test's statistic and p-value, then its parts."""
    lines = []
    for r in claims.itertuples():
        head = f"claim {r.claim_id}: {r.verdict.replace('_', ' ')}"
        if pd.notna(r.p_value):
            head += f" (t = {r.statistic:.2f}, p = {r.p_value:.3g})"
        lines.append(head)
        lines += [f"    {part}" for part in str(r.detail).split("; ")]
    return "\n".join(lines)
