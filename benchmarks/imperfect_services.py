"""How an imperfect uncertainty-reduction service changes the default runs' fronts.

For web_ids (the scan's false-negative rate ``scan_fn``, and its false-positive rate
``scan_fp``) and tas (the probe's misreport probability ``probe_error``), the default run
(population 100, 40 generations, seed 1, 2 workers; every front value re-checked by Storm)
at each rate in RATES, through the library (``parley_core.pipeline``). It prints, per rate:

- the front's size and hypervolume against the run's own reference point (what the run's
  summary.json reports as ``front.hypervolume``; the reference differs from run to run);
- the hypervolume against one common reference point per series (each objective's worst
  value over every front and baseline of the series, moved out by a tenth of its range, as
  a run does), so that the rates compare;
- the knee policy's values (the run's ``selected`` policy) and decisions.

It draws the fronts overlaid per rate in docs/img/web_ids-imperfect-scan.png (scan_fn and
scan_fp side by side) and docs/img/tas-imperfect-probe.png.

    .venv/bin/python benchmarks/imperfect_services.py [--quick]

``--quick``: 6 rounds (tas: intervals up to 3) and 5 generations, a smoke test of a minute.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import matplotlib
import numpy as np
from attrs import frozen
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure
from sweeps import Point, common_reference, sweep

from parley_core.search import SearchSettings

RATES = (0.0, 0.05, 0.1, 0.2, 0.3)
IMAGES = Path(__file__).resolve().parents[1] / "docs" / "img"


@frozen(kw_only=True)
class Series:
    """One case study, one rate option swept over RATES."""

    case: str
    option: str
    image: str
    zoom: tuple[float, float] | None = None
    """Limits of the first objective for a second, zoomed panel (None: no zoom)."""


SERIES = (
    Series(case="web_ids", option="scan_fn", image="web_ids-imperfect-scan.png"),
    Series(case="web_ids", option="scan_fp", image="web_ids-imperfect-scan.png"),
    Series(case="tas", option="probe_error", image="tas-imperfect-probe.png", zoom=(0.0312, 0.0362)),
)
QUICK = {"web_ids": {"rounds": "6"}, "tas": {"rounds": "6", "max_interval": "3"}}


def table(series: Series, points: list[Point]) -> list[str]:
    """The series' Markdown table."""
    names = [o.name for o in points[0].result.family.objectives]
    reference = common_reference(points)
    lines = [
        f"{series.case}, {series.option} (common reference: {_shown(reference)})",
        "",
        f"| {series.option} | front | HV (run's reference) | run's reference | HV (common reference) | "
        + " | ".join(f"knee {n}" for n in names)
        + " | knee decisions | s |",
        "|---|---|---|---|---|" + "---|" * len(names) + "---|---|",
    ]
    for p in points:
        knee = p.result.front.policies[p.result.selected]
        values = p.front[p.result.selected]
        decisions = ", ".join(f"{d}={v}" for d, v in zip(p.result.family.names, knee.values))
        lines.append(
            f"| {p.rate:g} | {len(p.front)} | {p.hypervolume(p.result.reference):.6g} | {_shown(p.result.reference)} | "
            f"{p.hypervolume(reference):.6g} | " + " | ".join(f"{v:.6g}" for v in values) + f" | {decisions} | "
            f"{p.seconds:.0f} |"
        )
    return lines


def _shown(point) -> str:
    return "(" + ", ".join(f"{float(v):.6g}" for v in point) + ")"


def draw(image: str, sweeps: list[tuple[Series, list[Point]]]) -> Path:
    """The fronts of each series overlaid per rate, one panel per series (and one more for a zoom)."""
    panels = [(series, points, None) for series, points in sweeps]
    panels += [(series, points, series.zoom) for series, points in sweeps if series.zoom is not None]
    fig = Figure(figsize=(5.2 * len(panels), 4.2))
    FigureCanvasAgg(fig)  # the Agg canvas, without pyplot's global state
    for ax, (series, points, zoom) in zip(fig.subplots(1, len(panels), squeeze=False)[0], panels):
        _fronts(ax, series, points, zoom)
    fig.tight_layout()
    IMAGES.mkdir(parents=True, exist_ok=True)
    path = IMAGES / image
    fig.savefig(path, dpi=130)
    return path


def _fronts(ax, series: Series, points: list[Point], zoom: tuple[float, float] | None) -> None:
    """One panel: each rate's front (points joined in the order of the first objective) and its knee."""
    colours = matplotlib.colormaps["viridis"](np.linspace(0.0, 0.9, len(RATES)))
    names = [o.name for o in points[0].result.family.objectives]
    for colour, p in zip(colours, points):
        front = p.front[np.argsort(p.front[:, 0])]
        ax.plot(front[:, 0], front[:, 1], "-", color=colour, lw=1.0, alpha=0.8)
        ax.plot(front[:, 0], front[:, 1], "o", color=colour, ms=2.5, label=f"{series.option}={p.rate:g}")
        knee = p.front[p.result.selected]
        ax.plot(knee[0], knee[1], "*", color=colour, ms=11, mec="black", mew=0.6)
    if zoom is not None:
        inside = np.vstack([p.front[(p.front[:, 0] >= zoom[0]) & (p.front[:, 0] <= zoom[1])] for p in points])
        ax.set_xlim(*zoom)
        margin = 0.03 * np.ptp(inside[:, 1])
        ax.set_ylim(inside[:, 1].min() - margin, inside[:, 1].max() + margin)
    ax.set_xlabel(f"{names[0]} (min)")
    ax.set_ylabel(f"{names[1]} (min)")
    where = f", {names[0]} {zoom[0]:g}..{zoom[1]:g}" if zoom else ""
    ax.set_title(f"{series.case}: fronts by {series.option}{where} (star: knee)", fontsize=10)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="small models and 5 generations (a smoke test)")
    args = parser.parse_args()
    settings = SearchSettings(population=100, generations=5 if args.quick else 40, seed=1)
    images: dict[str, list[tuple[Series, list[Point]]]] = {}
    for series in SERIES:
        points = sweep(series.case, series.option, RATES, settings, QUICK[series.case] if args.quick else {})
        print("\n".join(table(series, points)), end="\n\n", flush=True)
        images.setdefault(series.image, []).append((series, points))
    if args.quick:
        return  # the figures in docs/ show the full runs
    for image, sweeps in images.items():
        print(f"wrote {draw(image, sweeps)}")


if __name__ == "__main__":
    main()
