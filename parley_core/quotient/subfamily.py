"""Sound bounds of a sub-family, by compiled iterations on the quotient's relaxation.

A sub-family keeps, for each decision, an interval of its domain (indices ``lo..hi``). On
the relaxation (:mod:`parley_core.quotient.relaxation`) it keeps the actions whose
assignment lies in the intervals; every policy of the sub-family is one memoryless
scheduler of what is left, so the best value over all its schedulers bounds every policy's.

Every number these kernels return is on the safe side by construction, not by convergence:

- the probability to reach (``phi U psi``), maximised, is iterated *from above*: starting
  from 1 on the states that can reach ``psi`` at all, every Gauss-Seidel iterate is a
  pre-fixpoint of the Bellman operator and so lies above the least fixpoint, the value;
  minimised, it is iterated from 0, and every iterate lies below the value;
- minimised expected rewards (``F psi``, ``C``) are iterated from 0 (infinity where ``psi``
  cannot be reached): every iterate is below the value;
- step-bounded objectives and weighted sums of them are solved by backward induction over
  the horizon, exactly up to rounding; an unbounded reachability objective in a weighted sum
  continues past the horizon with its bound from the iteration above.

Values are in *sign space*: every objective maximised (a minimised one negated), and a
weighted sum is ``sum_i w_i * sign_i * value_i`` with ``w >= 0``.
"""

from __future__ import annotations

import numpy as np
from numba import njit


@njit(cache=True, nogil=True)
def allowed_actions(state_actions, state_decisions, decisions, domain_sizes, lo, hi):
    """Which actions of the relaxation the sub-family ``lo..hi`` keeps."""
    states = state_actions.shape[0] - 1
    out = np.zeros(state_actions[states], dtype=np.bool_)
    for s in range(states):
        for a in range(state_actions[s], state_actions[s + 1]):
            local = a - state_actions[s]
            keep = True
            for i in range(state_decisions[s], state_decisions[s + 1]):
                d = decisions[i]
                digit = local % domain_sizes[d]
                local //= domain_sizes[d]
                if digit < lo[d] or digit > hi[d]:
                    keep = False
                    break
            out[a] = keep
    return out


@njit(cache=True)
def reachable(initial, state_actions, action_entries, targets, allowed):
    """The states some scheduler of the sub-family reaches from the initial state."""
    states = state_actions.shape[0] - 1
    seen = np.zeros(states, dtype=np.bool_)
    stack = np.empty(states, dtype=np.int64)
    seen[initial] = True
    stack[0] = initial
    top = 1
    while top > 0:
        top -= 1
        s = stack[top]
        for a in range(state_actions[s], state_actions[s + 1]):
            if not allowed[a]:
                continue
            for e in range(action_entries[a], action_entries[a + 1]):
                t = targets[e]
                if not seen[t]:
                    seen[t] = True
                    stack[top] = t
                    top += 1
    return seen


@njit(cache=True, nogil=True)
def can_reach(pred_ptr, pred_state, pred_action, allowed, live, left, right):
    """The ``live`` states from which some scheduler reaches ``right`` through ``left``."""
    states = pred_ptr.shape[0] - 1
    mark = np.zeros(states, dtype=np.bool_)
    stack = np.empty(states, dtype=np.int64)
    top = 0
    for s in range(states):
        if right[s] and live[s]:
            mark[s] = True
            stack[top] = s
            top += 1
    while top > 0:
        top -= 1
        t = stack[top]
        for i in range(pred_ptr[t], pred_ptr[t + 1]):
            s = pred_state[i]
            if mark[s] or not left[s] or not live[s] or not allowed[pred_action[i]]:
                continue
            mark[s] = True
            stack[top] = s
            top += 1
    return mark


@njit(cache=True, fastmath=False, nogil=True)
def reach_probability(state_actions, action_entries, targets, probabilities, allowed, live, left, right, maximise,
                      pred_ptr, pred_state, pred_action, tolerance, max_sweeps):  # fmt: skip
    """Per state a sound bound on the best probability of ``left U right``: from above when
    ``maximise`` (an upper bound of the maximum), from below otherwise (a lower bound of the
    minimum)."""
    states = state_actions.shape[0] - 1
    reach = can_reach(pred_ptr, pred_state, pred_action, allowed, live, left, right)
    x = np.zeros(states)
    for s in range(states):
        if right[s]:
            x[s] = 1.0
        elif reach[s] and maximise:
            x[s] = 1.0
    for sweep in range(max_sweeps):
        change = 0.0
        for k in range(states):
            s = k if sweep % 2 == 0 else states - 1 - k
            if right[s] or not reach[s]:
                continue
            best = -1.0 if maximise else 2.0
            for a in range(state_actions[s], state_actions[s + 1]):
                if not allowed[a]:
                    continue
                v = 0.0
                for e in range(action_entries[a], action_entries[a + 1]):
                    v += probabilities[e] * x[targets[e]]
                if maximise:
                    best = max(best, v)
                else:
                    best = min(best, v)
            if best < 0.0 or best > 1.0:
                continue  # no allowed action: not reachable in this sub-family
            if maximise:
                best = min(best, x[s])  # rounding must not lift an iterate from above
            else:
                best = max(best, x[s])
            change = max(change, abs(best - x[s]))
            x[s] = best
        if change <= tolerance:
            break
    return x


@njit(cache=True)
def min_reward(state_actions, action_entries, targets, probabilities, allowed, live, rewards, row, right,
               has_right, pred_ptr, pred_state, pred_action, tolerance, max_sweeps):  # fmt: skip
    """Per state a lower bound on the least expected reward until ``right`` (``has_right``;
    infinity where it cannot be reached) or in total: iterated from 0."""
    states = state_actions.shape[0] - 1
    x = np.zeros(states)
    if has_right:
        everywhere = np.ones(states, dtype=np.bool_)
        reach = can_reach(pred_ptr, pred_state, pred_action, allowed, live, everywhere, right)
        for s in range(states):
            if not reach[s]:
                x[s] = np.inf
    min_reward_from(state_actions, action_entries, targets, probabilities, allowed, live, rewards[row], right,
                    has_right, x, tolerance, max_sweeps)  # fmt: skip
    return x


@njit(cache=True)
def min_reward_from(state_actions, action_entries, targets, probabilities, allowed, live, reward, right, has_right,
                    x, tolerance, max_sweeps):  # fmt: skip
    """Gauss-Seidel sweeps of the least expected reward, in place from ``x``: if ``x`` is below
    every scheduler's value (0 is; so is a checked post-fixpoint, :func:`post_fixpoint`),
    every iterate is, for each update is at most what any scheduler's choice gives."""
    states = state_actions.shape[0] - 1
    for sweep in range(max_sweeps):
        change = 0.0
        for k in range(states):
            s = k if sweep % 2 == 0 else states - 1 - k
            if not live[s] or (has_right and right[s]) or np.isinf(x[s]):
                continue
            best = least_action(state_actions, action_entries, targets, probabilities, allowed, reward, x, s, -1)[0]
            best = max(best, x[s])
            if np.isinf(best):
                change = np.inf
            else:
                change = max(change, best - x[s])
            x[s] = best
        if change <= tolerance:
            break


@njit(cache=True)
def least_action(state_actions, action_entries, targets, probabilities, allowed, reward, x, s, current):
    """At state ``s``, the least over allowed actions of the reward plus the expected ``x``
    after it, the action that gives it (-1 if none is allowed), and what action ``current``
    gives (infinity if it is not one of them)."""
    best = np.inf
    arg = -1
    kept = np.inf
    for a in range(state_actions[s], state_actions[s + 1]):
        if not allowed[a]:
            continue
        v = reward[a]
        for e in range(action_entries[a], action_entries[a + 1]):
            v += probabilities[e] * x[targets[e]]
        if a == current:
            kept = v
        if v < best:
            best = v
            arg = a
    return best, arg, kept


@njit(cache=True)
def greedy(state_actions, action_entries, targets, probabilities, allowed, free, reward, x, current, keep):
    """Per state of ``free`` the allowed action least in expected reward given ``x`` (-1
    elsewhere); the ``current`` one (if not -1) unless another is less by more than 1e-12 of
    its value, so that policy iteration does not cycle between ties, or whatever its value
    with ``keep``."""
    states = state_actions.shape[0] - 1
    out = np.full(states, -1, dtype=np.int64)
    for s in range(states):
        if not free[s]:
            continue
        best, out[s], kept = least_action(
            state_actions, action_entries, targets, probabilities, allowed, reward, x, s, current[s]
        )
        if current[s] >= 0 and allowed[current[s]] and (keep or kept <= best + 1e-12 * abs(best)):
            out[s] = current[s]
    return out


@njit(cache=True)
def post_fixpoint(state_actions, action_entries, targets, probabilities, allowed, free, reward, y, max_passes):
    """Lower ``y`` (>= 0, in place) on ``free`` until every allowed action of every free state
    gives at least ``y`` there, with a margin of 1e-13 of its value for rounding: then ``y`` is
    below every value of an expected reward to reach a target (0 outside ``free``) that a
    scheduler reaching it almost surely has (``y <= r + P y`` along any such scheduler, summed
    over its steps), and schedulers that do not have infinite values. False if ``max_passes``
    did not settle it."""
    states = state_actions.shape[0] - 1
    for _ in range(max_passes):
        lowered = False
        for s in range(states):
            if not free[s] or np.isinf(y[s]):
                continue
            best = least_action(state_actions, action_entries, targets, probabilities, allowed, reward, y, s, -1)[0]
            best = best * (1.0 - 1e-13)
            if y[s] > best:
                y[s] = max(best, 0.0)
                lowered = True
        if not lowered:
            return True
    return False


@njit(cache=True)
def compact(state_actions, action_entries, targets, probabilities, allowed, live):
    """The sub-family's part of the relaxation as its own CSR: per reached state (in order)
    its allowed actions (with their index in the relaxation) and their entries."""
    states = state_actions.shape[0] - 1
    n_states = n_actions = n_entries = 0
    for s in range(states):
        if not live[s]:
            continue
        n_states += 1
        for a in range(state_actions[s], state_actions[s + 1]):
            if allowed[a]:
                n_actions += 1
                n_entries += action_entries[a + 1] - action_entries[a]
    order = np.empty(n_states, dtype=np.int64)
    state_ptr = np.zeros(n_states + 1, dtype=np.int64)
    action_of = np.empty(n_actions, dtype=np.int64)
    entry_ptr = np.zeros(n_actions + 1, dtype=np.int64)
    out_targets = np.empty(n_entries, dtype=np.int64)
    out_probabilities = np.empty(n_entries)
    i = j = e = 0
    for s in range(states):
        if not live[s]:
            continue
        order[i] = s
        for a in range(state_actions[s], state_actions[s + 1]):
            if not allowed[a]:
                continue
            action_of[j] = a
            for x in range(action_entries[a], action_entries[a + 1]):
                out_targets[e] = targets[x]
                out_probabilities[e] = probabilities[x]
                e += 1
            j += 1
            entry_ptr[j] = e
        i += 1
        state_ptr[i] = j
    return order, state_ptr, action_of, entry_ptr, out_targets, out_probabilities


@njit(cache=True, nogil=True)
def weighted_horizon(order, state_ptr, action_of, entry_ptr, targets, probabilities, states, rewards, rows, steps,
                     coefficients, horizon, has_until, left, right, until_steps, gain, terminal, initial):  # fmt: skip
    """The best weighted sum (sign space) of step-bounded cumulative rewards (``rows``,
    ``steps``; reward i weighs ``coefficients[i]``) and at most one reachability objective
    (``left U right`` within ``until_steps`` steps, or unbounded: -1; reaching ``right``
    gains ``gain``; past the horizon an unbounded one is worth ``terminal[s]``), over all
    schedulers of the sub-family (``compact``'s arrays; history-dependent schedulers too, so
    the value bounds every policy's): backward induction over ``horizon`` steps, with a second
    value for "not yet reached". One weighting in scalars: :func:`weighted_horizons` solves
    several at once (three times as slow for one, twice as fast a weighting for eight, on a
    50x50 robot map), with the same arithmetic, so the same values."""
    n_actions = action_of.shape[0]
    b_next = np.zeros(states)
    a_next = np.zeros(states)
    b_now = np.zeros(states)
    a_now = np.zeros(states)
    step_reward = np.zeros(n_actions)
    for t in range(horizon, -1, -1):
        if t == horizon or any_step(steps, t):
            for j in range(n_actions):
                r = 0.0
                for i in range(rows.shape[0]):
                    if t < steps[i]:
                        r += coefficients[i] * rewards[rows[i], action_of[j]]
                step_reward[j] = r
        for i in range(order.shape[0]):
            s = order[i]
            best_b = -np.inf
            best_a = -np.inf
            for j in range(state_ptr[i], state_ptr[i + 1]):
                vb = step_reward[j]
                va = vb
                if t < horizon:
                    if has_until:
                        for e in range(entry_ptr[j], entry_ptr[j + 1]):
                            vb += probabilities[e] * b_next[targets[e]]
                            va += probabilities[e] * a_next[targets[e]]
                    else:
                        for e in range(entry_ptr[j], entry_ptr[j + 1]):
                            vb += probabilities[e] * b_next[targets[e]]
                best_b = max(best_b, vb)
                best_a = max(best_a, va)
            b_now[s] = best_b
            if not has_until:
                continue
            if until_steps >= 0 and t > until_steps:
                a_now[s] = best_b
            elif right[s]:
                a_now[s] = gain + best_b
            elif not left[s] or (until_steps >= 0 and t == until_steps):
                a_now[s] = best_b
            elif t == horizon and until_steps < 0:
                a_now[s] = terminal[s] + best_b
            else:
                a_now[s] = best_a
        b_now, b_next = b_next, b_now
        a_now, a_next = a_next, a_now
    return a_next[initial] if has_until else b_next[initial]


@njit(cache=True, nogil=True)
def weighted_horizons(order, state_ptr, action_of, entry_ptr, targets, probabilities, states, rewards, rows, steps,
                      coefficients, horizon, has_until, left, right, until_steps, gains, reach, initial):  # fmt: skip
    """Per weighting w, the best weighted sum (sign space) of step-bounded cumulative rewards
    (``rows``, ``steps``; reward k weighs ``coefficients[w, k]``) and at most one
    reachability objective (``left U right`` within ``until_steps`` steps, or unbounded: -1;
    reaching ``right`` gains ``gains[w]``; past the horizon an unbounded one is worth
    ``gains[w] * reach[s]``), over all schedulers of the sub-family (``compact``'s arrays;
    history-dependent schedulers too, so the value bounds every policy's): backward
    induction over ``horizon`` steps, with a second value for "not yet reached".

    All weightings in one pass over the transitions per step: a state's values of every
    weighting side by side (columns ``w``, and ``W + w`` for "not yet reached"), so a
    transition is read once for all of them (a weighting's arithmetic, and so its value,
    is the same whatever others it is solved with, and :func:`weighted_horizon`'s for it
    alone). Without the GIL: threads may solve parts of the weightings at once."""
    w_count = coefficients.shape[0]
    width = 2 * w_count if has_until else w_count
    after = np.zeros((states, width))  # values at t + 1: "reached or not" (b) and "not yet" (a)
    now = np.zeros((states, width))
    active = np.zeros(rows.shape[0], dtype=np.bool_)
    base = np.empty((action_of.shape[0], rows.shape[0]))  # each action's rewards, in action order
    for j in range(action_of.shape[0]):
        for k in range(rows.shape[0]):
            base[j, k] = rewards[rows[k], action_of[j]]
    v = np.zeros(width)
    best = np.zeros(width)
    for t in range(horizon, -1, -1):
        for k in range(rows.shape[0]):
            active[k] = t < steps[k]
        for i in range(order.shape[0]):
            s = order[i]
            for c in range(width):
                best[c] = -np.inf
            for j in range(state_ptr[i], state_ptr[i + 1]):
                for w in range(w_count):
                    v[w] = 0.0
                for k in range(rows.shape[0]):
                    if active[k]:
                        r = base[j, k]
                        for w in range(w_count):
                            v[w] += coefficients[w, k] * r
                if has_until:
                    for w in range(w_count):
                        v[w_count + w] = v[w]
                if t < horizon:
                    for e in range(entry_ptr[j], entry_ptr[j + 1]):
                        p = probabilities[e]
                        u = targets[e]
                        for c in range(width):
                            v[c] += p * after[u, c]
                for c in range(width):
                    best[c] = max(best[c], v[c])
            for w in range(w_count):
                now[s, w] = best[w]
            if not has_until:
                continue
            for w in range(w_count):
                if until_steps >= 0 and t > until_steps:
                    now[s, w_count + w] = best[w]
                elif right[s]:
                    now[s, w_count + w] = gains[w] + best[w]
                elif not left[s] or (until_steps >= 0 and t == until_steps):
                    now[s, w_count + w] = best[w]
                elif t == horizon and until_steps < 0:
                    now[s, w_count + w] = gains[w] * reach[s] + best[w]
                else:
                    now[s, w_count + w] = best[w_count + w]
        now, after = after, now
    out = np.empty(w_count)
    for w in range(w_count):
        out[w] = after[initial, w_count + w] if has_until else after[initial, w]
    return out


@njit(cache=True)
def reward_and_bounded(order, state_ptr, action_of, entry_ptr, targets, probabilities, states, reward, right, steps,
                       gain, terminal, initial):  # fmt: skip
    """The best of ``gain`` times the probability to reach ``right`` within ``steps`` steps less
    the expected ``reward`` (per action) until ``right``, over all schedulers of the
    sub-family (``compact``'s arrays; history-dependent ones too): backward induction over
    the steps; past them a state not in ``right`` is worth ``-terminal[s]``, a lower bound of
    the least expected reward still to come (infinite where the target cannot be reached)."""
    now = np.zeros(states)
    after = np.zeros(states)
    for i in range(order.shape[0]):
        s = order[i]
        after[s] = 0.0 if right[s] else -terminal[s]
    for _ in range(steps + 1):  # times steps down to 0
        for i in range(order.shape[0]):
            s = order[i]
            if right[s]:
                now[s] = gain
                continue
            best = -np.inf
            for j in range(state_ptr[i], state_ptr[i + 1]):
                v = -reward[action_of[j]]
                for e in range(entry_ptr[j], entry_ptr[j + 1]):
                    if probabilities[e] > 0.0:
                        v += probabilities[e] * after[targets[e]]
                best = max(best, v)
            now[s] = best
        now, after = after, now
    return after[initial]


@njit(cache=True)
def any_step(steps, t):
    """Whether some cumulative objective's bound is t + 1 (its reward stops at t + 1)."""
    for i in range(steps.shape[0]):
        if steps[i] == t + 1:
            return True
    return False


def predecessors(relaxation) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The relaxation's reversed entries: CSR over target states of (state, action)."""
    r = relaxation
    action_state = np.repeat(np.arange(r.states), np.diff(r.state_actions))
    entry_action = np.repeat(np.arange(r.actions), np.diff(r.action_entries))
    order = np.argsort(r.targets, kind="stable")
    pointers = np.zeros(r.states + 1, dtype=np.int64)
    np.add.at(pointers, r.targets + 1, 1)
    return np.cumsum(pointers), action_state[entry_action[order]], entry_action[order]


@njit(cache=True, nogil=True)
def horizon_mass(order, state_ptr, action_of, entry_ptr, targets, probabilities, states, rewards, rows, steps,
                 coefficients, horizon, has_until, left, right, until_steps, gain, terminal, initial):  # fmt: skip
    """Where the best scheduler of :func:`weighted_horizon`'s weighted sum acts: per action of
    the sub-family (``compact``'s order) the expected number of steps within the horizon at
    which it takes that action, before it reaches ``right`` where there is a reachability
    objective. Its backward induction is :func:`weighted_horizon`'s (the same values), keeping
    the best action per step and state; a forward pass from ``initial`` sums the mass. What
    PAYNT's refinement reads off the scheduler: a decision whose states take different values
    is where the relaxation is looser than any policy."""
    n_actions = action_of.shape[0]
    n = order.shape[0]
    choice = np.full((horizon + 1, n), -1, dtype=np.int64)
    b_next = np.zeros(states)
    a_next = np.zeros(states)
    b_now = np.zeros(states)
    a_now = np.zeros(states)
    step_reward = np.zeros(n_actions)
    for t in range(horizon, -1, -1):
        if t == horizon or any_step(steps, t):
            for j in range(n_actions):
                r = 0.0
                for i in range(rows.shape[0]):
                    if t < steps[i]:
                        r += coefficients[i] * rewards[rows[i], action_of[j]]
                step_reward[j] = r
        for i in range(n):
            s = order[i]
            best_b = -np.inf
            best_a = -np.inf
            arg_b = -1
            arg_a = -1
            for j in range(state_ptr[i], state_ptr[i + 1]):
                vb = step_reward[j]
                va = vb
                if t < horizon:
                    for e in range(entry_ptr[j], entry_ptr[j + 1]):
                        vb += probabilities[e] * b_next[targets[e]]
                        va += probabilities[e] * a_next[targets[e]]
                if vb > best_b:
                    best_b = vb
                    arg_b = j
                if va > best_a:
                    best_a = va
                    arg_a = j
            b_now[s] = best_b
            choice[t, i] = arg_b
            if not has_until:
                continue
            if until_steps >= 0 and t > until_steps:
                a_now[s] = best_b
            elif right[s]:
                a_now[s] = gain + best_b
            elif not left[s] or (until_steps >= 0 and t == until_steps):
                a_now[s] = best_b
            elif t == horizon and until_steps < 0:
                a_now[s] = terminal[s] + best_b
            else:
                a_now[s] = best_a
                choice[t, i] = arg_a
        b_now, b_next = b_next, b_now
        a_now, a_next = a_next, a_now
    index = np.full(states, -1, dtype=np.int64)
    for i in range(n):
        index[order[i]] = i
    mass = np.zeros(n_actions)
    now = np.zeros(states)
    later = np.zeros(states)
    now[initial] = 1.0
    for t in range(horizon):
        for s in range(states):
            later[s] = 0.0
        for s in range(states):
            m = now[s]
            if m == 0.0 or index[s] < 0 or (has_until and right[s]):
                continue
            j = choice[t, index[s]]
            if j < 0:
                continue
            mass[j] += m
            for e in range(entry_ptr[j], entry_ptr[j + 1]):
                later[targets[e]] += m * probabilities[e]
        now, later = later, now
    return mass
