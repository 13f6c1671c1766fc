"""A family's objectives on its relaxation, bounded per sub-family: the ideal point and
weighted sums, in sign space (every objective maximised), sound by construction
(:mod:`parley_core.quotient.subfamily` says why each kernel is on the safe side).

A sub-family is a pair of integer arrays ``lo``, ``hi``: per decision an interval of its
domain's indices.
"""

from __future__ import annotations

import functools
from concurrent.futures import ThreadPoolExecutor
from typing import Any

import numpy as np

from parley_core.model import Direction, Family
from parley_core.quotient import ordering, policy_iteration
from parley_core.quotient import subfamily as k
from parley_core.quotient.coloring import Quotient
from parley_core.quotient.compile import KernelKind
from parley_core.quotient.relaxation import Relaxation, relax

WIDEN = 1e-10
"""Every bound is widened by this much of its size (at least 1): rounding in the kernels."""
TOLERANCE = 1e-12
SWEEPS = 5000
WARM = 20
"""Sweeps from 0 before policy iteration guesses the least expected reward."""
PASSES = 50
"""Passes that may lower the guess to a post-fixpoint before it is given up."""
WEIGHTS_AT_ONCE = 8
"""Weighted sums solved in one pass of backward induction (:func:`.subfamily.weighted_horizons`):
a transition is read once for all of them; each adds four values a state of work memory
(a 100x100 robot map's relaxation: 2.4 million states, 77 MB a weighted sum)."""
TOGETHER = 4
"""Fewer weighted sums than this are solved one at a time by the scalar kernel
(:func:`.subfamily.weighted_horizon`; on a 50x50 robot map 1.44 s a weighted sum, against
3.2 s for two together and 0.73 s for eight)."""


class Restricted:
    """A sub-family's view of the relaxation: its actions, the states it reaches, and the
    per-state reachability bounds its objectives need (computed once, shared by the ideal
    point and the weighted sums)."""

    def __init__(self, allowed: np.ndarray, live: np.ndarray) -> None:
        self.allowed = allowed
        self.live = live
        self.reach: dict[int, np.ndarray] = {}
        self.schedulers: list[np.ndarray] = []
        """The schedulers the bounds found, where they are known (minimised rewards until a
        target): an action per state, -1 where none."""
        self.compact: tuple[np.ndarray, ...] | None = None


class RelaxedObjectives:
    """The family's objectives, bounded on sub-families of its quotient's relaxation."""

    def __init__(
        self, family: Family, quotient: Quotient, relaxation: Relaxation | None = None, threads: int = 1
    ) -> None:
        self.family = family
        self.threads = threads
        """Threads the weighted sums of one call are solved on (their kernel runs without the GIL)."""
        self.quotient = quotient
        self.relaxation = r = relaxation if relaxation is not None else relax(quotient, family)
        self.signs = np.array([1.0 if o.direction is Direction.MAX else -1.0 for o in family.objectives])
        self.kernels = quotient.objectives
        self.sizes = np.array([len(d.service.values) for d in family.decisions], dtype=np.int64)
        self.pred = k.predecessors(r)
        self._last: dict[object, np.ndarray] = {}
        """The scheduler last found per key: where the next policy iteration starts."""
        n = r.states
        self.left: list[np.ndarray] = []
        self.right: list[np.ndarray] = []
        self.supported: list[bool] = []
        for objective, kernel in zip(family.objectives, quotient.objectives):
            left = np.ones(n, dtype=bool)
            right = np.zeros(n, dtype=bool)
            ok = kernel is not None
            if kernel is not None:
                left[:-1] = True if kernel.left is None else kernel.left
                left[-1] = False
                if kernel.right is not None:
                    right[:-1] = kernel.right
                right[-1] = kernel.right_deadlock
                if kernel.right_deadlock and kernel.left is not None and kernel.kind is KernelKind.UNTIL:
                    ok = False
                if kernel.right_deadlock and kernel.kind is KernelKind.BOUNDED:
                    ok = False
                maximised = objective.direction is Direction.MAX
                if kernel.kind in (KernelKind.REACH_REWARD, KernelKind.TOTAL) and maximised:
                    ok = False  # the maximum may be infinite: no finite bound by iteration from 0
            self.left.append(left)
            self.right.append(right)
            self.supported.append(ok)
        # weighted sums: step-bounded rewards plus at most one reachability objective
        kinds = [kernel.kind if kernel is not None else None for kernel in quotient.objectives]
        probabilities = [i for i, kind in enumerate(kinds) if kind in (KernelKind.UNTIL, KernelKind.BOUNDED)]
        self.weighted_ok = (
            all(self.supported)
            and len(probabilities) <= 1
            and all(kind in (KernelKind.CUMULATIVE, KernelKind.UNTIL, KernelKind.BOUNDED) for kind in kinds)
        )
        # or minimised expected rewards that all stop at the same target (or none): their weighted
        # sum is one expected reward, bounded from below like each of them
        reward_kinds = set(kinds)
        self.summed_ok = (
            all(self.supported)
            and len(reward_kinds) == 1
            and reward_kinds <= {KernelKind.REACH_REWARD, KernelKind.TOTAL}
            and all(o.direction is Direction.MIN for o in family.objectives)
            and all((right == self.right[0]).all() for right in self.right)
        )
        # or minimised expected rewards to a target with the probability to reach it within a
        # step bound, maximised (PAYNT's herman: expected steps to stabilise, and stabilised
        # within 30 steps)
        rewards = [i for i, kind in enumerate(kinds) if kind is KernelKind.REACH_REWARD]
        bounded = [i for i, kind in enumerate(kinds) if kind is KernelKind.BOUNDED]
        self.mixed_ok = (
            all(self.supported)
            and len(bounded) == 1
            and len(rewards) == len(kinds) - 1 >= 1
            and all(family.objectives[i].direction is Direction.MIN for i in rewards)
            and family.objectives[bounded[0]].direction is Direction.MAX
            and all((right == self.right[0]).all() for right in self.right)
            and bool(self.left[bounded[0]][:-1].all())
        )
        self.combines = self.weighted_ok or self.summed_ok or self.mixed_ok
        """Whether :meth:`weighted` bounds weighted sums (else it returns infinity)."""
        self.until = probabilities[0] if probabilities else -1
        steps = [kernel.steps for kernel in quotient.objectives if kernel is not None]
        self.horizon = max(steps) if steps else 0
        # a weighted sum's parts: the step-bounded rewards, and the reachability objective's step bound
        found = [(i, kn) for i, kn in enumerate(self.kernels) if kn is not None and kn.kind is KernelKind.CUMULATIVE]
        self.cumulative = [i for i, _ in found]
        self.cumulative_rows = np.array([kn.reward for _, kn in found], dtype=np.int64)
        self.cumulative_steps = np.array([kn.steps for _, kn in found], dtype=np.int64)
        until_kernel = self.kernels[self.until] if self.until >= 0 else None
        self.until_steps = (
            until_kernel.steps if until_kernel is not None and until_kernel.kind is KernelKind.BOUNDED else -1
        )
        self.weighted_horizon = max([*self.cumulative_steps.tolist(), self.until_steps, 0])
        """The steps a weighted sum's backward induction runs over."""

    def restrict(self, lo: np.ndarray, hi: np.ndarray) -> Restricted:
        r = self.relaxation
        allowed = k.allowed_actions(r.state_actions, r.state_decisions, r.decisions, r.domain_sizes, lo, hi)
        return Restricted(allowed, k.reachable(r.initial, r.state_actions, r.action_entries, r.targets, allowed))

    def consulted(self, view: Restricted) -> np.ndarray:
        """Which decisions some reached state consults (the others cannot change a value)."""
        r = self.relaxation
        counts = np.diff(r.state_decisions)
        owners = np.repeat(np.arange(r.states), counts)
        out = np.zeros(len(self.sizes), dtype=bool)
        out[r.decisions[view.live[owners]]] = True
        return out

    def votes(self, view: Restricted, actions: np.ndarray) -> np.ndarray:
        """How often a scheduler (an action per state, -1 where none) takes each value (by its
        index in the domain) of each decision, over the states it acts in: [decisions, values].
        A scheduler that takes one value per decision everywhere is a policy of the family."""
        r = self.relaxation
        out = np.zeros((len(self.sizes), int(self.sizes.max(initial=1))), dtype=np.int64)
        acting = np.flatnonzero((actions >= 0) & view.live)
        local = actions[acting] - r.state_actions[acting]
        first, last = r.state_decisions[acting], r.state_decisions[acting + 1]
        for offset in range(int((last - first).max(initial=0))):
            has = first + offset < last
            decisions = r.decisions[(first + offset)[has]]
            sizes = r.domain_sizes[decisions]
            np.add.at(out, (decisions, local[has] % sizes), 1)
            local[has] //= sizes
        return out

    def horizon_votes(self, view: Restricted, weights: np.ndarray) -> np.ndarray | None:
        """Where the best scheduler of one weighted sum (``weights``, as :meth:`weighted`) acts,
        as votes per decision and value (its expected steps in states that take the value,
        :func:`~parley_core.quotient.subfamily.horizon_mass`); None where the weighted sums are
        not step-bounded ones solved by backward induction."""
        if not self.weighted_ok:
            return None
        r = self.relaxation
        weights = np.asarray(weights, dtype=float)
        cumulative, rows, steps = self.cumulative, self.cumulative_rows, self.cumulative_steps
        coefficients = np.ascontiguousarray(weights[cumulative] * self.signs[cumulative])
        until = self.until
        n = r.states
        left, right, until_steps, reach = self._until_parts(view, until)
        gain = float(weights[until] * self.signs[until]) if until >= 0 else 0.0
        compact = self._compact(view)
        solve: Any = k.horizon_mass  # a numba dispatcher: mypy cannot see its signature
        mass = solve(
            *compact, n, r.rewards, rows, steps, coefficients, self.weighted_horizon, until >= 0,
            left, right, until_steps, gain, gain * reach, r.initial,
        )  # fmt: skip
        return self.action_votes(compact[2], mass)

    def _until_parts(self, view: Restricted, until: int) -> tuple[np.ndarray, np.ndarray, int, np.ndarray]:
        """A weighted sum's reachability objective ``until`` (-1: none): its left and right
        states, its step bound (-1: unbounded) and, unbounded, its bound past the horizon."""
        n = self.relaxation.states
        left, right, until_steps, reach = np.ones(n, dtype=bool), np.zeros(n, dtype=bool), -1, np.zeros(n)
        if until >= 0:
            kernel = self.kernels[until]
            assert kernel is not None
            left, right = self.left[until], self.right[until]
            if kernel.kind is KernelKind.BOUNDED:
                until_steps = kernel.steps
            else:
                reach = self._reach(view, until)
        return left, right, until_steps, reach

    def action_votes(self, actions: np.ndarray, mass: np.ndarray) -> np.ndarray:
        """Per decision and value (its index in the domain), the ``mass`` of the relaxation's
        ``actions`` that take it: [decisions, values]."""
        r = self.relaxation
        out = np.zeros((len(self.sizes), int(self.sizes.max(initial=1))))
        taken = mass > 0
        actions, mass = actions[taken], mass[taken]
        owners = np.searchsorted(r.state_actions, actions, side="right") - 1
        local = actions - r.state_actions[owners]
        first, last = r.state_decisions[owners], r.state_decisions[owners + 1]
        for offset in range(int((last - first).max(initial=0))):
            has = first + offset < last
            decisions = r.decisions[(first + offset)[has]]
            sizes = r.domain_sizes[decisions]
            np.add.at(out, (decisions, local[has] % sizes), mass[has])
            local[has] //= sizes
        return out

    def _reach(self, view: Restricted, i: int) -> np.ndarray:
        if i not in view.reach:
            r = self.relaxation
            view.reach[i] = k.reach_probability(
                r.state_actions, r.action_entries, r.targets, r.probabilities, view.allowed, view.live,
                self.left[i], self.right[i], bool(self.signs[i] > 0), *self.pred, TOLERANCE, SWEEPS,
            )  # fmt: skip
        return view.reach[i]

    def ideal(self, view: Restricted) -> np.ndarray:
        """Per objective the best value over the sub-family's schedulers (sign space), widened."""
        r = self.relaxation
        out = np.empty(len(self.signs))
        horizon: list[int] = []
        for i, (kernel, sign) in enumerate(zip(self.kernels, self.signs)):
            if not self.supported[i] or kernel is None:
                probability = kernel is not None and kernel.kind in (KernelKind.UNTIL, KernelKind.BOUNDED)
                out[i] = (1.0 if sign > 0 else 0.0) if probability else (np.inf if sign > 0 else 0.0)
            elif kernel.kind is KernelKind.UNTIL:
                out[i] = sign * self._reach(view, i)[r.initial]
            elif kernel.kind in (KernelKind.REACH_REWARD, KernelKind.TOTAL):
                reach = kernel.kind is KernelKind.REACH_REWARD
                out[i] = -self._least_reward(view, r.rewards[kernel.reward], self.right[i], reach, i)
            elif kernel.kind is KernelKind.BOUNDED and i != self.until:
                out[i] = self._horizon(view, np.eye(len(self.signs))[i : i + 1], i)[0]
            else:
                horizon.append(i)
        if horizon:
            until = self.until if self.until in horizon else -1
            out[horizon] = self._horizon(view, np.eye(len(self.signs))[horizon], until)
        return out + WIDEN * np.maximum(1.0, np.abs(np.where(np.isfinite(out), out, 0.0)))

    def weighted(self, view: Restricted, weights: np.ndarray) -> np.ndarray:
        """Per row of ``weights`` (>= 0) a sound upper bound of ``sum_i w_i * sign_i * value_i``
        over the sub-family; infinity where the objectives do not combine."""
        weights = np.atleast_2d(weights)
        if self.weighted_ok:
            values = self._horizon(view, weights, self.until)
        elif self.summed_ok:
            values = self._summed(view, weights)
        elif self.mixed_ok:
            values = self._mixed(view, weights)
        else:
            return np.full(len(weights), np.inf)
        with np.errstate(invalid="ignore"):  # -inf (no scheduler has a finite sum) stays -inf
            widened = values + WIDEN * np.abs(weights).sum(axis=1) * np.maximum(1.0, np.abs(values))
        return np.where(np.isneginf(values), values, widened)

    def _summed(self, view: Restricted, weights: np.ndarray) -> np.ndarray:
        """Minimised expected rewards to one target: per row of weights, minus a lower bound of
        the least expected weighted reward; infinity (no cut) where no scheduler reaches the
        target, for a policy may still have a value."""
        r = self.relaxation
        rows = r.rewards[[kernel.reward for kernel in self.kernels if kernel is not None]]
        reach = self.kernels[0] is not None and self.kernels[0].kind is KernelKind.REACH_REWARD
        out = np.empty(len(weights))
        for row, w in enumerate(weights):
            least = self._least_reward(view, w @ rows, self.right[0], reach, "weighted")
            out[row] = -least if np.isfinite(least) else np.inf
        return out

    def _mixed(self, view: Restricted, weights: np.ndarray) -> np.ndarray:
        """Minimised expected rewards to a target and the maximised probability to reach it
        within a step bound: backward induction over the bound, and past it the least expected
        reward still to come, bounded from below per state (:meth:`_least_rewards`)."""
        r = self.relaxation
        bounded = next(i for i, kn in enumerate(self.kernels) if kn is not None and kn.kind is KernelKind.BOUNDED)
        kernel = self.kernels[bounded]
        assert kernel is not None
        rewards = [i for i in range(len(self.kernels)) if i != bounded]
        rows = r.rewards[[kn.reward for i, kn in enumerate(self.kernels) if i != bounded and kn is not None]]
        out = np.empty(len(weights))
        for row, w in enumerate(weights):
            reward = np.ascontiguousarray(w[rewards] @ rows)
            terminal = self._least_rewards(view, reward, self.right[0], True, "weighted")
            solve: Any = k.reward_and_bounded  # a numba dispatcher: mypy cannot see its signature
            out[row] = solve(
                *self._compact(view),
                r.states,
                reward,
                self.right[0],
                kernel.steps,
                float(w[bounded]),
                terminal,
                r.initial,
            )
        return out

    def _compact(self, view: Restricted) -> tuple[np.ndarray, ...]:
        """The sub-family's part of the relaxation as its own CSR, built once per view."""
        if view.compact is None:
            r = self.relaxation
            view.compact = k.compact(r.state_actions, r.action_entries, r.targets, r.probabilities, view.allowed,
                                     view.live)  # fmt: skip
        return view.compact

    def _least_reward(self, view: Restricted, reward: np.ndarray, right: np.ndarray, reach: bool, key: object) -> float:
        return float(self._least_rewards(view, reward, right, reach, key)[self.relaxation.initial])

    def _least_rewards(
        self, view: Restricted, reward: np.ndarray, right: np.ndarray, reach: bool, key: object
    ) -> np.ndarray:
        """Per state a lower bound of the least expected ``reward`` (per action) until ``right``
        (``reach``) or in total, over the sub-family's schedulers.

        Iterated from 0 every iterate is below the value, but on models where the target is
        far (queues, PAYNT's dpm) that takes thousands of sweeps. For rewards until a target
        the iteration starts higher, still below: from the value of the best scheduler policy
        iteration finds (a few sparse solves, started from the scheduler last found under the
        same ``key``), lowered until it is a post-fixpoint
        (:func:`~parley_core.quotient.subfamily.post_fixpoint`), which bounds every scheduler
        that reaches the target almost surely, and the others' values are infinite. The
        scheduler joins ``view.schedulers``."""
        r = self.relaxation
        reward = np.ascontiguousarray(reward, dtype=float)[None, :]
        x = k.min_reward(
            r.state_actions, r.action_entries, r.targets, r.probabilities, view.allowed, view.live, reward, 0,
            right, reach, *self.pred, TOLERANCE, WARM if reach else SWEEPS,
        )  # fmt: skip
        if not reach or not np.isfinite(x[r.initial]):
            return x
        free = view.live & ~right & np.isfinite(x)
        sweeps = SWEEPS
        found = None
        last = self._last.get(key)
        if last is not None:
            usable = last >= 0
            usable[usable] = view.allowed[last[usable]]
            found = policy_iteration.best_scheduler(
                r, self.rank, view.allowed, reward[0], free, x, np.where(usable, last, -1)
            )
        if found is None:
            found = policy_iteration.best_scheduler(
                r, self.rank, view.allowed, reward[0], free, x, np.full(r.states, -1, dtype=np.int64)
            )
        if found is not None:
            # less the expected steps times a small margin: the scheduler's own actions then
            # keep that margin, and what rounding or other actions need is lowered below
            guess, steps, actions = found
            self._last[key] = actions
            view.schedulers.append(actions)
            margin = 1e-9 * (1.0 + guess.max()) / max(1.0, steps.max())
            y = np.where(free, guess - margin * steps, np.where(right, 0.0, np.inf))
            y[~view.live] = 0.0
            if k.post_fixpoint(r.state_actions, r.action_entries, r.targets, r.probabilities, view.allowed, free,
                               reward[0], y, PASSES):  # fmt: skip
                x = np.where(free, np.maximum(x, y), x)
                sweeps = WARM  # a few more sweeps take back the margin; it is sound wherever it stops
        k.min_reward_from(r.state_actions, r.action_entries, r.targets, r.probabilities, view.allowed, view.live,
                          reward[0], right, True, x, TOLERANCE, sweeps)  # fmt: skip
        return x

    @functools.cached_property
    def rank(self) -> np.ndarray:
        """Per state of the relaxation its place in the sparse solves' elimination order."""
        r = self.relaxation
        return ordering.elimination_rank(r.state_actions, r.action_entries, r.targets)

    def _horizon(self, view: Restricted, weights: np.ndarray, until: int) -> np.ndarray:
        r = self.relaxation
        cumulative, rows, steps = self.cumulative, self.cumulative_rows, self.cumulative_steps
        coefficients = np.ascontiguousarray(weights[:, cumulative] * self.signs[cumulative])
        n = r.states
        # not always self.until: ideal() bounds each bounded probability this way
        left, right, until_steps, reach = self._until_parts(view, until)
        horizon = max([*steps.tolist(), until_steps, 0])
        gains = weights[:, until] * self.signs[until] if until >= 0 else np.zeros(len(weights))
        solve: Any = k.weighted_horizons  # numba dispatchers: mypy cannot see their signatures
        single: Any = k.weighted_horizon
        compact = self._compact(view)

        def chunk(part: np.ndarray) -> np.ndarray:
            if len(part) < TOGETHER:  # the scalar kernel, one weighting at a time
                return np.array([single(
                    *compact, n, r.rewards, rows, steps, np.ascontiguousarray(coefficients[w]), horizon, until >= 0,
                    left, right, until_steps, float(gains[w]), float(gains[w]) * reach, r.initial,
                ) for w in part])  # fmt: skip
            return solve(
                *compact, n, r.rewards, rows, steps, np.ascontiguousarray(coefficients[part]), horizon, until >= 0,
                left, right, until_steps, np.ascontiguousarray(gains[part]), reach, r.initial,
            )  # fmt: skip

        count = -(-len(weights) // WEIGHTS_AT_ONCE)
        if self.threads > 1:  # as many parts for each thread
            count = min(len(weights), -(-count // self.threads) * self.threads)
        parts = np.array_split(np.arange(len(weights)), count)
        if self.threads > 1 and len(parts) > 1:
            with ThreadPoolExecutor(min(self.threads, len(parts)), thread_name_prefix="parley-bound") as pool:
                return np.concatenate(list(pool.map(chunk, parts)))
        return np.concatenate([chunk(part) for part in parts])
