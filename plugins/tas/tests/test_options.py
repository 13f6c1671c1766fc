"""Options, the system model's interface, and errors a user can cause."""

from __future__ import annotations

import pytest

from parley_core import Direction, OptionError, testing
from parley_plugins.tas import CASE_STUDY as CASE


def test_the_system_model_names_its_service_observation_objectives_and_baselines():
    system = CASE.build(CASE.options())
    assert system.observation == ("bhat", "load")
    (service,) = system.services
    assert (service.constant, service.low, service.high) == ("c", 1, 11)
    assert [(o.name, o.direction, o.formula) for o in system.objectives] == [
        ("failure", Direction.MIN, 'R{"failures"}=? [C<=210]'),
        ("cost", Direction.MIN, 'R{"cost"}=? [C<=210]'),
    ]
    assert [b.name for b in system.baselines] == [*(f"every-{k}" for k in range(1, 11)), "never"]
    assert [b.values["c"] for b in system.baselines] == list(range(1, 12))
    family = testing.family(system)
    assert family.names == ("c_0_0", "c_0_1", "c_1_0", "c_1_1", "c_2_0", "c_2_1")


def test_response_time_is_an_optional_third_objective():
    system = CASE.build(CASE.options(["response_time=true", "rounds=4"]))
    assert [o.name for o in system.objectives] == ["failure", "cost", "response_time"]
    assert system.objectives[2].formula == 'R{"time"}=? [C<=28]'


def test_more_health_levels_give_more_decisions():
    family = testing.family(CASE.build(CASE.options(["backup_levels=0.05,0.1,0.2,0.5,1", "max_interval=3"])))
    assert len(family.decisions) == 10
    assert family.highs == (4,) * 10


@pytest.mark.parametrize(
    ("setting", "message"),
    [
        ("backup_levels=0.05;0.3", "separated by commas"),
        ("backup_levels=0.05", "2 to 6 failure rates"),
        ("backup_levels=0.05,1.5", "2 to 6 failure rates"),
        ("degrade=0.95", "degrade \\+ recover"),
        ("p_drug=0.6", "exceeds 1"),
        ("p_vital=1.2", "p_vital"),
        ("rounds=0", "rounds must be positive"),
        ("probe_cost=-1", "probe_cost"),
    ],
)
def test_bad_options_say_what_to_change(setting, message):
    with pytest.raises(OptionError, match=message):
        CASE.build(CASE.options([setting]))
