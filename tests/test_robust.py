"""Robust runs: the worst case over scenarios, checked by Storm in each; scenario sets; errors."""

from __future__ import annotations

import csv
import json
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from parley_core.cli import app
from parley_core.errors import OptionError
from parley_core.evaluate.storm import StormEvaluator
from parley_core.family.prepare import prepare, prepare_scenarios
from parley_core.family.scenarios import ScenarioSet
from parley_core.pipeline import run
from parley_core.plugin.manager import load_registry
from parley_core.prism.program import parse_program
from parley_core.prism.rewrite import override_constants
from parley_core.robust import worst
from parley_core.search import SearchSettings

QUICK = {"size": "5", "seed": "1", "max_interval": "4", "horizon": "45"}
PUMP = Path(__file__).parent.parent / "docs" / "tutorial"
SETTINGS = SearchSettings(population=20, generations=4, seed=3)


@pytest.fixture(scope="module")
def robot():
    return load_registry().get("robot_grid")


def _run(prepared, **kwargs):
    return run(prepared, SETTINGS, workers=1, **kwargs)


def test_one_scenario_is_the_plain_search(robot):
    plain = _run(prepare(robot, robot.options_from(QUICK)), bound="none")
    one = _run(prepare_scenarios(robot, dict(QUICK), ScenarioSet.parse(["p=0.01"])), bound="none")
    assert robot.options_from(QUICK).p == 0.01
    assert [p.values for p in one.front.policies] == [p.values for p in plain.front.policies]
    assert one.front.values == plain.front.values
    assert np.array_equal(one.search.values, plain.search.values)
    assert one.front_scenarios is not None and one.front_scenarios.shape == (len(one.front), 1, 2)


@pytest.fixture(scope="module")
def robust_result(robot):
    prepared = prepare_scenarios(robot, dict(QUICK), ScenarioSet.parse(["p=0.005,0.02", "localisation_cost=4,6"]))
    return _run(prepared, bound="pareto")


def test_the_worst_case_is_the_extreme_of_storms_values_in_each_scenario(robust_result):
    result = robust_result
    assert [m.label for m in result.scenarios] == [
        "p=0.005 localisation_cost=4",
        "p=0.005 localisation_cost=6",
        "p=0.02 localisation_cost=4",
        "p=0.02 localisation_cost=6",
    ]
    rows = np.array([p.values for p in result.front.policies])
    # Storm's reference path (the augmented program, one policy per build) in each scenario,
    # independently of the policy programs that verified the run
    for s, model in enumerate(result.scenarios):
        storm = StormEvaluator(model.family, workers=1)
        try:
            expected = storm.evaluate(rows[:8])
        finally:
            storm.close()
        np.testing.assert_allclose(result.front_scenarios[:8, s], expected, rtol=1e-9, atol=1e-12)
    front = np.array(result.front.values)
    success, cost = result.front_scenarios[:, :, 0], result.front_scenarios[:, :, 1]
    assert np.array_equal(front[:, 0], success.min(axis=1))
    assert np.array_equal(front[:, 1], cost.max(axis=1))
    # the scenarios differ, and the worst case comes from the slippery, costly one
    assert (success[:, 0] > success[:, 3]).all() and (cost[:, 3] > cost[:, 0]).all()
    base = np.array(result.baseline.values)
    assert np.array_equal(base, worst(result.baseline_scenarios, result.family.objectives))
    assert result.verification.scenarios == 4 and result.verification.by.by_storm


def test_the_bound_holds_the_worst_case_of_random_policies(robust_result):
    from parley_core.evaluate.quotient import QuotientEvaluator

    result = robust_result
    bound = result.bound
    assert bound is not None and "4 scenarios" in bound.method
    rng = np.random.default_rng(5)
    rows = np.vstack([result.family.random(rng, 60), np.array([p.values for p in result.front.policies])])
    each = []
    for model in result.scenarios:
        evaluator = QuotientEvaluator(model.family, workers=1)
        each.append(evaluator.evaluate(rows))
        evaluator.close()
    values = worst(np.stack(each, axis=1), result.family.objectives)
    points = np.asarray(bound.points)
    # every policy is weakly dominated by some point of the bound (success max, cost min)
    covered = (points[None, :, 0] >= values[:, None, 0] - 1e-9) & (points[None, :, 1] <= values[:, None, 1] + 1e-9)
    assert covered.any(axis=1).all()


def test_scenario_sets_parse_lists_grids_and_files(tmp_path):
    assert [s.label for s in ScenarioSet.parse(["p=0.01,0.02"])] == ["p=0.01", "p=0.02"]
    grid = ScenarioSet.parse(["p=0.01,0.02", "move_cost=1,2,3"])
    assert len(grid) == 6 and grid.keys == ("p", "move_cost")
    path = tmp_path / "s.csv"
    path.write_text("p,move_cost\n0.01,1\n0.03,2\n")
    read = ScenarioSet.parse([str(path)])
    assert [s.values for s in read] == [{"p": "0.01", "move_cost": "1"}, {"p": "0.03", "move_cost": "2"}]


@pytest.mark.parametrize(
    ("specs", "message"),
    [
        ([], "empty"),
        ([""], "empty"),
        (["p="], "empty value"),
        (["p=0.1,0.1"], "twice"),
        (["p=0.1", "p=0.2"], "twice"),
        (["1p=3"], "malformed"),
        (["missing.csv"], "does not exist"),
    ],
)
def test_bad_scenario_sets_are_user_errors(specs, message):
    with pytest.raises(OptionError, match=message):
        ScenarioSet.parse(specs)


def test_a_scenario_file_needs_a_value_per_option(tmp_path):
    path = tmp_path / "s.csv"
    path.write_text("p,move_cost\n0.01\n")
    with pytest.raises(OptionError, match="line 2"):
        ScenarioSet.parse([str(path)])


runner = CliRunner()
CLI_QUICK = ["--set=horizon=45", "--set=max_interval=4"]


@pytest.mark.parametrize(
    ("scenarios", "message"),
    [
        (["p=0.01,0", "size=5"], "scenario p=0 size=5 changes the model's structure (option p)"),
        (["seed=1,2", "size=5"], "scenario seed=2 size=5 changes the model's structure (option seed)"),
        (["size=5,6", "p=0.1"], "scenario size=6 p=0.1 changes the model's structure (option size)"),
        (["speed=1,2"], "unknown option 'speed' for robot_grid"),
        (["horizon=40"], "given by --set and by --scenarios"),
    ],
)
def test_cli_scenario_errors_are_one_line(tmp_path, scenarios, message):
    args = ["run", "robot_grid", *CLI_QUICK, "--workers", "1", "--out", str(tmp_path / "r")]
    for spec in scenarios:
        args += ["--scenarios", spec]
    result = runner.invoke(app, args)
    assert result.exit_code == 2, result.stderr
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: ") and message in lines[0], result.stderr
    assert not (tmp_path / "r").exists()


def test_cli_robust_run_writes_scenarios_csv(tmp_path):
    out = tmp_path / "r"
    args = ["run", "robot_grid", "--set=size=5", "--set=horizon=45", "--set=max_interval=3", "--workers", "1"]
    args += ["--generations", "3"]
    result = runner.invoke(app, [*args, "--population", "12", "--scenarios", "p=0.005,0.02", "--out", str(out)])
    assert result.exit_code == 0, result.stderr
    assert "worst case over 2 scenarios" in " ".join(result.stdout.split())
    summary = json.loads((out / "summary.json").read_text())
    assert [s["label"] for s in summary["robust"]["scenarios"]] == ["p=0.005", "p=0.02"]
    assert summary["verification"]["scenarios"] == 2
    assert summary["options"]["p"] == 0.005  # the first scenario's options
    rows = list(csv.DictReader((out / "scenarios.csv").open()))
    front = {r["policy"]: r for r in csv.DictReader((out / "front.csv").open())}
    assert len(rows) == 2 * (len(front) + 3)
    for name, row in front.items():
        mine = [r for r in rows if r["policy"] == name and r["set"] == "front"]
        assert float(row["success"]) == min(float(r["success"]) for r in mine)
        assert float(row["cost"]) == max(float(r["cost"]) for r in mine)


def test_constants_of_a_users_model_are_overridden():
    text = (PUMP / "pump.prism").read_text()
    changed = override_constants(text, {"wear_high": "0.2", "load_change": "0.05"})
    assert "const double wear_high = 0.2;" in changed and "const double load_change = 0.05;" in changed
    assert changed.count("wear_high = ") == 1
    # the rest of the program as it was: the same constants, modules and rewards, as Storm reads them
    before, after = parse_program(text), parse_program(changed)

    def values(program):
        return {c.name: c.definition.evaluate_as_double() for c in program.constants}

    # Storm prints the other doubles as exact fractions (0.04 as 1/25), which it reads back to the ulp
    assert values(after) == pytest.approx({**values(before), "wear_high": 0.2, "load_change": 0.05}, rel=1e-15)
    assert [str(m) for m in after.modules] == [str(m) for m in before.modules]
    assert [r.name for r in after.reward_models] == [r.name for r in before.reward_models]
    assert override_constants(text, {}) == text
    with pytest.raises(OptionError, match="declares no constant"):
        override_constants(text, {"nope": "1"})
    with pytest.raises(OptionError, match="decision constant"):
        override_constants(text, {"c": "2"}, services=["c"])
    with pytest.raises(OptionError, match="give a number"):
        override_constants(text, {"wear_low": "x"})


def test_synthesize_takes_scenarios_over_model_constants(tmp_path):
    out = tmp_path / "pump"
    result = runner.invoke(
        app,
        [
            "synthesize",
            str(PUMP / "pump.prism"),
            "--props",
            str(PUMP / "pump.pctl"),
            "--decision",
            "c=1..4",
            "--observe",
            "est",
            "--generations",
            "3",
            "--population",
            "12",
            "--workers",
            "1",
            "--scenarios",
            "wear_high=0.1,0.2",
            "--out",
            str(out),
        ],
    )
    assert result.exit_code == 0, result.stderr
    rows = list(csv.DictReader((out / "scenarios.csv").open()))
    by = {(r["policy"], r["wear_high"]): float(r["broken"]) for r in rows if r["set"] == "front"}
    front = {r["policy"]: float(r["broken"]) for r in csv.DictReader((out / "front.csv").open())}
    for name, value in front.items():
        # a pump that wears faster breaks more often: the worst case is wear_high=0.2's
        assert by[name, "0.2"] >= by[name, "0.1"] and value == by[name, "0.2"]
    assert "const double wear_high = 1/10;" in (out / "model.prism").read_text()
