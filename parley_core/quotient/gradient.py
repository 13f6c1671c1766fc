"""The compiled loops of policy improvement (:mod:`parley_core.quotient.improve` says what
they compute and why): which states a policy can be at after one deviation, its values by
backward induction there, and its occupancy forward with every decision value's score."""

from __future__ import annotations

import numpy as np
from numba import njit


@njit(cache=True)
def _step_rewards(rewards, rows, steps, coefficients, t, action, out):
    """Each channel's weighted reward of ``action`` at step ``t`` into ``out``."""
    for c in range(coefficients.shape[0]):
        value = 0.0
        for i in range(rows.shape[0]):
            if t < steps[i]:
                value += coefficients[c, i] * rewards[rows[i], action]
        out[c] = value


@njit(cache=True)
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


@njit(cache=True)
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


@njit(cache=True)
def chosen_rewards(rewards, rows, steps, coefficients, t, chosen, out):
    """Each channel's weighted reward of every state's chosen action at step ``t`` into ``out``."""
    for s in range(chosen.shape[0]):
        _step_rewards(rewards, rows, steps, coefficients, t, chosen[s], out[s])


@njit(cache=True)
def back_step(t, horizon, listed, chosen, action_entries, targets, probabilities, reward, has_until, left, right,
              until_steps, gain, terminal, a_next, b_next, a_now, b_now):  # fmt: skip
    """One step of backward induction, per channel (column), for the policy whose action at
    state ``s`` is ``chosen[s]`` (earning ``reward[s]`` now): ``b`` the value once the
    reachability objective is settled (or when there is none), ``a`` the value while it is
    not (reaching it is worth ``gain``, and past the horizon of an unbounded one ``terminal[s]``),
    at the ``listed`` states only."""
    channels = reward.shape[1]
    for s in listed:
        action = chosen[s]
        first, last = action_entries[action], action_entries[action + 1]
        for c in range(channels):
            vb = reward[s, c]
            if t < horizon:
                for e in range(first, last):
                    vb += probabilities[e] * b_next[targets[e], c]
            b_now[s, c] = vb
            if not has_until or (until_steps >= 0 and t > until_steps):
                a_now[s, c] = vb
            elif right[s]:
                a_now[s, c] = gain[c] + vb
            elif not left[s] or (until_steps >= 0 and t == until_steps):
                a_now[s, c] = vb
            elif t == horizon and until_steps < 0:
                a_now[s, c] = terminal[s, c] + vb
            else:
                va = reward[s, c]
                if t < horizon:
                    for e in range(first, last):
                        va += probabilities[e] * a_next[targets[e], c]
                a_now[s, c] = va


@njit(cache=True)
def forward_step(t, horizon, listed, chosen, state_actions, action_entries, targets, probabilities, rewards, rows, steps,
                 coefficients, has_until, left, right, until_steps, a_next, b_next, state_decisions, decisions,
                 sizes, ma, mb, na, nb, score, same, stamp, known):  # fmt: skip
    """Add to ``score[c, d, k]`` the value (channel ``c``) of moving, at the states with mass
    at step ``t`` that consult ``d``, to the action that gives ``d`` the value ``k`` and
    keeps the policy's other values, weighted by the mass (``ma``: mass still counting for
    the reachability objective, ``mb``: the rest); then move the mass one step along the
    policy's actions into ``na``, ``nb`` (zeroed by the caller). An action's value is
    computed once per state and mode (``known[same[action]]``, valid where ``stamp`` says so)."""
    channels = coefficients.shape[0]
    q = np.empty(channels)
    visit = stamp[0]
    for s in listed:
        for mode in range(2):
            mass = ma[s] if mode == 0 else mb[s]
            if mass == 0.0:
                continue
            visit += 1
            pending = mode == 0 and has_until and not _leaves(t, s, horizon, left, right, until_steps)
            base = state_actions[s]
            local = chosen[s] - base
            radix = 1
            rest = local
            for i in range(state_decisions[s], state_decisions[s + 1]):
                d = decisions[i]
                digit = rest % sizes[d]
                rest //= sizes[d]
                for value in range(sizes[d]):
                    action = same[base + local + (value - digit) * radix]
                    if stamp[action + 1] != visit:
                        _step_rewards(rewards, rows, steps, coefficients, t, action, q)
                        if t < horizon:
                            for e in range(action_entries[action], action_entries[action + 1]):
                                p = probabilities[e]
                                for c in range(channels):
                                    q[c] += p * (a_next[targets[e], c] if pending else b_next[targets[e], c])
                        known[action] = q
                        stamp[action + 1] = visit
                    for c in range(channels):
                        score[c, d, value] += mass * known[action, c]
                radix *= sizes[d]
            if t < horizon:
                action = chosen[s]
                for e in range(action_entries[action], action_entries[action + 1]):
                    if pending:
                        na[targets[e]] += mass * probabilities[e]
                    else:
                        nb[targets[e]] += mass * probabilities[e]
    stamp[0] = visit


@njit(cache=True)
def backward(pointers, listed, horizon, chosen, action_entries, targets, probabilities, rewards_by_window, window,
             has_until, left, right, until_steps, gain, terminal, values, next_a, next_b, now_a, now_b):  # fmt: skip
    """:func:`back_step` from the horizon down to step 0 at the states :func:`deviations`
    lists, step ``t``'s values kept only there (``values[i]``: the ``a`` and ``b`` values of
    the ``i``-th listed entry); the dense ``next``/``now`` arrays carry one step to the next
    (one call: a numba call per step costs more than its work)."""
    channels = next_a.shape[1]
    next_a[:] = 0.0
    next_b[:] = 0.0
    for t in range(horizon, -1, -1):
        here = listed[pointers[t] : pointers[t + 1]]
        back_step(t, horizon, here, chosen, action_entries, targets, probabilities, rewards_by_window[window[t]],
                  has_until, left, right, until_steps, gain, terminal, next_a, next_b, now_a, now_b)  # fmt: skip
        for i in range(pointers[t], pointers[t + 1]):
            s = listed[i]
            for c in range(channels):
                values[i, 0, c] = now_a[s, c]
                values[i, 1, c] = now_b[s, c]
        next_a, now_a = now_a, next_a
        next_b, now_b = now_b, next_b


@njit(cache=True)
def forward(pointers, listed, on_policy, horizon, chosen, state_actions, action_entries, targets, probabilities,
            rewards, rows, steps, coefficients, has_until, left, right, until_steps, state_decisions, decisions,
            sizes, masses, score, same, stamp, known, values, following_a, following_b):  # fmt: skip
    """:func:`forward_step` for every step, the values of step ``t + 1`` spread from
    ``values`` into the dense ``following`` arrays first (the successors the step reads are
    all listed at ``t + 1``), the occupancy in ``masses[t % 2]`` (moved into
    ``masses[1 - t % 2]``, and zeroed behind it)."""
    channels = following_a.shape[1]
    for t in range(horizon + 1):
        if t < horizon:
            for i in range(pointers[t + 1], pointers[t + 2]):
                s = listed[i]
                for c in range(channels):
                    following_a[s, c] = values[i, 0, c]
                    following_b[s, c] = values[i, 1, c]
        first, last = pointers[t], pointers[t + 1]
        count = 0
        for i in range(first, last):
            count += on_policy[i]
        here = np.empty(count, dtype=np.int64)
        j = 0
        for i in range(first, last):
            if on_policy[i]:
                here[j] = listed[i]
                j += 1
        mass, moved = masses[t % 2], masses[1 - t % 2]
        forward_step(t, horizon, here, chosen, state_actions, action_entries, targets, probabilities, rewards, rows,
                     steps, coefficients, has_until, left, right, until_steps, following_a, following_b,
                     state_decisions, decisions, sizes, mass[0], mass[1], moved[0], moved[1], score, same, stamp,
                     known)  # fmt: skip
        for s in here:
            mass[0, s] = 0.0
            mass[1, s] = 0.0
