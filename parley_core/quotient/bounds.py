"""A family's objectives on its relaxation, bounded per sub-family: the ideal point and
weighted sums, in sign space (every objective maximised), sound by construction
(:mod:`parley_core.quotient.subfamily` says why each kernel is on the safe side).

A sub-family is a pair of integer arrays ``lo``, ``hi``: per decision an interval of its
domain's indices.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from parley_core.model import Direction, Family
from parley_core.quotient import subfamily as k
from parley_core.quotient.coloring import Quotient
from parley_core.quotient.compile import KernelKind
from parley_core.quotient.relaxation import Relaxation, relax

WIDEN = 1e-10
"""Every bound is widened by this much of its size (at least 1): rounding in the kernels."""
TOLERANCE = 1e-12
SWEEPS = 5000


class Restricted:
    """A sub-family's view of the relaxation: its actions, the states it reaches, and the
    per-state reachability bounds its objectives need (computed once, shared by the ideal
    point and the weighted sums)."""

    def __init__(self, allowed: np.ndarray, live: np.ndarray) -> None:
        self.allowed = allowed
        self.live = live
        self.reach: dict[int, np.ndarray] = {}
        self.compact: tuple[np.ndarray, ...] | None = None


class RelaxedObjectives:
    """The family's objectives, bounded on sub-families of its quotient's relaxation."""

    def __init__(self, family: Family, quotient: Quotient, relaxation: Relaxation | None = None) -> None:
        self.family = family
        self.quotient = quotient
        self.relaxation = r = relaxation if relaxation is not None else relax(quotient, family)
        self.signs = np.array([1.0 if o.direction is Direction.MAX else -1.0 for o in family.objectives])
        self.kernels = quotient.objectives
        self.sizes = np.array([len(d.service.values) for d in family.decisions], dtype=np.int64)
        self.pred = k.predecessors(r)
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
                x = k.min_reward(
                    r.state_actions, r.action_entries, r.targets, r.probabilities, view.allowed, view.live,
                    r.rewards, kernel.reward, self.right[i], kernel.kind is KernelKind.REACH_REWARD, *self.pred,
                    TOLERANCE, SWEEPS,
                )  # fmt: skip
                out[i] = -x[r.initial]
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
        if not self.weighted_ok:
            return np.full(len(weights), np.inf)
        values = self._horizon(view, weights, self.until)
        return values + WIDEN * np.abs(weights).sum(axis=1) * np.maximum(1.0, np.abs(values))

    def _horizon(self, view: Restricted, weights: np.ndarray, until: int) -> np.ndarray:
        r = self.relaxation
        cumulative, rows, steps = self.cumulative, self.cumulative_rows, self.cumulative_steps
        coefficients = np.ascontiguousarray(weights[:, cumulative] * self.signs[cumulative])
        n = r.states
        left, right, until_steps, reach = np.ones(n, dtype=bool), np.zeros(n, dtype=bool), -1, np.zeros(n)
        if until >= 0:  # not always self.until: ideal() bounds each bounded probability this way
            kernel = self.kernels[until]
            assert kernel is not None
            left, right = self.left[until], self.right[until]
            if kernel.kind is KernelKind.BOUNDED:
                until_steps = kernel.steps
            else:
                reach = self._reach(view, until)
        horizon = max([*steps.tolist(), until_steps, 0])
        if view.compact is None:
            view.compact = k.compact(r.state_actions, r.action_entries, r.targets, r.probabilities, view.allowed,
                                     view.live)  # fmt: skip
        out = np.empty(len(weights))
        solve: Any = k.weighted_horizon  # a numba dispatcher: mypy cannot see its signature
        for row, (w, c) in enumerate(zip(weights, coefficients)):
            gain = float(w[until] * self.signs[until]) if until >= 0 else 0.0
            out[row] = solve(
                *view.compact, n, r.rewards, rows, steps, np.ascontiguousarray(c), horizon, until >= 0, left, right,
                until_steps, gain, gain * reach, r.initial,
            )  # fmt: skip
        return out
