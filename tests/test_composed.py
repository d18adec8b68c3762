"""A process's memory of composed configs (tavc_cli.config.composed): the same overrides over the
same config files are composed once, anything else is composed anew."""

import os

import pytest
from omegaconf import OmegaConf

from tavc_cli.config import composed as memory
from tavc_cli.config import load_config, loading
from tavc_cli.user_configs import using_config_dirs


@pytest.fixture(autouse=True)
def _nothing_remembered():
    memory.forget()
    yield
    memory.forget()


class Composer:
    """A stand-in for Hydra: counts its calls, gives a config holding the call's number."""

    def __init__(self):
        self.calls = 0

    def __call__(self):
        self.calls += 1
        return OmegaConf.create({"call": self.calls, "team": {"n_robots": 6}})


def _folder(tmp_path, text="team:\n  n_robots: 4\n"):
    folder = tmp_path / "conf"
    (folder / "experiment").mkdir(parents=True)
    (folder / "experiment" / "mine.yaml").write_text(text)
    return folder


def test_the_same_key_is_composed_once_and_each_caller_gets_its_own_copy(tmp_path):
    folders, compose = [_folder(tmp_path)], Composer()
    first = memory.composed(["a=1"], [], folders, compose)
    first.team.n_robots = 99  # the caller's to change
    second = memory.composed(["a=1"], [], folders, compose)
    assert compose.calls == 1
    assert second.call == 1 and second.team.n_robots == 6
    second.team.n_robots = 7
    assert memory.composed(["a=1"], [], folders, compose).team.n_robots == 6


@pytest.mark.parametrize("change", ["overrides", "order", "search", "folders"])
def test_other_overrides_search_path_or_folders_are_composed_anew(tmp_path, change):
    folders, compose = [_folder(tmp_path)], Composer()
    memory.composed(["a=1", "b=2"], [], folders, compose)
    other = {"overrides": (["a=1", "b=3"], [], folders),
             "order": (["b=2", "a=1"], [], folders),  # Hydra applies overrides in order: another key
             "search": (["a=1", "b=2"], ["hydra.searchpath=[x]"], folders),
             "folders": (["a=1", "b=2"], [], [*folders, _folder(tmp_path / "other")])}[change]
    assert memory.composed(*other, compose).call == 2


@pytest.mark.parametrize("edit", ["same size", "added", "removed", "renamed", "new group"])
def test_a_config_file_changed_between_two_calls_is_composed_anew(tmp_path, edit):
    folder = _folder(tmp_path)
    compose = Composer()
    memory.composed(["experiment=mine"], [], [folder], compose)
    mine = folder / "experiment" / "mine.yaml"
    if edit == "same size":  # within the same tick of the file system's clock, as a script may do it
        stat = mine.stat()
        mine.write_text("team:\n  n_robots: 5\n")
        os.utime(mine, ns=(stat.st_atime_ns, stat.st_mtime_ns))
        assert mine.stat().st_size == stat.st_size and mine.stat().st_mtime_ns == stat.st_mtime_ns
    elif edit == "added":
        (folder / "experiment" / "yours.yaml").write_text("seed: 1\n")
    elif edit == "removed":
        mine.unlink()
    elif edit == "renamed":
        mine.rename(folder / "experiment" / "mine2.yaml")
    else:
        (folder / "robot").mkdir()
    assert memory.composed(["experiment=mine"], [], [folder], compose).call == 2


def test_files_hydra_does_not_read_leave_the_key_as_it_was(tmp_path):
    folder = _folder(tmp_path)
    compose = Composer()
    memory.composed(["x=1"], [], [folder], compose)
    (folder / "notes.txt").write_text("a user's notes")
    assert memory.composed(["x=1"], [], [folder], compose).call == 1


@pytest.mark.parametrize("limit", ["MAX_FILES", "MAX_BYTES", "MAX_DEPTH"])
def test_a_folder_too_large_or_deep_to_read_is_composed_every_time(tmp_path, monkeypatch, limit):
    folder = _folder(tmp_path)
    (folder / "experiment" / "nested").mkdir()
    (folder / "experiment" / "nested" / "deep.yaml").write_text("seed: 1\n")
    # two files of 20 and 8 bytes, two levels deep: each limit set one below what the folder needs
    monkeypatch.setattr(memory, limit, {"MAX_FILES": 1, "MAX_BYTES": 27, "MAX_DEPTH": 1}[limit])
    assert memory.folders_digest([folder]) is None
    compose = Composer()
    memory.composed(["x=1"], [], [folder], compose)
    assert memory.composed(["x=1"], [], [folder], compose).call == 2


def test_a_folder_at_the_limits_is_remembered(tmp_path, monkeypatch):
    folder = _folder(tmp_path)
    (folder / "experiment" / "nested").mkdir()
    (folder / "experiment" / "nested" / "deep.yaml").write_text("seed: 1\n")
    for limit, value in {"MAX_FILES": 2, "MAX_BYTES": 28, "MAX_DEPTH": 2}.items():
        monkeypatch.setattr(memory, limit, value)
    compose = Composer()
    memory.composed(["x=1"], [], [folder], compose)
    assert memory.composed(["x=1"], [], [folder], compose).call == 1


def test_a_link_that_loops_ends_the_walk_and_is_composed_every_time(tmp_path):
    folder = _folder(tmp_path)
    (folder / "experiment" / "loop").symlink_to(folder)
    assert memory.folders_digest([folder]) is None
    compose = Composer()
    memory.composed(["x=1"], [], [folder], compose)
    assert memory.composed(["x=1"], [], [folder], compose).call == 2


def test_a_linked_group_is_read_through_its_link(tmp_path):
    target = tmp_path / "shared"
    target.mkdir()
    (target / "fast.yaml").write_text("epsilon: 0.1\n")
    folder = _folder(tmp_path)
    (folder / "learner").symlink_to(target)
    compose = Composer()
    memory.composed(["learner=fast"], [], [folder], compose)
    (target / "fast.yaml").write_text("epsilon: 0.2\n")
    assert memory.composed(["learner=fast"], [], [folder], compose).call == 2


def test_a_failed_composition_is_not_remembered(tmp_path):
    folders = [_folder(tmp_path)]

    def fails():
        raise ValueError("no such option")

    with pytest.raises(ValueError):
        memory.composed(["x=1"], [], folders, fails)
    assert memory.composed(["x=1"], [], folders, Composer()).call == 1


def test_the_least_recently_used_composition_is_dropped_first(tmp_path, monkeypatch):
    monkeypatch.setattr(memory, "MAX_ENTRIES", 2)
    folders, compose = [_folder(tmp_path)], Composer()
    memory.composed(["a"], [], folders, compose)  # call 1
    memory.composed(["b"], [], folders, compose)  # call 2
    memory.composed(["a"], [], folders, compose)  # remembered; b is now the oldest
    memory.composed(["c"], [], folders, compose)  # call 3 drops b
    assert compose.calls == 3
    assert memory.composed(["a"], [], folders, compose).call == 1
    assert memory.composed(["b"], [], folders, compose).call == 4


def test_load_config_composes_once_and_reads_a_users_file_edited_between_calls(tmp_path, monkeypatch):
    calls = []
    hydra_compose = loading.compose
    monkeypatch.setattr(loading, "compose", lambda **kw: calls.append(kw) or hydra_compose(**kw))
    first = load_config(["experiment=breakdown", "seed=5"])
    again = load_config(["experiment=breakdown", "seed=5"])
    assert len(calls) == 1
    assert OmegaConf.to_yaml(first) == OmegaConf.to_yaml(again) and first is not again
    folder = _folder(tmp_path, "# @package _global_\nteam:\n  n_robots: 4\n")
    with using_config_dirs([folder]):
        assert load_config(["experiment=mine"]).team.n_robots == 4
        (folder / "experiment" / "mine.yaml").write_text("# @package _global_\nteam:\n  n_robots: 5\n")
        assert load_config(["experiment=mine"]).team.n_robots == 5
    assert len(calls) == 3


def test_typing_a_config_leaves_the_schema_it_merges_into_as_built():
    from tavc_cli.settings import TavcConfig

    load_config(["experiment=breakdown", "seed=3", "learner.epsilon=0.3", "tasks.values=[3000,2000]"])
    assert OmegaConf.to_yaml(loading._schema()) == OmegaConf.to_yaml(OmegaConf.structured(TavcConfig))


def test_overrides_of_hydras_own_settings_are_composed_every_time(tmp_path, monkeypatch):
    """A search path given as an override reaches config files the key does not read."""
    calls = []
    hydra_compose = loading.compose
    monkeypatch.setattr(loading, "compose", lambda **kw: calls.append(kw) or hydra_compose(**kw))
    folder = _folder(tmp_path, "# @package _global_\nteam:\n  n_robots: 4\n")
    given = [f"hydra.searchpath=[file://{folder}]", "experiment=mine"]
    assert loading._compose(given).team.n_robots == 4
    (folder / "experiment" / "mine.yaml").write_text("# @package _global_\nteam:\n  n_robots: 5\n")
    assert loading._compose(given).team.n_robots == 5
    assert len(calls) == 2
