"""The front against the baseline (and the bound) as a matplotlib figure, from plain arrays:
the run directory's ``front.png`` (:mod:`parley_core.rundir.write`) and ``Run.plot()`` of the
:mod:`parley` library draw the same picture from the same numbers."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from matplotlib.figure import Figure

from parley_core.model import Direction, Objective
from parley_core.views.plotting import figure


def front_figure(
    *,
    title: str,
    objectives: Sequence[Objective],
    front: np.ndarray,
    baseline: np.ndarray,
    baseline_names: Sequence[str],
    selected: int,
    selected_name: str,
    reference: Sequence[float],
    bound: np.ndarray | None = None,
    scenarios: Sequence[tuple[str, np.ndarray]] = (),
) -> Figure:
    """``front`` and ``baseline``: one row of objective values per policy; ``selected``: the
    front row marked as the knee; ``bound``: a certified bound's points (the region it leaves
    open is shaded); ``scenarios``: a robust run's (label, front values in that scenario)."""
    fig, ax = figure(6.4, 4.6)
    front = np.asarray(front, dtype=float).reshape(-1, len(objectives))
    base = np.asarray(baseline, dtype=float).reshape(-1, len(objectives))
    if len(objectives) >= 2:
        i, j = (1, 0) if objectives[0].direction is Direction.MAX else (0, 1)
        third = next((k for k in range(len(objectives)) if k not in (i, j)), None)
        if third is None:
            ax.scatter(
                front[:, i],
                front[:, j],
                s=22,
                facecolors="none",
                edgecolors="tab:blue",
                label=f"parley front ({len(front)})",
            )
        else:  # a third objective as the points' colour; the others are named as left out
            shown = ax.scatter(
                front[:, i], front[:, j], s=22, c=front[:, third], cmap="viridis", label=f"parley front ({len(front)})"
            )
            fig.colorbar(shown, ax=ax, label=f"{objectives[third].name} ({objectives[third].direction.value})")
            ax.annotate(
                left_out(objectives, (i, j, third), bound),
                (0.0, -0.16),
                xycoords="axes fraction",
                fontsize=7,
                va="top",
            )
        ax.scatter(base[:, i], base[:, j], marker="x", color="tab:red", s=36, label=f"baseline ({len(base)})")
        # each scenario's values of the front's policies: the worst case is their lower envelope
        for label, each in scenarios:
            ax.scatter(each[:, i], each[:, j], s=5, alpha=0.5, label=f"front in {label}", zorder=1)
        chosen = front[selected]
        ax.scatter([chosen[i]], [chosen[j]], s=90, color="tab:blue", label=f"selected {selected_name} (knee)")
        if bound is not None and len(bound) and np.isfinite(bound).all():
            _shade_bound(ax, objectives, (i, j), np.asarray(bound, dtype=float), front, reference)
        for name, row in zip(baseline_names, base):
            ax.annotate(
                name.split("-")[-1],
                (row[i], row[j]),
                fontsize=7,
                color="tab:red",
                xytext=(3, -9),
                textcoords="offset points",
            )
        ax.set_xlabel(f"{objectives[i].name} ({objectives[i].direction.value})")
        ax.set_ylabel(f"{objectives[j].name} ({objectives[j].direction.value})")
    else:  # one objective: the values on a line, the front's best and the baselines
        ax.scatter(base[:, 0], np.zeros(len(base)), marker="x", color="tab:red", s=36, label=f"baseline ({len(base)})")
        ax.scatter(front[:, 0], np.zeros(len(front)), s=90, color="tab:blue", label="parley's best")
        ax.set_yticks([])
        ax.set_xlabel(f"{objectives[0].name} ({objectives[0].direction.value})")
    ax.set_title(title, fontsize=11)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    fig.tight_layout()
    return fig


def left_out(objectives: Sequence[Objective], shown: tuple[int, ...], bound: np.ndarray | None) -> str:
    """The note of a plot of three or more objectives: what it leaves out, and what the
    drawn bound is (its points projected onto the two axes; a single point is only the
    ideal point, sound for each objective alone)."""
    left = [o.name for k, o in enumerate(objectives) if k not in shown]
    notes = [f"not shown: {', '.join(left)} (front.csv has them)"] if left else []
    if bound is not None and len(bound):
        what = "the ideal point only" if len(bound) == 1 else f"its {len(bound)} points"
        notes.append(f"bound over {len(objectives)} objectives: {what}, projected onto these two")
    return "; ".join(notes)


def _shade_bound(ax, objectives, axes: tuple[int, int], bound, front, reference) -> None:
    """The region the bound leaves open: what it dominates beyond what the front does."""
    i, j = axes
    signs = -np.array([objectives[i].direction.sign, objectives[j].direction.sign])  # +1: maximised
    bound_points = bound[:, [i, j]]
    ax.scatter(bound_points[:, 0], bound_points[:, 1], s=0)  # the view takes in the bound ...
    limits = ax.get_xlim(), ax.get_ylim()  # ... but not the reference point the regions reach
    corner = np.array([reference[i], reference[j]])
    for points, color, label in (
        (bound_points, "tab:green", "bound: no policy beyond"),
        (front[:, [i, j]], "tab:blue", None),
    ):
        outline = staircase(points, signs, corner)
        ax.fill(outline[:, 0], outline[:, 1], color=color, alpha=0.18, lw=0, label=label, zorder=0)
    outline = staircase(bound_points, signs, corner)
    ax.plot(outline[:-1, 0], outline[:-1, 1], color="tab:green", lw=1.0)
    ax.set_xlim(*limits[0])
    ax.set_ylim(*limits[1])


def staircase(points: np.ndarray, signs: np.ndarray, reference: np.ndarray) -> np.ndarray:
    """The outline of what ``points`` (two objectives; ``signs`` +1 maximised, -1 minimised)
    dominate up to ``reference``: a closed polygon in the objectives' units."""
    space = points * signs
    ref = reference * signs
    space = space[(space > ref).all(axis=1)]
    if not len(space):
        return np.array([reference, reference])
    space = space[np.argsort(-space[:, 0], kind="stable")]
    best_y = np.maximum.accumulate(space[:, 1])
    keep = np.r_[True, best_y[1:] > best_y[:-1]]
    space = space[keep]
    corners = [[ref[0], space[-1, 1]]]
    for k in range(len(space) - 1, -1, -1):
        corners.append([space[k, 0], space[k, 1]])
        corners.append([space[k, 0], space[k - 1, 1] if k > 0 else ref[1]])
    corners.append([ref[0], ref[1]])
    return np.array(corners) * signs
