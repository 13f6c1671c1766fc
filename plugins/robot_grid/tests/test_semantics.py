"""The generated model means what the docs say: an independent Markov chain, written here
from the description (move, check, localise-or-skip; deviations; crashes; the package's
stuck self-loop), gives the same success probability and bounded cost as Storm on the
generated PRISM model, for random maps and random policies."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from parley_core import testing
from parley_plugins.robot_grid import CASE_STUDY as CASE
from parley_plugins.robot_grid.planner import MOVES


def reference(grid, moves, policy, p, horizon, move_cost=1.0, localisation_cost=5.0):
    """Success probability and expected cost within ``horizon`` steps, by explicit enumeration."""
    width, height = grid.width, grid.height

    def clamp(x, y):
        return min(max(x, 0), width - 1), min(max(y, 0), height - 1)

    def successors(state):
        x, y, xh, yh, step, crashed, t = state
        options = []  # (distribution, reward) per enabled command, mixed uniformly
        if t == 0 and not crashed and (xh, yh) in moves:
            move = moves[(xh, yh)]
            dist = []
            for direction, (dx, dy) in MOVES.items():
                nx, ny = clamp(x + dx, y + dy)
                hx, hy = clamp(xh + MOVES[move][0], yh + MOVES[move][1])
                dist.append((1 - 3 * p if direction == move else p, (nx, ny, hx, hy, step, crashed, 1)))
            options.append((dist, move_cost))
        if t == 1:
            options.append(([(1.0, (x, y, xh, yh, step, crashed or grid.is_obstacle(x, y), 2))], 0.0))
        if t == 2:
            if step >= policy[(xh, yh)]:
                options.append(([(1.0, (x, y, x, y, 1, crashed, 0))], localisation_cost))
            else:
                options.append(([(1.0, (x, y, xh, yh, step + 1, crashed, 0))], 0.0))
        if crashed:
            options.append(([(1.0, state)], 0.0))  # the package's "stucked" self-loop
        if not options:
            options.append(([(1.0, state)], 0.0))  # a deadlock stays put
        n = len(options)
        return [(q / n, s) for dist, _ in options for q, s in dist], sum(r for _, r in options) / n

    start = (0, 0, 0, 0, 1, False, 0)
    index, order, edges, rewards = {start: 0}, [start], [], []
    for state in order:
        dist, reward = successors(state)
        rewards.append(reward)
        for q, target in dist:
            if target not in index:
                index[target] = len(order)
                order.append(target)
            edges.append((index[state], index[target], q))
    n = len(order)
    rows, cols, vals = zip(*edges)
    matrix = sp.csr_matrix((vals, (rows, cols)), shape=(n, n))
    reward = np.array(rewards)

    cost = np.zeros(n)
    for _ in range(horizon):
        cost = reward + matrix @ cost

    goal = np.array([s[:2] == grid.target and not s[5] for s in order])
    # states that can reach the goal (backwards search); the others have probability 0
    reach = goal.copy()
    back = matrix.T.tocsr()
    frontier = list(np.flatnonzero(goal))
    while frontier:
        j = frontier.pop()
        for i in back.indices[back.indptr[j] : back.indptr[j + 1]]:
            if not reach[i] and matrix[i, j] > 0:
                reach[i] = True
                frontier.append(i)
    unknown = np.flatnonzero(reach & ~goal)
    success = goal.astype(float)
    if len(unknown):
        sub = matrix[unknown][:, unknown]
        rhs = np.asarray(matrix[unknown][:, np.flatnonzero(goal)].sum(axis=1)).ravel()
        success[unknown] = spla.spsolve(sp.identity(len(unknown), format="csc") - sub.tocsc(), rhs)
    return success[0], cost[0]


@pytest.mark.parametrize(("size", "seed", "p", "horizon"), [(4, 1, 0.05, 60), (5, 3, 0.02, 100), (6, 11, 0.08, 90)])
def test_storm_on_the_generated_model_matches_an_independent_chain(size, seed, p, horizon):
    options = CASE.options([f"size={size}", f"seed={seed}", f"p={p}", f"horizon={horizon}", "max_interval=5"])
    system = CASE.build(options)
    grid, moves = system.context
    family = testing.family(system)
    rng = np.random.default_rng(seed)
    policies = np.vstack([np.full(len(family.decisions), 1), rng.integers(1, 6, size=(4, len(family.decisions)))])
    values = testing.values(family, np.asarray(policies))
    for row, (success, cost) in zip(policies, values):
        policy = {d.valuation: int(v) for d, v in zip(family.decisions, row)}
        expected_success, expected_cost = reference(grid, moves, policy, p, horizon)
        assert success == pytest.approx(expected_success, abs=1e-9)
        assert cost == pytest.approx(expected_cost, abs=1e-9)


def test_without_deviations_the_robot_follows_its_plan_and_pays_per_move(tmp_path):
    path = tmp_path / "m.csv"
    path.write_text("0,0,0,0\n0,10,0,0\n0,0,0,0\n0,0,0,0\n")  # the plan takes 6 moves
    system = CASE.build(CASE.options([f"map={path}", "p=0"]))
    family = testing.family(system)
    values = testing.values(family, np.array([[k] * len(family.decisions) for k in (1, 2, 3, 7)]))
    assert values[:, 0] == pytest.approx([1.0] * 4)
    assert values[:, 1] == pytest.approx([6 + 5 * 6, 6 + 5 * 3, 6 + 5 * 2, 6])


def test_localising_after_every_move_on_a_map_without_obstacles_always_succeeds(tmp_path):
    # The robot may drift, but with no obstacle it cannot crash, and localising after every
    # move brings it back on its plan: it reaches the target with probability 1.
    path = tmp_path / "empty.csv"
    path.write_text("\n".join(["0,0,0,0,0"] * 5) + "\n")
    family = testing.family(CASE.build(CASE.options([f"map={path}", "p=0.1"])))
    success = testing.values(family, np.array([[1] * len(family.decisions), [10] * len(family.decisions)]))[:, 0]
    assert success[0] == pytest.approx(1.0, abs=1e-9)
    # Rarely localising, the robot may believe it has arrived while it has drifted elsewhere:
    # it then stops for good (no move at the target, no localisation without a move), as in
    # the paper's model. Eight moves, each exact with probability 0.7: about 0.7^8 succeed.
    assert 0.7**8 <= success[1] < 0.1
