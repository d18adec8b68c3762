"""`tavc report`: REPORT.md from saved results only; it never simulates.

It reads, for every run folder under the results directory at any depth (a sweep's jobs sit
two levels down: `<root>/breakdown/0_seed=1/`), what `tavc run` wrote (`config.yaml`,
`provenance.json`, `state_time.csv`, `trial_stats.csv`, and the model's `model/model.json`
if `tavc model` was run into it), checks all of it before writing anything
(`run_checks`: a damaged file is one line naming it, and nothing written), tests the
chapter's claims on the per-trial numbers of one run per experiment together (claim 7
compares two experiments), and writes `claims.csv` (every claim, and the part that decides
each verdict) and `REPORT.md` beside the run folders. A folder directly under the results
directory named `converged` or `x<factor>` holds a longer horizon's runs (`horizons`): their
claims are tested too, written to its own `claims.csv`, and each experiment gets a subsection
there. Every other run of an experiment gets a section of its own (`runs`), titled with its
folder relative to the results directory; the runs of the studies the report reads as a whole
(the value-ratio sweep, the horizon ladder) are named in its list of runs, with where they are
used. A report whose claims are tested on runs below the chapter's scale is headed "not a
verdict". The sections are written by `sections` (an experiment's, at any horizon), `text` (its
prose), `figures` (its figures), `studies` (section 1.4 and the value-ratio sweep) and `time_scale`.

Each run it reads has its claims tested again, and its comparison with the chapter made again,
on its own tables by today's rules (`retest`): a run whose `claims.csv` or `comparison.csv` says
otherwise (an older tavc wrote it, or the run it is compared with was run again) gets it
rewritten, and its `provenance.json` says by which tavc.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from concurrent.futures.process import BrokenProcessPool
from pathlib import Path

from tavc_cli import chapter
from tavc_cli.analysis.claims import verdict_words
from tavc_cli.errors import TavcError
from tavc_cli.io import claim_folder, write_text_atomic
from tavc_cli.ownership import READINGS_DIR, list_figures, take_report_folders
from tavc_cli.ownership import read as read_owned
from tavc_cli.report import horizons
from tavc_cli.report.beside import check_named_runs
from tavc_cli.report.compare import check_compare_tables, compare_lines
from tavc_cli.report.counterfactuals import (
    calibration_lines,
    calibration_tables,
    check_readings,
    counterfactual_lines,
    read_search,
)
from tavc_cli.report.drawing import FigurePool, figure_files, remove_stale_figures
from tavc_cli.report.figures import find_model
from tavc_cli.report.files import (
    SWEEPS,
    check_model,
    config_of,
    horizon_folders,
    model_alternators,
    model_learners,
    prediction_files,
    read_prediction,
    read_stay_switch,
    sweep_runs,
)
from tavc_cli.report.html import HTML_FILE, write_report_html
from tavc_cli.report.method import chapter_check_lines, gaps_lines, method_lines
from tavc_cli.report.runs import (
    LINK_LEFT_OUT,
    finished_runs,
    horizon_ladders,
    other_code_lines,
    rel,
    run_list_lines,
    study_runs,
)
from tavc_cli.report.sections import experiment_sections, submit_figures
from tavc_cli.report.studies import STAY_SWITCH_DIRS, check_value_ratio, stay_switch_lines, value_ratio_lines
from tavc_cli.report.surrogate import study_tables, surrogate_lines
from tavc_cli.report.text import p_cell
from tavc_cli.report.time_scale import time_scale_lines
from tavc_cli.run_checks import check_run
from tavc_cli.run_tables import check_ladder


def _check_readable(results_dir: Path, horizon_dirs: list[Path],
                    *horizon_runs: dict[str, list[Path]]) -> tuple[list[Path], dict[Path, str]]:
    """Check every file the report reads, and where it writes, before writing anything: a
    damaged file is one line naming it, not a half-built report. Every run of every horizon,
    of the sweeps (`files.SWEEPS`) and in other readings at every horizon (`run_checks.check_run`:
    its config.yaml, provenance.json and tables), the models' outputs, the ladders' tables, the
    readings' study's tables, the calibration searches' tables, the surrogate study's tables, the
    comparisons of other learners, the turn-taking model's predictions (at the chapter's scenarios
    and in the stay/switch studies' readings) and its own learners' and alternators' runs. The runs
    are checked two at a time (`_check_runs`). Returns the runs whose claims or comparison today's
    rules make otherwise than their files say, and the runs computed by other code than this
    tavc's, each with the digest of that code."""
    for path in (results_dir / "REPORT.md", results_dir / "claims.csv", *(d / "claims.csv" for d in horizon_dirs)):
        if path.is_dir():
            raise TavcError(f"RESULTS_DIR: {path} is a directory; the report writes a file there")
    folders = [d for runs in horizon_runs for ds in runs.values() for d in ds]
    for sweep in SWEEPS:  # their runs with tables, as `analysis.value_ratio` and the turn-taking checks read them
        folders += [d for d in sweep_runs(results_dir, sweep) if (d / "trial_stats.csv").is_file()]
    for top in (results_dir, *horizon_folders(results_dir)):  # runs in other readings, read by the studies
        folders += [d for d in sweep_runs(top, READINGS_DIR) if (d / "trial_stats.csv").is_file()]
    ladders = horizon_ladders(horizon_folders(results_dir))  # each ladder's table, read and checked, and its rungs
    folders += [d for rungs in ladders.values() for d in rungs]  # whose claims the ladder's table tests again
    stale, other = _check_runs(folders, results_dir)
    for ladder in ladders:  # its numbers beside its rungs' claims: both as the rungs give them now
        check_ladder(ladder)
    for d in STAY_SWITCH_DIRS:  # the stay/switch studies' tables, read as a whole
        read_stay_switch(results_dir / d)
    for _, table in calibration_tables(results_dir):  # the calibration searches' tables and records
        read_search(table)
    study_tables(results_dir)  # the surrogate study's
    check_compare_tables(results_dir)  # the comparisons of other learners, each held to its trials
    check_readings(results_dir)  # each reading's runs made in that reading, whose name their verdicts carry
    check_named_runs(results_dir)  # a prediction's learners found by its name: of its own learners' world
    check_value_ratio(results_dir)  # one run to a cell of the value-ratio table, its columns alike
    own = []  # the predictions' own learners (set beside the learners' runs seed for seed) and alternators
    in_readings = [p for d in STAY_SWITCH_DIRS for p in prediction_files(results_dir, d)]
    predictions = prediction_files(results_dir) + in_readings
    for path in predictions:  # the model's at the chapter's scenarios, and in the stay/switch studies' readings
        predicted = read_prediction(path)
        runs = (model_learners(path.parent, predicted), model_alternators(path.parent, predicted))
        own += [d for d in runs if d is not None and (d / "config.yaml").is_file()]
    own_stale, own_other = _check_runs(own, results_dir)
    return sorted({*stale, *own_stale}), {**other, **own_other}


def _check_runs(folders: list[Path], root: Path) -> tuple[list[Path], dict[Path, str]]:
    """`run_checks.check_run` on each folder, and its model's output, two folders at a time where the
    system forks (`FigurePool`); the first folder in their order with anything wrong is the one
    refused (or a failure of the check itself raised), as one by one, once the checks already
    handed to the processes have ended; where a check process dies, the folders from there on
    are checked here, one by one. Each folder's settings are then read here too, where the
    report reads them again (`files.config_of` keeps them). Returns the folders whose claims or
    comparison are not what today's rules give, and those computed by other code than this tavc's
    with that code's digest (`_check_run`; `root`, the results folder)."""
    refused, here_from, found = None, len(folders), {}
    with FigurePool() as pool:
        pending = [pool.submit(_check_run, d, root) for d in folders]
        for i, (d, checked) in enumerate(zip(folders, pending, strict=True)):
            try:
                found[d] = checked.result()
            except BrokenProcessPool:  # a check process died: this folder and the rest are checked here
                here_from = i
                break
            except Exception as exc:  # noqa: BLE001 - raised below, once the checks under way have ended
                refused = exc
                for later in pending:
                    later.cancel()
                break
            config_of(d / "config.yaml")
    if refused is not None:
        raise refused
    for d in folders[here_from:]:
        found[d] = _check_run(d, root)
        config_of(d / "config.yaml")
    return [d for d, (again, _) in found.items() if again], {d: code for d, (_, code) in found.items() if code}


def _check_run(folder: Path, root: Path) -> tuple[bool, str | None]:
    """`run_checks.check_run` on one folder, and its model's output if it has one; whether its
    claims or its comparison with the chapter, made again on its tables, are not what its files
    hold and tavc may rewrite them (`retest.retested_tables`; `root`, the results folder), and the
    digest of tavc's code that computed its trials where it is not this tavc's (`RunFacts.other_code`;
    else None)."""
    # deferred: a run's analysis loads the simulator's kernels, which importing the report must not
    from tavc_cli.retest import retested_tables

    facts = check_run(folder, config_of)
    check_model(folder)
    return bool(retested_tables(folder, root, config_of)), facts.other_code


def _retest(folders: list[Path], root: Path) -> tuple[dict[Path, list[str]], list[str]]:
    """Rewrite the claims and the comparison of the runs in `folders` under `root` as today's rules
    make them (`retest.rewrite_tables`); a run another tavc command holds now is left to it. Returns
    the files rewritten by run, and a line for each run left."""
    # deferred: as in `_check_run`
    from tavc_cli.retest import rewrite_tables

    rewritten, left = {}, []
    for d in folders:
        try:
            names = rewrite_tables(d, root, config_of)
        except TavcError as exc:  # the folder is in use: the command that holds it writes them
            left.append(f"claims and comparison of {d} not made again ({exc})")
            continue
        if names:
            rewritten[d] = names
    return rewritten, left


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
    with claim_folder(results_dir, what="RESULTS_DIR"):  # a second report of the folder meanwhile: one line
        return _build(results_dir, say, page, start)


def _build(results_dir: Path, say: Callable[[str], None], page: bool, start: float) -> dict:
    """`build_report`'s work, the folder held."""
    say(f"report: reading the runs under {results_dir}")
    links: list[Path] = []
    found, unfinished = finished_runs(results_dir, links)
    longer_found = [(d, *finished_runs(d, links)) for d in horizon_folders(results_dir)]
    emptied = [d for d, runs, _ in longer_found if not runs]  # an earlier report's files there go
    unfinished += [r for _, runs, left in longer_found if not runs for r in left]  # named as left out
    longer_found = [(d, runs, left) for d, runs, left in longer_found if runs]  # a horizon is its finished runs
    stale, other = _check_readable(results_dir, [d for d, _, _ in longer_found], found,
                                   *(runs for _, runs, _ in longer_found))
    experiments = {name: folders[0] for name, folders in found.items()}
    if not experiments and (results_dir / "state_time.csv").is_file():
        raise TavcError(f"RESULTS_DIR: {results_dir} is one run's folder; give the folder that holds the runs "
                        f"({results_dir.parent}: every run under it is read), or move it into a folder of its "
                        f"own (<folder>/{results_dir.name}) and give that folder to report it alone")
    if not experiments:
        raise TavcError(f"RESULTS_DIR: no finished runs under {results_dir} (run `tavc run experiment=...` first)")
    base = horizons.read_horizon(results_dir, found, unfinished)
    longer = sorted((horizons.read_horizon(d, runs, left) for d, runs, left in longer_found),
                    key=lambda h: (h.factor, h.folder.name))
    for i, h in enumerate(longer, start=1):
        h.index = i
    every = [base, *longer]
    claims = base.claims
    tested, n_ok = base.tested, base.n_reproduced
    # everything read: now the first write
    taken = take_report_folders(results_dir, [h.folder for h in longer], page, emptied)
    retested, left = _retest(stale, results_dir)
    drawn_before = figure_files(taken)
    model_json = find_model(experiments)
    n_runs = sum(len(h.experiments) + sum(len(ds) for ds in h.others.values()) for h in every)
    say(f"report: drawing the figures of {n_runs} runs and the studies while the text is written "
        f"({time.perf_counter() - start:.0f} s so far; this takes up to a minute or two)")
    try:
        with FigurePool() as pool:
            # every horizon's figures are drawn side by side from here, while the text is written
            ratio = pool.submit(value_ratio_lines, results_dir, model_json)
            figures = submit_figures(pool, every, results_dir, model_json)
            lines = _front_lines(every, results_dir, model_json, other)
            lines += experiment_sections(every, figures, results_dir, model_json)
            lines += ratio.result()
    except BaseException:
        # stopped while drawing (Ctrl-C, SIGTERM, an error): what is in figures/ now is this report's
        # (`take_report_folders` refused anything else there), so it is listed as tavc's, and the
        # next report replaces it rather than refusing it
        list_figures(taken)
        raise
    lines += chapter_check_lines()
    lines += ["", *run_list_lines(results_dir, every, links)]
    lines += gaps_lines()
    write_text_atomic(results_dir / "claims.csv", claims.to_csv(index=False, float_format="%.6g"))
    for h in longer:
        write_text_atomic(h.folder / "claims.csv", h.claims.to_csv(index=False, float_format="%.6g"))
    write_text_atomic(results_dir / "REPORT.md", "\n".join(lines))
    if page:
        write_report_html(results_dir)
    stale = remove_stale_figures(taken, drawn_before)  # what an earlier report drew and this one did not
    if stale:
        say(f"report: removed {len(stale)} figure(s) an earlier report drew and this one did not")
    list_figures(taken)
    say(f"report: written in {time.perf_counter() - start:.0f} s")
    out = {"report": str(results_dir / "REPORT.md"), "experiments": list(experiments), "claims": claims,
           **({"page": str(results_dir / HTML_FILE)} if page else {}),
           "n_reproduced": n_ok, "n_tested": len(tested), "unfinished": [str(d) for d in unfinished],
           "links": [str(d) for d in links],
           "retested": {rel(d, results_dir): names for d, names in retested.items()}, "retest_left": left,
           "other_code": {rel(d, results_dir): code for d, code in sorted(other.items())},
           "runs": {name: [rel(d, results_dir) for d in ds] for name, ds in found.items()},  # tested on first
           "not_a_verdict": base.shortfalls,
           "studies": {what: [rel(d, results_dir) for d in folders] for what, folders in study_runs(results_dir)},
           "horizons": [{"folder": rel(h.folder, results_dir), "factor": h.factor, "experiments": list(h.experiments),
                         "claims": h.claims, "n_reproduced": h.n_reproduced, "n_tested": len(h.tested),
                         "runs": {name: [rel(d, results_dir) for d in [d0, *h.others.get(name, [])]]
                                  for name, d0 in h.experiments.items()},
                         "not_a_verdict": h.shortfalls} for h in longer]}
    if longer:  # the first longer horizon under the keys it has always had
        first = out["horizons"][0]
        out.update({"factor": first["factor"], "experiments_long": first["experiments"],
                    "claims_long": first["claims"], "n_reproduced_long": first["n_reproduced"],
                    "n_tested_long": first["n_tested"], "runs_long": first["runs"],
                    "not_a_verdict_long": first["not_a_verdict"]})
    out["unfinished"] += [str(d) for h in longer for d in h.unfinished]
    return out


def _front_lines(every: list, results_dir: Path, model_json: Path | None, other: dict[Path, str]) -> list[str]:
    """The report's text before the experiments' sections: the headline (and the runs of `other`
    code, with its digests, where there are any), the claims table, the method, the time scale,
    the studies, the readings, the surrogate and `tavc compare`'s comparisons (written while the
    figures are drawn)."""
    base, longer = every[0], every[1:]
    runs, claims = base.runs, base.claims
    tested, n_ok = base.tested, base.n_reproduced
    lines = ["# tavc: the reproduction report", "",
             *horizons.not_a_verdict_lines(*every),
             "Built by `tavc report` from the saved results in this folder; nothing here was simulated "
             "while writing it, and no number was typed in.", "", *other_code_lines(other, results_dir)]
    if longer:
        lines += horizons.summary_lines(every)
        lines += horizons.claims_by_horizon_table(every)
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
    if longer:
        lines += time_scale_lines(results_dir, every, model_json)
    lines += stay_switch_lines(results_dir)
    lines += calibration_lines(results_dir)
    lines += counterfactual_lines(base, results_dir, longer)
    lines += surrogate_lines(results_dir)
    lines += compare_lines(results_dir)
    return lines


def summary_lines(result: dict) -> list[str]:
    """`build_report`'s result in a few lines: the runs left out, "not a verdict" where the
    claims were tested on runs below the chapter's scale, the claims and the runs they were
    tested on, every other run reported, the studies' runs, the runs whose claims or comparison it
    made again, where the report went."""
    lines = [f"left out {folder}: its run did not finish (no provenance.json); run it again to complete it"
             for folder in result["unfinished"]]
    lines += [f"left out {folder}: {LINK_LEFT_OUT}" for folder in result.get("links", [])]
    lines += _count_lines(result, "claims reproduced", "")
    for h in result.get("horizons", []):
        where = f" at {h['factor']:g} times the chapter's durations"
        lines += _count_lines(h, f"claims reproduced{where}", where, h["folder"])
    lines += [f"read as a whole, not run by run: {_common(folders)} ({len(folders)} runs: {what})"
              for what, folders in result.get("studies", {}).items()]
    retested = result.get("retested", {})
    if retested:
        files = [name for names in retested.values() for name in names]
        counts = ", ".join(f"{files.count(name)} {name}" for name in sorted(set(files), key=files.index))
        lines.append(f"claims and comparisons made again by this tavc's rules: {len(retested)} run(s) under "
                     f"{_common(list(retested))} held files other than today's rules give from their tables (and the "
                     f"runs they are compared with), now rewritten ({counts}); their provenance.json says by which "
                     "tavc")
    lines += result.get("retest_left", [])
    other = result.get("other_code", {})
    if other:
        lines.append(f"runs of other code: {len(other)} run(s) under {_common(list(other))} were computed by "
                     f"another version of tavc's code ({', '.join(sorted(set(other.values())))}); the report shows "
                     "their numbers as that code made them and says so: run each again to have this code's")
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


def _count_lines(result: dict, head: str, where: str, folder: str = "") -> list[str]:
    """One horizon's lines of `summary_lines` (`result`: the report's, or one of its
    `horizons`, in `folder`): "not a verdict" first where its runs are below the chapter's
    scale, then its count (what it would be) and the runs it was tested on."""
    short = result.get("not_a_verdict") or {}
    n, total, runs = result["n_reproduced"], result["n_tested"], result["runs"]
    lines = [f"{text[:text.index(' (')]}{where} ({name}: {text[text.index(' (') + 2:-1]})"
             for name, text in short.items()]
    if short:
        lines.append(f"claims (not a verdict){where}: {n} of {total} tested would be reproduced "
                     f"({_tested_on(runs, folder)})")
    else:
        lines.append(f"{head}: {n} of {total} tested ({_tested_on(runs, folder)})")
    return lines + _other_runs(runs)


def _tested_on(runs: dict[str, list[str]], folder: str = "") -> str:
    """The experiments and the folder of the run each one's claims were tested on, where it
    is not the folder named after it in its horizon's `folder`."""
    named = (lambda name: f"{folder}/{name}") if folder else (lambda name: name)
    return ", ".join(name if folders[0] == named(name) else f"{name} in {folders[0]}" for name, folders in runs.items())


def _other_runs(runs: dict[str, list[str]]) -> list[str]:
    return [f"also reported, in sections of their own: {', '.join(folders[1:])} ({name}; its claims tested on "
            f"{folders[0]})" for name, folders in runs.items() if len(folders) > 1]
