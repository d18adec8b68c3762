"""The surrogate checked against the physical simulator, and what it then answers in minutes.

`tavc surrogate --study` runs, into one folder (by default runs/<scale>/surrogate-study;
`make surrogate-study` writes results/surrogate):

- **the side-by-side comparison** (`comparison.csv`): every experiment the surrogate serves, at
  the chapter's durations and at 40 times them, on the surrogate calibrated by make-up and on
  the one calibrated by stayers alone, against the simulator's committed runs of the same
  configuration (same trial counts, same seeds): the largest difference in points of any state,
  the modal state, the make-up of the group (stayers, alternators), the convergence measures,
  the score rate and the claims' verdicts; and the horizon ladder of initial_distribution;
- **the phase diagram** (`phase.csv`): the learners' share of robot-time on the high-value
  circuit, their modal allocation and make-up, over team size x value ratio at 1x and 40x,
  with the model's prediction from the same static runs' stay tasks, and the physical
  simulator at a few checked points;
- **the convergence horizon** (`horizon.csv`): the first multiple of the chapter's duration at
  which the learner-side convergence measure (`analysis.convergence`) is met, for epsilon,
  alpha and gamma around the chapter's values;
- **the speed** (`speed.csv`): simulated seconds per second of a core, both engines.

Every grid, horizon and trial count below was fixed before any of it was run.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Iterator, Sequence
from pathlib import Path
from typing import TYPE_CHECKING

import pandas as pd

from tavc_cli.chapter import base_case, served_by
from tavc_cli.errors import TavcError
from tavc_cli.experiments.build import in_this_process, trial_specs
from tavc_cli.io import claim_folder, owned_path, write_text_atomic
from tavc_cli.notation import high_of
from tavc_cli.override_keys import setting, setting_key
from tavc_cli.ownership import STUDY, take
from tavc_cli.settings import to_yaml
from tavc_cli.surrogate.compare import check_beside, comparison_rows, high_share, predicted_state, run_facts
from tavc_cli.surrogate.engine import run_trial
from tavc_cli.surrogate.study_record import RECORD, identity, keep_record
from tavc_cli.surrogate.tasks import Team

if TYPE_CHECKING:
    from tavc_cli.settings import TavcConfig

BASE = base_case().name  # the one its ladder climbs, its phase diagram varies and its horizons measure
HORIZONS = {"paper": 1.0, "converged": 40.0}  # the scale of each horizon and its multiple of the chapter's
CALIBRATIONS = ("makeup", "stayers")
LADDER = (1.0, 4.0, 10.0, 20.0, 40.0)
PHASE_TEAMS = tuple(range(2, 11))
PHASE_RATIOS = (1.0, 1.1, 1.25, 1.5, 1.75, 2.0)
PHASE_TRIALS = 8
LOW_VALUE = 2000.0  # the chapter's low value; the high one is the ratio times it
CHAPTER_POINT = (6, 1.1)  # the chapter's own team and value ratio, whose committed runs the phase diagram shows
CHECKED = ((4, 1.5), (8, 1.1))  # the checked points beside the chapter's own
CHECKED_TRIALS = {"paper": 20, "converged": 8}
HORIZON_FACTORS = (1.0, 2.0, 4.0, 10.0, 20.0, 40.0, 80.0)
HORIZON_TRIALS = 8
HORIZON_PARAMETERS = {"epsilon": (0.05, 0.1, 0.2), "alpha": (0.05, 0.1, 0.2), "gamma": (0.9, 0.95, 0.99)}
STUDY_FILES = tuple(f"{name}.csv" for name in ("comparison", "ladder", "phase", "horizon", "speed")) + tuple(
    f"{name}.{ext}" for name in ("comparison", "phase", "horizon") for ext in ("png", "svg")) + (RECORD,)

# what the study sets for each of its runs: refused as overrides
STUDY_KEYS = ("experiment", "scale", "scale.time_factor", "output_dir", "surrogate.calibration", "surrogate.tasks_dir",
              "team.n_robots", "tasks.values", "trials", "baselines", "learner.epsilon", "learner.alpha",
              "learner.gamma")

Echo = Callable[[str], None]
Compose = Callable[[list[str]], "TavcConfig"]  # overrides -> the settings (`config.load_config`, at the front doors)


# --- the study --------------------------------------------------------------------

class Study:
    """Runs everything the study needs into `out` (each run resumes like any other) and writes
    its tables and figures; `results` holds the simulator's runs to compare with."""

    def __init__(self, out: Path, results: Path, overrides: Sequence[str], compose: Compose, *, progress: bool,
                 echo: Echo) -> None:
        """The study into `out`, comparing with the simulator's runs in `results`; `compose` makes settings
        from overrides, `echo` prints."""
        self.out, self.results, self.overrides, self.compose = Path(out), Path(results), list(overrides), compose
        self.progress, self.echo = progress, echo
        self.tasks_dir = self.below(self.out / "tasks")
        self._settings: dict[tuple[Path, tuple[str, ...]], TavcConfig] = {}

    def below(self, folder: Path) -> Path:
        """`folder`, a run's folder the study names below its own, once no part of it there is a link
        (`io.owned_path`: refused, not followed)."""
        return owned_path(self.out, folder, folder=True, what="--results")

    def surrogate(self, folder: Path, overrides: Sequence[str]) -> Path:
        """A surrogate run of `overrides` into `folder` (its tasks measured in the study's own tasks folder),
        resumed where finished; returns the folder."""
        # deferred: loads the simulator's compiled kernels
        from tavc_cli.surrogate.run import run_surrogate

        cfg = self.settings(folder, overrides)
        if not _finished_as(folder, cfg):
            run_surrogate(cfg, progress=self.progress, echo=self.echo)
        self.echo(f"surrogate: {folder}")
        return folder

    def settings(self, folder: Path, overrides: Sequence[str]) -> TavcConfig:
        """The settings of the surrogate run of `overrides` into `folder`, composed once."""
        key = (folder, tuple(overrides))
        if key not in self._settings:
            self._settings[key] = self.compose([*self.overrides, *overrides,
                                                setting("surrogate.tasks_dir", self.tasks_dir),
                                                setting("output_dir", self.below(folder))])
        return self._settings[key]

    def simulator(self, folder: Path, overrides: Sequence[str]) -> Path:
        """A run of `overrides` in the physical simulator into `folder`, unless it is finished there as
        configured; returns the folder."""
        # deferred: loads the simulator's compiled kernels
        from tavc_cli.pipeline import run_experiment

        cfg = self.compose([*self.overrides, *overrides, setting("output_dir", self.below(folder))])
        if not _finished_as(folder, cfg):
            run_experiment(cfg, progress=self.progress)
        self.echo(f"simulator: {folder}")
        return folder

    # -- what stands beside the surrogate's runs
    def compared(self, part: str) -> Iterator[tuple[str, str, Path, dict[str, tuple[Path, list[str]]]]]:
        """What `part` (compare, ladder) sets side by side, row group by row group: the experiment,
        the horizon's label, the simulator's run, and each surrogate engine's folder and overrides."""
        if part == "ladder":
            for f in LADDER:
                yield BASE, f"{f:g}x", self.results / "converged" / "ladder" / f"x{f:g}", {"surrogate_makeup": (
                    self.out / "makeup" / "ladder" / f"x{f:g}",
                    [f"experiment={BASE}", "scale=converged", f"scale.time_factor={f!r}"])}
            return
        for scale, factor in HORIZONS.items():
            for experiment in served_by("surrogate"):
                engines = {f"surrogate_{c}": (self.out / c / scale / experiment, [
                    f"experiment={experiment}", f"scale={scale}", f"surrogate.calibration={c}"]) for c in CALIBRATIONS}
                simulator = self.results / experiment if scale == "paper" else self.results / scale / experiment
                yield experiment, f"{factor:g}x", simulator, engines

    def chapter_point(self, scale: str) -> tuple[Path, Path, list[str]]:
        """The simulator's run of the chapter's own point (six robots, its values) the phase diagram
        shows at `scale`, beside the surrogate's folder and overrides of the same point."""
        chapter = self.results / BASE if scale == "paper" else self.results / "converged" / BASE
        return chapter, *self._phase_point(scale, *CHAPTER_POINT)

    def _phase_point(self, scale: str, n: int, ratio: float) -> tuple[Path, list[str]]:
        """A surrogate run of the phase diagram: its folder and overrides (`n` robots, the high value
        `ratio` times the low one)."""
        values = [ratio * LOW_VALUE, LOW_VALUE]
        return self.out / "phase" / scale / f"n{n}_r{ratio:g}", [
            f"experiment={BASE}", f"scale={scale}", f"team.n_robots={n}", f"tasks.values=[{values[0]!r},{values[1]!r}]",
            "baselines=[]", f"trials={PHASE_TRIALS}"]

    def references(self, parts: Sequence[str]) -> list[Path]:
        """The simulator's tables under `results` that `parts` set the surrogate beside: each run's
        state_time.csv (the comparison's, the ladder's rungs, the phase diagram's chapter point)
        and the horizon's ladder.csv."""
        runs = [run for part in ("compare", "ladder") if part in parts for _, _, run, _ in self.compared(part)]
        runs += [self.chapter_point(scale)[0] for scale in HORIZONS] if "phase" in parts else []
        tables = [run / "state_time.csv" for run in runs]
        return tables + ([self.results / "converged" / "ladder" / "ladder.csv"] if "horizon" in parts else [])

    def check_simulator(self, parts: Sequence[str]) -> None:
        """Before anything runs: `results` (``--simulator``) holds at least one of the simulator's
        tables `parts` compare with; with none, every comparison would stand without its reference."""
        wanted = self.references(parts)
        if wanted and not any(path.is_file() for path in wanted):
            found = ("is not a folder" if not self.results.is_dir()
                     else f"holds none of the simulator's runs the study compares with (such as {wanted[0].parent})")
            raise TavcError(f"--simulator: {self.results} {found}; name the folder of the simulator's committed runs "
                            "(results, as make reproduce-all writes it)")

    def check_beside(self, parts: Sequence[str]) -> None:
        """Before anything runs: every simulator's run the `parts` will set beside a surrogate's
        run (the comparison's, the ladder's rungs, the phase diagram's chapter point, the rungs
        behind the horizon's ladder.csv) made as that run will be (`compare.check_beside`)."""
        for part in ("compare", "ladder"):
            for _, _, simulator, engines in (self.compared(part) if part in parts else ()):
                if (simulator / "state_time.csv").is_file():
                    check_beside(simulator, [(f, self.settings(f, o)) for f, o in engines.values()])
        for scale in HORIZONS if "phase" in parts else ():
            chapter, folder, point = self.chapter_point(scale)
            if (chapter / "state_time.csv").is_file():
                check_beside(chapter, [(folder, self.settings(folder, point))])
        if "horizon" in parts and (self.results / "converged" / "ladder" / "ladder.csv").is_file():
            for f in HORIZON_FACTORS:
                rung = self.results / "converged" / "ladder" / f"x{f:g}"
                if (rung / "config.yaml").is_file():
                    folder = self.out / "horizon" / "chapter" / f"x{f:g}"
                    check_beside(rung, [(folder, self.settings(folder, self._horizon_point(f, [])))])

    # -- the parts
    def compare(self) -> pd.DataFrame:
        """The side-by-side comparison: every served experiment, both horizons, both calibrations."""
        return self._side_by_side("compare")

    def ladder(self) -> pd.DataFrame:
        """The surrogate's horizon ladder of the base case."""
        return self._side_by_side("ladder")

    def _side_by_side(self, part: str) -> pd.DataFrame:
        rows = []
        for experiment, horizon, simulator, engines in self.compared(part):
            folders = {engine: self.surrogate(f, o) for engine, (f, o) in engines.items()}
            rows += comparison_rows(experiment, horizon, simulator, folders)
        return pd.DataFrame(rows)

    def phase(self) -> pd.DataFrame:
        """The phase diagram over team size and value ratio, with the model and the checked points."""
        # deferred: loads the simulator's compiled kernels
        from tavc_cli.surrogate.run import measure_tasks

        rows = []
        for scale, factor in HORIZONS.items():
            for n in PHASE_TEAMS:
                for ratio in PHASE_RATIOS:
                    folder, point = self._phase_point(scale, n, ratio)
                    self.surrogate(folder, point)
                    rows.append(self._phase_row("surrogate", scale, factor, n, ratio, folder))
                    if (n, ratio) in CHECKED:
                        checked = self.out / "phase" / "checked" / scale / f"n{n}_r{ratio:g}"
                        self.simulator(checked, [*point[:-1], f"trials={CHECKED_TRIALS[scale]}"])
                        rows.append(self._phase_row("simulator", scale, factor, n, ratio, checked))
            chapter = self.chapter_point(scale)[0]
            if (chapter / "state_time.csv").is_file():  # the chapter's own point, as committed
                rows.append(self._phase_row("simulator", scale, factor, *CHAPTER_POINT, chapter))
        table = pd.DataFrame(rows)
        # the model's prediction, from the same static runs' stay tasks
        predicted = []
        for n in PHASE_TEAMS:
            cfg = self.compose([*self.overrides, f"experiment={BASE}", "scale=paper", f"team.n_robots={n}",
                                setting("surrogate.tasks_dir", self.tasks_dir)])
            times = measure_tasks(cfg, progress=self.progress, echo=self.echo)
            team = Team.of(["all"] * n, [float(cfg.robot.speed_mps)] * n)
            for ratio in PHASE_RATIOS:
                state = predicted_state(times, team.name, n, [ratio * LOW_VALUE, LOW_VALUE])
                predicted.append({"n_robots": n, "ratio": ratio, "model_state": state,
                                  "model_high_share": high_of(state) / n})
        return table.merge(pd.DataFrame(predicted), on=["n_robots", "ratio"], how="left")

    def _phase_row(self, engine: str, scale: str, factor: float, n: int, ratio: float, folder: Path) -> dict:
        facts = run_facts(folder)
        return {"engine": engine, "horizon": f"{factor:g}x", "n_robots": n, "ratio": ratio,
                "n_trials": facts["n_trials"], "high_share": high_share(facts["states"], n),
                "modal_state": facts["modal_state"], "pct_modal": facts["pct_modal"],
                **{k: facts.get(k, math.nan) for k in ("n_stayers_high", "n_stayers_low", "n_alternators", "n_mixed",
                                                       "switch_share", "regime", "converged")}}

    def horizon(self) -> pd.DataFrame:
        """The convergence horizon for each learning parameter around the chapter's values."""
        rows = []
        chapter = {"epsilon": 0.1, "alpha": 0.1, "gamma": 0.95}
        points = [("chapter", None)] + [(k, v) for k, vs in HORIZON_PARAMETERS.items() for v in vs if v != chapter[k]]
        for name, value in points:
            label = "chapter" if value is None else f"{name}_{value:g}"
            setting = [] if value is None else [f"learner.{name}={value!r}"]
            mine = []
            for f in HORIZON_FACTORS:
                folder = self.out / "horizon" / label / f"x{f:g}"
                self.surrogate(folder, self._horizon_point(f, setting))
                facts = run_facts(folder)
                mine.append({"parameter": name, "value": math.nan if value is None else value, "factor": f,
                             "n_trials": facts["n_trials"],
                             "q_drift": facts["q_drift"], "policy_changed_share": facts["policy_changed_share"],
                             "alloc_drift": facts["alloc_drift"], "converged": bool(facts["converged"]),
                             "pct_3:3": facts["states"].get("3:3", math.nan),
                             "n_alternators": facts.get("n_alternators", math.nan)})
            met = [r["factor"] for r in mine if r["converged"]]
            for r in mine:  # the first multiple at which the measure is met (inf: none of the ladder's)
                r["horizon"] = met[0] if met else math.inf
                r["engine"] = "surrogate"
            rows += mine
        rows += self._simulator_horizon()
        return pd.DataFrame(rows)

    @staticmethod
    def _horizon_point(factor: float, learner: list[str]) -> list[str]:
        """A surrogate run of the horizon part: the base case at `factor` times the chapter's durations,
        with the `learner` settings it varies."""
        return [f"experiment={BASE}", "scale=converged", f"scale.time_factor={factor!r}", "baselines=[]",
                f"trials={HORIZON_TRIALS}", *learner]

    def _simulator_horizon(self) -> list[dict]:
        """The checked point: the simulator's own ladder at the chapter's parameters, as committed."""
        path = self.results / "converged" / "ladder" / "ladder.csv"
        if not path.is_file():
            return []
        table = pd.read_csv(path)
        rungs = table[(table["controller"] == "tavc") & (table["quantity"] == "converged")].sort_values("factor")
        met = rungs.loc[rungs["mean"] >= 1.0, "factor"]
        first = float(met.iloc[0]) if len(met) else math.inf
        return [{"parameter": "chapter", "value": math.nan, "factor": float(r.factor), "converged": bool(r.mean >= 1.0),
                 "horizon": first, "engine": "simulator"} for r in rungs.itertuples()]

    def speeds(self) -> pd.DataFrame:
        """Simulated seconds per wall second of one core: the first learner trial of every
        experiment, on the simulator at the chapter's durations and on the surrogate at both
        horizons (kernels compiled and tasks measured beforehand: not timed)."""
        # deferred: loads the simulator's compiled kernels
        from tavc_cli.experiments.engine import run_trials
        from tavc_cli.surrogate.run import measure_tasks, surrogate_specs

        rows = []
        for experiment in served_by("surrogate"):
            for scale in HORIZONS:
                cfg = self.compose([*self.overrides, f"experiment={experiment}", f"scale={scale}",
                                    setting("surrogate.tasks_dir", self.tasks_dir)])
                times = measure_tasks(cfg, progress=self.progress, echo=self.echo)
                spec = surrogate_specs(cfg, times)[0]
                in_this_process([spec], cfg.executor.confine, "the surrogate study's speed")
                start = time.perf_counter()
                run_trial(spec, times)
                rows.append({"engine": "surrogate", "experiment": experiment, "scale": scale,
                             "sim_s_per_wall_s": spec.span_s / (time.perf_counter() - start)})
                if scale == "paper":
                    physical = trial_specs(cfg)[0]
                    run_trials([physical])  # the kernels compiled or loaded: not timed
                    start = time.perf_counter()
                    run_trials([physical])
                    rows.append({"engine": "simulator", "experiment": experiment, "scale": scale,
                                 "sim_s_per_wall_s": physical.span_s / (time.perf_counter() - start)})
        return pd.DataFrame(rows)


def _finished_as(folder: Path, cfg) -> bool:
    """Whether `folder` holds a finished run (its provenance.json, written last) of exactly this
    configuration: then the study reads it as it is instead of analysing it again."""
    config = folder / "config.yaml"
    return (folder / "provenance.json").is_file() and config.is_file() and config.read_text() == to_yaml(cfg)


def run_study(out: Path, results: Path, overrides: Sequence[str], compose: Compose, *,
              parts: Sequence[str] | None = None, progress: bool = False, echo: Echo = print) -> list[Path]:
    """Run the study (or only `parts` of it: compare, ladder, phase, horizon, speed) into `out`,
    composing each run's settings with `compose`, and write its tables and figures; returns the
    files written."""
    set_here = [o for o in overrides if setting_key(o) in STUDY_KEYS]
    if set_here:
        raise TavcError(f"{setting_key(set_here[0])}: set by the study for each of its runs; "
                        "overrides apply to all of them (e.g. seed=3, executor.n_jobs=2)")
    wanted = list(parts or ("compare", "ladder", "phase", "horizon", "speed"))
    unknown = [p for p in wanted if p not in ("compare", "ladder", "phase", "horizon", "speed")]
    if unknown:
        raise TavcError(f"--parts: no part {unknown[0]!r} (compare, ladder, phase, horizon, speed)")
    out = Path(out)
    base = compose([*overrides, f"experiment={BASE}", "scale=paper"])  # as its runs compose them, nothing written yet
    study = Study(out, results, overrides, compose, progress=progress, echo=echo)
    study.check_simulator(wanted)
    with claim_folder(out):
        owned = take(out, STUDY, STUDY_FILES, "--results")
    study.check_beside(wanted)
    with claim_folder(out):  # its parts made alike, or those of other settings gone (`study_record`)
        keep_record(owned, out, identity(base, results), bool(base.overwrite), STUDY_FILES)
    written = []
    for part, name in (("compare", "comparison"), ("ladder", "ladder"), ("phase", "phase"), ("horizon", "horizon"),
                       ("speed", "speed")):
        if part not in wanted:
            continue
        table = getattr(study, "speeds" if part == "speed" else part)()
        with claim_folder(out):
            owned.wrote(f"{name}.csv")
            write_text_atomic(out / f"{name}.csv", table.to_csv(index=False, float_format="%.4f"))
        written.append(out / f"{name}.csv")
        echo(f"{part}: {out / f'{name}.csv'}")
    # deferred: loads matplotlib
    from tavc_cli.viz.surrogate import study_figures

    figures = study_figures(out)
    with claim_folder(out):
        owned.wrote(*(p.name for p in figures))
    return written + figures


def summary_lines(out: Path) -> list[str]:
    """The study's headline numbers, from its tables."""
    lines = []
    path = Path(out) / "comparison.csv"
    if path.is_file():
        table = pd.read_csv(path)
        for (horizon, engine), group in table[table["engine"] != "simulator"].groupby(["horizon", "engine"]):
            worst = group.loc[group["largest_diff_pts"].idxmax()] if group["largest_diff_pts"].notna().any() else None
            if worst is not None:
                lines.append(f"{engine} at {horizon}: largest state difference against the simulator "
                             f"{worst['largest_diff_pts']:.1f} points ({worst['experiment']}, {worst['at_state']})")
    path = Path(out) / "speed.csv"
    if path.is_file():
        speed = pd.read_csv(path)
        by = speed.groupby("engine")["sim_s_per_wall_s"].median()
        if {"simulator", "surrogate"} <= set(by.index):
            lines.append(f"speed: the surrogate simulates {by['surrogate']:,.0f} s per second, the simulator "
                         f"{by['simulator']:,.0f} s ({by['surrogate'] / by['simulator']:.0f} times faster)")
    return lines

