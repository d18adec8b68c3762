"""Pictures of a run: an animation (GIF, and MP4 where ffmpeg exists) and a trajectory plot.

They are drawn from a trial record's pose trace, so what they show is what the
simulator did: walls, bar-coded targets with their ids, robots with heading and
their red (left), green (right) and yellow (rear) markings, coloured by the
circuit they serve, with short trails.
"""

from __future__ import annotations

import math
import shutil
import sys
import tempfile
from dataclasses import replace
from pathlib import Path

import numpy as np
from matplotlib import animation
from matplotlib.patches import Circle, Wedge

from tavc_cli.errors import TavcError
from tavc_cli.experiments.build import in_this_process, trial_specs
from tavc_cli.experiments.engine import run_trials
from tavc_cli.experiments.records import TrialRecord
from tavc_cli.io import atomic_path, owned_path, write_text_atomic
from tavc_cli.ownership import ANIMATION, RUN, Owned, config_differences, read
from tavc_cli.pictured import settings_record
from tavc_cli.settings import TavcConfig, to_yaml
from tavc_cli.sim.arena import Arena, arena_from_config
from tavc_cli.viz.figures import plt, write_figure
from tavc_cli.vocabulary import SOURCE

CIRCUIT_COLOURS = ["#1f77b4", "#ff7f0e", "#2ca02c", "#9467bd", "#8c564b", "#e377c2"]
MARKINGS = [(90.0, "#d62728"), (-90.0, "#2ca02c"), (180.0, "#e6c619")]  # left red, right green, rear yellow
_MARK_HALF_DEG = 35.0


def simulate_for_pictures(cfg: TavcConfig, duration_s: float, frame_every_s: float) -> tuple[TrialRecord, Arena]:
    """Run the config's first trial for `duration_s` (no warm-up) with a pose trace."""
    spec = trial_specs(cfg)[0]
    spec = replace(spec, duration_s=duration_s, warmup_s=0.0, start_s=0.0, deliveries=None, pose_every_s=frame_every_s,
                   breakdowns=tuple(b for b in spec.breakdowns if b.time_s < duration_s),
                   value_changes=tuple(v for v in spec.value_changes if v.time_s < duration_s))
    return run_trials([spec])[0], arena_from_config(spec.arena)


def _draw_arena(ax, arena: Arena) -> None:
    for x1, y1, x2, y2 in arena.walls:
        ax.plot([x1, x2], [y1, y2], color="black", lw=2)
    circuit_of = arena.target_circuit
    for k, (t, seg) in enumerate(zip(arena.targets, arena.target_segments, strict=True)):
        colour = CIRCUIT_COLOURS[circuit_of[k] % len(CIRCUIT_COLOURS)] if circuit_of[k] >= 0 else "grey"
        ax.plot([seg[0], seg[2]], [seg[1], seg[3]], color=colour, lw=7, solid_capstyle="butt")
        nx, ny = t.normal
        ax.annotate(f"{t.name}\n#{t.barcode}", (t.x + nx * 0.45, t.y + ny * 0.45), ha="center", va="center",
                    fontsize=7, color=colour, weight="bold" if t.kind == SOURCE else "normal")
    ax.set_xlim(-0.3, arena.width_m + 0.3)
    ax.set_ylim(-0.3, arena.height_m + 0.3)
    ax.set_aspect("equal")
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")


def trajectory_plot(rec: TrialRecord, arena: Arena, path: Path) -> Path:
    """Every robot's path over the whole trace, coloured by the circuit it was serving."""
    fig, ax = plt.subplots(figsize=(arena.width_m * 0.7 + 1.5, arena.height_m * 0.7 + 1))
    _draw_arena(ax, arena)
    poses, circuits = rec.poses, rec.pose_circuit
    for i in range(poses.shape[1]):
        for c in np.unique(circuits[:, i]):
            pts = np.where((circuits[:, i] == c)[:, None], poses[:, i, :2], np.nan)
            ax.plot(pts[:, 0], pts[:, 1], lw=0.6, alpha=0.5, color=CIRCUIT_COLOURS[int(c) % len(CIRCUIT_COLOURS)])
    ax.set_title(f"{arena.name}: {poses.shape[1]} robots, {rec.pose_t[-1] - rec.pose_t[0]:.0f} s "
                 "(colour = circuit served)", fontsize=9)
    fig.tight_layout()
    try:
        write_figure(fig, path, dpi=130)
    finally:
        plt.close(fig)
    return path


def _robot_artists(ax, radius: float):
    body = Circle((0, 0), radius, fc="white", ec="black", lw=1.2, zorder=3)
    marks = [Wedge((0, 0), radius, 0, 1, width=radius * 0.22, color=c, zorder=4) for _, c in MARKINGS]
    (heading,) = ax.plot([], [], color="black", lw=1.2, zorder=5)
    (trail,) = ax.plot([], [], lw=1.0, alpha=0.6, zorder=2)
    ax.add_patch(body)
    for m in marks:
        ax.add_patch(m)
    return body, marks, heading, trail


def animate_record(rec: TrialRecord, arena: Arena, radius: float, path: Path, fps: int,
                   trail_frames: int = 30, mp4: bool = False) -> list[Path]:
    """Render the pose trace to a GIF (and an MP4 beside it when asked and ffmpeg exists)."""
    fig, ax = plt.subplots(figsize=(arena.width_m * 0.6 + 1.2, arena.height_m * 0.6 + 1))
    _draw_arena(ax, arena)
    artists = [_robot_artists(ax, radius) for _ in range(rec.poses.shape[1])]
    title = ax.set_title("", fontsize=9)

    def draw(f: int):
        for i, (body, marks, heading, trail) in enumerate(artists):
            x, y, th = rec.poses[f, i]
            alive = bool(rec.pose_alive[f, i])
            colour = CIRCUIT_COLOURS[int(rec.pose_circuit[f, i]) % len(CIRCUIT_COLOURS)]
            body.center = (x, y)
            body.set_facecolor(colour if alive else "lightgrey")
            for (offset, _), m in zip(MARKINGS, marks, strict=True):
                m.set_center((x, y))
                m.set_theta1(math.degrees(th) + offset - _MARK_HALF_DEG)
                m.set_theta2(math.degrees(th) + offset + _MARK_HALF_DEG)
                m.set_visible(alive)
            heading.set_data([x, x + radius * 1.3 * math.cos(th)], [y, y + radius * 1.3 * math.sin(th)])
            lo = max(0, f - trail_frames)
            trail.set_data(rec.poses[lo:f + 1, i, 0], rec.poses[lo:f + 1, i, 1])
            trail.set_color(colour)
        title.set_text(f"t = {rec.pose_t[f]:7.1f} s")
        return []

    anim = animation.FuncAnimation(fig, draw, frames=len(rec.pose_t), blit=False)
    written = [path]
    try:
        _save_animation(anim, path, animation.PillowWriter(fps=fps), dpi=80)
        if mp4 and shutil.which("ffmpeg"):
            mp4_path = path.with_suffix(".mp4")
            _save_animation(anim, mp4_path, animation.FFMpegWriter(fps=fps), dpi=100)
            written.append(mp4_path)
    finally:
        plt.close(fig)
    return written


def _save_animation(anim, path: Path, writer, dpi: int) -> None:
    """``anim.save`` to `path`, through a temporary file renamed over it (`io.atomic_path`).

    A link, a pipe or a device at `path` is refused, never written through. The animation is
    drawn in a private folder first: the writers choose the format by the file's extension,
    which the temporary file beside `path` lacks.
    """
    with tempfile.TemporaryDirectory() as private:
        draft = Path(private) / path.name
        anim.save(draft, writer=writer, dpi=dpi)
        with atomic_path(path) as tmp:
            shutil.copyfile(draft, tmp)


MAX_FRAMES = 36_000  # ten simulated hours at a frame a second


def animate_run(cfg: TavcConfig, *, out: Path | None = None, duration_s: float = 300.0, fps: int = 10,
                mp4: bool = True, frame_every_s: float = 1.0) -> list[Path]:
    """Simulate the config's first trial and write animation.gif (+ .mp4), trajectories.png and the
    settings it pictures, animation.settings.yaml (`pictured`)."""
    shortest, longest = 2 * frame_every_s, MAX_FRAMES * frame_every_s
    if not shortest <= duration_s <= longest:  # NaN too
        raise TavcError(f"--duration-s: must be in [{shortest:g}, {longest:g}] s (two frames to {MAX_FRAMES:,}, "
                        f"a frame every {frame_every_s:g} s), got {duration_s}")
    if fps < 1:
        raise TavcError(f"--fps: must be >= 1, got {fps}")
    in_this_process(trial_specs(cfg)[:1], cfg.executor.confine, "tavc animate")  # before anything is written
    out = Path(out) if out is not None else Path(cfg.output_dir) / "animation.gif"
    if out.is_dir():
        raise TavcError(f"--out: {out} is a folder; give the file to write in it, e.g. --out {out / 'animation.gif'}")
    if out.suffix.lower() != ".gif":
        raise TavcError(f"--out: the animation is written as a .gif, got '{out.name}'")
    try:  # before simulating: a place that cannot be written is found now, not after the run
        out.parent.mkdir(parents=True, exist_ok=True)
        with tempfile.TemporaryFile(dir=out.parent):
            pass
    except OSError as exc:
        raise TavcError(f"--out: cannot write into {out.parent}: {exc.strerror}") from None
    owned = _owned_beside(out, mp4, cfg)
    if mp4 and not shutil.which("ffmpeg"):
        print("note: ffmpeg not found, so no MP4 is written (the GIF is)", file=sys.stderr)
    # what it pictures, which a run taking the folder compares with its own (`pictured`): an earlier
    # animation's record goes first and this one's is written last, so that one stopped half-way
    # leaves an animation without a record (its settings unknown), never one beside another's record
    owned.remove(settings_record(out).name)
    rec, arena = simulate_for_pictures(cfg, duration_s, frame_every_s)
    radius = float(cfg.robot.radius_m)
    written = animate_record(rec, arena, radius, out, fps, mp4=mp4)
    written.append(trajectory_plot(rec, arena, out.with_name("trajectories.png")))
    if out.with_suffix(".mp4") not in written:  # an earlier animation's MP4 would be taken for this one's
        owned.remove(out.with_suffix(".mp4").name)
    written.append(settings_record(out))
    owned.wrote(*(p.name for p in written))
    write_text_atomic(settings_record(out), to_yaml(cfg))
    return written


def _owned_beside(out: Path, mp4: bool, cfg: TavcConfig):
    """What tavc owns in the animation's folder (`ownership`): a run's, or one of animations
    (listed there from now on); refuses, before anything is simulated, a file the animation
    would replace that tavc did not write, and a run's folder whose run is of other settings
    than `cfg` (the animation beside it would be taken for that run's)."""
    owned = read(out.parent) or Owned(out.parent, ANIMATION)
    if owned.kind == RUN and (out.parent / "config.yaml").is_file():
        differ = config_differences(out.parent / "config.yaml", to_yaml(cfg))
        if differ:
            raise TavcError(f"--out: {out.parent} holds a run of another configuration ({'; '.join(differ)}), which "
                            "the animation would be taken for; choose another --out or output_dir")
    names = [out.name, *([out.with_suffix(".mp4").name] if mp4 else []), "trajectories.png", settings_record(out).name]
    for name in names:  # a link, a pipe or a device where a picture goes: refused now, not after simulating
        owned_path(out.parent, out.parent / name, what="--out")
    foreign = [name for name in names if (out.parent / name).exists() and not owned.owns(name)]
    if foreign:
        raise TavcError(f"--out: {out.parent / foreign[0]} was not written by tavc and the animation would replace it; "
                        "move it away or choose another --out")
    return owned
