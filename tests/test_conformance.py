"""The conformance suite on every registered case study (the suite itself is shipped:
:mod:`parley_core.testing.suite`), and what a run does when a plugin's plot fails."""

from __future__ import annotations

import stormpy

from parley_core.pipeline import run
from parley_core.rundir.write import write_run
from parley_core.search import SearchSettings
from parley_core.testing.suite import ConformanceSuite


class TestConformance(ConformanceSuite):
    """Every registered case study, with its quick options."""


def test_stormpy_is_the_checker():
    assert stormpy.__version__.startswith("2.")


def test_a_failing_policy_plot_costs_only_the_plot(toy, tmp_path):
    from attrs import frozen

    from parley_core import CaseStudy
    from parley_core.family.prepare import Prepared
    from parley_core.rundir.write import PLOT_ERROR
    from parley_core.testing import family

    @frozen
    class NoOptions:
        pass

    def broken_plot(system, table, path):
        path.write_bytes(b"half a png")
        raise RuntimeError("the plugin's drawing is broken")

    case = CaseStudy(
        name="toy", description="toy", options_type=NoOptions, build=lambda _: toy, plot_policy=broken_plot
    )
    prepared = Prepared(case=case, options=NoOptions(), system=toy, family=family(toy))
    result = run(prepared, SearchSettings(population=6, generations=2, seed=1), workers=1)
    written = {p.name for p in write_run(result, tmp_path / "run")}
    assert {"front.csv", "policies.csv", "summary.json", PLOT_ERROR} <= written
    assert "policy.png" not in written
    assert "the plugin's drawing is broken" in (tmp_path / "run" / PLOT_ERROR).read_text()


def test_the_policy_map_check_catches_a_wrong_map():
    import pytest
    from attrs import frozen

    from parley_core import CaseStudy, PolicyMap
    from parley_core.family.prepare import Prepared
    from parley_core.testing import family
    from parley_core.testing.conformance import ConformanceError, check_policy_map

    @frozen
    class NoOptions:
        pass

    from tests.conftest import toy_system

    toy = toy_system(observation=("phase", "step"))

    def prepared(found):
        case = CaseStudy(
            name="toy", description="toy", options_type=NoOptions, build=lambda _: toy, policy_map=lambda _s: found
        )
        return Prepared(case=case, options=NoOptions(), system=toy, family=family(toy))

    check_policy_map(prepared(PolicyMap(x="phase", y="step", width=2, height=4, marks=[("T", 1, 3)])))
    with pytest.raises(ConformanceError, match="not two observation variables"):  # h is hidden
        check_policy_map(prepared(PolicyMap(x="phase", y="h", width=2, height=2)))
    with pytest.raises(ConformanceError, match="leaves cells off"):  # step reaches 3
        check_policy_map(prepared(PolicyMap(x="phase", y="step", width=2, height=3)))
    with pytest.raises(ConformanceError, match="leaves cells off"):
        check_policy_map(prepared(PolicyMap(x="phase", y="step", width=2, height=4, marks=[("T", 5, 0)])))
