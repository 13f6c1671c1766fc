"""The test kit for plugin authors: the shipped conformance suite, run as a plugin author
runs it (in a pytest of its own), and checks that fail on a case study that breaks the contract."""

from __future__ import annotations

import attrs
import pytest

from parley_core import CaseStudy
from parley_core.testing import family, values
from parley_core.testing.conformance import ConformanceError, check_baselines, check_model, prepare_quick


@pytest.mark.slow
def test_one_option_runs_the_shipped_suite_on_an_installed_case_study(pytester):
    result = pytester.runpytest_subprocess("--parley-case", "tas", "-p", "no:cacheprovider")
    result.assert_outcomes(passed=5)


@pytest.mark.slow
def test_one_class_runs_the_suite_in_a_plugins_own_tests(pytester):
    pytester.makepyfile(
        test_mine="""
        from parley_core.testing.suite import ConformanceSuite

        class TestMine(ConformanceSuite):
            case_studies = ("web_ids",)
        """
    )
    pytester.runpytest_subprocess("-p", "no:cacheprovider").assert_outcomes(passed=5)


def test_a_case_study_without_baselines_fails_the_suite(toy):
    @attrs.frozen
    class NoOptions:
        pass

    bare = attrs.evolve(toy, baselines=())
    case = CaseStudy(name="bare", description="no baselines", options_type=NoOptions, build=lambda _options: bare)
    prepared = prepare_quick(case)
    check_model(prepared)
    with pytest.raises(ConformanceError, match="bare: a case study should offer at least one baseline policy"):
        check_baselines(prepared)


def test_family_and_values_evaluate_as_a_run_does(toy):
    toy_family = family(toy)
    policies = toy_family.baseline_policies()
    storm = values(toy_family, policies)
    assert storm.shape == (3, 2)
    assert values(toy_family, policies, evaluator="quotient") == pytest.approx(storm, abs=1e-9)
    robot = family("robot_grid", ["size=4", "max_interval=3", "horizon=30"])
    assert len(robot.decisions) == 16 and robot.system is not None
