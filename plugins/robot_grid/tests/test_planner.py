"""The movement controller: Dijkstra from the target with the package's tie breaking.

The expected moves were derived by hand, following the package's algorithm: a heap of
(distance, (x, y)), neighbors relaxed west, east, south, north, strict improvement only.
"""

from __future__ import annotations

from parley_plugins.robot_grid.grid import from_rows
from parley_plugins.robot_grid.planner import plan


def test_free_map_ties_are_broken_like_the_package():
    grid = from_rows([[0, 0, 0], [0, 0, 0], [0, 0, 0]], source="test")
    assert plan(grid) == {
        (1, 2): "east",
        (2, 1): "north",
        (0, 2): "east",
        (1, 1): "north",
        (0, 1): "north",
        (0, 0): "north",
        (1, 0): "west",
        (2, 0): "west",
    }


def test_obstacles_and_the_target_get_no_move():
    grid = from_rows([[0, 0, 0], [0, 10, 0], [0, 0, 0]], source="test")
    assert plan(grid) == {
        (1, 2): "east",
        (2, 1): "north",
        (0, 2): "east",
        (0, 1): "north",
        (0, 0): "north",
        (1, 0): "west",
        (2, 0): "west",
    }


def test_penalties_steer_the_path():
    # A penalty of 3 on (0, 1) makes the start go east along the free bottom row instead.
    grid = from_rows([[0, 0, 0], [3, 0, 0], [0, 0, 0]], source="test")
    moves = plan(grid)
    assert moves[(0, 0)] == "east"
    assert moves[(1, 0)] == "north"
