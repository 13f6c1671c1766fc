"""The files of a run: model, properties, front, policies, baseline, summary and plots.

A run directory is written in full next to its destination and then moved into place, so
an interrupted write never leaves half a run behind.
"""

from __future__ import annotations

import csv
import io
import json
import os
import platform
import shutil
import tempfile
import traceback
from importlib import metadata
from pathlib import Path
from typing import Any

import numpy as np

from parley_core import metrics
from parley_core import policies as policy_files
from parley_core.errors import OutputError
from parley_core.model import Direction, Valued
from parley_core.options import options_as_dict
from parley_core.pipeline import RunResult
from parley_core.plotting import figure, save


def check_output(out: Path, force: bool) -> None:
    """Refuse an existing, non-empty output directory unless ``force``."""
    if out.exists() and not out.is_dir():
        raise OutputError(f"output {out} exists and is not a directory; choose another --out")
    if out.is_dir() and any(out.iterdir()) and not force:
        raise OutputError(f"output directory {out} exists and is not empty; choose another --out or add --force")


def front_csv(front: Valued, extra: dict[str, list[Any]] | None = None) -> str:
    """``policy``, then any ``extra`` columns, then one column per objective (full precision)."""
    out = io.StringIO()
    writer = csv.writer(out, lineterminator="\n")
    extra = extra or {}
    writer.writerow(["policy", *extra, *(o.name for o in front.objectives)])
    for i, (policy, row) in enumerate(zip(front.policies, front.values)):
        writer.writerow([policy.name, *(column[i] for column in extra.values()), *(repr(v) for v in row)])
    return out.getvalue()


def decisions_csv(family) -> str:
    """Each decision constant of model.prism with its service constant and observation valuation."""
    out = io.StringIO()
    writer = csv.writer(out, lineterminator="\n")
    writer.writerow(["decision", "constant", *family.observation])
    for decision in family.decisions:
        writer.writerow([decision.name, decision.service.constant, *decision.valuation])
    return out.getvalue()


def versions() -> dict[str, str]:
    result = {"python": platform.python_version()}
    for package in ("parley", "stormpy", "pymoo", "moocore", "numpy"):
        try:
            result[package] = metadata.version(package)
        except metadata.PackageNotFoundError:
            result[package] = "unknown"
    return result


def hypervolume(result: RunResult, valued: Valued) -> float:
    """The hypervolume of a set of the run, against the run's reference point."""
    directions = [o.direction for o in result.family.objectives]
    return metrics.hypervolume(np.array(valued.values), directions, result.reference)


def spread(result: RunResult, valued: Valued) -> float | None:
    """Deb's spread of the set's non-dominated points (None unless two objectives)."""
    directions = [o.direction for o in result.family.objectives]
    if len(directions) != 2:
        return None
    values = np.array(valued.values)
    return metrics.spread(values[metrics.nondominated(values, directions)], directions)


def optimality(result: RunResult, front_hypervolume: float) -> dict[str, Any] | None:
    """How much of the certified bound's hypervolume the front covers (same reference point)."""
    bound = result.bound
    if bound is None:
        return None
    bound_hv = bound.hypervolume(result.reference)
    gap = (bound_hv - front_hypervolume) / bound_hv if bound_hv > 0 and np.isfinite(bound_hv) else None
    return {
        "bound_hypervolume": bound_hv,
        "front_hypervolume": front_hypervolume,
        "gap": gap,
        "bound_method": bound.method,
        "exact": bound.exact,
        "bound_points": len(bound.points),
        "seconds": round(bound.seconds, 4),
        **({"search": bound.details} if bound.details else {}),
    }


def _staircase(points: np.ndarray, signs: np.ndarray, reference: np.ndarray) -> np.ndarray:
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


def bound_csv(result: RunResult) -> str:
    """The bound's points, one column per objective."""
    assert result.bound is not None
    out = io.StringIO()
    writer = csv.writer(out, lineterminator="\n")
    writer.writerow([o.name for o in result.family.objectives])
    for row in result.bound.points:
        writer.writerow([repr(float(v)) for v in row])
    return out.getvalue()


def scenarios_csv(result: RunResult) -> str:
    """A robust run's values of every baseline and front policy in every scenario: columns
    ``policy``, ``set`` (front or baseline), ``scenario`` (its label), then the scenario's
    options, then one column per objective (Storm's values, full precision)."""
    assert result.front_scenarios is not None and result.baseline_scenarios is not None
    out = io.StringIO()
    writer = csv.writer(out, lineterminator="\n")
    keys = list(dict.fromkeys(k for m in result.scenarios for k in m.scenario.keys))
    writer.writerow(["policy", "set", "scenario", *keys, *(o.name for o in result.family.objectives)])
    for kind, valued, each in (
        ("front", result.front, result.front_scenarios),
        ("baseline", result.baseline, result.baseline_scenarios),
    ):
        for policy, rows in zip(valued.policies, each):
            for model, row in zip(result.scenarios, rows):
                values = model.scenario.values
                writer.writerow(
                    [policy.name, kind, model.label, *(values.get(k, "") for k in keys), *(repr(float(v)) for v in row)]
                )
    return out.getvalue()


def scenarios_summary(result: RunResult) -> dict[str, Any] | None:
    """A robust run's scenarios, and the front's and baseline's hypervolume in each (same
    reference point as the run's)."""
    if not result.scenarios:
        return None
    assert result.front_scenarios is not None and result.baseline_scenarios is not None
    directions = [o.direction for o in result.family.objectives]
    return {
        "objective": "worst case over the scenarios (front.csv, baseline.csv); each scenario's values: scenarios.csv",
        "scenarios": [
            {
                "label": model.label,
                "set": model.scenario.values,
                "front_hypervolume": metrics.hypervolume(result.front_scenarios[:, s], directions, result.reference),
                "baseline_hypervolume": metrics.hypervolume(
                    result.baseline_scenarios[:, s], directions, result.reference
                ),
            }
            for s, model in enumerate(result.scenarios)
        ],
    }


def infinite_counts(result: RunResult) -> dict[str, int]:
    """Per objective, how many evaluated policies have an infinite value (kept off the front)."""
    values = np.asarray(result.search.values, dtype=float).reshape(-1, len(result.family.objectives))
    counts = (~np.isfinite(values)).sum(axis=0)
    return {o.name: int(n) for o, n in zip(result.family.objectives, counts) if n}


def summary(result: RunResult) -> dict[str, Any]:
    family = result.family
    search = result.search
    hv_front = hypervolume(result, result.front)
    hv_base = hypervolume(result, result.baseline)
    timings = {k: round(v, 4) for k, v in result.timings.items()}
    return {
        "case_study": result.prepared.case.name,
        "description": result.prepared.system.description,
        "options": options_as_dict(result.prepared.options),
        "seed": result.settings.seed,
        "search": {
            "algorithm": result.settings.algorithm,
            "population": result.settings.population,
            "generations": result.settings.generations,
            "generations_done": search.generations,
            "evaluations": search.evaluations,
            "max_evaluations": result.settings.max_evaluations,
            "time_limit_seconds": result.settings.time_limit,
            "stopped_by": search.stopped_by.value,
            "interrupted": search.interrupted,
            "warm_start_policies": result.warm_start,
        },
        "evaluator": result.evaluator.value,
        "evaluator_details": result.evaluator_info,
        "storm_solver": "native, sound value iteration, relative precision 1e-12",
        "workers": result.workers,
        "model": {
            "observation": list(family.observation),
            "services": [s.to_json() for s in family.services],
            "decisions": len(family.decisions),
            "valuations": len(family.valuations),
            "valuations_left_out": len(family.left_out),
            "left_out": [list(v) for v in family.left_out],
        },
        "objectives": [o.to_json() for o in family.objectives],
        "constraints": [str(c) for c in result.settings.constraints],
        "optimality": optimality(result, hv_front),
        "robust": scenarios_summary(result),
        "infinite_values": infinite_counts(result),
        "front": {"size": len(result.front), "hypervolume": hv_front, "spread": spread(result, result.front)},
        "baseline": {"size": len(result.baseline), "hypervolume": hv_base, "spread": spread(result, result.baseline)},
        "hypervolume_reference": list(result.reference),
        "hypervolume_gain": hv_front - hv_base,
        "hypervolume_gain_percent": (100.0 * (hv_front - hv_base) / hv_base) if hv_base > 0 else None,
        "verification": result.verification.to_json(),
        "selected": {
            "policy": result.front.policies[result.selected].name,
            "rule": "knee (closest to the ideal point, normalized)",
        },
        "timings_seconds": timings,
        "versions": versions(),
    }


def plot_front(result: RunResult, path: Path) -> None:
    objectives = result.family.objectives
    fig, ax = figure(6.4, 4.6)
    if len(objectives) >= 2:
        i, j = (1, 0) if objectives[0].direction is Direction.MAX else (0, 1)
        front = np.array(result.front.values)
        base = np.array(result.baseline.values)
        ax.scatter(
            front[:, i],
            front[:, j],
            s=22,
            facecolors="none",
            edgecolors="tab:blue",
            label=f"parley front ({len(front)})",
        )
        ax.scatter(base[:, i], base[:, j], marker="x", color="tab:red", s=36, label=f"baseline ({len(base)})")
        if result.front_scenarios is not None and len(result.scenarios) > 1:
            # each scenario's values of the front's policies: the worst case is their lower envelope
            for s, model in enumerate(result.scenarios):
                each = result.front_scenarios[:, s]
                ax.scatter(each[:, i], each[:, j], s=5, alpha=0.5, label=f"front in {model.label}", zorder=1)
        chosen = front[result.selected]
        ax.scatter(
            [chosen[i]],
            [chosen[j]],
            s=90,
            color="tab:blue",
            label=f"selected {result.front.policies[result.selected].name} (knee)",
        )
        if result.bound is not None and np.isfinite(result.bound.points).all():
            # the region the bound leaves open: what it dominates beyond what the front does
            signs = -np.array([objectives[i].direction.sign, objectives[j].direction.sign])  # +1: maximised
            bound_points = np.asarray(result.bound.points)[:, [i, j]]
            ax.scatter(bound_points[:, 0], bound_points[:, 1], s=0)  # the view takes in the bound ...
            limits = ax.get_xlim(), ax.get_ylim()  # ... but not the reference point the regions reach
            reference = np.array([result.reference[i], result.reference[j]])
            for points, color, label in (
                (np.asarray(result.bound.points)[:, [i, j]], "tab:green", "bound: no policy beyond"),
                (front[:, [i, j]], "tab:blue", None),
            ):
                outline = _staircase(points, signs, reference)
                ax.fill(outline[:, 0], outline[:, 1], color=color, alpha=0.18, lw=0, label=label, zorder=0)
            outline = _staircase(bound_points, signs, reference)
            ax.plot(outline[:-1, 0], outline[:-1, 1], color="tab:green", lw=1.0)
            ax.set_xlim(*limits[0])
            ax.set_ylim(*limits[1])
        for policy, row in zip(result.baseline.policies, base):
            ax.annotate(
                policy.name.split("-")[-1],
                (row[i], row[j]),
                fontsize=7,
                color="tab:red",
                xytext=(3, -9),
                textcoords="offset points",
            )
        ax.set_xlabel(f"{objectives[i].name} ({objectives[i].direction.value})")
        ax.set_ylabel(f"{objectives[j].name} ({objectives[j].direction.value})")
    else:  # one objective: the values on a line, the front's best and the baselines
        base = np.array(result.baseline.values)[:, 0]
        best = np.array(result.front.values)[:, 0]
        ax.scatter(base, np.zeros(len(base)), marker="x", color="tab:red", s=36, label=f"baseline ({len(base)})")
        ax.scatter(best, np.zeros(len(best)), s=90, color="tab:blue", label="parley's best")
        ax.set_yticks([])
        ax.set_xlabel(f"{objectives[0].name} ({objectives[0].direction.value})")
    robust = f", worst case of {len(result.scenarios)} scenarios" if len(result.scenarios) > 1 else ""
    ax.set_title(f"{result.prepared.case.name}: front vs baseline{robust}", fontsize=11)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    save(fig, path, dpi=130)


PLOT_ERROR = "policy-plot-error.txt"
"""Written instead of policy.png when a plugin's ``plot_policy`` raises."""


def write_run(result: RunResult, out: Path, *, force: bool = False) -> list[Path]:
    """Write the run directory; returns the files written."""
    check_output(out, force)
    out.parent.mkdir(parents=True, exist_ok=True)
    family = result.family
    staging = Path(tempfile.mkdtemp(prefix=f".{out.name}.", dir=out.parent))
    staging.chmod(0o755)
    try:
        (staging / "model.prism").write_text(family.prism)
        (staging / "properties.pctl").write_text(family.properties_text())
        (staging / "front.csv").write_text(front_csv(result.front))
        (staging / "policies.csv").write_text(policy_files.wide_csv(family, result.front.policies))
        (staging / "decisions.csv").write_text(decisions_csv(family))
        constants = [s.constant for s in family.services]
        baseline_columns = {c: [b.values[c] for b in family.baselines] for c in constants}
        (staging / "baseline.csv").write_text(front_csv(result.baseline, baseline_columns))
        (staging / "summary.json").write_text(json.dumps(summary(result), indent=2) + "\n")
        if result.bound is not None:
            (staging / "bound.csv").write_text(bound_csv(result))
        if result.scenarios:
            (staging / "scenarios.csv").write_text(scenarios_csv(result))
        plot_front(result, staging / "front.png")
        case = result.prepared.case
        if case.plot_policy is not None:
            selected = result.front.policies[result.selected]
            try:
                case.plot_policy(result.prepared.system, policy_files.table(family, selected), staging / "policy.png")
            except Exception as exc:  # a plugin's drawing must not cost the verified results
                (staging / "policy.png").unlink(missing_ok=True)
                (staging / PLOT_ERROR).write_text(
                    f"the {case.name} plugin's plot_policy failed, so there is no policy.png:\n"
                    + "".join(traceback.format_exception(exc))
                )
        _move_into_place(staging, out)
    except BaseException:
        shutil.rmtree(staging, ignore_errors=True)
        raise
    return sorted(out.iterdir())


def _move_into_place(staging: Path, out: Path) -> None:
    if out.exists():
        old = out.with_name(f".{out.name}.old")
        shutil.rmtree(old, ignore_errors=True)
        os.replace(out, old)
        os.replace(staging, out)
        shutil.rmtree(old, ignore_errors=True)
    else:
        os.replace(staging, out)
