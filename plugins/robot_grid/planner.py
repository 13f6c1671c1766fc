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

from parley_plugins import localisation
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
    """``moves`` and a move for every other cell but the target, for a localisation that may
    err (:func:`parley_plugins.localisation.complete`; moves tried west, east, south, north)."""
    return localisation.complete(moves, grid.width, grid.height, grid.target, MOVES)
