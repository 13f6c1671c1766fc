"""How an erring localisation (option ``loc_error``) changes the robots' default fronts.

For robot_grid (the default generated 10x10 map, seed 0) and, with ``--case turtlebot``,
the turtlebot (its default kinematic motions), the default run (population 100, 40
generations, seed 1, 2 workers; every front value re-checked by Storm) at each
``loc_error`` of RATES, through the library (``parley_core.pipeline``), as
``parley run CASE --set loc_error=X`` does. It prints a Markdown table, one row per rate:

- the front's size and hypervolume against the run's own reference point (summary.json's
  ``front.hypervolume``; the reference differs from run to run), and against one common
  reference point (each objective's worst value over all fronts and baselines of the
  table, moved out by a tenth of its range, as a run chooses its own), so that rows compare;
- the knee policy's values (the run's ``selected`` policy), and the front's highest success;
- the run's wall time.

For robot_grid it draws the fronts overlaid in docs/img/robot_grid-loc-error.png.

    .venv/bin/python benchmarks/loc_error.py [--case robot_grid|turtlebot] [--quick]

``--quick``: a 5x5 map (turtlebot: 100 samples) and 5 generations, a smoke test.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import matplotlib
import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure
from sweeps import Point, common_reference, sweep

from parley_core.search import SearchSettings

RATES = (0.0, 0.05, 0.1, 0.2)
IMAGE = Path(__file__).resolve().parents[1] / "docs" / "img" / "robot_grid-loc-error.png"
QUICK = {"robot_grid": {"size": "5", "seed": "1"}, "turtlebot": {"samples": "100"}}


def table(name: str, points: list[Point]) -> list[str]:
    """The Markdown table of a sweep."""
    success, cost = (o.name for o in points[0].result.family.objectives)
    reference = common_reference(points)
    lines = [
        f"{name}: {points[0].result.prepared.system.description} (common reference: {_shown(reference)})",
        "",
        f"| loc_error | front | HV (run's reference) | HV (common reference) | knee {success} | knee {cost} "
        f"| highest {success} | s |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for p in points:
        lines.append(
            f"| {p.rate:g} | {len(p.front)} | {p.hypervolume(p.result.reference):.4f} | "
            f"{p.hypervolume(reference):.4f} | {p.knee[0]:.4f} | {p.knee[1]:.3f} | {p.front[:, 0].max():.4f} | "
            f"{p.seconds:.0f} |"
        )
    return lines


def _shown(point) -> str:
    return "(" + ", ".join(f"{float(v):.6g}" for v in point) + ")"


def draw(points: list[Point], path: Path) -> Path:
    """The fronts overlaid, one colour per rate, each knee a star (success against cost)."""
    fig = Figure(figsize=(6.4, 4.6))
    FigureCanvasAgg(fig)  # the Agg canvas, without pyplot's global state
    ax = fig.subplots()
    colours = matplotlib.colormaps["viridis"](np.linspace(0.0, 0.85, len(points)))
    success, cost = (o.name for o in points[0].result.family.objectives)
    for colour, p in zip(colours, points):
        front = p.front[np.argsort(p.front[:, 1])]
        ax.plot(front[:, 1], front[:, 0], "-", color=colour, lw=1.0, alpha=0.8)
        ax.plot(front[:, 1], front[:, 0], "o", color=colour, ms=2.2, label=f"loc_error={p.rate:g}")
        ax.plot(p.knee[1], p.knee[0], "*", color=colour, ms=12, mec="black", mew=0.6)
    ax.set_xlabel(f"{cost} (min)")
    ax.set_ylabel(f"{success} (max)")
    ax.set_title(f"robot_grid, {points[0].result.prepared.system.description}: fronts by loc_error", fontsize=9)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8, loc="lower right", title="star: knee", title_fontsize=8)
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=130)
    return path


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--case", choices=("robot_grid", "turtlebot"), default="robot_grid")
    parser.add_argument("--quick", action="store_true", help="small models and 5 generations (a smoke test)")
    args = parser.parse_args()
    settings = SearchSettings(population=100, generations=5 if args.quick else 40, seed=1)
    points = sweep(args.case, "loc_error", RATES, settings, QUICK[args.case] if args.quick else {})
    print("\n".join(table(args.case, points)), flush=True)
    if args.case == "robot_grid" and not args.quick:  # the figure in docs/ shows the full runs
        print(f"wrote {draw(points, IMAGE)}")


if __name__ == "__main__":
    main()
