"""policy.png: the chosen localisation intervals drawn on the map (as the paper's Fig. 3b)."""

from __future__ import annotations

from pathlib import Path

from matplotlib import colormaps
from matplotlib.cm import ScalarMappable
from matplotlib.colors import Normalize
from matplotlib.patches import Rectangle

from parley_core.plotting import figure, save
from parley_plugins.robot_grid.grid import Grid
from parley_plugins.robot_grid.planner import MOVES


def draw_policy(
    grid: Grid, moves: dict[tuple[int, int], str], intervals: dict[tuple[int, int], int], path: Path
) -> None:
    size = max(4.0, 0.55 * max(grid.width, grid.height))
    fig, ax = figure(size * grid.width / max(grid.width, grid.height) + 1.2, size)
    shown = [v for v in intervals.values()]
    norm = Normalize(vmin=min(shown, default=1), vmax=max(max(shown, default=1), min(shown, default=1) + 1))
    cmap = colormaps["viridis_r"]
    label_size = max(5, min(11, int(110 / max(grid.width, grid.height))))
    for x, y in grid.cells():
        if grid.is_obstacle(x, y):
            ax.add_patch(Rectangle((x - 0.5, y - 0.5), 1, 1, color="0.15"))
            continue
        value = intervals.get((x, y))
        if value is not None:
            ax.add_patch(Rectangle((x - 0.5, y - 0.5), 1, 1, color=cmap(norm(value)), alpha=0.55))
            ax.text(x, y + 0.18, str(value), ha="center", va="center", fontsize=label_size, weight="bold")
        if grid.weights[x][y] > 0:
            ax.add_patch(Rectangle((x - 0.5, y - 0.5), 1, 1, fill=False, hatch="..", edgecolor="0.6", lw=0))
        if (x, y) in moves:
            dx, dy = MOVES[moves[(x, y)]]
            ax.annotate(
                "",
                xy=(x + 0.3 * dx, y - 0.22 + 0.3 * dy),
                xytext=(x - 0.3 * dx, y - 0.22 - 0.3 * dy),
                arrowprops={"arrowstyle": "->", "color": "firebrick", "lw": 1.0},
            )
    for (x, y), mark in ((grid.start, "S"), (grid.target, "T")):
        ax.add_patch(Rectangle((x - 0.5, y - 0.5), 1, 1, fill=False, edgecolor="crimson", lw=2))
        ax.text(x - 0.33, y - 0.33, mark, color="crimson", fontsize=label_size, weight="bold", ha="center", va="center")
    ax.set_xlim(-0.5, grid.width - 0.5)
    ax.set_ylim(-0.5, grid.height - 0.5)
    ax.set_aspect("equal")
    ax.set_xticks(range(grid.width))
    ax.set_yticks(range(grid.height))
    ax.set_xlabel("x (estimated)")
    ax.set_ylabel("y (estimated)")
    ax.set_title("localise after every k-th move (k per estimated cell)", fontsize=10)
    ax.set_xticks([i - 0.5 for i in range(grid.width + 1)], minor=True)
    ax.set_yticks([i - 0.5 for i in range(grid.height + 1)], minor=True)
    ax.grid(which="minor", color="0.8", lw=0.5)
    ax.tick_params(which="minor", length=0)
    fig.colorbar(ScalarMappable(norm=norm, cmap=cmap), ax=ax, fraction=0.046, pad=0.04, label="interval k")
    save(fig, path, dpi=130)
