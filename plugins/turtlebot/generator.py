"""The turtlebot DTMC, with the localisation period as the constant ``c``.

The structure follows the paper's ``models/turtlebot/model.prism`` so that a policy gets the
same values on both (scripts/check_turtlebot.py compares them with Storm):

- ``Robot``: the true cell (x, y) and heading ``direction``; a move command draws its
  outcome from the motion table of the true cell and heading: a neighboring cell and new
  heading, ``crashed`` or ``out`` (left the area), after which the robot stays where it
  was and only idles (``stuck``). A cell without table entries (an obstacle) has no move.
  With heading memory (``World.remembered``) the table is that of the true cell, the
  *believed* heading ``directionhat`` and the move counter ``step`` instead: the robot
  turns from the heading it believes, and its true heading's error grows with the moves
  since the last localisation.
- ``Controller`` (the UAC): one move per estimated cell (xhat, yhat), none at the target.
- ``Knowledge``: the estimate (xhat, yhat, directionhat), updated as if every move went as
  commanded, and the move counter ``step`` (1 after a localisation); ``localise``
  (step >= c) sets the estimate to the truth, ``skip`` (step < c) counts on. With
  ``loc_error`` > 0 the localisation errs in the cell, not in the heading
  (:func:`parley_plugins.localisation.localise_commands`; the estimated heading stays the true one): one ``localise`` command per border situation of the true
  cell, each with the exact update and one per in-square neighbor.
- ``Turn``: move, localise or skip, then an idle step: one move is three DTMC steps.

Rewards "energy": ``move_cost`` per move, ``localisation_cost`` per localisation; "time":
1 per move.
"""

from __future__ import annotations

from fractions import Fraction

from parley_core.prism.writer import (
    Command,
    Constant,
    Label,
    Module,
    Program,
    RewardItem,
    Rewards,
    Update,
    Variable,
    conjunction,
)
from parley_plugins.localisation import localise_commands
from parley_plugins.turtlebot.world import HEADINGS, Outcome, World

_ESTIMATE = {
    "north": {"yhat": "min(yhat+1, N)", "directionhat": "0"},
    "east": {"xhat": "min(xhat+1, N)", "directionhat": "1"},
    "south": {"yhat": "max(yhat-1, 0)", "directionhat": "2"},
    "west": {"xhat": "max(xhat-1, 0)", "directionhat": "3"},
}


def prism_model(
    world: World, *, max_period: int, move_cost: float, localisation_cost: float, loc_error: float = 0.0
) -> str:
    """The DTMC text of ``world`` (its motion table and movement controller); with
    ``loc_error`` > 0 the localisation errs (:func:`parley_plugins.localisation.localise_commands`; the estimated heading stays the true one), and the world's plan
    must then have a move for every cell but the target
    (:func:`~parley_plugins.turtlebot.world.complete`). With ``loc_error`` = 0 the text is
    exactly the one without the option."""
    cells = [(x, y) for x in range(world.size) for y in range(world.size)]
    unplanned = [cell for cell in cells if cell not in world.plan and cell != world.target]
    if loc_error > 0 and unplanned:
        raise ValueError(f"an erring localisation may put the estimate on {unplanned[0]}, which has no move")
    robot_commands = [
        Command(
            action=move,
            guard=f"x={x} & y={y} & direction={heading}",
            updates=[Update(assignments=_assignments(outcome, x, y), probability=exact(p)) for outcome, p in outcomes],
        )
        for (x, y, heading, move), outcomes in sorted(world.motions.items(), key=lambda item: _order(item[0]))
    ]
    robot_commands += [
        Command(
            action=move,
            guard=f"x={x} & y={y} & directionhat={believed} & step={step}",
            updates=[Update(assignments=_assignments(outcome, x, y), probability=exact(p)) for outcome, p in outcomes],
        )
        for (x, y, believed, move, step), outcomes in sorted(
            (world.remembered or {}).items(), key=lambda item: (*_order(item[0][:4]), item[0][4])
        )
    ]
    robot_commands.append(Command(action="stuck", guard="crashed=1 | out=1"))
    robot = Module(
        name="Robot",
        variables=[
            Variable(name="x", low=0, high="N", init=world.start[0], comment="true cell"),
            Variable(name="y", low=0, high="N", init=world.start[1]),
            Variable(name="direction", low=0, high=3, init=0, comment="true heading: 0 north, 1 east, 2 south, 3 west"),
            Variable(name="crashed", low=0, high=1, init=0),
            Variable(name="out", low=0, high=1, init=0, comment="left the area"),
        ],
        commands=robot_commands,
    )
    planned = sorted(world.plan.items(), key=lambda item: (HEADINGS.index(item[1]), item[0]))
    controller = Module(
        name="Controller",
        commands=[
            *(Command(action=move, guard=f"xhat={x} & yhat={y} & crashed=0 & out=0") for (x, y), move in planned),
            *(Command(action=move, guard="false") for move in HEADINGS if move not in world.plan.values()),
        ],
    )
    knowledge = Module(
        name="Knowledge",
        variables=[
            Variable(name="xhat", low=0, high="N", init=world.start[0], comment="estimated cell"),
            Variable(name="yhat", low=0, high="N", init=world.start[1]),
            Variable(name="directionhat", low=0, high=3, init=0, comment="estimated heading"),
            Variable(name="step", low=1, high="maxStep", init=1, comment="moves since the last localisation"),
        ],
        commands=[
            *(Command(action=move, updates=[Update(assignments=_ESTIMATE[move])]) for move in HEADINGS),
            *localise_commands(
                loc_error,
                x_high="N",
                y_high="N",
                wide=world.size > 2,
                tall=world.size > 2,
                also={"directionhat": "direction"},
            ),
            Command(action="skip", guard="step<c", updates=[Update(assignments={"step": "step+1"})]),
        ],
    )
    turn = Module(
        name="Turn",
        variables=[Variable(name="t", low=0, high=2, init=0, comment="0 move, 1 localise or skip, 2 idle")],
        commands=[
            *(Command(action=move, guard="t=0", updates=[Update(assignments={"t": "1"})]) for move in HEADINGS),
            Command(action="localise", guard="t=1", updates=[Update(assignments={"t": "2"})]),
            Command(action="skip", guard="t=1", updates=[Update(assignments={"t": "2"})]),
            Command(guard="t=2", updates=[Update(assignments={"t": "0"})]),
        ],
    )
    tx, ty = world.target
    program = Program(
        header=(
            f"turtlebot: {world.size}x{world.size} cells ({world.source}); start {world.start}, target {world.target}.\n"
            "The localisation service runs once the move counter reaches c (every c-th move)."
            + (_ERRING if loc_error > 0 else "")
        ),
        constants=[
            Constant(name="N", value=world.size - 1, comment="largest x and y"),
            *([_loc_error_constant(loc_error)] if loc_error > 0 else []),
            Constant(name="maxStep", value=max_period),
            Constant(name="c", comment=f"localisation period in moves, 1..{max_period}"),
        ],
        # Turn first: Storm tries the modules of an action in this order and stops at the
        # first without an enabled command, and Turn disables two actions in three in every
        # state (the builder takes half the time; the DTMC is the same).
        modules=[turn, robot, controller, knowledge],
        rewards=[
            Rewards(
                name="energy",
                items=[
                    RewardItem(action="localise", value=localisation_cost),
                    *(RewardItem(action=move, value=move_cost) for move in HEADINGS),
                ],
            ),
            Rewards(name="time", items=[RewardItem(action=move, value=1) for move in HEADINGS]),
        ],
        labels=[
            Label(name="goal", expression=conjunction([f"x={tx}", f"y={ty}", "crashed=0", "out=0"])),
            Label(name="crashed", expression="crashed=1"),
            Label(name="out", expression="out=1"),
        ],
    )
    return program.render()


_ERRING = (
    "\nWith probability loc_error it puts the estimated cell on one of the true cell's in-square 4-neighbors"
    " (equally likely) instead; the estimated heading is always the true one."
)


def _loc_error_constant(loc_error: float) -> Constant:
    return Constant(
        name="loc_error",
        type="double",
        value=loc_error,
        comment="probability that a localisation puts the estimated cell on a neighbor of the true cell",
    )


def exact(probability: float) -> str:
    """A probability as PRISM text: ``count/samples`` where it is one (a sampled table's
    ``7/3000``), else the float as written. Storm reads a decimal as an exact rational
    (``0.00023333333333333333`` is 23333333333333333/10^20), and the products of such
    rationals in a large model overflow its 64-bit integers; small fractions do not, and
    they sum to exactly 1."""
    fraction = Fraction(probability).limit_denominator(1_000_000)
    if float(fraction) == probability:
        return str(fraction.numerator) if fraction.denominator == 1 else f"{fraction.numerator}/{fraction.denominator}"
    return repr(probability)


def _assignments(outcome: Outcome, x: int, y: int) -> dict[str, str]:
    if outcome.kind != "move":
        return {{"crash": "crashed", "out": "out"}[outcome.kind]: "1"}
    return {"x": str(x + outcome.dx), "y": str(y + outcome.dy), "direction": str(outcome.heading)}


def _order(key: tuple[int, int, int, str]) -> tuple:
    x, y, heading, move = key
    return (HEADINGS.index(move), x, y, heading)
