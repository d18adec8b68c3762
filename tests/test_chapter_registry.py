"""The chapter's registry of experiments: every experiment file of the chapter has its entry and
every entry its file; no module outside `tavc_cli/chapter/` names an experiment; and an
experiment of the user's own (a file and a registry module in a config folder) is listed by
`tavc list`, placed in the report's order and has its claims tested."""

import ast
import re
from pathlib import Path

import pandas as pd
import pytest
import yaml
from typer.testing import CliRunner

from tavc_cli import chapter
from tavc_cli.chapter import EXPERIMENTS, Claim, Experiment
from tavc_cli.cli import app
from tavc_cli.compare import run as compare_run
from tavc_cli.compare import scenarios
from tavc_cli.config import find_conf_dir, load_config, to_yaml
from tavc_cli.errors import TavcError
from tavc_cli.learning.plugins import CONFIG_DIRS_ENV

PACKAGE = Path(__file__).resolve().parent.parent / "tavc_cli"
CHAPTER = ("spatiotemporal", "initial_distribution", "breakdown", "breakdown_no_vacancy", "value_change",
           "heterogeneous")
# (module, name): where a module outside tavc_cli/chapter/ may hold an experiment's name, and why
ALLOWED = {
    # the kind of event that opened a vacancy, vacancy.csv's `event` column: a robot's breakdown or a
    # change of the values, whichever experiment the trial ran
    ("analysis/vacancy.py", "breakdown"), ("analysis/vacancy.py", "value_change"),
    # examples of overrides in the command line's help
    ("cli.py", "breakdown"), ("options.py", "initial_distribution"),
    # the default model file, where `tavc model` writes it: a setting's default in the learners' layer,
    # below the chapter's registry
    ("learning/parameters.py", "initial_distribution"),
}
# an experiment's name inside a longer string: chosen (experiment=NAME) or a folder (/NAME/)
NAME_IN_TEXT = re.compile(r"(?:experiment=|/)(" + "|".join(sorted(CHAPTER, key=len, reverse=True)) + r")\b")


def _experiment_files() -> dict[str, dict]:
    return {p.stem: yaml.safe_load(p.read_text()) for p in (find_conf_dir() / "experiment").glob("*.yaml")}


def test_every_experiment_file_has_its_entry_and_every_entry_its_file():
    files = _experiment_files()
    assert set(files) == set(EXPERIMENTS)
    for name, e in EXPERIMENTS.items():
        assert (e.name, e.section) == (files[name]["experiment_name"], files[name]["section"])


def test_the_entries_hold_together():
    assert list(EXPERIMENTS) == list(CHAPTER)  # the report's order, the chapter's
    assert [c.id for _, c in chapter.claims()] == list(range(1, 10))
    assert all(callable(c.test()) for _, c in chapter.claims())
    assert {c.against for _, c in chapter.claims()} - {None} <= set(EXPERIMENTS)
    assert chapter.base_case().name == "initial_distribution"
    reference = PACKAGE / "reference"
    for e in EXPERIMENTS.values():
        assert all((reference / f"table_{t.replace('.', '_')}.csv").is_file() for t in e.tables)


def test_the_checks_on_the_chapters_tables_are_those_its_claims_name():
    from tavc_cli.analysis.chapter_checks import chapter_checks

    named = [c.id for _, c in chapter.claims() if c.on_tables is not None]
    assert named == [3, 4, 6, 7, 8, 9]  # the claims on the time in each state (5: performance, printed in none)
    assert all(EXPERIMENTS[name].state_table is not None for name, c in chapter.claims() if c.on_tables)
    rows = [row["claim_id"] for row in chapter_checks()]
    assert sorted(set(rows)) == named and rows == sorted(rows)
    with pytest.raises(TavcError, match="no service 'ladder'"):
        chapter.served_by("ladder")


def _named_experiments(path: Path) -> set[str]:
    """The experiments' names a module holds as string constants, or inside one where it chooses
    an experiment or names its folder (its docstrings aside)."""
    tree = ast.parse(path.read_text())
    docstrings = {id(node.body[0].value) for node in ast.walk(tree)
                  if isinstance(node, (ast.Module, ast.ClassDef, ast.FunctionDef, ast.AsyncFunctionDef))
                  and ast.get_docstring(node, clean=False) is not None}
    strings = [node.value for node in ast.walk(tree)
               if isinstance(node, ast.Constant) and isinstance(node.value, str) and id(node) not in docstrings]
    return {s for s in strings if s in CHAPTER} | {name for s in strings for name in NAME_IN_TEXT.findall(s)}


def test_no_module_outside_the_chapter_names_an_experiment():
    found = {(path.relative_to(PACKAGE).as_posix(), name)
             for path in sorted(PACKAGE.rglob("*.py")) if path.relative_to(PACKAGE).parts[0] != "chapter"
             for name in _named_experiments(path)}
    assert found - ALLOWED == set()
    assert ALLOWED <= found, "an allowed exception no longer applies: remove it from ALLOWED"


def test_the_chapter_imports_nothing_above_it():
    above = ("tavc_cli.report", "tavc_cli.compare", "tavc_cli.surrogate", "tavc_cli.cli", "tavc_cli.pipeline",
             "tavc_cli.api", "tavc_cli.config")
    for path in (PACKAGE / "chapter").glob("*.py"):
        for node in ast.walk(ast.parse(path.read_text())):
            names = [a.name for a in node.names] if isinstance(node, ast.Import) else \
                [node.module or ""] if isinstance(node, ast.ImportFrom) else []
            assert not [n for n in names if n.startswith(above)], path.name


TOY_YAML = """\
# @package _global_
defaults:
  - override /arena: two_circuits
  - override /team: homogeneous
  - override /tasks: chapter
  - override /learner: tavc_egreedy

experiment_name: toy
section: "1.5.5"
description: "Four TAVC learners share two circuits (a toy)."
team:
  n_robots: 4
paper:
  trials: 2
  duration_s: 600.0
  convergence_s: 300.0
baselines: [random]
"""

TOY_MODULE = '''\
"""A toy experiment of the user's own, between initial_distribution and breakdown in the report."""

from tavc_cli.analysis.significance import Part
from tavc_cli.chapter import Claim, Experiment


def claim_10(runs, learner="tavc"):
    return [Part("the toy ran", 1.0, 0.01, "toy" in runs)]


EXPERIMENT = Experiment(name="toy", section="1.5.5", order=25, compare=True,
                        claims=(Claim(10, "four learners share two circuits.", claim_10),))
'''


@pytest.fixture
def toy(tmp_path, monkeypatch) -> Path:
    """A config folder holding the toy's file and its registry module; the config folders as they were after."""
    folder = tmp_path / "mine"
    (folder / "experiment").mkdir(parents=True)
    (folder / "experiment" / "toy.yaml").write_text(TOY_YAML)
    (folder / "chapter").mkdir()
    (folder / "chapter" / "toy.py").write_text(TOY_MODULE)
    monkeypatch.setenv(CONFIG_DIRS_ENV, "")  # `--config-dir` adds to it; restored after the test
    return folder


def test_an_experiment_of_ones_own_is_listed_ordered_and_tested(toy, tmp_path):
    result = CliRunner().invoke(app, ["--config-dir", str(toy), "list"])
    assert result.exit_code == 0, result.output
    lines = {line.split()[0]: line for line in result.stdout.splitlines() if line.strip()}
    assert set(CHAPTER) | {"toy"} == set(lines)
    assert lines["toy"].split()[1] == "1.5.5" and "four TAVC learners share two circuits (a toy)" in lines["toy"]
    # the report's order: the toy's place among the chapter's, read from runs found in a results folder
    from tavc_cli.report.runs import finished_runs

    results = tmp_path / "results"
    for name in ("breakdown", "toy", "initial_distribution"):
        (results / name).mkdir(parents=True)
        (results / name / "config.yaml").write_text(to_yaml(load_config([f"experiment={name}", "scale=quick"])))
        (results / name / "state_time.csv").write_text("")
        (results / name / "provenance.json").write_text("{}")
    assert list(finished_runs(results)[0]) == ["initial_distribution", "toy", "breakdown"]
    assert list(EXPERIMENTS)[2] == "toy"
    from tavc_cli.analysis.claims import claim_table

    table = claim_table({"toy": None}, "toy")
    assert table[["claim_id", "verdict"]].to_dict("records") == [{"claim_id": 10, "verdict": "reproduced"}]


@pytest.mark.slow
def test_an_experiment_of_ones_own_runs_is_reported_and_compared(toy, tmp_path, monkeypatch):
    """The toy end to end, from nothing but its file and its registry module: a run whose claim is
    tested, the report's section and claim row, and `tavc compare`, which serves it by default."""
    results = tmp_path / "results"
    mine = ["--config-dir", str(toy)]
    run = CliRunner().invoke(app, [*mine, "run", "experiment=toy", "scale=paper", f"output_dir={results / 'toy'}",
                                   "--no-progress"])
    assert run.exit_code == 0, run.output
    assert "claim 10: reproduced" in run.output
    report = CliRunner().invoke(app, [*mine, "report", str(results)])
    assert report.exit_code == 0, report.output
    text = (results / "REPORT.md").read_text()
    assert "## toy (section 1.5.5)" in text and "| 10 | toy | reproduced |" in text
    # compare's default: the chapter's scenarios and the toy, at its place in the report's order (25),
    # each composed for every controller before anything runs (`run_compare` stands in for the runs)
    model = PACKAGE.parent / "results" / "initial_distribution" / "model" / "model.json"
    planned = {}

    def planned_only(plans, results, **kwargs):
        planned.update({name: [str(cfg.experiment_name) for cfg in cfgs] for name, cfgs in plans.items()})
        return {"results": str(results), "figures": []}

    with monkeypatch.context() as patch:
        patch.setattr(compare_run, "run_compare", planned_only)
        default = CliRunner().invoke(app, [*mine, "compare", "scale=paper", f"learner.model_file={model}",
                                           "--learners", "tavc,random", "--results", str(tmp_path / "default")])
    assert default.exit_code == 0, default.output
    served = ["initial_distribution", "toy", "breakdown", "breakdown_no_vacancy", "value_change", "heterogeneous"]
    assert planned == {"tavc": served, "random": served}
    compared = CliRunner().invoke(app, [*mine, "compare", "scale=paper", f"learner.model_file={model}",
                                        "--learners", "tavc,random", "--experiments", "toy",
                                        "--results", str(tmp_path / "cmp"), "--no-progress"])
    assert compared.exit_code == 0, compared.output
    table = pd.read_csv(tmp_path / "cmp" / "compare.csv")
    assert set(table["experiment"]) == {"toy"} and set(table["controller"]) == {"tavc", "random"}


def test_an_entry_compare_serves_without_its_file_is_one_line_before_anything_runs(toy, tmp_path):
    (toy / "experiment" / "toy.yaml").unlink()
    result = CliRunner().invoke(app, ["--config-dir", str(toy), "compare", "scale=paper",
                                      "--results", str(tmp_path / "cmp")])
    assert result.exit_code == 1
    assert result.output.strip() == ("error: chapter: toy's registry entry says compare serves it, but no "
                                     "experiment/toy.yaml is in tavc's configs or a --config-dir folder")
    assert not (tmp_path / "cmp").exists()


def test_without_the_config_folder_the_toy_is_gone(toy):
    assert "toy" not in EXPERIMENTS
    assert "toy" not in scenarios()


def test_a_name_or_a_claim_number_registered_twice_is_refused(monkeypatch):
    monkeypatch.setattr(EXPERIMENTS, "_registered", {})
    chapter.register(Experiment(name="mine", section="9", order=90))
    assert "mine" in EXPERIMENTS and list(EXPERIMENTS)[-1] == "mine"
    with pytest.raises(TavcError, match="'mine' is registered twice"):
        chapter.register(Experiment(name="mine", section="9", order=91))
    with pytest.raises(TavcError, match="claims number 3, which initial_distribution has already"):
        chapter.register(Experiment(name="other", section="9", order=92, claims=(Claim(3, "again", "x:y"),)))
    with pytest.raises(TavcError, match="the chapter's is initial_distribution"):
        chapter.register(Experiment(name="other", section="9", order=92, base_case=True))


def test_a_registry_module_that_fails_is_one_line(toy):
    (toy / "chapter" / "broken.py").write_text("raise RuntimeError('half written')\n")
    result = CliRunner().invoke(app, ["--config-dir", str(toy), "list"])
    assert result.exit_code == 1
    assert result.output.strip() == (f"error: chapter: {toy / 'chapter' / 'broken.py'} failed to load: "
                                     "RuntimeError: half written")
