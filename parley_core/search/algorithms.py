"""The search configurations by name (``--algorithm NAME``).

Each is a pymoo algorithm over the genes of :class:`~parley_core.search.problem.Genes`, its
first population the baselines and random policies (:func:`~parley_core.search.run.initial_population`):

- ``paper``: the paper's NSGA-II, SBX (eta 3) and polynomial mutation (eta 3) on floats
  rounded to integers; kept so that the reproduction stays reproducible;
- ``ordinal``: NSGA-II with :class:`~parley_core.search.operators.OrdinalMating` (uniform
  crossover, creep/reset mutation of consulted decisions, no repeated DTMCs);
- ``archive``: ``ordinal`` whose parents come from the archive's front half of the time;
- ``sms``: SMS-EMOA (hypervolume-contribution survival, 10 children a generation) with the
  same mating as ``archive``;
- ``blend``: ``archive`` whose first population's random half is blends of two baselines;
- ``local``: ``archive`` whose matings make, half of the time, one-step neighbours of the
  archive's front instead (Pareto local search, :meth:`OrdinalMating.polish`);
- ``small``: ``archive`` with half the population (50 for the paper's 100) after the first
  generation, so twice the generations for the same evaluations;
- ``guided``: ``paper`` whose first population holds, after the baselines, the policies
  found by walks of policy improvement on the quotient's relaxation
  (:mod:`parley_core.search.guide`), evaluated as part of the budget;
- ``guided-small``: ``small`` started by the same walks, whose policies reach it through the
  archive's front only;
- ``polished``: ``guided`` for 30 % of the budget, then the rest spent on one-decision changes
  of the archive's front, ranked by the hypervolume the relaxation's scores predict they add
  (:mod:`parley_core.search.polish`).

benchmarks/search.py measures them against each other.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
from attrs import frozen
from pymoo.algorithms.moo.nsga2 import NSGA2
from pymoo.algorithms.moo.sms import SMSEMOA, cv_and_dom_tournament
from pymoo.core.algorithm import Algorithm
from pymoo.operators.crossover.sbx import SBX
from pymoo.operators.mutation.pm import PM
from pymoo.operators.repair.rounding import RoundingRepair

from parley_core.errors import OptionError
from parley_core.search.operators import OrdinalMating


@frozen
class Configuration:
    """A named search: ``build(population, sampling)`` gives the pymoo algorithm; ``blend``
    is the share of blended baselines in the first population (:func:`~parley_core.search.run.initial_population`)."""

    name: str
    summary: str
    build: Callable[[int, np.ndarray], Algorithm]
    blend: float = 0.0
    guided: str = ""
    """Whether the search first walks by policy improvement (:func:`~parley_core.search.guide.guided_start`),
    and where the walks' policies go: ``"population"`` (the first one) or ``"archive"`` (only there)."""
    polish: float = 0.0
    """The share of the evaluation budget (or of the time limit) left to polishing the front by
    predicted hypervolume (:func:`~parley_core.search.polish.polish`) after the pymoo search."""


def _paper(population: int, sampling: np.ndarray) -> Algorithm:
    return NSGA2(
        pop_size=population,
        sampling=sampling,
        crossover=SBX(prob=0.9, eta=3.0, vtype=float, repair=RoundingRepair()),
        mutation=PM(prob=1.0, eta=3.0, vtype=float, repair=RoundingRepair()),
        eliminate_duplicates=True,
    )


def _ordinal(population: int, sampling: np.ndarray) -> Algorithm:
    return NSGA2(pop_size=population, sampling=sampling, mating=OrdinalMating(), eliminate_duplicates=True)


def _archive(population: int, sampling: np.ndarray) -> Algorithm:
    return NSGA2(
        pop_size=population, sampling=sampling, mating=OrdinalMating(archive_rate=0.5), eliminate_duplicates=True
    )


def _local(population: int, sampling: np.ndarray) -> Algorithm:
    return NSGA2(
        pop_size=population,
        sampling=sampling,
        mating=OrdinalMating(archive_rate=0.5, local_rate=0.5),
        eliminate_duplicates=True,
    )


def _small(population: int, sampling: np.ndarray) -> Algorithm:
    return NSGA2(
        pop_size=max(2, population // 2),
        sampling=sampling,
        mating=OrdinalMating(archive_rate=0.5),
        eliminate_duplicates=True,
    )


def _sms(population: int, sampling: np.ndarray) -> Algorithm:
    return SMSEMOA(
        pop_size=population,
        sampling=sampling,
        n_offsprings=10,
        mating=OrdinalMating(archive_rate=0.5, tournament=cv_and_dom_tournament),
        eliminate_duplicates=True,
    )


ALGORITHMS: dict[str, Configuration] = {
    c.name: c
    for c in (
        Configuration("paper", "NSGA-II, SBX and polynomial mutation on rounded integers (the paper's)", _paper),
        Configuration("ordinal", "NSGA-II, uniform crossover, creep/reset of consulted decisions", _ordinal),
        Configuration("archive", "ordinal, half the parents from the archive's front", _archive),
        Configuration("sms", "SMS-EMOA with the archive's mating, 10 children a generation", _sms),
        Configuration("blend", "archive, half the first population blends of two baselines", _archive, blend=0.5),
        Configuration("local", "archive, half the matings one-step neighbours of the front (local search)", _local),
        Configuration("small", "archive with a population of 50 (twice the generations)", _small),
        Configuration(
            "guided",
            "paper, its first population from policy improvement on the relaxation",
            _paper,
            guided="population",
        ),
        Configuration(
            "guided-small", "small, started by policy improvement on the relaxation", _small, guided="archive"
        ),
        Configuration(
            "polished",
            "guided for 30% of the budget, then one-decision changes of the front ranked by predicted hypervolume",
            _paper,
            guided="population",
            polish=0.7,
        ),
    )
}
"""Every search configuration, by name."""


def configuration(name: str) -> Configuration:
    """The configuration called ``name``; an :class:`~parley_core.errors.OptionError` names the valid ones."""
    try:
        return ALGORITHMS[name]
    except KeyError:
        raise OptionError(f"unknown search algorithm {name!r}; valid: {', '.join(ALGORITHMS)}") from None
