"""Campaigns: many instances x repetitions of one case study, resumable, local or on Dask.

A campaign is planned as :class:`RunSpec` values (instance options, repetition, seed,
budget); :func:`run_spec` runs one and returns a :class:`RunRecord` (a pure function of the
spec, picklable, so any executor can call it); :func:`execute` sends the runs that the
store does not hold yet to a local process pool, or to a Dask cluster, and stores each
finished run as it arrives. Only the calling process writes the store.
"""

from __future__ import annotations

import glob
import itertools
import os
from collections.abc import Iterable, Sequence
from concurrent.futures import as_completed
from pathlib import Path
from typing import Any

import numpy as np
from attrs import asdict, evolve, field, frozen

from parley_core.errors import OptionError
from parley_core.evaluate import EvaluatorKind
from parley_core.evaluate.pool import default_workers, spawn_pool
from parley_core.experiment.store import RunRecord, Store, front_from_json
from parley_core.plugin.casestudy import CaseStudy
from parley_core.plugin.options import options_as_dict, parse_assignments
from parley_core.progress import Progress
from parley_core.search import SearchSettings
from parley_core.search import default as search_default


@frozen(kw_only=True)
class Budget:
    """What every run of a campaign shares: search budget, evaluator, verification."""

    algorithm: str = search_default("algorithm")
    population: int = search_default("population")
    generations: int | None = search_default("generations")
    evaluator: str = field(default=EvaluatorKind.QUOTIENT.value, converter=lambda k: EvaluatorKind.of(k).value)
    verify: bool = True
    max_evaluations: int | None = None
    time_limit: float | None = None

    def settings(self, seed: int) -> SearchSettings:
        return SearchSettings(
            algorithm=self.algorithm,
            population=self.population,
            generations=self.generations,
            max_evaluations=self.max_evaluations,
            time_limit=self.time_limit,
            seed=seed,
        )


@frozen(kw_only=True)
class RunSpec:
    campaign: str
    case: str
    instance: str
    assignments: tuple[str, ...] = field(converter=tuple[str, ...])
    repetition: int
    seed: int
    budget: Budget


def instance_label(assignments: Sequence[str]) -> str:
    """A short, stable name for an instance: ``map=…/map_10.csv`` -> ``map_10``; ``size=5 seed=1`` as is."""
    parts = []
    for key, value in parse_assignments(assignments).items():
        path = Path(value)
        is_file = os.sep in value or (path.suffix and not path.suffix[1:].isdigit())
        parts.append(path.stem if is_file else f"{key}={value}")
    return " ".join(parts) or "default"


def instances_from(
    case: CaseStudy, grid: Sequence[str] = (), files: str | None = None, option: str | None = None
) -> list[tuple[str, ...]]:
    """Instances as option assignments: the product of ``--grid KEY=V1,V2`` values, and/or one
    per file of a directory or glob (given to ``option``, by default the case study's first
    path-typed option)."""
    axes: list[list[str]] = []
    for item in grid:
        key, sep, values = item.partition("=")
        if not sep or not key or not values:
            raise OptionError(f"malformed --grid {item!r}; write KEY=V1,V2,... for example --grid seed=1,2,3")
        axes.append([f"{key.strip()}={v.strip()}" for v in values.split(",") if v.strip()])
    if files is not None:
        if option is None:
            paths = [f.name for f in case.option_fields() if "Path" in str(f.type)]
            if not paths:
                raise OptionError(f"{case.name} has no file option for --instances; use --grid instead")
            option = paths[0]
        matches = sorted(glob.glob(os.path.join(files, "*"))) if os.path.isdir(files) else sorted(glob.glob(files))
        matches = [m for m in matches if os.path.isfile(m)]
        if not matches:
            raise OptionError(
                f"--instances {files!r} matches no file; give a directory or a glob such as 'maps/map_*.csv'"
            )
        axes.append([f"{option}={m}" for m in _natural(matches)])
    if not axes:
        return [()]
    return [tuple(combination) for combination in itertools.product(*axes)]


def _natural(paths: list[str]) -> list[str]:
    """Sort so that map_9 comes before map_10."""

    def key(path: str):
        stem = Path(path).stem
        digits = "".join(ch if ch.isdigit() else " " for ch in stem).split()
        return (stem.rstrip("0123456789"), [int(d) for d in digits], path)

    return sorted(paths, key=key)


def plan(
    name: str,
    case: CaseStudy,
    instances: Iterable[Sequence[str]],
    fixed: Sequence[str],
    repetitions: int,
    budget: Budget,
    first_seed: int = 1,
) -> list[RunSpec]:
    """One spec per instance and repetition; repetition r uses seed ``first_seed + r``."""
    if repetitions < 1:
        raise OptionError("--reps must be at least 1")
    specs = []
    for assignments in instances:
        combined = tuple(fixed) + tuple(assignments)
        case.options(combined)  # check every instance's options before anything runs
        label = instance_label(assignments) if assignments else "default"
        for repetition in range(repetitions):
            specs.append(
                RunSpec(
                    campaign=name,
                    case=case.name,
                    instance=label,
                    assignments=combined,
                    repetition=repetition,
                    seed=first_seed + repetition,
                    budget=budget,
                )
            )
    labels = [s.instance for s in specs if s.repetition == 0]
    duplicates = sorted({label for label in labels if labels.count(label) > 1})
    if duplicates:
        raise OptionError(f"instances {', '.join(duplicates)} occur twice in the campaign; give each once")
    return specs


def run_spec(spec: RunSpec) -> RunRecord:
    """Run one campaign run in this process (one worker: campaigns parallelize over runs)."""
    from parley_core.family.prepare import prepare
    from parley_core.pipeline import run
    from parley_core.plugin.manager import load_registry
    from parley_core.prism.program import quiet_storm

    quiet_storm()  # on a Dask worker this is the entry point
    case = load_registry().get(spec.case)
    options = case.options(spec.assignments)
    prepared = prepare(case, options)
    # no bound per run: it depends on the instance alone and costs seconds on a 10x10 map,
    # which 900 runs would repeat (a per-instance bound for the report is still to come)
    result = run(
        prepared,
        spec.budget.settings(spec.seed),
        evaluator=spec.budget.evaluator,
        workers=1,
        verify=spec.budget.verify,
        bound="none",
    )
    family = result.family
    return RunRecord(
        campaign=spec.campaign,
        instance=spec.instance,
        repetition=spec.repetition,
        seed=spec.seed,
        options=options_as_dict(options),
        objectives=family.objectives,
        front=result.front,
        baseline=result.baseline,
        summary={
            "decisions": len(family.decisions),
            "evaluations": result.search.evaluations,
            "generations": result.search.generations,
            "timings": {k: round(v, 4) for k, v in result.timings.items()},
            "verification": result.verification.to_json(),
            "evaluator": result.evaluator.value,
            "evaluator_details": result.evaluator_info,
        },
    )


@frozen(kw_only=True)
class Outcome:
    planned: int
    skipped: int
    stored: int
    failures: list[tuple[str, int, str]]


def execute(
    specs: Sequence[RunSpec],
    store: Store,
    *,
    workers: int | None = None,
    scheduler: str | None = None,
    progress: Progress | None = None,
) -> Outcome:
    """Run what the store lacks; store each run as it finishes. A failed run is reported and
    not stored (rerunning the campaign retries it)."""
    done = store.done(specs[0].campaign) if specs else set()
    todo = [s for s in specs if (s.instance, s.repetition) not in done]
    stored = 0
    failures: list[tuple[str, int, str]] = []

    def finish(spec: RunSpec, result: RunRecord | None, error: BaseException | None) -> None:
        nonlocal stored
        if error is not None:
            failures.append((spec.instance, spec.repetition, f"{type(error).__name__}: {error}"))
        else:
            assert result is not None  # a run that raised nothing returned its record
            if store.add(result):
                stored += 1
        if progress:
            progress(1)

    if todo and scheduler is not None:
        _execute_dask(todo, scheduler, finish)
    elif todo:
        workers = default_workers(workers)
        if workers == 1:
            for spec in todo:
                try:
                    record = run_spec(spec)
                except Exception as exc:  # a failed run must not stop the campaign
                    finish(spec, None, exc)
                else:
                    finish(spec, record, None)
        else:
            with spawn_pool(workers) as pool:
                futures = {pool.submit(run_spec, spec): spec for spec in todo}
                for future in as_completed(futures):
                    spec = futures[future]
                    error = future.exception()
                    finish(spec, None if error else future.result(), error)
    return Outcome(planned=len(specs), skipped=len(specs) - len(todo), stored=stored, failures=failures)


def _execute_dask(todo: Sequence[RunSpec], scheduler: str, finish) -> None:
    try:
        from dask.distributed import Client
        from dask.distributed import as_completed as dask_completed
    except ImportError:
        raise OptionError("--scheduler needs Dask: pip install 'parley[dask]' (dask[distributed])") from None
    try:
        client = Client(scheduler, timeout="20s")
    except (OSError, TimeoutError) as exc:
        raise OptionError(f"cannot reach the Dask scheduler at {scheduler} ({exc}); check the address") from None
    try:
        futures = {
            client.submit(
                run_spec, spec, pure=False, key=f"parley-{spec.campaign}-{spec.instance}-{spec.repetition}"
            ): spec
            for spec in todo
        }
        for future in dask_completed(futures):
            spec = futures[future]
            error = future.exception()
            finish(spec, None if error else future.result(), error)
    finally:
        client.close()


def describe(budget: Budget, fixed: Sequence[str]) -> dict[str, Any]:
    """A campaign's settings as its store records them (limits that are not set are left out,
    so stores of campaigns without them resume)."""
    settings = asdict(budget)
    for key in ("max_evaluations", "time_limit"):
        if settings[key] is None:
            del settings[key]
    if settings["algorithm"] == "paper":  # stores from before there was a choice
        del settings["algorithm"]
    return {**settings, "fixed_options": list(fixed)}


def verify_record(case_name: str, record: RunRecord) -> RunRecord:
    """Re-check a stored front with the Storm evaluator; keep Storm's values and the
    non-dominated policies among them, and record the largest difference."""
    from parley_core import metrics
    from parley_core.family.prepare import prepare
    from parley_core.plugin.manager import load_registry
    from parley_core.verify import check_with_storm

    case = load_registry().get(case_name)
    family = prepare(case, case.options_from_json(record.options)).family
    policies = np.array([p.values for p in record.front.policies], dtype=np.int64).reshape(-1, len(family.decisions))
    searched = record.values()[0]
    verification, checked = check_with_storm(family, policies, searched, workers=1)
    keep = metrics.tolerant_front(checked, [o.direction for o in record.objectives])
    front = front_from_json(record.objectives, {"policies": policies[keep].tolist(), "values": checked[keep].tolist()})
    return evolve(record, front=front, summary={**record.summary, "verification": verification.to_json()})


def verify_stored(
    store: Store,
    campaign: str,
    case_name: str,
    *,
    workers: int | None = None,
    repetitions: set[int] | None = None,
    progress: Progress | None = None,
) -> tuple[int, int, float]:
    """Verify every stored front of a campaign (of the given repetitions, or all) that Storm
    has not checked yet; returns (verified now, already verified, largest difference)."""
    records = [r for r in store.runs(campaign) if repetitions is None or r.repetition in repetitions]
    todo = [r for r in records if not r.verified]
    worst = 0.0
    with spawn_pool(default_workers(workers)) as pool:
        futures = {pool.submit(verify_record, case_name, r): r for r in todo}
        for future in as_completed(futures):
            checked = future.result()
            store.replace_front(checked)
            verification = checked.verification
            assert verification is not None  # verify_record records it
            worst = max(worst, verification.max_difference)
            if progress:
                progress(1)
    return len(todo), len(records) - len(todo), worst
