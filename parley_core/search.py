"""Pareto search: pymoo NSGA-II over the integer decisions of a family.

The problem is vectorized (the evaluator sees a whole population at once) and memoized: a
:class:`~parley_core.evaluate.cache.CachingEvaluator` keeps every policy evaluated with its
values, so no policy is evaluated twice and the final front is taken from everything seen,
not only from the last population. The initial population holds the baseline policies, so
the front can never be worse than the baseline. One seed fixes the run.

The search ends by pymoo :class:`~pymoo.core.termination.Termination` objects, whichever
comes first: a number of generations, of evaluated policies (exactly: the generation that
reaches the budget evaluates only what is left of it), or of seconds.
"""

from __future__ import annotations

import enum
import time

import attrs
import numpy as np
from attrs import field, frozen, validators
from pymoo.algorithms.moo.nsga2 import NSGA2
from pymoo.core.problem import Problem
from pymoo.core.termination import TerminateIfAny, Termination
from pymoo.operators.crossover.sbx import SBX
from pymoo.operators.mutation.pm import PM
from pymoo.operators.repair.rounding import RoundingRepair
from pymoo.termination.max_gen import MaximumGenerationTermination
from pymoo.termination.max_time import TimeBasedTermination

from parley_core.constraints import Constraint
from parley_core.evaluate import Evaluator
from parley_core.evaluate.cache import CachingEvaluator
from parley_core.model import Family
from parley_core.progress import Progress

UNEVALUATED = 1e300
"""The objective value pymoo sees for offspring left unevaluated when the budget ran out
(the search stops after that generation, and the front holds evaluated policies only)."""


def _positive_or_none(_instance, attribute: attrs.Attribute, value) -> None:
    if value is not None and value <= 0:
        raise ValueError(f"{attribute.name} must be positive or None, got {value}")


@frozen(kw_only=True)
class SearchSettings:
    """Budget and seed of a search; the defaults are the paper's budget (100 x 40).

    The search stops at whichever limit comes first: ``generations`` (None: no limit),
    ``max_evaluations`` (new policies, the baselines included) or ``time_limit`` (seconds of
    search). ``constraints`` make NSGA-II prefer policies that meet them (pymoo's constraint
    handling).
    """

    population: int = field(default=100, validator=validators.ge(2))
    generations: int | None = field(default=40, validator=_positive_or_none)
    max_evaluations: int | None = field(default=None, validator=_positive_or_none)
    time_limit: float | None = field(default=None, validator=_positive_or_none)
    seed: int = 1
    constraints: tuple[Constraint, ...] = field(default=(), converter=tuple[Constraint, ...])

    def __attrs_post_init__(self) -> None:
        if self.generations is None and self.max_evaluations is None and self.time_limit is None:
            raise ValueError("a search needs a limit: generations, max_evaluations or time_limit")


def default(name: str):
    """The default of a :class:`SearchSettings` field (the CLI's defaults come from here)."""
    return attrs.fields_dict(SearchSettings)[name].default


class Stop(enum.Enum):
    """Why a search ended."""

    GENERATIONS = "generations"
    EVALUATIONS = "evaluations"
    TIME = "time"
    INTERRUPTED = "interrupted"


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


class EvaluationBudget(Termination):
    """Terminates once the archive holds ``budget`` policies."""

    def __init__(self, archive: CachingEvaluator, budget: int) -> None:
        super().__init__()
        self.archive = archive
        self.budget = budget

    def _update(self, algorithm) -> float:
        return len(self.archive) / self.budget


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

    def _evaluate(self, x, out, *args, **kwargs) -> None:
        policies = self.genes.decode(np.rint(np.asarray(x, dtype=float)).astype(np.int64))
        left = None if self.budget is None else max(0, self.budget - len(self.archive))
        values = self.archive.evaluate(policies, budget=left)
        unevaluated = np.isnan(values).all(axis=1) if left is not None else np.zeros(len(values), dtype=bool)
        # pymoo's crowding distance needs finite numbers: an infinite value is the worst (or
        # best) there is, so it becomes the largest (or smallest) number pymoo sees
        objectives = np.clip(values * self.signs, -UNEVALUATED, UNEVALUATED)
        out["F"] = np.where(unevaluated[:, None], UNEVALUATED, objectives)
        if self.constraints:
            violations = np.column_stack([c.violation(values[:, i]) for i, c in self.constraints])
            out["G"] = np.where(unevaluated[:, None], UNEVALUATED, np.clip(violations, -UNEVALUATED, UNEVALUATED))


@frozen(kw_only=True)
class SearchResult:
    policies: np.ndarray = field(eq=False)
    values: np.ndarray = field(eq=False)
    evaluations: int
    generations: int
    seconds: float
    stopped_by: Stop

    @property
    def interrupted(self) -> bool:
        return self.stopped_by is Stop.INTERRUPTED


def initial_population(family: Family, settings: SearchSettings) -> np.ndarray:
    """The baselines, then uniformly random policies (from the seed) up to the population
    size, as genes (:class:`Genes`)."""
    rng = np.random.default_rng(settings.seed)
    genes = Genes(family)
    baselines = genes.encode(
        np.array([p.values for p in family.baseline_policies()], dtype=np.int64).reshape(-1, len(genes.lows))
    )
    lows, highs = genes.lows, genes.highs
    n_random = max(0, settings.population - len(baselines))
    random_rows = rng.integers(lows, highs + 1, size=(n_random, len(lows)))
    rows = np.vstack([baselines, random_rows])
    return rows.astype(float)


def termination(settings: SearchSettings, archive: CachingEvaluator) -> dict[Stop, Termination]:
    """The pymoo terminations of the settings' limits, by what they stop for."""
    criteria: dict[Stop, Termination] = {}
    if settings.generations is not None:
        criteria[Stop.GENERATIONS] = MaximumGenerationTermination(settings.generations)
    if settings.max_evaluations is not None:
        criteria[Stop.EVALUATIONS] = EvaluationBudget(archive, settings.max_evaluations)
    if settings.time_limit is not None:
        criteria[Stop.TIME] = TimeBasedTermination(settings.time_limit)
    return criteria


def search(
    family: Family,
    evaluator: Evaluator,
    settings: SearchSettings,
    *,
    archive: CachingEvaluator | None = None,
    progress: Progress | None = None,
) -> SearchResult:
    """Run NSGA-II; Ctrl-C stops it and returns what was evaluated so far (``interrupted``).

    ``archive`` may hold policies evaluated before (by the same evaluator); they are not
    evaluated again, count towards ``max_evaluations`` and belong to the result.
    ``progress`` is called once per generation.
    """
    archive = (
        archive if archive is not None else CachingEvaluator(evaluator, len(family.decisions), len(family.objectives))
    )
    problem = PolicyProblem(family, archive, constraints=settings.constraints, budget=settings.max_evaluations)
    algorithm = NSGA2(
        pop_size=settings.population,
        sampling=initial_population(family, settings),
        crossover=SBX(prob=0.9, eta=3.0, vtype=float, repair=RoundingRepair()),
        mutation=PM(prob=1.0, eta=3.0, vtype=float, repair=RoundingRepair()),
        eliminate_duplicates=True,
    )
    criteria = termination(settings, archive)
    algorithm.setup(problem, termination=TerminateIfAny(*criteria.values()), seed=settings.seed, verbose=False)
    start = time.perf_counter()
    generation = 0
    stopped_by = None
    try:
        while algorithm.has_next():
            algorithm.next()
            generation += 1
            if progress:
                progress(1)
    except KeyboardInterrupt:
        stopped_by = Stop.INTERRUPTED
    if stopped_by is None:
        stopped_by = next((stop for stop, c in criteria.items() if c.has_terminated()), Stop.GENERATIONS)
    return SearchResult(
        policies=archive.policies,
        values=archive.values,
        evaluations=len(archive),
        generations=generation,
        seconds=time.perf_counter() - start,
        stopped_by=stopped_by,
    )
