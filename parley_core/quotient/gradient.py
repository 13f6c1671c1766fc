"""The compiled loops of policy improvement (:mod:`parley_core.quotient.improve` says what
they compute and why): which states a policy can be at after one deviation, its values by
backward induction there, and its occupancy forward with every decision value's score."""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numba import njit


@njit(cache=True, nogil=True)
def _step_rewards(rewards, rows, steps, coefficients, t, action, out):
    """Each channel's weighted reward of ``action`` at step ``t`` into ``out``."""
    for c in range(coefficients.shape[0]):
        value = 0.0
        for i in range(rows.shape[0]):
            if t < steps[i]:
                value += coefficients[c, i] * rewards[rows[i], action]
        out[c] = value


@njit(cache=True, nogil=True)
def _leaves(t, s, horizon, left, right, until_steps):
    """Whether probability mass not yet at the reachability target stops counting for it at
    state ``s`` and step ``t`` (it reached the target, left ``left``, or ran out of steps),
    exactly where :func:`~parley_core.quotient.subfamily.weighted_horizon` switches values."""
    if until_steps >= 0 and t >= until_steps:
        return True
    if right[s] or not left[s]:
        return True
    return t == horizon and until_steps < 0


@njit(cache=True)
def representatives(state_actions, action_entries, targets, probabilities, rewards):
    """Per action the first action of its state with the same entries and rewards (itself if
    none): on map_10 the ten values of an interval give two distinct actions, localise or not."""
    out = np.arange(action_entries.shape[0] - 1)
    for s in range(state_actions.shape[0] - 1):
        for a in range(state_actions[s] + 1, state_actions[s + 1]):
            for b in range(state_actions[s], a):
                if out[b] != b:
                    continue
                if action_entries[a + 1] - action_entries[a] != action_entries[b + 1] - action_entries[b]:
                    continue
                same = True
                for i in range(rewards.shape[0]):
                    if rewards[i, a] != rewards[i, b]:
                        same = False
                        break
                offset = action_entries[b] - action_entries[a]
                for e in range(action_entries[a], action_entries[a + 1]):
                    if not same:
                        break
                    same = targets[e] == targets[e + offset] and probabilities[e] == probabilities[e + offset]
                if same:
                    out[a] = b
                    break
    return out


@njit(cache=True, nogil=True)
def deviations(initial, horizon, chosen, state_actions, action_entries, targets, state_decisions, same):
    """Per step ``t`` the states where the policy, deviating at most once at a state that
    consults a decision, can be at step ``t`` (CSR: pointers, flat list), with a flag for
    those where the policy itself can be: the only states whose values at ``t`` the scores
    read, and the only ones with mass."""
    n = chosen.shape[0]
    seen = np.full(n, -1, dtype=np.int64)  # the last step a state was listed at
    where = np.zeros(n, dtype=np.int64)  # its place in the list then
    pointers = np.zeros(horizon + 2, dtype=np.int64)
    capacity = 4 * n
    flat = np.empty(capacity, dtype=np.int64)
    policy = np.zeros(capacity, dtype=np.bool_)
    flat[0] = initial
    policy[0] = True
    pointers[1] = 1
    seen[initial] = 0
    for t in range(horizon):
        size = pointers[t + 1]
        for i in range(pointers[t], pointers[t + 1]):
            s = flat[i]
            deviate = policy[i] and state_decisions[s + 1] > state_decisions[s]
            first = state_actions[s] if deviate else chosen[s]
            last = state_actions[s + 1] if deviate else chosen[s] + 1
            for action in range(first, last):
                if same[action] != action and action != chosen[s]:
                    continue  # its successors are those of an action before it
                followed = policy[i] and action == chosen[s]
                for e in range(action_entries[action], action_entries[action + 1]):
                    target = targets[e]
                    if seen[target] == t + 1:
                        if followed:
                            policy[where[target]] = True
                        continue
                    if size == capacity:
                        capacity *= 2
                        grown = np.empty(capacity, dtype=np.int64)
                        grown[:size] = flat[:size]
                        flat = grown
                        grown_policy = np.zeros(capacity, dtype=np.bool_)
                        grown_policy[:size] = policy[:size]
                        policy = grown_policy
                    seen[target] = t + 1
                    where[target] = size
                    flat[size] = target
                    policy[size] = followed
                    size += 1
        pointers[t + 2] = size
    total = pointers[horizon + 1]
    return pointers, flat[:total].copy(), policy[:total].copy()


@njit(cache=True, nogil=True)
def chosen_rewards(rewards, rows, steps, coefficients, t, chosen, out):
    """Each channel's weighted reward of every state's chosen action at step ``t`` into ``out``."""
    for s in range(chosen.shape[0]):
        _step_rewards(rewards, rows, steps, coefficients, t, chosen[s], out[s])


class Relaxed(NamedTuple):
    """The relaxation's arrays the scores walk (a :class:`~parley_core.quotient.relaxation.Relaxation`'s):
    per state its actions, per action its entries (``targets``, ``probabilities``), and per
    state the decisions its actions mention (CSR into ``decisions``)."""

    state_actions: np.ndarray
    action_entries: np.ndarray
    targets: np.ndarray
    probabilities: np.ndarray
    state_decisions: np.ndarray
    decisions: np.ndarray


class Reach(NamedTuple):
    """The reachability objective of the weighted sum, if there is one (``has_until``): the
    states of ``left U right``, and its step bound (negative: unbounded)."""

    has_until: bool
    left: np.ndarray
    right: np.ndarray
    until_steps: int


class StepRewards(NamedTuple):
    """The weighted sum's step-bounded rewards: reward ``rows`` of ``rewards`` within
    ``steps`` each, weighted per channel by ``coefficients``."""

    rewards: np.ndarray
    rows: np.ndarray
    steps: np.ndarray
    coefficients: np.ndarray


class Listing(NamedTuple):
    """What :func:`deviations` lists: per step the states (CSR ``pointers`` into ``listed``)
    and whether the policy itself can be there (``on_policy``)."""

    pointers: np.ndarray
    listed: np.ndarray
    on_policy: np.ndarray


class Dense(NamedTuple):
    """One step's values and the next's, dense over the states [states, channels]: what
    carries :func:`backward` from one step to the next (``a``: the reachability objective not
    yet settled, ``b``: settled)."""

    next_a: np.ndarray
    next_b: np.ndarray
    now_a: np.ndarray
    now_b: np.ndarray


@njit(cache=True, nogil=True)
def backward(listing, horizon, chosen, relaxed, rewards_by_window, window, reach, gain, terminal, values, dense):
    """Backward induction from the horizon down to step 0 at the states :func:`deviations`
    lists, per channel (column), for the policy whose action at state ``s`` is ``chosen[s]``:
    ``b`` the value once the reachability objective is settled (or when there is none), ``a``
    the value while it is not (reaching it is worth ``gain``, and past the horizon of an
    unbounded one ``terminal[s]``). Step ``t``'s values are kept only at its listed entries
    (``values[i]``: the ``a`` and ``b`` values of the ``i``-th); the dense ``next``/``now``
    arrays carry one step to the next. One call for all steps (a numba call per step costs
    more than its work), and one pass over an action's entries for both values."""
    pointers, listed = listing.pointers, listing.listed
    action_entries, targets, probabilities = relaxed.action_entries, relaxed.targets, relaxed.probabilities
    has_until, left, right, until_steps = reach
    next_a, next_b, now_a, now_b = dense
    channels = next_a.shape[1]
    next_a[:] = 0.0
    next_b[:] = 0.0
    vb = np.empty(channels)
    va = np.empty(channels)
    for t in range(horizon, -1, -1):
        reward = rewards_by_window[window[t]]
        settled = not has_until or (until_steps >= 0 and t > until_steps)
        for i in range(pointers[t], pointers[t + 1]):
            s = listed[i]
            action = chosen[s]
            first, last = action_entries[action], action_entries[action + 1]
            # which value ``a`` takes here: 0 the same as b, 1 gain + b, 2 terminal + b, 3 its own sum
            if settled:
                kind = 0
            elif right[s]:
                kind = 1
            elif not left[s] or (until_steps >= 0 and t == until_steps):
                kind = 0
            elif t == horizon and until_steps < 0:
                kind = 2
            else:
                kind = 3
            for c in range(channels):
                vb[c] = reward[s, c]
                va[c] = reward[s, c]
            if t < horizon:
                if kind == 3:
                    for e in range(first, last):
                        p = probabilities[e]
                        target = targets[e]
                        for c in range(channels):
                            vb[c] += p * next_b[target, c]
                            va[c] += p * next_a[target, c]
                else:
                    for e in range(first, last):
                        p = probabilities[e]
                        target = targets[e]
                        for c in range(channels):
                            vb[c] += p * next_b[target, c]
            for c in range(channels):
                b = vb[c]
                if kind == 0:
                    a = b
                elif kind == 1:
                    a = gain[c] + b
                elif kind == 2:
                    a = terminal[s, c] + b
                else:
                    a = va[c]
                now_a[s, c] = a
                now_b[s, c] = b
                values[i, 0, c] = a
                values[i, 1, c] = b
        next_a, now_a = now_a, next_a
        next_b, now_b = now_b, next_b


@njit(cache=True, nogil=True)
def forward(listing, horizon, chosen, relaxed, step_rewards, reach, sizes, same, work, values, following):
    """The policy's occupancy forward from the initial state, step by step, with the scores:
    at step ``t``, add to ``score[c, d, k]`` the value (channel ``c``) of moving, at the
    states with mass that consult ``d``, to the action that gives ``d`` the value ``k`` and
    keeps the policy's other values, weighted by the mass (``masses[t % 2][0]``: mass still
    counting for the reachability objective, ``[1]``: the rest); then move the mass one step
    along the policy's actions into ``masses[1 - t % 2]``. The values of step ``t + 1`` are
    spread from ``values`` into the dense ``following`` arrays first (the successors the
    step reads are all listed at ``t + 1``). An action's value is computed once per state
    and mode (``known[same[action]]``, valid where ``stamp`` says so); ``work`` is
    (``masses``, ``score``, ``stamp``, ``known``), ``following`` the two dense arrays."""
    pointers, listed, on_policy = listing
    state_actions, action_entries, targets, probabilities, state_decisions, decisions = relaxed
    rewards, rows, steps, coefficients = step_rewards
    has_until, left, right, until_steps = reach
    masses, score, stamp, known = work
    following_a, following_b = following
    channels = following_a.shape[1]
    q = np.empty(channels)
    local_score = np.zeros((score.shape[1], score.shape[2], channels))  # contiguous per value
    visit = stamp[0]
    for t in range(horizon + 1):
        if t < horizon:
            for i in range(pointers[t + 1], pointers[t + 2]):
                s = listed[i]
                for c in range(channels):
                    following_a[s, c] = values[i, 0, c]
                    following_b[s, c] = values[i, 1, c]
        mass_now, mass_next = masses[t % 2], masses[1 - t % 2]
        for i in range(pointers[t], pointers[t + 1]):
            if not on_policy[i]:
                continue
            s = listed[i]
            for mode in range(2):
                mass = mass_now[mode, s]
                if mass == 0.0:
                    continue
                visit += 1
                pending = mode == 0 and has_until and not _leaves(t, s, horizon, left, right, until_steps)
                following = following_a if pending else following_b
                base = state_actions[s]
                local = chosen[s] - base
                radix = 1
                rest = local
                for j in range(state_decisions[s], state_decisions[s + 1]):
                    d = decisions[j]
                    digit = rest % sizes[d]
                    rest //= sizes[d]
                    for value in range(sizes[d]):
                        action = same[base + local + (value - digit) * radix]
                        if stamp[action + 1] != visit:
                            _step_rewards(rewards, rows, steps, coefficients, t, action, q)
                            if t < horizon:
                                for e in range(action_entries[action], action_entries[action + 1]):
                                    p = probabilities[e]
                                    target = targets[e]
                                    for c in range(channels):
                                        q[c] += p * following[target, c]
                            for c in range(channels):
                                known[action, c] = q[c]
                            stamp[action + 1] = visit
                        for c in range(channels):
                            local_score[d, value, c] += mass * known[action, c]
                    radix *= sizes[d]
                if t < horizon:
                    action = chosen[s]
                    moved = mass_next[0] if pending else mass_next[1]
                    for e in range(action_entries[action], action_entries[action + 1]):
                        moved[targets[e]] += mass * probabilities[e]
            mass_now[0, s] = 0.0
            mass_now[1, s] = 0.0
    stamp[0] = visit
    for c in range(channels):
        for d in range(score.shape[1]):
            for value in range(score.shape[2]):
                score[c, d, value] += local_score[d, value, c]
