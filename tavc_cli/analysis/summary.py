"""Short text renderings of result tables for the terminal."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import pandas as pd


def run_summary_text(summary: dict[str, Any]) -> str:
    """What `tavc run` prints after a run (`pipeline.run_experiment`'s summary): where results
    went, how many trials ran, the state (or Table 1.1), performance and claims."""
    n_trials, n_reused = summary["n_trials"], summary["n_reused"]
    together = " (for every experiment of the invocation together)" if summary.get("together") else ""
    lines = [f"results: {summary['output_dir']}",
             *([f"engine: {summary['engine']}"] if summary.get("engine") else []),
             f"trials: {n_trials} ({n_reused} reused) in {summary['wall_time_s']:.1f} s wall time{together}",
             f"figures: tavc report {Path(summary['output_dir']).parent} draws them, with REPORT.md, into its "
             "figures/ folder, from every run under it"]
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
    short = summary.get("not_a_verdict") or ""
    if claims is not None and len(claims):
        head = "\nthe chapter's claims about this experiment (t-tests at 90 %; claims.csv has every part)"
        if short:  # a run below the chapter's scale: what the tests give on it, not a verdict
            head = (f"\n{short}: the tests below say what these trials give, not whether the chapter's "
                    "claims reproduce (that takes its trial counts and durations: scale=paper)" + head)
        lines += [head, claims_text(claims, verdicts=not short)]
    elif short:
        lines.append(f"\n{short}")
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


def claims_text(claims: pd.DataFrame, verdicts: bool = True) -> str:
    """One line per claim: id, verdict ("would be: ..." unless `verdicts`: a run below the
    chapter's scale), the statistic and p-value of the part that decides it (where the frame
    carries them: `analysis.claims.claim_rows`' ``attrs["deciding"]``; else the headline part's)
    and which part that is, or why the claim could not be tested; then every part."""
    # deferred: loads scipy
    from tavc_cli.analysis.claims import verdict_words

    deciding = claims.attrs.get("deciding", {})
    lines = []
    for r in claims.itertuples():
        head = f"claim {r.claim_id}: {verdict_words(r.verdict, verdicts)}"
        d = deciding.get(int(r.claim_id))
        if d is not None and r.verdict == "inconclusive":
            head += f" ({d['not_testable_because']})"
        elif d is not None and pd.notna(d["deciding_p_value"]):
            rule = f", which holds if {d['deciding_holds_if']}" if str(d["deciding_holds_if"]).startswith("p >=") \
                else ""
            head += (f" (t = {d['deciding_statistic']:.2f}, p = {d['deciding_p_value']:.3g}, decided by: "
                     f"{d['deciding_test']}{rule})")
        elif d is not None:
            head += f" (decided by: {d['deciding_test']}, a comparison of means)"
        elif pd.notna(r.p_value):
            head += f" (t = {r.statistic:.2f}, p = {r.p_value:.3g})"
        lines.append(head)
        lines += [f"    {part}" for part in str(r.detail).split("; ")]
        seen = getattr(r, "observations", "")
        if isinstance(seen, str) and seen:
            lines += [f"    beside the verdict: {part}" for part in seen.split("; ")]
    return "\n".join(lines)
