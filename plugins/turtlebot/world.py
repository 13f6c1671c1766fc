"""The turtlebot's world: a square of cells, obstacles, start, target, and its motion table.

Headings are numbered as in the paper's package: 0 north, 1 east, 2 south, 3 west; a move
command is named after the heading it drives to. The motion table gives, for the robot's
true cell and true heading and a commanded move, the distribution of outcomes: the cell it
ends in (one of the nine cells around it) with its new heading, a crash into an obstacle,
or leaving the area.
"""

from __future__ import annotations

import math
from collections import deque
from collections.abc import Mapping

import numpy as np
from attrs import field, frozen

from parley_core import OptionError
from parley_plugins import localisation

HEADINGS = ("north", "east", "south", "west")
"""Heading names by number, and the move commands' names."""

STEP = {"north": (0, 1), "east": (1, 0), "south": (0, -1), "west": (-1, 0)}

ANGLE = {"north": math.pi / 2, "east": 0.0, "south": -math.pi / 2, "west": math.pi}
"""The yaw of each heading in radians (x east, y north, counter-clockwise)."""


def heading_of(yaw: np.ndarray) -> np.ndarray:
    """The nearest of the four headings (their numbers) of yaws in radians."""
    return np.rint((math.pi / 2 - yaw) / (math.pi / 2)).astype(int) % 4


Cell = tuple[int, int]


@frozen
class Outcome:
    """Where a move ends: ``"move"`` to the cell ``(x+dx, y+dy)`` with ``heading``, ``"crash"`` or ``"out"``."""

    kind: str
    dx: int = 0
    dy: int = 0
    heading: int = 0


CRASH = Outcome("crash")
OUT = Outcome("out")


def decode(code: int) -> Outcome:
    """The outcome of a Monte Carlo code: -2 crash, -1 out, else ``((dx + 2) * 5 + dy + 2) * 4
    + heading`` (the simulators classify their draws so, to count them with numpy)."""
    if code == -2:
        return CRASH
    if code == -1:
        return OUT
    place, heading = divmod(code, 4)
    return Outcome("move", place // 5 - 2, place % 5 - 2, heading)


Key = tuple[int, int, int, str]
"""(x, y, true heading, commanded move)."""

Motions = Mapping[Key, tuple[tuple[Outcome, float], ...]]

MemoryKey = tuple[int, int, int, str, int]
"""(x, y, *believed* heading, commanded move, moves since the last localisation)."""

Remembered = Mapping[MemoryKey, tuple[tuple[Outcome, float], ...]]


@frozen(kw_only=True)
class World:
    """``size`` x ``size`` cells; ``plan`` is the movement controller: a move per estimated cell."""

    size: int
    start: Cell
    target: Cell
    obstacles: frozenset[Cell] = field(converter=frozenset)
    motions: Motions = field(repr=False)
    plan: Mapping[Cell, str] = field(repr=False)
    source: str = "generated"
    remembered: Remembered | None = field(default=None, repr=False)
    """With heading memory (MuJoCo motions, ``heading_memory=true``): the motions by true
    cell, *believed* heading, move and the moves since the last localisation, over which
    the weak wheel's heading error accumulates; ``motions`` is then empty."""


def shortest_moves(size: int, obstacles: frozenset[Cell], target: Cell) -> dict[Cell, str]:
    """The movement controller: for every free cell that can reach ``target``, the first move of a
    shortest path (breadth-first from the target; ties go to north, east, south, west in that order)."""
    distance = {target: 0}
    queue = deque([target])
    while queue:
        x, y = queue.popleft()
        for dx, dy in STEP.values():
            cell = (x + dx, y + dy)
            if 0 <= cell[0] < size and 0 <= cell[1] < size and cell not in obstacles and cell not in distance:
                distance[cell] = distance[(x, y)] + 1
                queue.append(cell)
    plan: dict[Cell, str] = {}
    for (x, y), d in sorted(distance.items()):
        if d == 0:
            continue
        plan[(x, y)] = next(m for m in HEADINGS if distance.get((x + STEP[m][0], y + STEP[m][1])) == d - 1)
    return plan


def complete(plan: Mapping[Cell, str], size: int, target: Cell) -> dict[Cell, str]:
    """``plan`` and a move for every other cell of the square but the target, for a
    localisation that may err (:func:`parley_plugins.localisation.complete`; moves tried in
    the order of ``HEADINGS``)."""
    return localisation.complete(plan, size, size, target, {m: STEP[m] for m in HEADINGS})


def parse_cells(text: str, what: str) -> frozenset[Cell]:
    """``"1:2,2:2"`` -> {(1, 2), (2, 2)}; an empty text is no cells."""
    cells = set()
    for item in filter(None, (part.strip() for part in text.split(","))):
        x, sep, y = item.partition(":")
        try:
            if not sep:
                raise ValueError
            cells.add((int(x), int(y)))
        except ValueError:
            raise OptionError(
                f"{what}: {item!r} is not a cell; write cells as X:Y separated by commas, e.g. 1:2,2:2"
            ) from None
    return frozenset(cells)


def check(world: World) -> World:
    """Raise OptionError unless the cells are in the square, start and target are free, and a
    path of free cells joins them; every move of the motion table must end inside the square."""
    for name, cell in (("start", world.start), ("target", world.target)):
        if not (0 <= cell[0] < world.size and 0 <= cell[1] < world.size):
            raise OptionError(
                f"the {name} cell {cell} is outside the {world.size}x{world.size} square; give a cell in 0..{world.size - 1}"
            )
        if cell in world.obstacles:
            raise OptionError(f"the {name} cell {cell} is an obstacle; remove it from the obstacles")
    if world.start == world.target:
        raise OptionError(f"start and target are the same cell {world.start}; give two different cells")
    outside = sorted(c for c in world.obstacles if not (0 <= c[0] < world.size and 0 <= c[1] < world.size))
    if outside:
        raise OptionError(
            f"obstacle {outside[0]} is outside the {world.size}x{world.size} square; give cells in 0..{world.size - 1}"
        )
    if world.start not in shortest_moves(world.size, world.obstacles, world.target):
        raise OptionError(
            f"no obstacle-free path joins the start {world.start} and the target {world.target}; move or remove obstacles"
        )
    tables = [world.motions.items(), (world.remembered or {}).items()]
    for (x, y, _heading, move, *_), outcomes in (entry for table in tables for entry in table):
        for outcome, _ in outcomes:
            nx, ny = x + outcome.dx, y + outcome.dy
            if outcome.kind == "move" and not (0 <= nx < world.size and 0 <= ny < world.size):
                raise OptionError(f"{world.source}: the move {move} from ({x},{y}) ends outside the square")
    return world
