"""Policy improvement on the relaxation (parley_core.quotient.improve) and the guided search's
walks (parley_core.search.guide): the policy's own values come out of the backward pass, a
score is the exact change of value where the performance-difference lemma is exact, and the
walks find policies the baselines do not dominate, within the budget."""

from __future__ import annotations

import attrs
import numpy as np
import pytest
from test_quotient import breaking_system, synchronised_system

from conftest import toy_system
from parley_core import metrics
from parley_core.evaluate.cache import CachingEvaluator
from parley_core.evaluate.quotient import QuotientEvaluator
from parley_core.model import Baseline, DecisionKind, Direction, Objective, Service
from parley_core.quotient.improve import PolicyImprover, improver_for
from parley_core.search import SearchSettings, Stop, search
from parley_core.search.guide import guided_start, weightings
from parley_core.testing import family as make_family

# Two stages, each observed once on every path (o = 0, then o = 1), each deciding with c how
# likely the goal becomes and at what cost; then o = 2 for good. A decision is consulted at
# most once on a path, so the performance-difference lemma is exact for a change of one.
TWO_STAGES = """dtmc
const int c;
module m
  o : [0..2] init 0;
  g : [0..1] init 0;
  [pay] o=0 & c=1 -> 0.5 : (o'=1) & (g'=1) + 0.5 : (o'=1);
  [pay] o=0 & c=2 -> 0.3 : (o'=1) & (g'=1) + 0.7 : (o'=1);
  [free] o=0 & c=3 -> 0.1 : (o'=1) & (g'=1) + 0.9 : (o'=1);
  [pay] o=1 & c=1 & g=0 -> 0.6 : (o'=2) & (g'=1) + 0.4 : (o'=2);
  [free] o=1 & (c>1 | g=1) -> 0.25 : (o'=2) & (g'=1) + 0.75 : (o'=2);
  [] o=2 -> true;
endmodule
rewards "cost"
  [pay] true : 3;
  o=1 : 1;
endrewards
"""


def two_stages():
    return toy_system(
        prism=TWO_STAGES,
        services=[Service(name="choose", constant="c", kind=DecisionKind.FREQUENCY, low=1, high=3)],
        observation=("o",),
        objectives=[
            Objective(name="goal", formula="P=? [F g=1]", direction=Direction.MAX),
            Objective(name="cost", formula='R{"cost"}=? [C<=4]', direction=Direction.MIN),
        ],
        baselines=[Baseline(name=f"always-{k}", values={"c": k}) for k in (1, 2, 3)],
    )


def _families():
    yield "robot_grid 5x5", make_family("robot_grid", ["size=5", "seed=1", "max_interval=4", "horizon=45"])
    yield "web_ids", make_family("web_ids", ["rounds=6"])
    yield "tas", make_family("tas", ["rounds=6", "max_interval=3"])
    yield "turtlebot", make_family("turtlebot", [])
    yield "two stages", make_family(two_stages(), prune=True)
    # overlapping enabled commands (mixed uniformly) and deadlocks, a bounded probability
    breaking = breaking_system({"bounded": "P=? [F<=6 broken]", "spent": 'R{"cost"}=? [C<=7]'})
    yield "breaking", make_family(breaking)
    reach = breaking_system({"reach": "P=? [F broken]", "once": 'R{"once"}=? [C<=5]'})
    yield "breaking, unbounded reach", make_family(reach)
    yield (
        "synchronised",
        make_family(synchronised_system(("full", "P=? [F b=3]", "max"), ("load", 'R{"b"}=? [C<=6]', "min"))),
    )


FAMILIES = list(_families())


def _indices(family, policies):
    return np.array([[list(d.service.values).index(int(v)) for d, v in zip(family.decisions, row)] for row in policies])


@pytest.mark.slow
@pytest.mark.parametrize("name, family", FAMILIES, ids=[name for name, _ in FAMILIES])
def test_the_backward_pass_gives_the_policys_own_values(name, family):
    with QuotientEvaluator(family, workers=1) as evaluator:
        improver = PolicyImprover(family, evaluator.quotient)
        assert improver.available, improver.unavailable
        policies = family.random(np.random.default_rng(4), 6)
        values = evaluator.evaluate(policies)
    for indices, value in zip(_indices(family, policies), values):
        _, own = improver.gradients(indices)
        # the unbounded reachability past the horizon is iterated to 1e-6: a guide, not a bound
        np.testing.assert_allclose(own * improver.signs, value, rtol=1e-9, atol=2e-6)


@pytest.mark.slow
@pytest.mark.parametrize("name, family", FAMILIES, ids=[name for name, _ in FAMILIES])
def test_scores_on_threads_are_those_computed_one_at_a_time(name, family):
    with QuotientEvaluator(family, workers=1) as evaluator:
        alone = PolicyImprover(family, evaluator.quotient)
        threaded = PolicyImprover(family, evaluator.quotient, threads=2)
    policies = _indices(family, family.random(np.random.default_rng(5), 5))
    together = threaded.gradients_of(list(policies))
    assert len(together) == len(policies)
    for indices, (score, own) in zip(policies, together):
        expected_score, expected_own = alone.gradients(indices)
        np.testing.assert_array_equal(score, expected_score)
        np.testing.assert_array_equal(own, expected_own)


def test_a_search_polishes_the_same_policies_whatever_the_evaluators_workers(monkeypatch):
    import parley_core.quotient.improve as improve

    threads = []

    def recording(family, quotient, threads_=1):
        improver = improver_for(family, quotient, threads_)
        threads.append(improver.threads)
        return improver

    monkeypatch.setattr(improve, "improver_for", recording)
    family = make_family("robot_grid", ["size=4", "seed=2", "max_interval=4", "horizon=40"])
    settings = SearchSettings(algorithm="polished", population=20, generations=None, max_evaluations=200, seed=3)
    archives = []
    for workers in (1, 2):
        with QuotientEvaluator(family, workers=workers) as evaluator:
            result = search(family, evaluator, settings)
        assert result.polished is not None and result.polished.evaluations > 0
        archives.append((result.policies.tolist(), result.values.tolist()))
    assert threads == [1, 2]  # the scores ran on as many threads as the evaluator has workers
    assert archives[0] == archives[1]


def test_a_score_is_the_exact_change_where_a_decision_is_consulted_once():
    family = make_family(two_stages(), prune=True)  # o=2 consults nothing
    assert [d.valuation for d in family.decisions] == [(0,), (1,)]
    with QuotientEvaluator(family, workers=1) as evaluator:
        improver = PolicyImprover(family, evaluator.quotient)
        policies = np.array([[a, b] for a in (1, 2, 3) for b in (1, 2, 3)])
        values = {tuple(row): v * improver.signs for row, v in zip(policies.tolist(), evaluator.evaluate(policies))}
    checked = 0
    for row in policies.tolist():
        score, own = improver.gradients(_indices(family, [row])[0])
        np.testing.assert_allclose(own, values[tuple(row)], rtol=1e-12, atol=1e-12)
        for d in range(len(row)):
            for k, value in enumerate(family.decisions[d].service.values):
                changed = list(row)
                changed[d] = value
                predicted = score[:, d, k] - score[:, d, row[d] - 1]
                np.testing.assert_allclose(predicted, values[tuple(changed)] - values[tuple(row)], atol=1e-12)
                checked += predicted.any()
    assert checked > 5  # the changes are not all zero


def test_improve_moves_each_decision_to_its_best_weighted_score():
    gradients = np.zeros((2, 2, 3))
    gradients[0, 0] = [0.0, 1.0, 2.0]  # decision 0: the first objective prefers its last value
    gradients[1, 0] = [0.0, 0.0, -5.0]  # the second objective dislikes it
    gradients[:, 1] = [[1.0, 1.0, -np.inf], [0.0, 0.0, -np.inf]]  # decision 1: a tie and a value it cannot take
    assert PolicyImprover.improve(np.array([0, 0]), gradients, np.array([1.0, 0.0])).tolist() == [2, 0]
    assert PolicyImprover.improve(np.array([0, 0]), gradients, np.array([1.0, 1.0])).tolist() == [1, 0]


def test_no_improvement_where_the_objectives_do_not_combine():
    family = make_family(breaking_system({"reach": "P=? [F broken]", "until": "P=? [h=1 U broken]"}))
    with QuotientEvaluator(family, workers=1) as evaluator:
        improver = PolicyImprover(family, evaluator.quotient)
        assert not improver.available and "weighted sum" in improver.unavailable
        archive = CachingEvaluator(evaluator, len(family.decisions), len(family.objectives))
        walked = guided_start(family, archive, improver_for(family, evaluator.quotient), budget=50)
        assert walked.skipped == improver.unavailable and not len(walked.policies)
        result = search(family, evaluator, SearchSettings(algorithm="guided", population=8, generations=2))
    assert result.walked is not None and result.walked.skipped
    assert result.evaluations > 0


def test_the_walks_find_policies_the_baselines_do_not_dominate_within_the_budget():
    family = make_family("robot_grid", ["size=5", "seed=1", "horizon=45"])
    directions = [o.direction for o in family.objectives]
    with QuotientEvaluator(family, workers=1) as evaluator:
        baselines = np.array([p.values for p in family.baseline_policies()])
        base = evaluator.evaluate(baselines)
        archive = CachingEvaluator(evaluator, len(family.decisions), len(family.objectives))
        walked = guided_start(family, archive, improver_for(family, evaluator.quotient), budget=40)
        assert 0 < len(walked.policies) <= 10  # a quarter of the budget
        assert len(archive) <= len(baselines) + 10
        found = archive.values[archive.lookup(walked.policies)]
        result = search(
            family, evaluator, SearchSettings(algorithm="guided", max_evaluations=120, generations=None, seed=3)
        )
    front = metrics.nondominated(np.vstack([base, found]), directions)
    assert front[len(base) :].any()  # some walked policy is on the front of baselines and walks
    assert result.evaluations <= 120
    assert result.walked is not None and len(result.walked.policies)
    assert set(map(tuple, result.walked.policies.tolist())) <= set(map(tuple, result.policies.tolist()))


def test_weightings_spread_over_the_directions_and_scale_by_the_values():
    values = np.array([[0.0, -100.0], [1.0, -10.0]])
    weights = weightings(values, 4)
    assert weights.shape == (4, 2) and (weights > 0).all()
    # scaled by the spread (1 and 90): the middle directions weigh a unit of the second 1/90 as much
    middle = weights[1] * np.array([1.0, 90.0])
    assert middle[0] == pytest.approx(np.cos(2 * np.pi / 10)) and middle[1] == pytest.approx(np.sin(2 * np.pi / 10))
    three = weightings(np.array([[1.0, 2.0, 3.0]]), 6)
    assert three.shape == (6, 3) and (three > 0).all()


def test_unbounded_probabilities_keep_their_value_past_the_horizon():
    # success is decided long after the cost's horizon: only the terminal value carries it
    system = attrs.evolve(
        two_stages(),
        objectives=[
            Objective(name="goal", formula="P=? [F g=1]", direction=Direction.MAX),
            Objective(name="cost", formula='R{"cost"}=? [C<=1]', direction=Direction.MIN),
        ],
    )
    family = make_family(system, prune=True)
    with QuotientEvaluator(family, workers=1) as evaluator:
        improver = PolicyImprover(family, evaluator.quotient)
        policy = np.array([[3, 1]])
        value = evaluator.evaluate(policy)[0]
    _, own = improver.gradients(_indices(family, policy)[0])
    np.testing.assert_allclose(own * improver.signs, value, atol=2e-6)


def test_the_walks_take_no_step_past_the_searchs_time_limit():
    family = make_family("robot_grid", ["size=5", "seed=1", "horizon=45"])
    with QuotientEvaluator(family, workers=1) as evaluator:
        archive = CachingEvaluator(evaluator, len(family.decisions), len(family.objectives))
        walked = guided_start(family, archive, improver_for(family, evaluator.quotient), budget=None, seconds=0.0)
        assert not len(walked.policies) and not walked.skipped
        assert len(archive) == len(family.baseline_policies())  # the baselines only
        result = search(family, evaluator, SearchSettings(algorithm="guided", generations=None, time_limit=0.5))
    assert result.stopped_by is Stop.TIME and result.walked is not None
