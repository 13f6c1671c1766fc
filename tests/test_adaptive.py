"""The adaptive URC (scripted traces), its controller file, drift specifications and the
drift simulation against Storm's values."""

from __future__ import annotations

import math

import numpy as np
import pytest
from typer.testing import CliRunner

from parley_core.cli import app
from parley_core.errors import OptionError, PolicyError
from parley_core.family.prepare import prepare
from parley_core.model import Policy
from parley_core.plugin.manager import load_registry
from parley_core.rundir.policies import table
from parley_core.simulation.drift import Drift, simulate_drift
from parley_core.urc.adaptive import AdaptiveController, Estimator
from parley_core.urc.controller import URC
from parley_plugins.robot_grid.events import SLIP, wrong_probability

QUICK = {"size": "5", "seed": "1", "max_interval": "4", "horizon": "45"}
CLI_QUICK = [f"--set={k}={v}" for k, v in QUICK.items()] + [
    "--workers",
    "1",
    "--generations",
    "2",
    "--population",
    "10",
]


def _urc(family, values, name: str) -> URC:
    return URC(
        observation=family.observation,
        services=family.services,
        table=table(family, Policy(name=name, values=values)),
        policy=name,
    )


def _toy_controller(forgetting: float = 1.0) -> AdaptiveController:
    urcs = [URC(observation=("o",), services=(), table={(0,): {}}, policy=name) for name in ("calm", "stormy")]
    return AdaptiveController(
        parameter="q", values=[0.1, 0.3], controllers=urcs, estimator=Estimator(forgetting=forgetting, hysteresis=2.0)
    )


def test_the_adaptive_urc_switches_when_the_likelihood_crosses_its_margin():
    urc = _toy_controller().runtime()
    up, down = math.log(0.3 / 0.1), math.log(0.7 / 0.9)  # what one event adds to stormy's lead
    assert urc.value == 0.1 and urc.urc.policy == "calm"
    urc.observe(1)
    assert urc.adapt() == 0.1  # lead 1.10 < 2
    urc.observe(1)
    assert urc.scores[0.3] - urc.scores[0.1] == pytest.approx(2 * up)
    assert urc.adapt() == 0.3 and urc.switches == [(2, 0.1, 0.3)]  # lead 2.20 > 2
    for _ in range(16):
        urc.observe(0)
    assert 2 * up + 16 * down > -2
    assert urc.adapt() == 0.3  # calm leads by 1.82 only
    urc.observe(0)
    assert 2 * up + 17 * down < -2
    assert urc.adapt() == 0.1 and urc.switches[-1] == (4, 0.3, 0.1)
    assert urc.decide({"o": 0}) == {}


def test_forgetting_discounts_old_events():
    urc = _toy_controller(forgetting=0.5).runtime()
    urc.observe(1)
    urc.observe(1)
    urc.adapt()  # switches, then halves
    assert urc.value == 0.3
    lead = urc.scores[0.3] - urc.scores[0.1]
    assert lead == pytest.approx(math.log(3))  # 2 log 3, halved


def test_an_adaptive_controller_file_round_trips(tmp_path):
    controller = _toy_controller()
    path = tmp_path / "adaptive.json"
    controller.save(path)
    assert AdaptiveController.load(path) == controller
    path.write_text('{"format": "parley-urc/1"}')
    with pytest.raises(PolicyError, match="not an adaptive controller"):
        AdaptiveController.load(path)
    with pytest.raises(PolicyError, match="two or more"):
        AdaptiveController(parameter="q", values=[0.1], controllers=controller.controllers[:1])


@pytest.mark.parametrize(
    ("text", "message"),
    [("p=0.01:0.03", "malformed"), ("p=a:0.03@4", "numbers"), ("p=0.01:0.03@9-4", "ends before"), ("p=1:1@3", "equal")],
)
def test_bad_drifts_are_user_errors(text, message):
    with pytest.raises(OptionError, match=message):
        Drift.parse(text)


def test_drift_levels_jump_and_ramp():
    values, index = Drift.parse("p=0.01:0.03@3").levels(6)
    assert values == (0.01, 0.03) and index.tolist() == [0, 0, 0, 1, 1, 1]
    values, index = Drift.parse("p=0.0:0.4@2-6").levels(9)
    assert values == pytest.approx((0.0, 0.1, 0.2, 0.3, 0.4))
    assert index.tolist() == [0, 0, 0, 1, 2, 3, 4, 4, 4]


def test_the_slip_likelihood():
    wrong = wrong_probability(0.02, np.array([1, 0]), np.array([3, 3]))
    assert wrong[0] == pytest.approx(1 - 0.94**3) and wrong.sum() == pytest.approx(1.0)


@pytest.fixture(scope="module")
def robot_family():
    case = load_registry().get("robot_grid")
    return prepare(case, case.options_from(QUICK)).family


def test_missions_at_a_constant_value_agree_with_storm(robot_family, tmp_path):
    from parley_core.simulation.drift_report import plot, to_json

    family = robot_family
    fixed = _urc(family, [2] * len(family.decisions), "every-2")
    # the drift starts after the last mission: every mission runs at p=0.01
    result = simulate_drift(
        family, Drift.parse("p=0.01:0.05@100"), [("fixed", fixed)], None, missions=20, episodes=400, seed=3
    )
    series = result.series[0]
    storm = series.checked["every-2", 0.01]
    for objective, value in zip(result.objectives, storm):
        mean, low, high = result.phase(series, objective, 0, 20)
        assert low <= value <= high, (objective, mean, low, high, value)
    assert series.in_force[:, 0].tolist() == [400] * 20
    # drift.json says the same: the phase before the drift (all 20 missions) and Storm's values
    (entry,) = to_json(result)["controllers"]
    assert entry["name"] == "fixed" and "after" not in entry["phases"]
    for objective, value in zip(result.objectives, storm):
        assert entry["phases"]["before"][objective]["mean"] == result.phase(series, objective, 0, 20)[0]
        assert entry["storm"][0][objective] == value and entry["storm"][0]["p"] == 0.01
    plot(result, tmp_path / "drift.png")
    assert (tmp_path / "drift.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_the_adaptive_urc_follows_a_jump_in_the_slip_probability(robot_family):
    family = robot_family
    controller = AdaptiveController(
        parameter="p",
        values=[0.01, 0.1],
        controllers=[
            _urc(family, [4] * len(family.decisions), "rare"),
            _urc(family, [1] * len(family.decisions), "often"),
        ],
    )
    result = simulate_drift(
        family, Drift.parse("p=0.01:0.1@15"), [("adaptive", controller)], SLIP, missions=40, episodes=100, seed=2
    )
    on_often = result.series[0].in_force[:, 1]
    assert on_often[:15].max() <= 20  # few false alarms at p=0.01
    assert on_often[-5:].min() >= 90  # nearly every system has switched after the jump
    # the missions after the switch are the "often" policy's at p=0.1 (Storm's value in the interval)
    storm = dict(zip(result.objectives, result.series[0].checked["often (p=0.1)", 0.1]))
    _, low, high = result.phase(result.series[0], "success", 30, 40)
    assert low - 0.02 <= storm["success"] <= high + 0.02


def test_an_adaptive_controller_needs_an_event_model(robot_family):
    controller = AdaptiveController(
        parameter="p",
        values=[0.01, 0.1],
        controllers=[_urc(robot_family, [2] * len(robot_family.decisions), n) for n in ("a", "b")],
    )
    with pytest.raises(OptionError, match="event model"):
        simulate_drift(
            robot_family, Drift.parse("p=0.01:0.1@2"), [("a", controller)], None, missions=3, episodes=2, seed=1
        )


@pytest.mark.slow
def test_cli_adapt_and_simulate_with_drift(tmp_path):
    runner = CliRunner()
    quick = CLI_QUICK
    for p in ("0.01", "0.05"):
        result = runner.invoke(
            app, ["run", "robot_grid", *quick, f"--set=p={p}", "--bound", "none", "--out", str(tmp_path / p)]
        )
        assert result.exit_code == 0, result.stderr
    adaptive = tmp_path / "adaptive.json"
    result = runner.invoke(
        app, ["adapt", str(tmp_path / "0.01"), str(tmp_path / "0.05"), "--parameter", "p", "--out", str(adaptive)]
    )
    assert result.exit_code == 0, result.stderr
    nominal = tmp_path / "nominal.json"
    assert runner.invoke(app, ["select", str(tmp_path / "0.01"), "--out", str(nominal)]).exit_code == 0
    result = runner.invoke(
        app,
        [
            "simulate",
            str(tmp_path / "0.01"),
            "--drift",
            "p=0.01:0.05@5",
            "--policy",
            str(nominal),
            "--policy",
            str(adaptive),
            "--missions",
            "10",
            "--episodes",
            "20",
            "--out",
            str(tmp_path / "drift"),
        ],
    )
    assert result.exit_code == 0, result.stderr
    assert (tmp_path / "drift" / "drift.json").is_file() and (tmp_path / "drift" / "drift.png").is_file()
    result = runner.invoke(app, ["adapt", str(tmp_path / "0.01"), "--parameter", "p", "--out", str(adaptive)])
    assert result.exit_code == 2 and "two or more" in result.stderr
    result = runner.invoke(app, ["adapt", str(tmp_path / "0.01"), str(tmp_path / "0.05"), "--parameter", "zz"])
    assert result.exit_code == 2 and "no option 'zz'" in result.stderr


def test_a_warm_start_puts_the_earlier_front_in_the_first_population(robot_family):
    from parley_core.search import SearchSettings
    from parley_core.search.problem import Genes
    from parley_core.search.run import initial_population

    family = robot_family
    rng = np.random.default_rng(4)
    warm = family.random(rng, 150)
    settings = SearchSettings(population=100, generations=1, seed=1)
    genes = Genes(family)
    first = genes.decode(initial_population(family, settings, warm=warm).astype(np.int64))
    baselines = len(family.baseline_policies())
    kept = first[baselines:100]
    assert len(first) == 100 and np.array_equal(kept[0], warm[0]) and np.array_equal(kept[-1], warm[-1])
    assert all(any(np.array_equal(row, w) for w in warm) for row in kept)  # evenly spaced, all from the front
    few = genes.decode(initial_population(family, settings, warm=warm[:5]).astype(np.int64))
    assert np.array_equal(few[baselines : baselines + 5], warm[:5])
    cold = genes.decode(initial_population(family, settings).astype(np.int64))
    assert np.array_equal(cold[:baselines], few[:baselines])


@pytest.mark.slow
def test_cli_warm_start_needs_a_run_of_the_same_family(tmp_path):
    runner = CliRunner()
    quick = CLI_QUICK
    first = tmp_path / "first"
    assert runner.invoke(app, ["run", "robot_grid", *quick, "--bound", "none", "--out", str(first)]).exit_code == 0
    result = runner.invoke(
        app,
        [
            "run",
            "robot_grid",
            *quick,
            "--set=p=0.03",
            "--bound",
            "none",
            "--warm-start",
            str(first),
            "--out",
            str(tmp_path / "w"),
        ],
    )
    assert result.exit_code == 0, result.stderr
    assert "warm start: the search started from" in " ".join(result.stdout.split())
    other = [a for a in quick if not a.startswith("--set=size")] + ["--set=size=6"]
    result = runner.invoke(app, ["run", "robot_grid", *other, "--warm-start", str(first), "--out", str(tmp_path / "x")])
    assert result.exit_code == 2 and len(result.stderr.strip().splitlines()) == 1, result.stderr


def test_the_calibration_counts_the_models_events(robot_family, tmp_path):
    from parley_core.simulation.drift import calibrate

    family = robot_family
    urcs = [_urc(family, [3] * len(family.decisions), "every-3"), _urc(family, [1] * len(family.decisions), "every-1")]
    found = calibrate([family, family], "p", [0.01, 0.05], urcs, SLIP, missions=300, seed=1)
    assert found.rates.shape == (2, 2, len(found.contexts)) and found.missions == 300
    assert found.contexts == (1, 3)  # every-1 localises after each move, every-3 after three
    k1, k3 = found.contexts.index(1), found.contexts.index(3)
    # a slipperier robot is found astray more often, and more so after three moves than after one
    assert (found.rates[1, :, :] > found.rates[0, :, :]).all()
    assert found.rates[1, 0, k3] > found.rates[1, 1, k1]
    controller = AdaptiveController(parameter="p", values=[0.01, 0.05], controllers=urcs, calibration=found)
    likelihood = controller.likelihood()
    probabilities = likelihood(1, np.array([1, 1]), np.array([1, 0]), np.array([1, 1]))
    assert probabilities[0] == pytest.approx(found.rates[1, 1, k1]) and probabilities.sum() == pytest.approx(1.0)
    controller.save(tmp_path / "adaptive.json")
    assert AdaptiveController.load(tmp_path / "adaptive.json").to_json() == controller.to_json()
