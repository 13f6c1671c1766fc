"""The search configurations: the paper's unchanged, every one deterministic by seed, and the
facts the ordinal operators rely on (a decision no reachable state consults changes nothing)."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from parley_core.evaluate.cache import CachingEvaluator
from parley_core.evaluate.quotient import QuotientEvaluator
from parley_core.evaluate.storm import StormEvaluator
from parley_core.search import ALGORITHMS, SearchSettings, Stop, search
from parley_core.search.operators import OrdinalMating
from parley_core.testing import family as make_family

FIXTURE = Path(__file__).parent / "data" / "search_paper_23ccbee.json"
"""Archives of two small searches made with commit 23ccbee, before there were configurations
(tests/data/README.md says how it was made)."""


@pytest.fixture(scope="module")
def web_ids():
    family = make_family("web_ids", [])
    with QuotientEvaluator(family, workers=1) as evaluator:
        yield family, evaluator


class Rounded:
    """The quotient's values rounded to 1e-7, as the fixture was recorded: NSGA-II's ties
    then no longer hang on the last bits, which differ between machines (tests/data/README.md)."""

    def __init__(self, inner) -> None:
        self.inner = inner
        self.name = inner.name
        self.workers = 1

    def evaluate(self, policies, progress=None):
        return np.round(self.inner.evaluate(policies, progress=progress), 7)

    def describe(self) -> dict[str, object]:
        return {}

    def close(self, abort: bool = False) -> None:
        self.inner.close(abort)


@pytest.mark.parametrize("key", ["web_ids", "robot_grid 4x4"])
def test_the_paper_configuration_searches_as_before(key):
    recorded = json.loads(FIXTURE.read_text())[key]
    family = make_family(key.split()[0], recorded["options"])
    with QuotientEvaluator(family, workers=1) as evaluator:
        settings = SearchSettings(
            algorithm="paper",
            population=recorded["population"],
            generations=recorded["generations"],
            seed=recorded["seed"],
        )
        result = search(family, Rounded(evaluator), settings)
    assert result.policies.tolist() == recorded["policies"]
    np.testing.assert_allclose(result.values, np.array(recorded["values"]), rtol=1e-12, atol=0)


@pytest.mark.parametrize("algorithm", sorted(ALGORITHMS))
def test_every_configuration_is_deterministic_by_seed(web_ids, algorithm):
    family, evaluator = web_ids
    # ten generations: ``polished`` leaves 70 % of them to polishing, and its first stage must
    # get past a first population that the baselines and the walks fill without a random draw
    runs = [
        search(family, evaluator, SearchSettings(algorithm=algorithm, population=12, generations=10, seed=seed))
        for seed in (5, 5, 6)
    ]
    assert runs[0].policies.tolist() == runs[1].policies.tolist()
    assert np.array_equal(runs[0].values, runs[1].values, equal_nan=True)
    assert runs[0].policies.tolist() != runs[2].policies.tolist()  # the seed is used


@pytest.mark.parametrize("algorithm", sorted(ALGORITHMS))
@pytest.mark.parametrize("budget", [1, 37])
def test_every_configuration_meets_an_evaluation_budget_exactly(small_robot, algorithm, budget):
    family, evaluator = small_robot
    settings = SearchSettings(algorithm=algorithm, population=10, generations=None, max_evaluations=budget, seed=2)
    result = search(family, evaluator, settings)
    assert result.stopped_by is Stop.EVALUATIONS
    assert result.evaluations == len({row.tobytes() for row in result.policies}) == budget


def test_a_decision_no_reachable_state_consults_changes_no_value(small_robot):
    """The quotient's consulted decisions: changing any of the others gives the same DTMC,
    so the same values (bit for bit on the quotient, and Storm's values agree)."""
    family, evaluator = small_robot
    rng = np.random.default_rng(4)
    lows, highs = np.array(family.lows), np.array(family.highs)
    policies = family.random(rng, 12)
    values, consulted = evaluator.evaluate_consulted(policies)
    assert (~consulted).any() and consulted.any(axis=1).all()
    changed = policies.copy()
    for row, mask in zip(changed, consulted):
        free = np.flatnonzero(~mask)
        row[free] = rng.integers(lows[free], highs[free] + 1)
    changed_values, changed_consulted = evaluator.evaluate_consulted(changed)
    assert np.array_equal(values, changed_values)
    assert np.array_equal(consulted, changed_consulted)
    with StormEvaluator(family, workers=1) as storm:
        np.testing.assert_allclose(storm.evaluate(changed[:4]), values[:4], rtol=1e-9)


def test_most_consulted_decisions_change_a_value(small_robot):
    """The mask is not everything: of a policy's consulted decisions, most change a value
    when set to another (a consulted decision can still be one no value depends on)."""
    family, evaluator = small_robot
    lows, highs = np.array(family.lows), np.array(family.highs)
    policy = family.random(np.random.default_rng(9), 1)
    values, consulted = evaluator.evaluate_consulted(policy)
    moved = 0
    for j in np.flatnonzero(consulted[0]):
        others = [v for v in range(lows[j], highs[j] + 1) if v != policy[0, j]]
        variants = np.repeat(policy, len(others), axis=0)
        variants[:, j] = others
        moved += bool((evaluator.evaluate(variants) != values).any())
    assert moved >= consulted[0].sum() // 2


def test_ordinal_children_stay_in_range_and_are_new_dtmcs(small_robot):
    family, evaluator = small_robot
    archive = CachingEvaluator(evaluator, len(family.decisions), len(family.objectives))
    settings = SearchSettings(algorithm="ordinal", population=10, generations=1, seed=3)
    search(family, evaluator, settings, archive=archive)
    from parley_core.search.problem import PolicyProblem

    problem = PolicyProblem(family, archive)
    mating = OrdinalMating()
    rng = np.random.default_rng(1)
    rows = rng.choice(len(archive), size=(30, 2))
    policies, masks = archive.rows(rows.ravel())
    genes = problem.genes.encode(policies).reshape(-1, 2, problem.n_var)
    masks = masks.reshape(-1, 2, problem.n_var)
    lows, highs = problem.genes.lows, problem.genes.highs
    for (first, second), mask in zip(genes, masks):
        children = mating._children(first, second, mask, lows, highs, rng, lambda child: False)
        assert len(children) == 2
        for child in children:
            assert ((child >= lows) & (child <= highs)).all()
            assert not any((child[m] == p[m]).all() for p, m in zip((first, second), mask))


def test_local_search_children_are_new_one_step_neighbours_of_the_front(small_robot):
    family, evaluator = small_robot
    archive = CachingEvaluator(evaluator, len(family.decisions), len(family.objectives))
    search(
        family, evaluator, SearchSettings(algorithm="archive", population=20, generations=3, seed=2), archive=archive
    )
    from parley_core.search.problem import PolicyProblem

    problem = PolicyProblem(family, archive)
    mating = OrdinalMating(local_rate=1.0)
    front = mating.front(problem)
    policies, masks = archive.rows(front)
    members = problem.genes.encode(policies)

    def known(child):
        return problem.genes.decode(child[None])[0] in archive

    children = mating.polish(problem, 40, np.random.default_rng(4), known)
    assert len(children) >= 30  # a few draws may find no new neighbour
    assert len({c.tobytes() for c in children}) == len(children)
    for child in children:
        assert not known(child)
        differences = np.abs(members - child)
        # one front member differs from the child in exactly one decision, by one step,
        # and that member's reachable states consult that decision
        near = np.flatnonzero((differences.sum(axis=1) == 1) & (differences.max(axis=1) == 1))
        assert any(masks[i][np.flatnonzero(differences[i])[0]] for i in near)


@pytest.mark.slow
@pytest.mark.parametrize("algorithm", sorted(ALGORITHMS))
def test_every_configuration_ends_on_a_family_smaller_than_its_budget(algorithm):
    """Nine policies and a budget of 50: the search evaluates each once and stops (it used
    to loop for ever, the mating producing only policies already evaluated)."""
    from test_improve import two_stages

    family = make_family(two_stages(), prune=True)
    settings = SearchSettings(algorithm=algorithm, population=4, generations=None, max_evaluations=50, seed=1)
    with QuotientEvaluator(family, workers=1) as evaluator:
        result = search(family, evaluator, settings)
    assert result.evaluations <= 9
    assert result.stopped_by in (Stop.STALLED, Stop.EXHAUSTED)
