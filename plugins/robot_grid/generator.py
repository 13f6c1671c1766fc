"""The robot_grid DTMC, with the localisation interval as the constant ``c``.

The structure follows the replication package's URC models (``model_N_umc.prism``) so that
any policy gets the same values as on those files:

- ``Robot``: the true position (x, y); a move goes the intended way with probability 1-3p and
  to each other direction with probability p, clamped at the border; ``check`` marks a
  crash on an obstacle, after which the robot never moves again; ``stucked`` is the crashed
  robot's self-loop, as in the package.
- ``Controller`` (the UAC): one move per estimated cell (xhat, yhat), from Dijkstra; a move
  that no cell plans still appears (never enabled), so that it is in the module's alphabet.
- ``Knowledge``: the estimate, updated as if every move succeeded, and the move counter
  ``step`` (1 after a localisation); ``localise`` (step >= c) sets the estimate to the true
  position, ``skip`` (step < c) counts on. With ``loc_error`` > 0 the localisation errs
  (:func:`parley_plugins.localisation.localise_commands`): one ``localise`` command per border situation of the true
  position, each with the exact update and one per in-map neighbor.
- ``Turn``: move, check, then localise or skip: one robot move is three DTMC steps.

Rewards "cost": ``move_cost`` per move, ``localisation_cost`` per localisation.
"""

from __future__ import annotations

from parley_core.prism.writer import (
    Command,
    Constant,
    Formula,
    Label,
    Module,
    Program,
    RewardItem,
    Rewards,
    Update,
    Variable,
    conjunction,
    disjunction,
)
from parley_plugins.localisation import localise_commands
from parley_plugins.robot_grid.grid import Grid
from parley_plugins.robot_grid.planner import MOVES

MOVES_ORDER = {move: i for i, move in enumerate(MOVES)}

# For each intended move, the outcome of each actual direction, in the package's order.
_OUTCOMES = {
    "east": ("x", "min(x+1, W)"),
    "north": ("y", "min(y+1, H)"),
    "south": ("y", "max(y-1, 0)"),
    "west": ("x", "max(x-1, 0)"),
}
_ESTIMATE = {
    "west": ("xhat", "max(xhat-1, 0)"),
    "east": ("xhat", "min(xhat+1, W)"),
    "south": ("yhat", "max(yhat-1, 0)"),
    "north": ("yhat", "min(yhat+1, H)"),
}


def prism_model(
    grid: Grid,
    moves: dict[tuple[int, int], str],
    *,
    p: float,
    max_interval: int,
    move_cost: float,
    localisation_cost: float,
    loc_error: float = 0.0,
) -> str:
    """The DTMC text for ``grid`` with the movement controller ``moves``; with ``loc_error``
    > 0 the localisation errs (:func:`parley_plugins.localisation.localise_commands`), and ``moves`` must then have a
    move for every cell but the target (:func:`~parley_plugins.robot_grid.planner.complete`).
    With ``loc_error`` = 0 the text is exactly the one without the option."""
    unplanned = [cell for cell in grid.cells() if cell not in moves and cell != grid.target]
    if loc_error > 0 and unplanned:
        raise ValueError(f"an erring localisation may put the estimate on {unplanned[0]}, which has no move")
    x_target, y_target = grid.target
    crash = disjunction(f"x={x} & {_one_of('y', ys)}" for x, ys in _by_column(grid.obstacles()).items())

    robot_commands = [
        Command(
            action=move,
            updates=[
                Update(assignments=[_OUTCOMES[direction]], probability="1-3*p" if direction == move else "p")
                for direction in ("east", "north", "south", "west")
            ],
        )
        for move in MOVES
    ]
    robot_commands += [
        Command(action="check", guard="hasCrashed", updates=[Update(assignments={"crashed": "1"})]),
        Command(action="check", guard="!hasCrashed", updates=[Update()]),
        Command(action="stucked", guard="crashed=1", updates=[Update()]),
    ]
    robot = Module(
        name="Robot",
        variables=[
            Variable(name="x", low=0, high="W", init=grid.start[0]),
            Variable(name="y", low=0, high="H", init=grid.start[1]),
            Variable(name="crashed", low=0, high=1, init=0),
        ],
        commands=robot_commands,
    )
    # One command per move and column (a guard that fails fast on xhat: Storm evaluates every
    # guard in every state). Every move must be in the Controller's alphabet, or PRISM would
    # let an unused one happen anywhere: a move no cell plans gets a command never enabled.
    columns = _by_column(
        sorted(moves, key=lambda cell: (MOVES_ORDER[moves[cell]], cell)), key=lambda cell: (moves[cell], cell[0])
    )
    controller = Module(
        name="Controller",
        commands=[
            *(
                Command(action=move, guard=f"xhat={x} & {_one_of('yhat', ys)} & crashed=0")
                for (move, x), ys in columns.items()
            ),
            *(Command(action=move, guard="false") for move in MOVES if move not in moves.values()),
        ],
    )
    knowledge = Module(
        name="Knowledge",
        variables=[
            Variable(name="xhat", low=0, high="W", init=grid.start[0], comment="estimated position"),
            Variable(name="yhat", low=0, high="H", init=grid.start[1]),
            Variable(name="step", low=1, high="maxStep", init=1, comment="moves since the last localisation"),
        ],
        commands=[
            *(Command(action=move, updates=[Update(assignments=[_ESTIMATE[move]])]) for move in MOVES),
            *localise_commands(loc_error, x_high="W", y_high="H", wide=grid.width > 2, tall=grid.height > 2),
            Command(action="skip", guard="step<c", updates=[Update(assignments={"step": "step+1"})]),
        ],
    )
    turn = Module(
        name="Turn",
        variables=[Variable(name="t", low=0, high=2, init=0, comment="0 move, 1 check, 2 localise or skip")],
        commands=[
            *(Command(action=move, guard="t=0", updates=[Update(assignments={"t": "1"})]) for move in MOVES),
            Command(action="check", guard="t=1", updates=[Update(assignments={"t": "2"})]),
            Command(action="localise", guard="t=2", updates=[Update(assignments={"t": "0"})]),
            Command(action="skip", guard="t=2", updates=[Update(assignments={"t": "0"})]),
        ],
    )
    program = Program(
        header=(
            f"robot_grid: {grid.width}x{grid.height} map {grid.source}; start {grid.start}, target {grid.target}.\n"
            "The localisation service runs once the move counter reaches c (every c-th move)."
            + (_ERRING if loc_error > 0 else "")
        ),
        constants=[
            Constant(name="W", value=grid.width - 1, comment="largest x"),
            Constant(name="H", value=grid.height - 1, comment="largest y"),
            Constant(name="p", type="double", value=p, comment="probability of deviating to each other direction"),
            *([_loc_error_constant(loc_error)] if loc_error > 0 else []),
            Constant(name="maxStep", value=max_interval),
            Constant(name="c", comment=f"localisation interval in moves, 1..{max_interval}"),
        ],
        formulas=[Formula(name="hasCrashed", expression=crash)],
        # Turn first: Storm tries the modules of an action in this order and stops at the
        # first without an enabled command, and Turn disables two actions in three in every
        # state (the builder takes half the time; the DTMC is the same).
        modules=[turn, robot, controller, knowledge],
        rewards=[
            Rewards(
                name="cost",
                items=[
                    *(RewardItem(action=move, value=move_cost) for move in MOVES),
                    RewardItem(action="localise", value=localisation_cost),
                ],
            )
        ],
        labels=[
            Label(name="goal", expression=conjunction([f"x={x_target}", f"y={y_target}", "crashed=0"])),
            Label(name="crashed", expression="crashed=1"),
        ],
    )
    return program.render()


_ERRING = (
    "\nWith probability loc_error it puts the estimate on one of the true cell's in-map 4-neighbors"
    " (equally likely) instead."
)


def _loc_error_constant(loc_error: float) -> Constant:
    return Constant(
        name="loc_error",
        type="double",
        value=loc_error,
        comment="probability that a localisation puts the estimate on a neighbor of the true cell",
    )


def _by_column(cells, key=lambda cell: cell[0]) -> dict:
    """y values of ``cells`` grouped by ``key`` (default: the column x), in order."""
    groups: dict = {}
    for cell in cells:
        groups.setdefault(key(cell), []).append(cell[1])
    return groups


def _one_of(variable: str, values: list[int]) -> str:
    return f"{variable}={values[0]}" if len(values) == 1 else "(" + " | ".join(f"{variable}={v}" for v in values) + ")"
