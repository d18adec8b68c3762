"""`tavc model`: measure the simulator, apply the TAVC model, write model.csv and model.json."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pandas as pd

from tavc_cli.errors import TavcError
from tavc_cli.experiments.build import TIME_UNITS_S
from tavc_cli.experiments.store import Executor
from tavc_cli.io import claim_folder, write_text_atomic
from tavc_cli.model import core
from tavc_cli.model.measure import measure
from tavc_cli.notation import counts_of, join_counts
from tavc_cli.ownership import MODEL, MODEL_FILES, refuse_other_settings, take
from tavc_cli.reference import chapter_world
from tavc_cli.settings import ArenaConfig, TavcConfig
from tavc_cli.sim.arena import arena_from_config
from tavc_cli.vocabulary import ACTIVITIES


def _scaled_measurement(cfg: TavcConfig) -> tuple[int, float, float]:
    """Trials per split and times, shrunk by the chosen scale like every other run."""
    m, scale = cfg.model, cfg.scale
    trials = int(m.trials_per_split)
    if scale.trials:
        trials = max(2, min(trials, int(scale.trials)))
    factor = float(scale.time_factor)
    return trials, float(m.warmup_s) * factor, float(m.measure_s) * factor


def team_sizes(n_robots: int, values) -> tuple[int, int]:
    """(N, N') where N' is the team the vacancy constraint (1.4) is checked on: one robot
    fewer when N robots split evenly (6 -> 5, as after the chapter's breakdown), else N."""
    intended = core.intended_split(n_robots, values)
    balanced = len(set(intended)) == 1
    return n_robots, (n_robots - 1 if balanced and n_robots > 1 else n_robots)


def predictions(table: core.CTable, n_robots: int, values) -> dict:
    """What the model predicts for `n_robots` robots at `values` from `table`: the predicted,
    optimal and slot-fill states, the equilibria and every split's value per second."""
    pred = core.predicted_split(table, n_robots, values)
    opt = core.optimal_split(table, n_robots, values)
    fill = core.slot_fill(table, n_robots, values)
    eq = core.equilibria(table, n_robots, values)
    return {
        "n_robots": n_robots,
        "predicted_state": core.state_label(pred, values),
        "optimal_state": core.state_label(opt, values),
        "slot_fill_state": core.state_label(fill, values),
        "equilibria": [core.state_label(n, values) for n in eq],
        "predictions_differ": pred != opt,
        "total_value_per_s": {core.state_label(n, values): core.total_value(table, n, values)
                              for n in core.splits(n_robots, table.n_circuits)},
    }


def constraints(table: core.CTable, n_robots: int, values) -> dict:
    """The chapter's (1.3) and (1.4) for two circuits; empty otherwise."""
    if table.n_circuits != 2:
        return {}
    n, n_vac = team_sizes(n_robots, values)
    high = int(np.argmax(values))
    m = max(core.intended_split(n, values))
    m_vac = max(core.intended_split(n_vac, values))
    return {"1.3": core.constraint_1_3(table, n, values, m),
            "1.4": core.constraint_1_4(table, n_vac, values, m_vac, high)}


def switch_legs(arena: ArenaConfig, speed_mps: float) -> list[dict]:
    """How much shorter (straight-line) the empty leg is when a robot switches circuit.

    The model's t_i(n) are measured on robots that never switch, but the learners'
    state is the class last serviced, and a task that follows a switch starts with the
    leg from the old circuit's sink to the new circuit's source. Where that leg is
    shorter than the leg back to the old source, switching is rewarded for geometry
    alone, which the static model does not see.
    """
    pos = {t.name: (float(t.x), float(t.y)) for t in arena.targets}
    circuits = arena.circuits
    out = []
    for i, ci in enumerate(circuits):
        for j, cj in enumerate(circuits):
            if i == j:
                continue
            stay = math.dist(pos[ci.sink], pos[ci.source])
            switch = math.dist(pos[ci.sink], pos[cj.source])
            out.append({"from": i, "to": j, "stay_leg_m": stay, "switch_leg_m": switch,
                        "switch_saves_s": (stay - switch) / speed_mps})
    return out


def table_from_rows(rows: pd.DataFrame) -> core.CTable:
    """The table back from `model.csv` (c_i and t_i per split and circuit; intervals, budgets
    and arrivals left out): what predictions for other task values need."""
    n_circuits = int(rows["circuit"].max()) + 1
    table = core.CTable(n_circuits)
    for split, g in rows.groupby("split", sort=False):
        n = counts_of(str(split))
        g = g.sort_values("circuit")
        table.cells[n] = tuple(core.Cell(c=float(r.c_per_s), t=float(r.task_time_s)) for r in g.itertuples())
    return table


def table_rows(table: core.CTable, values, time_unit_s: float) -> pd.DataFrame:
    """One row per split and circuit: c_i, t_i with intervals, reward, slot value, and where
    the completed tasks' time went (seconds per task in each activity)."""
    rows = []
    for n, cells in sorted(table.cells.items(), key=lambda kv: (sum(kv[0]), [-v for v in kv[0]])):
        for i, cell in enumerate(cells):
            budget = dict(zip((f"{a}_s" for a in ACTIVITIES), cell.budget, strict=True)) if cell.budget else {}
            rows.append({
                "split": join_counts(n), "state": core.state_label(n, values), "n_robots": sum(n),
                "circuit": i, "n_on_circuit": n[i], "c_per_s": cell.c, "c_lo": cell.c_lo, "c_hi": cell.c_hi,
                "task_time_s": cell.t, "t_lo": cell.t_lo, "t_hi": cell.t_hi,
                "task_time_delivered_s": cell.t_delivered,
                "reward_per_task": core.reward_rate(table, n, i, values, time_unit_s) if n[i] else math.nan,
                "slot_value": core.slot_value(table, n, i, values), "n_trials": cell.n_trials,
                "arrivals_per_h": table.arrivals_per_h.get(n, math.nan),
                **{f"{a}_s": budget.get(f"{a}_s", math.nan) for a in ACTIVITIES},
            })
    return pd.DataFrame(rows)


def dock_spots(arena: ArenaConfig, reading_m: float) -> dict[str, tuple[float, float]]:
    """Where each target's dock spot is: `reading_m` out from its bar-code along the wall's normal."""
    built = arena_from_config(arena)
    return {t.name: (t.x + t.normal[0] * reading_m, t.y + t.normal[1] * reading_m) for t in built.targets}


def world_facts(table: core.CTable, cfg: TavcConfig, n_robots: int, values) -> dict:
    """What static allocations show of the world, beside what the chapter says of its own.

    - a robot alone: its time per leg (target to target) against the straight line between
      the two dock spots at top speed;
    - the team split as intended (3:3 for six): target arrivals per 5 h, against the
      chapter's 3000 "traversals" per 5 h trial of six robots (which fit only as legs);
    - the ratio t(m+1) / t(m) that constraint (1.3) needs above w_high / w_low;
    - per number of robots on a circuit (the rest of the team on the other): where a
      completed task's time went.
    """
    speed = float(cfg.robot.speed_mps)
    spots = dock_spots(cfg.arena, float(cfg.robot.behaviour.arrive_dist_m))
    k = table.n_circuits
    lone = []
    for c, circ in enumerate(cfg.arena.circuits):
        alone = tuple(1 if j == c else 0 for j in range(k))
        if alone in table.cells:
            straight = math.dist(spots[circ.source], spots[circ.sink]) / speed
            leg = table.t(alone, c) / 2
            lone.append({"circuit": c, "leg_s": leg, "straight_line_leg_s": straight, "ratio": leg / straight})
    intended = core.intended_split(n_robots, values)
    per_h = table.arrivals_per_h.get(intended, math.nan)
    ref = chapter_world()
    facts = {
        "lone_robot": lone,
        "team_split": core.state_label(intended, values),
        "arrivals_per_5h": per_h * 5.0,
        "chapter_arrivals_per_5h": float(ref["traversals_per_trial"]) if n_robots == ref["n_robots"] else None,
        "time_budget": time_budget(table, n_robots),
    }
    if k == 2:
        m = max(intended)
        high = int(np.argmax(values))
        crowd = core.pair_split(n_robots, high, m + 1)
        even = intended
        if table.has(crowd) and table.has(even):
            facts["crowding_ratio"] = {
                "split_crowded": core.state_label(crowd, values), "split_even": core.state_label(even, values),
                "t_crowded_s": table.t(crowd, high), "t_even_other_s": table.t(even, 1 - high),
                "ratio": table.t(crowd, high) / table.t(even, 1 - high),
                "needed_above": max(values) / min(values),
            }
    return facts


def time_budget(table: core.CTable, n_robots: int) -> list[dict]:
    """Seconds per completed task in each activity, by robots on the circuit (whole team placed)."""
    rows = []
    for n, cells in table.cells.items():
        if sum(n) != n_robots:
            continue
        for i, cell in enumerate(cells):
            if n[i] == 0 or not cell.budget:
                continue
            rows.append({"n_on_circuit": n[i], "circuit": i, "split": join_counts(n),
                         "task_time_s": cell.t, **dict(zip(ACTIVITIES, cell.budget, strict=True))})
    return sorted(rows, key=lambda r: (r["n_on_circuit"], r["circuit"]))


def run_model(cfg: TavcConfig, *, progress: bool = False) -> dict:
    """Measure c_i(n), t_i(n) for all splits up to the team size, then predict and calibrate."""
    k = len(cfg.arena.circuits)
    if k < 2:
        raise TavcError("arena: the TAVC model needs at least two circuits to allocate robots between")
    n_robots = int(cfg.model.max_robots or cfg.team.n_robots)
    values = [float(v) for v in cfg.tasks.values]
    out_dir = Path(cfg.output_dir) / "model"
    Executor.from_config(cfg.executor).check()
    with claim_folder(out_dir, within=Path(cfg.output_dir)):
        owned = take(out_dir, MODEL, MODEL_FILES, save=False)  # nothing written until the checks pass
        if owned.owns("model.json"):
            refuse_other_settings(out_dir / "model.json", model_identity(cfg), "output_dir", cfg.overwrite)
        owned.wrote(*MODEL_FILES)
        owned.remove_temporaries()
        return _measure_and_predict(cfg, out_dir, n_robots, values, progress)


def model_identity(cfg: TavcConfig) -> dict:
    """What a model's ``model.json`` records of the settings it was measured with (the team,
    values and measurement), in its layout: a model of other settings is another result."""
    trials, warmup_s, measure_s = _scaled_measurement(cfg)
    return {
        "arena": cfg.arena.name, "n_robots": int(cfg.model.max_robots or cfg.team.n_robots),
        "values": [float(v) for v in cfg.tasks.values], "time_unit": cfg.tasks.time_unit,
        "measurement": {"trials_per_split": trials, "warmup_s": warmup_s, "measure_s": measure_s,
                        "confidence": float(cfg.model.confidence), "robot_speed_mps": float(cfg.robot.speed_mps)},
    }


def calibration_record(cfg: TavcConfig, tasks_dir: Path) -> Path:
    """The model output `save_calibration` keeps beside ``tasks_dir/calibrated.yaml``."""
    n_robots = int(cfg.model.max_robots or cfg.team.n_robots)
    return tasks_dir / "calibration" / f"{cfg.arena.name}_{n_robots}robots_model.json"


def _measure_and_predict(cfg: TavcConfig, out_dir: Path, n_robots: int, values: list[float], progress: bool) -> dict:
    k = len(cfg.arena.circuits)
    time_unit_s = TIME_UNITS_S[cfg.tasks.time_unit]
    trials, warmup_s, measure_s = _scaled_measurement(cfg)
    table, n_reused = measure(cfg, out_dir, n_max=n_robots, trials=trials, warmup_s=warmup_s,
                              measure_s=measure_s, confidence=float(cfg.model.confidence),
                              n_jobs=int(cfg.executor.n_jobs), progress=progress)
    n, n_vac = team_sizes(n_robots, values)
    result = {
        "arena": cfg.arena.name, "n_robots": n_robots, "n_circuits": k,
        "values": values, "time_unit": cfg.tasks.time_unit,
        "high_circuit": int(np.argmax(values)),
        **predictions(table, n, values),
        "by_team_size": {str(m): predictions(table, m, values) for m in sorted({n, n_vac})},
        "constraints": constraints(table, n, values),
        "switch_legs": switch_legs(cfg.arena, float(cfg.robot.speed_mps)),
        "world": world_facts(table, cfg, n, values),
        "measurement": {"trials_per_split": trials, "warmup_s": warmup_s, "measure_s": measure_s,
                        "confidence": float(cfg.model.confidence), "n_trials_reused": n_reused,
                        "robot_speed_mps": float(cfg.robot.speed_mps)},
    }
    if k == 2:
        targets = [(m, core.intended_split(m, [2.0, 1.0])) for m in sorted({n, n_vac}, reverse=True)]
        cal = core.calibrate(table, targets, low_value=min(values), high=0)
        if cal["feasible"]:
            cal_values = cal["values"]
            cal["predicted_state"] = predictions(table, n, cal_values)["predicted_state"]
            cal["by_team_size"] = {str(m): predictions(table, m, cal_values) for m in sorted({n, n_vac})}
            cal["constraints"] = constraints(table, n, cal_values)
        result["calibration"] = cal
    frame = table_rows(table, values, time_unit_s)
    write_text_atomic(out_dir / "model.csv", frame.to_csv(index=False, float_format="%.6g"))
    write_text_atomic(out_dir / "model.json", json.dumps(json_safe(result), indent=2))
    return {"output_dir": str(out_dir), "model": result, "table": frame, "n_reused": n_reused}


def json_safe(obj):
    """JSON has no inf/nan: write them as null."""
    if isinstance(obj, float) and not math.isfinite(obj):
        return None
    if isinstance(obj, dict):
        return {k: json_safe(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [json_safe(v) for v in obj]
    if isinstance(obj, (np.floating, np.integer, np.bool_)):
        return json_safe(obj.item())
    return obj


def save_calibration(result: dict, tasks_dir: Path) -> Path:
    """Record calibrated task values as the `tasks=calibrated` config option.

    Writes `calibrated.yaml` and, under `calibration/`, the model output it came from,
    so the values in conf/ always travel with the measurements that justify them.
    """
    m = result["model"]
    cal = m.get("calibration")
    if not cal or not cal["feasible"]:
        raise TavcError("model: no feasible calibration to save (see the constraints in model.json)")
    stem = f"{m['arena']}_{m['n_robots']}robots"
    out_dir = Path(result["output_dir"])
    record_dir = tasks_dir / "calibration"
    for name in ("model.json", "model.csv"):
        write_text_atomic(record_dir / f"{stem}_{name}", (out_dir / name).read_text())
    lo, hi = cal["ratio_interval"]
    rlo, rhi = cal["robust_ratio_interval"]
    text = (
        f"# Task values calibrated in tavc's own simulator by `tavc model` ({m['arena']},\n"
        f"# {m['n_robots']} robots, {m['measurement']['trials_per_split']} static trials per split of "
        f"{m['measurement']['measure_s']:g} s):\n"
        f"# the values under which {' and '.join(str(t['split']) for t in cal['targets'])} are the individual\n"
        f"# equilibria. Feasible w_high / w_low: [{lo:.4f}, {hi:.4f}]; robust to the measurement\n"
        f"# intervals: [{rlo:.4f}, {rhi:.4f}] ({'non-empty' if cal['robust'] else 'empty'}).\n"
        f"# Model output: calibration/{stem}_model.json and .csv beside this file.\n"
        f"values: [{float(cal['values'][0])}, {float(cal['values'][1])}]\n"
        "score_values: [10.0, 1.0]\n"
        f"time_unit: {m['time_unit']}\n"
    )
    path = tasks_dir / "calibrated.yaml"
    write_text_atomic(path, text)
    return path
