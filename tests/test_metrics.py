"""Metrics on fronts whose values are worked out by hand."""

from __future__ import annotations

import numpy as np
import pytest

from parley_core import metrics
from parley_core.model import Direction, Objective

MAX_MIN = [Direction.MAX, Direction.MIN]


def test_nondominated_respects_directions_and_keeps_one_of_equal_points():
    values = np.array([[0.9, 50], [0.8, 40], [0.8, 60], [0.9, 50], [0.7, 45]])
    assert metrics.nondominated(values, MAX_MIN).tolist() == [True, True, False, False, False]


def test_hypervolume_of_a_staircase():
    # success 0.8 at cost 50 and 0.7 at cost 40, reference (0, 100):
    # 0.7*60 (cost 40..100) plus the extra 0.1*50 that the first point adds.
    values = np.array([[0.8, 50.0], [0.7, 40.0]])
    assert metrics.hypervolume(values, MAX_MIN, [0.0, 100.0]) == pytest.approx(0.7 * 60 + 0.1 * 50)


def test_points_outside_the_reference_add_nothing():
    values = np.array([[0.8, 50.0], [0.9, 120.0]])
    assert metrics.hypervolume(values, MAX_MIN, [0.0, 100.0]) == pytest.approx(0.8 * 50)
    assert metrics.hypervolume(np.zeros((0, 2)), MAX_MIN, [0.0, 100.0]) == 0.0


def test_reference_point_uses_objective_references_or_worst_plus_a_tenth():
    objectives = [
        Objective(name="s", formula="P=? [F true]", direction="max", reference=0.0),
        Objective(name="c", formula='R{"c"}=? [C<=1]', direction="min"),
    ]
    ref = metrics.reference_point(objectives, np.array([[0.9, 10.0]]), np.array([[0.5, 30.0]]))
    assert ref.tolist() == pytest.approx([0.0, 32.0])


def test_spread_of_evenly_spaced_points_is_zero_and_grows_with_unevenness():
    even = np.array([[0.0, 1.0], [0.5, 0.5], [1.0, 0.0]])
    assert metrics.spread(even, [Direction.MIN, Direction.MIN]) == pytest.approx(0.0)
    uneven = np.array([[0.0, 1.0], [0.1, 0.9], [1.0, 0.0]])
    # gaps: 0.1*sqrt2 and 0.9*sqrt2, mean 0.5*sqrt2 -> (0.4+0.4)/(2*0.5) = 0.8
    assert metrics.spread(uneven, [Direction.MIN, Direction.MIN]) == pytest.approx(0.8)
    # extreme points 0.1 away (normalized) at both ends add d_f = d_l = 0.1
    extremes = np.array([[-0.1, 1.0], [1.1, 0.0]])
    expected = (0.1 + 0.1 + 0.8 * np.sqrt(2)) / (0.2 + 2 * 0.5 * np.sqrt(2))
    assert metrics.spread(
        uneven, [Direction.MIN, Direction.MIN], bounds=(np.array([0, 0]), np.array([1, 1])), extremes=extremes
    ) == pytest.approx(expected)
    assert metrics.spread(even[:1], [Direction.MIN, Direction.MIN]) == 1.0


def test_mean_gap_is_the_papers_spread():
    points = np.array([[0.0, 1.0], [0.5, 0.5], [1.0, 0.0]])
    assert metrics.mean_gap(points, [Direction.MIN, Direction.MIN]) == pytest.approx(np.sqrt(0.5))
    assert metrics.mean_gap(points[:1], [Direction.MIN, Direction.MIN]) == 1.5


def test_knee_is_closest_to_the_ideal_point():
    values = np.array([[0.6, 10.0], [0.85, 20.0], [0.9, 100.0]])
    assert metrics.knee(values, MAX_MIN) == 1


def test_front_disagreements_ignore_noise_ties_and_catch_real_differences():
    directions = [Direction.MIN, Direction.MAX]
    values = np.array(
        [[16.5, 1.0000000000000002], [63.7, 1.0000000000000036], [55.3, 1.0], [20.0, 0.5], [np.inf, 0.0], [1.0, np.nan]]
    )
    # the noise-level tie 63.7 may be kept or not; 55.3, 20.0 and inf are dominated
    for found in (values[[0, 1]], values[[0]], values[[1, 0]]):
        missed, foreign = metrics.front_disagreements(found, values, directions)
        assert not len(missed) and not len(foreign)
    missed, foreign = metrics.front_disagreements(values[[1]], values, directions)
    assert missed.tolist() == [[16.5, 1.0000000000000002], [55.3, 1.0], [20.0, 0.5]] and not len(foreign)
    missed, foreign = metrics.front_disagreements(values[[0, 2]], values, directions)
    assert not len(missed) and foreign.tolist() == [[55.3, 1.0]]
    # a real improvement beyond the tolerance is missed, even by a hair above it
    better = np.vstack([values, [16.5 * (1 - 1e-8), 1.0]])
    missed, _ = metrics.front_disagreements(values[[0]], better, directions)
    assert len(missed) == 1


def test_values_within_the_verification_tolerance_are_ties_on_the_front():
    # robot_grid's p001/p002 of the default run: 4e-13 apart in success, 2e-11 in cost
    values = np.array(
        [
            [0.6114549777711235, 19.548105901615955],
            [0.6114549777710948, 19.54810590161634],  # a tie of the first (it is exactly dominated)
            [0.6114549777711235 + 1e-13, 19.6],  # better success by noise only, worse cost: dominated
            [0.7, 25.0],
            [0.7 - 1e-8, 24.0],  # 1e-8 is beyond the tolerance: a real trade-off
            [np.nan, 1.0],
        ]
    )
    keep = metrics.tolerant_front(values, MAX_MIN)
    assert keep.tolist() == [True, True, False, True, True, False]
    assert metrics.nondominated(values[:5], MAX_MIN).tolist() == [True, False, True, True, True]  # exact: no ties
    assert metrics.tie_points(values[keep], MAX_MIN).tolist() == [1, 1, 2, 3]
    assert metrics.distinct_front(values, MAX_MIN).tolist() == [values[0].tolist(), [0.7, 25.0], values[4].tolist()]


def test_ties_chain_into_one_point_and_scale_with_the_value():
    step = 0.9e-9 * 1000  # within the tolerance of values near 1000, not of values near 1
    chained = np.array([[1000.0, 1.0], [1000.0 + step, 1.0], [1000.0 + 2 * step, 1.0]])
    assert metrics.tie_points(chained, [Direction.MIN, Direction.MIN]).tolist() == [1, 1, 1]
    small = np.array([[1.0, 1.0], [1.0 + step, 1.0]])
    assert metrics.tie_points(small, [Direction.MIN, Direction.MIN]).tolist() == [1, 2]


def test_a_front_plot_of_three_objectives_colours_the_third_and_says_what_is_left_out():
    from parley_core.views.frontplot import front_figure

    objectives = [
        Objective(name=n, formula="P=? [F x]", direction=d)
        for n, d in (
            ("success", Direction.MAX),
            ("cost", Direction.MIN),
            ("energy", Direction.MIN),
            ("risk", Direction.MIN),
        )
    ]
    front = np.array([[0.9, 10.0, 3.0, 0.1], [0.8, 5.0, 4.0, 0.2]])
    figure = front_figure(
        title="t", objectives=objectives, front=front, baseline=front[:1], baseline_names=["b"], selected=0,
        selected_name="p1", reference=[0.0, 20.0, 10.0, 1.0], bound=np.array([[1.0, 4.0, 2.0, 0.0]]),
    )  # fmt: skip
    texts = [t.get_text() for ax in figure.axes for t in ax.texts]
    assert any("not shown: risk" in t and "the ideal point only" in t for t in texts)
    assert [ax.get_ylabel() for ax in figure.axes][-1] == "energy (min)"  # the colour bar
