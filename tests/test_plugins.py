"""Learners beside the built-in ones: the simulator runs a policy's own code unless it is exactly
one of the built-in policies the compiled paths serve."""

from __future__ import annotations

import numpy as np

from tavc_cli import config
from tavc_cli.experiments.build import trial_specs
from tavc_cli.experiments.engine import run_trials
from tavc_cli.learning import registry
from tavc_cli.learning.compiled import POLICY_EGREEDY, POLICY_PYTHON, policy_kind
from tavc_cli.learning.policies import TavcPolicy


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

    def build(spec, n_robots, n_circuits, rng):
        return AlwaysZero(n_robots, n_circuits, selection="egreedy", epsilon=float(spec.epsilon), rng=rng,
                          **registry._q_learning(spec))

    entry = registry.LEARNERS["tavc_egreedy"]
    monkeypatch.setitem(registry.LEARNERS, "tavc_egreedy", registry.Learner(entry.name, entry.label,
                                                                            entry.seed_code, build))
    cfg = config.settings(config.load_config(["experiment=initial_distribution", "scale=smoke", "trials=1",
                                              "baselines=[]", "duration_s=600"]))
    record = run_trials(trial_specs(cfg))[0]
    chosen = record.table("choices")["circuit"]
    assert len(chosen) > 6 and set(chosen.tolist()) == {0}  # every choice its own: circuit 0
