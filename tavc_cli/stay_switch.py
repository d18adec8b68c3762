"""`tavc stay-switch`: what each reading of the world does to staying and switching.

For every reading on a grid fixed before any run (`analysis.stay_switch.GRID`: arrival at the dock or the code
read at range, passing by the nearest free heading or keeping left, crossing or parallel
circuits), the static `alternate` robots of the surrogate's measurement
(`surrogate.run.measure_tasks`) run every make-up of the experiment's team (robots staying
high, staying low, alternating), and `analysis.stay_switch` turns their tasks into the
stay/switch times, where the time goes, and whether staying pays; and `analysis.makeup_model`
into the make-ups of stayers and alternators that are rest points, and which one their drift
reaches from random tables; and the model that knows turn-taking (`turn_taking`: the chapter's
learners on the reading's measured tasks at 40x, static alternators where they take turns)
predicts the regime, the robots on the high-value circuit and the modal state. What t covers (the whole task
or from the source on) needs no runs of its own: both are read from the same tasks.

Each reading's tasks are kept in `<results>/<reading>/tasks/` (`dock-nearest-two_circuits/`),
guarded as the surrogate's are (other settings refused, other code measured again), so a
rerun measures only what is missing.
The study writes `stay_switch.csv`, `stay_switch_model.csv`, `stay_switch_turn_taking.csv`
(the turn-taking model's runs in `<reading>/turn_taking/`), `stay_switch.json` (the grid, the settings, the tasks'
digests) and the figure `stay_switch.png`/`.svg`. Static robots learn nothing, and the readings
are measured at their defaults, or (`--calibrated`) at the settings each one's own calibration
search chose against the chapter's facts: no learner's table and no claim enters.
"""

from __future__ import annotations

import json
from collections.abc import Callable, Sequence
from pathlib import Path

import pandas as pd

from tavc_cli.analysis.makeup_model import predict, readings_summary, times_of, values_high_low
from tavc_cli.analysis.stay_switch import GRID, reading_folder, reading_name, readings, stay_switch_table
from tavc_cli.chapter import base_case
from tavc_cli.errors import TavcError
from tavc_cli.io import claim_folder, owned_path, write_text_atomic
from tavc_cli.override_keys import setting, setting_key
from tavc_cli.ownership import READINGS, READINGS_DIR, STAY_SWITCH_FILES, WORLD_SEARCH_DIR, take
from tavc_cli.settings import TavcConfig
from tavc_cli.surrogate.tasks import Team
from tavc_cli.turn_taking import PREDICTED, TURN_TAKING_FOLDER, predict_turn_taking

DEFAULT_EXPERIMENT = base_case().name  # the chapter's base case: its team of six, no events
SET_BY_THE_STUDY = ("arrival", "passing", "arena", "surrogate.tasks_dir", "output_dir")

Compose = Callable[[list[str]], TavcConfig]


def run_stay_switch(out: Path, overrides: Sequence[str], compose: Compose, *, progress: bool = False,
                    echo: Callable[[str], None] = print, calibrated: Path | None = None) -> list[Path]:
    """Measure every reading of `GRID` into `out` and write the study's table, record and
    figure; returns the files written, the table first. `overrides` apply to every reading
    (e.g. `seed=3`, `surrogate.trials_per_makeup=8`, `experiment=...` of a one-group team).
    With `calibrated` (a results folder), each reading is measured at the settings its own
    calibration search there chose (`calibrated_overrides`), not at its defaults."""
    # deferred: loads the simulator's compiled kernels
    from tavc_cli.surrogate.run import measure_tasks, measurement_record, tasks_digest

    chosen = {reading_folder(r): calibrated_overrides(Path(calibrated), reading_folder(r)) for r in readings()} \
        if calibrated is not None else {}
    by_search = {setting_key(o) for c in chosen.values() for o in c}
    set_here = [k for k in map(setting_key, overrides) if k in (*SET_BY_THE_STUDY, *by_search)]
    if set_here:
        raise TavcError(f"{set_here[0]}: set by each reading's calibration search (--calibrated)"
                        if set_here[0] in by_search else f"{set_here[0]}: set by the study for each reading (its grid: "
                        + "; ".join(f"{k} {', '.join(v)}" for k, v in GRID) + ")")
    out = Path(out)
    base = [f"experiment={DEFAULT_EXPERIMENT}", *overrides]
    studied = []  # every reading's settings, composed and checked before anything is written
    for reading in readings():
        name, folder = reading_name(reading), reading_folder(reading)
        owned_path(out, out / folder / "tasks", folder=True, what="--results")  # a link there is refused
        world = [*name.split(), *chosen.get(folder, [])]
        cfg = compose([*base, *world, setting("surrogate.tasks_dir", out / folder / "tasks")])
        _check_studied(cfg)
        studied.append((name, folder, world, cfg))
    with claim_folder(out):
        owned = take(out, READINGS, STAY_SWITCH_FILES, "--results")
    frames, models, learners = [], [], []
    record: dict = {"grid": {k: list(v) for k, v in GRID}, "overrides": list(overrides), "readings": {},
                    **({"calibrated_from": str(calibrated)} if chosen else {})}
    for name, folder, world, cfg in studied:
        groups = tuple(m.group for m in cfg.team.members)
        team = Team.of(groups, tuple(m.speed_mps for m in cfg.team.members))
        echo(f"stay-switch: {name}")
        times = measure_tasks(cfg, [team], progress=progress, echo=echo)
        frames.append(stay_switch_table(times.frame, [float(v) for v in cfg.tasks.values], name))
        values, high = values_high_low(cfg.tasks.values)
        epsilon = float(cfg.learner.epsilon)
        prediction = predict(times_of(times.frame, high), len(groups), values, epsilon)
        models.append(prediction.assign(reading=name, epsilon=epsilon))
        learned = predict_turn_taking([*base, *world], out / folder / TURN_TAKING_FOLDER, compose,
                                      tasks_dir=out / folder / "tasks", progress=progress, echo=echo)
        learners.append({"reading": name, **{k: learned[k] for k in PREDICTED}})
        record.setdefault("scale", str(cfg.scale.name))
        record.setdefault("measurement", measurement_record(cfg)["measurement"])
        record["readings"][name] = {"tasks": f"{folder}/tasks/task_times.csv", "tasks_digest": tasks_digest(times),
                                    "values": [float(v) for v in cfg.tasks.values], "team": team.name,
                                    **({"calibrated": chosen[folder]} if chosen else {})}
    table = pd.concat(frames, ignore_index=True)
    model = pd.concat(models, ignore_index=True)
    model = model[["reading", *(c for c in model.columns if c != "reading")]]
    from tavc_cli.viz.stay_switch import stay_switch_figure  # deferred: loads matplotlib

    with claim_folder(out):
        owned.wrote(*STAY_SWITCH_FILES)
        write_text_atomic(out / "stay_switch.csv", table.to_csv(index=False, float_format="%.4f"))
        write_text_atomic(out / "stay_switch_model.csv", model.to_csv(index=False, float_format="%.4f"))
        write_text_atomic(out / "stay_switch_turn_taking.csv",
                          pd.DataFrame(learners).to_csv(index=False, float_format="%.4f"))
        write_text_atomic(out / "stay_switch.json", json.dumps(record, indent=2))
        figures = stay_switch_figure(table, out / "stay_switch")
    return [out / "stay_switch.csv", out / "stay_switch_model.csv", out / "stay_switch_turn_taking.csv",
            out / "stay_switch.json", *figures]


def _check_studied(cfg: TavcConfig) -> None:
    """What the study needs of a reading's settings: a team of one group, two circuits, and an
    epsilon-greedy learner (the drift model takes its exploration)."""
    groups = tuple(m.group for m in cfg.team.members)
    if len(set(groups)) != 1:
        raise TavcError(f"experiment={cfg.experiment_name}: stay and switch are measured on a team of one group; "
                        f"this team has {len(set(groups))} ({', '.join(dict.fromkeys(groups))})")
    if len(cfg.tasks.values) != 2:
        raise TavcError(f"arena: stay and switch need two circuits; {cfg.arena.name} has {len(cfg.tasks.values)}")
    if not hasattr(cfg.learner, "epsilon"):
        raise TavcError(f"learner={cfg.learner.name}: the drift model takes an epsilon-greedy learner's "
                        "exploration (learner.epsilon); this learner has none")


def calibrated_overrides(results_dir: Path, folder: str) -> list[str]:
    """The settings the calibration search of the reading in `folder` chose (`search.json`'s
    `chosen_overrides`): today's world's in `<results_dir>/calibration/world/`, another
    reading's in `<results_dir>/readings/<folder>/calibration/world/` (`make calibrate-readings`);
    refused in one line where there is no such search or it chose no point."""
    today = folder == reading_folder(readings()[0])
    path = results_dir / ("" if today else f"{READINGS_DIR}/{folder}") / WORLD_SEARCH_DIR / "search.json"
    if not path.is_file():
        raise TavcError(f"--calibrated: no calibration search of {folder} at {path} (make calibrate-readings)")
    try:
        record = json.loads(path.read_text())
    except (OSError, ValueError):
        raise TavcError(f"--calibrated: {path} cannot be read; rerun its tavc calibrate") from None
    chosen = record.get("chosen_overrides") if isinstance(record, dict) else None
    if not isinstance(chosen, list) or not chosen or not all(isinstance(o, str) and "=" in o for o in chosen):
        raise TavcError(f"--calibrated: {path} names no chosen point (no point met the chapter's facts)")
    return chosen


def summary_lines(table: pd.DataFrame, model: pd.DataFrame | None = None) -> list[str]:
    """Per reading: the range of t_switch / t_stay on the low-value circuit over the make-ups
    with both, against the threshold, and in how many make-ups staying pays (whole task; from
    the source on); with `model` (`stay_switch_model.csv`), the regime the drift model
    predicts and the robots it puts on the high-value circuit."""
    summary = readings_summary(table, model).set_index("reading")
    lines = []
    for name in dict.fromkeys(table["reading"]):
        if name not in summary.index:
            lines.append(f"{name}: no make-up with both a low-value stayer and an alternator")
            continue
        r = summary.loc[name]
        lines.append(f"{name}: t_switch / t_stay,low {r['ratio_min']:.3f} to {r['ratio_max']:.3f} "
                     f"(staying pays above {r['threshold']:.3f}) in {r['n']} make-ups; "
                     f"pays in {r['pays']}, timed from the source in {r['pays_source']}")
        if r["regime"] is not None:
            lines[-1] += (f"; the drift model: {r['regime']} ({r['basin']:.0%} of starts), "
                          f"{r['robots_high']:.2f} robots high")
    return lines
