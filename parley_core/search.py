"""Pareto search: pymoo NSGA-II over the integer decisions of a family.

The problem is vectorised (the evaluator sees a whole population at once) and memoised: an
:class:`Archive` keeps every policy evaluated with its values, so no policy is evaluated
twice and the final front is taken from everything seen, not only from the last population.
The initial population holds the baseline policies, so the front can never be worse than the
baseline. One seed fixes the run.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence

import numpy as np
from attrs import field, frozen, validators
from pymoo.algorithms.moo.nsga2 import NSGA2
from pymoo.core.problem import Problem
from pymoo.operators.crossover.sbx import SBX
from pymoo.operators.mutation.pm import PM
from pymoo.operators.repair.rounding import RoundingRepair

from parley_core.errors import OptionError
from parley_core.evaluate import Evaluator
from parley_core.model import Family


@frozen(kw_only=True)
class Constraint:
    """A requirement on one objective: ``success>=0.8``, ``cost<=60``."""

    objective: str
    operator: str = field(validator=validators.in_((">=", "<=")))
    bound: float

    @classmethod
    def parse(cls, text: str) -> Constraint:
        for operator in (">=", "<="):
            name, sep, bound = text.partition(operator)
            if sep:
                try:
                    return cls(objective=name.strip(), operator=operator, bound=float(bound))
                except ValueError:
                    break
        raise OptionError(f"malformed constraint {text!r}; write OBJECTIVE>=BOUND or OBJECTIVE<=BOUND, e.g. success>=0.8")

    def column(self, names: Sequence[str]) -> int:
        """The position of the constrained objective among ``names``; an unknown one is an error."""
        if self.objective not in names:
            raise OptionError(f"constraint {self}: no objective {self.objective!r}; objectives: {', '.join(names)}")
        return list(names).index(self.objective)

    def violation(self, values: np.ndarray) -> np.ndarray:
        """How far values are from meeting the constraint (<= 0: met), as pymoo wants it."""
        return self.bound - values if self.operator == ">=" else values - self.bound

    def __str__(self) -> str:
        return f"{self.objective}{self.operator}{self.bound:g}"


def meets(values: np.ndarray, names: Sequence[str], constraints: Sequence[Constraint]) -> np.ndarray:
    """Which rows of ``values`` (one column per objective in ``names``) meet every constraint."""
    ok = np.ones(len(values), dtype=bool)
    for constraint in constraints:
        ok &= constraint.violation(values[:, constraint.column(names)]) <= 0
    return ok


@frozen(kw_only=True)
class SearchSettings:
    """Budget and seed of a search. ``max_evaluations`` (new policies) stops it early if set;
    ``constraints`` make NSGA-II prefer policies that meet them (pymoo's constraint handling)."""

    population: int = field(default=100, validator=validators.ge(2))
    generations: int = field(default=40, validator=validators.ge(1))
    seed: int = 1
    max_evaluations: int | None = None
    constraints: tuple[Constraint, ...] = field(default=(), converter=tuple)


@frozen(kw_only=True)
class SearchProgress:
    generation: int
    generations: int
    evaluations: int


class Archive:
    """Every policy evaluated so far, in order, with its values; evaluates only what is new."""

    def __init__(self, evaluator: Evaluator, n_decisions: int, n_objectives: int) -> None:
        self.evaluator = evaluator
        self._index: dict[bytes, int] = {}
        self._policies: list[np.ndarray] = []
        self._values: list[np.ndarray] = []
        self.n_decisions = n_decisions
        self.n_objectives = n_objectives

    def __len__(self) -> int:
        return len(self._policies)

    @property
    def policies(self) -> np.ndarray:
        return np.array(self._policies, dtype=np.int64).reshape(-1, self.n_decisions)

    @property
    def values(self) -> np.ndarray:
        return np.array(self._values, dtype=float).reshape(-1, self.n_objectives)

    def evaluate(self, policies: np.ndarray, progress: Callable[[int], None] | None = None) -> np.ndarray:
        policies = np.asarray(policies, dtype=np.int64).reshape(-1, self.n_decisions)
        keys = [row.tobytes() for row in policies]
        new: dict[bytes, np.ndarray] = {}
        for key, row in zip(keys, policies):
            if key not in self._index and key not in new:
                new[key] = row
        if new:
            rows = np.array(list(new.values()))
            values = self.evaluator.evaluate(rows, progress=progress)
            for key, row, value in zip(new, rows, values):
                self._index[key] = len(self._policies)
                self._policies.append(row.copy())
                self._values.append(np.asarray(value, dtype=float))
        return np.array([self._values[self._index[k]] for k in keys])


class PolicyProblem(Problem):
    """pymoo's view of a family: integer genes in each decision's range, objectives to minimise."""

    def __init__(
        self,
        family: Family,
        archive: Archive,
        progress: Callable[[int], None] | None = None,
        constraints: tuple[Constraint, ...] = (),
    ) -> None:
        super().__init__(
            n_var=len(family.decisions),
            n_obj=len(family.objectives),
            n_ieq_constr=len(constraints),
            xl=np.array(family.lows, dtype=float),
            xu=np.array(family.highs, dtype=float),
            vtype=int,
        )
        names = [o.name for o in family.objectives]
        self.constraints = [(c.column(names), c) for c in constraints]
        self.archive = archive
        self.signs = np.array([o.direction.sign for o in family.objectives])
        self.progress = progress

    def _evaluate(self, x, out, *args, **kwargs) -> None:
        policies = np.rint(np.asarray(x, dtype=float)).astype(np.int64)
        values = self.archive.evaluate(policies, progress=self.progress)
        out["F"] = values * self.signs
        if self.constraints:
            out["G"] = np.column_stack([c.violation(values[:, i]) for i, c in self.constraints])


@frozen(kw_only=True)
class SearchResult:
    policies: np.ndarray = field(eq=False)
    values: np.ndarray = field(eq=False)
    evaluations: int
    generations: int
    seconds: float
    interrupted: bool


def initial_population(family: Family, settings: SearchSettings) -> np.ndarray:
    """The baselines, then uniformly random policies (from the seed) up to the population size."""
    rng = np.random.default_rng(settings.seed)
    baselines = [p.values for p in family.baseline_policies()]
    lows, highs = np.array(family.lows), np.array(family.highs)
    n_random = max(0, settings.population - len(baselines))
    random_rows = rng.integers(lows, highs + 1, size=(n_random, len(lows)))
    rows = np.vstack([np.array(baselines, dtype=np.int64).reshape(-1, len(lows)), random_rows])
    return rows.astype(float)


def search(
    family: Family,
    evaluator: Evaluator,
    settings: SearchSettings,
    *,
    archive: Archive | None = None,
    on_generation: Callable[[SearchProgress], None] | None = None,
    on_evaluation: Callable[[int], None] | None = None,
) -> SearchResult:
    """Run NSGA-II; Ctrl-C stops it and returns what was evaluated so far (``interrupted``).

    ``archive`` may hold policies evaluated before (by the same evaluator); they are not
    evaluated again and belong to the result.
    """
    archive = archive if archive is not None else Archive(evaluator, len(family.decisions), len(family.objectives))
    problem = PolicyProblem(family, archive, progress=on_evaluation, constraints=settings.constraints)
    algorithm = NSGA2(
        pop_size=settings.population,
        sampling=initial_population(family, settings),
        crossover=SBX(prob=0.9, eta=3.0, vtype=float, repair=RoundingRepair()),
        mutation=PM(prob=1.0, eta=3.0, vtype=float, repair=RoundingRepair()),
        eliminate_duplicates=True,
    )
    algorithm.setup(problem, termination=("n_gen", settings.generations), seed=settings.seed, verbose=False)
    start = time.perf_counter()
    generation = 0
    interrupted = False
    try:
        while algorithm.has_next():
            algorithm.next()
            generation += 1
            if on_generation:
                on_generation(SearchProgress(generation=generation, generations=settings.generations, evaluations=len(archive)))
            if settings.max_evaluations is not None and len(archive) >= settings.max_evaluations:
                break
    except KeyboardInterrupt:
        interrupted = True
    return SearchResult(
        policies=archive.policies,
        values=archive.values,
        evaluations=len(archive),
        generations=generation,
        seconds=time.perf_counter() - start,
        interrupted=interrupted,
    )
