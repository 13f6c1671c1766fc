"""Walking whole boxes forward on the quotient (:mod:`parley_core.quotient.forward`) gives
every policy's step-bounded rewards as solving it alone does: on the case studies and on
hand-written models with per-policy deadlocks, overlapping guards, synchronised decisions
and two step bounds; a policy walked alone and in a block of others gives the same bits;
and branch and bound over walked boxes finds the enumerated front."""

from __future__ import annotations

import numpy as np
import pytest
from test_exact import _assert_same_front, _solver
from test_quotient import breaking_system, synchronised_system

from parley_core.boxes import Box, box_rows
from parley_core.evaluate.quotient import QuotientEvaluator, _domain_table
from parley_core.optimality.branch_and_bound import branch_and_bound
from parley_core.quotient.coloring import build_quotient
from parley_core.quotient.forward import BoxWalker
from parley_core.quotient.solver import QuotientSolver
from parley_core.testing import family


def _cumulative_families():
    yield "web_ids 3^6", family("web_ids", ["rounds=6"], width=3)
    yield "tas 3^6", family("tas", ["rounds=6", "max_interval=2"])
    # deadlocks that depend on the policy, two reward structures, two step bounds
    yield (
        "breaking",
        family(breaking_system({"cumulative": 'R{"cost"}=? [C<=17]', "once": 'R{"once"}=? [C<=9]'})),
    )
    # choices that consult two decisions at once (no lookup), a reward of the state
    yield (
        "synchronised",
        family(synchronised_system(("load", 'R{"b"}=? [C<=6]', "max"))),
    )


FAMILIES = list(_cumulative_families())


def _walk(fam, box: Box):
    quotient = build_quotient(fam)
    walker = BoxWalker.of(quotient)
    assert walker is not None
    domains = [np.array(d.service.values, dtype=np.int64) for d in fam.decisions]
    return quotient, walker, domains, walker.solve(box, *_domain_table(domains))


def _whole(fam) -> Box:
    sizes = np.array([len(d.service.values) for d in fam.decisions], dtype=np.int64)
    return Box(np.zeros(len(sizes), dtype=np.int64), sizes - 1)


def _count_walks(engine: QuotientEvaluator) -> list[int]:
    """The sizes of the boxes the engine's walker walks from now on (in this process)."""
    walker = engine._walker
    assert walker is not None
    sizes: list[int] = []
    solve = walker.solve

    def counted(box, *table):
        sizes.append(box.size)
        return solve(box, *table)

    walker.solve = counted  # type: ignore[method-assign]
    return sizes


@pytest.mark.parametrize("name,fam", FAMILIES, ids=[f[0] for f in FAMILIES])
def test_a_walked_box_has_every_policy_with_its_solved_values(name, fam):
    box = _whole(fam)
    quotient, _, domains, (rows, values) = _walk(fam, box)
    assert sorted(map(tuple, rows)) == sorted(map(tuple, box_rows(box, domains)))
    solver = QuotientSolver(quotient)
    solved = np.array([solver.solve(row) for row in rows], dtype=float)
    np.testing.assert_allclose(values, solved, rtol=1e-12, atol=1e-14)
    assert len(np.unique(np.round(values, 9), axis=0)) > 1  # the policies do differ


@pytest.mark.parametrize("name,fam", FAMILIES, ids=[f[0] for f in FAMILIES])
def test_a_policy_alone_and_in_a_block_gives_the_same_bits(name, fam):
    box = _whole(fam)
    _, walker, domains, (rows, values) = _walk(fam, box)
    table = _domain_table(domains)
    for row, value in zip(rows, values):
        index = np.array([list(d.service.values).index(v) for d, v in zip(fam.decisions, row)], dtype=np.int64)
        _, alone = walker.solve(Box(index, index), *table)
        np.testing.assert_array_equal(alone[0], value)


def test_only_step_bounded_rewards_are_walked():
    assert BoxWalker.of(build_quotient(family("robot_grid", ["size=3", "seed=2"]))) is None
    assert (
        BoxWalker.of(build_quotient(family(breaking_system({"c": 'R{"cost"}=? [C<=5]', "r": "P=? [F broken]"}))))
        is None
    )


@pytest.mark.slow
@pytest.mark.parametrize(
    ("workers", "whole", "votes"),
    [(1, False, False), (2, False, False), (1, True, False), (2, True, False), (2, False, True)],
)
def test_branch_and_bound_over_walked_boxes_finds_the_enumerated_front(workers, whole, votes):
    fam = family("tas", ["rounds=6"], width=4)
    quotient, evaluate = _solver(fam)
    # the reference walks every policy too: a front of solved values can differ from one of
    # walked values in which of two policies tied to rounding it keeps
    _, _, _, (_, values) = _walk(fam, _whole(fam))
    with QuotientEvaluator(fam, workers=workers, quotient=quotient) as engine:
        engine._walk = True  # as if the walk had been timed faster
        walked = _count_walks(engine)
        boxes = []

        def fronts(batch, signs):
            boxes.extend(batch)
            return engine.submit_box_fronts(batch, signs)

        result = branch_and_bound(
            fam, quotient, evaluate, leaf=64, adaptive=False, fronts=fronts, whole=whole, sums_vote=votes
        )
        assert engine.describe()["boxes_walked"] is True
        if workers == 1:  # in this process: every box went through the walker
            assert walked and sum(walked) == result.evaluated
    assert result.exact and 0 < result.evaluated <= len(values)
    _assert_same_front(result.values, values, fam)
    np.testing.assert_allclose(evaluate(result.policies), result.values, rtol=1e-12, atol=1e-15)
    if votes:  # split where the weighted sums' schedulers disagree: the leaves' shapes follow them
        return
    # split by width: with ``whole`` the leaves keep a decision's whole range (4 values here)
    # for the walk's blocks; bisection alone leaves them balanced (64 policies: widths of 2)
    widest = [int((box.hi - box.lo + 1).max()) for box in boxes]
    assert (min(widest) == 4) if whole else (max(widest) <= 2)


def test_seeds_get_the_values_of_walked_boxes():
    fam = family("web_ids", ["rounds=6"], width=3)
    quotient, evaluate = _solver(fam)
    rows = np.array([[d.service.values[i % len(d.service.values)] for d in fam.decisions] for i in range(5)])
    with QuotientEvaluator(fam, workers=1, quotient=quotient) as engine:
        solved = engine.evaluate(rows)
        engine._walk = False  # as if solving had been timed faster: the seeds stay as they are
        assert engine.box_seeds(rows, solved)[1] is solved
        engine._walk = True
        walked = _count_walks(engine)
        seeded_rows, seeded = engine.box_seeds(rows, solved)
        assert sum(walked) == len(rows)  # each seed walked
    _, walker, domains, _ = _walk(fam, Box(np.zeros(6, dtype=np.int64), np.zeros(6, dtype=np.int64)))
    table = _domain_table(domains)
    for row, value in zip(seeded_rows, seeded):
        index = np.array([list(d.service.values).index(v) for d, v in zip(fam.decisions, row)], dtype=np.int64)
        np.testing.assert_array_equal(walker.solve(Box(index, index), *table)[1][0], value)
    np.testing.assert_allclose(seeded, solved, rtol=1e-12, atol=1e-14)
