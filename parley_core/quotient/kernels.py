"""Compiled kernels of the quotient evaluator (numba).

A policy's DTMC is never built as a Python object: :func:`explore` walks the quotient MDP
from the initial state, keeps the choices consistent with the policy, mixes them uniformly
(as Storm's DTMC builder mixes overlapping commands), turns states without a consistent
choice into self-loops, and writes the reachable part as a CSR matrix over local indices
(0 is the initial state, then breadth-first order). The other kernels solve on that matrix.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numba import njit

FIRST_GUESS = 12
"""Sweeps before :func:`gauss_seidel` may judge, from how fast the change falls, that it will
not converge in time."""
RATE_SWEEPS = 4
"""The sweeps over which :func:`gauss_seidel` measures that rate."""


class Chain(NamedTuple):
    """The quotient's arrays that every walk of it reads (a :class:`~parley_core.quotient.coloring.Quotient`'s,
    made once per solver or walker by :func:`chain_of`): the initial state; per state its
    choices (CSR into the choices); per choice its branches (CSR into ``targets`` and
    ``probabilities``) and the decision and value it is labelled with (-1: unlabelled); the
    state and choice rewards per reward structure; and :func:`choice_index`'s ``lookup``."""

    initial: int
    state_choices: np.ndarray
    choice_branches: np.ndarray
    targets: np.ndarray
    probabilities: np.ndarray
    choice_dec: np.ndarray
    choice_val: np.ndarray
    state_rewards: np.ndarray
    choice_rewards: np.ndarray
    lookup: tuple


def chain_of(quotient) -> Chain:
    """The :class:`Chain` of a quotient, with its choice index."""
    q = quotient
    index = choice_index(q.state_choices, q.choice_dec, q.choice_val)
    return Chain(
        q.initial,
        q.state_choices,
        q.choice_branches,
        q.targets,
        q.probabilities,
        q.choice_dec,
        q.choice_val,
        q.state_rewards,
        q.choice_rewards,
        index,
    )


class Reached(NamedTuple):
    """Work space of :func:`explore`, as long as the quotient has states (``cols``, ``vals``:
    its branches and a self-loop per state), and what it writes: the reached states' global
    indices in local order (``order``), the DTMC as CSR over local indices (``indptr``,
    ``cols``, ``vals``), each reward structure's reward per local state (``rewards``), each
    state's distance from the initial one (``levels``), and the states without a consistent
    choice (``stuck``); ``local_of`` (-1 everywhere between calls) and ``chosen`` (as long as
    the most choices a state has) are scratch."""

    local_of: np.ndarray
    order: np.ndarray
    indptr: np.ndarray
    cols: np.ndarray
    vals: np.ndarray
    rewards: np.ndarray
    levels: np.ndarray
    chosen: np.ndarray
    stuck: np.ndarray


@njit(cache=True)
def _consistent(policy, choice_dec, choice_val, c, consulted):
    """Whether choice ``c`` is consistent with ``policy``; marks in ``consulted`` every
    decision the test reads (it stops at the first that disagrees)."""
    for j in range(choice_dec.shape[1]):
        d = choice_dec[c, j]
        if d < 0:
            return True
        consulted[d] = True
        if policy[d] != choice_val[c, j]:
            return False
    return True


@njit(cache=True)
def explore(policy, chain, reached, consulted):
    """The reachable DTMC of ``policy`` on the quotient's :class:`Chain`, written into the
    :class:`Reached` work space; returns (states, entries).

    ``reached.local_of`` must hold -1 everywhere on entry and does again on return.
    ``reached.rewards`` [r, :states] receives each reward structure's state reward plus the
    mean action reward of the consistent choices (nothing in a state without one: Storm
    drops a deadlock state's rewards); ``levels`` each state's distance (in steps) from the
    initial one; ``stuck`` marks the states without a consistent choice, which Storm's DTMC
    of the policy labels "deadlock". ``consulted`` (False everywhere on entry) gets True for
    each decision a reachable state's consistency test reads: a policy that agrees with this
    one on those decisions has the same reachable DTMC, choice by choice. Where a state's
    labelled choices each test one value of the same decision, the consistent one is looked
    up in the chain's ``lookup`` (:func:`choice_index`) instead of testing each (the same
    choices, in the same order).
    """
    initial, state_choices, choice_branches, targets, probabilities = chain[:5]
    choice_dec, choice_val, state_rewards, choice_rewards, lookup = chain[5:]
    local_of, order, indptr, cols, vals, rewards_out, levels, chosen, stuck = reached
    lookup_dec, lookup_lo, lookup_start, lookup_choice, free_start, free_choice = lookup
    n_rewards = state_rewards.shape[0]
    order[0] = initial
    local_of[initial] = 0
    levels[0] = 0
    count = 1
    head = 0
    nnz = 0
    indptr[0] = 0
    while head < count:
        s = order[head]
        k = 0
        d = lookup_dec[s]
        if d >= 0:  # one decision decides among the labelled choices: look its value up
            consulted[d] = True
            x = policy[d] - lookup_lo[s]
            found = -1
            if 0 <= x < lookup_start[s + 1] - lookup_start[s]:
                found = lookup_choice[lookup_start[s] + x]
            for f in range(free_start[s], free_start[s + 1]):  # unlabelled: always consistent
                u = free_choice[f]
                if 0 <= found < u:
                    chosen[k] = found
                    k += 1
                    found = -1
                chosen[k] = u
                k += 1
            if found >= 0:
                chosen[k] = found
                k += 1
        else:
            for c in range(state_choices[s], state_choices[s + 1]):
                if _consistent(policy, choice_dec, choice_val, c, consulted):
                    chosen[k] = c
                    k += 1
        for r in range(n_rewards):
            # Storm gives a deadlock state (made a self-loop) no reward, state rewards included
            rewards_out[r, head] = state_rewards[r, s] if k > 0 else 0.0
        stuck[head] = k == 0
        if k == 0:
            cols[nnz] = head
            vals[nnz] = 1.0
            nnz += 1
        else:
            w = 1.0 / k
            for i in range(k):
                c = chosen[i]
                for r in range(n_rewards):
                    rewards_out[r, head] += w * choice_rewards[r, c]
                for b in range(choice_branches[c], choice_branches[c + 1]):
                    t = targets[b]
                    if local_of[t] < 0:
                        local_of[t] = count
                        order[count] = t
                        levels[count] = levels[head] + 1
                        count += 1
                    cols[nnz] = local_of[t]
                    vals[nnz] = w * probabilities[b]
                    nnz += 1
        head += 1
        indptr[head] = nnz
    for i in range(count):
        local_of[order[i]] = -1
    return count, nnz


@njit(cache=True)
def backward_reach(count, indptr, cols, start, through):
    """States (local) that can reach a ``start`` state by a path whose other states are ``through``."""
    nnz = indptr[count]
    rev_ptr = np.zeros(count + 1, dtype=np.int64)
    for e in range(nnz):
        rev_ptr[cols[e] + 1] += 1
    for i in range(count):
        rev_ptr[i + 1] += rev_ptr[i]
    fill = rev_ptr[:-1].copy()
    rev = np.empty(nnz, dtype=np.int64)
    for s in range(count):
        for e in range(indptr[s], indptr[s + 1]):
            rev[fill[cols[e]]] = s
            fill[cols[e]] += 1
    seen = start.copy()
    stack = np.empty(count, dtype=np.int64)
    top = 0
    for s in range(count):
        if start[s]:
            stack[top] = s
            top += 1
    while top > 0:
        top -= 1
        t = stack[top]
        for e in range(rev_ptr[t], rev_ptr[t + 1]):
            s = rev[e]
            if not seen[s] and through[s]:
                seen[s] = True
                stack[top] = s
                top += 1
    return seen


@njit(cache=True)
def cannot_reach(count, indptr, cols, right, through):
    """States that cannot reach a ``right`` state, found in one pass from the last state to
    the first: a state outside ``through`` (and not right), or one in it whose successors
    other than itself were all found before. A subset of all such states (a successor with
    a smaller index than its predecessor counts as able to reach), so cheap and always sound;
    on breadth-first orders it is nearly all of them (crashed robots, finished runs)."""
    out = np.zeros(count, dtype=np.bool_)
    for s in range(count - 1, -1, -1):
        if right[s]:
            continue
        if not through[s]:
            out[s] = True
            continue
        unable = True
        for e in range(indptr[s], indptr[s + 1]):
            t = cols[e]
            if t != s and not out[t]:
                unable = False
                break
        out[s] = unable
    return out


@njit(cache=True)
def pass_through(count, indptr, cols, vals, stop, cap):
    """For each state that a solver can pass through, its successor, else -1.

    A state is passed through when its only transition goes with probability 1 to another
    state and it is neither the initial state nor a ``stop`` state (robot_grid's check and
    skip steps: two thirds of the states). Chains of such states are cut on cycles and
    after ``cap`` states (a state of the chain is made an end), so a walk from any state
    meets an end within ``cap`` steps."""
    through = np.full(count, -1, dtype=np.int64)
    for s in range(1, count):
        e = indptr[s]
        if not stop[s] and indptr[s + 1] - e == 1 and cols[e] != s and vals[e] == 1.0:
            through[s] = cols[e]
    depth = np.full(count, -1, dtype=np.int64)  # states passed before an end; -2: on the walk
    path = np.empty(count, dtype=np.int64)
    for s in range(count):
        if depth[s] != -1:
            continue
        top = 0
        u = s
        while through[u] >= 0 and depth[u] == -1:
            depth[u] = -2
            path[top] = u
            top += 1
            u = through[u]
        if depth[u] == -2:  # the walk came back to u: cut the cycle there
            through[u] = -1
        if through[u] < 0:
            depth[u] = 0
        for i in range(top - 1, -1, -1):
            v = path[i]
            if through[v] < 0:
                depth[v] = 0
                continue
            d = depth[through[v]] + 1
            if d > cap:
                through[v] = -1
                d = 0
            depth[v] = d
    return through


@njit(cache=True)
def lump(count, indptr, cols, vals, through, constant):
    """The equations x = constant + P x with the passed-through states substituted: their
    rows are emptied, and an entry to one goes to the end of its chain instead, the
    constants along the chain added to the row's constant (x[s] = constant[s] + x[next])."""
    end = np.arange(count)
    along = np.zeros(count)
    path = np.empty(count, dtype=np.int64)
    for s in range(count):
        if through[s] < 0 or end[s] != s:
            continue
        top = 0
        u = s
        while through[u] >= 0 and end[u] == u:
            path[top] = u
            top += 1
            u = through[u]
        for i in range(top - 1, -1, -1):
            v = path[i]
            nxt = through[v]
            if through[nxt] >= 0:
                end[v] = end[nxt]
                along[v] = constant[v] + along[nxt]
            else:
                end[v] = nxt
                along[v] = constant[v]
    lumped_ptr = np.zeros(count + 1, dtype=np.int64)
    lumped_cols = np.empty(indptr[count], dtype=np.int64)
    lumped_vals = np.empty(indptr[count], dtype=np.float64)
    lumped_constant = constant.copy()
    k = 0
    for s in range(count):
        if through[s] < 0:
            for e in range(indptr[s], indptr[s + 1]):
                t = cols[e]
                if through[t] >= 0:
                    lumped_constant[s] += vals[e] * along[t]
                    t = end[t]
                lumped_cols[k] = t
                lumped_vals[k] = vals[e]
                k += 1
        lumped_ptr[s + 1] = k
    return lumped_ptr, lumped_cols[:k], lumped_vals[:k], lumped_constant


@njit(cache=True)
def unlump(through, constant, x):
    """The values of the passed-through states (in place), from the chains' ends in ``x``:
    x[s] = constant[s] + x[next], the inverse of :func:`lump`."""
    count = through.shape[0]
    done = through < 0
    path = np.empty(count, dtype=np.int64)
    for s in range(count):
        top = 0
        u = s
        while not done[u]:
            path[top] = u
            top += 1
            u = through[u]
        for i in range(top - 1, -1, -1):
            v = path[i]
            x[v] = constant[v] + x[through[v]]
            done[v] = True


@njit(cache=True)
def chosen_rows(actions, action_entries, targets, probabilities, index):
    """The CSR (pointers, columns, values) over local states of the transitions of the
    chosen ``actions`` (one per local state), keeping only targets with a local ``index``
    (>= 0)."""
    n = actions.shape[0]
    size = 0
    for i in range(n):
        size += action_entries[actions[i] + 1] - action_entries[actions[i]]
    pointers = np.zeros(n + 1, dtype=np.int64)
    columns = np.empty(size, dtype=np.int64)
    values = np.empty(size)
    k = 0
    for i in range(n):
        a = actions[i]
        for e in range(action_entries[a], action_entries[a + 1]):
            j = index[targets[e]]
            if j >= 0:
                columns[k] = j
                values[k] = probabilities[e]
                k += 1
        pointers[i + 1] = k
    return pointers, columns[:k], values[:k]


@njit(cache=True, fastmath=True)
def gauss_seidel(indptr, cols, vals, rows, x, constant, tolerance, max_sweeps, give_up=False):
    """Solve x = constant + P x on the states ``rows`` (in this order), the others fixed at
    their x.

    A state's self-loop is solved for directly (its factor 1 / (1 - loop) computed once; a
    state that only loops keeps its x). Stops when no value moves by more than
    ``tolerance`` relative to its size (absolutely, below 1); returns the sweeps used, or
    -1 without convergence. With ``give_up``, also -1 as soon as the change's rate (from sweep
    :data:`FIRST_GUESS` on, the smaller of its rate over the last :data:`RATE_SWEEPS` sweeps
    and over all sweeps after the first :data:`RATE_SWEEPS`) says that twice the sweeps left
    would not reach the tolerance: a slowly mixing chain (PAYNT's dpm, where a battery runs
    out with probability 0.01 a step) then goes to a direct solve at once.
    Whether it gives up depends on the equations alone.
    """
    n = rows.shape[0]
    scale = np.zeros(n)
    for i in range(n):
        s = rows[i]
        loop = 0.0
        for e in range(indptr[s], indptr[s + 1]):
            if cols[e] == s:
                loop += vals[e]
        if loop < 1.0:
            scale[i] = 1.0 / (1.0 - loop)
    history = np.zeros(RATE_SWEEPS + 1)
    early = 0.0
    for sweep in range(max_sweeps):
        change = 0.0
        for i in range(n):
            factor = scale[i]
            if factor == 0.0:
                continue
            s = rows[i]
            total = constant[s]
            for e in range(indptr[s], indptr[s + 1]):
                t = cols[e]
                if t != s:
                    total += vals[e] * x[t]
            value = total * factor
            delta = abs(value - x[s])
            size = abs(value)
            if size > 1.0:
                delta /= size
            if delta > change:
                change = delta
            x[s] = value
        if change <= tolerance:
            return sweep + 1
        if sweep == RATE_SWEEPS - 1:
            early = change
        history[sweep % (RATE_SWEEPS + 1)] = change
        if give_up and tolerance > 0.0 and sweep + 1 >= FIRST_GUESS:
            # the more hopeful of two rates: the last RATE_SWEEPS sweeps' and all sweeps'
            # since the first RATE_SWEEPS (values spreading over a large map hold the change
            # up for a while before it falls fast; a slowly mixing chain's falls slowly
            # throughout)
            before = history[(sweep + 1) % (RATE_SWEEPS + 1)]  # the change RATE_SWEEPS sweeps ago
            recent = (change / before) ** (1.0 / RATE_SWEEPS) if 0.0 < change < before else 1.0
            since = sweep - (RATE_SWEEPS - 1)
            overall = (change / early) ** (1.0 / since) if 0.0 < change < early else 1.0
            rate = min(recent, overall)
            if rate >= 1.0:
                return -1
            needed = np.log(tolerance / change) / np.log(rate)
            if needed > 2.0 * (max_sweeps - sweep - 1):
                return -1
    return -1


@njit(cache=True, fastmath=True)
def bounded(count, indptr, cols, vals, steps, x, constant, free, levels):
    """``steps`` Jacobi iterations of x = constant + P x on ``free`` states: exact for
    step-bounded properties. Only the value at the initial state is wanted, so iteration j
    updates only states within ``steps - j`` steps of it (a prefix of the breadth-first
    order ``levels`` comes from)."""
    y = x.copy()
    limit = count
    for j in range(1, steps + 1):
        horizon = steps - j
        while limit > 0 and levels[limit - 1] > horizon:
            limit -= 1
        for s in range(limit):
            if not free[s]:
                y[s] = x[s]
                continue
            total = constant[s]
            for e in range(indptr[s], indptr[s + 1]):
                total += vals[e] * x[cols[e]]
            y[s] = total
        x, y = y, x
    return x


@njit(cache=True, fastmath=True)
def cumulative(count, indptr, cols, vals, steps, rewards, levels):
    """Expected reward within ``steps`` steps from the initial state, for each reward
    structure (row) of ``rewards``, computed forward: each state's expected number of visits
    in the first ``steps`` steps (the distribution pushed one step at a time, once for all
    reward structures), weighed by its reward.

    While few states carry probability at a step, the step visits only those, from a list
    in the order they were reached: on web_ids about 17 of 1,600 states a step, as the hour
    and the phase of the round are part of the state, on tas about 100 of 1,100 (7 and 2
    times faster than a scan). Once more than an eighth of all states, and a third of those
    within j steps of the initial one, carry probability at step j (robot_grid, turtlebot:
    after a few steps), each later step scans the states within its number of steps of the
    initial one (a prefix of the breadth-first order ``levels`` comes from), which is
    cheaper when most of them carry probability. States with no reward and no successor but
    themselves and such states (crashed or finished robots) are dropped
    with their mass, found in one pass from the last state to the first."""
    n_rewards = rewards.shape[0]
    earns = np.zeros(count, dtype=np.bool_)
    for r in range(n_rewards):
        for s in range(count):
            if rewards[r, s] != 0.0:
                earns[s] = True
    idle = cannot_reach(count, indptr, cols, earns, np.ones(count, dtype=np.bool_))
    mass = np.zeros(count)
    pushed = np.zeros(count)
    visits = np.zeros(count)  # expected visits within the bound; the rewards are weighed at the end
    active = np.empty(count, dtype=np.int64)
    following = np.empty(count, dtype=np.int64)
    listed = np.zeros(count, dtype=np.bool_)
    mass[0] = 1.0
    active[0] = 0
    n_active = 1
    limit = 1
    j = 0
    while j < steps:  # sparse steps: from the list
        while limit < count and levels[limit] <= j:
            limit += 1
        if n_active > max(64, count // 8) and 3 * n_active > limit:
            break
        last = j + 1 == steps
        n_next = 0
        for i in range(n_active):
            s = active[i]
            m = mass[s]
            mass[s] = 0.0
            if m == 0.0 or idle[s]:
                continue
            visits[s] += m
            if not last:
                for e in range(indptr[s], indptr[s + 1]):
                    t = cols[e]
                    pushed[t] += m * vals[e]
                    if not listed[t]:
                        listed[t] = True
                        following[n_next] = t
                        n_next += 1
        for i in range(n_next):
            listed[following[i]] = False
        mass, pushed = pushed, mass
        active, following = following, active
        n_active = n_next
        j += 1
    for k in range(j, steps):  # dense steps: scan the prefix of states within k steps
        while limit < count and levels[limit] <= k:
            limit += 1
        last = k + 1 == steps
        for s in range(limit):
            m = mass[s]
            if m == 0.0:
                continue
            mass[s] = 0.0
            if idle[s]:
                continue
            visits[s] += m
            if not last:
                for e in range(indptr[s], indptr[s + 1]):
                    pushed[cols[e]] += m * vals[e]
        mass, pushed = pushed, mass
    totals = np.zeros(n_rewards)
    for r in range(n_rewards):
        for s in range(count):
            totals[r] += rewards[r, s] * visits[s]
    return totals


@njit(cache=True)
def equations(indptr, cols, vals, idx, x, constant):
    """The CSR (data, indices, pointers) of I - P on the states ``idx`` (in any order: row and
    column i are state idx[i]), with the diagonal first in each row, and the right-hand side
    ``constant + P x`` over the other states (their x fixed)."""
    count = indptr.shape[0] - 1
    local = np.full(count, -1, dtype=np.int64)
    for i in range(idx.shape[0]):
        local[idx[i]] = i
    size = 0
    for i in range(idx.shape[0]):
        s = idx[i]
        size += 1 + indptr[s + 1] - indptr[s]
    data = np.empty(size)
    indices = np.empty(size, dtype=np.int64)
    pointers = np.zeros(idx.shape[0] + 1, dtype=np.int64)
    rhs = np.empty(idx.shape[0])
    k = 0
    for i in range(idx.shape[0]):
        s = idx[i]
        diagonal = k
        data[k] = 1.0
        indices[k] = i
        k += 1
        total = constant[s]
        for e in range(indptr[s], indptr[s + 1]):
            t = cols[e]
            j = local[t]
            if j == i:
                data[diagonal] -= vals[e]
            elif j >= 0:
                data[k] = -vals[e]
                indices[k] = j
                k += 1
            else:
                total += vals[e] * x[t]
        rhs[i] = total
        pointers[i + 1] = k
    return data[:k], indices[:k], pointers, rhs


@njit(cache=True)
def residual(indptr, cols, vals, rows, x, constant):
    """max over ``rows`` of |constant + P x - x|: how far x is from solving x = constant + P x.

    With N = (I - P)^-1 >= 0 on the rows, x* - x = N r, so |x* - x| <= max|r| N 1: this and
    a bound on N 1 (``QuotientSolver._amplification``) certify an approximate solution, whatever
    produced it (exact arithmetic aside: the residual is computed in floating point)."""
    worst = 0.0
    for i in range(rows.shape[0]):
        s = rows[i]
        total = constant[s] - x[s]
        for e in range(indptr[s], indptr[s + 1]):
            total += vals[e] * x[cols[e]]
        if abs(total) > worst:
            worst = abs(total)
    return worst


@njit(cache=True)
def choice_index(state_choices, choice_dec, choice_val):
    """For :func:`explore`: per state whose labelled choices all test one value of the same
    decision, each value once, that decision (else -1), the smallest value and a table from
    value to choice (-1: none), and the state's unlabelled choices in order. A table is built
    only where the values are not spread much wider than the choices."""
    n = len(state_choices) - 1
    width = choice_dec.shape[1]
    lookup_dec = np.full(n, -1, dtype=np.int64)
    lookup_lo = np.zeros(n, dtype=np.int64)
    lookup_start = np.zeros(n + 1, dtype=np.int64)
    free_start = np.zeros(n + 1, dtype=np.int64)
    tables = 0
    frees = 0
    spans = np.zeros(n, dtype=np.int64)
    for s in range(n):
        d, lo, hi, labelled, single = -1, 0, -1, 0, True
        for c in range(state_choices[s], state_choices[s + 1]):
            if choice_dec[c, 0] < 0:
                frees += 1
                continue
            if width > 1 and choice_dec[c, 1] >= 0:
                single = False
            if d < 0:
                d, lo, hi = choice_dec[c, 0], choice_val[c, 0], choice_val[c, 0]
            elif choice_dec[c, 0] != d:
                single = False
            lo = min(lo, choice_val[c, 0])
            hi = max(hi, choice_val[c, 0])
            labelled += 1
        if single and labelled > 0 and hi - lo + 1 <= 4 * labelled + 16:
            lookup_dec[s] = d
            lookup_lo[s] = lo
            spans[s] = hi - lo + 1
            tables += hi - lo + 1
    lookup_choice = np.full(tables, -1, dtype=np.int64)
    free_choice = np.empty(frees, dtype=np.int64)
    at, f = 0, 0
    for s in range(n):
        lookup_start[s] = at
        free_start[s] = f
        for c in range(state_choices[s], state_choices[s + 1]):
            if choice_dec[c, 0] < 0:
                free_choice[f] = c
                f += 1
            elif lookup_dec[s] >= 0:
                slot = at + choice_val[c, 0] - lookup_lo[s]
                if lookup_choice[slot] >= 0:  # a value twice: test the choices one by one
                    lookup_dec[s] = -1
                lookup_choice[slot] = c
        at += spans[s]
    lookup_start[n] = at
    free_start[n] = f
    return lookup_dec, lookup_lo, lookup_start, lookup_choice, free_start, free_choice
