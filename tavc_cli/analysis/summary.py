"""Short text renderings of result tables for the terminal."""

from __future__ import annotations

import pandas as pd


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
