"""The drift simulation's report: drift.json and drift.png."""

from __future__ import annotations

from typing import Any

import numpy as np

from parley_core.simulation.drift import DriftResult


def to_json(result: DriftResult) -> dict[str, Any]:
    """The drift simulation as drift.json: per controller, the phases' means with 99 %
    intervals, Storm's values of its policies, and the series per mission."""
    drift = result.drift
    phases = {
        "before": (0, min(drift.begin, result.missions)),
        "after": (min(drift.end, result.missions), result.missions),
    }
    document: dict[str, Any] = {
        "drift": str(drift),
        "missions": result.missions,
        "episodes": result.episodes,
        "seed": result.seed,
        "levels": list(result.levels),
        "controllers": [],
    }
    for series in result.series:
        entry: dict[str, Any] = {"name": series.name, "policies": list(series.policies), "phases": {}}
        for phase, (first, last) in phases.items():
            if last > first:
                entry["phases"][phase] = {
                    "missions": [first, last],
                    **{
                        o: dict(zip(("mean", "low", "high"), result.phase(series, o, first, last)))
                        for o in result.objectives
                    },
                }
        entry["storm"] = [
            {"policy": policy, drift.parameter: level, **dict(zip(result.objectives, values))}
            for (policy, level), values in series.checked.items()
        ]
        entry["per_mission"] = {o: series.means[o].tolist() for o in result.objectives}
        entry["in_force"] = series.in_force.tolist()
        entry["cut"] = series.cut
        document["controllers"].append(entry)
    return document


def plot(result: DriftResult, path) -> None:
    """Each objective per mission (the mean over the systems, a 99 % band), one line per
    controller; the drift shaded; for adaptive controllers, the share of systems on the
    policy of the drift's final value."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    from parley_core.views.plotting import save

    rows = len(result.objectives) + 1
    fig = Figure(figsize=(7.5, 2.4 * rows))
    FigureCanvasAgg(fig)
    axes = fig.subplots(rows, 1, sharex=True)
    missions = np.arange(result.missions)
    drift = result.drift
    for ax, objective in zip(axes, result.objectives):
        for k, series in enumerate(result.series):
            ax.plot(missions, series.means[objective], lw=1.2, label=series.name, color=f"C{k}")
            ax.fill_between(missions, series.lows[objective], series.highs[objective], color=f"C{k}", alpha=0.15)
        ax.set_ylabel(objective)
        ax.grid(alpha=0.3)
    share = axes[-1]
    for k, series in enumerate(result.series):
        if series.in_force.shape[1] > 1:
            share.plot(missions, series.in_force[:, -1] / result.episodes, lw=1.2, label=series.name, color=f"C{k}")
    share.set_ylabel(f"on the last\n{drift.parameter} policy")
    share.set_ylim(-0.05, 1.05)
    share.set_xlabel("mission")
    share.grid(alpha=0.3)
    for ax in axes:
        ax.axvspan(drift.begin - 0.5, drift.end + 0.5, color="tab:gray", alpha=0.2, lw=0)
    axes[0].legend(fontsize=8)
    axes[0].set_title(f"{result.episodes} systems, {result.missions} missions each; drift {drift}", fontsize=10)
    save(fig, path, dpi=120)
