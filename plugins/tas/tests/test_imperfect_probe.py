"""An imperfect probe (option ``probe_error``) means what docs/tas.md says.

A probe reports the backup's true level with probability ``1 - probe_error`` and each of the
``L`` other levels with probability ``probe_error / L`` (two levels: the other one); the UAC
takes the report as its estimate. The tests check, on values Storm computes:

- at ``probe_error=0`` the model is today's, bit for bit: the same text as the default
  options, and the values of fixed policies recorded with the generator before the option
  existed;
- the quotient evaluator and the independent computation of ``test_semantics.py`` (which
  follows the description, not the generator) agree with Storm when ``probe_error > 0``;
- exact consequences of the model: a fixed interval probes on a schedule that no report
  changes, so its values are affine in ``probe_error``; at ``probe_error = L/(L+1)`` every
  level is reported with probability ``1/(L+1)`` whatever the truth, the probe carries no
  information, and a fixed interval's values are a mixture of "always trust the backup" and
  "never trust it", paid for with the probes' cost;
- a tiny instance computed by hand, and a hand-written DTMC, give Storm's values on the
  generated model.
"""

from __future__ import annotations

import attrs
import numpy as np
import pytest

from parley_core import Direction, Objective, OptionError, testing
from parley_core.testing import storm_values
from parley_plugins.tas import CASE_STUDY as CASE
from parley_plugins.tas.tests.test_semantics import reference

# Storm's values on the generator as it was before probe_error existed (commit aede3d8):
# (settings, [(policy, failure, cost)]).
TODAY = [
    (
        [],
        [
            ([1] * 6, 0.03147363500890228, 24.82764526728934),
            ([3] * 6, 0.03247345048016325, 16.88337925778557),
            ([11] * 6, 0.04562540613532967, 12.745894185373906),
            ([5, 4, 11, 11, 11, 11], 0.03324979702756725, 14.4881988168035),
            ([2, 7, 1, 9, 3, 6], 0.03305060394739714, 17.998974364254572),
        ],
    ),
    (
        ["rounds=8", "max_interval=3", "backup_levels=0.05,0.07,0.4,1"],
        [
            ([1] * 8, 0.030843256838862135, 24.690306617406552),
            ([2, 4, 1, 3, 4, 1, 2, 2], 0.031024215512107996, 17.65559774263523),
        ],
    ),
    (
        ["rounds=6", "max_interval=3", "backup_levels=0.05,1"],
        [([1] * 4, 0.030677010724226454, 24.695314384644), ([2, 1, 4, 3], 0.0322784436618432, 19.0959874785799)],
    ),
]
SMALL = ["rounds=12", "max_interval=5"]


def values(settings: list[str], policies, extra: tuple[Objective, ...] = ()) -> np.ndarray:
    system = CASE.build(CASE.options(settings))
    if extra:
        system = attrs.evolve(system, objectives=[*system.objectives, *extra])
    family = testing.family(system)
    return testing.values(family, np.asarray(policies, dtype=np.int64).reshape(-1, len(family.decisions)))


def uniform(settings: list[str], c: int) -> list[int]:
    return [c] * len(testing.family(CASE, settings).decisions)


@pytest.mark.parametrize(("settings", "today"), TODAY, ids=["defaults", "four levels", "two levels"])
def test_probe_error_zero_gives_todays_model_and_values(settings, today):
    exact = CASE.build(CASE.options([*settings, "probe_error=0"])).prism
    assert exact == CASE.build(CASE.options(settings)).prism
    assert "pProbeError" not in exact
    got = values([*settings, "probe_error=0"], [p for p, _, _ in today])
    for row, (_, failure, cost) in zip(got, today):
        assert row[0] == pytest.approx(failure, rel=1e-12, abs=1e-15)
        assert row[1] == pytest.approx(cost, rel=1e-12)


def test_a_misreport_picks_one_of_the_other_levels():
    two = CASE.build(CASE.options(["backup_levels=0.05,1", "probe_error=0.3"])).prism
    assert (
        "[probe] step>=c -> 1-pProbeError : (bhat'=b) & (step'=1) + pProbeError/L : (bhat'=mod(b+1, L+1)) & (step'=1);"
    ) in two
    always_wrong = CASE.build(CASE.options(["probe_error=1"])).prism  # three levels: the true one is never written
    assert (
        "[probe] step>=c -> pProbeError/L : (bhat'=mod(b+1, L+1)) & (step'=1)"
        " + pProbeError/L : (bhat'=mod(b+2, L+1)) & (step'=1);"
    ) in always_wrong


@pytest.mark.parametrize(
    "settings",
    [
        ["rounds=8", "max_interval=4", "probe_error=0.2", "response_time=true"],
        ["rounds=8", "max_interval=3", "backup_levels=0.05,0.07,0.4,1", "degrade=0.15", "probe_error=0.5"],
        ["rounds=6", "max_interval=3", "backup_levels=0.05,1", "probe_error=1", "p_vital=0.9"],
    ],
)
def test_storm_matches_the_independent_computation_with_an_imperfect_probe(settings):
    options = CASE.options(settings)
    family = testing.family(CASE, settings)
    n = len(family.decisions)
    rng = np.random.default_rng(n)
    policies = np.vstack([np.full(n, 1), np.full(n, 2), rng.integers(1, options.max_interval + 2, size=(4, n))])
    got = testing.values(family, policies)
    for row, policy in zip(got, policies):
        expected = reference(options, {d.valuation: int(v) for d, v in zip(family.decisions, policy)})
        assert tuple(row) == pytest.approx(expected[: len(row)], rel=1e-9, abs=1e-12)


def test_the_quotient_evaluator_agrees_with_storm_with_an_imperfect_probe():
    family = testing.family(CASE, [*SMALL, "probe_error=0.15"])
    policies = np.random.default_rng(3).integers(1, 7, size=(12, len(family.decisions)))
    assert testing.left_to_storm(family) == ()
    fast = testing.values(family, policies, evaluator="quotient")
    assert fast == pytest.approx(testing.values(family, policies), rel=1e-9, abs=1e-12)


def test_a_fixed_interval_is_affine_in_the_probe_error_and_a_policy_that_reads_reports_is_not():
    # every-k probes at executions k, 2k, ... whatever the reports say, so each execution's
    # estimate is one report (or the initial one): its distribution, and every expected
    # value, is affine in probe_error. A policy whose interval depends on bhat probes on a
    # schedule that the reports change: products of report probabilities, not affine.
    mixed = [1, 2, 6, 6, 3, 6]
    policies = [[1] * 6, [3] * 6, mixed]
    by_error = {e: values([*SMALL, f"probe_error={e}"], policies) for e in (0, 0.5, 1)}
    midpoint = (by_error[0] + by_error[1]) / 2
    assert by_error[0.5][:2] == pytest.approx(midpoint[:2], rel=1e-12, abs=1e-15)
    assert abs(by_error[0.5][2, 0] - midpoint[2, 0]) > 1e-5
    # a misreport hurts the fixed intervals here (the backup is often trusted when it is bad)
    assert by_error[0.5][0, 0] > by_error[0][0, 0]


@pytest.mark.parametrize("k", [1, 3])
def test_an_uninformative_probe_makes_a_fixed_interval_a_mixture_of_never_probing(k):
    # With three levels and probe_error = 2/3 each level is reported with probability 1/3,
    # independently of everything: the estimate after a probe says nothing. Under every-k,
    # executions 1..k-1 keep the initial estimate 0 (trust the backup) and each later one
    # acts on a fresh uniform report: trust (level 0) with 1/3, the alternative with 2/3.
    # Never probing keeps the estimate at 0 and always trusts the backup; with every level's
    # failure rate above the alternative's (backup_levels=1,1,1) the UAC never trusts it and
    # the backup's level plays no part. So each objective of every-k, summed over executions,
    # is "trust" over the first k-1, then 1/3 trust + 2/3 alternative, plus the probes' cost.
    rounds = 12
    head = (
        Objective(name="failure_head", formula=f'R{{"failures"}}=? [C<={7 * (k - 1)}]', direction=Direction.MIN),
        Objective(name="cost_head", formula=f'R{{"cost"}}=? [C<={7 * (k - 1)}]', direction=Direction.MIN),
    )
    trust = values(SMALL, [[6] * 6], head)[0]
    alternative = values([*SMALL, "backup_levels=1,1,1"], [[6] * 6], head)[0]
    mixture = trust[2:] + (trust[:2] - trust[2:]) / 3 + 2 * (alternative[:2] - alternative[2:]) / 3
    mixture[1] += 11.9 * (rounds // k) / rounds
    uninformative = values([*SMALL, f"probe_error={2 / 3!r}"], [[k] * 6])[0]
    assert uninformative == pytest.approx(mixture, rel=1e-12, abs=1e-15)
    informative = values(SMALL, [[k] * 6])[0]
    assert informative[0] < uninformative[0] - 1e-4  # a perfect probe, though, is worth something


def test_probing_every_execution_no_longer_keeps_the_estimate_right():
    # A perfect probe every execution means a fail-over never acts on a stale estimate
    # (test_semantics.py); a misreport does, and more often the more it misreports.
    formula = 'P=? [F<=70 ("failover" & "stale")]'
    stale = [
        storm_values(
            CASE.build(CASE.options(["rounds=10", "max_interval=4", f"probe_error={e}"])).prism, [formula], {"c": 1}
        )[0]
        for e in (0, 0.1, 0.4)
    ]
    assert stale[0] == 0.0 and 0.0 < stale[1] < stale[2]


TINY = ["backup_levels=0.05,1", "p_vital=1", "p_alarm=0", "p_drug=0", "p_dose=0", "max_interval=4"]
"""Two health levels, every request analyzed, every analysis "patient ok": an execution
fails only if the primary fails and so does the provider it fails over to."""


def test_one_execution_by_hand():
    # rounds=1, probe every execution, probe_error 0.2. Before the probe the backup degrades
    # to level 1 with 0.05 and the load turns to peak with 0.1 (independently), so
    # E[primary fails] = 0.9 x 0.12 + 0.1 x 0.24 = 0.132. The fail-over fails with
    # level 0: 0.8 x 0.05 (reported 0: backup) + 0.2 x 0.07 (reported 1: alternative) = 0.054,
    # level 1: 0.8 x 0.07 + 0.2 x 1.0 = 0.256;
    # failure = 0.132 x (0.95 x 0.054 + 0.05 x 0.256) = 0.132 x 0.0641 = 0.0084612.
    # cost = probe 11.9 + primary 4 + 0.132 x (0.95 x (0.8 x 11.9 + 0.2 x 14) + 0.05 x (0.8 x 14 + 0.2 x 11.9))
    #      = 15.9 + 0.132 x 12.383 = 17.534556.
    failure, cost = values(["rounds=1", *TINY, "probe_error=0.2"], [[1] * 4])[0]
    assert failure == pytest.approx(0.0084612, rel=1e-12)
    assert cost == pytest.approx(17.534556, rel=1e-12)


HAND_MODEL = """
dtmc
// The TINY scenario under every-k, written by hand from docs/tas.md: one execution is drift
// (and load), probe or not, serve.
const int R;
const int k;
const double e;
formula up = min(b+1, 1);
formula down = max(b-1, 0);
formula fPrimary = load=1 ? 0.24 : 0.12;
module M
  b : [0..1] init 0;
  load : [0..1] init 0;
  bhat : [0..1] init 0;
  step : [1..k] init 1;
  n : [0..R] init 0;
  p : [0..2] init 0;
  [drift] p=0 & n<R & load=0 -> 0.05*0.1 : (b'=up) & (load'=1) & (n'=n+1) & (p'=1)
                              + 0.05*0.9 : (b'=up) & (n'=n+1) & (p'=1)
                              + 0.1*0.1 : (b'=down) & (load'=1) & (n'=n+1) & (p'=1)
                              + 0.1*0.9 : (b'=down) & (n'=n+1) & (p'=1)
                              + 0.85*0.1 : (load'=1) & (n'=n+1) & (p'=1)
                              + 0.85*0.9 : (n'=n+1) & (p'=1);
  [drift] p=0 & n<R & load=1 -> 0.05*0.2 : (b'=up) & (load'=0) & (n'=n+1) & (p'=1)
                              + 0.05*0.8 : (b'=up) & (n'=n+1) & (p'=1)
                              + 0.1*0.2 : (b'=down) & (load'=0) & (n'=n+1) & (p'=1)
                              + 0.1*0.8 : (b'=down) & (n'=n+1) & (p'=1)
                              + 0.85*0.2 : (load'=0) & (n'=n+1) & (p'=1)
                              + 0.85*0.8 : (n'=n+1) & (p'=1);
  [probe] p=1 & step>=k -> 1-e : (bhat'=b) & (step'=1) & (p'=2) + e : (bhat'=1-b) & (step'=1) & (p'=2);
  [skip] p=1 & step<k -> (step'=step+1) & (p'=2);
  [serve] p=2 -> (p'=0);
  [over] p=0 & n=R -> true;
endmodule
rewards "failures"
  [serve] true : fPrimary * (bhat=0 ? (b=0 ? 0.05 : 1.0) : 0.07) / R;
endrewards
rewards "cost"
  [probe] true : 11.9 / R;
  [serve] true : (4 + fPrimary * (bhat=0 ? 11.9 : 14)) / R;
endrewards
label "over" = p=0 & n=R;
"""


@pytest.mark.parametrize(("rounds", "k", "error"), [(1, 1, "0.2"), (5, 2, "0.3"), (9, 3, "1")])
def test_a_fixed_interval_matches_a_hand_written_dtmc(rounds, k, error):
    constants = {"R": rounds, "k": k}
    text = HAND_MODEL.replace("const double e;", f"const double e = {error};")
    failure, cost = storm_values(text, ['R{"failures"}=? [F "over"]', 'R{"cost"}=? [F "over"]'], constants)
    got = values([f"rounds={rounds}", *TINY, f"probe_error={error}"], [[k] * 4])[0]
    assert got == pytest.approx([failure, cost], rel=1e-9, abs=1e-12)


@pytest.mark.parametrize("levels", ["0.05,1", "0.05,0.3,1.0", "0.05,0.07,0.4,1"])
@pytest.mark.parametrize("error", ["0.3", "1"])
def test_every_probe_error_gives_a_dtmc_also_in_exact_arithmetic(levels, error):
    # Storm's rational engine refuses distributions that do not sum to exactly 1.
    settings = ["rounds=3", "max_interval=2", f"backup_levels={levels}", f"probe_error={error}"]
    text = CASE.build(CASE.options(settings)).prism
    formulas = ['R{"failures"}=? [C<=21]', 'R{"cost"}=? [C<=21]']
    exact = storm_values(text, formulas, {"c": 1}, exact=True)
    assert exact == pytest.approx(storm_values(text, formulas, {"c": 1}), rel=1e-12)


@pytest.mark.parametrize("setting", ["probe_error=1.01", "probe_error=-0.5"])
def test_probe_errors_outside_zero_one_are_refused(setting):
    with pytest.raises(OptionError, match="probe_error"):
        CASE.options([setting])
