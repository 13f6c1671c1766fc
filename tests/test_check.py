"""Requirements answered (``parley check``): branch and bound driven by a box of objective
values says feasible, infeasible or unknown; each answer is compared with enumeration of the
whole family, every infeasible answer's certificate is checked again, and a feasible one's
values are Storm's."""

from __future__ import annotations

import itertools
import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from test_bound import dpm, herman
from test_exact import CASES
from test_quotient import OBJECTIVES, breaking_system

from parley_core import metrics
from parley_core.constraints import Constraint, Operator
from parley_core.errors import OptionError
from parley_core.model import Direction
from parley_core.optimality.requirement import (
    CertificateError,
    Requirement,
    Verdict,
    answer,
    certificate_json,
    read_certificate,
    recheck,
)
from parley_core.quotient.coloring import build_quotient
from parley_core.quotient.solver import QuotientSolver
from parley_core.testing import family, storm_values

DOCS = Path(__file__).resolve().parents[1] / "docs"


def _solver(fam):
    quotient = build_quotient(fam)
    solver = QuotientSolver(quotient)
    return quotient, lambda rows: np.array([solver.solve(row) for row in rows], dtype=float)


def _enumerate(fam, evaluate):
    rows = np.array(list(itertools.product(*(d.service.values for d in fam.decisions))), dtype=np.int64)
    return rows, evaluate(rows)


def _signs(fam) -> np.ndarray:
    return np.array([1.0 if o.direction is Direction.MAX else -1.0 for o in fam.objectives])


def _box(fam, point: np.ndarray, shift: float, columns) -> list[Constraint]:
    """Constraints at ``point`` moved by ``shift`` of each value's size (at least 1e-3) in the
    better direction (negative: a looser box)."""
    out = []
    for i in columns:
        objective, value = fam.objectives[i], float(point[i])
        better = 1.0 if objective.direction is Direction.MAX else -1.0
        level = value + better * shift * max(abs(value), 1e-3)
        operator = Operator.AT_LEAST if objective.direction is Direction.MAX else Operator.AT_MOST
        out.append(Constraint(objective=objective.name, operator=operator, bound=level))
    return out


def _boxes(fam, values: np.ndarray):
    """Boxes around the enumerated front: a loose one, one whose corner is a front value (on
    the front's edge), one just beyond a front value, and per objective one beyond its best."""
    # up to three objectives some policy has a finite value of, and the policies finite in them
    columns = [i for i in range(values.shape[1]) if np.isfinite(values[:, i]).any()][:3]
    directions = [fam.objectives[i].direction for i in columns]
    values = values[np.isfinite(values[:, columns]).all(axis=1)]
    part = values[:, columns]
    front = part[metrics.nondominated(part, directions)]
    front = front[np.lexsort(tuple(front[:, i] for i in reversed(range(front.shape[1]))))]
    middle = np.full(values.shape[1], np.nan)
    middle[columns] = front[len(front) // 2]
    yield "loose", _box(fam, middle, -0.05, columns)
    yield "edge", _box(fam, middle, 0.0, columns)
    yield "beyond", _box(fam, middle, 1e-3, columns)
    for i, direction in zip(columns, directions):
        best = values[:, i].max() if direction is Direction.MAX else values[:, i].min()
        point = np.full(values.shape[1], best)
        yield f"beyond best {fam.objectives[i].name}", _box(fam, point, 1e-3, [i])


def _assert_answer(fam, quotient, evaluate, rows, values, constraints, **options):
    requirement = Requirement.of(fam, constraints)
    truth = requirement.met(values, _signs(fam))
    found = answer(fam, quotient, evaluate, requirement, **options)
    if truth.any():
        assert found.verdict is Verdict.FEASIBLE, (str(requirement), found.counts)
        # the policies it names meet the box by their own values, evaluated again
        assert requirement.met(evaluate(found.policies), _signs(fam)).all()
    else:
        assert found.verdict is Verdict.INFEASIBLE, (str(requirement), found.counts)
        recheck(fam, quotient, requirement, found.closed, evaluate)
        # the certificate read back from its document holds too
        again, closed = read_certificate(fam, json.loads(json.dumps(certificate_json(fam, found))))
        recheck(fam, quotient, again, closed, evaluate)
    return found


FAST = [
    c for c in CASES if c[0] in ("robot_grid 3x3", "web_ids 3^6", "breaking (min)", "breaking rewards to one target")
]


@pytest.mark.parametrize("name,fam", FAST, ids=[c[0] for c in FAST])
def test_each_answer_is_what_enumeration_says(name, fam):
    quotient, evaluate = _solver(fam)
    rows, values = _enumerate(fam, evaluate)
    verdicts = set()
    for _, constraints in _boxes(fam, values):
        verdicts.add(_assert_answer(fam, quotient, evaluate, rows, values, constraints, leaf=4, adaptive=False).verdict)
    assert verdicts == {Verdict.FEASIBLE, Verdict.INFEASIBLE}


@pytest.mark.slow
@pytest.mark.parametrize("name,fam", CASES, ids=[c[0] for c in CASES])
def test_each_answer_is_what_enumeration_says_on_every_family(name, fam):
    quotient, evaluate = _solver(fam)
    rows, values = _enumerate(fam, evaluate)
    for _, constraints in _boxes(fam, values):
        for leaf, adaptive, whole in ((4, False, False), (32, True, False), (4, False, True)):
            _assert_answer(
                fam, quotient, evaluate, rows, values, constraints, leaf=leaf, adaptive=adaptive, whole=whole
            )


def test_a_certificate_that_does_not_cover_the_family_or_reaches_the_box_fails():
    fam = family("robot_grid", ["size=3", "seed=2"], width=3)
    quotient, evaluate = _solver(fam)
    rows, values = _enumerate(fam, evaluate)
    beyond = dict(_boxes(fam, values))["beyond"]
    requirement = Requirement.of(fam, beyond)
    found = answer(fam, quotient, evaluate, requirement, leaf=4, adaptive=False)
    assert found.verdict is Verdict.INFEASIBLE and len(found.closed) > 2
    with pytest.raises(CertificateError, match="policies"):
        recheck(fam, quotient, requirement, found.closed[1:], evaluate)
    # the same sub-families against a looser box: some bound or policy reaches it
    loose = Requirement.of(fam, dict(_boxes(fam, values))["loose"])
    with pytest.raises(CertificateError, match="reaches|meets"):
        recheck(fam, quotient, loose, found.closed, evaluate)


def test_a_time_limit_leaves_the_answer_unknown_with_the_share_open():
    fam = family("robot_grid", ["size=3", "seed=2"], width=3)
    quotient, evaluate = _solver(fam)
    rows, values = _enumerate(fam, evaluate)
    requirement = Requirement.of(fam, dict(_boxes(fam, values))["beyond"])
    found = answer(fam, quotient, evaluate, requirement, leaf=4, adaptive=False, time_limit=1e-9)
    assert found.verdict is Verdict.UNKNOWN
    assert 0.0 < found.open_share <= 1.0
    # what the open sub-families' bounds still allow reaches the box
    assert (found.open_best * _signs(fam) >= requirement.corner).all()


@pytest.mark.parametrize(
    "texts, message",
    [
        (["success<=0.9"], "maximised"),
        (["cost>=3"], "minimised"),
        (["success>=0.5", "success>=0.6"], "two requirements"),
        (["speed>=1"], "no objective 'speed'"),
        ([], "at least one"),
    ],
)
def test_requirements_that_cannot_be_answered_are_one_line_errors(texts, message):
    fam = family("robot_grid", ["size=3", "seed=2"], width=2)
    with pytest.raises(OptionError, match=message):
        Requirement.of(fam, [Constraint.parse(t) for t in texts])


def test_an_infeasible_answer_on_a_model_we_did_not_write_is_what_storm_says():
    """The breaking model's family enumerated with Storm, policy by policy: no policy's
    values (Storm's) meet a box the check calls infeasible, and one meets the box it calls
    feasible."""
    fam = family(breaking_system({name: OBJECTIVES[name] for name in ("reach", "cumulative")}))
    fam = fam if len(fam.objectives) == 2 else pytest.skip("two objectives wanted")
    quotient, evaluate = _solver(fam)
    rows, values = _enumerate(fam, evaluate)
    formulas = [o.formula for o in fam.objectives]
    names = [d.name for d in fam.decisions]
    storm = np.array([storm_values(fam.prism, formulas, dict(zip(names, map(int, row)))) for row in rows])
    for label, constraints in _boxes(fam, storm):
        requirement = Requirement.of(fam, constraints)
        found = answer(fam, quotient, evaluate, requirement, leaf=4, adaptive=False)
        met = requirement.met(storm, _signs(fam))
        assert (found.verdict is Verdict.FEASIBLE) == met.any(), label
        assert found.verdict is not Verdict.UNKNOWN


@pytest.mark.slow
@pytest.mark.parametrize("model", ["herman 0..2", "herman 22..24", "dpm 6"])
def test_answers_on_models_we_did_not_write_are_enumerations(foreign, model):
    """PAYNT's herman (infinite expected steps for some policies) and dpm (six holes free):
    every box's answer is what enumeration of the family says."""
    name, arg = model.split()
    fam = herman(foreign, arg) if name == "herman" else dpm(foreign, free=int(arg))
    quotient, evaluate = _solver(fam)
    rows, values = _enumerate(fam, evaluate)
    for _, constraints in _boxes(fam, values):
        _assert_answer(fam, quotient, evaluate, rows, values, constraints, leaf=4, adaptive=False)


def _parley(*args: str, cwd: Path) -> subprocess.CompletedProcess:
    return subprocess.run(
        [sys.executable, "-m", "parley_core", *args], capture_output=True, text=True, cwd=cwd, timeout=600
    )


SMALL = ["--set", "size=4", "--set", "seed=3", "--set", "max_interval=3", "--set", "horizon=30", "--generations", "3"]


@pytest.mark.slow
def test_parley_check_answers_all_three_ways_and_rechecks(tmp_path):
    """The command as a user runs it, with --json: a feasible box (a Storm-verified policy and
    its controller), an infeasible one (a certificate that `parley recheck` accepts) and a time
    limit too short to say (unknown)."""
    feasible = _parley("check", "robot_grid", *SMALL, "--require", "success>=0.5", "--out", "f", "--json", cwd=tmp_path)
    assert feasible.returncode == 0, feasible.stderr
    document = json.loads(feasible.stdout)
    assert document["answer"] == "feasible" and document["policy"]["verified_by"] == "storm"
    assert document["policy"]["values"]["success"] >= 0.5
    controller = json.loads((tmp_path / "f" / "controller.json").read_text())
    assert controller["values"]["success"] == pytest.approx(document["policy"]["values"]["success"], rel=1e-12)
    # Storm's value of the chosen policy, from the run directory's model and policy
    infeasible = _parley(
        "check", "robot_grid", *SMALL, "--require", "success>=0.9999", "--require", "cost<=1", "--out", "i", "--json",
        cwd=tmp_path,
    )  # fmt: skip
    assert infeasible.returncode == 0, infeasible.stderr
    document = json.loads(infeasible.stdout)
    assert document["answer"] == "infeasible"
    certificate = json.loads(Path(document["certificate"]).read_text())
    assert certificate["format"] == "parley-certificate/1" and certificate["sub_families"]
    again = _parley("recheck", "i", cwd=tmp_path)
    assert again.returncode == 0 and "certificate holds" in again.stdout, again.stderr
    unknown = _parley(
        "check", "robot_grid", "--set", "size=6", "--require", "success>=0.97", "--require", "cost<=30",
        "--time-limit", "0.01", "--out", "u", "--json", cwd=tmp_path,
    )  # fmt: skip
    assert unknown.returncode == 0, unknown.stderr
    document = json.loads(unknown.stdout)
    assert document["answer"] == "unknown" and 0 < document["open_share"] <= 1
    wrong = _parley("check", "robot_grid", *SMALL, "--require", "success<=0.5", "--out", "w", cwd=tmp_path)
    assert wrong.returncode == 2 and wrong.stderr.count("\n") == 1 and "maximised" in wrong.stderr


@pytest.mark.slow
def test_the_api_checks_a_users_model_from_a_plain_script(tmp_path):
    """``parley.check_model`` in a script run as a plain file: the tutorial's pump model, a
    feasible and an infeasible requirement; the feasible policy's values are Storm's on the
    run directory's model."""
    script = tmp_path / "check.py"
    script.write_text(
        f"""
import json, parley
tutorial = {str(DOCS / "tutorial")!r}
common = dict(props=tutorial + "/pump.pctl", decisions={{"c": (1, 8)}}, observe=["est"], progress=False)
yes = parley.check_model(tutorial + "/pump.prism", ["broken<=1", "cost<=100000"], out="yes", generations=2, **common)
no = parley.check_model(tutorial + "/pump.prism", ["broken<=0", "cost<=0"], out="no", generations=2, **common)
print(json.dumps({{"yes": yes.answer, "values": dict(yes.values or {{}}), "no": no.answer,
                  "decide": yes.controller().decide({{"est": 0}}) if yes.feasible else None,
                  "rechecked": parley.recheck("no") if no.answer == "infeasible" else None}}))
"""
    )
    done = subprocess.run([sys.executable, str(script)], capture_output=True, text=True, cwd=tmp_path, timeout=600)
    assert done.returncode == 0, done.stderr
    out = json.loads(done.stdout.strip().splitlines()[-1])
    assert out["yes"] == "feasible" and out["no"] == "infeasible" and out["rechecked"] >= 1
    assert out["values"]["cost"] <= 100000 and set(out["decide"]) == {"c"}
