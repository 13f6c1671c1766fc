"""The search's limits: pymoo terminations by generations, exact evaluation budgets and time."""

from __future__ import annotations

import pytest

from parley_core.evaluate.cache import CachingEvaluator
from parley_core.search import SearchSettings, Stop, search


def test_generations_stop_the_search(small_robot):
    family, evaluator = small_robot
    result = search(family, evaluator, SearchSettings(population=10, generations=3, seed=2))
    assert result.stopped_by is Stop.GENERATIONS and result.generations == 3
    assert result.evaluations <= 30


@pytest.mark.parametrize("budget", [1, 7, 37, 64])
def test_an_evaluation_budget_is_met_exactly(small_robot, budget):
    family, evaluator = small_robot
    result = search(family, evaluator, SearchSettings(population=10, generations=None, max_evaluations=budget, seed=2))
    assert result.stopped_by is Stop.EVALUATIONS
    assert result.evaluations == len(result.policies) == budget
    assert len({row.tobytes() for row in result.policies}) == budget


def test_the_budget_counts_what_the_archive_held_before(small_robot):
    family, evaluator = small_robot
    archive = CachingEvaluator(evaluator, len(family.decisions), len(family.objectives))
    archive.evaluate([p.values for p in family.baseline_policies()])
    result = search(family, evaluator, SearchSettings(population=10, max_evaluations=25, seed=2), archive=archive)
    assert result.evaluations == 25 and len(archive) == 25


def test_a_time_limit_stops_an_unbounded_search(small_robot):
    family, evaluator = small_robot
    result = search(family, evaluator, SearchSettings(population=10, generations=None, time_limit=0.3, seed=2))
    assert result.stopped_by is Stop.TIME
    assert result.seconds >= 0.3


def test_the_same_seed_gives_the_same_policies_under_any_limit(small_robot):
    family, evaluator = small_robot
    by_generations = search(family, evaluator, SearchSettings(population=10, generations=4, seed=5))
    by_budget = search(
        family,
        evaluator,
        SearchSettings(population=10, generations=None, max_evaluations=by_generations.evaluations, seed=5),
    )
    assert (by_generations.policies == by_budget.policies).all()


def test_a_search_needs_a_limit():
    with pytest.raises(ValueError, match="needs a limit"):
        SearchSettings(generations=None)
    with pytest.raises(ValueError, match="positive"):
        SearchSettings(max_evaluations=0)
