"""Augmentation: the canonical form, its meaning (checked by Storm), and its errors."""

from __future__ import annotations

import pytest
import stormpy

from conftest import TOY, storm_values, toy_system
from parley_core import DecisionKind, Service
from parley_core.errors import ModelError
from parley_core.evaluate.storm import StormEvaluator
from parley_core.family.augment import augment
from parley_core.model import Policy

FORMULAS = ['R{"cost"}=? [C<=10]', 'P=? [F<=3 !"healthy"]']


def test_decision_constants_are_named_after_constant_and_valuation(toy):
    family = augment(toy)
    assert family.names == ("c_0", "c_1")
    assert family.valuations == ((0,), (1,))
    undefined = [c for c in stormpy.parse_prism_program(_write(family.prism)).constants if not c.defined]
    assert sorted(c.name for c in undefined) == ["c_0", "c_1"]


def test_uniform_policy_equals_the_original_model_with_that_constant(toy):
    family = augment(toy)
    for k in (1, 2, 3):
        original = storm_values(TOY, FORMULAS, {"c": k})
        augmented = storm_values(family.prism, FORMULAS, {"c_0": k, "c_1": k})
        assert augmented == pytest.approx(original, abs=1e-12)


def test_policy_depends_on_observation_as_a_hand_written_model_does(toy):
    # The same policy written by hand: c is 1 in phase 0 and 3 in phase 1.
    by_hand = TOY.replace("const int c;", "formula c = (phase=0 ? 1 : 3);")
    expected = storm_values(by_hand, FORMULAS)
    family = augment(toy)
    got = storm_values(family.prism, FORMULAS, {"c_0": 1, "c_1": 3})
    assert got == pytest.approx(expected, abs=1e-12)
    # and not the same as the uniform policies (the observation matters)
    assert got != pytest.approx(storm_values(TOY, FORMULAS, {"c": 1}), abs=1e-6)
    assert got != pytest.approx(storm_values(TOY, FORMULAS, {"c": 3}), abs=1e-6)


def test_storm_evaluator_matches_plain_stormpy(toy):
    family = augment(toy)
    with StormEvaluator(family, workers=1) as evaluator:
        values = evaluator.evaluate([[1, 3], [2, 2]])
    assert values[0] == pytest.approx(storm_values(family.prism, FORMULAS, {"c_0": 1, "c_1": 3}), abs=1e-9)
    assert values[1] == pytest.approx(storm_values(TOY, FORMULAS, {"c": 2}), abs=1e-9)


def test_negative_and_boolean_observations_name_decisions():
    text = TOY.replace("phase : [0..1] init 0;", "phase : [-2..1] init 0;").replace(
        "(phase'=1-phase)", "(phase'=min(phase+1, 1))"
    )
    text = text.replace("h : [0..1] init 1;", "h : [0..1] init 1;\n  flag : bool init false;")
    family = augment(toy_system(prism=text, observation=("phase", "flag")))
    assert family.names[:3] == ("c_m2_0", "c_m2_1", "c_m1_0")
    assert len(family.names) == 8


def test_two_services_get_one_decision_each_per_valuation():
    text = TOY.replace("const int c;", "const int c;\nconst int d;").replace("step<c & h=0", "step<c & h=0 & d>0")
    system = toy_system(
        prism=text,
        services=[
            Service(name="probe", constant="c", kind=DecisionKind.FREQUENCY, low=1, high=3),
            Service(name="other", constant="d", kind=DecisionKind.THRESHOLD, low=0, high=1),
        ],
        baselines=[],
    )
    family = augment(system)
    assert family.names == ("c_0", "d_0", "c_1", "d_1")


def test_the_family_checks_policy_ranges(toy):
    family = augment(toy)
    family.check(Policy(name="ok", values=[1, 3]))
    with pytest.raises(Exception, match="outside 1..3"):
        family.check(Policy(name="bad", values=[0, 3]))


@pytest.mark.parametrize(
    ("change", "message"),
    [
        (lambda t: t.replace("dtmc", "mdp"), "is a MDP but parley needs a DTMC"),
        (lambda t: t.replace("const int c;", "const int c;\nconst int z;"), "leaves constants z undefined"),
        (lambda t: t.replace("endmodule", "  [] h=2 -> (h'=0)\nendmodule"), "does not parse: Parsing error at"),
    ],
)
def test_model_errors(change, message):
    with pytest.raises(ModelError, match=message):
        augment(toy_system(prism=change(TOY)))


def test_unknown_service_constant():
    system = toy_system(services=[Service(name="probe", constant="q", kind="frequency", low=1, high=3)], baselines=[])
    with pytest.raises(ModelError, match="constant 'q' is not declared"):
        augment(system)


def test_service_constant_used_in_no_command():
    text = TOY.replace("const int c;", "const int c;\nconst int unused;")
    system = toy_system(
        prism=text,
        services=[
            Service(name="probe", constant="c", kind="frequency", low=1, high=3),
            Service(name="never", constant="unused", kind="frequency", low=1, high=3),
        ],
        baselines=[],
    )
    with pytest.raises(ModelError, match="unused are used in no command"):
        augment(system)


def test_unknown_observation_variable():
    with pytest.raises(ModelError, match="'nope' is not a variable of the model"):
        augment(toy_system(observation=("nope",)))


def test_decision_name_collision():
    text = TOY.replace("const int K = 3;", "const int K = 3;\nconst int c_0 = 1;")
    with pytest.raises(ModelError, match="already has an identifier 'c_0'"):
        augment(toy_system(prism=text))


def _write(text: str) -> str:
    import tempfile

    with tempfile.NamedTemporaryFile("w", suffix=".prism", delete=False) as handle:
        handle.write(text)
    return handle.name
