"""The quotient evaluator agrees with Storm: every property kind it supports, the fallback
for those it does not, the robot on random maps and policies (also property-based)."""

from __future__ import annotations

import itertools

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from conftest import TOY, toy_system
from parley_core.evaluate.quotient import QuotientEvaluator
from parley_core.evaluate.storm import StormEvaluator
from parley_core.family.augment import augment
from parley_core.model import DecisionKind, Objective, Service
from parley_core.quotient.coloring import build_quotient
from parley_core.quotient.solver import QuotientSolver
from parley_core.testing import family as case_family
from parley_plugins.robot_grid import CASE_STUDY as ROBOT

# The toy (tests/conftest.py) with an absorbing "broken" state reached from a degraded
# server, so that rewards until it are finite and total rewards can be infinite, and an
# overlap of two enabled commands (probe and inspect) that Storm mixes uniformly.
BREAKING = (
    TOY.replace(
        "  [wait] step<c & h=0 -> (phase'=1-phase) & (step'=step+1);",
        "  [wait] step<c & h=0 -> 0.7 : (phase'=1-phase) & (step'=step+1) + 0.3 : (h'=0) & (broken'=true);\n"
        "  [inspect] step>=c & phase=1 & !broken -> (step'=1);",
    )
    .replace("  step : [1..K] init 1;", "  step : [1..K] init 1;\n  broken : bool init false;")
    .replace("  [probe] step>=c ->", "  [probe] step>=c & !broken ->")
    .replace("  [wait] step<c & h=1 ->", "  [wait] step<c & h=1 & !broken ->")
)

OBJECTIVES = {
    "reach": "P=? [F broken]",
    "until": "P=? [h=1 U broken]",
    "bounded": "P=? [F<=6 broken]",
    "bounded_until": "P=? [phase=0 | h=1 U<=5 broken]",
    "reward_reach": 'R{"cost"}=? [F broken]',
    "reward_reach_infinite": 'R{"cost"}=? [F h=2]',
    "cumulative": 'R{"cost"}=? [C<=17]',
    "total": 'R{"cost"}=? [C]',
    "total_finite": 'R{"once"}=? [C]',
}


def breaking_system(objectives: dict[str, str]):
    text = BREAKING.replace(
        "endrewards", 'endrewards\nrewards "once"\n  [probe] step=3 : 2;\n  phase=1 & !broken & h=0 : 0;\nendrewards', 1
    )
    return toy_system(
        prism=text,
        objectives=[Objective(name=name, formula=formula, direction="min") for name, formula in objectives.items()],
    )


def all_policies(family):
    return np.array(list(itertools.product(*(range(d.service.low, d.service.high + 1) for d in family.decisions))))


def test_every_supported_kind_agrees_with_storm_on_every_policy():
    family = augment(breaking_system(OBJECTIVES))
    policies = all_policies(family)
    with QuotientEvaluator(family, workers=1) as quotient, StormEvaluator(family, workers=1) as storm:
        assert quotient.fallback == ()
        fast, reference = quotient.evaluate(policies), storm.evaluate(policies)
    finite = np.isfinite(reference)
    assert (np.isfinite(fast) == finite).all()
    # both solvers stop at a relative precision of 1e-12
    assert np.allclose(fast[finite], reference[finite], rtol=1e-9, atol=1e-9)
    names = list(OBJECTIVES)
    assert np.isinf(reference[:, names.index("reward_reach_infinite")]).all()
    assert np.isinf(reference[:, names.index("total")]).any(), "the total-reward case should meet infinity"
    assert np.isfinite(reference[:, names.index("total_finite")]).all()


def test_the_direct_solve_after_the_sweep_limit_agrees_with_storm(monkeypatch):
    # one sweep is never enough here, so every iterative objective ends in the direct solve,
    # where states that cannot reach the target must be left out of I - P
    from parley_core.quotient import solver as module

    monkeypatch.setattr(module, "SLOW_SWEEPS", 1)
    kinds = ("reach", "until", "reward_reach", "total_finite")
    degraded = "P=? [F h=0 & !broken]"  # the broken states (reached after it) never reach it
    family = augment(breaking_system({"degraded": degraded, **{k: OBJECTIVES[k] for k in kinds}}))
    policies = all_policies(family)
    with QuotientEvaluator(family, workers=1) as quotient, StormEvaluator(family, workers=1) as storm:
        fast, reference = quotient.evaluate(policies), storm.evaluate(policies)
    finite = np.isfinite(reference)
    assert (np.isfinite(fast) == finite).all() and finite.sum() > finite.size // 2
    assert np.allclose(fast[finite], reference[finite], rtol=1e-9, atol=1e-9)
    assert (fast[:, 0] > 0).all()


def test_unsupported_properties_fall_back_to_storm():
    objectives = {"globally": "P=? [G h=1]", "instant": 'R{"cost"}=? [I=5]', "reach": "P=? [F broken]"}
    family = augment(breaking_system(objectives))
    policies = all_policies(family)
    with QuotientEvaluator(family, workers=1) as quotient, StormEvaluator(family, workers=1) as storm:
        assert quotient.fallback == ("globally", "instant")
        assert np.abs(quotient.evaluate(policies) - storm.evaluate(policies)).max() <= 1e-9


@pytest.mark.slow
@pytest.mark.parametrize(("size", "seed", "p"), [(6, 1, 0.02), (8, 4, 0.05), (10, 0, 0.01)])
def test_robot_random_policies_and_baselines_agree_with_storm(size, seed, p):
    family = augment(ROBOT.build(ROBOT.options([f"size={size}", f"seed={seed}", f"p={p}"])))
    rng = np.random.default_rng(seed)
    policies = np.vstack(
        [[b.values for b in family.baseline_policies()], rng.integers(1, 11, size=(12, len(family.decisions)))]
    )
    with QuotientEvaluator(family, workers=1) as quotient, StormEvaluator(family, workers=1) as storm:
        assert np.abs(quotient.evaluate(policies) - storm.evaluate(policies)).max() <= 1e-9


@pytest.mark.slow
def test_worker_processes_give_bit_identical_values():
    family = augment(ROBOT.build(ROBOT.options(["size=5", "seed=2"])))
    policies = np.random.default_rng(0).integers(1, 11, size=(70, len(family.decisions)))
    with QuotientEvaluator(family, workers=1) as one, QuotientEvaluator(family, workers=2) as two:
        assert two.evaluate(policies[:20]).shape == (20, 2) and two._pool is None  # too few to start them
        assert np.array_equal(one.evaluate(policies), two.evaluate(policies))
        # once the workers run, a polishing round's 20 go to them too (a chunk each), with the same values
        pool, submitted = two._pool, []
        assert pool is not None
        submit = pool.submit
        pool.submit = lambda *args, **kwargs: submitted.append(args) or submit(*args, **kwargs)  # type: ignore[method-assign]
        assert np.array_equal(one.evaluate(policies[:20]), two.evaluate(policies[:20]))
        assert len(submitted) == 2


@settings(max_examples=25, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(
    size=st.integers(3, 5),
    seed=st.integers(0, 10_000),
    p=st.sampled_from([0.0, 0.01, 0.05, 0.1]),
    horizon=st.integers(1, 60),
    max_interval=st.integers(1, 4),
    data=st.data(),
)
def test_property_quotient_equals_storm_on_random_maps_and_policies(size, seed, p, horizon, max_interval, data):
    options = ROBOT.options(
        [f"size={size}", f"seed={seed}", f"p={p}", f"horizon={horizon}", f"max_interval={max_interval}"]
    )
    family = augment(ROBOT.build(options))
    n = len(family.decisions)
    policy = data.draw(st.lists(st.integers(1, max_interval), min_size=n, max_size=n))
    with QuotientEvaluator(family, workers=1) as quotient, StormEvaluator(family, workers=1) as storm:
        difference = np.abs(quotient.evaluate([policy]) - storm.evaluate([policy])).max()
    assert difference <= 1e-6


SYNCHRONISED = """dtmc
const int c;
module A
  a : [0..3] init 0;
  [go] a<c -> (a'=a+1);
  [go] a>=c -> (a'=0);
endmodule
module B
  b : [0..3] init 0;
  [go] b<c -> 0.5 : (b'=b+1) + 0.5 : (b'=b);
  [go] b>=c -> (b'=b);
endmodule
rewards "b"
  true : b;
endrewards
"""


def synchronised_system(*objectives: tuple[str, str, str]):
    """:data:`SYNCHRONISED`, its service observed by ``a``, with objectives (name, formula,
    direction)."""
    return toy_system(
        prism=SYNCHRONISED,
        observation=("a",),
        objectives=[Objective(name=name, formula=formula, direction=way) for name, formula, way in objectives],
    )


def test_a_constant_read_by_synchronising_modules_agrees_with_storm():
    # a choice of the quotient combines A's copy for one value of c with B's for another:
    # no policy keeps it, as no policy's DTMC has it
    system = synchronised_system(("full", "P=? [F b=3]", "max"), ("load", 'R{"b"}=? [C<=6]', "min"))
    family = augment(system)
    policies = np.array(list(itertools.product(range(1, 4), repeat=len(family.decisions))))
    with QuotientEvaluator(family, workers=1) as fast, StormEvaluator(family, workers=1) as storm:
        assert fast.evaluate(policies) == pytest.approx(storm.evaluate(policies), abs=1e-9)


STUCK = """dtmc
const int c;
module m
  x : [0..3] init 0;
  [a] x<c -> 0.5 : (x'=x+1) + 0.5 : (x'=0);
  [b] x>c -> (x'=0);
  [d] x=3 -> true;
endmodule
rewards "steps"
  true : 1;
endrewards
"""


@pytest.mark.slow
def test_the_deadlock_label_is_each_policys_own():
    # at x=c no command is enabled: the policy's DTMC labels that state "deadlock", which
    # the quotient (where another value of c enables a command there) does not
    system = toy_system(
        prism=STUCK,
        services=[Service(name="probe", constant="c", kind=DecisionKind.FREQUENCY, low=0, high=3)],
        observation=("x",),
        objectives=[
            Objective(name="stuck", formula='P=? [F "deadlock"]', direction="min"),
            Objective(name="until", formula='R{"steps"}=? [F "deadlock"]', direction="min"),
            Objective(name="soon", formula='P=? [F<=4 "deadlock"]', direction="min"),
            Objective(name="mixed", formula='P=? [F ("deadlock" & x=1)]', direction="min"),
        ],
        baselines=[],
    )
    family = augment(system)
    policies = np.array(list(itertools.product(range(0, 4), repeat=len(family.decisions))))[::3]
    with QuotientEvaluator(family, workers=1) as fast, StormEvaluator(family, workers=1) as storm:
        assert fast.fallback == ("mixed",)  # "deadlock" inside another formula: Storm decides it
        assert fast.evaluate(policies) == pytest.approx(storm.evaluate(policies), abs=1e-9)


def _without_lookup(solver: QuotientSolver) -> QuotientSolver:
    """The solver testing each choice's labels, as before the lookup (kernels.choice_index)."""
    lookup = solver.chain.lookup
    solver.chain = solver.chain._replace(lookup=(np.full_like(lookup[0], -1), *lookup[1:]))
    return solver


@pytest.mark.parametrize("name", ["breaking", "synchronised", "stuck", "robot_grid 3x3", "web_ids 3^6"])
def test_looking_choices_up_keeps_the_choices_a_test_of_each_keeps(name):
    family = {
        "breaking": lambda: augment(breaking_system(OBJECTIVES)),
        "synchronised": lambda: augment(synchronised_system(("load", 'R{"b"}=? [C<=6]', "min"))),
        "stuck": lambda: augment(
            toy_system(
                prism=STUCK,
                observation=("x",),
                objectives=[Objective(name="steps", formula='R{"steps"}=? [C<=5]', direction="min")],
            )
        ),
        "robot_grid 3x3": lambda: case_family("robot_grid", ["size=3", "seed=2"], width=3),
        "web_ids 3^6": lambda: case_family("web_ids", ["rounds=6"], width=3),
    }[name]()
    quotient = build_quotient(family)
    fast, slow = QuotientSolver(quotient), _without_lookup(QuotientSolver(quotient))
    rng = np.random.default_rng(5)
    values = [d.service.values for d in family.decisions]
    policies = np.array([[rng.choice(v) for v in values] for _ in range(60)], dtype=np.int64)
    for policy in policies:
        assert fast.solve(policy) == slow.solve(policy)  # bit for bit: the same choices, in order
        assert (fast.consulted == slow.consulted).all()
    looked_up = (fast.chain.lookup[0] >= 0).any()
    # synchronised: every labelled choice reads two decisions, so each is tested as before
    assert looked_up == (name != "synchronised"), looked_up


def test_a_large_batch_is_cut_into_chunks_by_the_time_a_policy_took():
    from parley_core.evaluate import quotient as module

    fam = case_family("robot_grid", ["size=4", "seed=1", "max_interval=2"])
    evaluator = QuotientEvaluator(fam, workers=2)
    fewest, most = (2 * c for c in module.CHUNKS)
    assert evaluator._chunks(100) == fewest  # nothing timed yet
    evaluator._per_policy = 0.03  # a 50x50 map's: a chunk a policy would do, up to the most
    assert evaluator._chunks(100) == most
    evaluator._per_policy = 0.0015  # map_10's: 14 policies a chunk
    assert evaluator._chunks(100) == max(fewest, -(-100 // 14))
    rows = fam.random(np.random.default_rng(2), module.START_WORKERS).astype(np.int64)
    with evaluator:
        timed = evaluator.evaluate(rows)
    assert evaluator._per_policy is not None and evaluator._per_policy > 0
    with QuotientEvaluator(fam, workers=1) as alone:
        assert np.array_equal(timed, alone.evaluate(rows))
