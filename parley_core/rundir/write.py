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
from parley_core.errors import OutputError
from parley_core.model import Valued
from parley_core.pipeline import RunResult
from parley_core.plugin.options import options_as_dict
from parley_core.rundir import policies as policy_files
from parley_core.rundir.summary import (
    Guided,
    ModelRecord,
    OptimalityRecord,
    Polished,
    RobustRecord,
    RunSummary,
    ScenarioRecord,
    SearchRecord,
    SetRecord,
)
from parley_core.views.frontplot import front_figure
from parley_core.views.plotting import save


def check_output(out: Path, force: bool) -> None:
    """Refuse an existing, non-empty output directory unless ``force``."""
    if out.exists() and not out.is_dir():
        raise OutputError(f"output {out} exists and is not a directory; choose another --out")
    if out.is_dir() and any(out.iterdir()) and not force:
        raise OutputError(f"output directory {out} exists and is not empty; choose another --out or add --force")


def front_csv(front: Valued, extra: dict[str, list[Any]] | None = None, *, points: bool = False) -> str:
    """``policy``, then any ``extra`` columns, then one column per objective (full precision);
    with ``points``, last the ``point`` of each policy (policies whose values are ties, within
    the verification tolerance, share one: :func:`parley_core.metrics.tie_points`)."""
    out = io.StringIO()
    writer = csv.writer(out, lineterminator="\n")
    extra = dict(extra or {})
    directions = [o.direction for o in front.objectives]
    tail = {"point": list(metrics.tie_points(np.array(front.values), directions))} if points else {}
    writer.writerow(["policy", *extra, *(o.name for o in front.objectives), *tail])
    for i, (policy, row) in enumerate(zip(front.policies, front.values)):
        cells = [*(column[i] for column in extra.values()), *(repr(v) for v in row), *(c[i] for c in tail.values())]
        writer.writerow([policy.name, *cells])
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


def point_count(valued: Valued) -> int:
    """How many points the set's values make, policies whose values are ties sharing one."""
    directions = [o.direction for o in valued.objectives]
    points = metrics.tie_points(np.array(valued.values), directions)
    return int(points.max()) if len(points) else 0


def spread(result: RunResult, valued: Valued) -> float | None:
    """Deb's spread of the set's non-dominated points, one per tie (None unless two objectives)."""
    directions = [o.direction for o in result.family.objectives]
    if len(directions) != 2:
        return None
    return metrics.spread(metrics.distinct_front(np.array(valued.values), directions), directions)


def optimality(result: RunResult, front_hypervolume: float) -> OptimalityRecord | None:
    """How much of the certified bound's hypervolume the front covers (same reference point)."""
    bound = result.bound
    if bound is None:
        return None
    bound_hv = bound.hypervolume(result.reference)
    gap = (bound_hv - front_hypervolume) / bound_hv if bound_hv > 0 and np.isfinite(bound_hv) else None
    return OptimalityRecord(
        bound_hypervolume=bound_hv,
        front_hypervolume=front_hypervolume,
        gap=gap,
        bound_method=bound.method,
        exact=bound.exact,
        bound_points=len(bound.points),
        seconds=round(bound.seconds, 4),
        search=bound.search,
        belief=bound.belief,
    )


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


def scenarios_summary(result: RunResult) -> RobustRecord | None:
    """A robust run's scenarios, and the front's and baseline's hypervolume in each (same
    reference point as the run's)."""
    if not result.scenarios:
        return None
    assert result.front_scenarios is not None and result.baseline_scenarios is not None
    directions = [o.direction for o in result.family.objectives]
    return RobustRecord(
        objective="worst case over the scenarios (front.csv, baseline.csv); each scenario's values: scenarios.csv",
        scenarios=[
            ScenarioRecord(
                label=model.label,
                values=model.scenario.values,
                front_hypervolume=metrics.hypervolume(result.front_scenarios[:, s], directions, result.reference),
                baseline_hypervolume=metrics.hypervolume(result.baseline_scenarios[:, s], directions, result.reference),
            )
            for s, model in enumerate(result.scenarios)
        ],
    )


def infinite_counts(result: RunResult) -> dict[str, int]:
    """Per objective, how many evaluated policies have an infinite value (kept off the front)."""
    values = np.asarray(result.search.values, dtype=float).reshape(-1, len(result.family.objectives))
    counts = (~np.isfinite(values)).sum(axis=0)
    return {o.name: int(n) for o, n in zip(result.family.objectives, counts) if n}


def search_record(result: RunResult) -> SearchRecord:
    search, settings = result.search, result.settings
    walked, polished = search.walked, search.polished
    return SearchRecord(
        algorithm=settings.algorithm,
        population=settings.population,
        generations=settings.generations,
        generations_done=search.generations,
        evaluations=search.evaluations,
        max_evaluations=settings.max_evaluations,
        time_limit_seconds=settings.time_limit,
        stopped_by=search.stopped_by,
        interrupted=search.interrupted,
        warm_start_policies=result.warm_start,
        guided=None
        if walked is None
        else Guided(walked_policies=len(walked.policies), seconds=round(walked.seconds, 4), skipped=walked.skipped),
        polished=None
        if polished is None
        else Polished(
            evaluations=polished.evaluations,
            expanded_policies=polished.expanded,
            seconds=round(polished.seconds, 4),
            skipped=polished.skipped,
        ),
    )


def summary(result: RunResult) -> RunSummary:
    """The run's ``summary.json`` record."""
    family = result.family
    hv_front = hypervolume(result, result.front)
    hv_base = hypervolume(result, result.baseline)
    return RunSummary(
        case_study=result.prepared.case.name,
        description=result.prepared.system.description,
        options=options_as_dict(result.prepared.options),
        seed=result.settings.seed,
        search=search_record(result),
        evaluator=result.evaluator.value,
        evaluator_details=result.evaluator_info,
        storm_solver="native, sound value iteration, relative precision 1e-12",
        workers=result.workers,
        model=ModelRecord(
            observation=family.observation,
            services=family.services,
            decisions=len(family.decisions),
            valuations=len(family.valuations),
            valuations_left_out=len(family.left_out),
            left_out=family.left_out,
        ),
        objectives=family.objectives,
        constraints=result.settings.constraints,
        optimality=optimality(result, hv_front),
        robust=scenarios_summary(result),
        infinite_values=infinite_counts(result),
        front=SetRecord(
            size=len(result.front),
            hypervolume=hv_front,
            spread=spread(result, result.front),
            points=point_count(result.front),
        ),
        baseline=SetRecord(size=len(result.baseline), hypervolume=hv_base, spread=spread(result, result.baseline)),
        hypervolume_reference=result.reference,
        hypervolume_gain=hv_front - hv_base,
        hypervolume_gain_percent=(100.0 * (hv_front - hv_base) / hv_base) if hv_base > 0 else None,
        verification=result.verification,
        selected=result.front.policies[result.selected].name,
        timings_seconds={k: round(v, 4) for k, v in result.timings.items()},
        versions=versions(),
    )


def plot_front(result: RunResult, path: Path) -> None:
    robust = f", worst case of {len(result.scenarios)} scenarios" if len(result.scenarios) > 1 else ""
    scenarios = []
    if result.front_scenarios is not None and len(result.scenarios) > 1:
        scenarios = [(m.label, result.front_scenarios[:, s]) for s, m in enumerate(result.scenarios)]
    fig = front_figure(
        title=f"{result.prepared.case.name}: front vs baseline{robust}",
        objectives=result.family.objectives,
        front=np.array(result.front.values),
        baseline=np.array(result.baseline.values),
        baseline_names=[p.name for p in result.baseline.policies],
        selected=result.selected,
        selected_name=result.front.policies[result.selected].name,
        reference=result.reference,
        bound=None if result.bound is None else np.asarray(result.bound.points),
        scenarios=scenarios,
    )
    save(fig, path, dpi=130)


PLOT_ERROR = "policy-plot-error.txt"
"""Written instead of policy.png when a plugin's ``plot_policy`` raises."""
REPORT_ERROR = "report-error.txt"
"""Written instead of report.html when the interactive page cannot be made."""
MAP_ERROR = "map-error.txt"
"""Written instead of map.json when a plugin's ``policy_map`` raises (report.html then has no map)."""


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
        (staging / "front.csv").write_text(front_csv(result.front, points=True))
        (staging / "policies.csv").write_text(policy_files.wide_csv(family, result.front.policies))
        (staging / "decisions.csv").write_text(decisions_csv(family))
        constants = [s.constant for s in family.services]
        baseline_columns = {c: [b.values[c] for b in family.baselines] for c in constants}
        (staging / "baseline.csv").write_text(front_csv(result.baseline, baseline_columns))
        (staging / "summary.json").write_text(json.dumps(summary(result).to_json(), indent=2) + "\n")
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
        if case.policy_map is not None:
            _policy_map(case, result, staging)
        _interactive_report(staging)
        move_into_place(staging, out)
    except BaseException:
        shutil.rmtree(staging, ignore_errors=True)
        raise
    return sorted(out.iterdir())


def _policy_map(case, result: RunResult, staging: Path) -> None:
    """map.json, the plugin's map for report.html (a failure costs the map, not the run)."""
    try:
        found = case.policy_map(result.prepared.system)
        (staging / "map.json").write_text(json.dumps(found.to_json(), indent=1) + "\n")
    except Exception as exc:
        (staging / MAP_ERROR).write_text(
            f"the {case.name} plugin's policy_map failed, so report.html has no map:\n"
            + "".join(traceback.format_exception(exc))
        )


def _interactive_report(staging: Path) -> None:
    """report.html, from the files already written; a failure costs the page, not the run."""
    from parley_core.rundir import page
    from parley_core.rundir.read import load

    try:
        (staging / page.REPORT).write_text(page.render(load(staging)), encoding="utf-8")
    except Exception as exc:
        (staging / page.REPORT).unlink(missing_ok=True)
        (staging / REPORT_ERROR).write_text(
            "the interactive report could not be made, so there is no report.html:\n"
            + "".join(traceback.format_exception(exc))
        )


def move_into_place(staging: Path, out: Path) -> None:
    if out.exists():
        old = out.with_name(f".{out.name}.old")
        shutil.rmtree(old, ignore_errors=True)
        os.replace(out, old)
        os.replace(staging, out)
        shutil.rmtree(old, ignore_errors=True)
    else:
        os.replace(staging, out)
