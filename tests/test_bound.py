"""The certified bound is sound: every policy Storm evaluates, and every front, is weakly
dominated by a point of the bound, on the case studies, the tutorial's model and models
with overlapping guards, synchronised decisions and per-policy deadlocks."""

from __future__ import annotations

import csv
import json
from pathlib import Path

import attrs
import numpy as np
import pytest
from conftest import toy_system
from test_quotient import OBJECTIVES, STUCK, breaking_system, synchronised_system
from typer.testing import CliRunner

from parley_core.bound import ideal_point, pareto_outer
from parley_core.cli import app
from parley_core.model import DecisionKind, Direction, Objective, Service
from parley_core.quotient.coloring import build_quotient
from parley_core.storm_pareto import storm_pareto
from parley_core.testing import family, values
from parley_core.usermodel import system_from_file

DOCS = Path(__file__).resolve().parents[1] / "docs"


def _flip(objectives, maximize):
    return [attrs.evolve(o, direction=Direction.MAX) if o.name in maximize else o for o in objectives]


def _families():
    yield "robot_grid 5x5", family("robot_grid", ["size=5", "seed=1", "max_interval=4", "horizon=45"])
    yield "web_ids", family("web_ids", ["rounds=6"])
    yield "tas", family("tas", ["rounds=6", "max_interval=3"])
    pump = system_from_file(DOCS / "tutorial" / "pump.prism", ["c=1..8"], ["est,load"], DOCS / "tutorial" / "pump.pctl")
    yield "pump", family(pump, prune=True)
    # overlapping enabled commands (mixed uniformly), every objective shape, both directions
    breaking = breaking_system(OBJECTIVES)
    yield "breaking (min)", family(breaking)
    yield "breaking (max)", family(attrs.evolve(breaking, objectives=_flip(breaking.objectives, set(OBJECTIVES))))
    yield (
        "synchronised",
        family(synchronised_system(("full", "P=? [F b=3]", "max"), ("load", 'R{"b"}=? [C<=6]', "min"))),
    )
    yield (
        "stuck",
        family(
            toy_system(
                prism=STUCK,
                services=[Service(name="probe", constant="c", kind=DecisionKind.FREQUENCY, low=0, high=3)],
                observation=("x",),
                objectives=[
                    Objective(name="stuck", formula='P=? [F "deadlock"]', direction="max"),
                    Objective(name="until", formula='R{"steps"}=? [F "deadlock"]', direction="min"),
                    Objective(name="soon", formula='P=? [F<=4 "deadlock"]', direction="max"),
                    Objective(name="escape", formula="P=? [F x=3]", direction="max"),
                ],
                baselines=[],
            )
        ),
    )


@pytest.mark.parametrize("name, case", list(_families()), ids=lambda v: v if isinstance(v, str) else "")
def test_every_policy_is_dominated_by_the_bound(name, case):
    quotient = build_quotient(case)
    bound = ideal_point(case, quotient)
    outer = pareto_outer(case, quotient, bound)
    policies = np.vstack(
        [np.array([p.values for p in case.baseline_policies()]).reshape(-1, len(case.decisions)),
         case.random(np.random.default_rng(11), 40)]
    ).astype(np.int64)  # fmt: skip
    storm = values(case, policies)
    dominated = bound.dominates(storm)
    assert dominated.all(), f"{name}: {storm[~dominated][:3]} beyond the bound {bound.points}"
    dominated = outer.dominates(storm)
    assert dominated.all(), f"{name}: {storm[~dominated][:3]} beyond the Pareto outer approximation"
    # the outer approximation is inside the ideal box
    assert bound.dominates(outer.points).all()


@pytest.mark.parametrize("name, case", list(_families()), ids=lambda v: v if isinstance(v, str) else "")
def test_the_kernels_ideal_point_is_storms_on_the_relaxation(name, case):
    # the compiled kernels (safe by construction) against Storm's sound value iteration
    quotient = build_quotient(case)
    ours, storms = ideal_point(case, quotient), ideal_point(case, quotient, by_storm=True)
    assert "Storm" in storms.method
    for objective, a, b in zip(case.objectives, ours.points[0], storms.points[0]):
        if np.isinf(a) or np.isinf(b):
            assert a == b or (np.isinf(a) and objective.direction is Direction.MAX), (name, objective.name, a, b)
            continue
        # Storm widens by its precision, 1e-9 of the largest state value
        assert abs(a - b) <= 1e-6 * max(1.0, abs(b)), (name, objective.name, a, b)


@pytest.mark.parametrize("name", ["robot_grid 5x5", "web_ids", "tas", "synchronised"])
def test_storms_multi_objective_points_of_the_relaxation_lie_inside_the_pareto_bound(name):
    # Storm's own multi-objective engine (PCAA) on the relaxation: the vertices of its
    # under-approximation are values relaxed schedulers reach, so a sound outer bound of the
    # relaxation, the kernels' backward induction here, weakly dominates every one of them
    case = dict(_families())[name]
    quotient = build_quotient(case)
    outer = pareto_outer(case, quotient)
    assert "weighted sums" in outer.method  # a staircase, not the ideal point alone
    storm = storm_pareto(case, quotient, precision=1e-4)
    assert len(storm.achieved) >= 2
    assert outer.dominates(storm.achieved, tolerance=1e-6).all(), (name, storm.achieved, outer.points)
    # and the check has teeth: the staircase moved inwards by 1 % (of its span, or of its
    # values where the span is nil) leaves some out
    signs = np.array([o.direction.sign for o in case.objectives])
    step = 0.01 * np.maximum(np.ptp(outer.points, axis=0), np.abs(outer.points).max(axis=0))
    moved = attrs.evolve(outer, points=outer.points + step * signs)
    assert not moved.dominates(storm.achieved, tolerance=1e-6).all()


def test_a_bound_that_is_wrong_is_caught():
    # the check itself can fail: a bound moved inside the values is not a bound
    case = family("tas", ["rounds=6", "max_interval=3"])
    bound = ideal_point(case, build_quotient(case))
    storm = values(case, case.baseline_policies())
    moved = attrs.evolve(bound, points=np.array([storm.mean(axis=0)]))
    assert not moved.dominates(storm).all()


def test_every_run_writes_its_bound_and_the_front_is_inside_it(tmp_path):
    out = tmp_path / "run"
    quick = ["--set", "size=5", "--set", "seed=1", "--set", "max_interval=4", "--set", "horizon=45"]
    result = CliRunner().invoke(app, ["run", "robot_grid", *quick, "--population", "10", "--generations", "3",
                                      "--workers", "1", "--out", str(out)])  # fmt: skip
    assert result.exit_code == 0, result.stderr
    optimality = json.loads((out / "summary.json").read_text())["optimality"]
    assert 0 <= optimality["gap"] < 1 and optimality["bound_hypervolume"] >= optimality["front_hypervolume"]
    assert "optimality: the front covers" in result.stdout
    with open(out / "bound.csv") as handle:
        points = np.array([[float(v) for v in row.values()] for row in csv.DictReader(handle)])
    with open(out / "front.csv") as handle:
        front = np.array([[float(row["success"]), float(row["cost"])] for row in csv.DictReader(handle)])
    assert (
        ((points[:, None, 0] >= front[None, :, 0] - 1e-9) & (points[:, None, 1] <= front[None, :, 1] + 1e-9))
        .any(axis=0)
        .all()
    )
