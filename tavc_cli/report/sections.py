"""An experiment's section of the report, at any horizon: one function writes it whether the
horizon is the chapter's durations (the headline: the experiment's title, what the chapter
says, how fast the learners settled, the run's own model) or a longer one (a subsection: the
stretch its shares were measured over, the learners' convergence, the model beside the
learners, both horizons' states in one figure, the vacancy chains' mechanism, its claims).
The figures are drawn in the report's figure pool (`submit_figures`), every horizon's at
once, and their lines read here when the text reaches them."""

from __future__ import annotations

from concurrent.futures import Future
from pathlib import Path

import pandas as pd

from tavc_cli import chapter
from tavc_cli.analysis.comparison import experiment_comparison
from tavc_cli.readers import load_json
from tavc_cli.reference import chapter_table
from tavc_cli.report.drawing import FigurePool
from tavc_cli.report.figures import experiment_figures
from tavc_cli.report.files import config_of, model_misfit
from tavc_cli.report.horizons import (
    Horizon,
    convergence_sentence,
    horizons_stem,
    label,
    model_lines,
    window_words,
)
from tavc_cli.report.mechanism import mechanism_lines, vacancy_mechanism_lines
from tavc_cli.report.runs import choice_lines, draw_figures, other_run_lines
from tavc_cli.report.spatiotemporal import spatiotemporal_lines
from tavc_cli.report.text import (
    chapter_says,
    claims_table,
    performance,
    q_gap_lines,
    robot_lines,
    run_lines,
    settle_lines,
    state_table,
    vacancy_lines,
)
from tavc_cli.report.text import model_lines as own_model_lines
from tavc_cli.settings import TavcConfig


def submit_figures(pool: FigurePool, horizons: list[Horizon], results_dir: Path,
                   model_json: Path | None) -> dict[Path, Future]:
    """Draw every horizon's figures in `pool`: run folder -> the future of its figures' lines
    (for section 1.4, of its whole text), the designated runs' and the other runs' alike."""
    base = horizons[0]
    out: dict[Path, Future] = {}
    for h in horizons:
        for name, d in h.experiments.items():
            cfg, state_time = h.read[name]
            both = (base.read[name][1], horizons_stem(name, h), h.factor) \
                if not h.headline and name in base.read else None
            out[d] = pool.submit(run_figures, name, d, cfg, state_time, h.folder, results_dir, model_json, both)
        for name, folders in h.others.items():
            for d in folders:
                out[d] = pool.submit(draw_figures, name, d, config_of(d / "config.yaml"), h.folder, results_dir,
                                     model_json)
    return out


def run_figures(name: str, d: Path, cfg: TavcConfig, state_time: pd.DataFrame, folder: Path, results_dir: Path,
                model_json: Path | None, both: tuple[pd.DataFrame, str, float] | None = None) -> list[str]:
    """The figures of the run an experiment's claims are tested on at the horizon in `folder`,
    drawn under its `figures/`, as lines linked from results_dir's REPORT.md (section 1.4: its
    whole text); at a longer horizon (`both`: the chapter's durations' state table, the
    figure's name, the horizon's factor), first its states beside the chapter's durations'
    where its states are the circuits'."""
    if (d / "table_1_1.csv").is_file():
        return [_relinked(line, results_dir, folder) for line in spatiotemporal_lines(name, d, cfg, folder)]
    lines = []
    if both is not None and cfg.analysis.state == "circuits":
        # deferred: loads matplotlib
        from tavc_cli.viz.figures import horizon_state_figure

        base_state, stem, factor = both
        table = chapter.state_table_id(name)
        horizon_state_figure(base_state, state_time, chapter_table(table) if table else None, factor,
                             f"{name}: % of the stable period in each state at both horizons",
                             results_dir / "figures" / stem)
        lines += [f"![{name} at both horizons](figures/{stem}.png)", ""]
    figures = experiment_figures(name, d, cfg, state_time, folder, model_json)
    return [*lines, *(_relinked(line, results_dir, folder) for line in figures)]


def _relinked(line: str, results_dir: Path, folder: Path) -> str:
    """A markdown line written for `folder`'s own report, its links made relative to `results_dir`."""
    if folder == results_dir:
        return line
    return line.replace("](figures/", f"]({folder.relative_to(results_dir).as_posix()}/figures/")


def experiment_sections(horizons: list[Horizon], figures: dict[Path, Future], results_dir: Path,
                        model_json: Path | None) -> list[str]:
    """Each experiment's section at the chapter's durations, the sections of its other runs,
    then its subsection at each longer horizon (and that horizon's other runs); experiments run
    at longer horizons only after them."""
    base, longer = horizons[0], horizons[1:]
    lines: list[str] = []
    names = list(base.experiments)
    names += [n for h in longer for n in h.experiments if n not in names]
    for name in names:
        if name not in base.experiments:
            cfg = next(h.read[name][0] for h in longer if name in h.experiments)
            lines += [f"## {name} (section {cfg.section or '?'})", "", chapter_says(cfg.description), "",
                      "Not run at the chapter's durations here.", ""]
        for h in horizons:
            if name in h.experiments:
                lines += section_lines(name, h, figures, results_dir, model_json)
                lines += _other_sections(name, h, figures, results_dir)
    return lines


def _other_sections(name: str, h: Horizon, figures: dict[Path, Future], results_dir: Path) -> list[str]:
    """The sections of an experiment's other runs at horizon `h`."""
    where = "" if h.headline else f" at {label(h.factor)}"
    lines: list[str] = []
    for other in h.others.get(name, []):
        lines += other_run_lines(name, other, config_of(other / "config.yaml"), h.experiments[name], results_dir,
                                 figures[other].result(), h.deliveries[other], where)
    return lines


def section_lines(name: str, h: Horizon, figures: dict[Path, Future], results_dir: Path,
                  model_json: Path | None) -> list[str]:
    """An experiment's section at horizon `h`: its title (a subsection at a longer horizon),
    which run its claims are tested on, what was delivered, its state table beside the
    chapter's, its performance, then what the horizon adds (see the module), its figures,
    the robots, the vacancy chains, its claims and the run's provenance."""
    d = h.experiments[name]
    cfg, state_time = h.read[name]
    prov = load_json(d / "provenance.json") if (d / "provenance.json").is_file() else {}
    if h.headline:
        lines = [f"## {name} (section {cfg.section or '?'})", "", chapter_says(cfg.description), ""]
    else:
        lines = [f"### {name} at {label(h.factor)}", ""]
    lines += choice_lines(name, [d, *h.others.get(name, [])], results_dir)
    lines += h.deliveries.get(d, [])
    if (d / "table_1_1.csv").is_file():  # section 1.4's study: its own text, not a state table
        if h.headline:
            return [*lines, *figures[d].result(), *run_lines(name, d, cfg, prov, h.claims, h.runs)]
        return [*lines, *convergence_sentence(d), *figures[d].result(), *_claims_lines(name, h)]
    table = chapter.state_table_id(name)
    window = "" if h.headline else f" ({window_words(cfg)})"
    lines += [f"% of the stable period{window} in each state, mean ± std over trials"
              + (f"; the chapter's Table {table} beside ours:" if table else ":"), "",
              *state_table(state_time, experiment_comparison(name, state_time)), ""]
    if name in h.runs:
        lines += [performance(h.runs[name]), ""]
        if h.headline:
            lines += settle_lines(h.runs[name], cfg)
            lines += q_gap_lines(h.runs[name])
    if h.headline:
        own = d / "model" / "model.json"
        if own.is_file():
            misfit = model_misfit(own, cfg)
            lines += [f"The model beside this run (`{own.parent.relative_to(results_dir).as_posix()}/`) was measured "
                      f"with other settings ({misfit}): not set beside it.", ""] if misfit else \
                [*own_model_lines(own, state_time), ""]
        lines += figures[d].result()
        lines += mechanism_lines(d)
    else:
        lines += convergence_sentence(d)
        lines += mechanism_lines(d)
        lines += model_lines(name, d, cfg, model_json)
        lines += figures[d].result()
    lines += robot_lines(d)
    lines += vacancy_lines(d)
    if h.headline:
        return [*lines, *run_lines(name, d, cfg, prov, h.claims, h.runs)]
    lines += vacancy_mechanism_lines(d)
    lines += _claims_lines(name, h)
    return [*lines, *run_lines(name, d, cfg, prov, h.claims.iloc[0:0], h.runs)]  # its claims are above


def _claims_lines(name: str, h: Horizon) -> list[str]:
    """The experiment's claims as tested at a longer horizon."""
    own = h.claims[[chapter.experiment_of(c) == name for c in h.claims["claim_id"]]]
    return [*claims_table(own, verdicts=name not in h.shortfalls), ""] if len(own) and name in h.runs else []
