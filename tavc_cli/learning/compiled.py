"""The task policies' choices and Q-learning in compiled code, for deliveries served there.

Each kernel does what its Python twin (`policies`, `qlearning`) does, in the same order
and with the same roundings, drawing from the same generator (`draws`), so that a delivery
served in compiled code and one served in Python leave the same tables, the same stream
and the same record. Section 1.4's behaviour learners are served in Python only
(`POLICY_PYTHON`).
"""

from __future__ import annotations

import math

from tavc_cli.kernel import kernel
from tavc_cli.learning.draws import below, uniform
from tavc_cli.learning.policies import RandomPolicy, StaticPolicy, TaskPolicy, TavcPolicy

# which policy a trial's deliveries are served by in compiled code
POLICY_PYTHON, POLICY_EGREEDY, POLICY_RANDOM, POLICY_STATIC, POLICY_SOFTMAX = range(5)


def policy_kind(policy: TaskPolicy) -> int:
    """How compiled code serves this policy's deliveries (`POLICY_*`): the compiled paths serve the
    exact built-in policies only; any other class, a subclass of one of them included, runs its
    own `choose` and `learn` in Python."""
    kind = type(policy)
    if kind is TavcPolicy:
        return {"egreedy": POLICY_EGREEDY, "softmax": POLICY_SOFTMAX}.get(policy.selection, POLICY_PYTHON)
    if kind is RandomPolicy:
        return POLICY_RANDOM
    if kind is StaticPolicy:
        return POLICY_STATIC
    return POLICY_PYTHON


@kernel(inline="always")
def row_max(q_row):
    """The largest value of a row, as Python's max gives it (the first of equals)."""
    top = q_row[0]
    for b in range(1, q_row.shape[0]):
        if q_row[b] > top:
            top = q_row[b]
    return top


@kernel
def q_learn(q, state, action, reward, next_state, alpha, gamma):
    """`qlearning.q_update` on one robot's table q (n_states, n_actions), in place."""
    q_sa = q[state, action]
    q[state, action] = q_sa + alpha * (reward + gamma * row_max(q[next_state]) - q_sa)


@kernel
def egreedy(q_row, epsilon, next_uint32, next_double, rng):
    """`qlearning.epsilon_greedy`: a random action with probability epsilon, else the
    greedy one, ties broken by a draw among them."""
    n = q_row.shape[0]
    if uniform(next_double, rng) < epsilon:
        return below(next_uint32, rng, n)
    top = row_max(q_row)
    ties = 0
    for b in range(n):
        ties += q_row[b] == top
    pick = 0 if ties == 1 else below(next_uint32, rng, ties)
    for b in range(n):
        if q_row[b] == top:
            if pick == 0:
                return b
            pick -= 1
    return n - 1  # not reached: one action holds the maximum


@kernel
def softmax(q_row, tau, next_double, rng):
    """`qlearning.softmax_choice`: the first action whose cumulative Boltzmann probability
    exceeds a uniform draw. Each exp(Q/tau) is the C library's, as Python's math.exp is, and is
    computed again in the second pass rather than kept (the same number; no array to allocate)."""
    n = q_row.shape[0]
    top = row_max(q_row)
    total = 0.0
    for b in range(n):
        total += math.exp((q_row[b] - top) / tau)
    u = uniform(next_double, rng)
    cumulative, chosen = 0.0, 0
    for b in range(n):
        cumulative += math.exp((q_row[b] - top) / tau) / total
        if cumulative <= u:
            chosen = b + 1
    return min(chosen, n - 1)
