"""Q-learning and task-selection policies (tavc_cli.learning)."""

import importlib
import math

import numpy as np
import pytest
from scipy import stats

from tavc_cli.errors import TavcError
from tavc_cli.kernel import kernel
from tavc_cli.learning.compiled import egreedy, q_learn, softmax
from tavc_cli.learning.draws import NEXT_DOUBLE, below, entry_points, uniform
from tavc_cli.learning.parameters import LearnerSettings
from tavc_cli.learning.policies import (
    RandomPolicy,
    StaticPolicy,
    TavcPolicy,
    even_allocation,
)
from tavc_cli.learning.qlearning import epsilon_greedy, q_update, softmax_choice, softmax_probs
from tavc_cli.learning.registry import make_policy
from tavc_cli.settings import settings_of

N_DRAWS = 20_000


def _chi2_pvalue(counts, probs):
    counts = np.asarray(counts, dtype=float)
    return stats.chisquare(counts, counts.sum() * np.asarray(probs)).pvalue


# --- q_update ------------------------------------------------------------------------------------


def test_q_update_by_hand():
    q = np.array([[0.5, 1.0], [2.0, -1.0]])
    td = q_update(q, state=0, action=1, reward=3.0, next_state=1, alpha=0.1, gamma=0.95)
    # target = r + gamma * max_b Q(1, b) = 3 + 0.95 * 2.0 = 4.9
    # td = target - Q(0, 1) = 4.9 - 1.0 = 3.9
    # Q(0, 1) = 1.0 + 0.1 * 3.9 = 1.39
    assert td == pytest.approx(3.9)
    np.testing.assert_allclose(q, [[0.5, 1.39], [2.0, -1.0]])


def test_q_update_on_its_own_state_uses_the_value_before_the_update():
    # the TAVC learners move from state s to s' = the action taken, often s itself
    q = np.array([[0.2, 0.4]])
    td = q_update(q, state=0, action=0, reward=1.0, next_state=0, alpha=0.1, gamma=0.95)
    # target = 1 + 0.95 * max(0.2, 0.4) = 1.38; td = 1.38 - 0.2 = 1.18; Q = 0.2 + 0.118 = 0.318
    assert td == pytest.approx(1.18)
    np.testing.assert_allclose(q, [[0.318, 0.4]])


def test_repeated_updates_converge_to_the_fixed_point():
    # one state, one action, reward 1 every time: Q* = r / (1 - gamma) = 1 / 0.05 = 20
    q = np.zeros((1, 1))
    for _ in range(5000):
        q_update(q, 0, 0, 1.0, 0, 0.1, 0.95)
    assert q[0, 0] == pytest.approx(20.0, rel=1e-6)


# --- epsilon-greedy ------------------------------------------------------------------------------


def test_epsilon_zero_always_takes_the_greedy_action():
    rng = np.random.default_rng(0)
    row = np.array([0.1, 0.7, -0.3])
    assert {epsilon_greedy(row, 0.0, rng) for _ in range(1000)} == {1}


def test_epsilon_one_is_uniform():
    rng = np.random.default_rng(1)
    row = np.array([0.1, 0.7, -0.3, 0.0])
    counts = np.bincount([epsilon_greedy(row, 1.0, rng) for _ in range(N_DRAWS)], minlength=4)
    assert _chi2_pvalue(counts, [0.25] * 4) > 0.001


def test_epsilon_mixes_greedy_and_uniform():
    rng = np.random.default_rng(2)
    row = np.array([0.1, 0.7, -0.3, 0.0])
    counts = np.bincount([epsilon_greedy(row, 0.2, rng) for _ in range(N_DRAWS)], minlength=4)
    # P(greedy) = 1 - 0.2 + 0.2 / 4 = 0.85, every other action 0.2 / 4 = 0.05
    assert _chi2_pvalue(counts, [0.05, 0.85, 0.05, 0.05]) > 0.001


def test_greedy_ties_are_broken_at_random():
    rng = np.random.default_rng(3)
    row = np.array([0.5, 0.2, 0.5, 0.5])
    counts = np.bincount([epsilon_greedy(row, 0.0, rng) for _ in range(N_DRAWS)], minlength=4)
    assert counts[1] == 0
    assert _chi2_pvalue(counts[[0, 2, 3]], [1 / 3] * 3) > 0.001


def test_epsilon_greedy_is_numpys_argmax_with_random_ties():
    """The plain-Python choice takes exactly the action, and the draws, of numpy's formulation."""

    def numpys(q_row, epsilon, rng):
        if rng.random() < epsilon:
            return int(rng.integers(len(q_row)))
        best = np.flatnonzero(q_row == q_row.max())
        return int(best[0]) if len(best) == 1 else int(rng.choice(best))

    g = np.random.default_rng(7)
    ours, theirs = np.random.default_rng(8), np.random.default_rng(8)
    for _ in range(20_000):
        # coarse values, so that ties among the greedy actions are common
        row = g.integers(-2, 3, int(g.integers(1, 6))) * float(g.choice([0.5, 1.0, 1e-300]))
        epsilon = float(g.choice([0.0, 0.1, 1.0]))
        assert epsilon_greedy(row, epsilon, ours) == numpys(row, epsilon, theirs)
    assert ours.random() == theirs.random()  # both drew the same numbers all along


# --- softmax -------------------------------------------------------------------------------------


def test_softmax_probs_by_hand():
    # tau = 0.5: exp(Q / tau) = exp(0), exp(1), exp(2) for Q = 0, 0.5, 1
    p = softmax_probs(np.array([0.0, 0.5, 1.0]), 0.5)
    e = np.array([1.0, math.e, math.e**2])  # sum = 1 + 2.71828 + 7.38906 = 11.10734
    np.testing.assert_allclose(p, e / e.sum(), rtol=1e-12)
    np.testing.assert_allclose(p, [0.090031, 0.244728, 0.665241], atol=1e-6)


def test_softmax_does_not_overflow_at_low_temperature():
    # Q / tau up to 1e4 (exp(1e4) overflows a double): only differences matter
    p = softmax_probs(np.array([50.0, 49.999, 10.0]), 0.005)
    assert np.all(np.isfinite(p))
    # exp((49.999 - 50) / 0.005) = exp(-0.2) = 0.818731; exp(-8000) = 0
    e = np.array([1.0, math.exp(-0.2), 0.0])
    np.testing.assert_allclose(p, e / e.sum(), rtol=1e-12)


def test_softmax_choice_follows_its_probabilities():
    rng = np.random.default_rng(4)
    row = np.array([0.0, 0.5, 1.0])
    counts = np.bincount([softmax_choice(row, 0.5, rng) for _ in range(N_DRAWS)], minlength=3)
    assert _chi2_pvalue(counts, softmax_probs(row, 0.5)) > 0.001


class _Draw:
    """A generator whose uniform draw is fixed."""

    def __init__(self, u: float) -> None:
        self.u = u

    def random(self) -> float:
        return self.u


@pytest.mark.parametrize(("u", "action"), [(0.0, 0), (0.2499, 0), (0.2501, 1), (0.9999, 1)])
def test_softmax_choice_by_hand(u, action):
    # Q = [0, tau ln 3]: probabilities 1/4 and 3/4, cumulative 0.25 and 1
    tau = 0.5
    assert softmax_choice(np.array([0.0, tau * np.log(3.0)]), tau, _Draw(u)) == action


def test_softmax_choice_is_numpys_search_over_the_cumulative_probabilities():
    """The plain-Python draw picks exactly what searching numpy's cumulative sum would."""
    g = np.random.default_rng(1)
    for _ in range(20_000):
        row = g.normal(0.0, g.choice([0.01, 1.0, 100.0]), int(g.integers(2, 6)))
        tau, u = float(g.choice([0.01, 0.1, 1.0, 10.0])), float(g.random())
        expected = min(int(np.searchsorted(np.cumsum(softmax_probs(row, tau)), u, side="right")), len(row) - 1)
        assert softmax_choice(row, tau, _Draw(u)) == expected


def test_softmax_choice_never_picks_an_impossible_action():
    rng = np.random.default_rng(5)
    row = np.array([1.0, 0.0])  # p = (1, exp(-200)) at tau 0.005
    assert {softmax_choice(row, 0.005, rng) for _ in range(1000)} == {0}


# --- policies ------------------------------------------------------------------------------------


def test_tavc_q_tables_start_within_the_init_range():
    rng = np.random.default_rng(6)
    policy = TavcPolicy(
        6,
        2,
        alpha=0.1,
        gamma=0.95,
        selection="egreedy",
        epsilon=0.1,
        tau=0.005,
        q_init=(-0.1, 0.1),
        rng=rng,
    )
    q = policy.q_tables()
    assert q.shape == (6, 2, 2)  # robots x states (class last serviced) x actions (circuits)
    assert np.all((q >= -0.1) & (q <= 0.1))
    assert len(np.unique(q)) == q.size  # random, so ties (and a bias to circuit 0) are unlikely


def test_tavc_learns_only_its_own_table():
    policy = TavcPolicy(
        2,
        2,
        alpha=0.1,
        gamma=0.95,
        selection="egreedy",
        epsilon=0.0,
        tau=0.005,
        q_init=(0.0, 0.0),
        rng=np.random.default_rng(7),
    )
    policy.learn(robot=1, state=0, action=1, reward=2.0, next_state=1)
    q = policy.q_tables()
    # Q(0, 1) = 0 + 0.1 * (2 + 0.95 * 0 - 0) = 0.2, robot 0 untouched
    np.testing.assert_allclose(q[1], [[0.0, 0.2], [0.0, 0.0]])
    np.testing.assert_array_equal(q[0], 0.0)
    assert policy.choose(1, 0) == 1  # greedy now prefers the rewarded circuit
    q[1, 0, 1] = -5.0  # q_tables() hands out a copy
    assert policy.choose(1, 0) == 1


def test_static_policy_follows_its_allocation():
    policy = StaticPolicy([0, 0, 1, 1, 1], 2)
    assert [policy.choose(i, state) for i in range(5) for state in (0, 1)] == [
        0,
        0,
        0,
        0,
        1,
        1,
        1,
        1,
        1,
        1,
    ]
    assert policy.q_tables() is None


def test_even_allocation_by_hand():
    assert even_allocation(6, 2) == [3, 3]
    assert even_allocation(5, 2) == [3, 2]  # the extra robot on the first circuit
    assert even_allocation(7, 3) == [3, 2, 2]


def test_make_policy_static_splits_evenly_or_as_told():
    rng = np.random.default_rng(8)
    even = make_policy(settings_of({"name": "static"}), 5, 2, rng)
    assert [even.choose(i, 0) for i in range(5)] == [0, 0, 0, 1, 1]
    told = make_policy(settings_of({"name": "static", "allocation": [1, 4]}), 5, 2, rng)
    assert [told.choose(i, 0) for i in range(5)] == [0, 1, 1, 1, 1]


def test_make_policy_builds_each_learner():
    rng = np.random.default_rng(9)
    assert isinstance(make_policy(settings_of({"name": "random"}), 3, 2, rng), RandomPolicy)
    soft = make_policy(
        settings_of({"name": "tavc_softmax", "tau": 0.01, "q_init_low": 0.0, "q_init_high": 0.5}), 3, 2, rng
    )
    assert isinstance(soft, TavcPolicy) and soft.selection == "softmax" and soft.tau == 0.01
    assert np.all((soft.q >= 0.0) & (soft.q <= 0.5))
    greedy = make_policy(settings_of({"name": "tavc_egreedy", "epsilon": 0.2}), 3, 2, rng)
    assert greedy.selection == "egreedy" and greedy.epsilon == 0.2
    with pytest.raises(ValueError, match="no task policy"):
        make_policy(LearnerSettings(name="nope"), 3, 2, rng)
    with pytest.raises(TavcError, match="learner.name: must be one of"):
        settings_of({"name": "nope"})


def test_random_policy_is_uniform_over_circuits():
    policy = RandomPolicy(3, np.random.default_rng(10))
    counts = np.bincount([policy.choose(0, 0) for _ in range(N_DRAWS)], minlength=3)
    assert _chi2_pvalue(counts, [1 / 3] * 3) > 0.001


def test_the_registry_keeps_every_learners_label_and_seed_code():
    from tavc_cli.learning.registry import BASELINES, LEARNERS, SEED_CODES, controller_label

    # the seed codes are part of every trial's seed: these values are what finished trials were run with
    assert SEED_CODES == {"tavc": 0, "random": 1, "static": 2, "behaviour": 3, "alternate": 4, "wolf_phc": 5,
                          "threshold": 6, "model": 7, "informed": 8}
    assert controller_label("tavc_softmax") == controller_label("tavc_egreedy") == "tavc"
    assert BASELINES == ("random", "static", "alternate")
    # every entry's policy class loads and declares the constructor the registry calls
    for entry in LEARNERS.values():
        module, cls = entry.policy.split(":")
        assert callable(getattr(importlib.import_module(f"tavc_cli.learning.{module}"), cls).from_settings)


# --- the same draws and choices in compiled code (deliveries served there) -----------------------

@kernel
def _draw_sequence(next_uint32, next_double, state, ns, out):
    """out[k]: a uniform draw where ns[k] == 0, else a draw below ns[k]."""
    for k in range(ns.shape[0]):
        out[k] = uniform(next_double, state) if ns[k] == 0 else below(next_uint32, state, ns[k])


@pytest.mark.parametrize("seed", range(6))
def test_compiled_draws_are_numpys_draw_for_draw(seed):
    # ranges of every kind numpy's bounded integers treat apart: 1 (nothing drawn), small ones,
    # one just under 2**32 whose rejection zone is nearly half of all draws, 2**32 - 1 itself
    # (taken whole), mixed with doubles, and an odd number of 32-bit draws before (a half of a
    # 64-bit draw left in the generator's buffer)
    ns = np.random.default_rng(seed).integers(0, 9, size=400)
    ns[::13] = 2**31 + 1
    ns[::17] = 2**32 - 1
    ns[::19] = 1
    ours, numpys = np.random.default_rng([seed, 7]), np.random.default_rng([seed, 7])
    ours.integers(5)
    numpys.integers(5)
    points = entry_points(ours)
    out = np.zeros(len(ns))
    _draw_sequence(points.next_uint32, points.next_double, points.state, ns, out)
    expected = [numpys.random() if n == 0 else float(numpys.integers(n)) for n in ns]
    np.testing.assert_array_equal(out, expected)
    assert ours.random() == numpys.random()  # and the streams go on alike


@kernel
def _choose(q, epsilon, next_uint32, next_double, state, out):
    for k in range(q.shape[0]):
        out[k] = egreedy(q[k], epsilon, next_uint32, next_double, state)


@pytest.mark.parametrize("epsilon", [0.0, 0.3, 1.0])
def test_compiled_epsilon_greedy_is_pythons_choice_for_choice(epsilon):
    # rows with one best action and rows with two, three or four tied best ones
    rows = np.random.default_rng(1).choice([0.5, 1.0, 2.0, 3.0], size=(300, 4))
    ours, pythons = np.random.default_rng(2), np.random.default_rng(2)
    points = entry_points(ours)
    out = np.zeros(len(rows), dtype=np.int64)
    _choose(rows, epsilon, points.next_uint32, points.next_double, points.state, out)
    expected = [epsilon_greedy(row, epsilon, pythons) for row in rows]
    np.testing.assert_array_equal(out, expected)
    assert ours.random() == pythons.random()
    if epsilon < 1.0:  # ties were met and broken both ways
        assert len({int(a) for a, row in zip(out, rows, strict=True) if (row == row.max()).sum() > 1}) > 1


@kernel
def _boltzmann(q, tau, next_double, state, out):
    for k in range(q.shape[0]):
        out[k] = softmax(q[k], tau, next_double, state)


@pytest.mark.parametrize("tau", [0.005, 0.5, 50.0])
def test_compiled_softmax_is_pythons_choice_for_choice(tau):
    # rows of two to four actions whose Q-values lie from far apart to within the temperature
    # (where every action gets drawn, the cumulative sums' roundings meet the uniform draws)
    rng = np.random.default_rng(4)
    for n in (2, 3, 4):
        rows = rng.uniform(-0.1, 0.1, size=(400, n)) * 10.0 ** rng.integers(-3, 3, size=(400, 1))
        ours, pythons = np.random.default_rng([5, n]), np.random.default_rng([5, n])
        points = entry_points(ours)
        out = np.zeros(len(rows), dtype=np.int64)
        _boltzmann(rows, tau, points.next_double, points.state, out)
        expected = [softmax_choice(row, tau, pythons) for row in rows]
        np.testing.assert_array_equal(out, expected)
        assert ours.random() == pythons.random()
        assert len(set(out.tolist())) == n  # every action was drawn somewhere


def test_compiled_softmax_meets_each_cumulative_sum_as_python_does():
    # a uniform draw placed exactly on each cumulative probability Python sums up: where the
    # compiled sums rounded anywhere differently, the choice at that draw would differ
    rng = np.random.default_rng(6)
    drawn = [0.0]
    fixed = NEXT_DOUBLE(lambda state: drawn[0])  # the generator's next double, as given
    met = 0
    for _ in range(300):
        n, tau = int(rng.integers(2, 5)), float(rng.choice([0.005, 0.5, 50.0]))
        row = rng.uniform(-1.0, 1.0, n) * tau * float(rng.uniform(0.1, 10.0))
        top = max(row.tolist())
        e = [math.exp((v - top) / tau) for v in row.tolist()]
        total = 0.0
        for v in e:
            total += v
        cumulative = 0.0
        for v in e[:-1]:
            cumulative += v / total
            for u in (cumulative, math.nextafter(cumulative, 0.0), math.nextafter(cumulative, 1.0)):
                drawn[0] = u
                assert softmax(row, tau, fixed, 0) == softmax_choice(row, tau, _Draw(u)), (row, tau, u)
                met += 1
    assert met > 1000


def test_compiled_q_update_is_pythons_bit_for_bit():
    # rewards over six orders of magnitude, so that any other order of the operations rounds
    # differently somewhere
    rng = np.random.default_rng(3)
    ours = rng.uniform(0, 1, size=(2, 2))
    pythons = ours.copy()
    for _ in range(2000):
        s, a = (int(x) for x in rng.integers(2, size=2))
        reward = float(rng.uniform(0, 1) * 10.0 ** rng.uniform(-3, 3))
        alpha, gamma = (float(x) for x in rng.choice([0.1, 0.5, 1.0], size=2))
        q_learn(ours, s, a, reward, a, alpha, gamma)
        q_update(pythons, s, a, reward, a, alpha, gamma)
    np.testing.assert_array_equal(ours, pythons)
