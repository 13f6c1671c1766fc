"""web_ids: the PARLEY paper's RQ4 web application (after Moreno et al., SEAMS 2018).

A web server A and a database B; an attacker may compromise A, then B. An intrusion
detection system (IDS) gives a noisy estimate (0..9) of A being compromised, less reliable
when its rules are stale. The adaptation controller restores A when the estimate reaches 3,
and A and B when B is seen compromised; restoring costs more in business hours than at
night. The uncertainty-reduction service ``scanA`` reveals A's true state at a cost (or, with
``scan_fn``/``scan_fp``, reports it with false negatives and false positives). The URC
chooses, per cost level of the hour and state of the IDS's rules, the threshold of the
estimate at which to scan. Details and every difference from the published model:
docs/web_ids.md.
"""

from __future__ import annotations

from pathlib import Path

from attrs import frozen, validators

from parley_core import (
    Baseline,
    CaseStudy,
    DecisionKind,
    Direction,
    Objective,
    PolicyTable,
    Service,
    SystemModel,
    hookimpl,
    option,
    probability,
)
from parley_plugins.web_ids.generator import KNOWN, MAX_THRESHOLD, STEPS_PER_ROUND, prism_model

_cost = [validators.ge(0.0)]


@frozen(kw_only=True)
class WebIdsOptions:
    rounds: int = option(
        50, f"rounds (hours) both objectives look at; a round is {STEPS_PER_ROUND} DTMC steps", validators.ge(1)
    )
    start_hour: int = option(0, "hour of the day at the start (0..23)", validators.ge(0), validators.le(23))
    attack_a: float = option(0.3, "probability per round that a clean A is compromised", probability, converter=float)
    attack_b: float = option(
        0.3, "probability per round that B is compromised through a compromised A", probability, converter=float
    )
    stale: float = option(0.3, "probability per round that the IDS's rules are stale", probability, converter=float)
    ids_error: float = option(
        1.0, "weight of the published IDS's errors: 1 the published IDS, 0 a perfect one", probability, converter=float
    )
    restore_at: int = option(
        3,
        f"the controller restores A when the estimate reaches this (0..{KNOWN})",
        validators.ge(0),
        validators.le(KNOWN),
    )
    scan_cost: float = option(25.0, "cost of one scan of A", _cost, converter=float)
    breach_cost: float = option(500.0, "cost of a round with B compromised", _cost, converter=float)
    scan_fn: float = option(
        0.0,
        "false-negative rate of the scan: probability that it reports a compromised A clean",
        probability,
        converter=float,
    )
    scan_fp: float = option(
        0.0,
        "false-positive rate of the scan: probability that it reports a clean A compromised",
        probability,
        converter=float,
    )


def build(options: WebIdsOptions) -> SystemModel:
    text = prism_model(
        start_hour=options.start_hour,
        attack_a=options.attack_a,
        attack_b=options.attack_b,
        stale=options.stale,
        ids_error=options.ids_error,
        restore_at=options.restore_at,
        scan_cost=options.scan_cost,
        breach_cost=options.breach_cost,
        scan_fn=options.scan_fn,
        scan_fp=options.scan_fp,
    )
    steps = STEPS_PER_ROUND * options.rounds
    return SystemModel(
        name="web_ids",
        description=f"web server and database under attack, {options.rounds} rounds from hour {options.start_hour}",
        prism=text,
        services=[
            Service(
                name="scanA",
                constant="th",
                kind=DecisionKind.THRESHOLD,
                low=0,
                high=MAX_THRESHOLD,
                description=f"scan A when the IDS's estimate reaches th (0: always, {MAX_THRESHOLD}: never)",
            )
        ],
        observation=("level", "fresh"),
        objectives=[
            Objective(
                name="infected",
                formula=f'R{{"infected"}}=? [C<={steps}]',
                direction=Direction.MIN,
                description=f"expected cost of rounds with the database compromised, within {options.rounds} rounds",
            ),
            Objective(
                name="cost",
                formula=f'R{{"cost"}}=? [C<={steps}]',
                direction=Direction.MIN,
                description=f"expected cost of restores and scans within {options.rounds} rounds",
            ),
        ],
        baselines=[Baseline(name=_baseline_name(k), values={"th": k}) for k in range(MAX_THRESHOLD + 1)],
        context=options,
    )


def _baseline_name(threshold: int) -> str:
    if threshold == 0:
        return "scan-always"
    if threshold == MAX_THRESHOLD:
        return "scan-never"
    return f"threshold-{threshold}"


def plot_policy(system: SystemModel, table: PolicyTable, path: Path) -> None:
    from parley_plugins.web_ids.plot import draw_policy

    draw_policy(table.values_of("th"), path)


CASE_STUDY = CaseStudy(
    name="web_ids",
    description="Web server and database under attack: when to scan A, by IDS estimate threshold (the paper's RQ4)",
    options_type=WebIdsOptions,
    build=build,
    plot_policy=plot_policy,
    quick={"rounds": "6"},
)


@hookimpl
def parley_case_studies() -> list[CaseStudy]:
    return [CASE_STUDY]
