"""Closed-loop validation: a run's policies on the plugin's own simulator, against Storm.

A case study whose plugin offers a :class:`Simulator` (turtlebot: the Waffle in MuJoCo)
can run a URC in closed loop on something closer to the real system than the DTMC: the
URC decides from what the system's controller believes, the simulator's physics decide what
happens. :func:`validate` runs the chosen front policy and the baselines of a run directory
for ``episodes`` episodes each and sets the empirical value of each objective, with a 99 %
confidence interval (Wilson's for a probability, the normal one for a mean), next to
Storm's value for the same policy (front.csv and baseline.csv hold Storm's values). A Storm
value outside the interval is a finding about the abstraction, not a defect of either: the
DTMC forgets what the simulator remembers (where in a cell the robot is).
"""

from __future__ import annotations

import csv
import math
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import numpy as np
from attrs import field, frozen

from parley_core.errors import OptionError
from parley_core.model import SystemModel
from parley_core.plugin.simulator import Z99, Episodes, Estimate, wilson
from parley_core.progress import NullReporter, Reporter
from parley_core.urc.controller import URC


def estimate_json(e: Estimate) -> dict[str, Any]:
    """One estimate in validation.json (``checked`` is Storm's value)."""
    return {
        "objective": e.objective,
        "kind": e.kind,
        "closed_loop": e.mean,
        "interval99": [e.low, e.high],
        "storm": e.checked,
        "episodes": e.episodes,
        "storm_within_interval": e.agrees,
    }


@frozen(kw_only=True)
class PolicyValidation:
    policy: str
    role: str
    """``chosen`` or ``baseline``"""
    estimates: tuple[Estimate, ...]
    notes: tuple[str, ...]
    episodes: Episodes = field(eq=False, repr=False)


@frozen(kw_only=True)
class Validation:
    run: Path
    simulator: str
    episodes: int
    seed: int
    policies: tuple[PolicyValidation, ...]
    system: SystemModel = field(eq=False, repr=False)
    draw: Callable[[SystemModel, Episodes, Any], None] | None = field(default=None, eq=False, repr=False)

    def to_json(self) -> dict[str, Any]:
        return {
            "run": str(self.run),
            "simulator": self.simulator,
            "episodes": self.episodes,
            "seed": self.seed,
            "policies": [
                {
                    "policy": p.policy,
                    "role": p.role,
                    "estimates": [estimate_json(e) for e in p.estimates],
                    "notes": list(p.notes),
                }
                for p in self.policies
            ],
        }


def estimate(objective: str, formula: str, samples: np.ndarray, storm: float) -> Estimate:
    """The 99 % interval of an objective's per-episode values (a proportion for ``P=?``)."""
    n = len(samples)
    mean = float(np.mean(samples))
    if formula.lstrip().startswith("P"):
        low, high = wilson(int(round(float(np.sum(samples)))), n)
        kind = "probability"
    else:
        deviation = float(np.std(samples, ddof=1)) if n > 1 else 0.0
        half = Z99 * deviation / math.sqrt(n)
        low, high, kind = mean - half, mean + half, "mean"
    return Estimate(objective=objective, kind=kind, mean=mean, low=low, high=high, checked=storm, episodes=n)


def _baselines(run_dir: Path, names: Sequence[str]) -> list[tuple[str, dict[str, int], tuple[float, ...]]]:
    """(name, decision per service constant, Storm's values) of each uniform baseline of baseline.csv."""
    path = run_dir / "baseline.csv"
    if not path.is_file():
        return []
    rows = []
    with open(path) as handle:
        for row in csv.DictReader(handle):
            decision = {k: int(v) for k, v in row.items() if k not in ("policy", *names)}
            rows.append((row["policy"], decision, tuple(float(row[n]) for n in names)))
    return rows


def validate(
    run_dir: Path,
    policy: str = "knee",
    episodes: int = 1000,
    seed: int = 1,
    baselines: bool = True,
    reporter: Reporter | None = None,
) -> Validation:
    """Run the chosen policy (``knee``, a front policy's name, or its row in front.csv
    counting from 1) and
    the baselines of a run directory on the case study's simulator (module docstring)."""
    from parley_core.plugin.manager import load_registry
    from parley_core.rundir import read
    from parley_core.rundir.select import controller, select

    reporter = reporter or NullReporter()
    run = read.load(run_dir)
    case_name = run.case_study
    if not case_name:
        raise OptionError(f"{run_dir} is a run of `parley synthesize`; validation needs a case study's run")
    case = load_registry().get(str(case_name))
    if case.simulator is None:
        raise OptionError(
            f"the {case.name} plugin offers no simulator to validate against; case studies with one: turtlebot (MuJoCo)"
        )
    if run.summary.robust is not None:
        raise OptionError(
            f"{run_dir} is a robust run: its front.csv holds worst cases over scenarios, which no one simulated "
            "system has; validate a run of one scenario (parley run without --scenarios)"
        )
    options = case.options_from_json(run.summary.options)
    if case.warm_up is not None:
        case.warm_up(options, reporter)
    reporter.stage("build model")
    system = case.build(options)
    from parley_core.family.prepare import make_family

    if make_family(system, prune=case.prune).prism != run.model:
        raise OptionError(
            f"the {case.name} model built from {run_dir}/summary.json's options is not the run's model.prism "
            "(the plugin changed since the run); rerun `parley run` and validate the new run"
        )
    names = [o.name for o in run.objectives]
    if policy == "knee":
        chosen = select(run)
    elif policy.isdigit():
        row = int(policy)
        if not 1 <= row <= len(run.front.policies):
            raise OptionError(
                f"--policy {policy}: front.csv has rows 1..{len(run.front.policies)}; give a row, a name or knee"
            )
        chosen = run.front.policies[row - 1].name
    else:
        chosen = run.policy(policy).name
    jobs: list[tuple[str, str, URC]] = [("chosen", chosen, controller(run, chosen))]
    if baselines:
        for name, decision, values in _baselines(run_dir, names):
            table = {v: dict(decision) for v in {d.valuation for d in run.decisions}}
            urc = URC(
                observation=run.observation,
                services=run.services,
                table=table,
                left_out=run.left_out,
                policy=name,
                values=dict(zip(names, values)),
            )
            jobs.append(("baseline", name, urc))
    results = []
    for role, name, urc in jobs:
        reporter.stage(f"closed loop: {name}", episodes)
        found = case.simulator.run(system, options, urc, episodes, seed, reporter.advance)
        estimates = []
        for objective in run.objectives:
            samples = found.values.get(objective.name)
            if samples is None:
                continue
            estimates.append(
                estimate(
                    objective.name, objective.formula, np.asarray(samples, dtype=float), urc.values[objective.name]
                )
            )
        results.append(
            PolicyValidation(policy=name, role=role, estimates=tuple(estimates), notes=found.notes, episodes=found)
        )
    return Validation(
        run=run_dir,
        simulator=case.simulator.description,
        episodes=episodes,
        seed=seed,
        policies=tuple(results),
        system=system,
        draw=case.simulator.draw,
    )


def plot(validation: Validation, path: Path) -> None:
    """validation.png: per objective, each policy's closed-loop interval and Storm's value;
    and the chosen policy's episodes as the simulator draws them."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    from parley_core.views.plotting import save

    objectives = [e.objective for e in validation.policies[0].estimates]
    panels = len(objectives) + (validation.draw is not None)
    fig = Figure(figsize=(4.6 * panels, 4.6))
    FigureCanvasAgg(fig)
    axes = fig.subplots(1, panels, squeeze=False)[0]
    labels = [p.policy for p in validation.policies]
    for ax, objective in zip(axes, objectives):
        for i, p in enumerate(validation.policies):
            found = next(e for e in p.estimates if e.objective == objective)
            color = "tab:blue" if p.role == "chosen" else "0.45"
            ax.errorbar(
                [i],
                [found.mean],
                yerr=[[found.mean - found.low], [found.high - found.mean]],
                fmt="o",
                color=color,
                capsize=4,
                label="closed loop, 99 % interval" if i == 0 else None,
            )
            ax.plot(
                [i - 0.3, i + 0.3],
                [found.checked] * 2,
                color="crimson" if not found.agrees else "tab:green",
                lw=2,
                label="Storm (the model)" if i == 0 else None,
            )
        ax.set_xticks(range(len(labels)))
        ax.set_xticklabels(labels, rotation=30, ha="right", fontsize=8)
        ax.set_title(objective)
        ax.grid(axis="y", alpha=0.3)
    axes[0].legend(fontsize=8)
    if validation.draw is not None:
        chosen = validation.policies[0]
        validation.draw(validation.system, chosen.episodes, axes[-1])
        axes[-1].set_title(f"{chosen.policy}: episodes from above", fontsize=10)
    fig.suptitle(
        f"{validation.simulator}: {validation.episodes} episodes a policy (seed {validation.seed})", fontsize=10
    )
    save(fig, path)
