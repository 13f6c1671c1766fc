"""The generated turtlebot model means what docs/turtlebot.md says.

``Reference`` below is an independent explicit-state DTMC written from the description (not
from the generator): it steps through move / localise-or-skip / idle with the motion table,
the movement controller and the policy, applying the PRISM semantics the description
relies on (a crashed robot's ``stuck`` loop competes uniformly with the other commands; a
state without a command loops). Storm on the generated model must give the same success
probability and bounded energy for baselines and random policies.
"""

from __future__ import annotations

import numpy as np
import pytest

from parley_core import testing
from parley_core.testing import storm_values
from parley_plugins.turtlebot import CASE_STUDY as CASE
from parley_plugins.turtlebot import world_of
from parley_plugins.turtlebot.world import CRASH, HEADINGS, OUT, STEP

SMALL = [
    "size=4",
    "start=0:0",
    "target=3:3",
    "obstacles=1:1,2:1",
    "samples=40",
    "heading_noise=20",
    "horizon=45",
    "max_period=3",
]


class Reference:
    """The DTMC of a world and a policy {(xhat, yhat, dirhat): period}, state by state."""

    def __init__(self, world, policy, move_cost=1.0, localisation_cost=5.0):
        self.world, self.policy = world, policy
        self.move_cost, self.localisation_cost = move_cost, localisation_cost

    def initial(self):
        (x, y) = self.world.start
        return (0, x, y, 0, x, y, 0, 1, False)  # t, x, y, heading, xhat, yhat, dirhat, step, stopped

    def successors(self, state):
        """[(probability, energy, next state)]."""
        t, x, y, d, xh, yh, dh, step, stopped = state
        if t == 0:
            move = None if stopped else self.world.plan.get((xh, yh))
            outcomes = self.world.motions.get((x, y, d, move)) if move else None
            if not outcomes:
                return [(1.0, 0.0, state)]
            n = self.world.size - 1
            ex = min(max(xh + STEP[move][0], 0), n)
            ey = min(max(yh + STEP[move][1], 0), n)
            result = []
            for outcome, p in outcomes:
                if outcome.kind == "move":
                    nxt = (
                        1,
                        x + outcome.dx,
                        y + outcome.dy,
                        outcome.heading,
                        ex,
                        ey,
                        HEADINGS.index(move),
                        step,
                        False,
                    )
                else:
                    nxt = (1, x, y, d, ex, ey, HEADINGS.index(move), step, True)
                result.append((p, self.move_cost, nxt))
            return result
        if t == 1:
            if step >= self.policy[(xh, yh, dh)]:
                service = (1.0, self.localisation_cost, (2, x, y, d, x, y, d, 1, stopped))
            else:
                service = (1.0, 0.0, (2, x, y, d, xh, yh, dh, step + 1, stopped))
        else:
            service = (1.0, 0.0, (0, *state[1:]))
        if stopped:  # the stuck loop is enabled too: one of two commands, uniformly
            return [(0.5, service[1], service[2]), (0.5, 0.0, state)]
        return [service]

    def chain(self):
        index, order, rows = {}, [], []
        index[self.initial()] = 0
        order.append(self.initial())
        for state in order:
            row = []
            for p, reward, nxt in self.successors(state):
                if nxt not in index:
                    index[nxt] = len(order)
                    order.append(nxt)
                row.append((index[nxt], p, reward))
            rows.append(row)
        size = len(order)
        matrix = np.zeros((size, size))
        earn = np.zeros(size)
        for i, row in enumerate(rows):
            for j, p, reward in row:
                matrix[i, j] += p
                earn[i] += p * reward
        return order, matrix, earn

    def values(self, horizon):
        order, matrix, earn = self.chain()
        tx, ty = self.world.target
        goal = np.array([s[1] == tx and s[2] == ty and not s[8] for s in order])
        # P(F goal): solve on the states that are not goal; states that cannot reach goal get 0
        can = goal.copy()
        changed = True
        while changed:
            grown = can | (matrix[:, can].sum(axis=1) > 0)
            changed = bool((grown != can).any())
            can = grown
        unknown = can & ~goal
        a = np.eye(unknown.sum()) - matrix[np.ix_(unknown, unknown)]
        b = matrix[np.ix_(unknown, goal)].sum(axis=1)
        success = np.zeros(len(order))
        success[goal] = 1.0
        success[unknown] = np.linalg.solve(a, b)
        # energy within the first `horizon` steps
        energy = np.zeros(len(order))
        for _ in range(horizon):
            energy = earn + matrix @ energy
        return success[0], energy[0]


@pytest.fixture(scope="module")
def small():
    options = CASE.options(SMALL)
    return world_of(options), testing.family(CASE.build(options))


def _policies(family, count, seed):
    rng = np.random.default_rng(seed)
    for k in range(1, 4):
        yield {v: k for v in family.valuations}
    for _ in range(count):
        yield {v: int(rng.integers(1, 4)) for v in family.valuations}


def test_storm_on_the_generated_model_agrees_with_the_reference(small):
    world, family = small
    assert world.motions and world.plan
    for policy in _policies(family, 4, seed=7):
        constants = {d.name: policy[d.valuation] for d in family.decisions}
        storm = storm_values(family.prism, ['P=? [F "goal"]', 'R{"energy"}=? [C<=45]'], constants, exact=True)
        reference = Reference(world, policy).values(45)
        assert storm == pytest.approx(reference, rel=1e-9, abs=1e-12)


def test_localising_every_move_costs_the_localisations(small):
    world, family = small
    every = {d.name: 1 for d in family.decisions}
    never = {d.name: 3 for d in family.decisions}
    move_only = storm_values(family.prism, ['R{"time"}=? [C<=45]'], every)[0]
    energy_every, energy_never = (storm_values(family.prism, ['R{"energy"}=? [C<=45]'], p)[0] for p in (every, never))
    # every move is followed by one localisation of energy 5 (on top of the move's 1), except a
    # move whose localisation falls beyond the horizon
    assert energy_every > 5 * move_only
    assert energy_never < energy_every


def test_without_noise_the_robot_follows_its_plan_and_never_needs_localising():
    options = CASE.options(
        [
            "size=4",
            "start=0:0",
            "target=3:3",
            "obstacles=1:1",
            "heading_noise=0",
            "turn_noise=0",
            "left_wheel=1",
            "distance_noise=0",
            "samples=20",
        ]
    )
    world = world_of(options)
    assert len(world.motions) == (16 - 1) * 4 * 4
    for (x, y, _heading, move), outcomes in world.motions.items():
        ((outcome, p),) = outcomes
        ahead = (x + STEP[move][0], y + STEP[move][1])
        if not (0 <= ahead[0] < 4 and 0 <= ahead[1] < 4):
            assert outcome == OUT
        elif ahead in world.obstacles:
            assert outcome == CRASH
        else:
            assert (outcome.kind, outcome.dx, outcome.dy, HEADINGS[outcome.heading]) == ("move", *STEP[move], move)
        assert p == 1.0
    family = testing.family(CASE.build(options))
    never = {d.name: 5 for d in family.decisions}
    (success,) = storm_values(family.prism, ['P=? [F "goal"]'], never)
    assert success == pytest.approx(1.0, abs=1e-12)


def test_runs_decide_only_where_the_service_is_consulted():
    family, world = testing.family(CASE, SMALL), world_of(CASE.options(SMALL))
    assert family.left_out and len(family.valuations) + len(family.left_out) == 4 * 4 * 4
    consulted = set()
    for k in range(1, 4):
        order, _, _ = Reference(world, {v: k for v in [*family.valuations, *family.left_out]}).chain()
        consulted |= {(s[4], s[5], s[6]) for s in order if s[0] == 1}
    assert consulted <= set(family.valuations)
    # the estimated heading at a decision is that of the move just made, so most are never consulted
    assert len(family.valuations) < 4 * 4 * 2
