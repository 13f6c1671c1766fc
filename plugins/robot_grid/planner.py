"""The movement controller (the UAC): one move per cell, from Dijkstra's algorithm on the weights.

The search runs from the target outwards and computes, for every cell, the move towards the
neighbor it was reached from. Ties are broken exactly as the replication package breaks
them (its ``dijkstra.compute_directions``): a heap ordered by (distance, (x, y)), neighbors
relaxed in the order west, east, south, north of the popped cell, and only a strictly shorter
distance replaces a recorded one. Entering a cell costs its weight; obstacles cannot be
entered. Obstacles, the target and cells that cannot reach the target get no move.
"""

from __future__ import annotations

import heapq
import math
from collections import deque

from parley_plugins.robot_grid.grid import Grid

MOVES = {"west": (-1, 0), "east": (1, 0), "south": (0, -1), "north": (0, 1)}


def plan(grid: Grid) -> dict[tuple[int, int], str]:
    """The move ('west', 'east', 'south' or 'north') for every cell that has one."""
    inf = math.inf
    distance = {cell: inf for cell in grid.cells()}
    distance[grid.target] = 0
    moves: dict[tuple[int, int], str] = {}
    heap = [(0, grid.target)]
    while heap:
        _, (x, y) = heapq.heappop(heap)
        for nx, ny in ((x - 1, y), (x + 1, y), (x, y - 1), (x, y + 1)):
            if not (0 <= nx < grid.width and 0 <= ny < grid.height):
                continue
            weight = inf if grid.is_obstacle(nx, ny) else grid.weights[nx][ny]
            candidate = distance[(x, y)] + weight
            if candidate < distance[(nx, ny)]:
                distance[(nx, ny)] = candidate
                moves[(nx, ny)] = _direction(x - nx, y - ny)
                heapq.heappush(heap, (candidate, (nx, ny)))
    return moves


def _direction(dx: int, dy: int) -> str:
    for name, step in MOVES.items():
        if step == (dx, dy):
            return name
    raise ValueError((dx, dy))


def complete(grid: Grid, moves: dict[tuple[int, int], str]) -> dict[tuple[int, int], str]:
    """``moves`` and a move for every other cell but the target: the controller of a robot
    whose localisation may put its estimate on any cell (``loc_error`` > 0).

    Dijkstra plans no move for obstacles and for free cells cut off from the target, and
    without localisation errors the estimate of a robot that has not crashed is never
    there; a wrong localisation can put it on an obstacle next to the robot, and without a
    move the DTMC would deadlock. Such a cell gets the first move (in the order west, east,
    south, north) to a neighbor one step nearer (breadth-first, through any cells) to the
    nearest cell with a planned move or the target, so that following the moves always
    leads the estimate to the target. The neighbors of a localisation's error stay purely
    geometric so (erring only to cells with a planned move would make them depend on the
    plan, and leave a cell whose other neighbors are obstacles, the border or the target
    without any). The target keeps no move: an estimate there stops the robot, as a drifted
    robot that believes it has arrived stops today.
    """
    known = set(moves) | {grid.target}
    distance = {cell: 0 for cell in known}
    queue = deque(sorted(known))
    while queue:
        x, y = queue.popleft()
        for dx, dy in MOVES.values():
            cell = (x + dx, y + dy)
            if 0 <= cell[0] < grid.width and 0 <= cell[1] < grid.height and cell not in distance:
                distance[cell] = distance[(x, y)] + 1
                queue.append(cell)
    completed = dict(moves)
    for (x, y), d in sorted(distance.items()):
        if (x, y) not in known:
            completed[(x, y)] = next(
                name for name, (dx, dy) in MOVES.items() if distance.get((x + dx, y + dy)) == d - 1
            )
    return completed
