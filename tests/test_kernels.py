"""The quotient evaluator's numba kernels against plain numpy on random DTMCs with the
shapes that their shortcuts rely on: absorbing states with and without reward, states
that cannot reach the target, self-loops, states unreachable in few steps."""

from __future__ import annotations

from collections import deque

import numpy as np
import pytest

from parley_core.quotient import kernels


def random_dtmc(seed: int, n: int = 60, single: float = 0.0):
    """A random DTMC in breadth-first order from state 0: (indptr, cols, vals, levels).
    About a ``single`` share of the states have one successor (chains, also cycles)."""
    rng = np.random.default_rng(seed)
    rows = []
    for s in range(n):
        kind = rng.random()
        if kind < 0.15:
            rows.append({s: 1.0})  # absorbing
        elif kind < 0.15 + single:
            rows.append({int(rng.integers(n)): 1.0})
        else:
            successors = rng.choice(n, size=rng.integers(1, 4), replace=False)
            weights = rng.random(len(successors)) + 0.1
            rows.append(dict(zip(successors.tolist(), (weights / weights.sum()).tolist())))
    # breadth-first renumbering from state 0, dropping what it cannot reach
    order, level = [0], {0: 0}
    queue = deque([0])
    while queue:
        s = queue.popleft()
        for t in rows[s]:
            if t not in level:
                level[t] = level[s] + 1
                order.append(t)
                queue.append(t)
    local = {s: i for i, s in enumerate(order)}
    indptr, cols, vals = [0], [], []
    for s in order:
        for t, p in rows[s].items():
            cols.append(local[t])
            vals.append(p)
        indptr.append(len(cols))
    levels = np.array([level[s] for s in order], dtype=np.int64)
    return np.array(indptr, dtype=np.int64), np.array(cols, dtype=np.int64), np.array(vals), levels


def dense(indptr, cols, vals):
    count = len(indptr) - 1
    matrix = np.zeros((count, count))
    for s in range(count):
        for e in range(indptr[s], indptr[s + 1]):
            matrix[s, cols[e]] += vals[e]
    return matrix


def reaches(matrix, target, through):
    """Plain fixpoint: states that reach ``target`` through ``through`` states."""
    can = target.copy()
    while True:
        more = can | (through & ((matrix > 0) @ can))
        if (more == can).all():
            return can
        can = more


@pytest.mark.parametrize("seed", range(40))
def test_cumulative_is_the_backward_recurrence(seed):
    indptr, cols, vals, levels = random_dtmc(seed)
    count = len(levels)
    rng = np.random.default_rng(1000 + seed)
    # about half the states earn nothing, so that absorbing states with and without reward
    # (dropped with their mass, or earning at every step) both occur
    reward = np.where(rng.random(count) < 0.5, 0.0, rng.random(count) * 3)
    matrix = dense(indptr, cols, vals)
    for steps in (0, 1, 2, 7, 40):
        x = np.zeros(count)
        for _ in range(steps):
            x = reward + matrix @ x
        # alone and together with a second reward structure (one pass serves both)
        (alone,) = kernels.cumulative(count, indptr, cols, vals, steps, reward[None], levels)
        assert alone == pytest.approx(x[0], rel=1e-12, abs=1e-12)
        both = kernels.cumulative(count, indptr, cols, vals, steps, np.stack([reward, 1 - reward / 3]), levels)
        assert both[0] == alone
        y = np.zeros(count)
        for _ in range(steps):
            y = (1 - reward / 3) + matrix @ y
        assert both[1] == pytest.approx(y[0], rel=1e-12, abs=1e-12)


def test_cumulative_keeps_earning_in_an_absorbing_state_with_a_reward():
    # 0 -> 1 (absorbing, reward 2) or 2 (absorbing, no reward), one half each
    indptr = np.array([0, 2, 3, 4])
    cols = np.array([1, 2, 1, 2])
    vals = np.array([0.5, 0.5, 1.0, 1.0])
    reward = np.array([1.0, 2.0, 0.0])
    levels = np.array([0, 1, 1])
    # 1 at step 0, then 0.5 * 2 at each of the 9 later steps
    assert kernels.cumulative(3, indptr, cols, vals, 10, reward[None], levels)[0] == pytest.approx(1 + 9 * 0.5 * 2)


@pytest.mark.parametrize("seed", range(40))
def test_cannot_reach_is_sound_and_leaves_the_solution_unchanged(seed):
    indptr, cols, vals, levels = random_dtmc(seed)
    count = len(levels)
    rng = np.random.default_rng(2000 + seed)
    right = rng.random(count) < 0.1
    left = rng.random(count) < 0.85
    matrix = dense(indptr, cols, vals)
    truly_unable = ~reaches(matrix, right, left)
    found = kernels.cannot_reach(count, indptr, cols, right, left)
    assert not (found & ~truly_unable).any(), "a state that can reach the target was dropped"

    # P[left U right] with and without the found states in the sweeps
    values = []
    for free in (left & ~right, left & ~right & ~found):
        x = np.where(right, 1.0, 0.0)
        rows = np.flatnonzero(free)[::-1].copy()
        assert kernels.gauss_seidel(indptr, cols, vals, rows, x, np.zeros(count), 1e-14, 100_000) >= 0
        values.append(x)
    assert np.array_equal(values[0][found], np.zeros(found.sum()))
    assert np.allclose(values[0], values[1], rtol=1e-12, atol=1e-12)
    # and against a direct solve on the states that can reach
    assert np.allclose(values[1], until_exactly(matrix, right, truly_unable | right | ~left), rtol=1e-9, atol=1e-10)


def until_exactly(matrix, right, fixed):
    """P[F right] by a direct solve, with the ``fixed`` states at 1 (right) or 0."""
    exact = np.where(right, 1.0, 0.0)
    idx = np.flatnonzero(~fixed)
    if len(idx):
        a = np.eye(len(idx)) - matrix[np.ix_(idx, idx)]
        b = matrix[np.ix_(idx, np.flatnonzero(right))].sum(axis=1)
        exact[idx] = np.linalg.solve(a, b)
    return exact


@pytest.mark.parametrize("seed", range(40))
def test_lumping_chains_of_single_transitions_keeps_the_solution(seed):
    indptr, cols, vals, levels = random_dtmc(seed, single=0.5)
    count = len(levels)
    rng = np.random.default_rng(3000 + seed)
    matrix = dense(indptr, cols, vals)
    right = rng.random(count) < 0.1
    free = ~right & reaches(matrix, right, np.ones(count, bool))
    for cap in (count, 2):
        through = kernels.pass_through(count, indptr, cols, vals, ~free, cap)
        passed = through >= 0
        assert not passed[0] and not (passed & ~free).any()
        # walks end within cap steps (so cycles were cut)
        for s in np.flatnonzero(passed):
            u, steps = s, 0
            while through[u] >= 0:
                assert cols[indptr[u]] == through[u] and vals[indptr[u]] == 1.0
                u, steps = through[u], steps + 1
            assert steps <= cap
        # probabilities: constant 0
        x = np.where(right, 1.0, 0.0)
        lumped = kernels.lump(count, indptr, cols, vals, through, np.zeros(count))
        rows = np.flatnonzero(free & ~passed)[::-1].copy()
        assert kernels.gauss_seidel(*lumped[:3], rows, x, lumped[3], 1e-14, 100_000) >= 0
        exact = until_exactly(matrix, right, ~free)
        assert np.allclose(x[~passed], exact[~passed], rtol=1e-9, atol=1e-10)
        # rewards: the constants along a chain are added up
        reward = rng.random(count) * free
        x = np.zeros(count)
        lumped = kernels.lump(count, indptr, cols, vals, through, reward)
        assert kernels.gauss_seidel(*lumped[:3], rows, x, lumped[3], 1e-14, 100_000) >= 0
        idx = np.flatnonzero(free)
        expected = np.zeros(count)
        expected[idx] = np.linalg.solve(np.eye(len(idx)) - matrix[np.ix_(idx, idx)], reward[idx])
        assert np.allclose(x[~passed], expected[~passed], rtol=1e-9, atol=1e-10)


@pytest.mark.parametrize("seed", [0, 1, 2, 4, 6, 7, 9, 10, 13, 14, 15, 16, 17])  # those with 60 states or more
def test_the_lumped_equations_solved_directly_are_the_solution(seed):
    # what the direct solve factors: I - P on the unknowns of the lumped equations, with the
    # other states' values (targets) moved to the right-hand side
    indptr, cols, vals, levels = random_dtmc(seed, n=200, single=0.3)
    count = len(levels)
    rng = np.random.default_rng(5000 + seed)
    matrix = dense(indptr, cols, vals)
    right = rng.random(count) < 0.3
    free = ~right & reaches(matrix, right, np.ones(count, bool))
    through = kernels.pass_through(count, indptr, cols, vals, ~free, count)
    reward = rng.random(count) * free
    x = np.where(right, 1.0, 0.0)  # probabilities plus rewards: a target is worth 1
    lumped = kernels.lump(count, indptr, cols, vals, through, reward)
    idx = np.flatnonzero(free & (through < 0))
    assert len(idx) > 1
    data, indices, pointers, rhs = kernels.equations(*lumped[:3], idx, x, lumped[3])
    system = np.zeros((len(idx), len(idx)))
    for i in range(len(idx)):
        assert indices[pointers[i]] == i  # the diagonal first
        for e in range(pointers[i], pointers[i + 1]):
            system[i, indices[e]] += data[e]
    unknown = np.flatnonzero(free)
    expected = x.copy()
    expected[unknown] = np.linalg.solve(
        np.eye(len(unknown)) - matrix[np.ix_(unknown, unknown)],
        reward[unknown] + matrix[np.ix_(unknown, np.flatnonzero(~free))] @ x[~free],
    )
    assert np.allclose(np.linalg.solve(system, rhs), expected[idx], rtol=1e-9, atol=1e-10)


def _loop(stay: float):
    """One state that stays with probability ``stay`` and otherwise reaches an absorbing target."""
    indptr = np.array([0, 2, 3], dtype=np.int64)
    cols = np.array([0, 1, 1], dtype=np.int64)
    vals = np.array([stay, 1.0 - stay, 1.0])
    return indptr, cols, vals


def _two_states(stay: float):
    """Two states that pass to each other (the self-loop trick cannot solve them at once)."""
    indptr = np.array([0, 2, 4, 5], dtype=np.int64)
    cols = np.array([1, 2, 0, 2, 2], dtype=np.int64)
    vals = np.array([stay, 1.0 - stay, stay, 1.0 - stay, 1.0])
    return indptr, cols, vals


def test_gauss_seidel_gives_up_early_on_a_slowly_mixing_chain_only_when_asked():
    indptr, cols, vals = _two_states(0.999)
    rows = np.array([1, 0], dtype=np.int64)
    constant = np.array([1.0, 1.0, 0.0])
    patient, hasty = np.zeros(3), np.zeros(3)
    assert kernels.gauss_seidel(indptr, cols, vals, rows, patient, constant, 1e-12, 100) == -1
    assert kernels.gauss_seidel(indptr, cols, vals, rows, hasty, constant, 1e-12, 100, True) == -1
    # iterated from 0 the values only grow: the hasty one stopped after far fewer sweeps
    assert hasty[0] < 0.2 * patient[0]
    # a chain that converges in time converges the same either way
    indptr, cols, vals = _two_states(0.5)
    for give_up in (False, True):
        x = np.zeros(3)
        assert 0 < kernels.gauss_seidel(indptr, cols, vals, rows, x, constant, 1e-12, 100, give_up) <= 100
        assert x[0] == pytest.approx(2.0, rel=1e-11)
    # one that converges slowly but within the sweeps given is not given up
    indptr, cols, vals = _two_states(0.8)
    x = np.zeros(3)
    used = kernels.gauss_seidel(indptr, cols, vals, rows, x, constant, 1e-12, 400, True)
    assert used > kernels.FIRST_GUESS and x[0] == pytest.approx(5.0, rel=1e-10)


@pytest.mark.parametrize("seed", [0, 1, 4, 6])
def test_solves_in_the_models_elimination_order_are_the_solution(seed):
    from parley_core.quotient import ordering

    indptr, cols, vals, levels = random_dtmc(seed, n=200, single=0.3)
    count = len(levels)
    matrix = dense(indptr, cols, vals)
    right = np.random.default_rng(7000 + seed).random(count) < 0.3
    free = ~right & reaches(matrix, right, np.ones(count, bool))
    rank = ordering.elimination_rank(np.arange(count + 1), indptr, cols)  # one choice a state
    assert sorted(rank.tolist()) == list(range(count))
    idx = ordering.in_order(np.flatnonzero(free), rank[free])
    assert (np.diff(rank[idx]) > 0).all()
    reward = np.ones(count)
    data, indices, pointers, rhs = kernels.equations(indptr, cols, vals, idx, np.zeros(count), reward)
    system, factors = ordering.factor(data, indices, pointers)
    expected = np.linalg.solve(np.eye(len(idx)) - matrix[np.ix_(idx, idx)], reward[idx])
    assert np.allclose(factors.solve(rhs), expected, rtol=1e-9)
    assert np.allclose(system.toarray(), np.eye(len(idx)) - matrix[np.ix_(idx, idx)])


def test_a_system_without_a_way_out_is_refused_as_singular():
    from parley_core.quotient import ordering

    # two states that pass to each other with probability 1: I - P is singular
    with pytest.raises(RuntimeError):
        ordering.factor(np.array([1.0, -1.0, 1.0, -1.0]), np.array([0, 1, 1, 0]), np.array([0, 2, 4]))


def test_gauss_seidel_keeps_sweeping_while_values_still_spread():
    # a line that the sweeps' order crosses one state a sweep: the change falls fast near the
    # target, then stays level while the value travels up the line (as on a large robot
    # map before the success probability has spread over it), then is gone at once
    length, near = 300, 10
    stay = np.ones(length)
    stay[-near:] = 0.3  # each of the last ten passes on 0.3 and loses the rest
    indptr = np.arange(length + 2, dtype=np.int64)
    cols = np.append(np.arange(1, length + 1), length).astype(np.int64)  # state i -> i + 1; the target loops
    vals = np.append(stay, 1.0)
    rows = np.arange(length, dtype=np.int64)  # from the far end: one state nearer the target a sweep
    x = np.zeros(length + 1)
    x[length] = 1.0
    constant = np.zeros(length + 1)
    used = kernels.gauss_seidel(indptr, cols, vals, rows, x, constant, 1e-12, 1000, True)
    assert length <= used <= length + 2 and x[0] == pytest.approx(0.3**near, rel=1e-12)
    # with too few sweeps for the line it still gives up
    assert (
        kernels.gauss_seidel(
            indptr, cols, vals, rows, np.where(np.arange(length + 1) == length, 1.0, 0.0), constant, 1e-12, 200, True
        )
        == -1
    )


def test_the_sweep_budget_grows_with_the_unknowns():
    from parley_core.quotient import solver

    assert solver.sweep_budget(1_000) == solver.SLOW_SWEEPS
    assert solver.sweep_budget(100_000) == 100_000 // solver.ROWS_PER_SWEEP > solver.SLOW_SWEEPS
