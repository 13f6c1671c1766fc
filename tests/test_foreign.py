"""Models nobody here wrote: PAYNT's benchmarks and PRISM's examples, read from
``../shared/foreign-models`` (other projects' files: never copied into this repository).

For each: the quotient evaluator against Storm on the baselines and 50 random policies
(1e-9, relative to the value's size), then a short ``parley synthesize`` whose every written
value is Storm's. The folder's README says where each model comes from and what changed.
"""

from __future__ import annotations

import csv
import json
import math
from pathlib import Path

import attrs
import numpy as np
import pytest
from typer.testing import CliRunner

from parley_core.cli import app
from parley_core.family.prepare import make_family
from parley_core.family.usermodel import system_from_file
from parley_core.testing import storm_values, values
from parley_core.verify import TOLERANCE, differences


@attrs.frozen
class Foreign:
    folder: str
    model: str
    properties: str
    decisions: tuple[str, ...]
    observe: tuple[str, ...] = ()
    baselines: int | None = None  # check the first of them only (the rest cost time, not coverage)
    agreement: tuple[str, ...] = ()  # smaller ranges for the agreement test (the quotient's size is its time)
    infinite: str = ""  # an objective some policies make infinite
    note: str = ""


def _range(names: str, domain: str) -> tuple[str, ...]:
    return tuple(f"{name}={domain}" for name in names.split())


MAZE_PROPERTIES = '// name: steps, min\nR{"steps"}=? [ F "goal" ]\n'  # PAYNT's query asks R<=7.32; here its value

MODELS = [
    Foreign(
        folder="paynt-dpm",
        model="dpm.prism",
        properties="dpm.pctl",
        decisions=_range("X11 X21 X31 X41 X12 X22 X32 X42 X13 X23 X33 X43 X14 X24 X34 X44", "0..2"),
        observe=("c",),
        baselines=24,
        note="rewards with upper-case names (lostH); zero-valued reward states",
    ),
    Foreign(
        folder="paynt-herman",
        model="herman.prism",
        properties="herman.pctl",
        decisions=_range("M0LFAIR M0HFAIR M1LFAIR M1HFAIR", "0..24") + _range("MxxA MxxB MxxC", "0..1"),
        baselines=12,
        infinite="steps",
        agreement=_range("M0LFAIR M0HFAIR M1LFAIR M1HFAIR", "0..12") + _range("MxxA MxxB MxxC", "0..1"),
        note="no observation (a family of constants); coin bias 0 never stabilises: infinite expected steps",
    ),
    Foreign(
        folder="paynt-maze",
        model="maze.prism",
        properties=MAZE_PROPERTIES,
        decisions=_range("M_0_1 M_0_2 M_0_3 M_0_4 M_0_5 M_0_6 M_1_1 M_1_2 M_1_3 M_1_4 M_1_5 M_1_6", "0..1")
        + ("P_0_1=2,3", "P_0_2=2,4", "P_0_3=2,3,4", "P_0_4=3,4", "P_0_5=1,3", "P_0_6=1")
        + ("P_1_1=2,3", "P_1_2=2,4", "P_1_3=2,3,4", "P_1_4=3,4", "P_1_5=1,3", "P_1_6=1"),
        note="set-valued holes as in PAYNT's sketch; expected steps up to 10^5 (slowly mixing)",
    ),
    Foreign(
        folder="prism-brp",
        model="brp.pm",
        properties="brp.pctl",
        decisions=("MAX=1..6",),
        observe=("i",),
        note="PRISM's bounded retransmission protocol with a frames reward",
    ),
    Foreign(
        folder="prism-brp",
        model="brp.pm",
        properties="brp.pctl",
        decisions=("MAX=-2..3",),
        observe=("i",),
        note="values of MAX that leave states without an enabled command: each policy's own deadlocks",
    ),
    Foreign(
        folder="prism-brp",
        model="brp-orig-N16.pm",
        properties="brp-unnamed.pctl",
        decisions=("MAX=1..6",),
        observe=("i",),
        note="as PRISM ships it: one unnamed reward structure, and an unnamed R=? property",
    ),
]


def _paths(foreign: Path, spec: Foreign, tmp_path: Path) -> tuple[Path, Path]:
    model = foreign / spec.folder / spec.model
    if spec.properties.endswith(".pctl"):
        return model, foreign / spec.folder / spec.properties
    properties = tmp_path / "properties.pctl"
    properties.write_text(spec.properties)
    return model, properties


@pytest.mark.slow
@pytest.mark.parametrize("spec", MODELS, ids=lambda s: f"{s.folder}/{s.model}")
def test_the_quotient_agrees_with_storm(foreign, spec, tmp_path):
    model, properties = _paths(foreign, spec, tmp_path)
    system = system_from_file(model, spec.agreement or spec.decisions, list(spec.observe), properties)
    family = make_family(system, prune=True)
    baselines = family.baseline_policies()[: spec.baselines]
    rows = np.vstack([np.array([p.values for p in baselines]), family.random(np.random.default_rng(7), 50)]).astype(
        np.int64
    )
    fast = values(family, rows, evaluator="quotient")
    storm = values(family, rows, workers=2)
    _, relative = differences(fast, storm)
    worst = np.unravel_index(int(np.argmax(relative)), relative.shape)
    assert relative.max() <= TOLERANCE, (
        f"{spec.folder}/{spec.model}: policy {rows[worst[0]].tolist()}, {family.objectives[worst[1]].name}: "
        f"quotient {fast[worst]!r}, Storm {storm[worst]!r}"
    )


@pytest.mark.slow
@pytest.mark.parametrize("spec", MODELS, ids=lambda s: f"{s.folder}/{s.model}")
def test_a_short_synthesis_reports_storms_values(foreign, spec, tmp_path):
    model, properties = _paths(foreign, spec, tmp_path)
    out = tmp_path / "run"
    decisions = [item for d in spec.decisions for item in ("--decision", d)]
    observe = ["--observe", ",".join(spec.observe)] if spec.observe else []
    result = CliRunner().invoke(
        app,
        ["synthesize", str(model), "--props", str(properties), *decisions, *observe]
        + ["--population", "12", "--generations", "3", "--workers", "1", "--out", str(out)],
    )
    assert result.exit_code == 0, (result.stdout, result.stderr)
    infinite = json.loads((out / "summary.json").read_text())["infinite_values"]
    if spec.infinite:  # reported, and kept off the front
        assert infinite.get(spec.infinite, 0) > 0 and f"have an infinite {spec.infinite}" in result.stdout
    text = (out / "model.prism").read_text()
    formulas = [
        line for line in (out / "properties.pctl").read_text().splitlines() if line and not line.startswith("//")
    ]
    with open(out / "policies.csv") as handle:
        policies = list(csv.DictReader(handle))
    with open(out / "front.csv") as handle:
        written = list(csv.DictReader(handle))
    assert written and [p["policy"] for p in policies] == [w["policy"] for w in written]
    names = [n for n in written[0] if n != "policy"]
    for policy, row in zip(policies, written):
        constants = {k: int(v) for k, v in policy.items() if k != "policy"}
        # exact rational arithmetic: Storm's own answer, with no solver precision in between
        expected = storm_values(text, formulas, constants, exact=True)
        for name, checked in zip(names, expected):
            value = float(row[name])
            assert math.isfinite(value) or spec.infinite != name
            assert math.isclose(value, checked, rel_tol=TOLERANCE, abs_tol=TOLERANCE) or value == checked, (
                f"{spec.folder}: {policy['policy']} {name}: front.csv {value!r}, Storm {checked!r}"
            )


@pytest.mark.slow
@pytest.mark.parametrize("spec", MODELS, ids=lambda s: f"{s.folder}/{s.model}")
def test_policy_programs_agree_with_the_augmented_model(foreign, spec, tmp_path):
    # the default verification path (policy programs) against the reference (the augmented
    # program, one build per policy): both Storm's, to 1e-12
    from parley_core.evaluate.batch import BatchStormEvaluator
    from parley_core.evaluate.storm import StormEvaluator

    model, properties = _paths(foreign, spec, tmp_path)
    system = system_from_file(model, spec.agreement or spec.decisions, list(spec.observe), properties)
    family = make_family(system, prune=True)
    baselines = family.baseline_policies()[:3]
    rows = np.vstack([np.array([p.values for p in baselines]), family.random(np.random.default_rng(8), 12)]).astype(
        np.int64
    )
    with BatchStormEvaluator(family, workers=1) as fast, StormEvaluator(family, workers=1) as reference:
        batch, single = fast.evaluate(rows), reference.evaluate(rows)
    _, relative = differences(batch, single)
    assert relative.max() <= 1e-12, f"{spec.folder}/{spec.model}: {batch.tolist()} against {single.tolist()}"


@pytest.mark.slow
def test_on_dpm_both_rewards_share_one_direct_solve(foreign, monkeypatch):
    # PAYNT's dpm mixes slowly (its battery runs out with probability 0.01 a step): the sweeps
    # give up early and both expected rewards (power, lostH: one target) are solved with one
    # LU factorization a policy, and still agree with Storm
    from test_bound import dpm

    from parley_core.quotient import ordering
    from parley_core.quotient import solver as module
    from parley_core.quotient.coloring import build_quotient

    fam = dpm(foreign, free=3)
    factorizations = []
    real = ordering.splu
    monkeypatch.setattr(
        ordering, "splu", lambda matrix, **how: factorizations.append(matrix.shape) or real(matrix, **how)
    )
    solver = module.QuotientSolver(build_quotient(fam))
    rows = np.array([[a, b, c] + [1] * 13 for a in range(3) for b in range(3) for c in range(3)], dtype=np.int64)
    fast = np.array([solver.solve(row) for row in rows], dtype=float)
    assert len(factorizations) == len(rows) and solver.direct_solves == 2 * len(rows)
    assert solver.last_sweeps == -1 and solver.uncertified == 0
    # the lumped equations leave out the states that only pass on (tick1's choice)
    assert max(n for n, _ in factorizations) < solver.last_states
    _, relative = differences(fast, values(fam, rows))
    assert relative.max() <= TOLERANCE
