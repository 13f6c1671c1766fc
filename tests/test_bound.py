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
from test_quotient import OBJECTIVES, STUCK, breaking_system, synchronised_system
from typer.testing import CliRunner

from conftest import toy_system
from parley_core.cli import app
from parley_core.family.usermodel import system_from_file
from parley_core.model import DecisionKind, Direction, Objective, Service
from parley_core.optimality.bound import ideal_point, pareto_outer
from parley_core.optimality.storm_pareto import storm_pareto
from parley_core.quotient.coloring import build_quotient
from parley_core.testing import family, values

DOCS = Path(__file__).resolve().parents[1] / "docs"


TO_BROKEN = {"cost": 'R{"cost"}=? [F broken]', "once": 'R{"once"}=? [F broken]'}
MIXED = {"cost": 'R{"cost"}=? [F broken]', "soon": "P=? [F<=6 broken]"}
DPM = ("X11 X21 X31 X41 X12 X22 X32 X42 X13 X23 X33 X43 X14 X24 X34 X44", "0..2")


def dpm(foreign: Path, free: int = 16):
    """PAYNT's dpm family (no observation: each decision a constant), the decisions after the
    first ``free`` fixed to 1."""
    names = DPM[0].split()
    decisions = [f"{n}={DPM[1] if i < free else '1..1'}" for i, n in enumerate(names)]
    folder = foreign / "paynt-dpm"
    return family(system_from_file(folder / "dpm.prism", decisions, [], folder / "dpm.pctl"))


def herman(foreign: Path, biases: str, bits: str = "0..1"):
    """PAYNT's herman family with its four coin biases cut to ``biases`` and its three bits
    to ``bits`` (bias 0 never flips a coin to 0: some policies never stabilise)."""
    folder = foreign / "paynt-herman"
    decisions = [f"{n}={biases}" for n in ("M0LFAIR", "M0HFAIR", "M1LFAIR", "M1HFAIR")] + [
        f"{n}={bits}" for n in ("MxxA", "MxxB", "MxxC")
    ]
    return family(system_from_file(folder / "herman.prism", decisions, [], folder / "herman.pctl"))


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
    # minimised expected rewards to one target combine into one expected reward
    yield "breaking, rewards to one target", family(breaking_system(TO_BROKEN))
    # and with the probability to reach that target within a step bound, maximised
    mixed = breaking_system(MIXED)
    yield (
        "breaking, reward and bounded reach",
        family(attrs.evolve(mixed, objectives=_flip(mixed.objectives, {"soon"}))),
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


@pytest.mark.parametrize("name", ["robot_grid 5x5", "web_ids", "tas"])
def test_a_weighted_sums_best_scheduler_votes_for_the_one_policy_of_its_sub_family(name):
    """Step-bounded weighted sums know no scheduler of their own; the best scheduler of one,
    read off its backward induction, votes by its expected steps in each value's states.
    Restricted to one policy, its votes name that policy's value of every decision a reached
    state consults, and no other; its steps within the horizon are at most the horizon."""
    from parley_core.quotient.bounds import RelaxedObjectives

    case = dict(_families())[name]
    relaxed = RelaxedObjectives(case, build_quotient(case))
    assert relaxed.weighted_ok
    rng = np.random.default_rng(3)
    for _ in range(3):
        policy = np.array([rng.integers(0, size) for size in relaxed.sizes], dtype=np.int64)
        view = relaxed.restrict(policy, policy.copy())
        votes = relaxed.horizon_votes(view, np.ones(len(case.objectives)))
        assert votes is not None
        consulted = relaxed.consulted(view)
        assert (np.count_nonzero(votes, axis=1) <= 1).all()
        taken = votes.sum(axis=1) > 0
        assert not (taken & ~consulted).any()
        assert (votes.argmax(axis=1)[taken] == policy[taken]).all()
        assert 0 < votes.sum() <= relaxed.weighted_horizon + 1e-9
    # over the whole family the relaxation's scheduler is free to disagree with itself
    everything = relaxed.restrict(np.zeros(len(relaxed.sizes), dtype=np.int64), relaxed.sizes - 1)
    assert relaxed.horizon_votes(everything, np.ones(len(case.objectives))).sum() > 0


@pytest.mark.slow
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


@pytest.mark.slow
def test_rewards_to_one_target_give_a_pareto_bound_on_a_model_we_did_not_write(foreign, monkeypatch):
    # PAYNT's dpm: power and lost requests, both expected until "finished"; their weighted
    # sums are one expected reward, bounded from below by policy iteration's value checked as
    # a post-fixpoint, where iterating from 0 takes thousands of sweeps
    from parley_core.quotient import policy_iteration
    from parley_core.quotient.bounds import RelaxedObjectives

    case = dpm(foreign)
    quotient = build_quotient(case)
    relaxed = RelaxedObjectives(case, quotient)
    assert relaxed.summed_ok and not relaxed.weighted_ok
    outer = pareto_outer(case, quotient, bounds=relaxed)
    assert "weighted sums (expected rewards to the target)" in outer.method
    policies = np.vstack(
        [np.array([p.values for p in case.baseline_policies()]).reshape(-1, len(case.decisions)),
         case.random(np.random.default_rng(5), 30)]
    ).astype(np.int64)  # fmt: skip
    storm = values(case, policies)
    assert outer.dominates(storm).all()
    # and much tighter than the ideal point (power 135.88, lostH 0.0095): with power below 137
    # no policy loses fewer than 5 requests
    ideal = ideal_point(case, quotient, relaxed).points[0]
    assert ideal[0] < 136 and ideal[1] < 0.01
    assert outer.points[outer.points[:, 0] < 137.0][:, 1].min() > 5.0
    # each weighted level is the least expected weighted reward to 1e-7: policy iteration's
    # guess against iterating from 0 to convergence, and below every policy's weighted sum
    view = relaxed.restrict(np.zeros(len(case.decisions), dtype=np.int64), relaxed.sizes - 1)
    weights = np.array([[1.0, 10.0], [1.0, 0.1]])
    fast = relaxed.weighted(view, weights)
    assert len(view.schedulers) == 2
    monkeypatch.setattr(policy_iteration, "ITERATIONS", 0)
    slow = relaxed.weighted(relaxed.restrict(np.zeros(len(case.decisions), dtype=np.int64), relaxed.sizes - 1), weights)
    np.testing.assert_allclose(fast, slow, rtol=1e-7)
    assert ((storm @ weights.T) * -1 <= fast + 1e-9).all()


def test_a_guess_is_lowered_to_a_post_fixpoint_or_refused():
    from parley_core.quotient.subfamily import post_fixpoint

    # state 0 pays 1 and reaches state 1 (the target) with probability 1/2, else stays: value 2
    state_actions, action_entries = np.array([0, 1, 1]), np.array([0, 2])
    targets, probabilities = np.array([1, 0]), np.array([0.5, 0.5])
    allowed, free, reward = np.array([True]), np.array([True, False]), np.array([1.0])
    for guess in (1.5, 2.0, 3.0):
        y = np.array([guess, 0.0])
        assert post_fixpoint(state_actions, action_entries, targets, probabilities, allowed, free, reward, y, 200)
        assert y[0] <= 2.0 and y[0] >= min(guess, 2.0) - 1e-9
    # a second action that stays for free: never reaching the target, its value is infinite,
    # but the margin for rounding cannot hold on a cycle that pays nothing, and it is refused
    state_actions, action_entries = np.array([0, 2, 2]), np.array([0, 2, 3])
    targets, probabilities = np.array([1, 0, 0]), np.array([0.5, 0.5, 1.0])
    allowed, reward = np.array([True, True]), np.array([1.0, 0.0])
    y = np.array([2.0, 0.0])
    assert not post_fixpoint(state_actions, action_entries, targets, probabilities, allowed, free, reward, y, 50)


@pytest.mark.slow
def test_a_reward_and_a_bounded_reach_combine_and_the_bound_holds(foreign):
    # PAYNT's herman (coin biases cut to 0..6 and three bits): expected steps to stabilise, and
    # stabilised within 30 steps; weighted sums by backward induction over the 30 steps,
    # then the least expected steps still to come. Storm's values of random policies (some
    # never stabilise: infinite steps) lie inside the bound, and the bound's weighted levels
    # lie above every policy's weighted sum
    from parley_core.quotient.bounds import RelaxedObjectives

    case = herman(foreign, "0..6")
    quotient = build_quotient(case)
    relaxed = RelaxedObjectives(case, quotient)
    assert relaxed.mixed_ok and relaxed.combines
    policies = case.random(np.random.default_rng(2), 30).astype(np.int64)
    storm = values(case, policies)
    assert np.isinf(storm[:, 0]).any() and np.isfinite(storm[:, 0]).any()
    outer = pareto_outer(case, quotient, bounds=relaxed)
    assert outer.dominates(storm).all()
    view = relaxed.restrict(np.zeros(len(case.decisions), dtype=np.int64), relaxed.sizes - 1)
    weights = np.array([[1.0, 1.0], [0.1, 1.0], [1.0, 0.01]])
    levels = relaxed.weighted(view, weights)
    finite = np.isfinite(storm).all(axis=1)
    sums = (storm[finite] * relaxed.signs) @ weights.T
    assert (sums <= levels + 1e-9).all()
    # and no level is looser than the ideal point's weighted sum
    assert (levels < ideal_point(case, quotient, relaxed).points[0] * relaxed.signs @ weights.T + 1e-9).all()


@pytest.mark.slow
def test_where_one_scheduler_attains_the_ideal_point_one_weighted_sum_shows_it(foreign, monkeypatch):
    # PAYNT's herman from bias 1: one scheduler of the relaxation has both the fewest steps and
    # the likeliest stabilisation within 30 steps, so no weighted sum can cut the ideal box;
    # the Pareto bound stops after one balanced sum (two more give its scale) and is the ideal point
    from parley_core.quotient.bounds import RelaxedObjectives

    case = herman(foreign, "1..6")
    quotient = build_quotient(case)
    relaxed = RelaxedObjectives(case, quotient)
    ideal = ideal_point(case, quotient, relaxed)
    solved = []
    weighted = relaxed.weighted
    monkeypatch.setattr(relaxed, "weighted", lambda view, w: solved.append(len(w)) or weighted(view, w))
    outer = pareto_outer(case, quotient, ideal, relaxed)
    assert sum(solved) == 3
    # the ideal point itself, as where nothing is cut: run_bounds.outer tells by identity
    assert outer is ideal
    storm = values(case, case.random(np.random.default_rng(4), 20).astype(np.int64))
    assert outer.dominates(storm).all()


@pytest.mark.slow
def test_a_sub_family_of_one_policy_has_schedulers_that_vote_for_it(foreign):
    # restricted to one policy, every scheduler the bounds find is that policy: its votes
    # (the mixed-radix digits of each state's action) name the policy's value of each decision
    # the reached states consult, and no other value. herman's states consult several
    # decisions at once (its coin biases and bits), so every digit is read
    from parley_core.quotient.bounds import RelaxedObjectives

    case = herman(foreign, "0..3")
    relaxed = RelaxedObjectives(case, build_quotient(case))
    r = relaxed.relaxation
    assert np.diff(r.state_decisions).max() > 1
    policy = np.array([2, 3, 1, 2, 1, 0, 1])  # coin biases from 1: it stabilises
    view = relaxed.restrict(policy, policy.copy())
    relaxed.ideal(view)
    relaxed.weighted(view, np.array([[1.0, 10.0]]))
    assert len(view.schedulers) == 2
    consulted = relaxed.consulted(view)
    for actions in view.schedulers:
        votes = relaxed.votes(view, actions)
        assert (votes.sum(axis=1) > 0).tolist() == consulted.tolist()
        assert (votes.argmax(axis=1)[consulted] == policy[consulted]).all()
        assert (np.count_nonzero(votes, axis=1) <= 1).all()


@pytest.mark.parametrize("name", ["robot_grid 5x5", "web_ids", "tas", "synchronised"])
def test_weighted_sums_solved_together_or_on_threads_are_each_solved_alone(name):
    # one pass of backward induction solves several weightings; how they are grouped and
    # how many threads solve the groups must not change a value
    from parley_core.quotient.bounds import RelaxedObjectives

    case = dict(_families())[name]
    quotient = build_quotient(case)
    weights = np.random.default_rng(3).random((11, len(case.objectives)))
    alone = RelaxedObjectives(case, quotient)
    assert alone.weighted_ok, f"{name}: its objectives should combine by backward induction"
    view = alone.restrict(np.zeros(len(alone.sizes), dtype=np.int64), alone.sizes - 1)
    one_by_one = np.concatenate([alone.weighted(view, w[None, :]) for w in weights])
    together = RelaxedObjectives(case, quotient, threads=2)
    assert np.isfinite(one_by_one).all()
    assert np.array_equal(together.weighted(view, weights), one_by_one)
    assert np.array_equal(alone.weighted(view, weights), one_by_one)
