"""The figure of a sweep: time share of each state against the swept value, per controller."""

from __future__ import annotations

from pathlib import Path

import pandas as pd

from tavc_cli.viz.figures import clipped_err, n_text, plt, write_figure


def _trials(table: pd.DataFrame) -> str:
    """The trials behind each point, as "n trials" (its range over jobs): the table's
    `n_trials` if it has one, else each job's state_time.csv (`output_dir`)."""
    if "n_trials" in table:
        return n_text(table["n_trials"])
    counts = []
    for folder in dict.fromkeys(table.get("output_dir", pd.Series(dtype=str))):
        path = Path(str(folder)) / "state_time.csv"
        if path.is_file():
            st = pd.read_csv(path)
            counts += st.loc[st["controller"] != "theory", "n_trials"].tolist()
    return n_text(counts)


def sweep_figure(table: pd.DataFrame, key: str, out: Path) -> list[Path]:
    """% of the stable period in each state against `key`'s values, one panel per controller;
    error bars one std over each job's trials, cut at 0 and 100 %."""
    n = _trials(table)
    controllers = list(dict.fromkeys(table["controller"]))
    fig, axes = plt.subplots(1, len(controllers), figsize=(5.0 * len(controllers), 3.6), squeeze=False)
    numeric = pd.to_numeric(table[key], errors="coerce")
    x = numeric if numeric.notna().all() else table[key].astype(str)
    for ax, ctrl in zip(axes[0], controllers, strict=True):
        rows = table[table["controller"] == ctrl].assign(x=x)
        for state, group in rows.groupby("state", sort=False):
            group = group.sort_values("x")
            err = None if ctrl == "theory" else clipped_err(group["mean_pct"], group["std_pct"], 0.0, 100.0)
            ax.errorbar(group["x"], group["mean_pct"], yerr=err, marker="o", capsize=3, label=state)
        ax.set_title(ctrl)
        ax.set_xlabel(key)
        ax.set_ylabel("% of the stable period" + ("" if ctrl == "theory" else
                                                  f"\n(mean ± std over {n}, cut at 0 and 100)"))
        ax.set_ylim(bottom=0.0)
        ax.legend(fontsize=7, ncol=2, title="state")
    fig.tight_layout()
    paths = [out.with_suffix(".png"), out.with_suffix(".svg")]
    try:
        for path in paths:
            write_figure(fig, path, dpi=120)
    finally:
        plt.close(fig)
    return paths
