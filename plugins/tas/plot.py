"""policy.png: the probing interval per estimated backup level (columns) and load phase (rows)."""

from __future__ import annotations

from pathlib import Path

from matplotlib import colormaps
from matplotlib.colors import Normalize
from matplotlib.patches import Rectangle

from parley_core import figure, save
from parley_plugins.tas.generator import Scenario


def draw_policy(s: Scenario, intervals: dict[tuple[int, int], int], path: Path) -> None:
    """``intervals`` maps (bhat, load) to the policy's c; c = max_interval+1 is drawn as "never"."""
    levels = len(s.backup_levels)
    never = s.max_interval + 1
    fig, ax = figure(1.6 + 1.3 * levels, 2.8)
    cmap = colormaps["viridis_r"]
    norm = Normalize(vmin=1, vmax=never)
    for (level, load), value in intervals.items():
        ax.add_patch(Rectangle((level - 0.5, load - 0.5), 1, 1, color=cmap(norm(value)), alpha=0.6))
        ax.text(
            level, load, "never" if value >= never else str(value), ha="center", va="center", fontsize=11, weight="bold"
        )
    ax.set_xlim(-0.5, levels - 0.5)
    ax.set_ylim(-0.5, 1.5)
    ax.set_xticks(range(levels))
    ax.set_xticklabels(
        [
            f"{level}\n(fails {rate:g}{'' if s.uses_backup(level) else ', use alt.'})"
            for level, rate in enumerate(s.backup_levels)
        ],
        fontsize=8,
    )
    ax.set_yticks([0, 1])
    ax.set_yticklabels(["normal", "peak"])
    ax.set_xlabel("estimated backup level (bhat)")
    ax.set_ylabel("load")
    ax.set_title("probe the backup every k-th execution", fontsize=10)
    save(fig, path, dpi=130)
