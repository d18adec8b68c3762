"""`tavc animate` and `tavc bench` as a user calls them (a benchmark, not a timing test)."""

import json

from PIL import Image
from typer.testing import CliRunner

from tavc_cli.cli import app

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


def test_animate_rejects_a_non_gif_output_with_one_line(tmp_path):
    result = runner.invoke(app, ["animate", "--out", str(tmp_path / "run.mp4")])
    assert result.exit_code == 1
    assert result.output.strip().count("\n") == 0 and "--out" in result.output


def test_bench_json_reports_the_contract_fields():
    result = runner.invoke(app, ["bench", "--json", "--duration-s", "20", "--repeats", "1", "--batch", "2"])
    assert result.exit_code == 0, result.output
    data = json.loads(result.output)
    for key in ("scenario", "n_robots", "sim_seconds_per_wall_second", "physics_only_sim_seconds_per_wall_second",
                "overhead_ratio"):
        assert key in data
    assert data["scenario"] == "two_circuits" and data["n_robots"] == 6
    assert data["sim_seconds_per_wall_second"] > 0
    # the ratio is what its name says, computed from the two medians
    assert abs(data["overhead_ratio"] - data["physics_only_sim_seconds_per_wall_second"]
               / data["sim_seconds_per_wall_second"]) < 0.01
