"""The conformance suite: every registered case study, with its ``quick`` options, must
build a DTMC that parses and builds, name objectives, decisions and observations that exist,
and give a tiny search a non-empty, mutually non-dominated front whose written values
Storm confirms from the written files."""

from __future__ import annotations

import csv

import numpy as np
import pytest
import stormpy

from conftest import storm_values
from parley_core import metrics
from parley_core.pipeline import prepare, run
from parley_core.plugins import load_registry
from parley_core.prism import program as prism
from parley_core.report import write_run
from parley_core.search import SearchSettings

REGISTRY = load_registry()


@pytest.fixture(params=REGISTRY.names, scope="module")
def prepared(request):
    case = REGISTRY.get(request.param)
    return prepare(case, case.options_from(case.quick))


def test_model_parses_and_names_what_exists(prepared):
    system, family = prepared.system, prepared.family
    program = prism.parse_program(system.prism)
    assert program.model_type.name == "DTMC"
    for name in system.observation:
        assert prism.find_variable(program, name) is not None
    constants = {c.name for c in program.constants}
    assert {s.constant for s in system.services} <= constants
    assert len(family.decisions) == len(family.valuations) * len(system.services) > 0
    augmented = prism.parse_program(family.prism)
    assert {c.name for c in augmented.get_undefined_constants()} == set(family.names)
    properties = prism.parse_properties([o.formula for o in system.objectives], augmented)
    assert len(properties) == len(system.objectives)


def test_baselines_build_and_check(prepared):
    family = prepared.family
    assert family.system.baselines, "a case study should offer at least one baseline policy"
    for policy in family.baseline_policies()[:3]:
        values = storm_values(
            family.prism, [o.formula for o in family.objectives], dict(zip(family.names, policy.values))
        )
        assert all(np.isfinite(values))


def test_tiny_search_gives_a_front_that_storm_confirms(prepared, tmp_path):
    result = run(prepared, SearchSettings(population=8, generations=2, seed=3), workers=1)
    front = np.array(result.front.values)
    assert len(front) > 0
    directions = [o.direction for o in result.family.objectives]
    assert metrics.nondominated(front, directions).all()
    assert result.hypervolume(result.front) >= result.hypervolume(result.baseline) - 1e-12

    out = tmp_path / "run"
    write_run(result, out)
    model = (out / "model.prism").read_text()
    formulas = [line for line in (out / "properties.pctl").read_text().splitlines() if line and not line.startswith("//")]
    with open(out / "policies.csv") as handle:
        policies = list(csv.DictReader(handle))
    with open(out / "front.csv") as handle:
        written = list(csv.DictReader(handle))
    assert [p["policy"] for p in policies] == [w["policy"] for w in written]
    names = [o.name for o in result.family.objectives]
    for policy, row in zip(policies, written):
        constants = {k: int(v) for k, v in policy.items() if k != "policy"}
        assert set(constants) == set(result.family.names)
        expected = storm_values(model, formulas, constants)
        # plain stormpy uses its default solver (relative precision 1e-6); parley, sound
        # value iteration at 1e-12: they agree to the default's precision
        assert [float(row[n]) for n in names] == pytest.approx(expected, rel=1e-6, abs=1e-7)


def test_stormpy_is_the_checker():
    assert stormpy.__version__.startswith("2.")


def test_a_failing_policy_plot_costs_only_the_plot(toy, tmp_path):
    from attrs import frozen

    from parley_core import CaseStudy
    from parley_core.augment import augment
    from parley_core.pipeline import Prepared
    from parley_core.report import PLOT_ERROR

    @frozen
    class NoOptions:
        pass

    def broken_plot(system, table, path):
        path.write_bytes(b"half a png")
        raise RuntimeError("the plugin's drawing is broken")

    case = CaseStudy(name="toy", description="toy", options_type=NoOptions, build=lambda _: toy, plot_policy=broken_plot)
    prepared = Prepared(case=case, options=NoOptions(), system=toy, family=augment(toy))
    result = run(prepared, SearchSettings(population=6, generations=2, seed=1), workers=1)
    written = {p.name for p in write_run(result, tmp_path / "run")}
    assert {"front.csv", "policies.csv", "summary.json", PLOT_ERROR} <= written
    assert "policy.png" not in written
    assert "the plugin's drawing is broken" in (tmp_path / "run" / PLOT_ERROR).read_text()
