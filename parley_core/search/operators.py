"""Variation for ordinal integer policies (every configuration but ``paper``).

A decision of a URC is an ordinal integer (an interval, a threshold): neighbouring values
give neighbouring behaviour, and most of a policy's decisions are never consulted (on a
10x10 map a random policy's reachable states read about 44 of its 100). SBX and polynomial
mutation on rounded floats know neither. :class:`OrdinalMating`

- picks parents by NSGA-II's binary tournament, and with ``archive_rate`` replaces a parent
  by a member of the archive's front (everything evaluated so far, not only the population:
  the front is taken from the archive, so it is the archive that should breed);
- crosses two parents uniformly (each gene from either parent), with ``crossover``;
- mutates each child in at least one gene among those its parents consult (the archive
  knows them: :meth:`~parley_core.evaluate.cache.CachingEvaluator.rows`), one more with
  probability ``extra`` each time; a mutated gene creeps one step up or down with ``creep``,
  else is reset to another value uniformly;
- and rejects a child that equals a parent on every decision that parent consults (it is
  the parent's DTMC again: the same values for a second evaluation) or that the archive
  already holds, drawing it again up to ``tries`` times;
- with ``local_rate``, makes a mating's two children instead by Pareto local search: each is
  a member of the archive's front (drawn with a weight of its distance to its nearest
  neighbour on the front, so the front's gaps are filled first) with one decision it consults
  moved one step up or down, a neighbour the archive does not hold yet.
"""

from __future__ import annotations

import numpy as np
from pymoo.algorithms.moo.nsga2 import binary_tournament
from pymoo.core.duplicate import DefaultDuplicateElimination
from pymoo.core.mating import Mating
from pymoo.core.population import Population
from pymoo.operators.selection.tournament import TournamentSelection

from parley_core import metrics
from parley_core.model import Direction
from parley_core.search.problem import PolicyProblem


class OrdinalMating(Mating):
    """Selection, uniform crossover and consulted-gene mutation in one (see the module)."""

    def __init__(
        self,
        *,
        crossover: float = 0.9,
        creep: float = 0.7,
        extra: float = 0.5,
        archive_rate: float = 0.0,
        local_rate: float = 0.0,
        tries: int = 20,
        tournament=binary_tournament,
    ) -> None:
        super().__init__(
            selection=TournamentSelection(func_comp=tournament),
            crossover=None,
            mutation=None,
            eliminate_duplicates=DefaultDuplicateElimination(),
            n_max_iterations=100,
        )
        self.crossover_rate = crossover
        self.creep = creep
        self.extra = extra
        self.archive_rate = archive_rate
        self.local_rate = local_rate
        self.tries = tries
        self._front: tuple[int, np.ndarray] = (-1, np.zeros(0, dtype=np.int64))
        self._near: tuple = (-1, None, None)

    def front(self, problem: PolicyProblem) -> np.ndarray:
        """Archive rows of its front (of the policies that meet the constraints, if any do)."""
        archive = problem.archive
        if self._front[0] != len(archive):
            values = archive.values
            candidates = metrics.front_candidates(values)
            if problem.constraints:
                feasible = (problem.violations(values) <= 0).all(axis=1) & candidates
                candidates = feasible if feasible.any() else candidates
            rows = np.flatnonzero(candidates)
            directions = [Direction.MIN] * values.shape[1]
            keep = metrics.nondominated(values[rows] * problem.signs, directions) if len(rows) else rows
            self._front = (len(archive), rows[keep] if len(rows) else rows)
        return self._front[1]

    def _nearest(self, problem: PolicyProblem):
        """The archive front's three nearest neighbours of each member and the members'
        weights (their distances to their nearest neighbour, normalised; None when those are
        not all finite and positive), objectives scaled to the front's range; cached until the
        archive grows."""
        front = self.front(problem)
        if self._near[0] != len(problem.archive):
            values = problem.archive.values[front] * problem.signs
            values = np.where(np.isfinite(values), values, 0.0)
            span = values.max(axis=0) - values.min(axis=0)
            scaled = (values - values.min(axis=0)) / np.where(span > 0, span, 1.0)
            distance = np.sqrt(((scaled[:, None, :] - scaled[None, :, :]) ** 2).sum(axis=2))
            np.fill_diagonal(distance, np.inf)
            near = np.argsort(distance, axis=1)[:, : min(3, len(front) - 1)]
            gap = distance.min(axis=1)
            weights = gap / gap.sum() if np.isfinite(gap).all() and gap.sum() > 0 else None
            self._near = (len(problem.archive), near, weights)
        return self._near[1], self._near[2]

    def neighbours(self, problem: PolicyProblem, count: int, rng) -> np.ndarray | None:
        """``count`` pairs of archive rows, neighbours on the archive's front: the first of
        each drawn with a weight of its distance to its nearest neighbour (isolated points
        border the front's gaps), the second one of its three nearest (objectives scaled
        to the front's range). None when the front has fewer than two points."""
        front = self.front(problem)
        if len(front) < 2 or count == 0:
            return None
        near, weights = self._nearest(problem)
        first = rng.choice(len(front), size=count, p=weights)
        second = near[first, rng.integers(0, near.shape[1], size=count)]
        return np.stack([front[first], front[second]], axis=1)

    def polish(self, problem: PolicyProblem, count: int, rng, known) -> list[np.ndarray]:
        """Up to ``count`` genes of one-step neighbours of the archive's front (the module's
        local search), none of them in the archive or repeated; fewer when no new neighbour
        turns up in ``tries`` draws of each."""
        front = self.front(problem)
        if len(front) == 0 or count == 0:
            return []
        weights = self._nearest(problem)[1] if len(front) >= 2 else None
        lows, highs = problem.genes.lows, problem.genes.highs
        members = front[rng.choice(len(front), size=count, p=weights)]
        policies, masks = problem.archive.rows(members)
        genes = problem.genes.encode(policies)
        children: list[np.ndarray] = []
        for parent, mask in zip(genes, masks):
            movable = np.flatnonzero(mask & (highs > lows))
            if len(movable) == 0:
                continue
            for _attempt in range(self.tries):
                child = parent.copy()
                j = movable[rng.integers(0, len(movable))]
                child[j] = _creep(child[j], lows[j], highs[j], rng)
                if not (known(child) or any((child == c).all() for c in children)):
                    children.append(child)
                    break
        return children

    def _do(self, problem, pop, n_offsprings, parents=None, random_state=None, **kwargs):
        rng = random_state
        archive = problem.archive
        n_matings = (n_offsprings + 1) // 2
        if parents is None:
            parents = self.selection.do(problem, pop, n_matings, 2, to_pop=False, random_state=rng, **kwargs)
        genes = np.rint(pop.get("X")).astype(np.int64)
        pairs = genes[np.asarray(parents, dtype=np.int64)]  # [matings, 2, decisions]
        if self.archive_rate > 0:
            chosen = rng.random(len(pairs)) < self.archive_rate
            neighbours = self.neighbours(problem, int(chosen.sum()), rng)
            if neighbours is not None:
                policies = archive.rows(neighbours.ravel())[0]
                pairs[chosen] = problem.genes.encode(policies).reshape(-1, 2, problem.n_var)
        lows, highs = problem.genes.lows, problem.genes.highs

        def known(child: np.ndarray) -> bool:
            return problem.genes.decode(child[None])[0] in archive

        local = rng.random(len(pairs)) < self.local_rate if self.local_rate > 0 else np.zeros(len(pairs), dtype=bool)
        children = self.polish(problem, 2 * int(local.sum()), rng, known)
        for first, second in pairs[~local]:
            masks = self._consulted(problem, np.stack([first, second]))
            for child in self._children(first, second, masks, lows, highs, rng, known):
                children.append(child)
        X = np.array(children[:n_offsprings], dtype=float).reshape(-1, problem.n_var)
        return Population.new(X=X)

    def _consulted(self, problem: PolicyProblem, parents: np.ndarray) -> np.ndarray:
        rows = problem.archive.lookup(problem.genes.decode(parents))
        masks = np.ones(parents.shape, dtype=bool)
        known = rows >= 0
        masks[known] = problem.archive.rows(rows[known])[1]
        return masks

    def _children(self, first, second, masks, lows, highs, rng, known):
        both = masks[0] | masks[1]
        genes = np.flatnonzero(both & (highs > lows))
        if len(genes) == 0:
            genes = np.flatnonzero(highs > lows)
        if len(genes) == 0:
            return [first.copy()]
        parents = (first, second)
        children = []
        for _ in range(2):
            child = first
            for _attempt in range(self.tries):
                if rng.random() < self.crossover_rate:
                    pick = rng.random(len(first)) < 0.5
                    child = np.where(pick, first, second)
                else:
                    child = parents[len(children)].copy()
                self._mutate(child, genes, lows, highs, rng)
                if not (
                    self._repeats(child, parents, masks) or any((child == c).all() for c in children) or known(child)
                ):
                    break
            children.append(child)
        return children

    def _mutate(self, child, genes, lows, highs, rng) -> None:
        count = 1
        while count < len(genes) and rng.random() < self.extra:
            count += 1
        for j in rng.choice(genes, size=count, replace=False):
            if rng.random() < self.creep:
                child[j] = _creep(child[j], lows[j], highs[j], rng)
            else:
                others = highs[j] - lows[j]
                value = lows[j] + rng.integers(0, others)
                child[j] = value if value < child[j] else value + 1

    @staticmethod
    def _repeats(child, parents, masks) -> bool:
        return any((child[m] == p[m]).all() for p, m in zip(parents, masks))


def _creep(value: int, low: int, high: int, rng) -> int:
    """One step up or down at random, the other way at the end of the range."""
    step = 1 if rng.random() < 0.5 else -1
    return value + step if low <= value + step <= high else value - step
