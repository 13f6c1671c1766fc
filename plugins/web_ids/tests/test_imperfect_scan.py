"""An imperfect scan (options ``scan_fn``, ``scan_fp``) means what docs/web_ids.md says.

A scan reports "compromised" (``ahat := 10``) or "clean" (``ahat := 0``), and the
controller trusts the report: a compromised A is missed (reported clean) with probability
``scan_fn``, a clean A flagged with probability ``scan_fp``. The tests check, on values
Storm computes:

- at rates 0 the model is today's, bit for bit: the same text as the default options, and
  the values of fixed policies recorded with the generator before the options existed;
- the quotient evaluator and the independent computation of ``test_semantics.py`` (which
  follows the description, not the generator) agree with Storm when the rates are positive;
- exact consequences of the model: a false positive restores a clean A, which changes no
  server's state, so ``infected`` does not depend on ``scan_fp`` and ``cost`` is affine in
  it; a false negative leaves a compromised A alone, so ``infected`` cannot fall as
  ``scan_fn`` grows; with ``scan_fn=1`` every scan says "clean": it costs, tells nothing,
  and silences the restore the IDS's estimate would have caused;
- a tiny instance computed by hand, and a hand-written DTMC of always scanning, give
  Storm's values on the generated model.
"""

from __future__ import annotations

import numpy as np
import pytest

from parley_core import OptionError, testing
from parley_core.testing import storm_values
from parley_plugins.web_ids import CASE_STUDY as CASE
from parley_plugins.web_ids.tests.test_semantics import reference

NEVER = 11

# Storm's values on the generator as it was before scan_fn/scan_fp existed (commit aede3d8),
# with the default options (50 rounds): (policy, infected, cost).
TODAY = [
    ([0] * 6, 0.0, 1633.9999999999986),
    ([2] * 6, 314.3004483102318, 1169.2102072986654),
    ([NEVER] * 6, 388.9725066371982, 735.2543116337416),
    ([NEVER, NEVER, 1, 1, 2, 2], 276.6659720884145, 1013.0437072848697),
    ([5, 3, 0, 7, 10, 4], 340.5301756664759, 1062.9236865302464),
]
# ... and with rounds=6, ids_error=0.4, restore_at=5
TODAY_OTHER = [([0] * 6, 0.0, 167.99999999999994), ([4, NEVER, 1, 6, 2, 9], 28.5621774847046, 37.434458660344646)]


def values(settings: list[str], policies) -> np.ndarray:
    family = testing.family(CASE, settings)
    return testing.values(family, np.asarray(policies, dtype=np.int64).reshape(-1, len(family.decisions)))


def random_policies(seed: int, n: int) -> np.ndarray:
    return np.random.default_rng(seed).integers(0, NEVER + 1, size=(n, 6))


@pytest.mark.parametrize(
    ("settings", "today"), [([], TODAY), (["rounds=6", "ids_error=0.4", "restore_at=5"], TODAY_OTHER)]
)
def test_rates_zero_give_todays_model_and_values(settings, today):
    exact = CASE.build(CASE.options([*settings, "scan_fn=0", "scan_fp=0"])).prism
    assert exact == CASE.build(CASE.options(settings)).prism
    assert "scanFN" not in exact and "scanFP" not in exact
    got = values([*settings, "scan_fn=0", "scan_fp=0"], [p for p, _, _ in today])
    for row, (_, infected, cost) in zip(got, today):
        assert row[0] == pytest.approx(infected, rel=1e-12, abs=1e-12)
        assert row[1] == pytest.approx(cost, rel=1e-12, abs=1e-12)


def test_each_rate_alone_writes_only_its_own_updates():
    fn_only = CASE.build(CASE.options(["scan_fn=0.25"])).prism
    assert "[scan] a=1 -> 1-scanFN : (ahat'=10) + scanFN : (ahat'=0);" in fn_only
    assert "[scan] a=0 -> (ahat'=0);" in fn_only and "scanFP" not in fn_only
    extreme = CASE.build(CASE.options(["scan_fn=1", "scan_fp=1"])).prism
    assert "[scan] a=1 -> (ahat'=0);" in extreme and "[scan] a=0 -> (ahat'=10);" in extreme


@pytest.mark.parametrize("rates", [("0.2", "0.1"), ("0.5", "0"), ("0", "0.35"), ("1", "1")])
def test_storm_matches_the_independent_computation_with_an_imperfect_scan(rates):
    settings = ["rounds=9", "start_hour=7", f"scan_fn={rates[0]}", f"scan_fp={rates[1]}"]
    options = CASE.options(settings)
    family = testing.family(CASE, settings)
    policies = np.vstack([[0] * 6, [NEVER] * 6, random_policies(11, 4)])
    got = testing.values(family, policies)
    for row, policy in zip(got, policies):
        expected = reference(options, {d.valuation: int(v) for d, v in zip(family.decisions, policy)})
        assert tuple(row) == pytest.approx(expected, rel=1e-9, abs=1e-9)


def test_the_quotient_evaluator_agrees_with_storm_with_an_imperfect_scan():
    family = testing.family(CASE, ["rounds=20", "scan_fn=0.15", "scan_fp=0.05"])
    policies = random_policies(5, 12)
    assert testing.left_to_storm(family) == ()
    fast = testing.values(family, policies, evaluator="quotient")
    assert fast == pytest.approx(testing.values(family, policies), rel=1e-9, abs=1e-9)


def test_false_positives_cost_restores_of_a_clean_a_and_nothing_else():
    # A false positive restores a clean A: the servers' states, and so every later round,
    # are as with a perfect scan. infected is the same; cost gains fp x (the expected
    # restore prices of scans of a clean A), linear in fp.
    policies = np.vstack([[0] * 6, [3] * 6, random_policies(2, 4)])
    by_fp = {fp: values(["rounds=20", "scan_fn=0.3", f"scan_fp={fp}"], policies) for fp in (0, 0.4, 1)}
    assert by_fp[0.4][:, 0] == pytest.approx(by_fp[0][:, 0], rel=1e-12, abs=1e-12)
    assert by_fp[1][:, 0] == pytest.approx(by_fp[0][:, 0], rel=1e-12, abs=1e-12)
    assert by_fp[0.4][:, 1] == pytest.approx(0.6 * by_fp[0][:, 1] + 0.4 * by_fp[1][:, 1], rel=1e-12)
    assert np.all(by_fp[1][:, 1] > by_fp[0][:, 1])  # every policy here scans a clean A sometimes


def test_more_false_negatives_never_lower_infected():
    # A missed compromise leaves A compromised, from where B can fall; a caught one restores
    # A. By induction over the rounds (a round that starts with A compromised is no better
    # for infected than one that starts clean), infected is nondecreasing in scan_fn, for
    # every policy, strictly for one that scans.
    policies = np.vstack([[0] * 6, [NEVER] * 6, random_policies(4, 4)])
    infected = np.array([values(["rounds=20", f"scan_fn={fn}"], policies)[:, 0] for fn in (0, 0.1, 0.6, 1)])
    assert np.all(np.diff(infected, axis=0) >= -1e-9)
    assert infected[-1, 0] > infected[0, 0] + 100  # always scanning
    assert infected[:, 1] == pytest.approx([infected[0, 1]] * 4, rel=1e-12)  # never scanning: no scans to fail


def test_always_scanning_with_false_negatives_misses_what_threshold_1_misses():
    # Always scanning with scan_fn=0.05 lets a compromised A through with probability 0.05 a
    # round; so does threshold 1 with a perfect scan: the IDS reports 0 for a compromised A
    # with probability 0.05, with fresh and with stale rules. Same misses, same infected
    # (the costs differ: threshold 1 does not scan the estimate 0).
    (always,) = values(["rounds=20", "scan_fn=0.05"], [[0] * 6])
    (one,) = values(["rounds=20"], [[1] * 6])
    assert always[0] == pytest.approx(one[0], rel=1e-12)
    assert always[1] != pytest.approx(one[1], rel=1e-3)


def test_a_scan_that_always_says_clean_tells_nothing_and_silences_restores():
    # scan_fn=1, scan_fp=0: every scan reports "clean" (ahat := 0) whatever A's state, so the
    # controller does NOP after every scan. Not "the same as never scanning minus the scan's
    # cost": a scan of an estimate >= restore_at cancels the restore that estimate would have
    # caused. What holds exactly:
    # (1) no policy has lower infected than never scanning (scans only cancel restores);
    policies = np.vstack([[NEVER] * 6, random_policies(9, 6)])
    blind = values(["rounds=20", "scan_fn=1"], policies)
    assert np.all(blind[1:, 0] >= blind[0, 0] - 1e-9)
    assert np.any(blind[1:, 0] > blind[0, 0] + 1.0)
    # (2) a policy whose thresholds are all <= restore_at (3) scans every estimate that would
    # restore A, so A is never restored alone: the chain is that of never scanning with a
    # controller that never restores A (restore_at=10: the published IDS never reports 10
    # while B is up), plus the scans' cost. With scans for free, the values are equal.
    low = np.array([[0] * 6, [3] * 6, [1, 2, 3, 0, 3, 2]])
    free = values(["rounds=20", "scan_fn=1", "scan_cost=0"], low)
    unrestored = values(["rounds=20", "restore_at=10"], [[NEVER] * 6])[0]
    assert free == pytest.approx(np.tile(unrestored, (3, 1)), rel=1e-12, abs=1e-12)
    paid = values(["rounds=20", "scan_fn=1"], low)
    assert paid[:, 0] == pytest.approx(free[:, 0], rel=1e-12)
    assert np.all(paid[:, 1] > free[:, 1])
    # threshold 0 scans every round but those with B seen, which are infected / 500 in expectation
    assert paid[0, 1] - free[0, 1] == pytest.approx(25 * (20 - free[0, 0] / 500), rel=1e-12)


def test_two_rounds_of_always_scanning_by_hand():
    # rounds=2 from midnight, always scanning (threshold 0: the IDS's estimate plays no part),
    # fn=0.2, fp=0.1, attack_a=attack_b=0.3, night prices (restoreA 10, restoreAB 25).
    # Round 1 (hour 1): A falls with 0.3; the scan catches it with 0.24 and flags a clean A
    # with 0.07: cost 25 + 10 x 0.31 = 28.1; A is left compromised with 0.06.
    # Round 2 (hour 2): from A compromised, B falls with 0.018 (infected 500 x 0.018 = 9, a
    # restoreAB 25 x 0.018 = 0.45, no scan); A is compromised after the attack with
    # 0.94 x 0.3 + 0.06 x 0.7 = 0.324, clean with 0.658; scans 25 x 0.982 = 24.55, restores
    # 10 x (0.324 x 0.8 + 0.658 x 0.1) = 3.25. Total cost 28.1 + 24.55 + 0.45 + 3.25 = 56.35.
    infected, cost = values(["rounds=2", "scan_fn=0.2", "scan_fp=0.1"], [[0] * 6])[0]
    assert infected == pytest.approx(9.0, rel=1e-12)
    assert cost == pytest.approx(56.35, rel=1e-12)


HAND_MODEL = """
dtmc
// Always scanning, written by hand from docs/web_ids.md: the IDS's estimate plays no part.
const int R;
const double fn = 0.2;
const double fp = 0.1;
module M
  a : [0..1] init 0;
  b : [0..1] init 0;
  hour : [0..23] init 0;
  k : [0..R] init 0;        // rounds begun
  p : [0..2] init 0;        // 0 attack, 1 scan (or restore both), 2 act on the scan's report
  alarm : [0..1] init 0;    // the scan reported "compromised"
  [attack] p=0 & k<R & a=0 -> 0.3 : (a'=1) & (hour'=mod(hour+1, 24)) & (k'=k+1) & (p'=1)
                            + 0.7 : (hour'=mod(hour+1, 24)) & (k'=k+1) & (p'=1);
  [attack] p=0 & k<R & a=1 -> 0.3 : (b'=1) & (hour'=mod(hour+1, 24)) & (k'=k+1) & (p'=1)
                            + 0.7 : (hour'=mod(hour+1, 24)) & (k'=k+1) & (p'=1);
  [restoreAB] p=1 & b=1 -> (a'=0) & (b'=0) & (p'=0);
  [scan] p=1 & b=0 & a=1 -> 1-fn : (alarm'=1) & (p'=2) + fn : (alarm'=0) & (p'=2);
  [scan] p=1 & b=0 & a=0 -> fp : (alarm'=1) & (p'=2) + 1-fp : (alarm'=0) & (p'=2);
  [restoreA] p=2 & alarm=1 -> (a'=0) & (alarm'=0) & (p'=0);
  [nop] p=2 & alarm=0 -> (p'=0);
  [done] p=0 & k=R -> true;
endmodule
rewards "cost"
  [scan] true : 25;
  [restoreA] hour<=8 : 10;
  [restoreA] hour>=9 & hour<=16 : 50;
  [restoreA] hour>=17 : 20;
  [restoreAB] hour<=8 : 25;
  [restoreAB] hour>=9 & hour<=16 : 100;
  [restoreAB] hour>=17 : 50;
endrewards
rewards "infected"
  [restoreAB] true : 500;
endrewards
label "over" = p=0 & k=R;
"""


@pytest.mark.parametrize("rounds", [2, 30])
def test_always_scanning_matches_a_hand_written_dtmc(rounds):
    # The hand-written chain counts rounds itself (a round with B seen has two steps there)
    # and sums the rewards until the last round is over; 30 rounds cover every price.
    infected, cost = storm_values(HAND_MODEL, ['R{"infected"}=? [F "over"]', 'R{"cost"}=? [F "over"]'], {"R": rounds})
    got = values([f"rounds={rounds}", "scan_fn=0.2", "scan_fp=0.1"], [[0] * 6])[0]
    assert got == pytest.approx([infected, cost], rel=1e-9, abs=1e-9)


@pytest.mark.parametrize("rates", [("0.3", "0.7"), ("1", "0"), ("0", "1"), ("1", "1")])
def test_every_rate_gives_a_dtmc_also_in_exact_arithmetic(rates):
    # Storm's rational engine refuses distributions that do not sum to exactly 1.
    text = CASE.build(CASE.options(["rounds=3", f"scan_fn={rates[0]}", f"scan_fp={rates[1]}"])).prism
    formulas = ['R{"cost"}=? [C<=12]', 'R{"infected"}=? [C<=12]']
    exact = storm_values(text, formulas, {"th": 0}, exact=True)
    assert exact == pytest.approx(storm_values(text, formulas, {"th": 0}), rel=1e-12, abs=1e-12)


@pytest.mark.parametrize("setting", ["scan_fn=2", "scan_fn=-0.1", "scan_fp=1.5", "scan_fp=nan"])
def test_rates_outside_zero_one_are_refused(setting):
    with pytest.raises(OptionError, match=setting.split("=")[0]):
        CASE.options([setting])
