"""The erring localisation (option ``loc_error``) means what docs/robot_grid.md says.

- ``loc_error=0`` (the default) is today's model: no trace of the erring localisation in
  the text (the default map's text has the sha256 the code before the option produced), and
  Storm gives the values recorded from that code to 1e-12.
- With ``loc_error`` > 0: the quotient evaluator agrees with Storm; every estimate the
  robot can be in has a move, except the target where it stops; and Storm on the plugin's
  model agrees with an independent DTMC built here state by state (a stormpy sparse DTMC in
  exact rational arithmetic, no PRISM), whose localisation errs to the in-map 4-neighbors.
"""

from __future__ import annotations

import hashlib
from fractions import Fraction

import numpy as np
import pytest
from typer.testing import CliRunner

from parley_core import OptionError, testing
from parley_core.cli import app
from parley_plugins.robot_grid import CASE_STUDY as CASE
from parley_plugins.robot_grid.generator import prism_model
from parley_plugins.robot_grid.grid import load_csv
from parley_plugins.robot_grid.planner import MOVES, complete, plan

SMALL = ["size=4", "seed=1", "p=0.05", "horizon=60", "max_interval=5"]
QUICK = ["size=5", "seed=1", "horizon=45", "max_interval=4"]

DEFAULT_SHA256 = "7988def68d43625569f4568ae421deb14db8f4f9cc8007231658c2891107237f"
"""The default model's text (10x10, seed 0), as the generator wrote it before ``loc_error``."""

TODAY = {
    "default": (
        [],
        [(0.8465238999696787, 103.80286524920895), (0.7501062073475051, 42.785558653551256)],
        (0.7085641088211663, 44.75076834897741),
    ),
    "small": (
        SMALL,
        [(0.9882304051116418, 44.114238151678066), (0.8233345480176242, 17.548186446669337)],
        (0.918290271718124, 24.168386789626418),
    ),
    "quick": (
        QUICK,
        [(0.9889693975552505, 49.58846268388845), (0.9164638546755599, 18.462358908085907)],
        (0.9415704757768381, 28.54702977930124),
    ),
}
"""Storm's (success, cost) before ``loc_error`` existed: intervals 1 and 3 everywhere, and
the policy ``default_rng(5).integers(1, 5, decisions)``."""

# A 3x3 map with an obstacle in the middle (CSV, top row first). Its controller, derived by
# hand from the package's Dijkstra (all free weights 0, so ties decide; see test_planner.py)
# and from planner.complete for the obstacle (west is the first move to a planned cell).
RING = "0,0,0\n0,10,0\n0,0,0\n"
RING_CONTROLLER = {
    (0, 0): "north",
    (0, 1): "north",
    (0, 2): "east",
    (1, 2): "east",
    (2, 1): "north",
    (1, 0): "west",
    (2, 0): "west",
    (1, 1): "west",
}


def _localise_lines(text):
    """The Knowledge module's localise commands (the Turn module's has no ``step``)."""
    return [line.strip() for line in text.splitlines() if line.strip().startswith("[localise] step")]


def _policies(family):
    n = len(family.decisions)
    return np.vstack([np.full(n, 1), np.full(n, 3), np.random.default_rng(5).integers(1, 5, n)])


@pytest.mark.parametrize("name", list(TODAY))
def test_without_loc_error_the_model_and_its_values_are_todays(name):
    assignments, uniform, random = TODAY[name]
    text = CASE.build(CASE.options(assignments)).prism
    assert CASE.build(CASE.options([*assignments, "loc_error=0"])).prism == text
    assert "loc_error" not in text and "neighbor" not in text
    (localise,) = _localise_lines(text)
    assert localise == "[localise] step>=c -> (xhat'=x) & (yhat'=y) & (step'=1);"
    if name == "default":
        assert hashlib.sha256(text.encode()).hexdigest() == DEFAULT_SHA256
    family = testing.family(CASE, assignments)
    values = testing.values(family, _policies(family))
    assert values == pytest.approx(np.array([*uniform, random]), rel=1e-12, abs=1e-12)


def test_the_quotient_evaluator_agrees_with_storm_when_the_localisation_errs():
    family = testing.family(CASE, [*QUICK, "loc_error=0.15"])
    policies = _policies(family)
    storm = testing.values(family, policies)
    assert storm[0, 0] < TODAY["quick"][1][0][0]  # erring costs success
    assert testing.values(family, policies, evaluator="quotient") == pytest.approx(storm, rel=1e-9, abs=1e-9)


class Chain:
    """The DTMC of the robot_grid description on ``grid`` with ``controller`` (a move per
    estimated cell), one localisation interval ``c`` everywhere, slip probability ``p`` and
    localisation error ``e`` (exact fractions), written state by state from the description:
    move (1-3p the intended way, p each other one, clamped; the estimate as if intended),
    check (crash on an obstacle), localise (step >= c: the estimate to the true cell with
    1-e, to each in-map 4-neighbor with e/their number; step := 1) or skip (step + 1). A
    crashed robot's ``stucked`` loop competes uniformly with its other commands; a state
    without a command loops."""

    def __init__(self, grid, controller, c, p, e, move_cost=1, localisation_cost=5):
        self.grid, self.controller, self.c, self.p, self.e = grid, controller, c, p, e
        self.move_cost, self.localisation_cost = Fraction(move_cost), Fraction(localisation_cost)

    def inside(self, x, y):
        return 0 <= x < self.grid.width and 0 <= y < self.grid.height

    def clamp(self, x, y):
        return min(max(x, 0), self.grid.width - 1), min(max(y, 0), self.grid.height - 1)

    def located(self, x, y):
        """Where a localisation puts the estimate of a robot at (x, y): [(probability, cell)]."""
        around = [(x + dx, y + dy) for dx, dy in ((1, 0), (0, 1), (0, -1), (-1, 0)) if self.inside(x + dx, y + dy)]
        return [(1 - self.e, (x, y)), *((self.e / len(around), cell) for cell in around)]

    def commands(self, state):
        """The enabled commands of ``state``: [([(probability, next state)], reward)]."""
        t, x, y, xh, yh, step, crashed = state
        found = []
        if t == 0 and not crashed and (xh, yh) in self.controller:
            move = self.controller[(xh, yh)]
            estimate = self.clamp(xh + MOVES[move][0], yh + MOVES[move][1])
            found.append(
                (
                    [
                        (
                            1 - 3 * self.p if direction == move else self.p,
                            (1, *self.clamp(x + dx, y + dy), *estimate, step, crashed),
                        )
                        for direction, (dx, dy) in MOVES.items()
                    ],
                    self.move_cost,
                )
            )
        if t == 1:
            found.append(
                ([(Fraction(1), (2, x, y, xh, yh, step, crashed or self.grid.is_obstacle(x, y)))], Fraction(0))
            )
        if t == 2 and step >= self.c:
            found.append(
                ([(q, (0, x, y, *cell, 1, crashed)) for q, cell in self.located(x, y)], self.localisation_cost)
            )
        if t == 2 and step < self.c:
            found.append(([(Fraction(1), (0, x, y, xh, yh, step + 1, crashed))], Fraction(0)))
        if crashed:
            found.append(([(Fraction(1), state)], Fraction(0)))
        return found or [([(Fraction(1), state)], Fraction(0))]

    def values(self, horizon):
        """Storm's success and cost of the chain (no PRISM: :func:`parley_core.testing.chain_values`)."""
        start = (0, *self.grid.start, *self.grid.start, 1, False)
        target = self.grid.target
        return testing.chain_values(
            start,
            self.commands,
            {"goal": lambda state: (state[1], state[2]) == target and not state[6]},
            "cost",
            ['P=? [F "goal"]', f'R{{"cost"}}=? [C<={horizon}]'],
        )


@pytest.mark.parametrize(("interval", "p", "loc_error"), [(1, "0.05", "0.2"), (2, "0.02", "0.1"), (3, "0.05", "1")])
def test_storm_on_the_plugins_model_agrees_with_an_independent_chain(tmp_path, interval, p, loc_error):
    path = tmp_path / "ring.csv"
    path.write_text(RING)
    assignments = [f"map={path}", f"p={p}", f"loc_error={loc_error}", "horizon=45", "max_interval=3"]
    system = CASE.build(CASE.options(assignments))
    _, controller = system.context
    assert controller == RING_CONTROLLER
    family = testing.family(system)
    (success, cost) = testing.values(family, np.full((1, len(family.decisions)), interval))[0]
    chain = Chain(load_csv(path), RING_CONTROLLER, interval, Fraction(p), Fraction(loc_error))
    expected_success, expected_cost = chain.values(45)
    assert success == pytest.approx(expected_success, abs=1e-9)
    assert cost == pytest.approx(expected_cost, abs=1e-9)
    if loc_error != "1":  # an exact localisation is likelier to find the target
        exact = Chain(load_csv(path), RING_CONTROLLER, interval, Fraction(p), Fraction(0)).values(45)
        assert exact[0] > expected_success


def test_the_localisation_errs_to_the_in_map_neighbors_only(tmp_path):
    # a 2-wide map has no inner column: 2 x 3 border situations, none with 4 neighbors
    path = tmp_path / "narrow.csv"
    path.write_text("0,0\n0,0\n0,0\n")
    narrow = _localise_lines(CASE.build(CASE.options([f"map={path}", "loc_error=0.3"])).prism)
    assert sorted(line.count("loc_error/") for line in narrow) == [2, 2, 2, 2, 3, 3]
    # a corner has 2 neighbors, a border cell 3, an inner cell 4: each gets loc_error / that
    text = CASE.build(CASE.options([*QUICK, "loc_error=0.3"])).prism
    localise = _localise_lines(text)
    assert len(localise) == 9
    corner = next(line for line in localise if "x=0 & y=0 " in line)
    assert corner == (
        "[localise] step>=c & x=0 & y=0 -> 1-loc_error : (xhat'=x) & (yhat'=y) & (step'=1)"
        " + loc_error/2 : (xhat'=x+1) & (yhat'=y) & (step'=1) + loc_error/2 : (xhat'=x) & (yhat'=y+1) & (step'=1);"
    )
    assert sorted(line.count("loc_error/") for line in localise) == [2, 2, 2, 2, 3, 3, 3, 3, 4]
    assert "min(x+1" not in "".join(localise) and "max(x-1" not in "".join(localise)
    assert "const double loc_error = 0.3;" in text


def test_every_estimate_but_the_target_has_a_move(tmp_path):
    # (0,3) is free but cut off by the obstacles (1,3) and (0,2): Dijkstra plans no move there
    path = tmp_path / "pocket.csv"
    path.write_text("0,10,0,0\n10,0,0,0\n0,0,0,0\n0,0,0,0\n")
    grid = load_csv(path)
    planned = plan(grid)
    with pytest.raises(ValueError, match="has no move"):
        prism_model(grid, planned, p=0.01, max_interval=3, move_cost=1, localisation_cost=5, loc_error=0.1)
    controller = complete(grid, planned)
    assert set(controller) == set(grid.cells()) - {grid.target}
    assert all(controller[cell] == move for cell, move in planned.items())
    for cell in controller:  # following the moves leads every estimate to the target
        for _ in range(grid.width * grid.height):
            if cell == grid.target:
                break
            dx, dy = MOVES[controller[cell]]
            cell = (cell[0] + dx, cell[1] + dy)
            assert 0 <= cell[0] < grid.width and 0 <= cell[1] < grid.height
        assert cell == grid.target
    # in Storm's DTMC of the plugin's model, the robot deadlocks only where it believes it has arrived
    family = testing.family(CASE, [f"map={path}", "loc_error=0.2", "max_interval=3"])
    model = tmp_path / "family.prism"
    model.write_text(family.prism)
    deadlocks, estimates = _deadlocks_and_estimates(model, {d.name: 2 for d in family.decisions})
    assert deadlocks and all(estimate == grid.target for estimate in deadlocks)
    assert {(0, 2), (1, 3)} <= estimates  # obstacles next to the robot's cells: estimates with a move


def _deadlocks_and_estimates(path, constants):
    """The estimates (xhat, yhat) of the deadlock states of a robot that has not crashed,
    and every estimate of such a robot, in Storm's DTMC of the PRISM file ``path``."""
    import stormpy.developer

    program = stormpy.parse_prism_program(str(path))
    manager = program.expression_manager
    program = program.define_undefined_constants(
        {c.expression_variable: manager.integer(constants[c.name]) for c in program.constants if not c.defined}
    )
    options = stormpy.developer.BuilderOptions(build_all_reward_models=False, build_all_labels=True)
    options.set_build_state_valuations()
    model = stormpy.build_model(program, options=options)
    valuations = model.state_valuations
    xhat, yhat, crashed = (valuations.get_values_states(manager.get_variable(n)) for n in ("xhat", "yhat", "crashed"))
    deadlock = model.labeling.get_states("deadlock")
    alive = [s for s in range(model.nr_states) if not crashed[s]]
    return [(xhat[s], yhat[s]) for s in alive if deadlock.get(s)], {(xhat[s], yhat[s]) for s in alive}


@pytest.mark.parametrize("value", ["2", "-0.1", "nan"])
def test_a_loc_error_outside_0_1_is_a_one_line_error(value):
    with pytest.raises(OptionError, match="loc_error"):
        CASE.options([f"loc_error={value}"])
    result = CliRunner().invoke(app, ["run", "robot_grid", "--set", f"loc_error={value}"])
    assert result.exit_code == 2
    assert result.stderr.strip().count("\n") == 0 and "loc_error" in result.stderr
