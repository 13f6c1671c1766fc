"""policy.png: the chosen localisation intervals drawn on the map (as the paper's Fig. 3b)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
from matplotlib import colormaps
from matplotlib.cm import ScalarMappable
from matplotlib.collections import PatchCollection
from matplotlib.colors import ListedColormap, Normalize
from matplotlib.patches import Rectangle

from parley_core import figure, save
from parley_plugins.robot_grid.grid import Grid
from parley_plugins.robot_grid.planner import MOVES

DETAILED = 30
"""Maps up to this many cells a side get each cell's interval written in it, the movement
plan's arrows, the hatching of weighted cells and a grid line around each cell; larger maps
are the intervals' image alone (a 100x100 map took 50 s drawn cell by cell)."""

LARGEST_FIGURE = 14.0
"""Inches: the figure grows with the map up to this size."""


def draw_policy(
    grid: Grid, moves: dict[tuple[int, int], str], intervals: dict[tuple[int, int], int], path: Path
) -> None:
    size = min(LARGEST_FIGURE, max(4.0, 0.55 * max(grid.width, grid.height)))
    fig, ax = figure(size * grid.width / max(grid.width, grid.height) + 1.2, size)
    shown = [v for v in intervals.values()]
    norm = Normalize(vmin=min(shown, default=1), vmax=max(max(shown, default=1), min(shown, default=1) + 1))
    cmap = colormaps["viridis_r"]
    detailed = max(grid.width, grid.height) <= DETAILED
    label_size = max(5, min(11, int(110 / max(grid.width, grid.height))))
    extent = (-0.5, grid.width - 0.5, -0.5, grid.height - 0.5)
    chosen = np.full((grid.height, grid.width), np.nan)
    blocked = np.zeros((grid.height, grid.width), dtype=bool)
    weighted, arrows = [], []
    for x, y in grid.cells():
        if grid.is_obstacle(x, y):
            blocked[y, x] = True
            continue
        value = intervals.get((x, y))
        if value is not None:
            chosen[y, x] = value
            if detailed:
                ax.text(x, y + 0.18, str(value), ha="center", va="center", fontsize=label_size, weight="bold")
        if detailed and grid.weights[x][y] > 0:
            weighted.append(Rectangle((x - 0.5, y - 0.5), 1, 1))
        if detailed and (x, y) in moves:
            arrows.append((x, y, *MOVES[moves[(x, y)]]))
    ax.imshow(np.ma.masked_invalid(chosen), origin="lower", extent=extent, cmap=cmap, norm=norm, alpha=0.55)
    ax.imshow(
        np.ma.masked_where(~blocked, blocked), origin="lower", extent=extent, cmap=ListedColormap(["0.15"]), vmin=0
    )
    if weighted:
        ax.add_collection(PatchCollection(weighted, facecolor="none", edgecolor="0.6", hatch="..", lw=0))
    if arrows:
        x, y, dx, dy = np.array(arrows, dtype=float).T
        ax.quiver(
            x - 0.3 * dx,
            y - 0.22 - 0.3 * dy,
            0.6 * dx,
            0.6 * dy,
            angles="xy",
            scale_units="xy",
            scale=1,
            color="firebrick",
            width=0.004,
        )
    for (x, y), mark in ((grid.start, "S"), (grid.target, "T")):
        ax.add_patch(Rectangle((x - 0.5, y - 0.5), 1, 1, fill=False, edgecolor="crimson", lw=2))
        ax.text(x - 0.33, y - 0.33, mark, color="crimson", fontsize=label_size, weight="bold", ha="center", va="center")
    ax.set_xlim(-0.5, grid.width - 0.5)
    ax.set_ylim(-0.5, grid.height - 0.5)
    ax.set_aspect("equal")
    step = 1 if detailed else max(1, round(max(grid.width, grid.height) / 10))
    ax.set_xticks(range(0, grid.width, step))
    ax.set_yticks(range(0, grid.height, step))
    ax.set_xlabel("x (estimated)")
    ax.set_ylabel("y (estimated)")
    ax.set_title("localise after every k-th move (k per estimated cell)", fontsize=10)
    if detailed:
        ax.set_xticks([i - 0.5 for i in range(grid.width + 1)], minor=True)
        ax.set_yticks([i - 0.5 for i in range(grid.height + 1)], minor=True)
        ax.grid(which="minor", color="0.8", lw=0.5)
        ax.tick_params(which="minor", length=0)
    fig.colorbar(ScalarMappable(norm=norm, cmap=cmap), ax=ax, fraction=0.046, pad=0.04, label="interval k")
    save(fig, path, dpi=130)
