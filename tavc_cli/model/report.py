"""A readable summary of a `tavc model` result for the terminal."""

from __future__ import annotations

import math

from tavc_cli.vocabulary import ACTIVITIES


def _fmt(x: float, spec: str = ".4g") -> str:
    return "-" if x is None or (isinstance(x, float) and not math.isfinite(x)) else format(x, spec)


def _interval(lo: float, hi: float) -> tuple[str, bool]:
    """A 90 % interval of a rate (or a time) as text, and whether it was clipped. Neither can be
    negative, but a t interval over few trials can reach below 0: its lower bound is then shown
    as 0 and marked with a star, and the table says why below it, rather than printing a rate
    no robot could have."""
    clipped = lo is not None and math.isfinite(lo) and lo < 0
    return f"[{'0*' if clipped else _fmt(lo)}, {_fmt(hi)}]", clipped


def measurement_shortfall(measured: dict, trials_per_split: int, measure_s: float, scale: str) -> str:
    """Where a model's `measured` measurement (its ``measurement`` record) falls below the
    model's own settings (`trials_per_split` static trials of `measure_s` each, as `scale=paper`
    measures them), in words ("2 of 12 static trials per split, 60 of 3,000 s each"); "" where it
    does not. A scale shrinks the measurement as it shrinks every run."""
    out = []
    if int(measured["trials_per_split"]) < int(trials_per_split):
        out.append(f"{int(measured['trials_per_split'])} of {int(trials_per_split)} static trials per split")
    if float(measured["measure_s"]) < float(measure_s):
        out.append(f"{float(measured['measure_s']):,.0f} of {float(measure_s):,.0f} s each")
    return f"scale={scale} measures {', '.join(out)}" if out else ""


def model_text(result: dict, shortfall: str = "") -> str:
    """Per split of the full team: c_i, t_i and reward per task by circuit, total value, and
    which splits are individual equilibria; then predictions, constraints and calibration.
    Headed "not a verdict" with the `shortfall` (`measurement_shortfall`) where there is one."""
    m = result["model"]
    frame = result["table"]
    n = m["n_robots"]
    values = m["values"]
    eq = set(m["equilibria"])
    lines = [f"not a verdict: {shortfall}; its predictions and constraints are a first look, not the model "
             "measured as its settings say (scale=paper)"] if shortfall else []
    lines += [f"TAVC model: {m['arena']}, {n} robots, task values {values} (t in {m['time_unit']})",
              f"written to {result['output_dir']} ({result['n_reused']} measurement trials reused)", ""]
    full = frame[frame["n_robots"] == n]
    head = f"{'state':>7}  {'circuit':>7}  {'robots':>6}  {'c (1/s)':>9}  {'90% CI':>19}  {'t (s)':>7}  " \
           f"{'w/t':>9}  {'slot value':>10}"
    lines.append(head)
    any_clipped = False
    for state, rows in full.groupby("state", sort=False):
        mark = "  <- equilibrium" if state in eq else ""
        for k, r in enumerate(rows.itertuples()):
            ci, clipped = _interval(r.c_lo, r.c_hi)
            any_clipped = any_clipped or clipped
            lines.append(f"{state if k == 0 else '':>7}  {r.circuit:>7}  {r.n_on_circuit:>6}  {_fmt(r.c_per_s):>9}  "
                         f"{ci:>19}  {_fmt(r.task_time_s, '.1f'):>7}  {_fmt(r.reward_per_task):>9}  "
                         f"{_fmt(r.slot_value):>10}" + (mark if k == 0 else ""))
    if any_clipped:
        lines.append("* interval below 0: too few trials to bound the rate from below; shown from 0 "
                     "(more trials per split: model.trials_per_split)")
    lines += ["",
              f"individual equilibrium (predicted): {m['predicted_state']}   "
              f"value-maximising optimum: {m['optimal_state']}   slot filling: {m['slot_fill_state']}"]
    if m["predictions_differ"]:
        lines.append("the learners' predicted allocation differs from the model's optimum")
    for size, p in m["by_team_size"].items():
        if int(size) != n:
            lines.append(f"with {size} robots: predicted {p['predicted_state']}, optimum {p['optimal_state']}")
    for name, c in m.get("constraints", {}).items():
        lines.append(f"constraint ({name}) with {c['n_robots']} robots: {'holds' if c['holds'] else 'fails'}")
    world = m.get("world") or {}
    for lone in world.get("lone_robot", []):
        lines.append(f"a robot alone on circuit {lone['circuit']}: {lone['leg_s']:.1f} s per leg, "
                     f"{lone['ratio']:.2f} x the straight line between its dock spots at top speed")
    if world.get("arrivals_per_5h") is not None:
        ref = world.get("chapter_arrivals_per_5h")
        lines.append(f"target arrivals per 5 h in {world['team_split']}: {_fmt(world['arrivals_per_5h'], '.0f')}"
                     + (f" (the chapter: {ref:.0f})" if ref else ""))
    crowd = world.get("crowding_ratio")
    if crowd:
        lines.append(f"t({crowd['split_crowded']}, crowded circuit) / t({crowd['split_even']}, other) = "
                     f"{crowd['ratio']:.3f}; constraint (1.3) needs more than {crowd['needed_above']:.3f}")
    if world.get("time_budget"):
        lines.append("where a task's time goes (s per task), by robots on the circuit:")
        lines.append("  robots  " + "  ".join(f"{a:>7}" for a in ACTIVITIES[:6]) + "     total")
        for row in world["time_budget"]:
            lines.append(f"  {row['n_on_circuit']:>6}  " + "  ".join(f"{row[a]:7.1f}" for a in ACTIVITIES[:6])
                         + f"  {sum(row[a] for a in ACTIVITIES):8.1f}  (circuit {row['circuit']}, {row['split']})")
    saves = [leg["switch_saves_s"] for leg in m.get("switch_legs", [])]
    if saves and max(saves) > 0:
        lines.append(f"note: switching circuit shortens the empty leg by up to {max(saves):.1f} s (straight line); "
                     "the static model does not see this")
    cal = m.get("calibration")
    if cal:
        lo, hi = cal["ratio_interval"]
        if cal["feasible"]:
            lines.append(f"calibrated values {cal['values']} (w_high / w_low in [{_fmt(lo)}, {_fmt(hi)}], "
                         f"robust to the 90% intervals: {'yes' if cal['robust'] else 'no'}); "
                         f"predicted then: {cal['predicted_state']}")
        elif math.isnan(lo):
            lines.append(f"no calibration: the measurement gave no task time in a split "
                         f"{[t['split'] for t in cal['targets']]} are compared with (nothing delivered there; "
                         "measure longer, model.measure_s)")
        else:
            lines.append(f"no task values make {[t['split'] for t in cal['targets']]} the equilibria "
                         f"(w_high / w_low would need to lie in [{_fmt(lo)}, {_fmt(hi)}])")
    return "\n".join(lines)


def search_text(search: dict) -> str:
    """The world search as a table, one grid point a line, the chosen one marked."""
    res, frame = search["result"], search["table"]
    keys = [c for c in frame.columns if "." in c]
    short = {k: k.rsplit(".", 1)[1] for k in keys}
    lines = [f"world search: {res['n_points']} points, {res['measurement']['trials_per_split']} trials per split "
             f"({res['n_trials_reused']} trials reused), values {res['values']}; written to {search['output_dir']}",
             "  ".join(f"{short[k]:>13}" for k in keys)
             + f"  {'leg s':>6}  {'arr/5h':>6}  {'t4/t3':>6}  {'wait@4':>6}  {'ratio interval':>15}  verdict"]
    for _, row in frame.iterrows():
        verdict = "robust" if row["robust"] else ("feasible" if row["feasible"] else "-")
        interval = f"[{_fmt(row['ratio_lo'], '.3f')}, {_fmt(row['ratio_hi'], '.3f')}]"
        lines.append("  ".join(f"{_fmt(row[k], 'g'):>13}" for k in keys)
                     + f"  {_fmt(row['lone_leg_s'], '.1f'):>6}  {_fmt(row['arrivals_per_5h'], '.0f'):>6}  "
                     f"{_fmt(row['crowding_ratio_6'], '.3f'):>6}  {_fmt(row['wait_s_at_4'], '.1f'):>6}  "
                     f"{interval:>15}  {verdict}" + ("  <- chosen" if row["chosen"] else ""))
    if res["chosen"] is None:
        lines.append("no point meets the chapter's constraints: nothing chosen")
    else:
        lines.append(f"chosen ({'robust' if res['robust'] else 'NOT robust to the intervals'}): "
                     + " ".join(res["chosen_overrides"]))
    return "\n".join(lines)


def sensitivity_text(sens: dict) -> str:
    """Per world (the chosen one, then one setting changed at a time): t_i(n) on each circuit
    for n = 1..N, the crowding ratio and the predicted allocations."""
    res, frame = sens["result"], sens["table"]
    n_team = int(res["measurement"]["n_robots"])
    ns = range(1, n_team + 1)
    lines = [f"sensitivity: every split of {n_team} and {n_team - 1} robots, {res['measurement']['trials_per_split']} "
             f"trials each; t_i(n) in s with n robots on circuit i and the rest on the other",
             f"{'world':>22}  {'circuit':>7}  " + "  ".join(f"{f't({k})':>6}" for k in ns)
             + f"  {'t4/t3':>6}  {'wait@4':>6}  predicted"]
    for w in res["worlds"]:
        for i in range(2):
            rows = frame[(frame["world"] == w["world"]) & (frame["circuit"] == i)].set_index("n_on_circuit")
            t = "  ".join(f"{_fmt(rows['task_time_s'].get(k, math.nan), '.1f'):>6}" for k in ns)
            tail = (f"  {_fmt(w['crowding_ratio_6'], '.3f'):>6}  {_fmt(w['wait_s_at_4'], '.1f'):>6}  "
                    f"{n_team}->{w[f'predicted_{n_team}']}, {n_team - 1}->{w[f'predicted_{n_team - 1}']}"
                    + ("" if w["robust"] else ("  (not robust)" if w["feasible"] else "  (fails a constraint)"))
                    if i == 0 else "")
            lines.append(f"{w['world'] if i == 0 else '':>22}  {('w=' + format(rows['value'].iloc[0], 'g')):>7}  {t}"
                         + tail)
    return "\n".join(lines)
