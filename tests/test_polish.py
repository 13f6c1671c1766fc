"""Polishing the front by predicted hypervolume (parley_core.search.polish): the ranking's
hypervolume arithmetic, what a polished search spends its budget on, and where it does not
polish (no quotient, constraints, a family it has exhausted)."""

from __future__ import annotations

import numpy as np
import pytest
from test_improve import two_stages

from parley_core import metrics
from parley_core.constraints import Constraint
from parley_core.evaluate.cache import CachingEvaluator
from parley_core.evaluate.quotient import QuotientEvaluator
from parley_core.model import Direction
from parley_core.quotient.improve import improver_for
from parley_core.search import SearchSettings, Stop, search
from parley_core.search.polish import contributions, dominated, polish, shortfall
from parley_core.testing import family as make_family

MAX2 = [Direction.MAX, Direction.MAX]


class NoQuotient:
    """An evaluator that cannot say how to improve a policy (as Storm's cannot)."""

    def __init__(self, inner) -> None:
        self.inner = inner
        self.name = inner.name
        self.workers = 1

    def evaluate(self, policies, progress=None):
        return self.inner.evaluate(policies, progress=progress)

    def describe(self) -> dict[str, object]:
        return {}

    def close(self, abort: bool = False) -> None:
        pass


def test_contributions_are_the_hypervolume_each_point_would_add():
    rng = np.random.default_rng(11)
    for trial in range(60):
        points = rng.random((25, 2))
        front = points[metrics.nondominated(points, MAX2)]
        reference = np.array([-0.1, -0.2]) if trial % 2 else np.array([0.3, 0.2])  # some candidates below it
        candidates = rng.random((15, 2)) * 1.3 - 0.15
        alone = metrics.hypervolume(front, MAX2, reference)
        expected = [metrics.hypervolume(np.vstack([front, c]), MAX2, reference) - alone for c in candidates]
        np.testing.assert_allclose(contributions(front, candidates, reference), expected, atol=1e-12)


def test_dominated_and_shortfall_measure_against_the_staircase():
    front = np.array([[0.0, 4.0], [1.0, 3.0], [3.0, 1.0]])
    points = np.array([[0.5, 3.0], [2.0, 2.0], [3.0, 1.0], [4.0, 0.0], [2.0, 0.5]])
    assert dominated(front, points).tolist() == [True, False, True, False, True]
    # (2, 0.5) lies 0.5 below the step at x in (1, 3] (height 1), a sixth of the front's spread of 3 in y
    # and 1 to the left of (3, 1), a third of its spread of 3 in x: the smaller share counts
    np.testing.assert_allclose(shortfall(front, points[[2, 4]]), [0.0, 0.5 / 3])


def test_a_polished_search_spends_the_rest_of_its_budget_on_neighbours_of_the_front(small_robot):
    family, evaluator = small_robot
    settings = SearchSettings(algorithm="polished", population=20, generations=None, max_evaluations=200, seed=4)
    result = search(family, evaluator, settings)
    assert result.evaluations == 200 and result.stopped_by is Stop.EVALUATIONS
    polished = result.polished
    assert polished is not None and not polished.skipped and polished.expanded > 0
    assert polished.evaluations == 200 - 60  # the first stage gets 30 %
    for i in range(60, 200):  # every polished policy is one decision away from a policy evaluated before it
        changed = (result.policies[:i] != result.policies[i]).sum(axis=1)
        assert changed.min() == 1, i


def test_polishing_evaluates_first_the_neighbour_that_adds_the_most_hypervolume():
    """On the two-stage model a score is the exact change of value (each decision is consulted
    at most once on a path), so the first neighbour polishing evaluates must be the one whose
    true values add the most hypervolume to the front of the baselines."""
    family = make_family(two_stages(), prune=True)
    with QuotientEvaluator(family, workers=1) as evaluator:
        archive = CachingEvaluator(evaluator, len(family.decisions), len(family.objectives))
        archive.evaluate(np.array([p.values for p in family.baseline_policies()], dtype=np.int64))
        improver = improver_for(family, evaluator.quotient)
        signs = improver.signs
        values = archive.values * signs
        front = values[metrics.nondominated(archive.values, [o.direction for o in family.objectives])]
        reference = values.min(axis=0) - 1e-9 * np.maximum(1.0, np.abs(values.min(axis=0)))
        domains = [list(d.service.values) for d in family.decisions]
        neighbours = {
            tuple(parent[:d]) + (v,) + tuple(parent[d + 1 :])
            for parent in archive.policies
            for d, domain in enumerate(domains)
            for v in domain
        } - set(map(tuple, archive.policies.tolist()))
        neighbours = np.array(sorted(neighbours), dtype=np.int64)
        gains = contributions(front, evaluator.evaluate(neighbours) * signs, reference)
        assert gains.max() > 0  # some neighbour improves the front
        before = len(archive)
        polish(family, archive, improver, before + 1, seed=0, batch=1, expand=len(front))
        first = archive.policies[before]
    best = neighbours[np.isclose(gains, gains.max(), rtol=1e-9, atol=1e-12)]
    assert any(np.array_equal(first, b) for b in best)


def test_polishing_finds_a_better_front_than_the_guided_search_with_the_same_budget(small_robot):
    family, evaluator = small_robot
    directions = [o.direction for o in family.objectives]
    fronts = {}
    for algorithm in ("guided", "polished"):
        settings = SearchSettings(algorithm=algorithm, generations=None, max_evaluations=400, seed=1)
        fronts[algorithm] = search(family, evaluator, settings).values
    union = np.vstack(list(fronts.values()))
    baseline = evaluator.evaluate(np.array([p.values for p in family.baseline_policies()]))
    reference = metrics.reference_point(family.objectives, union[metrics.nondominated(union, directions)], baseline)
    volume = {k: metrics.hypervolume(v, directions, reference) for k, v in fronts.items()}
    assert volume["polished"] > volume["guided"]


def test_without_a_quotient_nothing_is_polished_and_the_first_stage_gets_the_whole_budget(small_robot):
    family, evaluator = small_robot
    settings = SearchSettings(algorithm="polished", population=10, generations=None, max_evaluations=60, seed=2)
    result = search(family, NoQuotient(evaluator), settings)
    assert result.polished is not None and result.polished.skipped == "the evaluator has no quotient"
    assert result.evaluations == 60 and result.stopped_by is Stop.EVALUATIONS


def test_a_search_with_constraints_is_not_polished(small_robot):
    family, evaluator = small_robot
    constraint = Constraint.parse("success>=0.5")
    settings = SearchSettings(
        algorithm="polished", population=10, generations=None, max_evaluations=60, seed=2, constraints=(constraint,)
    )
    result = search(family, evaluator, settings)
    assert result.polished is not None and "constraints" in result.polished.skipped
    assert result.evaluations == 60


def test_polishing_stops_when_the_fronts_neighbours_are_all_evaluated():
    family = make_family(two_stages(), prune=True)
    size = int(np.prod([len(d.service.values) for d in family.decisions]))
    with QuotientEvaluator(family, workers=1) as evaluator:
        settings = SearchSettings(algorithm="polished", population=4, generations=None, max_evaluations=200, seed=1)
        result = search(family, evaluator, settings)
    assert result.stopped_by is Stop.EXHAUSTED and result.evaluations <= size
    assert result.polished is not None and result.polished.expanded > 0


@pytest.mark.slow
def test_polishing_keeps_to_the_searchs_time_limit(small_robot):
    family, evaluator = small_robot
    result = search(family, evaluator, SearchSettings(algorithm="polished", generations=None, time_limit=1.0, seed=3))
    assert result.stopped_by is Stop.TIME and result.polished is not None and result.polished.evaluations > 0
    assert result.seconds < 2.0
