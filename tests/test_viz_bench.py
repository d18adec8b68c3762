"""`tavc animate` and `tavc bench` as a user calls them (a benchmark, not a timing test)."""

import json
import os
import shutil

import pytest
from PIL import Image
from typer.testing import CliRunner

from tavc_cli import config
from tavc_cli.cli import app
from tavc_cli.settings import from_yaml

runner = CliRunner()


def test_animate_writes_a_gif_with_one_frame_per_second_and_a_trajectory_plot(tmp_path):
    out = tmp_path / "run.gif"
    result = runner.invoke(app, ["animate", "team.n_robots=3", "--duration-s", "12", "--fps", "5", "--no-mp4",
                                 "--out", str(out)])
    assert result.exit_code == 0, result.output
    # frames every simulated second from t = 0: 12 s of poses -> 12 frames
    with Image.open(out) as gif:
        assert gif.n_frames == 12
    assert (tmp_path / "trajectories.png").stat().st_size > 10_000
    assert str(out) in result.output


def test_animate_never_replaces_a_file_it_did_not_write(tmp_path):
    """Its own animation is drawn again; a trajectories.png of somebody else's beside it is
    refused before anything is simulated."""
    args = ["animate", "team.n_robots=2", "--duration-s", "4", "--no-mp4", "--out", str(tmp_path / "a" / "run.gif")]
    assert runner.invoke(app, args).exit_code == 0
    # an earlier animation's MP4 (written where ffmpeg was): this one writes none, so that one goes
    folder = tmp_path / "a"
    (folder / "run.mp4").write_bytes(b"an earlier animation's")
    record = json.loads((folder / ".tavc.json").read_text())
    (folder / ".tavc.json").write_text(json.dumps({**record, "files": [*record["files"], "run.mp4"]}))
    assert runner.invoke(app, args).exit_code == 0  # tavc's own files, listed in the folder's .tavc.json
    ours = ["run.gif", "run.settings.yaml", "trajectories.png"]
    assert sorted(p.name for p in folder.iterdir()) == [".tavc.json", *ours]
    assert json.loads((folder / ".tavc.json").read_text())["files"] == ours
    assert from_yaml(folder / "run.settings.yaml").team.n_robots == 2  # what it pictures
    (tmp_path / "b").mkdir()
    (tmp_path / "b" / "trajectories.png").write_bytes(b"mine")
    result = runner.invoke(app, [*args[:-1], str(tmp_path / "b" / "run.gif")])
    assert result.exit_code == 1
    assert result.output.strip() == (f"error: --out: {tmp_path / 'b' / 'trajectories.png'} was not written by tavc and "
                                     "the animation would replace it; move it away or choose another --out")
    assert (tmp_path / "b" / "trajectories.png").read_bytes() == b"mine" and not (tmp_path / "b" / "run.gif").exists()


def test_animate_into_a_runs_folder_only_beside_a_run_of_its_own_settings(tmp_path):
    """An animation in a run's folder would be taken for that run's: beside a run of other
    settings it is refused in one line before anything is simulated; beside one of its own it is
    drawn."""
    run = tmp_path / "run"
    run.mkdir()
    (run / ".tavc.json").write_text('{"tavc": "run", "files": ["config.yaml"]}')  # a run's folder, as tavc marks it
    (run / "config.yaml").write_text(config.to_yaml(config.load_config(["team.n_robots=3"])))
    args = ["animate", "--duration-s", "4", "--no-mp4", "--out", str(run / "animation.gif")]
    result = runner.invoke(app, [*args, "team.n_robots=2"])
    assert result.exit_code == 1 and result.output.count("\n") == 1
    assert result.output.startswith(f"error: --out: {run} holds a run of another configuration (")
    assert "team.n_robots: 3 -> 2), which the animation would be taken for" in result.output
    assert sorted(p.name for p in run.iterdir()) == [".tavc.json", "config.yaml"]
    result = runner.invoke(app, [*args, "team.n_robots=3"])
    assert result.exit_code == 0, result.output
    assert (run / "animation.gif").is_file()
    # a run of other settings replacing that one (overwrite=true) takes its animation with it
    result = runner.invoke(app, ["run", "team.n_robots=2", "scale=smoke", "overwrite=true", f"output_dir={run}"])
    assert result.exit_code == 0, result.output
    assert not (run / "animation.gif").exists() and not (run / "trajectories.png").exists()
    assert "animation.gif" not in json.loads((run / ".tavc.json").read_text())["files"]


def test_a_run_into_the_folder_of_an_animation_of_other_settings_is_refused_or_replaces_it(tmp_path):
    """`tavc animate` first writes into the run's folder: a run of the settings it pictures adopts
    it, animation kept; a run of other settings is refused in one line, and with overwrite=true
    the animation goes with the folder's other pictures before the run writes anything."""
    folder = tmp_path / "run"
    animate = ["animate", "scale=smoke", "seed=1", "--duration-s", "4", "--no-mp4", f"output_dir={folder}"]
    run = ["run", "scale=smoke", f"output_dir={folder}"]
    assert runner.invoke(app, animate).exit_code == 0
    pictures = {"animation.gif", "animation.settings.yaml", "trajectories.png"}
    refused = runner.invoke(app, [*run, "seed=2"])
    assert refused.exit_code == 1
    assert refused.output == (f"error: output_dir: {folder} holds an animation of another configuration "
                              "(seed: 1 -> 2); add overwrite=true to replace it, or choose another "
                              "output_dir\n")
    assert {p.name for p in folder.iterdir()} == {".tavc.json", *pictures}
    adopted = runner.invoke(app, [*run, "seed=1"])
    assert adopted.exit_code == 0, adopted.output
    assert pictures <= {p.name for p in folder.iterdir()} and (folder / "provenance.json").is_file()
    shutil.rmtree(folder)
    assert runner.invoke(app, animate).exit_code == 0
    replaced = runner.invoke(app, [*run, "seed=2", "overwrite=true"])
    assert replaced.exit_code == 0, replaced.output
    assert not pictures & {p.name for p in folder.iterdir()} and (folder / "provenance.json").is_file()
    assert not pictures & set(json.loads((folder / ".tavc.json").read_text())["files"])


def test_an_animation_whose_settings_are_not_known_or_are_read_through_a_link_is_refused(tmp_path):
    """An animation written as `.GIF` is compared as one written as `.gif`; one whose record is
    gone (`tavc animate` stopped before writing it last) may picture any settings, and is refused
    as a run whose config.yaml is missing is; a record that is a link is never read."""
    folder = tmp_path / "run"
    animate = ["animate", "scale=smoke", "seed=1", "--duration-s", "4", "--no-mp4", "--out", str(folder / "a.GIF")]
    assert runner.invoke(app, animate).exit_code == 0
    assert (folder / "a.settings.yaml").is_file()
    run = ["run", "scale=smoke", f"output_dir={folder}"]
    refused = runner.invoke(app, [*run, "seed=2"])
    assert refused.exit_code == 1 and "holds an animation of another configuration (seed: 1 -> 2)" in refused.output
    (folder / "a.settings.yaml").unlink()
    refused = runner.invoke(app, [*run, "seed=1"])
    assert refused.output == (f"error: output_dir: {folder} holds an animation whose a.settings.yaml is missing, so "
                              "it may be of another configuration; add overwrite=true to replace it, or choose "
                              "another output_dir\n")
    elsewhere = tmp_path / "elsewhere.yaml"
    elsewhere.write_text("seed: 2\n")
    (folder / "a.settings.yaml").symlink_to(elsewhere)
    refused = runner.invoke(app, [*run, "seed=1"])
    assert refused.exit_code == 1 and refused.output.count("\n") == 1 and "a.settings.yaml" in refused.output
    assert "seed: 2" not in refused.output
    assert not (folder / "config.yaml").exists() and elsewhere.read_text() == "seed: 2\n"


def test_animate_rejects_a_non_gif_output_with_one_line(tmp_path):
    result = runner.invoke(app, ["animate", "--out", str(tmp_path / "run.mp4")])
    assert result.exit_code == 1
    assert result.output.strip().count("\n") == 0 and "--out" in result.output


def test_bench_json_reports_the_contract_fields():
    result = runner.invoke(app, ["bench", "--json", "--duration-s", "20", "--repeats", "1", "--batch", "2",
                                 "--no-scaling"])
    assert result.exit_code == 0, result.output
    data = json.loads(result.output)
    for key in ("scenario", "n_robots", "sim_seconds_per_wall_second", "physics_only_sim_seconds_per_wall_second",
                "overhead_ratio"):
        assert key in data
    assert data["scenario"] == "two_circuits" and data["n_robots"] == 6
    assert data["sim_seconds_per_wall_second"] > 0
    # the ratio is what its name says: physics-only over full loop, here of the one pair of runs
    assert abs(data["overhead_ratio"] - data["physics_only_sim_seconds_per_wall_second"]
               / data["sim_seconds_per_wall_second"]) < 0.01


def test_bench_overhead_is_the_median_of_back_to_back_pairs(monkeypatch):
    from tavc_cli import bench, config

    # warm-up, then three pairs: full loop 100, 50, 90 and physics only 200, 150, 171 simulated s per wall s.
    # Pair by pair the physics is 2.0, 3.0 and 1.9 times faster: median 2.0 (the medians' ratio would say 1.9)
    full, phys = iter([1.0, 100.0, 50.0, 90.0]), iter([200.0, 150.0, 171.0])
    monkeypatch.setattr(bench, "_full_loop", lambda specs: next(full))
    monkeypatch.setattr(bench, "_physics_only", lambda specs: next(phys))
    result = bench.run_bench(lambda n, d: config.settings(config.load_config(bench.bench_overrides("two_circuits", n, d,
                                                                                                   None))),
                             duration_s=10.0, repeats=3, batch=2, scaling=False)
    assert result["sim_seconds_per_wall_second"] == 90.0 and result["physics_only_sim_seconds_per_wall_second"] == 171.0
    assert result["overhead_ratio"] == 2.0


@pytest.mark.slow
def test_bench_scaling_covers_robot_counts_and_processes():
    result = runner.invoke(app, ["bench", "--json", "--duration-s", "10", "--repeats", "1", "--batch", "1"])
    assert result.exit_code == 0, result.output
    data = json.loads(result.output)
    rows = data["scaling_robots"]
    assert [r["n_robots"] for r in rows] == [2, 6, 12, 24]
    # robot-seconds are simulated seconds times robots in the arena
    for r in rows:
        assert abs(r["robot_seconds_per_wall_second"] - r["sim_seconds_per_wall_second"] * r["n_robots"]) <= 0.1 * r[
            "n_robots"]
    procs = data["scaling_processes"]
    assert [p["processes"] for p in procs] == sorted({1, 2, os.cpu_count() or 1})
    for p in procs:
        assert p["sim_seconds_per_wall_second"] > 0
        assert abs(p["per_process"] * p["processes"] - p["sim_seconds_per_wall_second"]) <= 0.1 * p["processes"]


def test_bench_against_an_unknown_simulator_is_one_line():
    result = runner.invoke(app, ["bench", "--against", "webots"])
    assert result.exit_code == 1
    assert result.output.strip().count("\n") == 0 and "--against" in result.output


def test_bench_against_enki_without_its_source_says_so_in_one_line(monkeypatch, tmp_path):
    from tavc_cli import bench_enki

    monkeypatch.setattr(bench_enki, "SOURCE", tmp_path / "missing.cpp")
    result = runner.invoke(app, ["bench", "--against", "enki", "--duration-s", "5", "--repeats", "1"])
    assert result.exit_code == 1
    assert result.output.strip().count("\n") == 0 and "Enki" in result.output


def test_profile_names_numbas_functions_for_perf():
    """A kernel compiled here is written to perf's map of this process under its Python name,
    at the address the compiled code really has."""
    import numba

    from tavc_cli.profiling import readable, write_perf_map

    @numba.njit
    def tavc_probe_kernel(x):
        return 2.0 * x

    tavc_probe_kernel(1.0)
    cres = next(iter(tavc_probe_kernel.overloads.values()))
    path, n_named = write_perf_map([tavc_probe_kernel], pid=os.getpid())
    try:
        lines = path.read_text().splitlines()
    finally:
        path.unlink()
    assert n_named >= 1 and len(lines) == n_named
    entry = cres.library.get_pointer_to_function(cres.fndesc.mangled_name)
    by_address = {int(line.split()[0], 16): line.split(maxsplit=2)[2] for line in lines}
    assert by_address[entry].endswith("tavc_probe_kernel")
    mangled = "_ZN8tavc_cli3sim7sensors10cast_laserB2v7B46c8tJTIeFIjxE5Array"
    assert readable(mangled) == "tavc_cli.sim.sensors.cast_laser"
    assert readable("__sincos_fma") == "__sincos_fma"


def test_profile_groups_perfs_rows_by_what_they_do():
    from tavc_cli.profiling import group_of, parse_report

    text = ("# comment\n"
            "    25.50%,[JIT] tid 9332,[.] tavc_cli.sim.sensors.cast_laser\n"
            "     9.65%,libm.so.6,[.] __sincos_fma\n"
            "     1.71%,_chipmunk.abi3.so,[.] cpBodyGetType\n"
            "     5.99%,_chipmunk.abi3.so,[.] applyImpulse\n"
            "     3.66%,[JIT] tid 9332,[.] tavc_cli.behaviours.motion.steer_to\n"
            "     1.00%,libpython3.11.so.1.0,[.] _PyEval_EvalFrameDefault\n")
    rows = parse_report(text)
    assert rows[0] == (25.5, "compiled kernel", "tavc_cli.sim.sensors.cast_laser")
    assert [group_of(dso, sym) for _, dso, sym in rows] == [
        "laser", "C maths library (sin, cos, atan2, fmod)", "reading and writing the bodies", "Chipmunk (stepping)",
        "behaviours", "Python, numpy and random draws"]


def test_profile_without_perf_is_one_line(monkeypatch):
    import shutil

    monkeypatch.setattr(shutil, "which", lambda name: None)
    result = CliRunner().invoke(app, ["bench", "--profile", "--duration-s", "10"])
    assert result.exit_code != 0
    assert result.output.strip().splitlines() == [
        "error: --profile: needs Linux's perf on the PATH (Debian: apt-get install linux-perf)"]


@pytest.mark.slow
@pytest.mark.skipif(shutil.which("perf") is None, reason="needs Linux's perf")
def test_profile_of_a_real_batch_names_the_kernels_that_take_the_time():
    import subprocess
    import sys

    # a process of its own, as `tavc bench --profile` always is: one whose kernels are not compiled yet
    run = subprocess.run([sys.executable, "-m", "tavc_cli", "bench", "--profile", "--json", "--batch", "2"],
                         capture_output=True, text=True, timeout=600, check=False)
    if run.returncode != 0 and ("perf recorded nothing" in run.stdout + run.stderr
                                or "report was empty" in run.stdout + run.stderr):
        pytest.skip("perf is not allowed to record here")
    assert run.returncode == 0, run.stdout + run.stderr
    result = json.loads(run.stdout)
    assert result["functions_named"] >= 10
    assert sum(result["groups_pct"].values()) == pytest.approx(100.0, abs=0.5)
    assert result["groups_pct"].get("laser", 0.0) > 5.0
    assert any(row["function"] == "tavc_cli.sim.sensors.cast_laser" for row in result["top"])


def test_profile_beside_enki_is_one_line():
    result = CliRunner().invoke(app, ["bench", "--profile", "--against", "enki"])
    assert result.exit_code != 0
    assert result.output.strip().splitlines() == ["error: --profile: profiles tavc alone; leave out --against"]
