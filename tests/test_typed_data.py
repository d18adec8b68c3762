"""Reading a run's settings without OmegaConf where the file needs nothing converted: the same
settings as OmegaConf's path for every committed config, and OmegaConf's path (its result, its
message) for anything else."""

import copy
import dataclasses
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Dict, List, Optional

import pytest
import yaml
from omegaconf import MISSING, OmegaConf
from omegaconf._utils import get_yaml_loader

from tavc_cli.config import load_config
from tavc_cli.config import settings as to_settings
from tavc_cli.dotted import plain
from tavc_cli.learning.parameters import PluginSettings, recorded_learner, settings_mapping
from tavc_cli.learning.registry import SETTINGS
from tavc_cli.readers import load_yaml
from tavc_cli.settings import TavcConfig, from_mapping, from_yaml, settings_of, to_yaml
from tavc_cli.typed_data import DECLINED, exact
from tests.helpers import REPO


@dataclass
class Leaf:
    name: str = MISSING
    x: float = 0.5


@dataclass
class Tree:
    leaves: List[Leaf] = field(default_factory=list)
    count: int = 1
    scale: float = 1.0
    flag: bool = False
    maybe: Optional[List[float]] = None
    open_node: Dict[str, Any] = field(default_factory=lambda: {"a": 1, "nested": {"b": 2, "c": 3}})
    anything: Any = None


def test_values_of_their_fields_types_are_read_as_omegaconf_reads_them():
    data = {"leaves": [{"name": "l1", "x": 2}, {"name": "l2"}], "scale": 3, "maybe": [1, 2.5],
            "open_node": {"nested": {"c": 30}, "d": [1]}, "anything": {"k": [1, "v"]}}
    tree = exact(Tree, data)
    # by hand: an integer in a float field becomes that float; a field left out takes its default;
    # the open mapping is merged over its default key by key
    assert tree == Tree(leaves=[Leaf("l1", 2.0), Leaf("l2", 0.5)], count=1, scale=3.0, maybe=[1.0, 2.5],
                        open_node={"a": 1, "nested": {"b": 2, "c": 30}, "d": [1]}, anything={"k": [1, "v"]})
    assert isinstance(tree.scale, float) and isinstance(tree.leaves[0].x, float)
    assert tree == OmegaConf.to_object(OmegaConf.merge(OmegaConf.structured(Tree), data))
    assert tree.anything is not data["anything"] and tree.leaves is not data["leaves"]  # copies, not the data


@pytest.mark.parametrize("data", [
    {"count": "2"},  # a string OmegaConf would convert
    {"count": 2.0},  # a float in an int field
    {"flag": 1},  # an integer in a bool field
    {"leaves": [{"x": 1.0}]},  # a mandatory field left out
    {"leaves": [{"name": "l", "z": 1}]},  # a key the class lacks
    {"nothing": 1},
    {"leaves": [{"name": "${count}"}]},  # an interpolation
    {"anything": {"k": "${count}"}},
    {"leaves": [{"name": "???"}]},  # OmegaConf's missing value
    {"count": None},  # None where the field is not optional
    {"leaves": {"name": "l"}},  # a mapping where a list belongs
    {"open_node": {"nested": [1]}},  # a list over a mapping of the default: OmegaConf refuses it
    {"open_node": {"a": {"b": 1}}},  # a mapping over a value of the default
    {"scale": 10 ** 400},  # an integer no float holds
    None,
])
def test_anything_to_convert_fill_in_or_refuse_is_left_to_omegaconf(data):
    assert exact(Tree, data) is DECLINED


def test_a_refusal_of_the_class_itself_is_left_to_omegaconf():
    data = load_yaml(REPO / "results" / "initial_distribution" / "config.yaml", loader=get_yaml_loader())
    data["learner"]["name"] = "no_such_learner"
    assert exact(TavcConfig, data) is DECLINED


def _shape(value):
    """What `typed_data.exact` decides a value by: its keys, each leaf's type, whether an int is
    too large for a float and whether a string is an interpolation or `???` (never the other
    values); two configs of one shape take the same path through it."""
    if isinstance(value, dict):
        return tuple((key, _shape(v)) for key, v in value.items())
    if isinstance(value, list):
        return ("list", *map(_shape, value))
    if isinstance(value, str):
        return "str", "${" in value or value == MISSING
    if isinstance(value, int) and not isinstance(value, bool):
        return "int", abs(value) < 2 ** 1023
    return type(value).__name__


def test_every_committed_config_reads_as_omegaconf_reads_it():
    """Every committed config, through one config of each shape (`_shape`, with its learner's name,
    which picks the learner's settings class): the fast path's settings are OmegaConf's, value,
    type and YAML alike."""
    paths = sorted((REPO / "results").rglob("config.yaml"))
    assert len(paths) > 100
    shapes = {}
    for path in paths:
        data = load_yaml(path, loader=get_yaml_loader())
        shapes.setdefault((data["learner"].get("name"), _shape(data)), (path, data))
        # every one is read by the fast path: the learner's values, which its class converts, lie outside the shape
        assert exact(TavcConfig, {**data, "learner": recorded_learner(data["learner"], SETTINGS)}) is not DECLINED, path
    assert len(shapes) > 10  # the committed runs hold many shapes: sweeps, readings, other learners
    for path, data in shapes.values():
        data["learner"] = recorded_learner(data["learner"], SETTINGS)
        fast = exact(TavcConfig, data)
        assert fast is not DECLINED, path
        slow = from_mapping(TavcConfig, OmegaConf.create(data))
        assert fast == slow and repr(fast) == repr(slow) and to_yaml(fast) == to_yaml(slow), path
        assert repr(from_yaml(path)) == repr(slow)  # the path the report reads by
        # written and compared without OmegaConf: its text of the settings, and that text read back
        text = _omegaconf_yaml(slow)
        assert to_yaml(slow) == text and plain(slow) == yaml.safe_load(text), path


def _omegaconf_yaml(settings: TavcConfig) -> str:
    """The settings' YAML as OmegaConf writes it from a structured copy (the learner as its plain node)."""
    node = copy.copy(settings)
    node.learner = settings_mapping(settings.learner)
    return OmegaConf.to_yaml(OmegaConf.structured(node))


@pytest.mark.parametrize("overrides", [["experiment=breakdown"], ["experiment=heterogeneous", "scale=converged"],
                                       ["experiment=spatiotemporal"], ["learner=random", "team.n_robots=3"],
                                       ["experiment=value_change", "learner=tavc_egreedy"]])
def test_a_composed_run_is_written_as_omegaconf_writes_it(overrides):
    settings = to_settings(load_config(overrides))
    text = _omegaconf_yaml(settings)
    assert to_yaml(settings) == text and plain(settings) == yaml.safe_load(text)


def test_settings_changed_in_code_are_written_as_omegaconf_writes_them():
    """Settings a program changed (a whole number where a float goes, in a field and in a list of
    floats; a path for a folder) are written as OmegaConf's structured copy wrote them."""
    settings = dataclasses.replace(to_settings(load_config(["experiment=breakdown"])), duration_s=100,
                                   output_dir=Path("/tmp/somewhere"))
    settings.tasks.values = [2200, 2000]
    text = _omegaconf_yaml(settings)
    assert "duration_s: 100.0\n" in text and "- 2200.0\n" in text and "output_dir: /tmp/somewhere\n" in text
    assert to_yaml(settings) == text and plain(settings) == yaml.safe_load(text)


def test_a_settings_section_left_out_is_left_to_omegaconf():
    """A section whose class has mandatory fields (the arena's) cannot take its default; the file
    is refused where it is read, as before."""
    data = load_yaml(REPO / "results" / "initial_distribution" / "config.yaml", loader=get_yaml_loader())
    del data["arena"]
    assert exact(TavcConfig, data) is DECLINED


def test_an_interrupt_hidden_in_the_class_own_check_is_not_taken_for_a_refusal(monkeypatch):
    """A Ctrl-C that a library hides behind its own error while the learner's node is read (the
    class's `__post_init__`) comes out, for the command line to end on, rather than being
    retried away by OmegaConf's path."""
    import tavc_cli.settings as settings
    from tavc_cli.errors import TavcError, interrupt_behind

    def interrupted(node):
        try:
            raise KeyboardInterrupt
        except KeyboardInterrupt:
            raise TavcError("learner.name: unknown key") from None

    monkeypatch.setattr(settings, "settings_of", interrupted)
    data = load_yaml(REPO / "results" / "initial_distribution" / "config.yaml", loader=get_yaml_loader())
    with pytest.raises(TavcError) as raised:
        exact(TavcConfig, data)
    assert isinstance(interrupt_behind(raised.value), KeyboardInterrupt)


@pytest.mark.parametrize(("node", "fast_path"), [
    ({"name": "random"}, True), ({"name": "static", "allocation": [3, 3]}, True),
    ({"name": "alternate", "roles": None}, True), ({"name": "wolf_phc", "alpha": 1, "delta_win": 0.01}, True),
    ({"name": "threshold", "theta_low": 2}, True), ({"name": "tavc_softmax", "tau": 3}, True),
    ({"name": "tavc_egreedy", "epsilon": 0.2, "q_init_low": -1}, True),
    ({"name": "behaviour_softmax", "decide_on_change": False, "decision_period_s": 2}, True),
    ({"name": "informed", "model_file": "m.json", "allocations": None}, True),
    ({"name": "mine", "target": "pkg.mod.Learner", "params": {"rate": 1, "nested": {"a": [1, 2]}}}, True),
    # a mapping of lists in a typed field is OmegaConf's to convert
    ({"name": "model", "model_file": "m.json", "allocations": {"6": [3, 3], "5": [3, 2]}}, False),
])
def test_a_learners_node_read_without_omegaconf_is_what_omegaconf_reads(node, fast_path):
    """A learner's node whose values are of its fields' types (an integer standing for a float)
    is read straight into its settings class: the settings OmegaConf's path gives, of the same
    types; a node it cannot read so is OmegaConf's, with the same result."""
    cls = PluginSettings if "target" in node else SETTINGS[node["name"]]
    fast, slow = settings_of(copy.deepcopy(node)), from_mapping(cls, copy.deepcopy(node))
    assert fast == slow and repr(fast) == repr(slow)
    assert [type(getattr(fast, k)) for k in node] == [type(getattr(slow, k)) for k in node]
    assert (exact(cls, node) is not DECLINED) == fast_path
