"""The conformance suite as pytest tests, for parley and for third-party plugins.

In a plugin's own tests, one class runs it on the plugin's case studies::

    from parley_core.testing.suite import ConformanceSuite

    class TestConformance(ConformanceSuite):
        case_studies = ("thermostat",)

``case_studies`` None (the default) means every installed case study, or those named by
``pytest --parley-case NAME``. ``pytest --parley-case NAME`` alone, without any test file,
runs :class:`TestInstalledCaseStudies` below (parley's pytest plugin adds this module to
the collection).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import Any

import pytest

from parley_core.errors import ParleyError
from parley_core.testing import case_study
from parley_core.testing.conformance import (
    ConformanceError,
    check_baselines,
    check_model,
    check_options,
    check_policy_map,
    check_search,
    prepare_quick,
)


def _checked(check: Callable[..., Any], *args: Any) -> Any:
    """``check(*args)``; a contract failure or a parley error fails the test with its
    one-line message alone, not parley's frames."""
    __tracebackhide__ = True
    try:
        return check(*args)
    except (ConformanceError, ParleyError) as error:
        failure = f"{type(error).__name__}: {error}"
    pytest.fail(failure, pytrace=False)  # outside the handler: no chained traceback


class ConformanceSuite:
    """Subclass it in a test module (the class name must start with ``Test``)."""

    case_studies: Sequence[str] | None = None
    """The case studies to check; None: those of ``--parley-case``, else every installed one."""
    options: dict[str, str] | None = None
    """Option values (``--set`` strings) to check them with; None: each one's ``quick`` options."""

    def pytest_generate_tests(self, metafunc: pytest.Metafunc) -> None:
        if "parley_case_name" in metafunc.fixturenames:
            names = list(self.case_studies) if self.case_studies is not None else None
            if names is None:
                names = metafunc.config.getoption("parley_case", default=None) or None
            if names is None:
                from parley_core.plugin.manager import load_registry

                names = load_registry(strict=True).names
            metafunc.parametrize("parley_case_name", names, scope="class")

    @pytest.fixture(scope="class")
    @classmethod
    def parley_prepared(cls, parley_case_name: str):
        return _checked(prepare_quick, _checked(case_study, parley_case_name), cls.options)

    def test_options_are_frozen_and_explained(self, parley_case_name: str) -> None:
        _checked(check_options, _checked(case_study, parley_case_name))

    def test_model_parses_and_names_what_exists(self, parley_prepared) -> None:
        _checked(check_model, parley_prepared)

    def test_policy_map_fits_the_observation(self, parley_prepared) -> None:
        _checked(check_policy_map, parley_prepared)

    def test_baselines_build_and_check(self, parley_prepared) -> None:
        _checked(check_baselines, parley_prepared)

    def test_tiny_search_gives_a_front_that_storm_confirms(self, parley_prepared, tmp_path) -> None:
        _checked(check_search, parley_prepared, tmp_path)


class TestInstalledCaseStudies(ConformanceSuite):
    """The suite on the case studies of ``--parley-case`` (or every installed one)."""
