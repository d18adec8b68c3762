"""Learners beside the built-in ones: the simulator runs a policy's own code unless it is exactly
one of the built-in policies the compiled paths serve."""

from __future__ import annotations

import json
import shutil

import numpy as np
import pytest
from typer.testing import CliRunner

from tavc_cli import api, config
from tavc_cli.cli import app
from tavc_cli.errors import TavcError
from tavc_cli.experiments.build import trial_specs
from tavc_cli.experiments.engine import run_trials
from tavc_cli.io import file_digest
from tavc_cli.learning import policies
from tavc_cli.learning.compiled import POLICY_EGREEDY, POLICY_PYTHON, policy_kind
from tavc_cli.learning.plugins import CONFIG_DIRS_ENV
from tavc_cli.learning.policies import TavcPolicy
from tavc_cli.run_checks import check_run


class AlwaysZero(TavcPolicy):
    """A TAVC learner that always serves circuit 0 (its Q-tables are there, and ignored)."""

    def choose(self, robot: int, state: int) -> int:
        return 0


def test_a_subclass_of_a_built_in_policy_runs_its_own_code(monkeypatch):
    rng = np.random.default_rng(0)
    assert policy_kind(TavcPolicy(2, 2, alpha=0.1, gamma=0.9, selection="egreedy", epsilon=0.1, tau=1.0,
                                  q_init=(0.0, 0.0), rng=rng)) == POLICY_EGREEDY
    always = AlwaysZero(2, 2, alpha=0.1, gamma=0.9, selection="egreedy", epsilon=0.1, tau=1.0, q_init=(0.0, 0.0),
                        rng=rng)
    assert policy_kind(always) == POLICY_PYTHON

    # the registry builds tavc_egreedy from the class its entry names, looked up when a trial starts
    monkeypatch.setattr(policies, "TavcPolicy", AlwaysZero)
    cfg = config.settings(config.load_config(["experiment=initial_distribution", "scale=smoke", "trials=1",
                                              "baselines=[]", "duration_s=600"]))
    record = run_trials(trial_specs(cfg))[0]
    chosen = record.table("choices")["circuit"]
    assert len(chosen) > 6 and set(chosen.tolist()) == {0}  # every choice its own: circuit 0


LEARNER_FILE = '''
import numpy as np
import pytest


class Stubborn:
    """Each robot serves the circuit it was given at the start, for ever; `favourite` is that
    circuit for every robot, or None for a random one each."""

    def __init__(self, n_robots, n_circuits, rng, favourite=None):
        self.n_states = n_circuits
        self.given = [favourite if favourite is not None else int(rng.integers(n_circuits)) for _ in range(n_robots)]
        self.learned = 0

    def choose(self, robot, state):
        return self.given[robot]

    def learn(self, robot, state, action, reward, next_state):
        self.learned += 1
'''


def _plugin_folder(tmp_path):
    folder = tmp_path / "mine"
    (folder / "learner").mkdir(parents=True)
    (folder / "stubborn.py").write_text(LEARNER_FILE)
    (folder / "learner" / "stubborn.yaml").write_text(
        "name: stubborn\ntarget: stubborn.py:Stubborn\nparams:\n  favourite: 1\n")
    return folder


def _stubborn_run(tmp_path, monkeypatch, baselines: str):
    """One smoke trial of `Stubborn` from a folder of one's own (`--config-dir`), into tmp_path/run,
    beside `baselines`; returns the learner's folder and the run's."""
    folder = _plugin_folder(tmp_path)
    monkeypatch.setenv(CONFIG_DIRS_ENV, "")  # restored after the test, whatever the command sets
    monkeypatch.chdir(tmp_path)
    out = tmp_path / "run"
    result = CliRunner().invoke(app, ["--config-dir", str(folder), "run", "experiment=initial_distribution",
                                      "scale=smoke", "learner=stubborn", f"baselines={baselines}", "trials=1",
                                      f"output_dir={out}", "--no-progress"])
    assert result.exit_code == 0, result.output
    return folder, out


def test_a_learner_from_a_folder_of_ones_own_runs_with_one_yaml(tmp_path, monkeypatch):
    _, out = _stubborn_run(tmp_path, monkeypatch, "[random]")
    run = api.load(out)
    choices = run.events("choices")
    mine = choices[choices["controller"] == "stubborn"]
    assert len(mine) > 6 and set(mine["circuit"]) == {1}  # favourite: 1, from the YAML
    states = run.state_time
    assert set(states["controller"]) >= {"stubborn", "random"}
    stubborn = states[states["controller"] == "stubborn"].set_index("state")["mean_pct"]
    assert stubborn["0:6"] == 100.0  # circuit 1 is the low-value one: every robot there, state 0:6


def test_a_learners_settings_are_checked_against_its_signature(tmp_path, monkeypatch):
    from tavc_cli.errors import TavcError
    from tavc_cli.learning.plugins import CONFIG_DIRS_ENV

    folder = _plugin_folder(tmp_path)
    monkeypatch.setenv(CONFIG_DIRS_ENV, str(folder))
    base = ["experiment=initial_distribution", "scale=smoke", "learner=stubborn"]
    assert config.load_config(base).learner.params["favourite"] == 1
    import pytest

    with pytest.raises(TavcError, match=r"learner.params.favorite: Stubborn takes no parameter 'favorite' "
                                        r"\(it takes: favourite\)"):
        config.load_config([*base, "+learner.params.favorite=0"])
    with pytest.raises(TavcError, match="learner.name: 'tavc' is a built-in"):
        config.load_config([*base, "learner.name=tavc"])
    with pytest.raises(TavcError, match="learner.target: no file nowhere.py"):
        config.load_config([*base, "learner.target=nowhere.py:Stubborn"])
    with pytest.raises(TavcError, match="names no class"):
        config.load_config([*base, "learner.target=stubborn.py:Nothing"])
    with pytest.raises(TavcError, match="^learner.target: /etc/passwd is not a Python file: give path/to/file"):
        config.load_config([*base, "learner.target=/etc/passwd:Stubborn"])


def test_a_learners_seed_code_comes_from_its_name():
    import zlib

    from tavc_cli.learning.registry import seed_code

    assert seed_code("tavc") == 0 and seed_code("random") == 1
    assert seed_code("stubborn") == 1000 + zlib.crc32(b"stubborn") % 1_000_000  # by hand, the same everywhere


def _docs_learner(tmp_path, monkeypatch) -> str:
    """docs/plugins.md's two files written where the page puts them, in a temporary working
    folder with no config folders of anyone else's; returns the page."""
    import re
    from pathlib import Path

    from tavc_cli.learning.plugins import CONFIG_DIRS_ENV

    page = (Path(__file__).resolve().parent.parent / "docs" / "plugins.md").read_text()
    python = re.search(r"`mine/greedy.py`:\n\n```python\n(.*?)```", page, re.S).group(1)
    yaml_text = re.search(r"`mine/learner/decaying.yaml`:\n\n```yaml\n(.*?)```", page, re.S).group(1)
    (tmp_path / "mine" / "learner").mkdir(parents=True)
    (tmp_path / "mine" / "greedy.py").write_text(python)
    (tmp_path / "mine" / "learner" / "decaying.yaml").write_text(yaml_text)
    monkeypatch.setenv(CONFIG_DIRS_ENV, "")
    monkeypatch.chdir(tmp_path)
    return page


def test_the_docs_example_learner_runs_as_the_page_shows(tmp_path, monkeypatch):
    """docs/plugins.md's two files, written where the page puts them, run through tavc from a
    temporary folder."""

    from typer.testing import CliRunner

    from tavc_cli.cli import app

    _docs_learner(tmp_path, monkeypatch)
    result = CliRunner().invoke(app, ["--config-dir", "mine", "run", "experiment=initial_distribution",
                                      "learner=decaying", "baselines=[random]", "scale=smoke", "--no-progress"])
    assert result.exit_code == 0, result.output
    assert (tmp_path / "runs" / "smoke" / "initial_distribution" / "state_time.csv").is_file()
    bad = CliRunner().invoke(app, ["--config-dir", "mine", "run", "experiment=initial_distribution",
                                   "learner=decaying", "+learner.params.decai=0.9", "scale=smoke"])
    assert bad.exit_code == 1
    assert "learner.params.decai: DecayingGreedy takes no parameter 'decai' (it takes: alpha, epsilon, decay)" \
        in bad.output


@pytest.mark.slow
def test_the_docs_example_learner_runs_through_reproduce_and_compare(tmp_path, monkeypatch):
    """The page's learner, from a temporary folder, through `tavc reproduce` and `tavc compare` as
    the page shows them (at scale=smoke, two scenarios)."""
    from pathlib import Path

    import pandas as pd
    from typer.testing import CliRunner

    from tavc_cli.cli import app

    page = _docs_learner(tmp_path, monkeypatch)
    for line in ("tavc --config-dir mine reproduce learner=decaying 'baselines=[random]' scale=quick",
                 "tavc --config-dir mine compare --learners tavc,random,model,informed,decaying scale=quick"):
        assert line in page
    # the committed model file the model's controllers read, where a checkout has it
    model = Path(__file__).resolve().parent.parent / "results/initial_distribution/model/model.json"
    runner = CliRunner()
    result = runner.invoke(app, ["--config-dir", "mine", "reproduce", "learner=decaying", "baselines=[random]",
                                 "scale=smoke", "--experiments", "initial_distribution,breakdown", "--no-progress"])
    assert result.exit_code == 0, result.output
    claims = pd.read_csv(tmp_path / "runs/smoke/breakdown/claims.csv")
    assert claims["detail"].str.contains("decaying above random").any()
    result = runner.invoke(app, ["--config-dir", "mine", "compare", "--learners", "tavc,random,model,informed,decaying",
                                 "--experiments", "initial_distribution,breakdown", "scale=smoke",
                                 f"learner.model_file={model}", "--no-progress"])
    assert result.exit_code == 0, result.output
    table = pd.read_csv(tmp_path / "runs/smoke/compare/compare.csv")
    assert set(table["controller"]) == {"tavc", "random", "model", "informed", "decaying"}
    mine = table[table["controller"] == "decaying"]
    assert mine["p_vs_tavc"].notna().all() and mine["p_vs_random"].notna().all()
    # its runs are reused as they are while its code is, and refused once the code changed
    reuse = ["--config-dir", "mine", "compare", "--learners", "random,decaying", "--experiments",
             "initial_distribution", "scale=smoke", f"learner.model_file={model}", "--reuse",
             "decaying=runs/smoke/compare/runs/decaying", "--results", "again", "--no-progress"]
    result = runner.invoke(app, reuse)
    assert result.exit_code == 0, result.output
    with (tmp_path / "mine" / "greedy.py").open("a") as code:
        code.write("# changed\n")
    result = runner.invoke(app, [*reuse[:-2], "again2", "--no-progress"])
    assert result.exit_code == 1 and "computed by other code of the learner" in result.output, result.output


# --- learners from the literature -----------------------------------------------------------------

def test_wolf_phc_one_step_by_hand():
    """Two circuits, alpha 0.5, gamma 0.5, delta_w 0.1, delta_l 0.4. From Q = 0 and uniform
    policies, robot 0 in state 0 takes action 1 and earns 2, landing in state 1."""
    from tavc_cli.learning.literature import WolfPhcPolicy

    p = WolfPhcPolicy(1, 2, alpha=0.5, gamma=0.5, epsilon=0.0, delta_win=0.1, delta_lose=0.4,
                      rng=np.random.default_rng(0))
    p.learn(0, 0, 1, 2.0, 1)
    # Q(0,1) = 0 + 0.5 (2 + 0.5 * max Q(1,.) = 0 - 0) = 1
    assert p.q[0, 0].tolist() == [0.0, 1.0]
    # average policy after one visit: pi_avg = pi = [0.5, 0.5]; pi . Q = 0.5 = pi_avg . Q: not winning
    # -> delta_l = 0.4; the non-greedy action 0 gives min(0.5, 0.4 / 1) = 0.4 to the greedy action 1
    assert p.pi[0, 0].tolist() == pytest.approx([0.1, 0.9])
    assert p.pi_avg[0, 0].tolist() == pytest.approx([0.5, 0.5])
    p.learn(0, 0, 1, 2.0, 1)
    # Q(0,1) = 1 + 0.5 (2 + 0 - 1) = 1.5; visits 2: pi_avg = [0.5, 0.5] + ([0.1, 0.9] - [0.5, 0.5]) / 2
    assert p.q[0, 0, 1] == pytest.approx(1.5)
    assert p.pi_avg[0, 0].tolist() == pytest.approx([0.3, 0.7])
    # pi . Q = 0.9 * 1.5 = 1.35 > pi_avg . Q = 0.7 * 1.5 = 1.05: winning -> delta_w = 0.1,
    # action 0 gives min(0.1, 0.1) = 0.1
    assert p.pi[0, 0].tolist() == pytest.approx([0.0, 1.0])
    assert p.choose(0, 0) == 1  # epsilon 0: drawn from pi, which is all on action 1


def test_wolf_phc_runs_in_the_simulator_from_its_config():
    cfg = config.settings(config.load_config(["experiment=initial_distribution", "scale=smoke", "learner=wolf_phc",
                                              "trials=1", "baselines=[]", "duration_s=600"]))
    specs = trial_specs(cfg)
    assert specs[0].controller == "wolf_phc" and specs[0].seed[1] == 5
    record = run_trials(specs)[0]
    assert len(record.table("deliveries")["t_s"]) > 0 and record.q.shape[1:] == (6, 2, 2)


def test_the_response_threshold_by_hand():
    from tavc_cli.learning.literature import ThresholdPolicy

    p = ThresholdPolicy(1, 2, alpha=0.5, theta_low=1.0, theta_high=1.0, steepness=2.0, rng=np.random.default_rng(3))
    assert p.stimulus(0, 0) == 1.0 and p.stay_probability(0, 0) == 0.5  # nothing seen: 1 / (1 + 1)
    p.learn(0, 1, 0, 3.0, 0)  # the first reward on circuit 0 is taken whole
    assert p.stimulus(0, 0) == 1.0  # one circuit seen: no comparison yet
    p.learn(0, 0, 1, 1.0, 1)
    # running means 3 and 1, their mean 2: stimuli 1.5 and 0.5
    assert p.stimulus(0, 0) == pytest.approx(1.5) and p.stimulus(0, 1) == pytest.approx(0.5)
    # T = s^2 / (s^2 + theta^2): 2.25 / 3.25 on circuit 0, 0.25 / 1.25 on circuit 1
    assert p.stay_probability(0, 0) == pytest.approx(2.25 / 3.25)
    assert p.stay_probability(0, 1) == pytest.approx(0.2)
    p.learn(0, 0, 0, 1.0, 0)  # 3 + 0.5 (1 - 3) = 2
    assert p.mean[0].tolist() == [2.0, 1.0]
    p.started[0] = True
    stays = sum(p.choose(0, 1) == 1 for _ in range(4000)) / 4000
    # stimulus of circuit 1: 1 / 1.5; T = (4/9) / (4/9 + 1) = 4/13
    assert abs(stays - 4 / 13) < 0.03


def test_a_parameter_the_learners_yaml_does_not_list_says_how_to_add_it(tmp_path, monkeypatch):
    from tavc_cli.errors import TavcError
    from tavc_cli.learning.plugins import CONFIG_DIRS_ENV

    monkeypatch.setenv(CONFIG_DIRS_ENV, str(_plugin_folder(tmp_path)))
    base = ["experiment=initial_distribution", "scale=smoke", "learner=stubborn"]
    said = (r"^learner.params.other: the learner's config lists no such parameter; to give one it does not "
            r"list, add it with a plus: \+learner.params.other=\.\.\.$")
    with pytest.raises(TavcError, match=said):
        config.load_config([*base, "learner.params.other=1"])
    with pytest.raises(TavcError, match=r"learner.params.other: Stubborn takes no parameter 'other'"):
        config.load_config([*base, "+learner.params.other=1"])  # with the plus, the class's signature decides


def test_a_run_of_a_learner_from_outside_is_held_to_its_keys_by_the_code_it_records(tmp_path, monkeypatch):
    """A finished run's `provenance.json` records the digest of the learner's code; its trials'
    keys are held to it as a built-in learner's are to its settings, so a value edited after the
    run is refused though the config's digest was written again. Of a run that did not finish,
    `records()` keeps only the trials the learner's code as it is now gives, where it finds that
    code; where it cannot, it takes them as they are."""
    folder, out = _stubborn_run(tmp_path, monkeypatch, "[]")
    monkeypatch.setenv(CONFIG_DIRS_ENV, "")  # the learner's folder no longer searched: read from the record
    check_run(out)  # its keys are those its settings and its learner's recorded digest give

    edited = tmp_path / "edited"
    shutil.copytree(out, edited)
    path = edited / "config.yaml"
    path.write_text(path.read_text().replace("  - 2200.0\n", "  - 2300.0\n", 1))
    prov = json.loads((edited / "provenance.json").read_text())
    prov["tables"]["config.yaml"] = file_digest(path)
    (edited / "provenance.json").write_text(json.dumps(prov, indent=2))
    with pytest.raises(TavcError, match=r"provenance.json: stubborn trial 0 is listed under a key its config.yaml "
                                        r"and plan.json do not give it"):
        check_run(edited)

    unfinished = tmp_path / "unfinished"
    shutil.copytree(out, unfinished)
    (unfinished / "provenance.json").unlink()
    assert len(api.load(unfinished).records()) == 1  # its learner not found from here: taken as it is
    monkeypatch.setenv(CONFIG_DIRS_ENV, str(folder))
    assert len(api.load(unfinished).records()) == 1  # found, and the code that made it
    (folder / "stubborn.py").write_text(LEARNER_FILE + "\n# another version\n")
    with pytest.raises(TavcError, match="no trial of its run has finished yet"):
        api.load(unfinished).records()  # a record of the learner's earlier code: resuming computes it anew
