"""Branch and bound finds the whole Pareto front: as a set of values it equals the front of
exhaustive enumeration, on tiny families of the case studies and on hand-written models with
overlapping guards, synchronised decisions, per-policy deadlocks, ties and objectives of every
shape; and a bound it leaves when stopped early is sound."""

from __future__ import annotations

import itertools
import json

import attrs
import numpy as np
import pytest
from test_bound import MIXED, TO_BROKEN, _families, _flip, dpm, herman
from test_quotient import OBJECTIVES, breaking_system, synchronised_system
from typer.testing import CliRunner

from conftest import assert_points_are_not_ties
from parley_core import metrics
from parley_core.boxes import Box, box_rows, local_front
from parley_core.cli import app
from parley_core.evaluate.quotient import QuotientEvaluator
from parley_core.family.prepare import make_family
from parley_core.optimality.archive import Archive, region_points, robust_front
from parley_core.optimality.bound import refined_bound
from parley_core.optimality.branch_and_bound import branch_and_bound
from parley_core.optimality.records import Stopped
from parley_core.quotient.coloring import build_quotient
from parley_core.quotient.solver import QuotientSolver
from parley_core.testing import case_study, family


def narrow(name: str, assignments: list[str], width: int):
    return family(name, assignments, width=width)


def _solver(fam):
    quotient = build_quotient(fam)
    solver = QuotientSolver(quotient)
    return quotient, lambda rows: np.array([solver.solve(row) for row in rows], dtype=float)


def _front_set(values: np.ndarray, fam) -> np.ndarray:
    directions = [o.direction for o in fam.objectives]
    finite = ~np.isnan(values).any(axis=1)
    values = values[finite]
    return np.unique(np.round(values[metrics.nondominated(values, directions)], 9), axis=0)


def _assert_same_front(found: np.ndarray, values: np.ndarray, fam) -> None:
    """``found`` is the Pareto front of ``values`` up to ties within 1e-9, as branch and
    bound promises (:func:`parley_core.metrics.front_disagreements`)."""
    missed, foreign = metrics.front_disagreements(found, values, [o.direction for o in fam.objectives])
    assert not len(missed) and not len(foreign), (missed[:5], foreign[:5])
    assert len(found) or not len(values)


def _enumerate(fam, evaluate) -> tuple[np.ndarray, np.ndarray]:
    rows = np.array(list(itertools.product(*(d.service.values for d in fam.decisions))), dtype=np.int64)
    return rows, evaluate(rows)


def _pairs():
    breaking = breaking_system(OBJECTIVES)
    chosen = {o.name: o for o in breaking.objectives}
    # two objectives at a time, so that weighted sums of every combinable shape are exercised
    for first, second, maximize in [
        ("reach", "cumulative", {"reach"}),
        ("bounded", "cumulative", set()),
        ("bounded_until", "cumulative", {"cumulative"}),
        ("until", "total", set()),
        ("reward_reach", "reach", {"reach"}),
    ]:
        objectives = _flip([chosen[first], chosen[second]], maximize)
        yield f"breaking {first}+{second}", make_family(attrs.evolve(breaking, objectives=objectives))
    # minimised expected rewards that combine into one: to one target, and in total
    yield "breaking rewards to one target", make_family(breaking_system(TO_BROKEN))
    mixed = breaking_system(MIXED)
    yield (
        "breaking reward and bounded reach",
        make_family(attrs.evolve(mixed, objectives=_flip(mixed.objectives, {"soon"}))),
    )
    totals = {name: OBJECTIVES[name] for name in ("total", "total_finite")}
    yield "breaking total rewards", make_family(breaking_system(totals))


def _cases():
    yield "web_ids 3^6", narrow("web_ids", ["rounds=6"], 3)
    yield "tas 4^6", family("tas", ["rounds=6", "max_interval=3"])
    yield "robot_grid 3x3", narrow("robot_grid", ["size=3", "seed=2"], 3)
    for name, fam in _families():
        if name not in ("robot_grid 5x5", "web_ids", "tas"):
            yield name, fam
    yield from _pairs()
    yield (
        "synchronised, max load",
        family(synchronised_system(("full", "P=? [F<=4 b=3]", "max"), ("load", 'R{"b"}=? [C<=6]', "max"))),
    )


CASES = list(_cases())


@pytest.mark.slow
@pytest.mark.parametrize("name,fam", CASES, ids=[c[0] for c in CASES])
def test_branch_and_bound_equals_enumeration(name, fam):
    quotient, evaluate = _solver(fam)
    _, values = _enumerate(fam, evaluate)
    # ``whole`` (a node's widest decision kept whole) splits other decisions first
    for leaf, adaptive, whole in ((4, False, False), (32, False, False), (4, True, False), (4, False, True)):
        result = branch_and_bound(fam, quotient, evaluate, leaf=leaf, adaptive=adaptive, whole=whole)
        assert result.exact and result.stopped_by is Stopped.COMPLETE
        _assert_same_front(result.values, values, fam)
        # every policy returned has the value it claims
        np.testing.assert_allclose(evaluate(result.policies), result.values, rtol=1e-12, atol=1e-15)


@pytest.mark.parametrize("objectives", [2, 3])
def test_local_front_keeps_what_the_archive_would(objectives):
    """A box's own front keeps exactly the rows an archive fed the rows in order still holds
    at the end: ties (the first kept), infinitely bad values and NaN included."""
    rng = np.random.default_rng(objectives)
    for _ in range(200):
        values = rng.integers(0, 6, size=(40, objectives)).astype(float)
        values[rng.random(40) < 0.1, 0] = np.nan
        values[rng.random(40) < 0.1, 1] = -np.inf
        signs = np.where(rng.random(objectives) < 0.5, 1.0, -1.0)
        archive, admitted = Archive(objectives), []
        for i, value in enumerate(values):
            if archive.add(value * signs):
                admitted.append(i)
        alive = [i for i in admitted if (archive.points == np.maximum(values[i] * signs, -1e300)).all(axis=1).any()]
        assert local_front(values, signs).tolist() == alive


def test_box_rows_enumerate_like_itertools():
    domains = [np.array([1, 3, 5]), np.array([0, 2]), np.array([7, 8, 9, 10])]
    box = Box(np.array([1, 0, 1]), np.array([2, 1, 3]))
    expected = [
        [domains[0][a], domains[1][b], domains[2][c]]
        for a, b, c in itertools.product(range(1, 3), range(2), range(1, 4))
    ]
    assert box.size == 12 and box_rows(box, domains).tolist() == expected


@pytest.mark.slow
@pytest.mark.parametrize("workers", [1, 2])
def test_box_fronts_give_the_same_front(workers):
    """Whole boxes evaluated where they are solved, each cut to its own front, give branch
    and bound the same front as every row handed back (in one process and over workers)."""
    fam = narrow("tas", ["rounds=6"], 4)
    quotient, evaluate = _solver(fam)
    _, values = _enumerate(fam, evaluate)
    with QuotientEvaluator(fam, workers=workers, quotient=quotient) as engine:
        # solved as ``evaluate`` solves (tests/test_forward.py walks them): values from two
        # solvers that agree to rounding can differ in which of two tied policies is kept
        engine._walk = False
        result = branch_and_bound(fam, quotient, evaluate, leaf=64, adaptive=False, fronts=engine.submit_box_fronts)
    assert result.exact and 0 < result.evaluated <= len(values)
    _assert_same_front(result.values, values, fam)
    np.testing.assert_allclose(evaluate(result.policies), result.values, rtol=1e-12, atol=1e-15)


@pytest.mark.slow
def test_pruning_happens_and_seeds_count():
    fam = narrow("robot_grid", ["size=4", "seed=1"], 3)
    quotient, evaluate = _solver(fam)
    size = np.prod([len(d.service.values) for d in fam.decisions])
    cold = branch_and_bound(fam, quotient, evaluate, leaf=32, adaptive=False)
    assert cold.exact and cold.pruned > 0 and cold.evaluated < size / 100
    # with the front known in advance, no more policies need evaluating, and the front is the same
    seeded = branch_and_bound(fam, quotient, evaluate, seeds=(cold.policies, cold.values), leaf=32, adaptive=False)
    assert seeded.exact and seeded.evaluated <= cold.evaluated
    _assert_same_front(seeded.values, cold.values, fam)


@pytest.mark.parametrize("limit", [0.0, 0.5])
def test_stopped_early_the_bound_is_sound(limit):
    fam = narrow("web_ids", ["rounds=6"], 4)
    quotient, evaluate = _solver(fam)
    result = branch_and_bound(fam, quotient, evaluate, time_limit=limit, leaf=4, adaptive=False)
    assert not result.exact and result.open > 0
    bound = refined_bound(fam, result)
    _, values = _enumerate(fam, evaluate)
    assert bound.dominates(values).all()


@pytest.mark.slow
def test_stopped_early_on_a_model_we_did_not_write_the_bound_is_sound(foreign):
    # PAYNT's dpm with six decisions free (729 policies): the bound left after a second holds
    # the open sub-families' regions (ideal box and half-spaces, as a staircase); finished,
    # the front is enumeration's
    fam = dpm(foreign, free=6)
    quotient, evaluate = _solver(fam)
    result = branch_and_bound(fam, quotient, evaluate, time_limit=1.0, leaf=4, adaptive=False)
    assert not result.exact and result.open > 0
    bound = refined_bound(fam, result)
    _, values = _enumerate(fam, evaluate)
    assert bound.dominates(values).all()
    finished = branch_and_bound(fam, quotient, evaluate)
    assert finished.exact
    _assert_same_front(finished.values, values, fam)


@pytest.mark.slow
@pytest.mark.parametrize("biases", ["0..2", "22..24"])
def test_on_herman_the_front_is_enumerations(foreign, biases):
    # PAYNT's herman, four coin biases of three values and three bits (648 policies): steps to
    # stabilise (min) and stabilised within 30 steps (max), a reward and a bounded reach that
    # the bounds combine. With biases from 0 some policies never stabilise (infinite steps);
    # with the largest biases one policy is best in both (a front of one point), as in the
    # whole family
    fam = herman(foreign, biases)
    quotient, evaluate = _solver(fam)
    _, values = _enumerate(fam, evaluate)
    if biases == "0..2":
        assert np.isinf(values[:, 0]).any()
    result = branch_and_bound(fam, quotient, evaluate, leaf=4, adaptive=False)
    assert result.exact and result.evaluated < len(values)
    _assert_same_front(result.values, values, fam)


@pytest.mark.parametrize("after", [1, 5, 40, 200])
def test_ctrl_c_leaves_the_front_so_far_and_a_sound_bound(after):
    # Ctrl-C at the ``after``-th node settled (raised from the progress callback, between any
    # two steps of the search): the front so far, and a bound that still holds every policy
    fam = narrow("web_ids", ["rounds=6"], 3)
    quotient, evaluate = _solver(fam)
    _, values = _enumerate(fam, evaluate)
    calls = itertools.count(1)

    def progress(_fraction):
        if next(calls) == after:
            raise KeyboardInterrupt

    result = branch_and_bound(fam, quotient, evaluate, leaf=4, adaptive=False, progress=progress)
    assert result.stopped_by is Stopped.INTERRUPTED and not result.exact and result.open > 0
    if len(result.policies):
        np.testing.assert_allclose(evaluate(result.policies), result.values, rtol=1e-12, atol=1e-15)
    assert refined_bound(fam, result).dominates(values).all()


@pytest.mark.parametrize("lost", ["first", "second", "last"])
def test_ctrl_c_in_the_workers_puts_their_boxes_back_among_the_open(lost):
    # one batch of boxes fails as the workers' Ctrl-C does: its policies are not in the front,
    # so the nodes its boxes came from must be open again for the bound to hold them. The last
    # batch is solved when no node is left on the stack: only the reopened nodes cover it
    from parley_core.boxes import BoxValues, Ready

    fam = narrow("web_ids", ["rounds=6"], 3)
    quotient, evaluate = _solver(fam)
    _, values = _enumerate(fam, evaluate)
    domains = [np.array(d.service.values, dtype=np.int64) for d in fam.decisions]

    class Interrupted:
        def done(self):
            return True

        def result(self):
            raise KeyboardInterrupt

    def search(failing):
        batches = itertools.count(1)

        def fronts(boxes, signs):
            if next(batches) == failing:
                return Interrupted()
            rows = np.vstack([box_rows(b, domains) for b in boxes])
            return Ready(BoxValues(rows=rows, values=evaluate(rows), evaluated=len(rows), seconds=1e-3))

        result = branch_and_bound(fam, quotient, evaluate, leaf=16, adaptive=False, fronts=fronts)
        return result, next(batches) - 1

    _, total = search(failing=0)
    assert total >= 3
    result, _ = search(failing={"first": 1, "second": 2, "last": total}[lost])
    assert result.stopped_by is Stopped.INTERRUPTED and not result.exact and result.open > 0
    assert refined_bound(fam, result).dominates(values).all()


def test_an_open_nodes_staircase_covers_its_region_and_stays_in_its_box():
    rng = np.random.default_rng(4)
    ideal = np.array([-1.0, 2.0])
    cuts = ((np.array([1.0, 1.0]), 0.5), (np.array([0.2, 1.0]), 1.2))
    points = region_points(ideal, cuts)
    assert len(points) > 2 and (points <= ideal + 1e-12).all()
    sample = ideal - rng.uniform(0, 6, size=(4000, 2))
    inside = sample[np.all([sample @ w <= c for w, c in cuts], axis=0)]
    assert len(inside) > 100
    assert ((points[None, :, :] >= inside[:, None, :]).all(axis=2).any(axis=1)).all()
    # and it is tighter than the box: the box's corner is outside the region, and not covered
    assert not (points >= ideal - 1e-9).all(axis=1).any()


def test_archive_corners_are_exactly_the_undominated_region():
    rng = np.random.default_rng(3)
    archive = Archive(3)
    points = rng.integers(0, 6, size=(40, 3)).astype(float)
    for point in points:
        archive.add(point)
    probes = rng.integers(-1, 7, size=(2000, 3)).astype(float) + 0.5
    undominated = ~(points[None, :, :] >= probes[:, None, :]).all(axis=2).any(axis=1)
    in_orthant = (archive.corners[None, :, :] < probes[:, None, :]).all(axis=2).any(axis=1)
    assert (undominated == in_orthant).all()
    kept = archive.points
    assert not any((kept >= p).all(axis=1).sum() > 1 for p in kept)  # no duplicates, none dominated


@pytest.mark.slow
def test_parley_exact_writes_an_exact_run(tmp_path):
    out = tmp_path / "exact"
    result = CliRunner().invoke(
        app, ["exact", "tas", "--set", "rounds=4", "--set", "max_interval=2", "--out", str(out)]
    )
    assert result.exit_code == 0, result.output
    assert "exact: the front is the family's whole Pareto front" in result.output
    summary = json.loads((out / "summary.json").read_text())
    assert summary["optimality"]["exact"] is True
    # exact up to ties: a point better than another by less than the verification tolerance
    # (1e-9) in one objective and worse in another is the other's tie-dominated twin, and
    # its sliver of hypervolume is left out of the front
    assert 0.0 <= summary["optimality"]["gap"] <= 1e-6
    # Storm checked every candidate; its values decide the front (ties kept together)
    rows = len((out / "front.csv").read_text().splitlines()) - 1
    assert rows <= summary["verification"]["policies"] <= rows + 5
    fam = family("tas", ["rounds=4", "max_interval=2"])
    _, evaluate = _solver(fam)
    _, values = _enumerate(fam, evaluate)
    front = np.loadtxt(out / "front.csv", delimiter=",", skiprows=1, usecols=range(1, 1 + len(fam.objectives)))
    # the same front up to ties within 1e-9 (a point the enumeration keeps by a 1e-15 edge on
    # one objective may be dominated under Storm's last bits, and drop out)
    _assert_same_front(front, values, fam)
    # as many points as the enumeration's front has once ties are one point
    directions = [o.direction for o in fam.objectives]
    assert assert_points_are_not_ties(out) == len(metrics.distinct_front(values, directions))


def test_a_refined_run_bound_is_sound_and_no_looser_than_the_outer_one():
    from parley_core.family.prepare import Prepared
    from parley_core.pipeline import run
    from parley_core.search import SearchSettings

    fam = narrow("web_ids", ["rounds=6"], 4)
    case = case_study("web_ids")
    prepared = Prepared(case=case, options=case.options(["rounds=6"]), system=fam.system, family=fam)
    settings = SearchSettings(population=8, generations=2, seed=3)
    outer = run(prepared, settings, workers=1, verify=False, bound="pareto").bound
    refined = run(prepared, settings, workers=1, verify=False, bound="refine", bound_time=0.3).bound
    assert outer is not None and refined is not None
    _, evaluate = _solver(fam)
    _, values = _enumerate(fam, evaluate)
    assert refined.dominates(values).all() and outer.dominates(values).all()
    # the refined bound lies within the outer one
    assert outer.dominates(refined.points).all()


def test_ties_at_the_level_of_float_noise_are_not_two_front_values():
    # sign space (maximised): a probability 1 - 1.4e-14 at cost 5.5 beside 1 - 1.2e-14 at
    # cost 6.625 is one front value; 1e-6 better at cost 6.625 is two
    noise = np.array([[1 - 1.4e-14, -5.5], [1 - 1.2e-14, -6.625], [0.0, -4.0]])
    assert robust_front(noise).tolist() == [0, 2]
    real = np.array([[1 - 1e-6, -5.5], [1.0, -6.625], [0.0, -4.0]])
    assert robust_front(real).tolist() == [0, 1, 2]
    # equal values are both kept (the archive keeps the first of them before this)
    assert robust_front(np.array([[1.0, -2.0], [1.0, -2.0]])).tolist() == [0, 1]


def test_a_time_limit_is_kept_when_policies_are_slow(monkeypatch):
    # batches are cut to what the evaluator solves in BATCH_SECONDS once its speed is known,
    # so that a stopped search does not wait long for what is in flight (on PAYNT's dpm,
    # batches of 65,536 policies once kept it 20 minutes past its limit)
    import time

    from parley_core.optimality import branch_and_bound as exact

    monkeypatch.setattr(exact, "BATCH_SECONDS", 0.1)
    fam = narrow("web_ids", ["rounds=6"], 4)
    quotient, solve = _solver(fam)

    def slow(rows):
        time.sleep(0.002 * len(rows))
        return solve(rows)

    began = time.perf_counter()
    result = branch_and_bound(fam, quotient, slow, time_limit=0.5, leaf=64, adaptive=False)
    assert not result.exact and result.stopped_by is Stopped.TIME
    assert time.perf_counter() - began < 4.0  # a batch of 4,096 would take 8 s
