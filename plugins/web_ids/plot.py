"""policy.png: the selected policy's scan thresholds, per cost level and state of the IDS's rules."""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path

from matplotlib import colormaps
from matplotlib.cm import ScalarMappable
from matplotlib.colors import Normalize
from matplotlib.patches import Rectangle

from parley_core import figure, save
from parley_plugins.web_ids.generator import LEVELS, MAX_THRESHOLD, RESTORE_A

RULES = {1: "fresh rules", 0: "stale rules"}


def label(threshold: int) -> str:
    if threshold <= 0:
        return "always"
    if threshold >= MAX_THRESHOLD:
        return "never"
    return f"ahat ≥ {threshold}"


def draw_policy(thresholds: Mapping[tuple[int, int], int], path: Path) -> None:
    """``thresholds`` maps (level, fresh) to the scan threshold."""
    fig, ax = figure(6.4, 2.8)
    norm = Normalize(vmin=0, vmax=MAX_THRESHOLD)
    cmap = colormaps["viridis"]
    for column, _name in enumerate(LEVELS):
        for row, fresh in enumerate(RULES):
            value = thresholds.get((column, fresh))
            if value is None:
                continue
            ax.add_patch(Rectangle((column - 0.5, row - 0.5), 1, 1, color=cmap(norm(value)), alpha=0.6))
            ax.text(column, row, label(value), ha="center", va="center", fontsize=11, weight="bold")
    ax.set_xlim(-0.5, len(LEVELS) - 0.5)
    ax.set_ylim(len(RULES) - 0.5, -0.5)
    ax.set_xticks(range(len(LEVELS)), [f"{n}\n(restore A: {c:g})" for n, c in zip(LEVELS, RESTORE_A)])
    ax.set_yticks(range(len(RULES)), list(RULES.values()))
    ax.set_title("scan A when the IDS's estimate ahat reaches the threshold", fontsize=10)
    fig.colorbar(ScalarMappable(norm=norm, cmap=cmap), ax=ax, fraction=0.046, pad=0.04, label="threshold")
    save(fig, path, dpi=130)
