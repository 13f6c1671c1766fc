"""An example third-party parley plugin: a thermostat whose thermometer drifts.

The room's temperature level ``temp`` (0..4, comfortable at 1..3) drifts by one level up or
down with probability ``drift`` each round. The thermostat acts on its estimate ``est``:
it heats when est < 2, cools when est > 2, and updates est as if its action worked. A
calibration (cost 1) sets est to the true temperature; it runs once ``step`` reaches the
constant ``c``. The URC chooses c per estimated level.

Install it with ``pip install docs/examples/parley-thermostat``; then ``parley list`` shows
``thermostat`` and ``parley run thermostat`` synthesizes its URC. Its tests
(``tests/test_thermostat.py``) run parley's conformance suite on it and check its values.
"""

from __future__ import annotations

from attrs import frozen, validators

from parley.plugin import (
    Baseline,
    CaseStudy,
    Command,
    Constant,
    DecisionKind,
    Direction,
    Formula,
    Label,
    Module,
    Objective,
    Program,
    RewardItem,
    Rewards,
    Service,
    SystemModel,
    Update,
    Variable,
    hookimpl,
    option,
    positive,
)


@frozen(kw_only=True)
class ThermostatOptions:
    drift: float = option(
        0.15, "probability of drifting up, and of drifting down, per round", validators.ge(0.0), validators.le(0.5)
    )
    rounds: int = option(20, "rounds the objectives look at", positive)
    max_interval: int = option(4, "largest calibration interval", positive)


def build(options: ThermostatOptions) -> SystemModel:
    # One round: act on the estimate (h: heat +1, cool -1, idle 0) while the room drifts,
    # then calibrate (est := temp) or skip.
    def clamp(expression: str) -> str:
        return f"max(min({expression}, 4), 0)"

    act = Command(
        action="act",
        guard="t=0",
        updates=[
            Update(probability="drift", assignments={"temp": clamp("temp+h-1"), "est": clamp("est+h"), "t": "1"}),
            Update(probability="drift", assignments={"temp": clamp("temp+h+1"), "est": clamp("est+h"), "t": "1"}),
            Update(probability="1-2*drift", assignments={"temp": clamp("temp+h"), "est": clamp("est+h"), "t": "1"}),
        ],
    )
    room = Module(
        name="Room",
        variables=[
            Variable(name="temp", low=0, high=4, init=2, comment="true temperature level"),
            Variable(name="est", low=0, high=4, init=2, comment="the thermostat's estimate"),
            Variable(name="step", low=1, high="maxStep", init=1, comment="rounds since the last calibration"),
            Variable(name="t", low=0, high=1, init=0),
        ],
        commands=[
            act,
            Command(
                action="calibrate",
                guard="t=1 & step>=c",
                updates=[Update(assignments={"est": "temp", "step": "1", "t": "0"})],
            ),
            Command(action="skip", guard="t=1 & step<c", updates=[Update(assignments={"step": "step+1", "t": "0"})]),
        ],
    )
    text = Program(
        header="thermostat: an example third-party parley plugin",
        constants=[
            Constant(name="drift", type="double", value=options.drift),
            Constant(name="maxStep", value=options.max_interval),
            Constant(name="c", comment="calibrate every c-th round"),
        ],
        formulas=[Formula(name="h", expression="est<2 ? 1 : (est>2 ? -1 : 0)")],
        modules=[room],
        rewards=[Rewards(name="calibrations", items=[RewardItem(action="calibrate", value=1)])],
        labels=[Label(name="uncomfortable", expression="temp=0 | temp=4")],
    ).render()
    horizon = 2 * options.rounds
    return SystemModel(
        name="thermostat",
        description="room whose thermometer drifts",
        prism=text,
        services=[
            Service(name="calibration", constant="c", kind=DecisionKind.FREQUENCY, low=1, high=options.max_interval)
        ],
        observation=("est",),
        objectives=[
            Objective(name="discomfort", formula=f'P=? [F<={horizon} "uncomfortable"]', direction=Direction.MIN),
            Objective(name="calibrations", formula=f'R{{"calibrations"}}=? [C<={horizon}]', direction=Direction.MIN),
        ],
        baselines=Baseline.sweep("c", range(1, options.max_interval + 1), "every-{}"),
    )


@hookimpl
def parley_case_studies():
    return [
        CaseStudy(
            name="thermostat",
            description="Thermostat with a drifting thermometer: when to calibrate (example plugin)",
            options_type=ThermostatOptions,
            build=build,
            quick={"rounds": "6"},
        )
    ]
