"""The generated TAS model means what docs/tas.md says.

``reference`` below is an independent computation written from the description (not from
the generator): a distribution over (true level, load, estimate, counter) at the start of
each execution, pushed forward one execution at a time, with each execution's failure
probability, cost and response time in closed form. Storm on the generated PRISM model must
give the same per-execution means, for baselines and random policies. Further tests check
properties of the model's meaning with Storm: probing is useless when a provider never
fails, without drift the estimate is always right, and probing every k-th execution bounds
how long the UAC acts on a stale estimate.
"""

from __future__ import annotations

import itertools
from collections import defaultdict

import numpy as np
import pytest

from parley_core import testing
from parley_core.testing import storm_values
from parley_plugins.tas import CASE_STUDY as CASE

# The provider table (docs/tas.md), written out again so that a change of the generator's table shows.
PRIMARY = {"cost": 4.0, "time": 22.0}  # MAS1 (failure rate: an option, by load)
BACKUP = {"cost": 11.9, "time": 20.0}  # MAS5 (failure rate: by health level)
ALTERNATIVE = {"fail": 0.07, "cost": 14.0, "time": 27.0}  # MAS2
ALARM = {"fail": 0.04, "cost": 12.0, "time": 9.0}  # AS2
DRUG = {"fail": 0.01, "cost": 5.0, "time": 1.0}  # DS


def probe_reports(o, level: int, top: int) -> list[tuple[float, int]]:
    """(probability, reported level) of a probe of a backup at ``level``: the true level with
    probability 1 - probe_error, each of the ``top`` other levels with probe_error / top."""
    return [(1 - o.probe_error if j == level else o.probe_error / top, j) for j in range(top + 1)]


def reference(o, policy) -> tuple[float, float, float]:
    """Per-execution means of failure, cost and response time over o.rounds executions.

    ``o`` are TasOptions; ``policy`` maps (bhat, load) to the probing interval c.
    """
    levels = [float(x) for x in o.backup_levels.split(",")]
    top = len(levels) - 1

    def execution(b, load, bhat):
        f_primary = o.primary_failure_peak if load else o.primary_failure
        use_backup = levels[bhat] < ALTERNATIVE["fail"] or (
            levels[bhat] == ALTERNATIVE["fail"] and BACKUP["cost"] <= ALTERNATIVE["cost"]
        )
        if use_backup:
            f_over, c_over, t_over = levels[b], BACKUP["cost"], BACKUP["time"]
        else:
            f_over, c_over, t_over = ALTERNATIVE["fail"], ALTERNATIVE["cost"], ALTERNATIVE["time"]
        analyzed = (1 - f_primary) + f_primary * (1 - f_over)  # some provider delivered an analysis
        p_change = o.p_drug + o.p_dose
        vital = (
            f_primary * f_over + analyzed * (o.p_alarm * ALARM["fail"] + p_change * DRUG["fail"]),
            PRIMARY["cost"] + f_primary * c_over + analyzed * (o.p_alarm * ALARM["cost"] + p_change * DRUG["cost"]),
            PRIMARY["time"] + f_primary * t_over + analyzed * (o.p_alarm * ALARM["time"] + p_change * DRUG["time"]),
        )
        button = (ALARM["fail"], ALARM["cost"], ALARM["time"])
        return [o.p_vital * v + (1 - o.p_vital) * w for v, w in zip(vital, button)]

    def drift(b):
        return [(min(b + 1, top), o.degrade), (max(b - 1, 0), o.recover), (b, 1 - o.degrade - o.recover)]

    def switch(load):
        p = o.peak_end if load else o.peak_start
        return [(1 - load, p), (load, 1 - p)]

    totals = np.zeros(3)
    distribution = {(0, 0, 0, 1): 1.0}  # (b, load, bhat, step) before an execution
    for _ in range(o.rounds):
        following = defaultdict(float)
        for (b, load, bhat, step), p in distribution.items():
            for (b2, pb), (load2, pl) in itertools.product(drift(b), switch(load)):
                q = p * pb * pl
                if q == 0:
                    continue
                probe = step >= policy[(bhat, load2)]
                reports, step2 = (
                    (probe_reports(o, b2, top), 1) if probe else ([(1.0, bhat)], min(step + 1, o.max_interval))
                )
                for y, bhat2 in reports:
                    totals += q * y * np.array(execution(b2, load2, bhat2))
                    following[(b2, load2, bhat2, step2)] += q * y
                totals[1] += q * probe * o.probe_cost
        distribution = following
    return tuple(totals / o.rounds)


def evaluate(options, policies):
    family = testing.family(CASE.build(options))
    return family, testing.values(family, np.array(policies))


def uniform(options, c):
    levels = len(options.backup_levels.split(","))
    return {(bhat, load): c for bhat in range(levels) for load in (0, 1)}


@pytest.mark.parametrize(
    "settings",
    [
        ["rounds=8", "max_interval=4", "response_time=true"],
        [
            "rounds=12",
            "max_interval=5",
            "backup_levels=0.05,0.07,0.4,1",
            "degrade=0.15",
            "recover=0.05",
            "response_time=true",
        ],
        [
            "rounds=10",
            "max_interval=3",
            "p_vital=0.9",
            "p_alarm=0.2",
            "p_drug=0.3",
            "p_dose=0.1",
            "peak_start=0.5",
            "peak_end=0.5",
            "response_time=true",
        ],
        [
            "rounds=5",
            "max_interval=2",
            "p_vital=1",
            "peak_start=0",
            "backup_levels=0.05,1",
            "probe_cost=3",
            "response_time=true",
        ],
    ],
)
def test_storm_on_the_generated_model_matches_an_independent_computation(settings):
    options = CASE.options(settings)
    family = testing.family(CASE.build(options))
    rng = np.random.default_rng(len(settings))
    n = len(family.decisions)
    policies = [np.full(n, k) for k in (1, 2, options.max_interval + 1)]
    policies += list(rng.integers(1, options.max_interval + 2, size=(6, n)))
    values = testing.values(family, np.array(policies))
    assert [o.name for o in family.objectives] == ["failure", "cost", "response_time"]
    for row, got in zip(policies, values):
        policy = {d.valuation: int(v) for d, v in zip(family.decisions, row)}
        assert got == pytest.approx(reference(options, policy), rel=1e-9, abs=1e-12)


def test_default_baselines_trade_failures_for_probing_cost():
    # the shipped scenario: probing more often costs more and fails less, and never probing
    # is clearly worst (a degraded backup stays unnoticed)
    options = CASE.options(["rounds=20"])
    family, values = evaluate(options, [[k] * 6 for k in (1, 2, 4, 8, 11)])
    failure, cost = values[:, 0], values[:, 1]
    assert np.all(np.diff(failure) > 0)
    assert np.all(np.diff(cost) < 0)
    assert failure[-1] - failure[0] > 0.005
    for row, k in zip(values, (1, 2, 4, 8, 11)):
        assert tuple(row) == pytest.approx(reference(options, uniform(options, k))[:2], rel=1e-9)


@pytest.mark.parametrize(
    "never_fails",
    [["primary_failure=0", "primary_failure_peak=0"], ["backup_levels=0,0,0"]],
    ids=["primary", "backup"],
)
def test_a_provider_that_never_fails_makes_probing_useless(never_fails):
    # If the primary never fails, no execution fails over; if the backup never fails, the UAC
    # always trusts it and is right. Either way the failure probability is the same whatever
    # the policy, and probing only costs: every-k pays probe_cost on floor(rounds/k) executions.
    rounds, probe_cost = 12, 7.5
    options = CASE.options(["rounds=12", "max_interval=5", f"probe_cost={probe_cost}", *never_fails])
    intervals = [1, 2, 3, 5, 6]
    family, values = evaluate(options, [[k] * 6 for k in intervals])
    never = values[-1]
    for k, (failure, cost) in zip(intervals, values):
        assert failure == pytest.approx(never[0], rel=1e-12)
        assert cost - never[1] == pytest.approx(
            probe_cost * (rounds // k if k <= 5 else 0) / rounds, rel=1e-9, abs=1e-12
        )
    # and the failure probability is the closed form without any fail-over failure
    assert never[0] == pytest.approx(reference(options, uniform(options, 6))[0], rel=1e-12)


def test_without_drift_the_estimate_is_always_right():
    # The backup keeps its initial health, which the UAC knows: no state with bhat != b is
    # reachable, every policy fails equally often, and that rate has a closed form over the
    # load phase's distribution (a two-state chain, computed here directly).
    options = CASE.options(["rounds=15", "max_interval=4", "degrade=0", "recover=0"])
    family = testing.family(CASE.build(options))
    policies = {"every-1": [1] * 6, "mixed": [1, 3, 5, 2, 4, 5], "never": [5] * 6}
    failures = []
    for row in policies.values():
        constants = dict(zip(family.names, row))
        stale, failure = storm_values(family.prism, ['P=? [F "stale"]', 'R{"failures"}=? [C<=105]'], constants)
        assert stale == 0.0
        failures.append(failure)
    assert failures == pytest.approx([failures[0]] * 3, rel=1e-12)

    peak = 0.0  # probability of peak load at each execution (the load switches before it)
    expected = 0.0
    for _ in range(options.rounds):
        peak = peak * (1 - options.peak_end) + (1 - peak) * options.peak_start
        f_primary = peak * options.primary_failure_peak + (1 - peak) * options.primary_failure
        f_over = 0.05  # the healthy backup, trusted
        analyzed = 1 - f_primary * f_over
        vital = f_primary * f_over + analyzed * (options.p_alarm * 0.04 + (options.p_drug + options.p_dose) * 0.01)
        expected += options.p_vital * vital + (1 - options.p_vital) * 0.04
    assert failures[0] == pytest.approx(expected / options.rounds, rel=1e-12)


@pytest.mark.parametrize("k", [1, 2, 3])
def test_probing_every_k_executions_bounds_how_long_a_changed_backup_goes_unnoticed(k):
    # A probe runs in step 1 of every k-th execution and sets bhat to b; the level changes in
    # step 0. So the estimate can be stale for at most 7(k-1)+1 consecutive states (from
    # step 1 after a change to the next probe), and that long run does occur (almost surely,
    # in the unbounded run). Checked with exact arithmetic, as the thresholds are nested.
    options = CASE.options(["rounds=10", "max_interval=4", "degrade=0.3", "recover=0.3"])
    system = CASE.build(options)
    longest = 7 * (k - 1)

    def stale_for(n):  # some state from which "stale" may hold for the next n steps (G<=n, as !F<=n !)
        return f'P=? [F P<1 [F<={n} !"stale"]]'

    reach_longest, reach_longer = storm_values(
        system.prism, [stale_for(longest), stale_for(longest + 1)], {"c": k}, exact=True
    )
    assert reach_longest == 1.0
    assert reach_longer == 0.0


def test_probing_every_execution_means_a_fail_over_never_acts_on_a_stale_estimate():
    options = CASE.options(["rounds=10", "max_interval=4"])
    system = CASE.build(options)
    formula = 'P=? [F<=70 ("failover" & "stale")]'
    every_1, every_2, never = (storm_values(system.prism, [formula], {"c": c})[0] for c in (1, 2, 5))
    assert every_1 == 0.0
    assert 0.0 < every_2 < never
