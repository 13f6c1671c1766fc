"""pymoo's view of a family: integer genes, a memoized vectorized problem, budget terminations."""

from __future__ import annotations

import numpy as np
from pymoo.core.problem import Problem
from pymoo.core.termination import Termination
from pymoo.termination.max_gen import MaximumGenerationTermination
from pymoo.termination.max_time import TimeBasedTermination

from parley_core.constraints import Constraint
from parley_core.evaluate.cache import CachingEvaluator
from parley_core.model import Family
from parley_core.search.settings import SearchSettings, Stop

UNEVALUATED = 1e300
"""The objective value pymoo sees for offspring left unevaluated when the budget ran out
(the search stops after that generation, and the front holds evaluated policies only)."""


class Genes:
    """pymoo's integer genes of a family: a decision's value itself where it takes a range
    (``1..10``), its position in its set of values where it takes a set (``{2,4}``)."""

    def __init__(self, family: Family) -> None:
        self.tables = [
            np.array(d.service.choices, dtype=np.int64) if d.service.choices else None for d in family.decisions
        ]
        self.sets = [j for j, table in enumerate(self.tables) if table is not None]
        self.lows = np.array([0 if t is not None else d.service.low for d, t in zip(family.decisions, self.tables)])
        self.highs = np.array(
            [len(t) - 1 if t is not None else d.service.high for d, t in zip(family.decisions, self.tables)]
        )

    def decode(self, genes: np.ndarray) -> np.ndarray:
        """Policies (decision values) of integer genes [n, decisions]."""
        values = np.array(genes, dtype=np.int64)
        for j in self.sets:
            table = self.tables[j]
            assert table is not None
            values[:, j] = table[values[:, j]]
        return values

    def encode(self, values: np.ndarray) -> np.ndarray:
        """Integer genes of policies [n, decisions]."""
        genes = np.array(values, dtype=np.int64)
        for j in self.sets:
            table = self.tables[j]
            assert table is not None
            genes[:, j] = np.searchsorted(table, genes[:, j])
        return genes


STALL = 25
"""Generations in a row without a new policy after which a search ends (:class:`Stalled`)."""


class EvaluationBudget(Termination):
    """Terminates once the archive holds ``budget`` policies."""

    def __init__(self, archive: CachingEvaluator, budget: int) -> None:
        super().__init__()
        self.archive = archive
        self.budget = budget

    def _update(self, algorithm) -> float:
        return len(self.archive) / self.budget


class Stalled(Termination):
    """Terminates once ``generations`` generations in a row evaluated no new policy: the
    mating keeps producing policies already evaluated (a family smaller than the budget, or
    a population that has converged), and without this a search limited only by evaluations
    would never end."""

    def __init__(self, archive: CachingEvaluator, generations: int = STALL) -> None:
        super().__init__()
        self.archive = archive
        self.generations = generations
        self.seen = -1
        self.idle = 0

    def _update(self, algorithm) -> float:
        if len(self.archive) == self.seen:
            self.idle += 1
        else:
            self.seen, self.idle = len(self.archive), 0
        return self.idle / self.generations


class PolicyProblem(Problem):
    """pymoo's view of a family: integer genes in each decision's range, objectives to minimize."""

    def __init__(
        self,
        family: Family,
        archive: CachingEvaluator,
        constraints: tuple[Constraint, ...] = (),
        budget: int | None = None,
    ) -> None:
        self.genes = Genes(family)
        super().__init__(
            n_var=len(family.decisions),
            n_obj=len(family.objectives),
            n_ieq_constr=len(constraints),
            xl=self.genes.lows.astype(float),
            xu=self.genes.highs.astype(float),
            vtype=int,
        )
        names = [o.name for o in family.objectives]
        self.constraints = [(c.column(names), c) for c in constraints]
        self.archive = archive
        self.signs = np.array([o.direction.sign for o in family.objectives])
        self.budget = budget

    def policies(self, x: np.ndarray) -> np.ndarray:
        """The policies of pymoo's (float) genes."""
        return self.genes.decode(np.rint(np.asarray(x, dtype=float)).astype(np.int64))

    def violations(self, values: np.ndarray) -> np.ndarray:
        """pymoo's inequality constraints (<= 0 is met) of values [n, objectives]."""
        if not self.constraints:
            return np.zeros((len(values), 0))
        return np.column_stack([c.violation(values[:, i]) for i, c in self.constraints])

    def _evaluate(self, x, out, *args, **kwargs) -> None:
        policies = self.policies(x)
        left = None if self.budget is None else max(0, self.budget - len(self.archive))
        values = self.archive.evaluate(policies, budget=left)
        unevaluated = np.isnan(values).all(axis=1) if left is not None else np.zeros(len(values), dtype=bool)
        # pymoo's crowding distance needs finite numbers: an infinite value is the worst (or
        # best) there is, so it becomes the largest (or smallest) number pymoo sees
        objectives = np.clip(values * self.signs, -UNEVALUATED, UNEVALUATED)
        out["F"] = np.where(unevaluated[:, None], UNEVALUATED, objectives)
        if self.constraints:
            violations = self.violations(values)
            out["G"] = np.where(unevaluated[:, None], UNEVALUATED, np.clip(violations, -UNEVALUATED, UNEVALUATED))


def termination(settings: SearchSettings, archive: CachingEvaluator) -> dict[Stop, Termination]:
    """The pymoo terminations of the settings' limits, by what they stop for."""
    criteria: dict[Stop, Termination] = {}
    if settings.generations is not None:
        criteria[Stop.GENERATIONS] = MaximumGenerationTermination(settings.generations)
    if settings.max_evaluations is not None:
        criteria[Stop.EVALUATIONS] = EvaluationBudget(archive, settings.max_evaluations)
    if settings.time_limit is not None:
        criteria[Stop.TIME] = TimeBasedTermination(settings.time_limit)
    criteria[Stop.STALLED] = Stalled(archive)
    return criteria
