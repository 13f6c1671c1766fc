"""What every command shares: one-line user errors, case studies, search limits."""

from __future__ import annotations

import functools
import sys

import typer

from parley_core.api.commands import prepare_case, search_settings  # noqa: F401  (re-exported for the commands)
from parley_core.constraints import Constraint
from parley_core.errors import ParleyDefect, ParleyError
from parley_core.plugin.casestudy import CaseStudy

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
    from parley_core.plugin.manager import load_registry

    return load_registry()


def case_study(name: str) -> CaseStudy:
    return registry().get(name)


def constraints(texts: list[str] | None) -> tuple[Constraint, ...]:
    return tuple(Constraint.parse(t) for t in texts or [])
