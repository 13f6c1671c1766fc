"""Solving one policy on a quotient: explore its reachable DTMC, then each objective.

Every objective is solved from zero for each policy, so a value depends on the policy alone.
Reachability and reward objectives use Gauss-Seidel sweeps (:func:`.kernels.gauss_seidel`)
to a relative change of :data:`TOLERANCE`, with a direct sparse solve as the fallback;
step-bounded ones are exact iterations.
"""

from __future__ import annotations

import functools
from typing import Any

import numpy as np
import scipy.sparse as sp
from scipy.sparse import csgraph

from parley_core.quotient import kernels, ordering
from parley_core.quotient.coloring import Quotient
from parley_core.quotient.compile import KernelKind

TOLERANCE = 1e-12
"""Gauss-Seidel stops when no value moves by more than this, relative to its size."""
CERTIFIED = 1e-10
"""The largest error a reported unbounded value may have, relative to its size (at least 1):
a value that cannot be certified within it is solved again directly, or left to Storm."""
CERTIFY_SWEEPS = 2_000
"""Sweeps for the rough solution of the certificate; a chain that needs more gets a direct solve."""
ROUGH = (1e-3, 1e-6)
"""The tolerances of the certificate's rough solution, the second where the first leaves a
residual above 1/2. Any h with residual at most w < 1 bounds the amplification (by
h / (1 - w)), so a rough h costs only a slightly looser bound: at 1e-3 the 50x50 map's
residuals stay below 0.05, and the certificate takes half the sweeps it took at 1e-6."""
REFINEMENTS = 3
"""Rounds of :data:`MORE_SWEEPS` further sweeps when a converged solution is not yet certified."""
MORE_SWEEPS = 100
SLOW_SWEEPS = 100
"""The fewest sweeps a solve may use before it gives up as slowly mixing: its Gauss-Seidel
value is then far less reliable than its last change suggests, and a sparse LU solve is
cheaper than certifying it (PAYNT's dpm, 1,100 unknowns: its LU solve costs about 55 sweeps,
and certified sweeps 500). The sweeps give up earlier where the rate at which their change
falls says they cannot make it (:func:`.kernels.gauss_seidel`'s ``give_up``)."""
ROWS_PER_SWEEP = 40
"""A larger system may sweep one more time for every this many unknowns (:func:`sweep_budget`)."""


def sweep_budget(unknowns: int) -> int:
    """The sweeps a solve of ``unknowns`` unknowns may use before it gives up and goes to a
    direct solve: :data:`SLOW_SWEEPS`, or more where the LU solve costs more than that many
    sweeps. An LU solve's fill grows faster than its unknowns, so its cost in sweeps grows
    with them: on a 50x50 robot map's chains (robot_grid, seed 11) it was worth 115 sweeps at
    2,476 unknowns, 200 at 13,794 and 775 at 34,605 (its factors 28 times as large as the
    system there), about one sweep per :data:`ROWS_PER_SWEEP` unknowns. With the fixed 100,
    the rate of the first sweeps, while the values still spread over the map, predicted about
    170 sweeps where 16-25 sufficed, and 288 of 300 policies of a 50x50 search went to an LU
    solve costing 10-30 times the sweeps (docs/performance.md). Depends on the size alone, so
    a value still depends on the policy alone."""
    return max(SLOW_SWEEPS, unknowns // ROWS_PER_SWEEP)


class _Equations:
    """What one policy's objectives with the same equations share (:meth:`QuotientSolver._solve`)."""

    def __init__(self) -> None:
        self.through: np.ndarray | None = None
        """Per state the one it passes on to (:func:`.kernels.pass_through`), -1 if none."""
        self.slow = False
        """The sweeps gave up: a direct solve at once."""
        self.singular = False
        self.factors: Any = None
        self.system: Any = None
        self.steps = np.zeros(0)
        """h solving (I - P) h = 1, by the factors."""
        self.worst = np.inf
        """max |1 - (I - P) h|: h's residual."""


class QuotientSolver:
    """Evaluates policies on a quotient in this process, with reusable work arrays.

    A policy's values depend on the policy alone (iterations start from zero, never from an
    earlier policy's solution), so results do not depend on which process solved what
    before: runs are reproducible whatever the number of workers (docs/performance.md says
    why there are no warm starts).
    """

    def __init__(self, quotient: Quotient) -> None:
        self.q = quotient
        n, b = quotient.states, quotient.branches
        self.reached = kernels.Reached(
            local_of=np.full(n, -1, dtype=np.int64),
            order=np.empty(n, dtype=np.int64),
            indptr=np.empty(n + 1, dtype=np.int64),
            cols=np.empty(max(b, n) + n, dtype=np.int64),
            vals=np.empty(max(b, n) + n, dtype=np.float64),
            rewards=np.empty((quotient.state_rewards.shape[0], n)),
            levels=np.empty(n, dtype=np.int64),
            chosen=np.empty(max(1, int(np.diff(quotient.state_choices).max(initial=0))), dtype=np.int64),
            stuck=np.zeros(n, dtype=np.bool_),
        )
        """Where :func:`.kernels.explore` writes a policy's DTMC (its arrays, for the solves)."""
        self.chain = kernels.chain_of(quotient)
        """The quotient's arrays as the kernels read them; ``chain.lookup`` looks up a state's
        consistent choice by value where one decision decides."""
        self.consulted = np.zeros(0, dtype=np.bool_)
        """The decisions the last solved policy consulted (see :func:`.kernels.explore`)."""
        self.last_states = 0
        self.direct_solves = 0
        self.last_sweeps = 0
        """Solves the sweeps could not certify, done again by a direct solve."""
        self.uncertified = 0
        """Values no solve could certify (NaN: the evaluator has Storm check them)."""
        # C<=k objectives with the same k share one forward pass: {k: (objectives, rewards)}
        self.cumulative: dict[int, tuple[list[int], np.ndarray]] = {}
        for i, objective in enumerate(quotient.objectives):
            if objective is not None and objective.kind is KernelKind.CUMULATIVE:
                indices, rewards = self.cumulative.get(objective.steps, ([], np.empty(0, dtype=np.int64)))
                self.cumulative[objective.steps] = ([*indices, i], np.append(rewards, objective.reward))

    def solve(self, policy: np.ndarray) -> list[float | None]:
        q = self.q
        policy = np.asarray(policy, dtype=np.int64)
        if len(self.consulted) != len(policy):
            self.consulted = np.zeros(len(policy), dtype=np.bool_)
        self.consulted[:] = False
        count, nnz = kernels.explore(policy, self.chain, self.reached, self.consulted)
        self.last_states = count
        indptr, cols, vals = self.reached.indptr[: count + 1], self.reached.cols[:nnz], self.reached.vals[:nnz]
        order = self.reached.order[:count]
        values: list[float | None] = [None] * len(q.objectives)
        shared: dict[bytes, _Equations] = {}
        for steps, (indices, rewards) in self.cumulative.items():
            totals = kernels.cumulative(
                count, indptr, cols, vals, steps, self.reached.rewards[rewards, :count], self.reached.levels
            )
            for i, total in zip(indices, totals):
                values[i] = float(total)
        for i, objective in enumerate(q.objectives):
            if objective is not None and objective.kind is not KernelKind.CUMULATIVE:
                values[i] = self._objective(objective, count, indptr, cols, vals, order, shared)
        return values

    def _objective(self, objective, count, indptr, cols, vals, order, shared) -> float:
        if objective.kind is KernelKind.UNTIL:
            left, right = objective.left[order], self._right(objective, order, count)
            # Iterating from 0, a state that cannot reach a right state keeps exactly 0 (the
            # value Storm's prob0 analysis gives it). One cheap pass finds most of them and
            # leaves them out of the sweeps; the certificate and the direct solve need all.
            free = left & ~right & ~kernels.cannot_reach(count, indptr, cols, right, left)
            can = kernels.backward_reach(count, indptr, cols, right, left)
            x = np.where(right, 1.0, 0.0)
            return self._solve(count, indptr, cols, vals, free, x, np.zeros(count), can & ~right, shared, order)
        if objective.kind is KernelKind.BOUNDED:
            left, right = objective.left[order], self._right(objective, order, count)
            x = np.where(right, 1.0, 0.0)
            x = kernels.bounded(
                count, indptr, cols, vals, objective.steps, x, np.zeros(count), left & ~right, self.reached.levels
            )
            return float(x[0])
        reward = self.reached.rewards[objective.reward, :count].copy()
        if objective.kind is KernelKind.REACH_REWARD:
            right = self._right(objective, order, count)
            can = kernels.backward_reach(count, indptr, cols, right, np.ones(count, bool))
            # infinite where a state that cannot reach the target is reachable (avoiding it)
            infinite = kernels.backward_reach(count, indptr, cols, ~can, ~right)
            if infinite[0]:
                return float("inf")
            free = ~right & ~infinite
            constant = np.where(free, reward, 0.0)
            return self._solve(count, indptr, cols, vals, free, np.zeros(count), constant, free, shared, order)
        if objective.kind is KernelKind.TOTAL:
            matrix = sp.csr_matrix((vals, cols, indptr), shape=(count, count))
            _, labels = csgraph.connected_components(matrix, directed=True, connection="strong")
            # bottom components: no transition with positive probability leaves them
            sources = np.repeat(np.arange(count), np.diff(indptr))
            leaving = (labels[cols] != labels[sources]) & (vals > 0)
            leaves = np.ones(labels.max() + 1, dtype=bool)
            leaves[labels[sources[leaving]]] = False
            bottom = leaves[labels]
            positive = np.zeros(labels.max() + 1, dtype=bool)
            np.logical_or.at(positive, labels, bottom & (reward > 0))
            infinite = kernels.backward_reach(count, indptr, cols, positive[labels], np.ones(count, bool))
            if infinite[0]:
                return float("inf")
            free = ~bottom & ~infinite
            constant = np.where(free, reward, 0.0)
            return self._solve(count, indptr, cols, vals, free, np.zeros(count), constant, free, shared, order)
        raise ValueError(objective.kind)

    def _right(self, objective, order, count) -> np.ndarray:
        """The objective's target states, local: the policy's own deadlocks for "deadlock"."""
        if objective.right_deadlock:
            return objective.right[order] | self.reached.stuck[:count]
        return objective.right[order]

    def _solve(self, count, indptr, cols, vals, free, x, constant, exact, shared, order) -> float:
        """x[0] for x = constant + P x on the ``free`` states, certified: Gauss-Seidel sweeps
        first, a direct sparse solve if they do not converge or cannot be certified, and NaN
        if neither can be (the evaluator has Storm check that policy instead). ``exact``
        are the states whose values the equations determine (``free`` minus any it holds
        that keep their value anyway); the certificate (:func:`.kernels.residual` times
        :meth:`_amplification`) bounds the error at the initial state by :data:`CERTIFIED`
        times its size (at least 1). Objectives of one policy with the same ``free`` and
        ``exact`` (expected rewards to one target) share ``shared``'s entry for them: once
        the sweeps give up on one, the others go to the direct solve at once, and all use
        its factors."""
        known = shared.setdefault(free.tobytes() + exact.tobytes(), _Equations())
        if known.through is None:
            known.through = kernels.pass_through(count, indptr, cols, vals, ~free, count)
        through = known.through
        # (indptr, cols, vals, constant) of the lumped equations
        lumped = kernels.lump(count, indptr, cols, vals, through, constant)
        rows = np.flatnonzero(free & (through < 0))[::-1].copy()
        if not known.slow:
            lumped_ptr, lumped_cols, lumped_vals, lumped_constant = lumped
            budget = sweep_budget(len(rows))
            sweeps = kernels.gauss_seidel(
                lumped_ptr, lumped_cols, lumped_vals, rows, x, lumped_constant, TOLERANCE, budget, True
            )
            self.last_sweeps = sweeps
            known.slow = sweeps < 0
            if not known.slow:
                checked = rows[exact[rows]]
                if not exact[0] or checked.size == 0:
                    return float(x[0])  # the initial state's value is fixed (a target, or no way to one)
                target = CERTIFIED * max(1.0, abs(x[0]))
                gain = self._amplification(lumped_ptr, lumped_cols, lumped_vals, checked, count)
                for _ in range(REFINEMENTS + 1):
                    error = kernels.residual(lumped_ptr, lumped_cols, lumped_vals, checked, x, lumped_constant) * gain
                    if error <= target:
                        return float(x[0])
                    if not np.isfinite(gain):
                        break
                    kernels.gauss_seidel(
                        lumped_ptr, lumped_cols, lumped_vals, rows, x, lumped_constant, 0.0, MORE_SWEEPS
                    )
        self.direct_solves += 1
        return self._direct(lumped, exact & (through < 0), x, known, order)

    @functools.cached_property
    def rank(self) -> np.ndarray:
        """Per quotient state its place in the direct solves' elimination order (the quotient's
        alone: a value does not depend on which policies were solved before)."""
        return ordering.elimination_rank(self.q.state_choices, self.q.choice_branches, self.q.targets)

    def _amplification(self, indptr, cols, vals, rows, count) -> float:
        """A bound on (N 1)(s0) for N = (I - P)^-1 on ``rows``: h[s0] / c for a rough solution
        h of h = 1 + P h whose residual is at most 1 - c, c >= 1/2 (infinite if Gauss-Seidel
        does not get there within :data:`CERTIFY_SWEEPS`: a very slowly mixing chain)."""
        ones = np.zeros(count)
        ones[rows] = 1.0
        h = np.zeros(count)
        for tolerance in ROUGH:
            kernels.gauss_seidel(indptr, cols, vals, rows, h, ones, tolerance, CERTIFY_SWEEPS)
            worst = kernels.residual(indptr, cols, vals, rows, h, ones)
            if worst <= 0.5:
                break
        return float(h[0] / (1.0 - worst)) if worst <= 0.5 else float("inf")

    def _direct(self, lumped, exact, x, known: _Equations, order: np.ndarray) -> float:
        """x[0] by a sparse LU solve of the lumped equations (``lumped``: :func:`.kernels.lump`'s)
        on the ``exact`` states (none passed through; ``order``: their quotient states, for the
        elimination order of :mod:`.ordering`), the others fixed at their x, with the
        same kind of bound as :meth:`_solve`, computed from the LU solution of (I - P) h = 1;
        NaN if the bound exceeds :data:`CERTIFIED`. The factors, and h, are kept in ``known``
        for the next objective with the same equations."""
        if not exact[0]:
            return float(x[0])
        idx = np.flatnonzero(exact)
        idx = ordering.in_order(idx, self.rank[order[idx]])
        start = int(np.flatnonzero(idx == 0)[0])  # the initial state's place
        ptr, lumped_cols, lumped_vals, lumped_constant = lumped
        data, indices, pointers, rhs = kernels.equations(ptr, lumped_cols, lumped_vals, idx, x, lumped_constant)
        if known.factors is None and not known.singular:
            try:
                system, factors = ordering.factor(data, indices, pointers)
            except RuntimeError:  # singular: the equations do not determine the values
                known.singular = True
            else:
                steps = factors.solve(np.ones(len(idx)))
                known.factors, known.system, known.steps = factors, system, steps
                known.worst = float(np.abs(1.0 - system @ steps).max(initial=0.0))
        if known.singular:
            self.uncertified += 1
            return float("nan")
        factors, system, steps = known.factors, known.system, known.steps
        solution = factors.solve(rhs)
        solution += factors.solve(rhs - system @ solution)  # one step of iterative refinement
        residual = np.abs(rhs - system @ solution)
        # x* - x = N r with N = (I - P)^-1 >= 0, so |x* - x| <= N |r|: e = N |r| solved with
        # the same factors, and its own error bounded the same way (|e* - e| <= max|r_e| N 1,
        # N 1 <= 2 h when h solves (I - P) h = 1 with a residual at most 1/2)
        error = factors.solve(residual)
        slack = float(np.abs(residual - system @ error).max(initial=0.0))
        x[idx] = solution
        value = float(x[0])
        if known.worst <= 0.5:
            bound = abs(error[start]) + slack * 2.0 * abs(steps[start])
            if bound <= CERTIFIED * max(1.0, abs(value)):
                return value
        self.uncertified += 1
        return float("nan")
