"""`tavc report`: REPORT.md from saved results only; it never simulates.

It reads, for every run folder under the results directory at any depth (a sweep's jobs sit
two levels down: `<root>/breakdown/0_seed=1/`), what `tavc run` wrote (`config.yaml`,
`provenance.json`, `state_time.csv`, `trial_stats.csv`, and the model's `model/model.json`
if `tavc model` was run into it), checks all of it before writing anything
(`analysis.schema`: a damaged file is one line naming it, and nothing written), tests the
chapter's claims on the per-trial numbers of one run per experiment together (claim 7
compares two experiments), and writes `claims.csv` (every claim, and the part that decides
each verdict) and `REPORT.md` beside the run folders. Every other run of an experiment gets a
section of its own (`runs`), titled with its folder relative to the results directory; the
runs of the studies the report reads as a whole (the value-ratio sweep, the horizon ladder)
are named in its list of runs, with where they are used. A report whose claims are tested on
runs below the chapter's scale is headed "not a verdict". The sections are written by `text`
(an experiment's prose), `figures` (its figures) and `studies` (section 1.4 and the
value-ratio sweep).
"""

from __future__ import annotations

import json
import time
from collections.abc import Callable
from functools import lru_cache
from pathlib import Path

import pandas as pd

from tavc_cli import chapter
from tavc_cli.analysis.claims import CLAIM_TABLES, claim_table, verdict_words
from tavc_cli.analysis.comparison import experiment_comparison
from tavc_cli.analysis.schema import check_run
from tavc_cli.errors import TavcError
from tavc_cli.io import write_text_atomic
from tavc_cli.ownership import list_figures, take_report_folders
from tavc_cli.ownership import read as read_owned
from tavc_cli.readers import load_json
from tavc_cli.report import horizons
from tavc_cli.report.compare import compare_lines
from tavc_cli.report.drawing import FigurePool
from tavc_cli.report.figures import experiment_figures, find_model
from tavc_cli.report.html import HTML_FILE, write_report_html
from tavc_cli.report.mechanism import mechanism_lines
from tavc_cli.report.method import chapter_check_lines, gaps_lines, method_lines
from tavc_cli.report.runs import (
    choice_lines,
    designated_first,
    draw_figures,
    other_run_lines,
    rel,
    run_folders,
    run_list_lines,
    study_runs,
)
from tavc_cli.report.studies import spatiotemporal_lines, value_ratio_lines
from tavc_cli.report.surrogate import surrogate_lines
from tavc_cli.report.text import (
    chapter_says,
    delivery_lines,
    model_lines,
    p_cell,
    performance,
    q_gap_lines,
    robot_lines,
    run_lines,
    settle_lines,
    state_table,
    vacancy_lines,
)
from tavc_cli.report.time_scale import time_scale_lines
from tavc_cli.settings import TavcConfig, from_yaml


def _finished_runs(results_dir: Path) -> tuple[dict[str, list[Path]], list[Path]]:
    """experiment name -> the folders of its finished runs (their `provenance.json`, written
    last, is there) at any depth under results_dir (`runs.run_folders`: not the long horizon's
    nor a study's), the one its claims are tested on first (`runs.designated_first`); and the
    folders of runs that did not finish."""
    found: dict[str, list[Path]] = {}
    unfinished = []
    for d in run_folders(results_dir):
        if (d / "state_time.csv").is_file() and (d / "config.yaml").is_file() and (d / "provenance.json").is_file():
            found.setdefault(str(_read(d / "config.yaml", _config).experiment_name or d.name), []).append(d)
        else:
            unfinished.append(d)
    ordered = sorted(found.items(), key=lambda kv: chapter.order_key(kv[0]))  # the chapter's order
    return {name: designated_first(name, folders, results_dir) for name, folders in ordered}, unfinished


def _experiments(results_dir: Path) -> tuple[dict[str, Path], list[Path]]:
    """experiment name -> the folder of the run its claims are tested on; and the folders of
    runs that did not finish (`_finished_runs`)."""
    runs, unfinished = _finished_runs(results_dir)
    return {name: folders[0] for name, folders in runs.items()}, unfinished


def _check_readable(results_dir: Path, *horizon_runs: dict[str, list[Path]]) -> None:
    """Check every file the report reads, and where it writes, before writing anything: a
    damaged file is one line naming it, not a half-built report. Every run of every horizon
    and of the value-ratio sweep (`schema.check_run`: its config.yaml, provenance.json and
    tables), the models' outputs, the ladder's table."""
    for name in ("REPORT.md", "claims.csv", f"{horizons.CONVERGED_DIR}/claims.csv"):
        if (results_dir / name).is_dir():
            raise TavcError(f"RESULTS_DIR: {results_dir / name} is a directory; the report writes a file there")
    folders = [d for runs in horizon_runs for ds in runs.values() for d in ds]
    if (results_dir / "value_ratio").is_dir():  # its runs as `analysis.value_ratio` finds them
        folders += sorted(p.parent for p in (results_dir / "value_ratio").rglob("trial_stats.csv")
                          if (p.parent / "config.yaml").is_file())
    ladder_dir = results_dir / horizons.CONVERGED_DIR / "ladder"
    if (ladder_dir / "ladder.csv").is_file():  # the rungs whose claims the ladder's table tests again
        folders += sorted(p.parent for p in ladder_dir.glob("*/trial_stats.csv")
                          if (p.parent / "config.yaml").is_file())
    for d in folders:
        check_run(d, _config)
        if (d / "model" / "model.json").is_file():
            _read(d / "model" / "model.json", lambda p: json.loads(p.read_text()))
    ladder = results_dir / horizons.CONVERGED_DIR / "ladder" / "ladder.csv"
    if ladder.is_file():
        _read(ladder, pd.read_csv)


def _config(path: Path) -> TavcConfig:
    """An experiment's settings, read once per version of its file (the report reads each
    several times)."""
    stat = path.stat()
    return _config_of(str(path.resolve()), stat.st_mtime_ns, stat.st_size)


@lru_cache(maxsize=64)
def _config_of(path: str, mtime_ns: int, size: int) -> TavcConfig:
    return from_yaml(Path(path))


def _read(path: Path, read):
    """`read(path)`, with any failure to parse the file as one line naming it."""
    try:
        return read(path)
    except TavcError:
        raise  # a refusal naming the file already
    except Exception as exc:  # any library's parse error: the file is damaged, whatever the library
        detail = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
        raise TavcError(f"{path}: cannot be read ({detail}); rerun its experiment to rewrite it") from None


def build_report(results_dir: Path, progress: Callable[[str], None] | None = None, page: bool = False) -> dict:
    """Write `claims.csv` and `REPORT.md` under results_dir (with `page`, or where a page tavc
    wrote is there already, `REPORT.html` too: `report.html`); return what was found. `progress`
    hears what the report is doing, a line at each stage (reading, drawing, written)."""
    say = progress or (lambda _: None)
    start = time.perf_counter()
    results_dir = Path(results_dir)
    owned = read_owned(results_dir) if results_dir.is_dir() else None
    page = page or (owned is not None and owned.owns(HTML_FILE))  # a page tavc wrote there stays in step
    if not results_dir.is_dir():
        raise TavcError(f"RESULTS_DIR: {results_dir} is not a directory")
    say(f"report: reading the runs under {results_dir}")
    found, unfinished = _finished_runs(results_dir)
    long_dir = results_dir / horizons.CONVERGED_DIR
    found_long, unfinished_long = _finished_runs(long_dir) if long_dir.is_dir() else ({}, [])
    _check_readable(results_dir, found, found_long)
    experiments = {name: folders[0] for name, folders in found.items()}
    if not experiments and (results_dir / "state_time.csv").is_file():
        raise TavcError(f"RESULTS_DIR: {results_dir} is one run's folder; give the folder that holds the runs "
                        f"({results_dir.parent})")
    if not experiments:
        raise TavcError(f"RESULTS_DIR: no finished runs under {results_dir} (run `tavc run experiment=...` first)")
    base = _horizon(results_dir, found, unfinished)
    runs, claims = base.runs, base.claims
    tested, n_ok = base.tested, base.n_reproduced
    long = _horizon(long_dir, found_long, unfinished_long) if found_long else None
    # everything read: now the first write
    taken = take_report_folders(results_dir, long_dir if found_long else None, page)
    lines = ["# tavc: the reproduction report", "",
             *horizons.not_a_verdict_lines(base, long),
             "Built by `tavc report` from the saved results in this folder; nothing here was simulated "
             "while writing it, and no number was typed in.", ""]
    if long is not None:
        lines += horizons.summary_lines(base, long)
        lines += horizons.claims_both_table(base, long)
    else:
        head = (f"**Claims reproduced: {n_ok} of {len(tested)} tested**" if base.verdicts else
                f"**Claims (not a verdict): {n_ok} of {len(tested)} tested would be reproduced at "
                f"scale={', scale='.join(base.scale_names())}**")
        lines += [f"{head} (claims {claims['claim_id'].min()}-{claims['claim_id'].max()} of the chapter's nine; "
                  f"{len(claims) - len(tested)} not tested because their experiment has not been run here).", "",
                  "| claim | experiment | verdict | p (the deciding part) |", "|---|---|---|---|"]
        for r in claims.itertuples():
            exp = chapter.experiment_of(r.claim_id)
            ran = exp in runs
            verdict = verdict_words(r.verdict, base.verdicts) if ran else "not run"
            lines.append(f"| {r.claim_id} | {horizons.experiment_cell(base, exp, results_dir)} | {verdict} | "
                         f"{p_cell(r) if ran else ''} |")
    lines += method_lines()
    model_json = find_model(experiments)
    read = base.read
    if long is not None:
        lines += time_scale_lines(results_dir, long, model_json, base)
    lines += surrogate_lines(results_dir)
    lines += compare_lines(results_dir)
    n_runs = len(experiments) + sum(len(ds) for ds in base.others.values())
    say(f"report: drawing the figures of {n_runs} runs and the studies "
        f"({time.perf_counter() - start:.0f} s so far; this takes up to a minute or two)")
    try:
        with FigurePool() as pool:
            # the sections that draw figures are written side by side while the rest of the text is
            ratio = pool.submit(value_ratio_lines, results_dir, model_json)
            figures = {name: pool.submit(spatiotemporal_lines, name, d, read[name][0], results_dir)
                       if (d / "table_1_1.csv").is_file()
                       else pool.submit(experiment_figures, name, d, read[name][0], read[name][1], results_dir,
                                        model_json)
                       for name, d in experiments.items()}
            figures.update({d: pool.submit(draw_figures, name, d, _config(d / "config.yaml"), results_dir,
                                           results_dir, model_json)
                            for name, ds in base.others.items() for d in ds})
            lines += _experiment_sections(base, figures, long=long, results_dir=results_dir, model_json=model_json)
            lines += ratio.result()
    except BaseException:
        # stopped while drawing (Ctrl-C, SIGTERM, an error): what is in figures/ now is this report's
        # (`take_report_folders` refused anything else there), so it is listed as tavc's, and the
        # next report replaces it rather than refusing it
        list_figures(taken)
        raise
    lines += chapter_check_lines()
    lines += ["", *run_list_lines(results_dir, base, long)]
    lines += gaps_lines()
    write_text_atomic(results_dir / "claims.csv", claims.to_csv(index=False, float_format="%.6g"))
    if long is not None:
        write_text_atomic(long.folder / "claims.csv", long.claims.to_csv(index=False, float_format="%.6g"))
    write_text_atomic(results_dir / "REPORT.md", "\n".join(lines))
    if page:
        write_report_html(results_dir)
    list_figures(taken)
    say(f"report: written in {time.perf_counter() - start:.0f} s")
    out = {"report": str(results_dir / "REPORT.md"), "experiments": list(experiments), "claims": claims,
           **({"page": str(results_dir / HTML_FILE)} if page else {}),
           "n_reproduced": n_ok, "n_tested": len(tested), "unfinished": [str(d) for d in unfinished],
           "runs": _run_names(found, results_dir), "not_a_verdict": base.shortfalls,
           "studies": {what: [rel(d, results_dir) for d in folders] for what, folders in study_runs(results_dir)}}
    if long is not None:
        out.update({"factor": long.factor, "experiments_long": list(long.experiments), "claims_long": long.claims,
                    "n_reproduced_long": long.n_reproduced, "n_tested_long": len(long.tested),
                    "runs_long": _run_names(found_long, results_dir), "not_a_verdict_long": long.shortfalls})
        out["unfinished"] += [str(d) for d in long.unfinished]
    return out


def _horizon(folder: Path, found: dict[str, list[Path]], unfinished: list[Path]) -> horizons.Horizon:
    """One horizon's runs, read (its folders already checked; a damaged trial record that
    `text.delivery_lines` reads is refused here, before anything is written): settings,
    state tables, the per-trial tables the claims read, and the claims tested on them
    together, for the run of each experiment they are tested on; the other runs' folders
    beside, and what every run delivered."""
    experiments = {name: folders[0] for name, folders in found.items()}
    runs = {name: pd.read_csv(d / "trial_stats.csv") for name, d in experiments.items()
            if (d / "trial_stats.csv").is_file()}
    runs.update({f"{name}/{t}": pd.read_csv(d / f"{t}.csv") for name, d in experiments.items()
                 for t in CLAIM_TABLES if (d / f"{t}.csv").is_file()})
    read = {name: (_config(d / "config.yaml"), pd.read_csv(d / "state_time.csv", dtype={"state": str}))
            for name, d in experiments.items()}
    others = {name: folders[1:] for name, folders in found.items() if len(folders) > 1}
    deliveries = {d: delivery_lines(d, load_json(d / "provenance.json"))
                  for folders in found.values() for d in folders}
    return horizons.Horizon(folder, experiments, read, runs, claim_table(runs, learner=_under_test(read)), unfinished,
                            others, deliveries)


def _under_test(read: dict) -> str:
    """The learner the claims about learning test: the task learner every run's trials are of
    (TAVC's runs: `tavc`), else TAVC (`claims.learner_under_test`)."""
    from tavc_cli.analysis.claims import learner_under_test
    from tavc_cli.learning.registry import controller_label

    return learner_under_test(controller_label(str(cfg.learner.name)) for cfg, _ in read.values())


def _run_names(found: dict[str, list[Path]], results_dir: Path) -> dict[str, list[str]]:
    """experiment -> its runs' folders as the report names them, the one its claims are tested on first."""
    return {name: [rel(d, results_dir) for d in folders] for name, folders in found.items()}


def summary_lines(result: dict) -> list[str]:
    """`build_report`'s result in a few lines: the runs left out, "not a verdict" where the
    claims were tested on runs below the chapter's scale, the claims and the runs they were
    tested on, every other run reported, the studies' runs, where the report went."""
    lines = [f"left out {folder}: its run did not finish (no provenance.json); run it again to complete it"
             for folder in result["unfinished"]]
    lines += _count_lines(result, "", "claims reproduced", "")
    if "factor" in result:
        lines += _count_lines(result, "_long", f"claims reproduced at {result['factor']:g} times the chapter's "
                              "durations", f" at {result['factor']:g} times the chapter's durations")
    lines += [f"read as a whole, not run by run: {_common(folders)} ({len(folders)} runs: {what})"
              for what, folders in result.get("studies", {}).items()]
    return [*lines, result["report"], *([result["page"]] if "page" in result else [])]


def _common(folders: list[str]) -> str:
    """The folder that holds all of `folders` (paths relative to the results folder), with a slash."""
    parts = [f.split("/") for f in folders]
    common = []
    for level in zip(*parts, strict=False):
        if len(set(level)) > 1:
            break
        common.append(level[0])
    return "/".join(common) + "/" if common else "./"


def _count_lines(result: dict, suffix: str, head: str, where: str) -> list[str]:
    """One horizon's lines of `summary_lines`: "not a verdict" first where its runs are below
    the chapter's scale, then its count (what it would be) and the runs it was tested on."""
    short = result.get(f"not_a_verdict{suffix}") or {}
    n, total, runs = result[f"n_reproduced{suffix}"], result[f"n_tested{suffix}"], result[f"runs{suffix}"]
    lines = [f"{text[:text.index(' (')]}{where} ({name}: {text[text.index(' (') + 2:-1]})"
             for name, text in short.items()]
    if short:
        lines.append(f"claims (not a verdict){where}: {n} of {total} tested would be reproduced ({_tested_on(runs)})")
    else:
        lines.append(f"{head}: {n} of {total} tested ({_tested_on(runs)})")
    return lines + _other_runs(runs)


def _tested_on(runs: dict[str, list[str]]) -> str:
    """The experiments and the folder of the run each one's claims were tested on, where it
    is not the folder named after it."""
    return ", ".join(name if folders[0] in (name, f"{horizons.CONVERGED_DIR}/{name}") else f"{name} in {folders[0]}"
                     for name, folders in runs.items())


def _other_runs(runs: dict[str, list[str]]) -> list[str]:
    return [f"also reported, in sections of their own: {', '.join(folders[1:])} ({name}; its claims tested on "
            f"{folders[0]})" for name, folders in runs.items() if len(folders) > 1]


def _experiment_sections(base: horizons.Horizon, figures: dict, *, long: horizons.Horizon | None = None,
                         results_dir: Path | None = None, model_json: Path | None = None) -> list[str]:
    """Each experiment's section of the report: its tables, notes, figures and run lines
    (`figures[name]`: the future of its figures' lines, or of section 1.4's whole text), the
    sections of its other runs (`figures[folder]`: theirs), then its subsection at the long
    horizon where there is one, and the long horizon's other runs."""
    lines: list[str] = []
    for name, d in base.experiments.items():
        lines += _experiment_section(name, d, base, figures)
        for other in base.others.get(name, []):
            lines += other_run_lines(name, other, _config(other / "config.yaml"), d, base.folder,
                                     figures[other].result(), base.deliveries[other])
        if long is not None and results_dir is not None:
            lines += _long_lines(name, long, results_dir, model_json, base_state=base.read[name][1])
    for name in (long.experiments if long is not None and results_dir is not None else {}):
        if name not in base.experiments:  # run at the long horizon only
            cfg = long.read[name][0]
            lines += [f"## {name} (section {cfg.section or '?'})", "", chapter_says(cfg.description), "",
                      "Not run at the chapter's durations here.", ""]
            lines += _long_lines(name, long, results_dir, model_json)
    return lines


def _long_lines(name: str, long: horizons.Horizon, results_dir: Path, model_json: Path | None,
                base_state: pd.DataFrame | None = None) -> list[str]:
    """An experiment's subsection at the long horizon, then the sections of its other runs there."""
    lines = horizons.experiment_lines(name, results_dir, long, model_json, base_state=base_state)
    for other in long.others.get(name, []):
        cfg = _config(other / "config.yaml")
        drawn = draw_figures(name, other, cfg, long.folder, results_dir, model_json)
        lines += other_run_lines(name, other, cfg, long.experiments[name], results_dir, drawn,
                                 long.deliveries[other], f" at {horizons.label(long.factor)}")
    return lines


def _experiment_section(name: str, d: Path, base: horizons.Horizon, figures: dict) -> list[str]:
    """One experiment's section at the chapter's durations."""
    cfg, state_time = base.read[name]
    claims, runs = base.claims, base.runs
    prov = load_json(d / "provenance.json") if (d / "provenance.json").is_file() else {}
    comparison = experiment_comparison(name, state_time)
    lines = [f"## {name} (section {cfg.section or '?'})", "", chapter_says(cfg.description), ""]
    lines += choice_lines(name, [d, *base.others.get(name, [])], base.folder)
    lines += base.deliveries[d]
    if (d / "table_1_1.csv").is_file():
        return [*lines, *figures[name].result(), *run_lines(name, d, cfg, prov, claims, runs)]
    table = chapter.state_table_id(name)
    lines.append("% of the stable period in each state, mean ± std over trials"
                 + (f"; the chapter's Table {table} beside ours:" if table else ":"))
    lines += ["", *state_table(state_time, comparison), ""]
    if name in runs:
        lines += [performance(runs[name]), ""]
        lines += settle_lines(runs[name], cfg)
        lines += q_gap_lines(runs[name])
    lines += model_lines(d / "model" / "model.json", state_time)
    if (d / "model" / "model.json").is_file():
        lines.append("")
    lines += figures[name].result()
    lines += mechanism_lines(d)
    lines += robot_lines(d)
    lines += vacancy_lines(d)
    lines += run_lines(name, d, cfg, prov, claims, runs)
    return lines
