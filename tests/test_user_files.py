"""A config file of the user's whose YAML aliases would expand without end is refused in one line
before Hydra reads it; one with a few aliases composes as it always did."""

from __future__ import annotations

import pytest
from typer.testing import CliRunner

from tavc_cli.cli import app
from tavc_cli.config import load_config
from tavc_cli.config.user_files import MAX_CONFIG_BYTES, MAX_CONFIG_NODES
from tavc_cli.errors import TavcError
from tavc_cli.learning.plugins import CONFIG_DIRS_ENV
from tavc_cli.readers import yaml_nodes
from tavc_cli.user_configs import using_config_dirs

HEADER = "# @package _global_\n"


def _laughs(levels: int, width: int = 10) -> str:
    """A list of `width` scalars, then `levels` lists each naming the one before `width` times:
    width ** (levels + 1) scalars once expanded, in a few hundred bytes."""
    lines = [f"l0: &l0 [{', '.join(['x'] * width)}]"]
    lines += [f"l{i}: &l{i} [{', '.join([f'*l{i - 1}'] * width)}]" for i in range(1, levels + 1)]
    return HEADER + "\n".join(lines) + "\n"


def _laughs_nodes(levels: int) -> int:
    """The nodes `_laughs(levels)` expands to: the root mapping and its levels + 1 keys, and the
    lists, 1 + 10 scalars, then each 1 + 10 times the one before."""
    sizes = [11]
    for _ in range(levels):
        sizes.append(1 + 10 * sizes[-1])
    return 1 + (levels + 1) + sum(sizes)


def test_nodes_are_counted_as_the_aliases_expand_them(tmp_path):
    doc = tmp_path / "doc.yaml"
    # the root mapping; a (1) and {k: 1} (3); b (1) and the merge of a's mapping (1 + 1 + 3 + 1 + 1);
    # c (1) and a list of a's mapping twice (1 + 3 + 3): 1 + 4 + 8 + 8
    doc.write_text("a: &a {k: 1}\nb: {<<: *a, j: 2}\nc: [*a, *a]\n")
    assert yaml_nodes(doc) == 21
    doc.write_text(_laughs(2))
    assert _laughs_nodes(2) == 1 + 3 + 11 + 111 + 1111
    assert yaml_nodes(doc) == 1 + 3 + 11 + 111 + 1111
    doc.write_text(_laughs(9))
    assert yaml_nodes(doc) == _laughs_nodes(9)
    doc.write_text("")
    assert yaml_nodes(doc) == 0


def test_a_node_that_holds_an_alias_of_itself_is_refused(tmp_path):
    doc = tmp_path / "loop.yaml"
    doc.write_text("x: 1\na: &a [1, [2, *a]]\n")
    with pytest.raises(TavcError, match=r"loop.yaml: cannot be read \(the node on line 2 holds an alias of itself\)"):
        yaml_nodes(doc)
    mine = tmp_path / "mine"
    (mine / "experiment").mkdir(parents=True)
    (mine / "experiment" / "alias.yaml").write_text("seed: &a [*a]\n")  # Hydra itself would recurse until it stops
    with using_config_dirs(mine), pytest.raises(TavcError) as caught:
        load_config(["experiment=alias"])
    assert str(caught.value) == (f"{mine / 'experiment' / 'alias.yaml'}: cannot be read (the node on line 1 "
                                 "holds an alias of itself); mend it, or take it out of your config folder")


def test_a_billion_laughs_in_a_config_folder_is_one_line_and_runs_nothing(tmp_path, monkeypatch):
    monkeypatch.setenv(CONFIG_DIRS_ENV, "")  # `--config-dir` adds to it; restored after the test
    mine = tmp_path / "mine"
    (mine / "experiment").mkdir(parents=True)
    (mine / "experiment" / "laughs.yaml").write_text(_laughs(8))  # 10**9 scalars: hours and all memory to build
    out = tmp_path / "out"
    result = CliRunner().invoke(app, ["--config-dir", str(mine), "run", "experiment=laughs", "scale=smoke",
                                      f"output_dir={out}"], catch_exceptions=False)
    assert result.exit_code == 1
    assert result.output.splitlines() == [
        f"error: {mine / 'experiment' / 'laughs.yaml'}: its aliases expand it to {_laughs_nodes(8):,} YAML nodes, more "
        f"than the {MAX_CONFIG_NODES:,} a config may hold; mend it, or take it out of your config folder"]
    assert not out.exists()


def test_only_the_files_a_composition_reads_are_checked(tmp_path):
    """A file no config selects is never read, whatever it holds; selected, it is refused."""
    mine = tmp_path / "mine"
    (mine / "team").mkdir(parents=True)
    (mine / "team" / "laughs.yaml").write_text(_laughs(6))
    (mine / "data").mkdir()
    (mine / "data" / "huge.yaml").write_bytes(b"x" * (MAX_CONFIG_BYTES + 1))
    with using_config_dirs(mine):
        assert load_config(["experiment=breakdown", "scale=smoke"]).team.n_robots == 6
        expands = f"team/laughs.yaml: its aliases expand it to {_laughs_nodes(6):,} YAML nodes"
        with pytest.raises(TavcError, match=expands):
            load_config(["experiment=breakdown", "scale=smoke", "team=laughs"])


def test_a_config_file_too_large_to_count_is_one_line(tmp_path):
    mine = tmp_path / "mine"
    (mine / "team").mkdir(parents=True)
    (mine / "team" / "huge.yaml").write_bytes(b"# " + b"x" * MAX_CONFIG_BYTES + b"\n")
    with using_config_dirs(mine), pytest.raises(TavcError) as caught:
        load_config(["team=huge"])
    assert str(caught.value).startswith(f"{mine / 'team' / 'huge.yaml'}: cannot be read (")
    assert str(caught.value).endswith("); mend it, or take it out of your config folder")


def test_a_config_of_ones_own_with_a_few_aliases_composes(tmp_path):
    mine = tmp_path / "mine"
    (mine / "experiment").mkdir(parents=True)
    (mine / "experiment" / "aliased.yaml").write_text(
        HEADER + "experiment_name: aliased\nseed: &seven 7\npaper:\n  trials: *seven\n  baseline_trials: *seven\n")
    with using_config_dirs(mine):
        cfg = load_config(["experiment=aliased"])
    assert (cfg.seed, cfg.paper.trials, cfg.paper.baseline_trials) == (7, 7, 7)
