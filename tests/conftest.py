"""Shared fixtures: a toy system model small enough to reason about by hand."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

from parley_core import Baseline, DecisionKind, Direction, Objective, Service, SystemModel
from parley_core.testing import storm_values  # noqa: F401  (tests import it from here)

pytest_plugins = ["pytester"]

# A server that is healthy (h=1) or degraded (h=0); each round it degrades with probability
# 0.2 (from healthy) and, unless probed, stays as it is. A probe (every c-th round, counted by
# step) repairs it at cost 3. Each degraded round costs 1. The observation is the phase
# (0 or 1), which alternates every round.
TOY = """dtmc
const int c;
const int K = 3;
module Server
  h : [0..1] init 1;
  phase : [0..1] init 0;
  step : [1..K] init 1;
  [probe] step>=c -> 0.8 : (h'=1) & (phase'=1-phase) & (step'=1) + 0.2 : (h'=0) & (phase'=1-phase) & (step'=1);
  [wait] step<c & h=1 -> 0.8 : (phase'=1-phase) & (step'=step+1) + 0.2 : (h'=0) & (phase'=1-phase) & (step'=step+1);
  [wait] step<c & h=0 -> (phase'=1-phase) & (step'=step+1);
endmodule
rewards "cost"
  [probe] true : 3;
  h=0 : 1;
endrewards
label "healthy" = h=1;
"""


def toy_system(prism: str = TOY, **changes) -> SystemModel:
    fields = dict(
        name="toy",
        prism=prism,
        services=[Service(name="probe", constant="c", kind=DecisionKind.FREQUENCY, low=1, high=3)],
        observation=("phase",),
        objectives=[
            Objective(name="cost", formula='R{"cost"}=? [C<=10]', direction=Direction.MIN),
            Objective(name="healthy", formula='P=? [F<=3 !"healthy"]', direction=Direction.MIN),
        ],
        baselines=[Baseline(name=f"every-{k}", values={"c": k}) for k in (1, 2, 3)],
    )
    fields.update(changes)
    return SystemModel(**fields)


@pytest.fixture
def toy() -> SystemModel:
    return toy_system()


FOREIGN = Path(__file__).resolve().parents[1].parent / "shared" / "foreign-models"
"""Real models from other projects (../shared/foreign-models)."""


@pytest.fixture(scope="module")
def foreign() -> Path:
    if not FOREIGN.is_dir():
        if os.environ.get("CI"):
            pytest.fail(f"{FOREIGN} is missing, and CI runs the foreign-model corpus; provide ../shared")
        pytest.skip(f"{FOREIGN} is absent (the foreign-model corpus lives beside the project, in ../shared)")
    return FOREIGN


@pytest.fixture(scope="module")
def small_robot():
    """A 5x5 robot map (intervals up to 4, horizon 45) and its quotient evaluator, one per
    module: the searches' tests run on it."""
    from parley_core.evaluate.quotient import QuotientEvaluator
    from parley_core.testing import family as make_family

    family = make_family("robot_grid", ["size=5", "seed=1", "max_interval=4", "horizon=45"])
    with QuotientEvaluator(family, workers=1) as evaluator:
        yield family, evaluator


def assert_points_are_not_ties(run_dir: Path) -> int:
    """front.csv's ``point`` column groups exactly the ties: two policies of different
    points are never within the verification tolerance of each other, and no policy is
    dominated by more than it. Returns the number of points (as summary.json has it)."""
    import csv
    import json

    import numpy as np

    from parley_core import metrics

    summary = json.loads((run_dir / "summary.json").read_text())
    names = [o["name"] for o in summary["objectives"]]
    directions = [Direction(o["direction"]) for o in summary["objectives"]]
    with open(run_dir / "front.csv") as handle:
        rows = list(csv.DictReader(handle))
    assert rows and list(rows[0])[-1] == "point"
    values = np.array([[float(r[n]) for n in names] for r in rows])
    points = np.array([int(r["point"]) for r in rows])
    assert metrics.tolerant_front(values, directions).all()
    firsts = {p: values[points == p][0] for p in set(points)}
    for p, value in firsts.items():
        for q, other in firsts.items():
            slack = metrics.TIE_TOLERANCE * np.maximum(1.0, np.maximum(np.abs(value), np.abs(other)))
            assert p == q or not (np.abs(value - other) <= slack).all(), (p, q, value, other)
    assert summary["front"]["points"] == len(firsts) == points.max()
    return len(firsts)
