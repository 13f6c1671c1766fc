"""The web_ids DTMC, with the scan threshold as the constant ``th``.

A round is one hour and four DTMC steps, always in this order (so ``C<=4*rounds`` covers
exactly ``rounds`` rounds):

1. ``attack``: the attacker compromises a clean web server A with probability ``attack_a``,
   or, if A is already compromised, the database B with probability ``attack_b``; the clock
   advances one hour (and the cost level with it); the IDS's rules are stale this round with
   probability ``stale``.
2. ``ids``: the IDS reports an estimate ``ahat`` in 0..9 of A being compromised, drawn from a
   distribution that depends on A's true state and on whether the rules are fresh. A
   compromised B is seen (it goes offline, as in the published model): ``bhat=1``,
   ``ahat=10``; that round costs ``breach_cost`` (reward "infected").
3. ``scan`` (``ahat >= th`` and B not known to be compromised) or ``noscan``: the scan
   reports A's state (``ahat := 10`` if compromised, ``0`` if clean) at ``scan_cost``. A
   perfect scan (the default) reports the true state; an imperfect one misses a compromised
   A with probability ``scan_fn`` (reports 0) and flags a clean A with probability
   ``scan_fp`` (reports 10), and the controller trusts the report either way.
4. The adaptation controller (UAC) acts on its estimates: ``restoreAB`` if ``bhat=1``,
   ``restoreA`` if ``ahat >= restore_at``, ``NOP`` otherwise. Restoring costs by the
   time-of-day level (night, business hours, evening). The estimates are cleared for the
   next round (the IDS reports afresh every round).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

from parley_core.prism.writer import (
    Command,
    Constant,
    Label,
    Module,
    Program,
    RewardItem,
    Rewards,
    Update,
    Variable,
)

STEPS_PER_ROUND = 4
KNOWN = 10
"""The estimate that means "A is known to be compromised" (after a scan, or with B seen)."""
MAX_THRESHOLD = KNOWN + 1
"""A threshold above every estimate: never scan."""

LEVELS = ("night", "business", "evening")
"""Cost levels of the time of day: 0 night (hours 0-8), 1 business (9-16), 2 evening (17-23)."""

RESTORE_A = (10.0, 50.0, 20.0)
"""Cost of restoring A per level, from the published model's rewards."""
RESTORE_AB = (25.0, 100.0, 50.0)
"""Cost of restoring A and B per level, from the published model's rewards."""

# The published model's IDS (cmu-no-umc.prism, module Knowledge, [check]), duplicates merged:
# P(ahat = k | A's state, rules fresh or stale).
IDS_REPORTS: Mapping[tuple[str, bool], Mapping[int, float]] = {
    ("fresh", False): {0: 0.15, 1: 0.40, 2: 0.10, 3: 0.10, 4: 0.10, 6: 0.10, 9: 0.05},
    ("fresh", True): {0: 0.05, 1: 0.10, 3: 0.10, 4: 0.10, 5: 0.10, 6: 0.10, 8: 0.20, 9: 0.25},
    ("stale", False): {0: 0.15, 1: 0.15, 2: 0.15, 3: 0.15, 4: 0.10, 5: 0.10, 6: 0.10, 7: 0.05, 8: 0.05},
    ("stale", True): {0: 0.05, 1: 0.05, 2: 0.10, 4: 0.10, 5: 0.10, 6: 0.10, 7: 0.10, 8: 0.10, 9: 0.30},
}


def level_of(hour: int) -> int:
    """The cost level of an hour of the day (the published rewards' boundaries)."""
    if not 0 <= hour <= 23:
        raise ValueError(f"hour {hour} is not in 0..23")
    return 0 if hour < 9 else (1 if hour < 17 else 2)


def ids_distribution(rules: str, compromised: bool, error: float) -> dict[int, float]:
    """The IDS's report distribution, its errors scaled by ``error``.

    ``error=1`` is the published IDS; ``error=0`` a perfect one (``10`` when A is
    compromised, ``0`` when clean); values between mix the two.
    """
    exact = KNOWN if compromised else 0
    result: dict[int, float] = {}
    for value, p in IDS_REPORTS[(rules, compromised)].items():
        result[value] = result.get(value, 0.0) + error * p
    result[exact] = result.get(exact, 0.0) + (1.0 - error)
    return {k: v for k, v in sorted(result.items()) if v > 0.0}


def prism_model(
    *,
    start_hour: int,
    attack_a: float,
    attack_b: float,
    stale: float,
    ids_error: float,
    restore_at: int,
    scan_cost: float,
    breach_cost: float,
    scan_fn: float = 0.0,
    scan_fp: float = 0.0,
) -> str:
    """The DTMC text; the scan threshold is the undefined constant ``th``.

    ``scan_fn`` and ``scan_fp`` are the scan's false-negative and false-positive rates; at 0
    (both) the text is exactly that of a perfect scan, with no trace of them.
    """
    servers = Module(
        name="Servers",
        variables=[
            Variable(name="a", low=0, high=1, init=0, comment="web server A compromised"),
            Variable(name="b", low=0, high=1, init=0, comment="database B compromised"),
        ],
        commands=[
            Command(action="attack", guard="a=0", updates=_choice("attackA", {"a": "1"})),
            Command(action="attack", guard="a=1 & b=0", updates=_choice("attackB", {"b": "1"})),
            Command(action="attack", guard="a=1 & b=1"),
            Command(action="restoreA", updates=[Update(assignments={"a": "0"})]),
            Command(action="restoreAB", updates=[Update(assignments={"a": "0", "b": "0"})]),
        ],
    )
    clock = Module(
        name="Clock",
        variables=[
            Variable(name="hour", low=0, high=23, init=start_hour, comment="hour of the day"),
            Variable(
                name="level",
                low=0,
                high=len(LEVELS) - 1,
                init=level_of(start_hour),
                comment="cost level of the hour: " + ", ".join(f"{i} {n}" for i, n in enumerate(LEVELS)),
            ),
        ],
        commands=[
            Command(action="attack", guard=_hour_range(low, high), updates=[Update(assignments=assignments)])
            for low, high, assignments in _clock_steps()
        ],
    )
    ids = Module(
        name="IDS",
        variables=[Variable(name="fresh", low=0, high=1, init=1, comment="1: the IDS's rules are up to date")],
        commands=[
            Command(
                action="attack",
                updates=[
                    Update(probability="stale", assignments={"fresh": "0"}),
                    Update(probability="1-stale", assignments={"fresh": "1"}),
                ],
            )
        ],
    )
    reports = []
    for fresh, rules in ((1, "fresh"), (0, "stale")):
        for a in (0, 1):
            distribution = ids_distribution(rules, bool(a), ids_error)
            reports.append(
                Command(
                    action="ids",
                    guard=f"b=0 & a={a} & fresh={fresh}",
                    updates=[
                        Update(probability=p if len(distribution) > 1 else None, assignments={"ahat": str(value)})
                        for value, p in distribution.items()
                    ],
                )
            )
    knowledge = Module(
        name="Knowledge",
        variables=[
            Variable(name="ahat", low=0, high=KNOWN, init=0, comment=f"estimate that A is compromised; {KNOWN}: known"),
            Variable(name="bhat", low=0, high=1, init=0, comment="B known to be compromised"),
        ],
        commands=[
            *reports,
            Command(action="ids", guard="b=1", updates=[Update(assignments={"ahat": str(KNOWN), "bhat": "1"})]),
            *scan_commands(scan_fn, scan_fp),
            Command(action="noscan"),
            Command(action="NOP", updates=[Update(assignments={"ahat": "0"})]),
            Command(action="restoreA", updates=[Update(assignments={"ahat": "0"})]),
            Command(action="restoreAB", updates=[Update(assignments={"ahat": "0", "bhat": "0"})]),
        ],
    )
    controller = Module(
        name="Controller",
        commands=[
            Command(action="NOP", guard="bhat=0 & ahat<restoreAt"),
            Command(action="restoreA", guard="bhat=0 & ahat>=restoreAt"),
            Command(action="restoreAB", guard="bhat=1"),
        ],
    )
    round_ = Module(
        name="Round",
        variables=[Variable(name="t", low=0, high=3, init=0, comment="0 attack, 1 ids, 2 scan or not, 3 act")],
        commands=[
            Command(action="attack", guard="t=0", updates=[Update(assignments={"t": "1"})]),
            Command(action="ids", guard="t=1", updates=[Update(assignments={"t": "2"})]),
            Command(action="scan", guard="t=2 & bhat=0 & ahat>=th", updates=[Update(assignments={"t": "3"})]),
            Command(action="noscan", guard="t=2 & (bhat=1 | ahat<th)", updates=[Update(assignments={"t": "3"})]),
            *(
                Command(action=action, guard="t=3", updates=[Update(assignments={"t": "0"})])
                for action in ("NOP", "restoreA", "restoreAB")
            ),
        ],
    )
    cost_items = [RewardItem(action="scan", value="scanCost")]
    for action, costs in (("restoreA", RESTORE_A), ("restoreAB", RESTORE_AB)):
        cost_items += [RewardItem(action=action, guard=f"level={i}", value=cost) for i, cost in enumerate(costs)]
    program = Program(
        header=(
            "web_ids: a self-protecting web application (after Moreno et al., SEAMS 2018, and the\n"
            "PARLEY paper's published model cmu-with-umc.prism). One round (an hour) is four steps:\n"
            "attack, ids, scan or noscan, then the controller's NOP, restoreA or restoreAB.\n"
            f"The URC scans A when the IDS's estimate reaches th (0: always, {MAX_THRESHOLD}: never)."
        ),
        constants=[
            Constant(
                name="attackA", type="double", value=float(attack_a), comment="P(a clean A is compromised) per round"
            ),
            Constant(
                name="attackB",
                type="double",
                value=float(attack_b),
                comment="P(B is compromised from a compromised A) per round",
            ),
            Constant(name="stale", type="double", value=float(stale), comment="P(the IDS's rules are stale) per round"),
            Constant(name="restoreAt", value=restore_at, comment="the controller restores A when ahat >= restoreAt"),
            Constant(name="scanCost", type="double", value=float(scan_cost)),
            Constant(
                name="breachCost", type="double", value=float(breach_cost), comment="per round with B compromised"
            ),
            *scan_error_constants(scan_fn, scan_fp),
            Constant(name="th", comment=f"scan A when ahat >= th, 0..{MAX_THRESHOLD}"),
        ],
        modules=[servers, clock, ids, knowledge, controller, round_],
        rewards=[
            Rewards(name="infected", items=[RewardItem(action="ids", guard="b=1", value="breachCost")]),
            Rewards(name="cost", items=cost_items),
        ],
        labels=[
            Label(name="compromisedA", expression="a=1"),
            Label(name="compromisedB", expression="b=1"),
            Label(name="roundStart", expression="t=0"),
        ],
    )
    return program.render()


def scan_commands(scan_fn: float, scan_fp: float) -> list[Command]:
    """The Knowledge module's ``scan`` commands: what a scan writes into ``ahat``.

    A perfect scan is one command, ``ahat := a*10``. An imperfect one is a command per true
    state of A, each a distribution over the two reports: a compromised A is reported clean
    (``ahat := 0``) with probability ``scanFN``, a clean A compromised (``ahat := 10``) with
    probability ``scanFP``. Only reports of positive probability are written, so every rate
    in [0, 1] gives a DTMC whose distributions sum to 1 (also in exact arithmetic).
    """
    if scan_fn == 0.0 and scan_fp == 0.0:
        return [Command(action="scan", updates=[Update(assignments={"ahat": f"a*{KNOWN}"})])]
    return [
        Command(action="scan", guard="a=1", updates=_report(KNOWN, 0, "scanFN", scan_fn)),
        Command(action="scan", guard="a=0", updates=_report(0, KNOWN, "scanFP", scan_fp)),
    ]


def _report(right: int, wrong: int, name: str, rate: float) -> list[Update]:
    """A scan's report: ``right`` with probability 1-``name``, ``wrong`` with ``name`` (its value ``rate``)."""
    if rate == 0.0:
        return [Update(assignments={"ahat": str(right)})]
    if rate == 1.0:
        return [Update(assignments={"ahat": str(wrong)})]
    return [
        Update(probability=f"1-{name}", assignments={"ahat": str(right)}),
        Update(probability=name, assignments={"ahat": str(wrong)}),
    ]


def scan_error_constants(scan_fn: float, scan_fp: float) -> list[Constant]:
    """The constants of the scan's error rates, each declared only when it is positive."""
    rates = (
        ("scanFN", scan_fn, "P(a scan reports a compromised A clean)"),
        ("scanFP", scan_fp, "P(a scan reports a clean A compromised)"),
    )
    return [
        Constant(name=name, type="double", value=float(rate), comment=comment)
        for name, rate, comment in rates
        if rate > 0.0
    ]


def _choice(probability: str, assignments: Mapping[str, str]) -> Sequence[Update]:
    return [Update(probability=probability, assignments=assignments), Update(probability=f"1-{probability}")]


def _clock_steps() -> list[tuple[int, int, dict[str, str]]]:
    """(first hour, last hour, assignments) of the clock's steps, hours grouped by the next level."""
    steps: list[tuple[int, int, dict[str, str]]] = []
    for hour in range(24):
        following = (hour + 1) % 24
        assignments = {"hour": "hour+1" if following else "0", "level": str(level_of(following))}
        if steps and steps[-1][2] == assignments and steps[-1][1] == hour - 1:
            steps[-1] = (steps[-1][0], hour, assignments)
        else:
            steps.append((hour, hour, assignments))
    return steps


def _hour_range(low: int, high: int) -> str:
    if low == high:
        return f"hour={low}"
    return f"hour>={low} & hour<={high}"
