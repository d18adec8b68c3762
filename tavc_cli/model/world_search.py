"""Reconstructing what the chapter leaves unsaid: a search over the docking world.

The chapter fixes the robots' speed (250 mm/s), the arena, and the task values
2200/2000, which its authors chose after measuring traversal times in their simulator so
that constraints (1.3) and (1.4) hold: the 4th robot on a circuit earns less than the 3rd
on the other, the 3rd on the high-value circuit more than the 3rd on the low one. It does
not say how its robots docked at a bar-code, how close they read it, whether they stood
there to load, or how finely the laser sampled. Those choices decide how strongly robots
crowd each other at the targets, so they are searched here, over the grid of physically
plausible values in the `calibration` config section, and judged only on facts that static
allocations measure: task times, the two constraints, arrivals per hour. No learner runs.

For every grid point the splits the constraints and equilibria need are measured (for six
robots 3:3 and its two neighbours 4:2 and 2:4; for five 3:2, 2:3 and 4:1; and one robot
alone), with the same seeds at every point so that points differ by their settings, not
their luck.

The rule that picks a point was fixed before any point was measured:

1. admissible: with the chapter's values the intended splits (3:3 for six robots, 3:2 for
   five) are individual equilibria, (1.3) and (1.4) hold, and the chapter's ratio
   w_high / w_low lies inside the ratio interval computed from the pessimistic ends of the
   task times' intervals (robust to the measurement);
2. of the admissible points, the one whose six robots make the most target arrivals per hour
   in 3:3, i.e. the least crowded world that still meets the chapter's constraints, nearest
   to the chapter's 3000 arrivals per 5 h;
3. ties: fewer laser rays (cheaper), then grid order.

If no point is robust, the same rule picks among the points that meet everything at the
point estimates, and the result says that it is not robust; if none does, nothing is chosen.
"""

from __future__ import annotations

import hashlib
import json
import math
from collections.abc import Sequence
from itertools import product
from pathlib import Path

import pandas as pd
import yaml

from tavc_cli.errors import TavcError
from tavc_cli.experiments.store import Executor, TrialStore
from tavc_cli.io import write_text_atomic
from tavc_cli.model import core
from tavc_cli.model.api import dock_spots, json_safe
from tavc_cli.model.measure import measurement_specs, table_from
from tavc_cli.settings import GridAxis, TavcConfig
from tavc_cli.vocabulary import ACTIVITIES

Point = dict[str, object]


def grid_points(axes: Sequence[GridAxis]) -> list[Point]:
    """Every combination of the axes' values ({key, values} each), in grid order."""
    keys = [str(a.key) for a in axes]
    return [dict(zip(keys, combo, strict=True)) for combo in product(*[list(a.values) for a in axes])]


def point_id(point: Point) -> str:
    """A short stable name for a grid point (its measurements live under it)."""
    return "w" + hashlib.sha256(json.dumps(point, sort_keys=True).encode()).hexdigest()[:8]


def point_overrides(point: Point) -> list[str]:
    """The grid point as config overrides, ``key=value``."""
    return [f"{k}={v}" for k, v in point.items()]


def needed_splits(n_robots: int, values: Sequence[float]) -> list[core.Split]:
    """The splits that decide the intended allocations of n and n-1 robots (each with its
    one-robot moves), and one robot alone."""
    out = {(1, 0)}
    for n in (n_robots, n_robots - 1):
        s = core.intended_split(n, values)
        out.add(s)
        for i in range(2):
            if s[i] > 0:
                out.add(core.add_robot(core.add_robot(s, i, -1), 1 - i))
    return sorted(out, key=lambda s: (sum(s), s))


def judge(table: core.CTable, cfg: TavcConfig, n_robots: int, values: Sequence[float]) -> dict:
    """What one grid point's measurements say: the world facts and every admission test."""
    n6, n5 = core.intended_split(n_robots, values), core.intended_split(n_robots - 1, values)
    high = max(range(2), key=lambda i: values[i])
    low = 1 - high
    rho = values[high] / values[low]
    cal = core.calibrate(table, [(n_robots, n6), (n_robots - 1, n5)], low_value=values[low], high=high)
    lo, hi = cal["ratio_interval"]
    rlo, rhi = cal["robust_ratio_interval"]
    m = max(n6)
    c13 = core.constraint_1_3(table, n_robots, values, m)
    c14 = core.constraint_1_4(table, n_robots - 1, values, max(n5), high)
    crowd6 = core.pair_split(n_robots, high, m + 1)
    crowd5 = core.add_robot(core.add_robot(n5, low, -1), high)
    speed = float(cfg.robot.speed_mps)
    spots = dock_spots(cfg.arena, float(cfg.robot.behaviour.arrive_dist_m))
    circ = cfg.arena.circuits[0]
    straight = math.dist(spots[circ.source], spots[circ.sink]) / speed
    lone_leg = table.t((1, 0), 0) / 2
    budget4 = table.cells[crowd6][high].budget
    row = {
        "lone_leg_s": lone_leg,
        "lone_leg_over_straight": lone_leg / straight,
        "arrivals_per_5h": table.arrivals_per_h[n6] * 5.0,
        f"t_{core.state_label(n6, values)}_s": table.t(n6, low),
        f"t_{core.state_label(crowd6, values)}_high_s": table.t(crowd6, high),
        "crowding_ratio_6": table.t(crowd6, high) / table.t(n6, low),
        "crowding_ratio_5": table.t(crowd5, high) / table.t(n5, low),
        "wait_s_at_4": budget4[ACTIVITIES.index("wait")] if budget4 else math.nan,
        "escape_s_at_4": budget4[ACTIVITIES.index("escape")] if budget4 else math.nan,
        "ratio_lo": lo, "ratio_hi": hi, "robust_ratio_lo": rlo, "robust_ratio_hi": rhi,
        "chapter_ratio": rho,
        "equilibrium_6": core.is_equilibrium(table, n6, values),
        "equilibrium_5": core.is_equilibrium(table, n5, values),
        "constraint_1_3": c13["holds"], "constraint_1_4": c14["holds"],
    }
    row["feasible"] = bool(row["equilibrium_6"] and row["equilibrium_5"] and row["constraint_1_3"]
                           and row["constraint_1_4"] and lo < rho < hi)
    row["robust"] = bool(row["feasible"] and rlo < rho < rhi)
    return row


def choose(rows: list[dict], rays_key: str = "robot.laser.n_rays") -> tuple[int | None, bool]:
    """The selection rule of the module docstring: (index of the chosen row, robust?)."""
    for flag in ("robust", "feasible"):
        pool = [i for i, r in enumerate(rows) if r[flag] and math.isfinite(r["arrivals_per_5h"])]
        if pool:
            best = max(pool, key=lambda i: (round(rows[i]["arrivals_per_5h"], 6),
                                            -float(rows[i].get(rays_key, 0) or 0), -i))
            return best, flag == "robust"
    return None, False


def run_search(points: Sequence[tuple[Point, TavcConfig]], out_dir: Path, *, n_robots: int, trials: int,
               warmup_s: float, measure_s: float, confidence: float, executor: Executor,
               progress: bool, configured: dict | None = None) -> dict:
    """Measure every grid point (reusing finished trials), judge each, pick one; write
    `search.csv` and `search.json` under out_dir. `configured`: the grid's settings as the search
    was asked them (the world as configured, e.g. a reading's defaults), recorded beside the choice."""
    if n_robots < 3:
        raise TavcError("team.n_robots: the world search needs a team of at least 3 robots")
    plans, specs = [], []
    for point, cfg in points:
        if len(cfg.arena.circuits) != 2:
            raise TavcError("arena: the world search checks the chapter's two-circuit constraints")
        values = [float(v) for v in cfg.tasks.values]
        plan = measurement_specs(cfg, n_robots, trials, warmup_s, measure_s,
                                 only=needed_splits(n_robots, values), prefix=point_id(point) + "_")
        specs += [s for group in plan.values() for s in group]
        plans.append(plan)
    n_reused = TrialStore(out_dir, executor).run(specs, progress)
    rows = []
    for (point, cfg), plan in zip(points, plans, strict=True):
        values = [float(v) for v in cfg.tasks.values]
        table = table_from(plan, out_dir, 2, warmup_s, measure_s, confidence)
        rows.append({"point": point_id(point), **point, **judge(table, cfg, n_robots, values)})
    chosen, robust = choose(rows)
    for i, r in enumerate(rows):
        r["chosen"] = i == chosen
    frame = pd.DataFrame(rows)
    result = {
        "n_points": len(rows), "n_trials_reused": n_reused,
        "measurement": {"trials_per_split": trials, "warmup_s": warmup_s, "measure_s": measure_s,
                        "confidence": confidence, "n_robots": n_robots},
        "values": [float(v) for v in points[0][1].tasks.values] if points else [],
        "chosen": rows[chosen] if chosen is not None else None,
        "chosen_overrides": point_overrides(points[chosen][0]) if chosen is not None else [],
        **({"configured": configured} if configured is not None else {}),
        "robust": robust,
        "n_feasible": int(sum(r["feasible"] for r in rows)),
        "n_robust": int(sum(r["robust"] for r in rows)),
    }
    write_text_atomic(out_dir / "search.csv", frame.to_csv(index=False, float_format="%.6g"))
    write_text_atomic(out_dir / "search.json", json.dumps(json_safe(result), indent=2))
    return {"output_dir": str(out_dir), "result": result, "table": frame}


def save_world(search: dict, world_dir: Path, grid_keys: Sequence[str]) -> Path:
    """Record the chosen world as the config option `world=calibrated`, with the search table
    that justifies it beside it (conf/world/calibration/)."""
    res = search["result"]
    if res["chosen"] is None:
        raise TavcError("calibration: no grid point meets the chapter's constraints; nothing to save")
    chosen = res["chosen"]
    record_dir = world_dir / "calibration"
    for name in ("search.csv", "search.json"):
        write_text_atomic(record_dir / name, (Path(search["output_dir"]) / name).read_text())
    meas = res["measurement"]
    lines = [
        "# @package _global_",
        "# The reconstructed docking world, chosen by `tavc calibrate --save` from a search over",
        f"# {res['n_points']} grid points ({meas['trials_per_split']} static trials per split of "
        f"{meas['measure_s']:g} s after {meas['warmup_s']:g} s) with task values {res['values']}.",
        f"# {res['n_robust']} points met the chapter's constraints robustly, {res['n_feasible']} at the "
        "point estimates;",
        f"# this one is {'robust' if res['robust'] else 'NOT robust to the 90 % intervals'} and makes the most "
        "arrivals per hour among them:",
        f"#   lone robot {chosen['lone_leg_s']:.1f} s per leg ({chosen['lone_leg_over_straight']:.2f} x the "
        "straight line at top speed),",
        f"#   {chosen['arrivals_per_5h']:.0f} target arrivals per 5 h in 3:3 (the chapter: 3000),",
        f"#   t(4 on a circuit) / t(3 on the other) = {chosen['crowding_ratio_6']:.3f} (must exceed "
        f"{chosen['chapter_ratio']:.2f}),",
        f"#   w_high / w_low may lie in [{chosen['ratio_lo']:.3f}, {chosen['ratio_hi']:.3f}], robustly in "
        f"[{chosen['robust_ratio_lo']:.3f}, {chosen['robust_ratio_hi']:.3f}].",
        "# The search table: calibration/search.csv beside this file.",
    ]
    nested: dict = {}
    for key in grid_keys:
        *parents, leaf = key.split(".")
        node = nested
        for part in parents:
            node = node.setdefault(part, {})
        value = chosen[key]
        node[leaf] = value.item() if hasattr(value, "item") else value
    path = world_dir / "calibrated.yaml"
    write_text_atomic(path, "\n".join(lines) + "\n" + yaml.safe_dump(nested, sort_keys=False))
    return path


def one_axis_variants(axes: Sequence[GridAxis], chosen: Point) -> list[tuple[str, Point]]:
    """The chosen point, then every point that differs from it on one grid axis only:
    (the key varied, or "chosen"; the point)."""
    out: list[tuple[str, Point]] = [("chosen", dict(chosen))]
    for axis in axes:
        key = str(axis.key)
        out += [(key, {**chosen, key: v}) for v in axis.values if v != chosen[key]]
    return out


def sensitivity_rows(table: core.CTable, n_robots: int, values: Sequence[float]) -> list[dict]:
    """t_i(n) for n = 1..N robots on circuit i and the rest of the team on the other, both circuits."""
    rows = []
    for i in range(2):
        for k in range(1, n_robots + 1):
            n = core.pair_split(n_robots, i, k)
            cell = table.cells[n][i]
            rows.append({
                "circuit": i, "value": float(values[i]), "n_on_circuit": k, "state": core.state_label(n, values),
                "task_time_s": cell.t, "t_lo": cell.t_lo, "t_hi": cell.t_hi,
                "wait_s": cell.budget[ACTIVITIES.index("wait")] if cell.budget else math.nan,
                "n_trials": cell.n_trials,
            })
    return rows


def run_sensitivity(variants: Sequence[tuple[str, Point, TavcConfig]], out_dir: Path, *, n_robots: int, trials: int,
                    warmup_s: float, measure_s: float, confidence: float, executor: Executor,
                    progress: bool) -> dict:
    """Measure every split of N and N-1 robots in each variant world (reusing the search's
    trials where they coincide) and say, per world, t_i(n) for n = 1..N, the crowding ratio
    and the allocations the model predicts with the chapter's values. Writes
    `sensitivity.csv` (t_i(n), one row per world, circuit and n) and `sensitivity.json`."""
    plans, specs = [], []
    for _, point, cfg in variants:
        only = [(1, 0), *core.splits(n_robots, 2), *core.splits(n_robots - 1, 2)]
        plan = measurement_specs(cfg, n_robots, trials, warmup_s, measure_s, only=only,
                                 prefix=point_id(point) + "_")
        specs += [s for group in plan.values() for s in group]
        plans.append(plan)
    TrialStore(out_dir, executor).run(specs, progress)
    worlds, rows = [], []
    for (varied, point, cfg), plan in zip(variants, plans, strict=True):
        values = [float(v) for v in cfg.tasks.values]
        table = table_from(plan, out_dir, 2, warmup_s, measure_s, confidence)
        value = point.get(varied)
        shown = format(value, "g") if isinstance(value, (int, float)) else str(value)
        label = "chosen" if varied == "chosen" else f"{varied.rsplit('.', 1)[-1]}={shown}"
        world = {"world": label, "varied": varied, "point": point_id(point), **point,
                 **judge(table, cfg, n_robots, values)}
        for m in (n_robots, n_robots - 1):
            world[f"predicted_{m}"] = core.state_label(core.predicted_split(table, m, values), values)
            world[f"intended_{m}"] = core.state_label(core.intended_split(m, values), values)
        worlds.append(world)
        rows += [{"world": label, "varied": varied, **point, **r} for r in sensitivity_rows(table, n_robots, values)]
    frame = pd.DataFrame(rows)
    result = {"measurement": {"trials_per_split": trials, "warmup_s": warmup_s, "measure_s": measure_s,
                              "confidence": confidence, "n_robots": n_robots}, "worlds": worlds}
    write_text_atomic(out_dir / "sensitivity.csv", frame.to_csv(index=False, float_format="%.6g"))
    write_text_atomic(out_dir / "sensitivity.json", json.dumps(json_safe(result), indent=2))
    return {"output_dir": str(out_dir), "result": result, "table": frame}
