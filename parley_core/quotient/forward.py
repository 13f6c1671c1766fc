"""Step-bounded cumulative rewards of whole boxes of policies, pushed forward on the quotient.

For a family whose objectives are all ``R=? [C<=k]`` (web_ids, tas), a policy's values need
only the probability of each state at each of the first ``k`` steps. :func:`box_cumulative`
pushes that distribution over the quotient's own states, choosing a state's consistent
choices when probability arrives there, so no policy's DTMC is explored or stored. The
semantics are :func:`.kernels.explore`'s: the consistent choices of a state are mixed
uniformly, a state without one keeps its probability (Storm's self-loop) and earns nothing,
and a state earns its state reward plus the mean action reward of its consistent choices.

Policies of a box share prefixes. The box is walked as an odometer whose fastest digits are
the decisions first consulted latest; the distribution is kept at each step where a
decision is first consulted, and the next policy resumes at the first step where a decision
it changes was consulted: every earlier step reads no changed decision, so it is the same
step, bit for bit, as a walk from the start. On web_ids the last two decisions are first
consulted at step 66 (of about 100 that carry probability), so most policies of a box skip
most steps. They share rows too: a state's mixed row (successors, probabilities, rewards)
is kept until a decision its choices read changes, so most states of a box are resolved
once for all its policies.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from parley_core.boxes import Box
from parley_core.quotient import kernels
from parley_core.quotient.coloring import Quotient
from parley_core.quotient.compile import KernelKind
from parley_core.quotient.relaxation import decision_lists

NEVER = np.iinfo(np.int64).max


@njit(cache=True)
def box_cumulative(
    lo, widths, dom_ptr, dom_vals, initial, state_choices, choice_branches, targets, probabilities,
    choice_dec, choice_val, state_rewards, choice_rewards, index, state_decisions, decisions,
    reward_rows, steps, idle, rows_out, out,
):  # fmt: skip
    """The box's policies in ``rows_out`` (decision values) and their objectives in ``out``:
    ``out[p, o]`` is the reward of row ``reward_rows[o]`` within ``steps[o]`` steps. Decision
    ``d`` ranges over ``dom_vals[dom_ptr[d] + lo[d] + i]``, ``i < widths[d]``. ``index`` is
    :func:`.kernels.choice_index`'s; ``state_decisions`` (CSR into ``decisions``) the
    decisions each state's choices mention; ``idle`` the states from which no state that
    earns can be reached under any choices (their probability is dropped)."""
    lookup_dec, lookup_lo, lookup_start, lookup_choice, free_start, free_choice = index
    n = len(state_choices) - 1
    n_dec = len(lo)
    n_obj = len(reward_rows)
    horizon = 0
    for o in range(n_obj):
        horizon = max(horizon, steps[o])
    most = 1
    for s in range(n):
        most = max(most, state_choices[s + 1] - state_choices[s])
    chosen = np.empty(most, dtype=np.int64)
    width = choice_dec.shape[1]
    mass = np.zeros(n)
    pushed = np.zeros(n)
    active = np.empty(n, dtype=np.int64)
    following = np.empty(n, dtype=np.int64)
    listed = np.zeros(n, dtype=np.bool_)
    keep = out.shape[0] > 1  # one policy shares nothing
    # the distribution at the start of each step where a decision is first consulted (the
    # only steps a walk resumes at), and the totals before it
    kept_at = np.full(horizon + 1, -1, dtype=np.int64)
    kept_len = np.zeros(horizon + 1, dtype=np.int64)
    kept_states = np.empty(n * (n_dec + 1) if keep else 1, dtype=np.int64)
    kept_mass = np.empty(n * (n_dec + 1) if keep else 1)
    kept_totals = np.zeros((horizon + 1, 2 * n_obj))
    fill = 0
    first = np.full(n_dec, NEVER, dtype=np.int64)
    """The step at which each decision was first consulted in the walk so far."""
    # each state's row (successors, probabilities and rewards of its consistent choices,
    # mixed), kept while no decision it reads changes: most states of a box keep theirs
    row_start = np.empty(n + 1, dtype=np.int64)
    for s in range(n + 1):
        row_start[s] = choice_branches[state_choices[s]]
    row_target = np.empty(max(1, row_start[n]), dtype=np.int64)
    row_probability = np.empty(max(1, row_start[n]))
    row_reward = np.empty((n_obj, n))
    row_len = np.full(n, -1, dtype=np.int64)  # -1: none kept; 0: a deadlock
    cached_at = np.zeros(n, dtype=np.int64)  # the policy a row was made for
    changed_at = np.zeros(n_dec, dtype=np.int64)  # the first policy since a decision's last change
    digits = np.zeros(n_dec, dtype=np.int64)
    order = np.arange(n_dec)  # odometer positions: order[-1] turns fastest
    policy = np.empty(n_dec, dtype=np.int64)
    totals = np.zeros(2 * n_obj)  # each objective's total and its compensation (Kahan)
    step_totals = np.zeros(n_obj)
    for d in range(n_dec):
        policy[d] = dom_vals[dom_ptr[d] + lo[d]]
    resume = 0
    mass[initial] = 1.0
    active[0] = initial
    n_active = 1
    for p in range(out.shape[0]):
        if p > 0 and resume < horizon:  # (at the horizon: nothing the walk read changed)
            n_active = 0  # a finished walk leaves no probability anywhere
            fill = kept_at[resume]
            for i in range(fill, fill + kept_len[resume]):
                s = kept_states[i]
                mass[s] = kept_mass[i]
                active[n_active] = s
                n_active += 1
            for o in range(2 * n_obj):
                totals[o] = kept_totals[resume, o]
        for j in range(resume, horizon):
            novel = False  # whether a decision is first consulted at this step
            last = j + 1 == horizon
            n_next = 0
            for o in range(n_obj):
                step_totals[o] = 0.0
            for i in range(n_active):
                s = active[i]
                m = mass[s]  # left until the step ends: it may be kept
                if m == 0.0 or idle[s]:
                    continue
                fresh = row_len[s] >= 0  # its row, if no decision it reads changed since
                for e in range(state_decisions[s], state_decisions[s + 1]):
                    d = decisions[e]
                    if first[d] > j:
                        first[d] = j
                        novel = True
                    if changed_at[d] > cached_at[s]:
                        fresh = False
                if not fresh:
                    k = 0
                    dd = lookup_dec[s]
                    if dd >= 0:  # one decision decides among the labelled choices
                        for f in range(free_start[s], free_start[s + 1]):
                            chosen[k] = free_choice[f]
                            k += 1
                        x = policy[dd] - lookup_lo[s]
                        if 0 <= x < lookup_start[s + 1] - lookup_start[s] and lookup_choice[lookup_start[s] + x] >= 0:
                            chosen[k] = lookup_choice[lookup_start[s] + x]
                            k += 1
                    else:
                        for c in range(state_choices[s], state_choices[s + 1]):
                            fits = True  # kernels._consistent, written out (a call costs more here)
                            for jj in range(width):
                                dec = choice_dec[c, jj]
                                if dec < 0:
                                    break
                                if policy[dec] != choice_val[c, jj]:
                                    fits = False
                                    break
                            if fits:
                                chosen[k] = c
                                k += 1
                    at = row_start[s]
                    length = 0
                    if k > 0:
                        w = 1.0 / k
                        for o in range(n_obj):
                            r = reward_rows[o]
                            earned = state_rewards[r, s]
                            for c in range(k):
                                earned += w * choice_rewards[r, chosen[c]]
                            row_reward[o, s] = earned
                        for c in range(k):
                            choice = chosen[c]
                            for b in range(choice_branches[choice], choice_branches[choice + 1]):
                                row_target[at + length] = targets[b]
                                row_probability[at + length] = w * probabilities[b]
                                length += 1
                    row_len[s] = length
                    cached_at[s] = p
                length = row_len[s]
                if length == 0:  # a deadlock: it keeps its probability and earns nothing
                    if not last:
                        pushed[s] += m
                        if not listed[s]:
                            listed[s] = True
                            following[n_next] = s
                            n_next += 1
                    continue
                for o in range(n_obj):
                    if j < steps[o]:
                        step_totals[o] += m * row_reward[o, s]
                if last:
                    continue
                # the push of kernels.cumulative, written out: as a numba function (even
                # inlined) it made the walk 20 % slower, and kernels.explore twice as slow
                at = row_start[s]
                for e in range(at, at + length):
                    t = row_target[e]
                    pushed[t] += m * row_probability[e]
                    if not listed[t]:
                        listed[t] = True
                        following[n_next] = t
                        n_next += 1
            if novel and keep:
                kept_at[j] = fill
                kept_len[j] = n_active
                for i in range(n_active):
                    kept_states[fill + i] = active[i]
                    kept_mass[fill + i] = mass[active[i]]
                fill += n_active
                for o in range(2 * n_obj):
                    kept_totals[j, o] = totals[o]
            for i in range(n_active):
                mass[active[i]] = 0.0
            for o in range(n_obj):
                # compensated (Kahan): adding each step's terms to one growing total lost
                # digits (1e-13 relative on web_ids); the step's own few terms are summed plain
                term = step_totals[o] - totals[n_obj + o]
                total = totals[o] + term
                totals[n_obj + o] = (total - totals[o]) - term
                totals[o] = total
            for i in range(n_next):
                listed[following[i]] = False
            mass, pushed = pushed, mass
            active, following = following, active
            n_active = n_next
        for o in range(n_obj):
            out[p, o] = totals[o]
        for d in range(n_dec):
            rows_out[p, d] = policy[d]
        if p == 0:  # turn fastest what the first policy consulted last
            late = np.empty(n_dec, dtype=np.int64)
            for d in range(n_dec):
                late[d] = first[d] if first[d] != NEVER else horizon
            order = np.argsort(late, kind="mergesort")
        # the next policy: the odometer; what it changes was consulted first at ``resume``
        resume = horizon
        position = n_dec - 1
        while position >= 0:
            d = order[position]
            if widths[d] > 1:
                resume = min(resume, first[d])
                changed_at[d] = p + 1
                digits[d] += 1
                if digits[d] < widths[d]:
                    policy[d] = dom_vals[dom_ptr[d] + lo[d] + digits[d]]
                    break
                digits[d] = 0
                policy[d] = dom_vals[dom_ptr[d] + lo[d]]
            position -= 1
        for d in range(n_dec):
            if first[d] >= resume:
                first[d] = NEVER


KEPT_LIMIT = 50_000_000
"""The most (state, kept step) pairs a walk may hold, 16 bytes each: a state for each
decision's first consultation and one more. Beyond, boxes are solved policy by policy."""


class BoxWalker:
    """:func:`box_cumulative` set up for one quotient whose objectives are all ``C<=k``."""

    def __init__(self, quotient: Quotient) -> None:
        q = quotient
        self.q = q
        self.index = kernels.choice_index(q.state_choices, q.choice_dec, q.choice_val)
        self.state_decisions, self.decisions = decision_lists(q.state_choices, q.choice_dec)
        objectives = [o for o in q.objectives if o is not None]
        self.reward_rows = np.array([o.reward for o in objectives], dtype=np.int64)
        self.steps = np.array([o.steps for o in objectives], dtype=np.int64)
        earns = (q.state_rewards[self.reward_rows] != 0).any(axis=0)
        owner = np.repeat(np.arange(q.states), np.diff(q.state_choices))
        earns[owner[(q.choice_rewards[self.reward_rows] != 0).any(axis=0)]] = True
        state_branches = q.choice_branches[q.state_choices]  # a state's branches are contiguous
        self.idle = ~kernels.backward_reach(q.states, state_branches, q.targets, earns, np.ones(q.states, dtype=bool))

    @classmethod
    def of(cls, quotient: Quotient) -> BoxWalker | None:
        """A walker, or None where the objectives are not all ``C<=k`` (or the walk would keep
        more than :data:`KEPT_LIMIT` pairs)."""
        kinds = [o is not None and o.kind is KernelKind.CUMULATIVE for o in quotient.objectives]
        if not kinds or not all(kinds):
            return None
        decisions = int(quotient.choice_dec.max(initial=-1)) + 1
        if quotient.states * (decisions + 1) > KEPT_LIMIT:
            return None
        return cls(quotient)

    def solve(self, box: Box, dom_ptr: np.ndarray, dom_vals: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The box's policies (rows, in the walk's order) and their values."""
        q = self.q
        rows = np.empty((box.size, len(box.lo)), dtype=np.int64)
        values = np.empty((box.size, len(self.steps)))
        box_cumulative(
            box.lo, box.hi - box.lo + 1, dom_ptr, dom_vals, q.initial, q.state_choices, q.choice_branches,
            q.targets, q.probabilities, q.choice_dec, q.choice_val, q.state_rewards, q.choice_rewards,
            self.index, self.state_decisions, self.decisions, self.reward_rows, self.steps, self.idle, rows, values,
        )  # fmt: skip
        return rows, values
