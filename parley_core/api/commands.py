"""One function per command that makes results: :func:`run` (``parley run``),
:func:`exact` (``parley exact``), :func:`synthesize` (``parley synthesize``) and
:func:`experiment` (``parley experiment run``). The CLI calls the same functions, so
both give the same run directory for the same arguments.

Nothing here prints. ``progress=True`` draws rich progress bars on stderr (in a terminal
or a notebook), ``False`` draws none, and a :class:`~parley_core.progress.Reporter`
receives the stages instead. Errors are parley's exception types
(:class:`~parley_core.errors.ParleyError` for what the caller can fix).
"""

from __future__ import annotations

import time
from collections.abc import Callable, Iterable, Mapping, Sequence
from pathlib import Path
from typing import Any

from parley_core.api.runs import Check, Run, load
from parley_core.constraints import Constraint
from parley_core.errors import OptionError
from parley_core.evaluate import EvaluatorKind
from parley_core.optimality.records import BoundMethod
from parley_core.progress import Reporter
from parley_core.views.richprogress import reporting

DEFAULT_POPULATION = 100


def constraints_of(items: Iterable[str | Constraint] | None) -> tuple[Constraint, ...]:
    return tuple(c if isinstance(c, Constraint) else Constraint.parse(c) for c in items or ())


def search_settings(
    *,
    population: int = DEFAULT_POPULATION,
    generations: int | None = None,
    max_evaluations: int | None = None,
    time_limit: float | None = None,
    seed: int = 1,
    constraints: Iterable[str | Constraint] | None = None,
    algorithm: str | None = None,
) -> Any:
    """SearchSettings from the command's limits: without ``generations``, the default number
    of generations applies unless ``max_evaluations`` or ``time_limit`` is given."""
    from parley_core.search import SearchSettings, configuration, default

    algorithm = algorithm if algorithm is not None else default("algorithm")
    configuration(algorithm)  # an unknown name is a one-line error
    if generations is None and max_evaluations is None and time_limit is None:
        generations = default("generations")
    try:
        return SearchSettings(
            algorithm=algorithm,
            population=population,
            generations=generations,
            max_evaluations=max_evaluations,
            time_limit=time_limit,
            seed=seed,
            constraints=constraints_of(constraints),
        )
    except ValueError as exc:
        raise OptionError(f"{exc}; give positive limits") from None


def assignments_of(options: Mapping[str, Any]) -> list[str]:
    """Plugin options as ``--set`` gives them (``KEY=VALUE``)."""
    return [f"{key}={value}" for key, value in options.items()]


def prepare_case(
    case_name: str, assignments: Sequence[str] | None, reporter=None, scenarios: Sequence[str] | None = None
):
    """The case study's prepared run; with ``scenarios`` (``--scenarios`` values), a robust one."""
    from parley_core.family.prepare import prepare, prepare_scenarios
    from parley_core.family.scenarios import ScenarioSet
    from parley_core.plugin.manager import load_registry
    from parley_core.plugin.options import parse_assignments

    case = load_registry().get(case_name)
    if scenarios is not None:
        return prepare_scenarios(
            case, parse_assignments(assignments or []), ScenarioSet.parse(list(scenarios)), reporter
        )
    return prepare(case, case.options(list(assignments or [])), reporter)


def default_out(stem: str) -> Path:
    return Path("runs") / f"{stem}-{time.strftime('%Y%m%d-%H%M%S')}"


def run(
    case: str,
    *,
    seed: int = 1,
    population: int = DEFAULT_POPULATION,
    generations: int | None = None,
    max_evaluations: int | None = None,
    time_limit: float | None = None,
    algorithm: str | None = None,
    constraints: Iterable[str | Constraint] = (),
    evaluator: str = EvaluatorKind.QUOTIENT.value,
    workers: int | None = None,
    bound: str = "pareto",
    bound_time: float | None = 60.0,
    verify_with: str = "batch",
    scenarios: Sequence[str] | None = None,
    warm_start: str | Path | None = None,
    out: str | Path | None = None,
    force: bool = False,
    progress: bool | Reporter = True,
    options: Mapping[str, Any] | None = None,
    **more_options: Any,
) -> Run:
    """``parley run CASE``: search the case study's family, verify the front with Storm, write
    the run directory (``out``, default ``runs/CASE-TIME``) and return it as a :class:`Run`.

    Plugin options go as keywords (``map="map_10.csv"``) or, where a name is taken by a
    parameter here (robot_grid's map ``seed``), in ``options``.
    """
    assignments = assignments_of({**(options or {}), **more_options})
    return _searched(
        lambda r: prepare_case(case, assignments, r, scenarios),
        Path(out) if out is not None else default_out(case),
        progress,
        dict(
            seed=seed,
            population=population,
            generations=generations,
            max_evaluations=max_evaluations,
            time_limit=time_limit,
            algorithm=algorithm,
            constraints=constraints,
        ),
        force=force,
        evaluator=evaluator,
        workers=workers,
        bound=bound,
        bound_time=bound_time,
        verify_with=verify_with,
        warm_start=Path(warm_start) if warm_start is not None else None,
    )


def _searched(prepare_with, out: Path, progress: bool | Reporter, limits: dict[str, Any], **how: Any) -> Run:
    """A search run (``run``, ``synthesize``): its settings from ``limits``, then :func:`execute`."""
    settings = search_settings(**limits)
    with reporting(progress) as reporter:
        return execute(prepare_with, settings, out, reporter=reporter, **how)


def exact(
    case: str,
    *,
    seed: int = 1,
    time_limit: float | None = None,
    workers: int | None = None,
    out: str | Path | None = None,
    force: bool = False,
    progress: bool | Reporter = True,
    options: Mapping[str, Any] | None = None,
    **more_options: Any,
) -> Run:
    """``parley exact CASE``: a search, then branch and bound until the front is the family's
    whole Pareto front (or ``time_limit`` seconds: the front and bound so far)."""
    assignments = assignments_of({**(options or {}), **more_options})
    with reporting(progress) as reporter:
        return execute(
            lambda r: prepare_case(case, assignments, r),
            search_settings(seed=seed),
            Path(out) if out is not None else default_out(f"{case}-exact"),
            reporter=reporter,
            force=force,
            workers=workers,
            bound="refine",
            bound_time=time_limit,
        )


CHECK_SECONDS = 300.0
"""A check's time limit when none is given."""


def check(
    case: str,
    require: Iterable[str | Constraint],
    *,
    time_limit: float | None = CHECK_SECONDS,
    seed: int = 1,
    generations: int | None = None,
    workers: int | None = None,
    out: str | Path | None = None,
    force: bool = False,
    progress: bool | Reporter = True,
    options: Mapping[str, Any] | None = None,
    command: str | None = None,
    **more_options: Any,
) -> Check:
    """``parley check CASE --require ...``: is there a policy of the case study's family that
    meets every requirement (``"success>=0.8"``, ``"cost<=60"``)? Within ``time_limit``
    seconds (None: until answered) the answer is "feasible" (a policy inside, verified by
    Storm, written as a run directory with its controller), "infeasible" (a certificate) or
    "unknown"; see :class:`~parley_core.api.runs.Check`."""
    assignments = assignments_of({**(options or {}), **more_options})
    return _checked(
        lambda r: prepare_case(case, assignments, r),
        require,
        Path(out) if out is not None else default_out(f"{case}-check"),
        progress,
        dict(seed=seed, generations=generations, time_limit=time_limit, workers=workers, force=force, command=command),
    )


def check_model(
    model: str | Path,
    require: Iterable[str | Constraint],
    *,
    props: str | Path,
    decisions: Mapping[str, tuple[int, int] | str] | Sequence[str],
    observe: Sequence[str] = (),
    maximize: Sequence[str] = (),
    minimize: Sequence[str] = (),
    time_limit: float | None = CHECK_SECONDS,
    seed: int = 1,
    generations: int | None = None,
    workers: int | None = None,
    out: str | Path | None = None,
    force: bool = False,
    progress: bool | Reporter = True,
    command: str | None = None,
) -> Check:
    """:func:`check` for your own PRISM DTMC, with :func:`synthesize`'s arguments."""
    path = Path(model)
    return _checked(
        synthesis_preparer(path, Path(props), decisions, observe, maximize, minimize, None),
        require,
        Path(out) if out is not None else default_out(f"{path.stem}-check"),
        progress,
        dict(
            seed=seed,
            generations=generations,
            time_limit=time_limit,
            workers=workers,
            force=force,
            command=command,
            model={
                "path": str(path.resolve()),
                "props": str(Path(props).resolve()),
                "decisions": decision_specs(decisions),
                "observe": list(observe),
                "maximize": list(maximize),
                "minimize": list(minimize),
            },
        ),
    )


def recheck(directory: str | Path) -> int:
    """``parley recheck DIR``: check the certificate of an infeasible answer again from the
    family alone (built again from the case study and options, or the model, ``check.json``
    names): returns how many sub-families it holds; a certificate that does not hold is a
    :class:`~parley_core.errors.ParleyDefect` naming the first that fails."""
    import json

    import numpy as np

    from parley_core.api.runs import load_check
    from parley_core.optimality.requirement import read_certificate
    from parley_core.optimality.requirement import recheck as recheck_certificate
    from parley_core.progress import NullReporter
    from parley_core.quotient.coloring import build_quotient
    from parley_core.quotient.solver import QuotientSolver

    found = load_check(directory)
    if found.answer != "infeasible" or found.certificate is None:
        raise OptionError(f"the check in {found.directory} is {found.answer}: it has no certificate to check again")
    document = found.document
    model = document.get("model")
    if model is not None:
        preparer = synthesis_preparer(
            Path(model["path"]), Path(model["props"]), model["decisions"], model["observe"], model["maximize"],
            model["minimize"], None,
        )  # fmt: skip
        family = preparer(NullReporter()).family
    else:
        family = prepare_case(document["case_study"], assignments_of(document.get("options", {}))).family
    requirement, closed = read_certificate(family, json.loads(found.certificate.read_text()))
    quotient = build_quotient(family)
    solver = QuotientSolver(quotient)
    recheck_certificate(
        family, quotient, requirement, closed, lambda rows: np.array([solver.solve(row) for row in rows], dtype=float)
    )
    return len(closed)


def _checked(prepare_with, require, out: Path, progress: bool | Reporter, how: dict[str, Any]) -> Check:
    from parley_core.api.runs import load_check
    from parley_core.pipeline import check as run_check
    from parley_core.rundir.check import write_check
    from parley_core.rundir.write import check_output

    requirements = constraints_of(require)
    if not requirements:
        raise OptionError("give at least one requirement, e.g. --require success>=0.8")
    check_output(out, how["force"])
    generations = how["generations"]
    settings = search_settings(seed=how["seed"], generations=generations)
    with reporting(progress) as reporter:
        prepared = prepare_with(reporter)
        result = run_check(
            prepared, settings, requirements, time_limit=how["time_limit"], workers=how["workers"], reporter=reporter
        )
        reporter.stage("write")
        write_check(result, out, force=how["force"], command=how["command"], model=how.get("model"))
    return load_check(out)


def synthesize(
    model: str | Path,
    *,
    props: str | Path,
    decisions: Mapping[str, tuple[int, int] | str] | Sequence[str],
    observe: Sequence[str] = (),
    maximize: Sequence[str] = (),
    minimize: Sequence[str] = (),
    seed: int = 1,
    population: int = DEFAULT_POPULATION,
    generations: int | None = None,
    max_evaluations: int | None = None,
    time_limit: float | None = None,
    algorithm: str | None = None,
    constraints: Iterable[str | Constraint] = (),
    evaluator: str = EvaluatorKind.QUOTIENT.value,
    workers: int | None = None,
    bound: str = "pareto",
    bound_time: float | None = 60.0,
    verify_with: str = "batch",
    scenarios: Sequence[str] | None = None,
    warm_start: str | Path | None = None,
    out: str | Path | None = None,
    force: bool = False,
    progress: bool | Reporter = True,
) -> Run:
    """``parley synthesize MODEL``: the same pipeline over your own PRISM DTMC.

    ``decisions``: ``{"c": (1, 8)}`` (a frequency decision over 1..8), ``{"c": "1..8:threshold"}``
    or the CLI's ``["c=1..8"]``; ``observe``: the variables the URC may read."""
    path = Path(model)
    return _searched(
        synthesis_preparer(path, Path(props), decisions, observe, maximize, minimize, scenarios),
        Path(out) if out is not None else default_out(path.stem),
        progress,
        dict(
            seed=seed,
            population=population,
            generations=generations,
            max_evaluations=max_evaluations,
            time_limit=time_limit,
            algorithm=algorithm,
            constraints=constraints,
        ),
        force=force,
        evaluator=evaluator,
        workers=workers,
        bound=bound,
        bound_time=bound_time,
        verify_with=verify_with,
        warm_start=Path(warm_start) if warm_start is not None else None,
    )


def synthesis_preparer(
    model: Path,
    props: Path,
    decisions: Mapping[str, tuple[int, int] | str] | Sequence[str],
    observe: Sequence[str],
    maximize: Sequence[str],
    minimize: Sequence[str],
    scenarios: Sequence[str] | None,
) -> Callable[[Reporter], Any]:
    """What prepares a user model's run (a robust one with ``scenarios``)."""
    from parley_core.family.prepare import prepare, prepare_scenarios
    from parley_core.family.scenarios import ScenarioSet
    from parley_core.family.usermodel import FileOptions, case_study_for, system_from_file

    specs = decision_specs(decisions)

    def read(constants=None):
        return system_from_file(model, specs, list(observe), props, list(maximize), list(minimize), constants)

    def prepare_with(reporter: Reporter):
        reporter.stage("read model")
        if scenarios is not None:
            chosen = ScenarioSet.parse(list(scenarios))
            return prepare_scenarios(case_study_for(read(), model, rebuild=read), {}, chosen, reporter)
        return prepare(case_study_for(read(), model), FileOptions(model=str(model)), reporter)

    return prepare_with


def decision_specs(decisions: Mapping[str, tuple[int, int] | str] | Sequence[str]) -> list[str]:
    """``--decision`` texts (``NAME=LOW..HIGH[:KIND]``) from the API's forms."""
    if isinstance(decisions, Mapping):
        specs = []
        for name, domain in decisions.items():
            if isinstance(domain, str):
                specs.append(f"{name}={domain}")
            else:
                low, high = domain
                specs.append(f"{name}={int(low)}..{int(high)}")
        return specs
    if isinstance(decisions, str):
        return [decisions]
    return list(decisions)


def execute(
    prepare_with: Callable[[Reporter], Any],
    settings: Any,
    out: Path,
    *,
    reporter: Reporter,
    force: bool = False,
    evaluator: str = EvaluatorKind.QUOTIENT.value,
    workers: int | None = None,
    bound: BoundMethod | str = BoundMethod.PARETO,
    bound_time: float | None = None,
    verify_with: str = "batch",
    warm_start: Path | None = None,
) -> Run:
    """Prepare, search, verify and write a run; returns it (shared by every command here)."""
    from parley_core.pipeline import run as run_pipeline
    from parley_core.rundir.write import check_output, write_run
    from parley_core.verify import VerifyPath

    kind = EvaluatorKind.of(evaluator)
    path = VerifyPath.of(verify_with)
    method = BoundMethod.of(bound)
    check_output(out, force)
    prepared = prepare_with(reporter)
    warm = []
    if warm_start is not None:
        from parley_core.rundir.policies import read_policies

        if not (warm_start / "policies.csv").is_file():
            raise OptionError(f"--warm-start {warm_start}: no policies.csv there; give a run directory")
        warm = read_policies(warm_start / "policies.csv", prepared.family)
    result = run_pipeline(
        prepared,
        settings,
        evaluator=kind,
        workers=workers,
        reporter=reporter,
        bound=method,
        bound_time=bound_time,
        verify_with=path,
        warm=warm,
    )
    reporter.stage("write report")
    write_run(result, out, force=force)
    return load(out, result=result)
