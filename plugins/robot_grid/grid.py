"""Grid maps in the replication package's CSV format, loaded from a file or generated.

A CSV map has one row per line, top row first (northmost), one column per x; each cell is a
weight: 0 free, 3/6/9... a penalty for cells next to obstacles, >= 10 an obstacle. Internally
``weights[x][y]`` has y growing northwards, as in the package's ``build_map`` (the CSV
transposed and each row reversed). The robot starts at (0, 0) and its target is the opposite
corner.
"""

from __future__ import annotations

import csv
import io
from collections import deque
from pathlib import Path

import numpy as np
from attrs import field, frozen

from parley_core import OptionError, read_text

OBSTACLE = 10
"""Cells weighing this much or more are obstacles."""

PENALTY = 3
"""Added to a cell's weight for each obstacle among its four neighbors."""


@frozen(kw_only=True)
class Grid:
    """A map: ``weights[x][y]``, y northwards; start (0, 0), target (width-1, height-1)."""

    weights: tuple[tuple[int, ...], ...] = field(converter=lambda w: tuple(tuple(int(v) for v in col) for col in w))
    source: str = "generated"

    @property
    def width(self) -> int:
        return len(self.weights)

    @property
    def height(self) -> int:
        return len(self.weights[0])

    @property
    def start(self) -> tuple[int, int]:
        return (0, 0)

    @property
    def target(self) -> tuple[int, int]:
        return (self.width - 1, self.height - 1)

    def is_obstacle(self, x: int, y: int) -> bool:
        return self.weights[x][y] >= OBSTACLE

    def obstacles(self) -> list[tuple[int, int]]:
        return [(x, y) for x in range(self.width) for y in range(self.height) if self.is_obstacle(x, y)]

    def cells(self) -> list[tuple[int, int]]:
        return [(x, y) for x in range(self.width) for y in range(self.height)]

    def to_csv(self) -> str:
        """The map in the package's CSV format (top row first)."""
        out = io.StringIO()
        writer = csv.writer(out, lineterminator="\n")
        for y in reversed(range(self.height)):
            writer.writerow([self.weights[x][y] for x in range(self.width)])
        return out.getvalue()


def from_rows(rows: list[list[int]], source: str) -> Grid:
    """A grid from CSV rows (top row first, one column per x)."""
    height = len(rows)
    width = len(rows[0])
    return Grid(weights=[[rows[height - 1 - y][x] for y in range(height)] for x in range(width)], source=source)


def load_csv(path: Path) -> Grid:
    """Read and check a CSV map; every problem is an OptionError saying what to fix."""
    text = read_text(path, "map file", "give the path of a CSV map (map=FILE)", OptionError)
    rows: list[list[int]] = []
    for number, row in enumerate(csv.reader(io.StringIO(text)), start=1):
        cells = [cell.strip() for cell in row]
        if not any(cells):
            continue
        try:
            values = [int(cell) for cell in cells]
        except ValueError:
            raise OptionError(
                f"map file {path}, line {number}: {','.join(cells)!r} is not a list of integer weights; "
                "write one comma-separated row of integers per line"
            ) from None
        if any(v < 0 for v in values):
            raise OptionError(f"map file {path}, line {number}: weights must not be negative")
        rows.append(values)
    if not rows:
        raise OptionError(f"map file {path} is empty; write one comma-separated row of weights per line")
    widths = {len(r) for r in rows}
    if len(widths) != 1:
        raise OptionError(
            f"map file {path}: rows have different lengths {sorted(widths)}; give every row the same number of cells"
        )
    if len(rows) < 2 or len(rows[0]) < 2:
        raise OptionError(f"map file {path}: the map must be at least 2x2")
    return check(from_rows(rows, source=str(path)))


def check(grid: Grid) -> Grid:
    """Raise OptionError unless start and target are free and joined by a path of free cells."""
    for name, (x, y) in (("start", grid.start), ("target", grid.target)):
        if grid.is_obstacle(x, y):
            raise OptionError(
                f"map {grid.source}: the {name} cell ({x},{y}) is an obstacle; free it (weight < {OBSTACLE})"
            )
    if not has_path(grid):
        raise OptionError(
            f"map {grid.source} has no obstacle-free path from the start {grid.start} to the target {grid.target}; "
            "use a map where the robot can reach its target"
        )
    return grid


def has_path(grid: Grid) -> bool:
    """Breadth-first search over non-obstacle cells from start to target."""
    seen = {grid.start}
    queue = deque([grid.start])
    while queue:
        x, y = queue.popleft()
        if (x, y) == grid.target:
            return True
        for nx, ny in ((x - 1, y), (x + 1, y), (x, y - 1), (x, y + 1)):
            if 0 <= nx < grid.width and 0 <= ny < grid.height and (nx, ny) not in seen and not grid.is_obstacle(nx, ny):
                seen.add((nx, ny))
                queue.append((nx, ny))
    return False


def generate(size: int, seed: int, *, attempts: int = 10_000) -> Grid:
    """A random ``size`` x ``size`` map as the paper describes, reproducible from ``seed``.

    Each cell draws z from a standard normal; |z| >= 1 (outside one sigma) makes an obstacle
    of weight 10 * floor(|z|). As in the package's published maps, the start row (y = 0) is
    kept free, and maps are drawn until free cells join start and target. Then every cell
    gets +3 per obstacle among its four neighbors.
    """
    rng = np.random.default_rng(seed)
    for _ in range(attempts):
        z = rng.standard_normal((size, size))  # [x][y]
        raw = (np.abs(z).astype(int) * 10).tolist()
        for x in range(size):
            raw[x][0] = 0
        grid = Grid(weights=raw, source=f"generated(size={size}, seed={seed})")
        if not grid.is_obstacle(*grid.target) and has_path(grid):
            return add_penalties(grid)
    raise OptionError(f"no map of size {size} with a path found after {attempts} draws; try another seed")


def add_penalties(grid: Grid) -> Grid:
    """+3 per obstacle among each cell's four neighbors (obstacles included)."""
    weights = [list(col) for col in grid.weights]
    for x, y in grid.cells():
        for nx, ny in ((x - 1, y), (x + 1, y), (x, y - 1), (x, y + 1)):
            if 0 <= nx < grid.width and 0 <= ny < grid.height and grid.weights[nx][ny] != 0:
                weights[x][y] += PENALTY
    return Grid(weights=weights, source=grid.source)
