"""What every command shares: one-line user errors, case studies, search limits."""

from __future__ import annotations

import functools
import sys
from typing import Any

import typer

from parley_core.casestudy import CaseStudy
from parley_core.constraints import Constraint
from parley_core.errors import OptionError, ParleyDefect, ParleyError

USER_ERROR = 2
"""The exit status of an error the user can fix (a ParleyError)."""
DEFECT = 3
"""The exit status of a defect of parley (a ParleyDefect, such as evaluators that disagree)."""


def user_errors(command):
    """Turn ParleyError into one line on stderr and exit status 2, ParleyDefect into one
    line and exit status 3."""

    @functools.wraps(command)
    def wrapper(*args, **kwargs):
        try:
            return command(*args, **kwargs)
        except ParleyError as exc:
            print(f"error: {' '.join(str(exc).split())}", file=sys.stderr)
            raise typer.Exit(USER_ERROR) from None
        except ParleyDefect as exc:
            print(f"error: parley defect: {' '.join(str(exc).split())}", file=sys.stderr)
            raise typer.Exit(DEFECT) from None

    return wrapper


def registry():
    from parley_core.plugins import load_registry

    return load_registry()


def case_study(name: str) -> CaseStudy:
    return registry().get(name)


def prepare_case(case_name: str, assignments: list[str] | None, reporter=None, scenarios: list[str] | None = None):
    """The case study's prepared run; with ``scenarios`` (``--scenarios`` values), a robust one."""
    from parley_core.options import parse_assignments
    from parley_core.pipeline import prepare, prepare_scenarios
    from parley_core.scenarios import ScenarioSet

    case = case_study(case_name)
    if scenarios is not None:
        return prepare_scenarios(case, parse_assignments(assignments or []), ScenarioSet.parse(scenarios), reporter)
    options = case.options(assignments or [])
    return prepare(case, options, reporter)


def constraints(texts: list[str] | None) -> tuple[Constraint, ...]:
    return tuple(Constraint.parse(t) for t in texts or [])


def search_settings(
    *,
    population: int,
    generations: int | None,
    max_evaluations: int | None,
    time_limit: float | None,
    seed: int,
    constraint: list[str] | None = None,
    algorithm: str | None = None,
) -> Any:
    """SearchSettings from the command line: without ``--generations``, the default number
    of generations applies unless ``--max-evaluations`` or ``--time-limit`` is given."""
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
            constraints=constraints(constraint),
        )
    except ValueError as exc:
        raise OptionError(f"{exc}; give positive limits") from None
