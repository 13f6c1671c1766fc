"""The thermostat plugin's tests: parley's conformance suite, and values worked out by hand.

They use parley's test kit only (``parley_core.testing``), never parley's internals.
"""

from __future__ import annotations

import pytest

from parley_core.testing import family, values
from parley_core.testing.suite import ConformanceSuite


class TestConformance(ConformanceSuite):
    case_studies = ("thermostat",)


@pytest.fixture(scope="module")
def thermostat():
    return family("thermostat", ["rounds=6"])


def test_calibrating_every_round_keeps_the_room_comfortable(thermostat):
    # The controller always knows the temperature and corrects one level of drift at a
    # time, so the room never gets to 0 or 4; 6 rounds are 6 calibrations.
    discomfort, calibrations = values(thermostat, thermostat.uniform("every-1", {"c": 1}))[0]
    assert discomfort == pytest.approx(0.0, abs=1e-12)
    assert calibrations == pytest.approx(6.0, abs=1e-9)


def test_calibrating_less_often_costs_less_and_risks_more(thermostat):
    found = values(thermostat, thermostat.baseline_policies())
    discomfort, calibrations = found[:, 0], found[:, 1]
    # the counter starts at 1 and calibrates when it reaches c: rounds // c calibrations in 6 rounds
    assert list(calibrations) == pytest.approx([6.0, 3.0, 2.0, 1.0], abs=1e-9)
    assert discomfort[1] > 0 and discomfort[3] >= discomfort[1]


def test_the_fast_evaluator_agrees_with_storm(thermostat):
    policies = thermostat.baseline_policies()
    assert values(thermostat, policies, evaluator="quotient") == pytest.approx(values(thermostat, policies), abs=1e-9)
