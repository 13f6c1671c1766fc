"""The conformance checks every case study must pass, as plain functions.

With its ``quick`` options, a case study must build a DTMC that parses and builds, name
objectives, decisions and observation variables that exist, offer baselines that Storm
checks, and give a tiny search a non-empty, mutually non-dominated front, at least as good
as the baselines, whose written values Storm confirms from the written files alone. Each
check raises :class:`ConformanceError` saying what is wrong; :mod:`parley_core.testing.suite`
runs them as pytest tests.
"""

from __future__ import annotations

import csv
import math
from pathlib import Path
from typing import Any

import attrs
import numpy as np

from parley_core import metrics
from parley_core.family.prepare import Prepared, prepare
from parley_core.pipeline import run
from parley_core.plugin.casestudy import CaseStudy
from parley_core.prism import program as prism
from parley_core.search import SearchSettings
from parley_core.testing import storm_values

TINY = SearchSettings(population=8, generations=2, seed=3)
"""The search of :func:`check_search`."""


class ConformanceError(AssertionError):
    """A case study does not meet the plugin contract."""


def _expect(condition: Any, message: str) -> None:
    __tracebackhide__ = True  # pytest shows the message, not this frame
    if not condition:
        raise ConformanceError(message)


def check_options(case: CaseStudy) -> None:
    """The options class is a frozen attrs class (options are values: a run's options cannot
    change under it) and every option has a help text (``option(default, help)`` of
    :mod:`parley.plugin`), which ``parley options`` and ``--help`` show."""
    __tracebackhide__ = True
    try:
        case.options_type().parley_probe = 1
        frozen = False
    except attrs.exceptions.FrozenInstanceError:
        frozen = True
    except AttributeError:  # a slotted class that is not frozen
        frozen = False
    _expect(frozen, f"{case.name}: the options class {case.options_type.__name__} is not frozen; use @frozen")
    unexplained = [f.name for f in case.option_fields() if not str(f.metadata.get("help", "")).strip()]
    _expect(
        not unexplained,
        f"{case.name}: option(s) {', '.join(unexplained)} have no help text; declare them as "
        "option(default, 'what it is') (from parley.plugin)",
    )


def prepare_quick(case: CaseStudy, options: dict[str, str] | None = None) -> Prepared:
    """The case study built (with its ``quick`` options, or ``options``) and augmented."""
    return prepare(case, case.options_from(case.quick if options is None else options))


def check_model(prepared: Prepared) -> None:
    """The DTMC parses as a DTMC; observation variables and service constants exist; the
    augmented model declares exactly the decision constants; the objectives parse on it."""
    system, family = prepared.system, prepared.family
    name = prepared.case.name
    program = prism.parse_program(system.prism)
    _expect(program.model_type.name == "DTMC", f"{name}: the model is a {program.model_type.name}, not a DTMC")
    for variable in system.observation:
        _expect(prism.find_variable(program, variable) is not None, f"{name}: no observation variable {variable!r}")
    constants = {c.name for c in program.constants}
    missing = {s.constant for s in system.services} - constants
    _expect(not missing, f"{name}: service constants {sorted(missing)} are not declared")
    _expect(
        len(family.decisions) == len(family.valuations) * len(system.services) > 0,
        f"{name}: expected one decision per valuation and service, found {len(family.decisions)}",
    )
    augmented = prism.parse_program(family.prism)
    undefined = {c.name for c in augmented.get_undefined_constants()}
    _expect(undefined == set(family.names), f"{name}: the augmented model leaves {sorted(undefined)} undefined")
    properties = prism.parse_properties([o.formula for o in system.objectives], augmented)
    _expect(len(properties) == len(system.objectives) > 0, f"{name}: the objectives do not parse one by one")


def check_baselines(prepared: Prepared, count: int = 3) -> None:
    """The case study offers baselines, and Storm gives the first ``count`` finite values."""
    family = prepared.family
    name = prepared.case.name
    _expect(family.baselines, f"{name}: a case study should offer at least one baseline policy")
    formulas = [o.formula for o in family.objectives]
    for policy in family.baseline_policies()[:count]:
        found = storm_values(family.prism, formulas, dict(zip(family.names, policy.values)))
        _expect(all(math.isfinite(v) for v in found), f"{name}: baseline {policy.name} has values {found}")


def check_search(prepared: Prepared, directory: Path, settings: SearchSettings = TINY) -> None:
    """A tiny search gives a non-empty, mutually non-dominated front no worse than the
    baselines in hypervolume; its run directory, read back, holds values Storm confirms."""
    from parley_core.rundir.write import hypervolume, write_run

    name = prepared.case.name
    result = run(prepared, settings, workers=1)
    front = np.array(result.front.values)
    _expect(len(front) > 0, f"{name}: the search found an empty front")
    directions = [o.direction for o in result.family.objectives]
    _expect(metrics.tolerant_front(front, directions).all(), f"{name}: the front holds dominated points")
    _expect(
        hypervolume(result, result.front) >= hypervolume(result, result.baseline) - 1e-12,
        f"{name}: the front's hypervolume is below the baseline's",
    )

    out = directory / f"{name}-run"
    write_run(result, out)
    model = (out / "model.prism").read_text()
    lines = (out / "properties.pctl").read_text().splitlines()
    formulas = [line for line in lines if line and not line.startswith("//")]
    with open(out / "policies.csv") as handle:
        policies = list(csv.DictReader(handle))
    with open(out / "front.csv") as handle:
        written = list(csv.DictReader(handle))
    _expect(
        [p["policy"] for p in policies] == [w["policy"] for w in written],
        f"{name}: policies.csv and front.csv list different policies",
    )
    names = [o.name for o in result.family.objectives]
    for policy, row in zip(policies, written):
        constants = {k: int(v) for k, v in policy.items() if k != "policy"}
        _expect(set(constants) == set(result.family.names), f"{name}: policies.csv has other columns than decisions")
        expected = storm_values(model, formulas, constants)
        # plain stormpy uses its default solver (relative precision 1e-6); parley, sound
        # value iteration at 1e-12: they agree to the default's precision
        for objective, value, checked in zip(names, (float(row[n]) for n in names), expected):
            _expect(
                math.isclose(value, checked, rel_tol=1e-6, abs_tol=1e-7),
                f"{name}: policy {policy['policy']} has {objective}={value} in front.csv, Storm gives {checked}",
            )


def check_policy_map(prepared: Prepared) -> None:
    """A plugin's map (``policy_map``) has observation variables as axes and every cell of
    the family's valuations, obstacles and marks on the map."""
    case = prepared.case
    if case.policy_map is None:
        return
    found = case.policy_map(prepared.system)
    observation = list(prepared.family.observation)
    _expect(
        found.x in observation and found.y in observation and found.x != found.y,
        f"{case.name}: policy_map's axes {found.x}, {found.y} are not two observation variables of {observation}",
    )
    if not (found.x in observation and found.y in observation):
        return
    i, j = observation.index(found.x), observation.index(found.y)
    cells = [(v[i], v[j]) for v in prepared.family.valuations] + list(found.blocked)
    cells += [(x, y) for _, x, y in found.marks]
    outside = [c for c in cells if not (0 <= c[0] < found.width and 0 <= c[1] < found.height)]
    _expect(
        not outside, f"{case.name}: policy_map leaves cells off its {found.width}x{found.height} map: {outside[:3]}"
    )


def check_case_study(case: CaseStudy, directory: Path, options: dict[str, str] | None = None) -> None:
    """Every check, on one case study (with its ``quick`` options unless ``options``)."""
    __tracebackhide__ = True
    check_options(case)
    prepared = prepare_quick(case, options)
    check_model(prepared)
    check_policy_map(prepared)
    check_baselines(prepared)
    check_search(prepared, directory)
