"""The Python API (tavc_cli.api) as the README shows it, and its one-line errors."""

import re
from pathlib import Path

import pandas as pd
import pytest

from tavc_cli import api
from tavc_cli.errors import TavcError

README = Path(__file__).resolve().parents[1] / "README.md"


def _readme_example() -> str:
    text = README.read_text()
    match = re.search(r"<!-- api-example[^>]*-->\s*```python\n(.*?)```", text, re.S)
    assert match, "the README's API example is missing"
    return match.group(1)


def test_the_readme_example_runs(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(README.parent)  # it reads the committed results/ by relative path
    code = _readme_example().replace("/tmp/tavc-demo", str(tmp_path / "demo"))
    exec(compile(code, "README.md", "exec"), {})
    out = capsys.readouterr().out
    assert "state_time" in out and "claim_id" in out


# a folder's name may hold what Hydra's override grammar reads as its own (a sweep's comma, quotes,
# brackets, an equals sign, a backslash): the API's folders are paths, never overrides
ODD_NAME = "Dahl, Mataric's [runs]=\\b"


def test_results_read_back_what_the_run_wrote(tmp_path):
    folder = tmp_path / ODD_NAME
    run = api.run(["experiment=breakdown", "scale=smoke"], output_dir=folder)
    assert run.path == folder and run.config["output_dir"] == str(folder)
    written = pd.read_csv(folder / "state_time.csv")
    pd.testing.assert_frame_equal(run.state_time, written)
    deliveries = run.events("deliveries")
    # every trial of every controller contributes, and each row is one delivery of its record
    records = run.records()
    assert len(deliveries) == sum(len(r.table("deliveries")["t_s"]) for r in records)
    assert set(deliveries["controller"]) == {r.meta["controller"] for r in records}
    assert run.config["experiment_name"] == "breakdown"
    # reading again reuses every finished trial and gives the same tables
    again = api.run(["experiment=breakdown", "scale=smoke"], output_dir=folder)
    pd.testing.assert_frame_equal(again.state_time, run.state_time)


def test_errors_are_one_line(tmp_path):
    with pytest.raises(TavcError, match="not a results folder"):
        api.load(tmp_path)
    (tmp_path / "config.yaml").write_text("seed: 0\n")
    res = api.load(tmp_path)
    with pytest.raises(TavcError, match="no table 'state_time'"):
        _ = res.state_time
    with pytest.raises(TavcError, match="no trial records"):
        res.events("deliveries")
    with pytest.raises(TavcError, match="no kind 'crashes'"):
        res.events("crashes")
    with pytest.raises(TavcError, match="team.n_robots"):
        api.run(["team.n_robots=-1"], output_dir=tmp_path / "x")
    # arguments of the wrong kind: one line, not a TypeError from deep inside
    with pytest.raises(TavcError, match="^path: a folder's path, not None$"):
        api.load(None)
    with pytest.raises(TavcError, match="^overrides: a list of strings .*, not 'scale=smoke'$"):
        api.run("scale=smoke", output_dir=tmp_path / "x")  # would be read a character at a time
    with pytest.raises(TavcError, match=r"^overrides: a list of strings .*, not \[3\]$"):
        api.surrogate([3], output_dir=tmp_path / "x")
    with pytest.raises(TavcError, match=r"^reuse\['tavc'\]: a folder's path, not None$"):
        api.compare(["scale=smoke"], learners=["tavc"], experiments=["initial_distribution"],
                    results_dir=tmp_path / "x", reuse={"tavc": None})
    assert not (tmp_path / "x").exists()
    for call, line in [(lambda: api.run(["scale=smoke"], output_dir=5), "output_dir: a folder's path, not 5"),
                       (lambda: api.reproduce(["scale=smoke"], experiments=5), "experiments: a name or a list"),
                       (lambda: api.reproduce_summaries(["scale=smoke"], ladder="1,4"), "ladder: a list of multiples"),
                       (lambda: api.compare(["scale=smoke"], reuse=["a"]), "reuse: a mapping of learner to folder"),
                       (lambda: api.model(["scale=smoke"], config_dir=5), "config_dir: a folder's path, or a list"),
                       (lambda: api.model(["scale=smoke", f"output_dir={tmp_path / 'x'}"], echo=None),
                        "echo: a function that takes a line of text, such as print, not None"),
                       (lambda: api.calibrate(["scale=smoke", f"output_dir={tmp_path / 'x'}"], echo="print"),
                        "echo: a function that takes a line of text"),
                       *((lambda share=share: api.seen_tasks(tmp_path / "x", from_share=share),
                          f"from_share: a share of each trial from 0 up to but not including 1, such as 0.5, "
                          f"not {share!r}")
                         for share in ("a", 2, -1, float("nan"), True))]:
        with pytest.raises(TavcError, match=f"^{re.escape(line)}"):
            call()
    # every scenario by default, each known: the unknown learner is what is refused, before any run
    with pytest.raises(TavcError, match="nobody"):
        api.compare(["scale=smoke"], learners=["tavc", "nobody"], results_dir=tmp_path / "x")
    assert not (tmp_path / "x").exists()
    # overrides given as any iterable of strings are all taken, a generator's too
    from tavc_cli.arguments import overrides_of

    assert overrides_of(o for o in ["scale=smoke", "seed=3"]) == ["scale=smoke", "seed=3"]


def test_an_empty_folder_or_one_holding_an_interpolation_is_refused_before_anything_is_written(tmp_path,
                                                                                                 monkeypatch):
    """``Path("")`` is the working folder, and a ``${`` in a folder's name would be read as an
    interpolation (``${oc.env:HOME}`` put the run under the home folder): both are one line."""
    monkeypatch.chdir(tmp_path)
    smoke = ["experiment=initial_distribution", "scale=smoke"]
    with pytest.raises(TavcError, match="^output_dir: must not be empty$"):
        api.run(smoke, output_dir="")
    with pytest.raises(TavcError, match="^--results: must not be empty$"):
        api.reproduce(["scale=smoke"], experiments=["initial_distribution"], results_dir="")
    with pytest.raises(TavcError, match="^--results: must not be empty$"):
        api.compare(["scale=smoke"], learners=["tavc"], experiments=["initial_distribution"], results_dir="")
    with pytest.raises(TavcError, match=r"holds '\$\{', which tavc's settings read as an interpolation"):
        api.surrogate(smoke, output_dir=tmp_path / "x${oc.env:HOME}")
    with pytest.raises(TavcError, match=r"^--results: .* holds '\$\{'"):
        api.reproduce_summaries(["scale=smoke"], experiments=[], results_dir=tmp_path / "x${oc.env:HOME}", ladder=[1])
    assert list(tmp_path.iterdir()) == []


def test_reproduce_opens_each_experiments_results(tmp_path):
    results = tmp_path / ODD_NAME
    together = api.reproduce(["scale=smoke", "trials=1", "baselines=[]"],
                             experiments=["breakdown_no_vacancy", "initial_distribution"], results_dir=results)
    assert sorted(together) == ["breakdown_no_vacancy", "initial_distribution"]
    for name, res in together.items():
        assert res.path == results / name and res.config["experiment_name"] == name
        assert len(res.records()) == 1
    with pytest.raises(TavcError, match="no experiment 'nope'"):
        api.reproduce(["scale=smoke"], experiments=["nope"], results_dir=tmp_path / "x")
    with pytest.raises(TavcError, match=r"^--experiments: name each experiment once \(breakdown, breakdown\)$"):
        api.reproduce(["scale=smoke"], experiments=["breakdown", "breakdown"], results_dir=tmp_path / "x")
    with pytest.raises(TavcError, match=r"^--experiments: name each scenario once \(breakdown, breakdown\)$"):
        api.compare(["scale=smoke"], experiments=["breakdown", "breakdown"], results_dir=tmp_path / "x")
    assert not (tmp_path / "x").exists()


SMOKE_SWEEP = ["experiment=initial_distribution", "scale=smoke", "trials=1", "baselines=[]", "duration_s=120",
               "convergence_s=20"]


def test_config_dir_gives_the_api_a_folder_of_the_users_own(tmp_path, monkeypatch):
    """`config_dir=` is `--config-dir`: an experiment from the user's folder runs, and the process's
    config folders are as they were afterwards; a folder that is not one is one line."""
    from tavc_cli.learning.plugins import CONFIG_DIRS_ENV

    monkeypatch.delenv(CONFIG_DIRS_ENV, raising=False)
    mine = tmp_path / "mine"
    (mine / "experiment").mkdir(parents=True)
    (mine / "experiment" / "tiny.yaml").write_text(
        "# @package _global_\ndefaults:\n  - override /learner: tavc_egreedy\nexperiment_name: tiny\n"
        "team:\n  n_robots: 2\n")
    with pytest.raises(TavcError, match="^experiment=tiny: no such option"):  # not without its folder
        api.run(["experiment=tiny", "scale=smoke"], output_dir=tmp_path / "no")
    run = api.run(["experiment=tiny", "scale=smoke", "trials=1", "duration_s=60", "convergence_s=10"],
                  output_dir=tmp_path / "tiny", config_dir=mine)
    assert run.config["experiment_name"] == "tiny" and run.config["team"]["n_robots"] == 2
    assert CONFIG_DIRS_ENV not in __import__("os").environ
    with pytest.raises(TavcError, match=r"^config_dir: .*nowhere is not a folder$"):
        api.run(["scale=smoke"], config_dir=tmp_path / "nowhere")
    with pytest.raises(TavcError, match=r"^config_dir: an empty folder name; give the folder of your configs"):
        api.run(["scale=smoke"], config_dir="")  # not the working folder taken silently


def test_a_sweep_opens_as_a_sweep_with_its_jobs(tmp_path):
    from typer.testing import CliRunner

    from tavc_cli.cli import app

    out = tmp_path / "eps\\x"  # a backslash in the sweep's folder: its jobs go below it, nowhere else
    result = CliRunner().invoke(app, ["run", "-m", *SMOKE_SWEEP, "learner.epsilon=0.05,0.3", f"output_dir='{out}'"])
    assert result.exit_code == 0, result.output
    assert sorted(p.name for p in tmp_path.iterdir()) == [out.name]
    with pytest.raises(TavcError, match="a sweep's folder .* api.load_sweep"):
        api.load(out)
    sweep = api.load_sweep(out)
    assert list(sweep.jobs) == ["0_learner.epsilon=0.05", "1_learner.epsilon=0.3"]
    assert sorted(sweep.table["learner.epsilon"].unique()) == [0.05, 0.3]
    job = sweep.jobs["1_learner.epsilon=0.3"]
    assert job.config["learner"]["epsilon"] == 0.3
    with pytest.raises(TavcError, match="no sweep.csv"):
        api.load_sweep(out / "0_learner.epsilon=0.05")
    # a job run again since (another seed, into its folder): sweep.csv no longer holds its numbers
    again = CliRunner().invoke(app, ["run", *SMOKE_SWEEP, "learner.epsilon=0.3", "seed=5", "overwrite=true",
                                     f"output_dir='{out / '1_learner.epsilon=0.3'}'"])
    assert again.exit_code == 0, again.output
    with pytest.raises(TavcError, match=r"sweep.csv: not what its jobs give now \(one of them run again since"):
        _ = api.load_sweep(out).table


def test_a_sweep_over_output_dir_opens_with_its_jobs_where_it_put_them(tmp_path, monkeypatch):
    """Each job of a sweep over output_dir lies in a folder of its own; the sweep's table, written
    beside the first, is checked against every job where it lies."""
    from typer.testing import CliRunner

    from tavc_cli.cli import app

    monkeypatch.chdir(tmp_path)
    result = CliRunner().invoke(app, ["run", "-m", *SMOKE_SWEEP, "output_dir=a,b"])
    assert result.exit_code == 0, result.output
    monkeypatch.chdir(tmp_path / "a")  # read from another folder: the jobs are found all the same
    sweep = api.load_sweep(tmp_path / "a")
    assert sorted(sweep.table["job"].unique()) == [0, 1] and len(sweep.table) == 2 * len(sweep.table.query("job == 0"))
    assert {name: job.path for name, job in sweep.jobs.items()} == {
        "0_output_dir=a": tmp_path / "a" / "0_output_dir=a", "1_output_dir=b": tmp_path / "b" / "1_output_dir=b"}


def test_results_say_in_their_data_whether_they_are_a_verdict(tmp_path):
    quick = api.run([*SMOKE_SWEEP], output_dir=tmp_path / "quick")
    assert quick.not_a_verdict.startswith("not a verdict: scale=smoke (")
    assert set(quick.claims["not_a_verdict"]) == {quick.not_a_verdict}
    committed = api.load(README.parent / "results" / "initial_distribution")
    assert committed.not_a_verdict == "" and set(committed.claims["not_a_verdict"]) == {""}


def test_a_learner_from_outside_tavc_replaces_an_experiments_own_from_the_overrides_alone(tmp_path):
    """`learner=plugin` with a name and a class: the experiment's learner (and its parameters) is
    replaced, the class's keyword arguments given as params; the run's trials are the plugin's."""
    (tmp_path / "mine.py").write_text(
        "class Mine:\n"
        "    def __init__(self, n_robots, n_circuits, rng, circuit=0):\n"
        "        self.circuit = circuit\n"
        "    def choose(self, robot, state):\n"
        "        return self.circuit\n"
        "    def learn(self, robot, state, action, reward, next_state):\n"
        "        pass\n")
    run = api.run([*SMOKE_SWEEP, "learner=plugin", "learner.name=mine", f"learner.target={tmp_path / 'mine.py'}:Mine",
                   "+learner.params.circuit=1"], output_dir=tmp_path / "run")
    assert run.config["learner"] == {"name": "mine", "target": f"{tmp_path / 'mine.py'}:Mine",
                                     "params": {"circuit": 1}}
    choices = run.events("choices")
    assert set(choices["controller"]) == {"mine"} and set(choices["circuit"]) == {1}  # every choice its own
