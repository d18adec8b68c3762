"""Figures say what they are: those drawn from runs below the chapter's scale carry "not a
verdict" in a corner, the others nothing; legends sit beside the data, not on it."""

from pathlib import Path

import pandas as pd

from tavc_cli.viz import figures

RESULTS = Path(__file__).resolve().parents[1] / "results"


def _drawn(monkeypatch) -> list:
    """The figures `save_figure` writes from now on, with their texts, instead of files."""
    drawn = []

    def keep(fig, path, **options):
        drawn.append((path.name, [t.get_text() for t in fig.texts], fig))
        return path

    monkeypatch.setattr(figures, "write_figure", keep)
    return drawn


def test_a_figure_drawn_within_marked_carries_the_mark_and_only_then(monkeypatch, tmp_path):
    drawn = _drawn(monkeypatch)
    state = pd.read_csv(RESULTS / "initial_distribution" / "state_time.csv", dtype={"state": str})
    with figures.marked("not a verdict: scale=quick (8 of the chapter's 20 trials)"):
        figures.state_figure(state, None, "marked", tmp_path / "a")
    figures.state_figure(state, None, "unmarked", tmp_path / "b")
    texts = {name: found for name, found, _ in drawn}
    assert texts["a.png"] == texts["a.svg"] == ["not a verdict: scale=quick (8 of the chapter's 20 trials)"]
    assert texts["b.png"] == texts["b.svg"] == []


def test_a_state_figures_legend_is_beside_the_bars(monkeypatch, tmp_path):
    drawn = _drawn(monkeypatch)
    state = pd.read_csv(RESULTS / "initial_distribution" / "state_time.csv", dtype={"state": str})
    figures.state_figure(state, None, "legend", tmp_path / "c")
    fig = drawn[0][2]
    ax = fig.axes[0]
    fig.canvas.draw()
    legend, plot = ax.get_legend().get_window_extent(), ax.get_window_extent()
    assert legend.x0 >= plot.x1  # entirely to the right of the axes: no bar is under it


def test_the_reports_figures_of_a_smoke_run_are_marked_and_the_chapter_scales_are_not(monkeypatch, tmp_path):
    from tavc_cli.config import load_config, settings
    from tavc_cli.pipeline import run_experiment
    from tavc_cli.report.figures import experiment_figures
    from tavc_cli.settings import from_yaml

    drawn = _drawn(monkeypatch)
    run = tmp_path / "runs" / "initial_distribution"
    run_experiment(settings(load_config(["experiment=initial_distribution", "scale=smoke", "trials=1",
                                         "baseline_trials=1", f"output_dir={run}"])))
    cfg = from_yaml(run / "config.yaml")
    experiment_figures("initial_distribution", run, cfg, pd.read_csv(run / "state_time.csv", dtype={"state": str}),
                       tmp_path / "runs", None)
    # the mark is the figure's last text (a many-panel figure's title comes first)
    assert drawn and all(found and found[-1].startswith("not a verdict: scale=smoke (") for _, found, _ in drawn)
    drawn.clear()
    paper = RESULTS / "initial_distribution"
    experiment_figures("initial_distribution", paper, from_yaml(paper / "config.yaml"),
                       pd.read_csv(paper / "state_time.csv", dtype={"state": str}), tmp_path / "out", None,
                       fig_dir=tmp_path / "out" / "figures")
    assert drawn and not any(t.startswith("not a verdict") for _, found, _ in drawn for t in found)
