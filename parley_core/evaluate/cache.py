"""A memo in front of an evaluator: every policy evaluated once, in the order first seen.

The search's cache: the front is taken from everything evaluated, not only from the last
population, and no policy is evaluated twice. Where the evaluator can say which decisions a
policy consults (a :class:`~parley_core.evaluate.Consulting` one, the quotient's), the cache
keeps that too; elsewhere every decision counts as consulted. (Branch and bound's archive,
with its local upper bounds, is :mod:`parley_core.optimality.archive`.)
"""

from __future__ import annotations

import numpy as np

from parley_core.evaluate import Consulting, Evaluator
from parley_core.progress import Progress


class CachingEvaluator:
    """Every policy evaluated so far, in order, with its values; evaluates only what is new.

    It is an :class:`~parley_core.evaluate.Evaluator` itself; ``close`` closes the one it wraps.
    """

    def __init__(self, evaluator: Evaluator, n_decisions: int, n_objectives: int) -> None:
        self.evaluator = evaluator
        self.name = evaluator.name
        self._index: dict[bytes, int] = {}
        self._policies: list[np.ndarray] = []
        self._values: list[np.ndarray] = []
        self._consulted: list[np.ndarray] = []
        self.n_decisions = n_decisions
        self.n_objectives = n_objectives

    @property
    def workers(self) -> int:
        return self.evaluator.workers

    def describe(self) -> dict[str, object]:
        return self.evaluator.describe()

    def __len__(self) -> int:
        return len(self._policies)

    @property
    def policies(self) -> np.ndarray:
        return np.array(self._policies, dtype=np.int64).reshape(-1, self.n_decisions)

    @property
    def values(self) -> np.ndarray:
        return np.array(self._values, dtype=float).reshape(-1, self.n_objectives)

    def rows(self, indices: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The policies of archive rows ``indices`` and the decisions their reachable states
        consult ([n, decisions] bool)."""
        indices = np.asarray(indices, dtype=np.int64).ravel()
        policies = np.array([self._policies[i] for i in indices], dtype=np.int64).reshape(-1, self.n_decisions)
        masks = np.array([self._consulted[i] for i in indices], dtype=bool).reshape(-1, self.n_decisions)
        return policies, masks

    def lookup(self, policies: np.ndarray) -> np.ndarray:
        """Archive rows of ``policies`` (-1: not evaluated)."""
        policies = np.asarray(policies, dtype=np.int64).reshape(-1, self.n_decisions)
        return np.array([self._index.get(row.tobytes(), -1) for row in policies], dtype=np.int64)

    def __contains__(self, policy: np.ndarray) -> bool:
        return np.asarray(policy, dtype=np.int64).tobytes() in self._index

    def evaluate(self, policies: np.ndarray, progress: Progress | None = None, budget: int | None = None) -> np.ndarray:
        """Values of ``policies``; at most ``budget`` new ones are evaluated (first come,
        first served), and the rows of the others are NaN."""
        policies = np.asarray(policies, dtype=np.int64).reshape(-1, self.n_decisions)
        keys = [row.tobytes() for row in policies]
        new: dict[bytes, np.ndarray] = {}
        for key, row in zip(keys, policies):
            if key not in self._index and key not in new:
                if budget is not None and len(new) >= budget:
                    continue
                new[key] = row
        if new:
            rows = np.array(list(new.values()))
            if isinstance(self.evaluator, Consulting):
                values, consulted = self.evaluator.evaluate_consulted(rows, progress=progress)
            else:
                values = self.evaluator.evaluate(rows, progress=progress)
                consulted = np.ones(rows.shape, dtype=bool)
            for key, row, value, mask in zip(new, rows, values, consulted):
                self._index[key] = len(self._policies)
                self._policies.append(row.copy())
                self._values.append(np.asarray(value, dtype=float))
                self._consulted.append(np.asarray(mask, dtype=bool))
        missing = np.full(self.n_objectives, np.nan)
        return np.array([self._values[self._index[k]] if k in self._index else missing for k in keys]).reshape(
            -1, self.n_objectives
        )

    def close(self, abort: bool = False) -> None:
        self.evaluator.close(abort)
