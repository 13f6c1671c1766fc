"""An erring localisation on a grid of cells, shared by robot_grid and turtlebot (``loc_error``).

With probability ``loc_error`` a localisation puts the estimated cell on one of the true
cell's 4-neighbors inside the map (equally likely) instead of the true cell. Both robots'
PRISM models write it with :func:`localise_commands`, and both controllers get a move for
every cell a wrong estimate can reach with :func:`complete`.
"""

from __future__ import annotations

from collections import deque
from collections.abc import Mapping

from parley_core.prism.writer import Command, Update

NEIGHBORS = {
    "east": {"xhat": "x+1", "yhat": "y"},
    "north": {"xhat": "x", "yhat": "y+1"},
    "south": {"xhat": "x", "yhat": "y-1"},
    "west": {"xhat": "x-1", "yhat": "y"},
}
"""The neighbors a localisation may err to, in this order, and where each puts the estimate."""


def localise_commands(
    loc_error: float, *, x_high: str, y_high: str, wide: bool, tall: bool, also: Mapping[str, str] | None = None
) -> list[Command]:
    """The ``localise`` commands of the Knowledge module (all guarded by ``step>=c``).

    Exact (``loc_error`` = 0): one command, the estimate := the true position, as always.
    Erring: the estimate goes to the true cell with probability 1 - loc_error and to each
    of the true cell's 4-neighbors inside the map with loc_error / (their number): 4
    inside, 3 on a border, 2 in a corner. The neighbors are written as ``x+1``, ``y-1``...
    in one command per border situation of the true position (``x=0``, ``x>0 & x<W``,
    ``x=W`` times the same for y, with ``x_high``/``y_high`` the largest coordinates'
    constants; without the middle one when the map is 2 wide or tall, ``wide``/``tall``),
    so that no update is clamped at a border: a clamped ``min(x+1, W)`` would put the east
    neighbor's share on the true cell. Obstacle cells are neighbors like any other (the
    controller has a move for them, :func:`complete`); a crashed robot's localisation errs
    too, which changes nothing it does. The guards are disjoint, so exactly one command is
    enabled, and the action names stay the same. ``also``: assignments every update makes
    besides the estimate (turtlebot's estimated heading := the true one), before ``step``.
    """
    extra = dict(also or {})

    def localised(position: Mapping[str, str], probability: str | None = None) -> Update:
        return Update(assignments={**position, **extra, "step": "1"}, probability=probability)

    if loc_error == 0:
        return [Command(action="localise", guard="step>=c", updates=[localised({"xhat": "x", "yhat": "y"})])]
    middle_x, middle_y = f"x>0 & x<{x_high}", f"y>0 & y<{y_high}"
    columns = [("x=0", ["east"]), *([(middle_x, ["east", "west"])] if wide else []), (f"x={x_high}", ["west"])]
    rows = [("y=0", ["north"]), *([(middle_y, ["north", "south"])] if tall else []), (f"y={y_high}", ["south"])]
    commands = []
    for column, east_west in columns:
        for row, north_south in rows:
            neighbors = [n for n in NEIGHBORS if n in east_west or n in north_south]
            updates = [localised({"xhat": "x", "yhat": "y"}, "1-loc_error")] if loc_error < 1 else []
            updates += [localised(NEIGHBORS[n], f"loc_error/{len(neighbors)}") for n in neighbors]
            commands.append(Command(action="localise", guard=f"step>=c & {column} & {row}", updates=updates))
    return commands


Cell = tuple[int, int]


def complete(
    moves: Mapping[Cell, str], width: int, height: int, target: Cell, steps: Mapping[str, tuple[int, int]]
) -> dict[Cell, str]:
    """``moves`` and a move for every other cell of the map but the target: the controller of
    a robot whose localisation may put its estimate on any cell (``loc_error`` > 0).

    The plan has no move for obstacles and for cells cut off from the target, and without
    localisation errors the estimate of a robot that has not crashed is never there; a wrong
    localisation can put it on an obstacle next to the robot, and without a move the DTMC
    would deadlock. Such a cell gets the first move (in the order of ``steps``, move name ->
    (dx, dy)) to a neighbor one step nearer (breadth-first, through any cells) to the
    nearest cell with a planned move or the target, so that following the moves always
    leads the estimate to the target. The neighbors of a localisation's error stay purely
    geometric so (erring only to cells with a planned move would make them depend on the
    plan, and leave a cell whose other neighbors are obstacles, the border or the target
    without any). The target keeps no move: an estimate there stops the robot, as a drifted
    robot that believes it has arrived stops today.
    """
    known = set(moves) | {target}
    distance = {cell: 0 for cell in known}
    queue = deque(sorted(known))
    while queue:
        x, y = queue.popleft()
        for dx, dy in steps.values():
            cell = (x + dx, y + dy)
            if 0 <= cell[0] < width and 0 <= cell[1] < height and cell not in distance:
                distance[cell] = distance[(x, y)] + 1
                queue.append(cell)
    completed = dict(moves)
    for (x, y), d in sorted(distance.items()):
        if (x, y) not in known:
            completed[(x, y)] = next(
                name for name, (dx, dy) in steps.items() if distance.get((x + dx, y + dy)) == d - 1
            )
    return completed
