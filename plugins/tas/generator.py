"""The TAS DTMC, with the probing interval of the backup medical analysis provider as ``c``.

One *round* is one execution of the TAS workflow, in exactly seven DTMC steps (so that
``C<=7*rounds`` covers the first ``rounds`` executions, whatever path each one takes):

====  ==================  =====================================================================
t     action(s)           what happens
====  ==================  =====================================================================
0     ``env``             the backup's health level ``b`` drifts one level worse (``degrade``)
                          or better (``recover``); the load phase switches (normal <-> peak)
1     ``probe``           the uncertainty-reduction service: once ``step`` reaches ``c``, a test
      ``noprobe``         invocation of the backup reveals its level (``bhat := b``), at a cost;
                          an imperfect probe (``probe_error``) misreports it, see
                          :func:`probe_updates`
2     ``request``         the patient's device sends vital parameters (analysis needed) or the
                          panic button is pressed (alarm needed)
3     ``analyse``         the primary medical analysis provider; if it fails the workflow fails
      ``no_analysis``     over; a successful analysis asks for a drug change, a dose change,
                          an alarm, or nothing
4     ``backup``          fail-over: the UAC invokes the backup if its *estimated* failure rate
      ``alternative``     is no worse than the alternative's, else the (stable, dearer)
      ``no_failover``     alternative provider; if the fail-over provider fails too, the
                          execution fails
5     ``drug``            the drug service (drug or dose change) or the alarm service
      ``alarm``
      ``no_action``
6     ``end``             the execution is over (failed or not); the next round starts
====  ==================  =====================================================================

Modules: ``Environment`` (``b``, ``load``), ``Knowledge`` (the UAC's estimate ``bhat`` and
the counter ``step``), ``Workflow`` (``req``) and ``Turn`` (``t``), which takes part in every
action so that each step happens at its turn only.

Reward structures (all divided by ``rounds``, so ``C<=7*rounds`` gives per-execution means):
``failures`` (1 per failed execution), ``cost`` (provider invocations and probes) and
``time`` (response times of the invocations on the execution's path; probes run off it).
"""

from __future__ import annotations

from attrs import field, frozen

from parley_core.prism.writer import (
    Command,
    Constant,
    Formula,
    Label,
    Module,
    Program,
    RewardItem,
    Rewards,
    Update,
    Variable,
    disjunction,
)

STEPS_PER_ROUND = 7

# req values
NONE, ANALYSE, FAILOVER, DRUG, ALARM, DONE, FAILED = range(7)
REQUESTS = ("none", "analyse", "failover", "drug", "alarm", "done", "failed")


@frozen(kw_only=True)
class Provider:
    """A concrete service from the TAS provider table."""

    name: str
    failure_rate: float
    response_time: float  # ms
    cost: float


# The TAS provider table (see docs/tas.md for the sources).
PROVIDERS = {
    p.name: p
    for p in (
        Provider(name="AS1", failure_rate=0.11, response_time=11, cost=4.0),
        Provider(name="AS2", failure_rate=0.04, response_time=9, cost=12.0),
        Provider(name="AS3", failure_rate=0.18, response_time=3, cost=2.0),
        Provider(name="MAS1", failure_rate=0.12, response_time=22, cost=4.0),
        Provider(name="MAS2", failure_rate=0.07, response_time=27, cost=14.0),
        Provider(name="MAS3", failure_rate=0.18, response_time=31, cost=2.15),
        Provider(name="MAS4", failure_rate=0.25, response_time=29, cost=7.3),
        Provider(name="MAS5", failure_rate=0.05, response_time=20, cost=11.9),
        Provider(name="DS", failure_rate=0.01, response_time=1, cost=5.0),
    )
}


@frozen(kw_only=True)
class Roles:
    """Which provider plays which part in the workflow."""

    primary: Provider = PROVIDERS["MAS1"]  # the medical analysis provider used first
    backup: Provider = PROVIDERS["MAS5"]  # the fail-over provider whose health drifts
    alternative: Provider = PROVIDERS["MAS2"]  # the stable, dearer fail-over provider
    alarm: Provider = PROVIDERS["AS2"]
    drug: Provider = PROVIDERS["DS"]


@frozen(kw_only=True)
class Scenario:
    """Everything the model depends on, already checked (see ``TasOptions`` for meanings)."""

    rounds: int
    max_interval: int
    backup_levels: tuple[float, ...] = field(converter=tuple)
    degrade: float
    recover: float
    peak_start: float
    peak_end: float
    primary_failure: float
    primary_failure_peak: float
    p_vital: float
    p_alarm: float
    p_drug: float
    p_dose: float
    probe_cost: float
    probe_error: float = 0.0
    roles: Roles = Roles()

    @property
    def horizon(self) -> int:
        """DTMC steps of ``rounds`` workflow executions."""
        return STEPS_PER_ROUND * self.rounds

    @property
    def p_ok(self) -> float:
        """Probability that an analysis finds the patient ok (0 within rounding when the others sum to 1)."""
        rest = 1.0 - self.p_alarm - self.p_drug - self.p_dose
        return rest if rest > 1e-12 else 0.0

    def uses_backup(self, level: int) -> bool:
        """The UAC's fail-over rule: the backup if its estimated failure rate is no worse than the alternative's."""
        backup, alternative = self.backup_levels[level], self.roles.alternative.failure_rate
        if backup != alternative:
            return backup < alternative
        return self.roles.backup.cost <= self.roles.alternative.cost


def prism_model(s: Scenario) -> str:
    """The DTMC text of scenario ``s``; the probing interval is the undefined constant ``c``."""
    roles = s.roles
    top = len(s.backup_levels) - 1
    results = _results(s)

    environment = Module(
        name="Environment",
        variables=[
            Variable(name="b", low=0, high="L", init=0, comment="the backup's true health level (0 = as in the table)"),
            Variable(name="load", low=0, high=1, init=0, comment="workload phase: 0 normal, 1 peak"),
        ],
        commands=[
            Command(
                action="env",
                updates=[
                    Update(probability=f"{pb}*{pl}", assignments={"b": b, "load": load})
                    for pb, b in (("pDegrade", "min(b+1, L)"), ("pRecover", "max(b-1, 0)"), ("pStay", "b"))
                    for pl, load in (("pSwitch", "1-load"), ("(1-pSwitch)", "load"))
                ],
            )
        ],
    )
    knowledge = Module(
        name="Knowledge",
        variables=[
            Variable(name="bhat", low=0, high="L", init=0, comment="the UAC's estimate of b (known at the start)"),
            Variable(name="step", low=1, high="maxStep", init=1, comment="executions since the last probe, capped"),
        ],
        commands=[
            Command(action="probe", guard="step>=c", updates=probe_updates(s.probe_error, top)),
            Command(action="noprobe", guard="step<c", updates=[Update(assignments={"step": "min(step+1, maxStep)"})]),
        ],
    )
    workflow = Module(
        name="Workflow",
        variables=[
            Variable(
                name="req",
                low=0,
                high=len(REQUESTS) - 1,
                init=NONE,
                comment=" ".join(f"{i} {r}" for i, r in enumerate(REQUESTS)),
            )
        ],
        commands=[
            Command(
                action="request",
                updates=[
                    Update(probability="pVital", assignments={"req": ANALYSE}),
                    Update(probability="1-pVital", assignments={"req": ALARM}),
                ],
            ),
            Command(
                action="analyse",
                guard=f"req={ANALYSE}",
                updates=[
                    *_on_success("(1-fPrimary)", results),
                    Update(probability="fPrimary", assignments={"req": FAILOVER}),
                ],
            ),
            Command(action="no_analysis", guard=f"req!={ANALYSE}"),
            Command(
                action="backup",
                guard=f"req={FAILOVER} & useBackup",
                updates=[
                    *_on_success("(1-fBackup)", results),
                    Update(probability="fBackup", assignments={"req": FAILED}),
                ],
            ),
            Command(
                action="alternative",
                guard=f"req={FAILOVER} & !useBackup",
                updates=[
                    *_on_success("(1-fAlternative)", results),
                    Update(probability="fAlternative", assignments={"req": FAILED}),
                ],
            ),
            Command(action="no_failover", guard=f"req!={FAILOVER}"),
            *(
                Command(
                    action=action,
                    guard=f"req={value}",
                    updates=[
                        Update(probability=f"1-{rate}", assignments={"req": DONE}),
                        Update(probability=rate, assignments={"req": FAILED}),
                    ],
                )
                for action, value, rate in (("drug", DRUG, "fDrug"), ("alarm", ALARM, "fAlarm"))
            ),
            Command(action="no_action", guard=f"req={DONE} | req={FAILED}"),
            Command(action="end", updates=[Update(assignments={"req": NONE})]),
        ],
    )
    turns = [
        (0, ["env"]),
        (1, ["probe", "noprobe"]),
        (2, ["request"]),
        (3, ["analyse", "no_analysis"]),
        (4, ["backup", "alternative", "no_failover"]),
        (5, ["drug", "alarm", "no_action"]),
        (6, ["end"]),
    ]
    turn = Module(
        name="Turn",
        variables=[
            Variable(name="t", low=0, high=STEPS_PER_ROUND - 1, init=0, comment="step of the current execution")
        ],
        commands=[
            Command(action=action, guard=f"t={t}", updates=[Update(assignments={"t": str((t + 1) % STEPS_PER_ROUND)})])
            for t, actions in turns
            for action in actions
        ],
    )

    good = [level for level in range(len(s.backup_levels)) if s.uses_backup(level)]
    constants = [
        Constant(name="rounds", value=s.rounds, comment="workflow executions the objectives look at"),
        Constant(name="maxStep", value=s.max_interval, comment="largest probing interval; c = maxStep+1 never probes"),
        Constant(name="c", comment=f"probing interval in executions, 1..{s.max_interval + 1}"),
        Constant(name="L", value=top, comment="worst health level of the backup"),
        *(
            Constant(name=f"fLevel{i}", type="double", value=rate, comment=f"backup failure rate at level {i}")
            for i, rate in enumerate(s.backup_levels)
        ),
        Constant(name="pDegrade", type="double", value=s.degrade, comment="per execution: backup one level worse"),
        Constant(name="pRecover", type="double", value=s.recover, comment="per execution: backup one level better"),
        Constant(name="pStay", type="double", value="1-pDegrade-pRecover"),
        Constant(name="pPeakStart", type="double", value=s.peak_start, comment="per execution: normal -> peak load"),
        Constant(name="pPeakEnd", type="double", value=s.peak_end, comment="per execution: peak -> normal load"),
        Constant(
            name="fPrimaryNormal",
            type="double",
            value=s.primary_failure,
            comment=f"{roles.primary.name} at normal load",
        ),
        Constant(
            name="fPrimaryPeak",
            type="double",
            value=s.primary_failure_peak,
            comment=f"{roles.primary.name} at peak load",
        ),
        Constant(
            name="fAlternative", type="double", value=roles.alternative.failure_rate, comment=roles.alternative.name
        ),
        Constant(name="fAlarm", type="double", value=roles.alarm.failure_rate, comment=roles.alarm.name),
        Constant(name="fDrug", type="double", value=roles.drug.failure_rate, comment=roles.drug.name),
        Constant(name="pVital", type="double", value=s.p_vital, comment="vital parameters (else: panic button)"),
        Constant(name="pResultAlarm", type="double", value=s.p_alarm, comment="analysis result: send an alarm"),
        Constant(name="pResultDrug", type="double", value=s.p_drug, comment="analysis result: change the drug"),
        Constant(
            name="pResultDose", type="double", value=s.p_dose, comment="analysis result: change the dose (the rest: ok)"
        ),
        *(
            Constant(name=f"cost{part}", type="double", value=value)
            for part, value in (
                ("Primary", roles.primary.cost),
                ("Backup", roles.backup.cost),
                ("Alternative", roles.alternative.cost),
                ("Alarm", roles.alarm.cost),
                ("Drug", roles.drug.cost),
                ("Probe", s.probe_cost),
            )
        ),
        *(
            Constant(name=f"time{part}", type="double", value=value)
            for part, value in (
                ("Primary", roles.primary.response_time),
                ("Backup", roles.backup.response_time),
                ("Alternative", roles.alternative.response_time),
                ("Alarm", roles.alarm.response_time),
                ("Drug", roles.drug.response_time),
            )
        ),
        *_probe_error_constants(s.probe_error),
    ]
    formulas = [
        Formula(name="fBackup", expression=_by_level("b", top)),
        Formula(name="fPrimary", expression="load=1 ? fPrimaryPeak : fPrimaryNormal"),
        Formula(name="pSwitch", expression="load=1 ? pPeakEnd : pPeakStart"),
        Formula(name="useBackup", expression=disjunction(f"bhat={level}" for level in good)),
    ]
    per_execution = "/rounds"
    rewards = [
        Rewards(name="failures", items=[RewardItem(action="end", guard=f"req={FAILED}", value=f"1{per_execution}")]),
        Rewards(
            name="cost",
            items=[
                RewardItem(action=action, value=f"cost{part}{per_execution}")
                for action, part in (
                    ("probe", "Probe"),
                    ("analyse", "Primary"),
                    ("backup", "Backup"),
                    ("alternative", "Alternative"),
                    ("alarm", "Alarm"),
                    ("drug", "Drug"),
                )
            ],
        ),
        Rewards(
            name="time",
            items=[
                RewardItem(action=action, value=f"time{part}{per_execution}")
                for action, part in (
                    ("analyse", "Primary"),
                    ("backup", "Backup"),
                    ("alternative", "Alternative"),
                    ("alarm", "Alarm"),
                    ("drug", "Drug"),
                )
            ],
        ),
    ]
    labels = [
        Label(name="failed", expression=f"req={FAILED}"),
        Label(name="failover", expression=f"t=4 & req={FAILOVER}"),
        Label(name="stale", expression="bhat!=b"),
        Label(name="peak", expression="load=1"),
    ]
    header = (
        "TAS, the Tele Assistance System (Weyns & Calinescu, SEAMS 2015), one workflow execution per\n"
        f"{STEPS_PER_ROUND} steps. The medical analysis provider {roles.primary.name} fails over to the backup "
        f"{roles.backup.name}, whose health drifts,\n"
        f"or, when the UAC believes the backup degraded, to {roles.alternative.name}. A probe (a test invocation "
        "of the backup)\nreveals the backup's level; it runs once the counter `step` reaches c."
    )
    return Program(
        header=header,
        constants=constants,
        formulas=formulas,
        modules=[environment, knowledge, workflow, turn],
        rewards=rewards,
        labels=labels,
    ).render()


def _probe_error_constants(error: float) -> list[Constant]:
    """The probe's misreport probability as a constant, declared only when it is positive."""
    if error == 0.0:
        return []
    return [Constant(name="pProbeError", type="double", value=error, comment="P(a probe misreports the level)")]


def probe_updates(error: float, top: int) -> list[Update]:
    """What a probe writes into ``bhat`` (and ``step``), with misreport probability ``error``.

    A perfect probe (``error=0``) writes the true level, ``bhat := b``. An imperfect one
    reports the true level with probability ``1-error`` and each of the other ``top`` levels
    with probability ``error/top``: a wrong report says nothing about which level is wrong.
    The other levels are ``mod(b+k, L+1)`` for k = 1..L (each once, whatever ``b``), so one
    command covers every level. Only reports of positive probability are written, so every
    ``error`` in [0, 1] gives distributions that sum to 1 (also in exact arithmetic). At
    ``error = top/(top+1)`` every level is reported with probability ``1/(top+1)``: the probe
    carries no information.
    """
    if error == 0.0:
        return [Update(assignments={"bhat": "b", "step": "1"})]
    right = [] if error == 1.0 else [Update(probability="1-pProbeError", assignments={"bhat": "b", "step": "1"})]
    wrong = [
        Update(probability="pProbeError/L", assignments={"bhat": f"mod(b+{k}, L+1)", "step": "1"})
        for k in range(1, top + 1)
    ]
    return right + wrong


def _results(s: Scenario) -> list[tuple[str, int]]:
    """The analysis results as (probability expression, req value), leaving out impossible ones.

    The last result's probability is written as 1 minus the others, so that each distribution
    sums to exactly 1 (also for Storm's exact, rational engine)."""
    parts = [
        ("pResultAlarm", ALARM, s.p_alarm),
        ("(pResultDrug+pResultDose)", DRUG, s.p_drug + s.p_dose),
        ("(1-pResultAlarm-pResultDrug-pResultDose)", DONE, s.p_ok),
    ]
    kept = [(expression, value) for expression, value, p in parts if p > 0]
    if len(kept) > 1:
        last = "(1-" + "-".join(expression for expression, _ in kept[:-1]) + ")"
        kept[-1] = (last, kept[-1][1])
    elif kept:
        kept[0] = ("1", kept[0][1])
    return kept


def _on_success(success: str, results: list[tuple[str, int]]) -> list[Update]:
    return [Update(probability=f"{success}*{p}", assignments={"req": value}) for p, value in results]


def _by_level(variable: str, top: int) -> str:
    expression = f"fLevel{top}"
    for level in reversed(range(top)):
        expression = f"({variable}={level} ? fLevel{level} : {expression})"
    return expression
