"""policy.png: the chosen localisation periods per estimated cell and heading.

Each cell is split into four triangles, one per estimated heading (the triangle on the
cell's north side for heading north, and so on), colored and labeled by the period.
"""

from __future__ import annotations

from pathlib import Path

from matplotlib import colormaps
from matplotlib.cm import ScalarMappable
from matplotlib.colors import Normalize
from matplotlib.patches import Polygon, Rectangle

from parley_core import figure, save
from parley_plugins.turtlebot.world import STEP, World

# Triangle corners (relative to the cell center) and label offset, per heading number.
_TRIANGLES = {
    0: ([(-0.5, 0.5), (0.5, 0.5), (0, 0)], (0, 0.3)),
    1: ([(0.5, 0.5), (0.5, -0.5), (0, 0)], (0.3, 0)),
    2: ([(0.5, -0.5), (-0.5, -0.5), (0, 0)], (0, -0.3)),
    3: ([(-0.5, -0.5), (-0.5, 0.5), (0, 0)], (-0.3, 0)),
}


def draw_policy(world: World, periods: dict[tuple[int, int, int], int], path: Path) -> None:
    fig, ax = figure(7.2, 6.2)
    shown = list(periods.values())
    norm = Normalize(vmin=min(shown, default=1), vmax=max(max(shown, default=1), min(shown, default=1) + 1))
    cmap = colormaps["viridis_r"]
    for x in range(world.size):
        for y in range(world.size):
            if (x, y) in world.obstacles:
                ax.add_patch(Rectangle((x - 0.5, y - 0.5), 1, 1, color="0.15"))
                continue
            for heading, (corners, (lx, ly)) in _TRIANGLES.items():
                value = periods.get((x, y, heading))
                if value is None:
                    continue
                ax.add_patch(
                    Polygon(
                        [(x + cx, y + cy) for cx, cy in corners], color=cmap(norm(value)), alpha=0.6, lw=0.3, ec="white"
                    )
                )
                ax.text(x + lx, y + ly, str(value), ha="center", va="center", fontsize=7)
            move = world.plan.get((x, y))
            if move is not None:
                dx, dy = STEP[move]
                ax.annotate(
                    "",
                    xy=(x + 0.18 * dx, y + 0.18 * dy),
                    xytext=(x - 0.18 * dx, y - 0.18 * dy),
                    arrowprops={"arrowstyle": "->", "color": "firebrick", "lw": 1.2},
                )
    for (x, y), mark in ((world.start, "S"), (world.target, "T")):
        ax.add_patch(Rectangle((x - 0.5, y - 0.5), 1, 1, fill=False, edgecolor="crimson", lw=2))
        ax.text(x - 0.36, y - 0.36, mark, color="crimson", fontsize=10, weight="bold", ha="center", va="center")
    ax.set_xlim(-0.5, world.size - 0.5)
    ax.set_ylim(-0.5, world.size - 0.5)
    ax.set_aspect("equal")
    ax.set_xticks(range(world.size))
    ax.set_yticks(range(world.size))
    ax.set_xlabel("x (estimated cell)")
    ax.set_ylabel("y (estimated cell)")
    ax.set_title("localise after every k-th move (k per estimated cell and heading)", fontsize=10)
    fig.colorbar(ScalarMappable(norm=norm, cmap=cmap), ax=ax, fraction=0.046, pad=0.04, label="period k")
    save(fig, path, dpi=130)
