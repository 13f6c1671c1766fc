"""Maps: the package's CSV orientation, checks, and generation from size and seed."""

from __future__ import annotations

import pytest

from parley_core.errors import OptionError
from parley_plugins.robot_grid import grid as grids


def test_csv_rows_are_north_first_and_columns_are_x(tmp_path):
    path = tmp_path / "m.csv"
    path.write_text("0,0,0\n10,0,3\n0,0,0\n")
    grid = grids.load_csv(path)
    assert (grid.width, grid.height) == (3, 3)
    assert grid.obstacles() == [(0, 1)]
    assert grid.weights[2][1] == 3
    assert grid.to_csv() == "0,0,0\n10,0,3\n0,0,0\n"


def test_rectangular_maps(tmp_path):
    path = tmp_path / "m.csv"
    path.write_text("0,0,0,0\n0,0,0,0\n")
    grid = grids.load_csv(path)
    assert (grid.width, grid.height, grid.target) == (4, 2, (3, 1))


def test_generation_is_reproducible_and_follows_the_package():
    first = grids.generate(10, 5)
    assert first == grids.generate(10, 5)
    assert first != grids.generate(10, 6)
    assert all(not first.is_obstacle(x, 0) for x in range(10)), "the start row is free"
    assert grids.has_path(first)
    raw = [[v % 10 if v < 10 else v for v in col] for col in first.weights]
    for x, y in first.cells():
        neighbors = sum(
            first.is_obstacle(nx, ny)
            for nx, ny in ((x - 1, y), (x + 1, y), (x, y - 1), (x, y + 1))
            if 0 <= nx < 10 and 0 <= ny < 10
        )
        # weight = 10 * floor(|z|) for obstacles, plus 3 per neighboring obstacle
        assert first.weights[x][y] - 3 * neighbors in (0, 10, 20, 30, 40, 50), (x, y, raw[x][y])


def test_no_path_is_reported(tmp_path):
    path = tmp_path / "m.csv"
    path.write_text("0,0,0\n10,10,10\n0,0,0\n")
    with pytest.raises(OptionError, match="no obstacle-free path"):
        grids.load_csv(path)
