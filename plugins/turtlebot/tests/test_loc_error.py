"""The erring localisation (option ``loc_error``) means what docs/turtlebot.md says.

- ``loc_error=0`` (the default) is today's model: no trace of the erring localisation in
  the text (the default world's text has the sha256 the code before the option produced),
  and Storm gives the values recorded from that code to 1e-12.
- With ``loc_error`` > 0: the quotient evaluator agrees with Storm; every estimated cell but
  the target has a move; and Storm on the plugin's model agrees with an independent DTMC
  built here state by state (a stormpy sparse DTMC in exact rational arithmetic, no PRISM)
  from the world's motion table, whose localisation errs to the in-square 4-neighbors of
  the true cell and reads the heading exactly. The closed loop's localisation errs alike.
"""

from __future__ import annotations

import hashlib
from fractions import Fraction

import numpy as np
import pytest

from parley_core import OptionError, testing
from parley_plugins.turtlebot import CASE_STUDY as CASE
from parley_plugins.turtlebot import world_of
from parley_plugins.turtlebot.closed_loop import misread
from parley_plugins.turtlebot.world import HEADINGS, STEP

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

DEFAULT_SHA256 = "54c92bce2bbac4a9db91034cfeb47a60def6600059f0dbc7284d6201acbf48fa"
"""The default model's text (7x7, kinematic motions), as the generator wrote it before ``loc_error``."""

TODAY = [(0.30632269140167573, 21.665105213835236), (0.29113641081808395, 11.174059751147338)]
"""Storm's (success, energy) on ``SMALL`` before ``loc_error`` existed: periods 1 and 2 everywhere."""

TODAY_RANDOM = (0.2713496851561877, 8.874184446849018)
"""... and for the policy ``default_rng(5).integers(1, 4, decisions)``."""

# 3x3 cells, obstacle in the middle. The controller derived by hand: breadth-first shortest
# paths to (2, 2), ties north, east, south, west; the obstacle's move from world.complete
# (north is the first move to a planned cell).
RING = ["size=3", "start=0:0", "target=2:2", "obstacles=1:1", "samples=20", "heading_noise=20", "max_period=3"]
RING_CONTROLLER = {
    (0, 0): "north",
    (0, 1): "north",
    (0, 2): "east",
    (1, 2): "east",
    (1, 0): "east",
    (2, 0): "north",
    (2, 1): "north",
    (1, 1): "north",
}


def _policies(family):
    n = len(family.decisions)
    return np.vstack([np.full(n, 1), np.full(n, 2), np.random.default_rng(5).integers(1, 4, n)])


def _localise_lines(text):
    return [line.strip() for line in text.splitlines() if line.strip().startswith("[localise] step")]


def test_without_loc_error_the_model_and_its_values_are_todays():
    for assignments in ([], SMALL):
        text = CASE.build(CASE.options([*assignments, "loc_error=0"])).prism
        if not assignments:
            assert hashlib.sha256(text.encode()).hexdigest() == DEFAULT_SHA256
        assert "loc_error" not in text and "neighbor" not in text
        assert _localise_lines(text) == [
            "[localise] step>=c -> (xhat'=x) & (yhat'=y) & (directionhat'=direction) & (step'=1);"
        ]
    family = testing.family(CASE, SMALL)
    values = testing.values(family, _policies(family))
    assert values == pytest.approx(np.array([*TODAY, TODAY_RANDOM]), rel=1e-12, abs=1e-12)


def test_the_quotient_evaluator_agrees_with_storm_when_the_localisation_errs():
    family = testing.family(CASE, [*SMALL, "loc_error=0.15"])
    policies = _policies(family)
    storm = testing.values(family, policies)
    assert storm[0, 0] < TODAY[0][0]  # erring costs success
    assert testing.values(family, policies, evaluator="quotient") == pytest.approx(storm, rel=1e-9, abs=1e-9)


def test_the_localisation_errs_in_the_cell_and_reads_the_heading():
    text = CASE.build(CASE.options([*SMALL, "loc_error=0.3"])).prism
    localise = _localise_lines(text)
    assert len(localise) == 9
    assert sorted(line.count("loc_error/") for line in localise) == [2, 2, 2, 2, 3, 3, 3, 3, 4]
    assert all(line.count("(directionhat'=direction)") == line.count(" : ") for line in localise)
    assert localise[0] == (
        "[localise] step>=c & x=0 & y=0 -> 1-loc_error : (xhat'=x) & (yhat'=y) & (directionhat'=direction) & (step'=1)"
        " + loc_error/2 : (xhat'=x+1) & (yhat'=y) & (directionhat'=direction) & (step'=1)"
        " + loc_error/2 : (xhat'=x) & (yhat'=y+1) & (directionhat'=direction) & (step'=1);"
    )
    # the obstacles (1,1) and (2,1) get moves; the target does not
    world = CASE.build(CASE.options([*SMALL, "loc_error=0.3"])).context
    assert set(world.plan) == {(x, y) for x in range(4) for y in range(4)} - {(3, 3)}
    assert world.plan == {**world_of(CASE.options(SMALL)).plan, **{c: world.plan[c] for c in ((1, 1), (2, 1))}}


class Chain:
    """The turtlebot DTMC of docs/turtlebot.md for a motion table, a controller, one period
    ``c`` everywhere and localisation error ``e``, state by state: move (the table's outcome
    for the true cell, heading and the controller's move of the estimated cell; the estimate
    as if commanded; a crash or leaving stops the robot), localise (step >= c: the estimated
    cell to the true one with 1-e, to each in-square 4-neighbor with e/their number, the
    estimated heading to the true one; step := 1) or skip (step + 1), idle. A stopped
    robot's ``stuck`` loop competes uniformly with its other commands; a state without a
    command loops."""

    def __init__(self, world, controller, c, e, move_cost=1, localisation_cost=5):
        self.world, self.controller, self.c, self.e = world, controller, c, e
        self.move_cost, self.localisation_cost = Fraction(move_cost), Fraction(localisation_cost)

    def located(self, x, y):
        n = self.world.size
        around = [
            (x + dx, y + dy) for dx, dy in ((1, 0), (0, 1), (0, -1), (-1, 0)) if 0 <= x + dx < n and 0 <= y + dy < n
        ]
        return [(1 - self.e, (x, y)), *((self.e / len(around), cell) for cell in around)]

    def commands(self, state):
        """The enabled commands of ``state``: [([(probability, next state)], reward)]."""
        t, x, y, d, xh, yh, dh, step, stopped = state
        found = []
        move = self.controller.get((xh, yh))
        outcomes = self.world.motions.get((x, y, d, move)) if t == 0 and not stopped and move else None
        if outcomes:
            top = self.world.size - 1
            ex, ey = min(max(xh + STEP[move][0], 0), top), min(max(yh + STEP[move][1], 0), top)
            distribution = []
            for outcome, p in outcomes:
                q = Fraction(p).limit_denominator(1000)
                if outcome.kind == "move":
                    after = (
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
                    after = (1, x, y, d, ex, ey, HEADINGS.index(move), step, True)
                distribution.append((q, after))
            assert sum(q for q, _ in distribution) == 1
            found.append((distribution, self.move_cost))
        if t == 1 and step >= self.c:
            located = [(q, (2, x, y, d, *cell, d, 1, stopped)) for q, cell in self.located(x, y)]
            found.append((located, self.localisation_cost))
        if t == 1 and step < self.c:
            found.append(([(Fraction(1), (2, x, y, d, xh, yh, dh, step + 1, stopped))], Fraction(0)))
        if t == 2:
            found.append(([(Fraction(1), (0, *state[1:]))], Fraction(0)))
        if stopped:
            found.append(([(Fraction(1), state)], Fraction(0)))
        return found or [([(Fraction(1), state)], Fraction(0))]

    def values(self, horizon):
        """Storm's success and energy of the chain (no PRISM: :func:`parley_core.testing.chain_values`)."""
        start = (0, *self.world.start, 0, *self.world.start, 0, 1, False)
        target = self.world.target
        return testing.chain_values(
            start,
            self.commands,
            {"goal": lambda state: state[1:3] == target and not state[8]},
            "energy",
            ['P=? [F "goal"]', f'R{{"energy"}}=? [C<={horizon}]'],
        )


@pytest.mark.parametrize(("period", "loc_error"), [(1, "0.2"), (2, "0.1"), (3, "1")])
def test_storm_on_the_plugins_model_agrees_with_an_independent_chain(period, loc_error):
    system = CASE.build(CASE.options([*RING, f"loc_error={loc_error}", "horizon=45"]))
    assert system.context.plan == RING_CONTROLLER
    family = testing.family(system)
    (success, energy) = testing.values(family, np.full((1, len(family.decisions)), period))[0]
    motions = world_of(CASE.options(RING))
    expected_success, expected_energy = Chain(motions, RING_CONTROLLER, period, Fraction(loc_error)).values(45)
    assert success == pytest.approx(expected_success, abs=1e-9)
    assert energy == pytest.approx(expected_energy, abs=1e-9)
    exact_success = Chain(motions, RING_CONTROLLER, period, Fraction(0)).values(45)[0]
    assert exact_success != pytest.approx(expected_success, abs=1e-6)  # the error matters


def test_the_closed_loops_localisation_errs_alike():
    rng = np.random.default_rng(3)
    cells = np.array([[0, 0], [1, 1], [3, 1]] * 4000)
    before = rng.bit_generator.state
    assert misread(cells, 0.0, 3, rng) is cells and rng.bit_generator.state == before  # no draw
    read = misread(cells, 0.3, 3, rng)
    corner, inner, outside = read[0::3], read[1::3], read[2::3]
    assert (outside == [3, 1]).all()  # left the square: kept
    for got, true, around in ((corner, (0, 0), [(1, 0), (0, 1)]), (inner, (1, 1), [(2, 1), (1, 2), (1, 0), (0, 1)])):
        share = {cell: np.mean((got == cell).all(axis=1)) for cell in [true, *around]}
        assert sum(share.values()) == 1.0
        assert share[true] == pytest.approx(0.7, abs=0.03)
        assert all(share[cell] == pytest.approx(0.3 / len(around), abs=0.03) for cell in around)


@pytest.mark.parametrize("value", ["1.5", "-1"])
def test_a_loc_error_outside_0_1_is_a_clear_error(value):
    with pytest.raises(OptionError, match="loc_error"):
        CASE.options([f"loc_error={value}"])
