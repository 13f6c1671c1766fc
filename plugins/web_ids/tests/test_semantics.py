"""The web_ids model means what docs/web_ids.md says, checked on values Storm computes.

``reference`` below is an independent computation written from the description (not from
the PRISM text, and without the generator's tables): the distribution of the servers' true
state at the start of each round, pushed through attack, IDS report, scan and the
controller's action, accumulating the expected costs. Storm on the generated model must
agree with it for random options and random policies, and with closed forms in the cases
where the answer is known by hand.
"""

from __future__ import annotations

import attrs
import numpy as np
import pytest

from parley_core import Direction, Objective, OptionError, testing
from parley_plugins.web_ids import CASE_STUDY as CASE

NEVER = 11  # a threshold above every estimate
NIGHT, BUSINESS, EVENING = range(9), range(9, 17), range(17, 24)
RESTORE_A = {"night": 10, "business": 50, "evening": 20}
RESTORE_AB = {"night": 25, "business": 100, "evening": 50}

# The published model's IDS, as its [check] commands list it (duplicate values included):
# (probability, estimate) per (rules fresh?, A compromised?).
PUBLISHED_IDS = {
    (1, 0): [(0.15, 0), (0.15, 1), (0.15, 1), (0.1, 1), (0.1, 2), (0.1, 3), (0.1, 4), (0.1, 6), (0.05, 9)],
    (1, 1): [(0.05, 0), (0.1, 1), (0.1, 3), (0.1, 4), (0.1, 5), (0.1, 6), (0.1, 8), (0.1, 8), (0.1, 9), (0.15, 9)],
    (0, 0): [(0.15, 0), (0.15, 1), (0.15, 2), (0.15, 3), (0.1, 4), (0.1, 5), (0.1, 6), (0.05, 7), (0.05, 8)],
    (0, 1): [(0.05, 0), (0.05, 1), (0.1, 2), (0.1, 4), (0.1, 5), (0.1, 6), (0.1, 7), (0.1, 8), (0.15, 9), (0.15, 9)],
}


def period(hour: int) -> str:
    return "night" if hour in NIGHT else ("business" if hour in BUSINESS else "evening")


def scan_reports(options, compromised: int) -> list[tuple[float, int]]:
    """(probability, estimate) of a scan's reports: 10 for "compromised", 0 for "clean"; a
    compromised A is missed with probability scan_fn, a clean one flagged with scan_fp."""
    if compromised:
        return [(1 - options.scan_fn, 10), (options.scan_fn, 0)]
    return [(1 - options.scan_fp, 0), (options.scan_fp, 10)]


def reference(options, policy) -> tuple[float, float]:
    """(expected infected cost, expected cost of restores and scans) over ``options.rounds``.

    ``policy`` maps (level, fresh) to a threshold, level 0 night, 1 business, 2 evening.
    """
    level_index = {"night": 0, "business": 1, "evening": 2}
    start = {(0, 0): 1.0}  # (A compromised, B compromised) at the start of a round
    infected = cost = 0.0
    hour = options.start_hour
    for _ in range(options.rounds):
        hour = (hour + 1) % 24  # the attack step advances the clock; the controller acts at the new hour
        when = period(hour)
        following: dict[tuple[int, int], float] = {}

        def land(state, p, following=following):
            following[state] = following.get(state, 0.0) + p

        for (a, b), p in start.items():
            if a == 0:
                attacked = [(1 - options.attack_a, (0, 0)), (options.attack_a, (1, 0))]
            elif b == 0:
                attacked = [(1 - options.attack_b, (1, 0)), (options.attack_b, (1, 1))]
            else:
                attacked = [(1.0, (1, 1))]
            for q, (a2, b2) in attacked:
                for fresh, r in ((1, 1 - options.stale), (0, options.stale)):
                    w = p * q * r
                    if w == 0:
                        continue
                    if b2:  # B goes offline: seen, paid for, both restored
                        infected += w * options.breach_cost
                        cost += w * RESTORE_AB[when]
                        land((0, 0), w)
                        continue
                    reports = [(options.ids_error * x, v) for x, v in PUBLISHED_IDS[(fresh, a2)]]
                    reports.append((1 - options.ids_error, 10 if a2 else 0))
                    threshold = policy[(level_index[when], fresh)]
                    for x, estimate in reports:
                        seen = [(1.0, estimate)]
                        if estimate >= threshold:
                            cost += w * x * options.scan_cost
                            seen = scan_reports(options, a2)
                        for y, report in seen:
                            if report >= options.restore_at:
                                cost += w * x * y * RESTORE_A[when]
                                land((0, 0), w * x * y)
                            else:
                                land((a2, b2), w * x * y)
        start = following
    return infected, cost


def family_of(options, *, extra: list[Objective] = ()):
    system = CASE.build(options)
    if extra:
        system = attrs.evolve(system, objectives=[*system.objectives, *extra])
    return testing.family(system)


def storm(family, policies) -> np.ndarray:
    return testing.values(family, np.asarray(policies, dtype=np.int64).reshape(-1, len(family.decisions)))


def uniform(family, threshold: int) -> list[int]:
    return [threshold] * len(family.decisions)


@pytest.mark.parametrize(
    "settings",
    [
        [],
        ["rounds=30", "start_hour=7", "attack_a=0.2", "attack_b=0.5", "stale=0.6"],
        ["rounds=20", "start_hour=15", "ids_error=0.4", "restore_at=5", "scan_cost=12"],
        ["rounds=13", "start_hour=22", "attack_a=0.7", "attack_b=0.1", "stale=0.0", "breach_cost=80"],
    ],
)
def test_storm_on_the_generated_model_matches_an_independent_computation(settings):
    options = CASE.options(settings)
    family = family_of(options)
    assert [d.valuation for d in family.decisions] == [(level, fresh) for level in range(3) for fresh in range(2)]
    rng = np.random.default_rng(len(settings))
    policies = np.vstack([uniform(family, 0), uniform(family, NEVER), rng.integers(0, NEVER + 1, size=(5, 6))])
    values = storm(family, policies)
    for row, (infected, cost) in zip(policies, values):
        policy = {d.valuation: int(v) for d, v in zip(family.decisions, row)}
        expected_infected, expected_cost = reference(options, policy)
        assert infected == pytest.approx(expected_infected, rel=1e-9, abs=1e-9)
        assert cost == pytest.approx(expected_cost, rel=1e-9, abs=1e-9)


def test_always_scanning_leaves_no_compromise_past_its_round():
    # A scan every round finds a compromised A in the round it falls, and the controller
    # restores it (the published model's `ahat := a` would leave it): A is never compromised
    # when a round starts, so B, which needs a compromised A, is never compromised at all.
    options = CASE.options()
    steps = 4 * options.rounds
    extra = [
        Objective(name="a_left", formula=f'P=? [F<={steps} ("roundStart" & "compromisedA")]', direction=Direction.MIN),
        Objective(name="b_ever", formula=f'P=? [F<={steps} "compromisedB"]', direction=Direction.MIN),
    ]
    family = family_of(options, extra=extra)
    always, never = storm(family, [uniform(family, 0), uniform(family, NEVER)])
    assert always[0] == 0.0 and always[2] == 0.0 and always[3] == 0.0
    # cost: one scan a round, and a restore of A in each round that A falls (probability 0.3)
    hours = [(options.start_hour + r) % 24 for r in range(1, options.rounds + 1)]
    assert always[1] == pytest.approx(sum(25 + 0.3 * RESTORE_A[period(h)] for h in hours), rel=1e-12)
    # never scanning, the IDS misses a compromised A (estimate below 3) with probability
    # 0.15 (fresh rules) or 0.2 (stale): A stays compromised and B falls
    assert never[2] > 0.5 and never[3] > 0.5 and never[0] > 300


def test_a_perfect_ids_makes_scanning_useless():
    options = CASE.options(["ids_error=0"])
    family = family_of(options)
    rng = np.random.default_rng(7)
    policies = np.vstack([uniform(family, NEVER), uniform(family, 0), rng.integers(0, NEVER + 1, size=(20, 6))])
    values = storm(family, policies)
    # The IDS reports 10 exactly when A is compromised: A is restored in the round it falls,
    # whatever the URC does, and never scanning is cheapest.
    assert np.all(values[:, 0] == 0.0)
    never = values[0, 1]
    hours = [(options.start_hour + r) % 24 for r in range(1, options.rounds + 1)]
    assert never == pytest.approx(sum(0.3 * RESTORE_A[period(h)] for h in hours), rel=1e-12)
    assert values[1, 1] == pytest.approx(never + 25 * options.rounds, rel=1e-12)
    assert np.all(values[:, 1] >= never - 1e-9)
    # a threshold in 1..10 scans only a compromised A: 25 for each of the expected 0.3 * rounds falls
    assert storm(family, [uniform(family, 5)])[0, 1] == pytest.approx(never + 25 * 0.3 * options.rounds, rel=1e-12)


def test_restores_cost_by_the_hour_of_the_day():
    # A falls every round (attack_a=1) and every round is scanned: round k costs the scan and
    # a restore of A at hour start+k; C<=4k sums the first k rounds.
    options = CASE.options(["attack_a=1", "rounds=24", "start_hour=0"])
    extra = [
        Objective(name=f"cost_{k}", formula=f'R{{"cost"}}=? [C<={4 * k}]', direction=Direction.MIN)
        for k in range(1, 25)
    ]
    family = family_of(options, extra=extra)
    totals = storm(family, [uniform(family, 0)])[0, 2:]
    per_round = np.diff(np.concatenate([[0.0], totals]))
    expected = [25 + (10 if h <= 8 else (50 if h <= 16 else 20)) for h in [*range(1, 24), 0]]
    assert per_round == pytest.approx(expected, abs=1e-9)
    assert min(per_round) == 35 and max(per_round) == 75  # night restores are the cheapest


@pytest.mark.parametrize(("start_hour", "expected"), [(1, 25.0), (9, 100.0), (20, 50.0), (22, 25.0)])
def test_a_compromised_database_costs_its_round_and_a_restore_of_both(start_hour, expected):
    # attack_a=attack_b=1, never scanning, and a controller that restores A only when sure
    # (restore_at=10; the IDS never reports 10): A falls in round 1, B in round 2; B is seen,
    # costs breach_cost, and both are restored at hour start+2.
    options = CASE.options(["attack_a=1", "attack_b=1", "restore_at=10", "rounds=2", f"start_hour={start_hour}"])
    family = family_of(options)
    infected, cost = storm(family, [uniform(family, NEVER)])[0]
    assert infected == 500.0
    assert cost == expected


def test_the_horizon_counts_rounds_of_four_steps():
    for rounds in (1, 5, 48):
        family = family_of(CASE.options(["attack_a=0", f"rounds={rounds}"]))
        infected, cost = storm(family, [uniform(family, 0)])[0]
        assert (infected, cost) == (0.0, 25.0 * rounds)  # one scan a round, nothing else


def test_never_scanning_gives_the_published_models_values():
    # Storm on the paper's cmu-with-umc.prism with every decision 0 (never `update`), both
    # properties of its props.pctl (C<=200: 50 rounds of 4 steps), gives these values;
    # never scanning, the published model's defects play no part, and this model agrees.
    family = family_of(CASE.options(["rounds=50"]))
    infected, cost = storm(family, [uniform(family, NEVER)])[0]
    assert infected == pytest.approx(388.97250663719825, rel=1e-12)
    assert cost == pytest.approx(735.2543116337416, rel=1e-12)


def test_stale_rules_make_the_ids_less_reliable():
    # Never scanning, an IDS that is always stale misses more compromises (0.2 against 0.15
    # a round) and raises more false alarms (0.55 against 0.35): both objectives worsen.
    values = {}
    for stale in (0.0, 1.0):
        family = family_of(CASE.options([f"stale={stale}"]))
        values[stale] = storm(family, [uniform(family, NEVER)])[0]
    assert values[1.0][0] > values[0.0][0] * 1.2
    assert values[1.0][1] > values[0.0][1] * 1.1
    # without attacks, the cost is false alarms only: 0.35 or 0.55 of the rounds restore A
    day = 9 * 10 + 8 * 50 + 7 * 20  # restore costs of one day's 24 decision hours
    for stale, false_alarm in ((0.0, 0.35), (1.0, 0.55)):
        family = family_of(CASE.options(["attack_a=0", f"stale={stale}", "rounds=48"]))
        assert storm(family, [uniform(family, NEVER)])[0, 1] == pytest.approx(2 * day * false_alarm, rel=1e-12)


def test_thresholds_by_time_and_ids_state_beat_every_fixed_threshold():
    # Scan everything (threshold 1) when a restore is dear (business hours), only high
    # estimates with stale rules in the evening, and never at night, where a restore (10)
    # is cheaper than a scan (25). No fixed threshold is as good in both objectives.
    family = family_of(CASE.options())
    mixed = {(0, 0): NEVER, (0, 1): NEVER, (1, 0): 1, (1, 1): 1, (2, 0): 2, (2, 1): 2}
    policy = [mixed[d.valuation] for d in family.decisions]
    values = storm(family, [policy, *(uniform(family, k) for k in range(NEVER + 1))])
    ours, baselines = values[0], values[1:]
    assert not np.any(np.all(baselines <= ours, axis=1)), "some fixed threshold is at least as good"
    assert reference(CASE.options(), mixed) == pytest.approx(tuple(ours), rel=1e-9)


def test_the_quotient_evaluator_handles_both_objectives_and_agrees_with_storm():
    family = family_of(CASE.options(["rounds=10"]))
    rng = np.random.default_rng(3)
    policies = rng.integers(0, NEVER + 1, size=(12, 6))
    assert testing.left_to_storm(family) == ()
    fast = testing.values(family, policies, evaluator="quotient")
    assert fast == pytest.approx(storm(family, policies), rel=1e-9, abs=1e-9)


@pytest.mark.parametrize(
    "setting",
    ["start_hour=24", "attack_a=1.5", "stale=-0.1", "ids_error=2", "rounds=0", "restore_at=11", "scan_cost=-1"],
)
def test_bad_options_are_refused(setting):
    with pytest.raises(OptionError):
        CASE.options([setting])
