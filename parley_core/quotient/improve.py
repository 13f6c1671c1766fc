"""Which value each decision of a policy should move to: policy improvement on the relaxation.

The search's evaluator says how good a policy is; this module says in which direction to
change it. For a policy and a weighting ``w >= 0`` of the objectives (in sign space, every
objective maximised, as in :mod:`parley_core.quotient.bounds`), it computes on the quotient's
relaxation (:mod:`parley_core.quotient.relaxation`), restricted to the policy's own actions
(one per state: the uniform mix of its consistent choices, or the deadlock):

- the policy's time-dependent weighted value ``V_t(s)`` of every state, by backward induction
  over the objectives' horizon (the weighted sum of step-bounded rewards and at most one
  reachability objective, as :func:`~parley_core.quotient.subfamily.weighted_horizon` solves it
  over all schedulers; past the horizon an unbounded reachability objective is worth the
  policy's own probability to reach);
- the policy's occupancy ``mu_t(s)``, forward from the initial state;
- per decision ``d`` and value ``k`` the score ``sum_t sum_s mu_t(s) Q_t(s, k)``, over the
  states that consult ``d``, where ``Q_t(s, k)`` is the value of taking at ``s`` an action
  that assigns ``k`` to ``d`` (the best such, if ``s`` consults other decisions too) and
  following the policy afterwards.

By the performance-difference lemma, ``score[d, k] - score[d, current]`` is the first-order
change of the policy's weighted value if it chose ``k`` for ``d``: exact where one state
consults ``d`` once, an estimate where many states share it (they all change together). So
moving every decision to its best-scored value is a step of policy iteration restricted to
policies that decide by what the controller observes; unlike policy iteration on an MDP it
need not improve, which is why the search evaluates every step
(:mod:`parley_core.search.guide`). Nothing here is a value the run reports: scores only
choose which policies get evaluated.

Memory: the backward values of every step are kept when they fit in :data:`MEMORY` bytes,
else only every ``K``-th (``K`` about the square root of the horizon) and each stretch of
``K`` recomputed from its checkpoint when the forward pass needs it (one more backward pass).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from parley_core.model import Family
from parley_core.quotient import subfamily as k
from parley_core.quotient.bounds import RelaxedObjectives
from parley_core.quotient.coloring import Quotient
from parley_core.quotient.compile import KernelKind

MEMORY = 256 * 2**20
"""Bytes the backward values of all steps may take before checkpointing starts."""

REACH_TOLERANCE = 1e-6
REACH_SWEEPS = 200
"""The policy's probability to reach past the horizon is a guide, not a bound: iterated to
this tolerance (at most this many sweeps)."""


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
def backward(top, bottom, slots, pointers, listed, horizon, chosen, action_entries, targets, probabilities,
             rewards_by_window, window, has_until, left, right, until_steps, gain, terminal, store):  # fmt: skip
    """:func:`back_step` from step ``top - 1`` down to ``bottom`` at the states
    :func:`deviations` lists, step ``t``'s values read from ``store[slots[t + 1]]`` and
    written to ``store[slots[t]]`` (one call: a numba call per step costs more than its work)."""
    for t in range(top - 1, bottom - 1, -1):
        here = listed[pointers[t] : pointers[t + 1]]
        following, now = store[slots[t + 1]], store[slots[t]]
        back_step(t, horizon, here, chosen, action_entries, targets, probabilities, rewards_by_window[window[t]],
                  has_until, left, right, until_steps, gain, terminal, following[0], following[1], now[0],
                  now[1])  # fmt: skip


@njit(cache=True)
def forward(start, end, slots, pointers, listed, on_policy, horizon, chosen, state_actions, action_entries, targets,
            probabilities, rewards, rows, steps, coefficients, has_until, left, right, until_steps, state_decisions,
            decisions, sizes, masses, score, same, stamp, known, store):  # fmt: skip
    """:func:`forward_step` for the steps ``start .. end - 1``, the values of step ``t + 1`` in
    ``store[slots[t + 1]]``, the occupancy in ``masses[t % 2]`` (moved into ``masses[1 - t % 2]``,
    and zeroed behind it)."""
    for t in range(start, end):
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
        following = store[slots[t + 1]]
        mass, moved = masses[t % 2], masses[1 - t % 2]
        forward_step(t, horizon, here, chosen, state_actions, action_entries, targets, probabilities, rewards, rows,
                     steps, coefficients, has_until, left, right, until_steps, following[0], following[1],
                     state_decisions, decisions, sizes, mass[0], mass[1], moved[0], moved[1], score, same, stamp,
                     known)  # fmt: skip
        for s in here:
            mass[0, s] = 0.0
            mass[1, s] = 0.0


class PolicyImprover:
    """Scores of every decision's values for policies of one family (see the module).

    ``available`` is False, with the reason in ``unavailable``, where the objectives do not
    combine into a weighted sum on the relaxation (the same condition as the Pareto outer
    bound's: step-bounded rewards and at most one reachability objective)."""

    def __init__(self, family: Family, quotient: Quotient, relaxed: RelaxedObjectives | None = None) -> None:
        self.family = family
        self.bounds = b = relaxed if relaxed is not None else RelaxedObjectives(family, quotient)
        self.relaxation = r = b.relaxation
        self.signs = b.signs
        self.unavailable = "" if b.weighted_ok else "the objectives do not combine into a weighted sum"
        found = [(i, kn) for i, kn in enumerate(b.kernels) if kn is not None and kn.kind is KernelKind.CUMULATIVE]
        self.cumulative = [i for i, _ in found]
        self.rows = np.array([kn.reward for _, kn in found], dtype=np.int64)
        self.steps = np.array([kn.steps for _, kn in found], dtype=np.int64)
        self.until = b.until
        n = r.states
        self.left, self.right, self.until_steps = np.ones(n, dtype=bool), np.zeros(n, dtype=bool), -1
        if self.until >= 0:
            kernel = b.kernels[self.until]
            assert kernel is not None
            self.left, self.right = b.left[self.until], b.right[self.until]
            if kernel.kind is KernelKind.BOUNDED:
                self.until_steps = kernel.steps
        self.horizon = max([*self.steps.tolist(), self.until_steps, 0])
        self.live = np.ones(n, dtype=bool)
        self.sizes = np.asarray(r.domain_sizes, dtype=np.int64)
        self.same = representatives(r.state_actions, r.action_entries, r.targets, r.probabilities, r.rewards)
        self._values: np.ndarray | None = None
        self._mass: np.ndarray | None = None
        per_step = 2 * 8 * n * len(self.signs)
        self.stride = 1 if (self.horizon + 2) * per_step <= MEMORY else max(1, math.isqrt(self.horizon + 1))

    def _slot(self, t: int) -> int:
        """Where step ``t``'s values live in :meth:`_store`: every step's, or every
        ``stride``-th step's and the horizon's (then the stretch and scratch slots follow)."""
        if self.stride == 1:
            return t
        return self.horizon // self.stride + 1 if t == self.horizon + 1 else t // self.stride

    def _stretch(self, i: int) -> int:
        return self.horizon // self.stride + 2 + i

    def _scratch(self, t: int) -> int:
        return self.horizon // self.stride + 2 + self.stride + t % 2

    def _store(self, channels: int) -> np.ndarray:
        slots = self.horizon + 2 if self.stride == 1 else self._scratch(1) + 1
        if self._values is None or self._values.shape != (slots, 2, self.relaxation.states, channels):
            self._values = np.empty((slots, 2, self.relaxation.states, channels))
        return self._values

    def _masses(self) -> np.ndarray:
        """[step parity, pending or not, state]: the occupancy now and one step on."""
        if self._mass is None:
            self._mass = np.zeros((2, 2, self.relaxation.states))
        return self._mass

    @property
    def available(self) -> bool:
        return not self.unavailable

    def chosen(self, indices: np.ndarray) -> np.ndarray:
        """The policy's action in every state of the relaxation (``indices``: per decision
        the position of its value in the decision's domain)."""
        r = self.relaxation
        indices = np.asarray(indices, dtype=np.int64)
        allowed = k.allowed_actions(r.state_actions, r.state_decisions, r.decisions, r.domain_sizes, indices, indices)
        actions = np.flatnonzero(allowed)
        if len(actions) != r.states:
            raise RuntimeError(f"a policy keeps {len(actions)} actions of the relaxation's {r.states} states")
        return actions

    def gradients(self, indices: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Per objective ``i`` (sign space) ``score[i, d, k]`` for every decision and value
        (-inf past a decision's domain), and the policy's values (sign space) at the initial
        state. Values and scores are linear in the objectives' weights, so the scores of a
        weighting ``w`` are ``w @ score`` over the first axis (:meth:`improve`)."""
        if not self.available:
            raise RuntimeError(f"no policy improvement here: {self.unavailable}")
        r, b = self.relaxation, self.bounds
        channels = len(self.signs)
        chosen = self.chosen(indices)
        unit = np.eye(channels) * self.signs
        coefficients = np.ascontiguousarray(unit[:, self.cumulative])
        has_until = self.until >= 0
        gain = np.ascontiguousarray(unit[:, self.until]) if has_until else np.zeros(channels)
        terminal = np.zeros((r.states, channels))
        if has_until and self.until_steps < 0:
            allowed = np.zeros(r.actions, dtype=bool)
            allowed[chosen] = True
            reach = k.reach_probability(
                r.state_actions, r.action_entries, r.targets, r.probabilities, allowed, self.live,
                self.left, self.right, True, *b.pred, REACH_TOLERANCE, REACH_SWEEPS,
            )  # fmt: skip
            terminal = np.ascontiguousarray(reach[:, None] * gain[None, :])
        horizon, stride, n = self.horizon, self.stride, r.states
        rewards = (r.rewards, self.rows, self.steps, coefficients)
        ends = sorted({0, *[int(x) for x in self.steps if x <= horizon], horizon + 1})
        window = np.array([max(i for i, e in enumerate(ends) if e <= t) for t in range(horizon + 1)], dtype=np.int64)
        rewards_by_window = np.empty((len(ends), n, channels))  # the chosen actions' rewards, where they stay
        for i, e in enumerate(ends):
            if e <= horizon:
                chosen_rewards(*rewards, e, chosen, rewards_by_window[i])
        pointers, listed, on_policy = deviations(
            r.initial, horizon, chosen, r.state_actions, r.action_entries, r.targets, r.state_decisions, self.same
        )
        store = self._store(channels)  # [slot, a or b, state, channel], reused: fresh pages cost more than the work
        store[self._slot(horizon + 1)] = 0.0
        common = (pointers, listed, horizon, chosen, r.action_entries, r.targets, r.probabilities, rewards_by_window,
                  window, has_until, self.left, self.right, self.until_steps, gain, terminal, store)  # fmt: skip
        # the first pass keeps every stride-th step (and the horizon's), the others in two scratch slots
        slots = np.array([self._slot(t) if t % stride == 0 or t == horizon + 1 else self._scratch(t)
                          for t in range(horizon + 2)], dtype=np.int64)  # fmt: skip
        backward(horizon + 1, 0, slots, *common)
        first = store[self._slot(0)]
        values = np.array(first[0, r.initial] if has_until else first[1, r.initial])

        score = np.zeros((channels, len(self.sizes), int(self.sizes.max()) if len(self.sizes) else 0))
        masses = self._masses()
        masses[:] = 0.0
        masses[0, 0 if has_until else 1, r.initial] = 1.0
        stamp, known = np.zeros(r.actions + 1, dtype=np.int64), np.empty((r.actions, channels))
        stretches = (
            [(0, horizon + 1)]
            if stride == 1
            else [(t, min(t + stride, horizon + 1)) for t in range(0, horizon + 1, stride)]
        )
        for start, end in stretches:  # a stretch needs the values of start+1 .. end
            if stride > 1:
                slots[start + 1 : end] = [self._stretch(t - start - 1) for t in range(start + 1, end)]
                slots[end] = self._slot(end)
                backward(end, start + 1, slots, *common)
            forward(start, end, slots, pointers, listed, on_policy, horizon, chosen, r.state_actions, r.action_entries,
                    r.targets, r.probabilities, *rewards, has_until, self.left, self.right, self.until_steps,
                    r.state_decisions, r.decisions, self.sizes, masses, score, self.same, stamp, known,
                    store)  # fmt: skip
        for d, size in enumerate(self.sizes):
            score[:, d, size:] = -np.inf
        return score, values

    @staticmethod
    def improve(indices: np.ndarray, gradients: np.ndarray, weights: np.ndarray) -> np.ndarray:
        """The policy with every decision at its best value under ``weights`` by the scores of
        :meth:`gradients` (a decision keeps its value unless another scores better by more
        than rounding)."""
        indices = np.asarray(indices, dtype=np.int64)
        with np.errstate(invalid="ignore"):
            score = np.tensordot(np.asarray(weights, dtype=float), gradients, axes=1)
        score = np.where(np.isnan(score), -np.inf, score)
        rows = np.arange(len(indices))
        current = score[rows, indices]
        best = score.argmax(axis=1)
        better = score[rows, best] > current + 1e-12 * np.maximum(1.0, np.abs(current))
        return np.where(better, best, indices)
