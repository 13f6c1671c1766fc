"""Solving one policy on a quotient: explore its reachable DTMC, then each objective.

Every objective is solved from zero for each policy, so a value depends on the policy alone.
Reachability and reward objectives use Gauss-Seidel sweeps (:func:`.kernels.gauss_seidel`)
to a relative change of :data:`TOLERANCE`, with a direct sparse solve as the fallback;
step-bounded ones are exact iterations.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp
from scipy.sparse import csgraph

from parley_core.quotient import kernels
from parley_core.quotient.coloring import Quotient
from parley_core.quotient.compile import KernelKind

TOLERANCE = 1e-12
MAX_SWEEPS = 1_000_000


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
        self.local_of = np.full(n, -1, dtype=np.int64)
        self.order = np.empty(n, dtype=np.int64)
        self.indptr = np.empty(n + 1, dtype=np.int64)
        self.cols = np.empty(max(b, n) + n, dtype=np.int64)
        self.vals = np.empty(max(b, n) + n, dtype=np.float64)
        self.rewards = np.empty((quotient.state_rewards.shape[0], n))
        self.levels = np.empty(n, dtype=np.int64)
        self.chosen = np.empty(max(1, int(np.diff(quotient.state_choices).max(initial=0))), dtype=np.int64)
        self.last_states = 0
        # C<=k objectives with the same k share one forward pass: {k: (objectives, rewards)}
        self.cumulative: dict[int, tuple[list[int], np.ndarray]] = {}
        for i, objective in enumerate(quotient.objectives):
            if objective is not None and objective.kind is KernelKind.CUMULATIVE:
                indices, rewards = self.cumulative.get(objective.steps, ([], np.empty(0, dtype=np.int64)))
                self.cumulative[objective.steps] = ([*indices, i], np.append(rewards, objective.reward))

    def solve(self, policy: np.ndarray) -> list[float | None]:
        q = self.q
        count, nnz = kernels.explore(
            np.asarray(policy, dtype=np.int64),
            q.initial,
            q.state_choices,
            q.choice_branches,
            q.targets,
            q.probabilities,
            q.choice_dec,
            q.choice_val,
            q.state_rewards,
            q.choice_rewards,
            self.local_of,
            self.order,
            self.indptr,
            self.cols,
            self.vals,
            self.rewards,
            self.levels,
            self.chosen,
        )
        self.last_states = count
        indptr, cols, vals = self.indptr[: count + 1], self.cols[:nnz], self.vals[:nnz]
        order = self.order[:count]
        values: list[float | None] = [None] * len(q.objectives)
        for steps, (indices, rewards) in self.cumulative.items():
            totals = kernels.cumulative(count, indptr, cols, vals, steps, self.rewards[rewards, :count], self.levels)
            for i, total in zip(indices, totals):
                values[i] = float(total)
        for i, objective in enumerate(q.objectives):
            if objective is not None and objective.kind is not KernelKind.CUMULATIVE:
                values[i] = self._objective(objective, count, indptr, cols, vals, order)
        return values

    def _objective(self, objective, count, indptr, cols, vals, order) -> float:
        if objective.kind is KernelKind.UNTIL:
            left, right = objective.left[order], objective.right[order]
            # Iterating from 0, a state that cannot reach a right state keeps exactly 0 (the
            # value Storm's prob0 analysis gives it), so the full graph analysis is only
            # needed for the direct solve after a sweep limit, where those states make I - P
            # singular. One cheap pass finds most of them and leaves them out of the sweeps.
            free = left & ~right & ~kernels.cannot_reach(count, indptr, cols, right, left)
            x = np.where(right, 1.0, 0.0)
            if self._sweeps(count, indptr, cols, vals, free, x, np.zeros(count)):
                return float(x[0])
            can = kernels.backward_reach(count, indptr, cols, right, left)
            x = np.where(right, 1.0, 0.0)
            return self._gauss_seidel(count, indptr, cols, vals, can & ~right, x, np.zeros(count))
        if objective.kind is KernelKind.BOUNDED:
            left, right = objective.left[order], objective.right[order]
            x = np.where(right, 1.0, 0.0)
            x = kernels.bounded(
                count, indptr, cols, vals, objective.steps, x, np.zeros(count), left & ~right, self.levels
            )
            return float(x[0])
        reward = self.rewards[objective.reward, :count].copy()
        if objective.kind is KernelKind.REACH_REWARD:
            right = objective.right[order]
            can = kernels.backward_reach(count, indptr, cols, right, np.ones(count, bool))
            # infinite where a state that cannot reach the target is reachable (avoiding it)
            infinite = kernels.backward_reach(count, indptr, cols, ~can, ~right)
            if infinite[0]:
                return float("inf")
            free = ~right & ~infinite
            return self._gauss_seidel(count, indptr, cols, vals, free, np.zeros(count), np.where(free, reward, 0.0))
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
            return self._gauss_seidel(count, indptr, cols, vals, free, np.zeros(count), np.where(free, reward, 0.0))
        raise ValueError(objective.kind)

    def _sweeps(self, count, indptr, cols, vals, free, x, constant) -> bool:
        """Gauss-Seidel for x = constant + P x on the ``free`` states, in reverse breadth-first
        order, with the states that only pass probability on (one transition, probability
        1) substituted away; x[0] holds the value when it returns True (converged)."""
        through = kernels.pass_through(count, indptr, cols, vals, ~free, count)
        # (indptr, cols, vals, constant) of the lumped equations
        lumped: tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray] = kernels.lump(
            count, indptr, cols, vals, through, constant
        )
        rows = np.flatnonzero(free & (through < 0))[::-1].copy()
        return kernels.gauss_seidel(*lumped[:3], rows, x, lumped[3], TOLERANCE, MAX_SWEEPS) >= 0

    def _gauss_seidel(self, count, indptr, cols, vals, free, x, constant) -> float:
        if not self._sweeps(count, indptr, cols, vals, free, x, constant):
            # no convergence: a direct solve on the free states
            idx = np.flatnonzero(free)
            matrix = sp.csr_matrix((vals, cols, indptr), shape=(count, count))
            sub = matrix[idx][:, idx]
            rhs = constant[idx] + matrix[idx][:, np.flatnonzero(~free)] @ x[~free]
            x[idx] = sp.linalg.spsolve((sp.identity(len(idx)) - sub).tocsc(), rhs)
        return float(x[0])
