"""From a front to a running controller: `parley select`, the runtime URC, `parley simulate`."""

from __future__ import annotations

import csv
import json

import pytest
from typer.testing import CliRunner

from parley_core import URC, ObservationError
from parley_core.cli import app
from parley_core.errors import PolicyError

runner = CliRunner()


def invoke(*args):
    return runner.invoke(app, [str(a) for a in args])


@pytest.fixture(scope="module")
def run_dir(tmp_path_factory):
    out = tmp_path_factory.mktemp("runs") / "robot"
    result = invoke(
        "run",
        "robot_grid",
        "--set",
        "size=6",
        "--set",
        "seed=3",
        "--population",
        "16",
        "--generations",
        "4",
        "--workers",
        "1",
        "--out",
        out,
    )
    assert result.exit_code == 0, result.stderr
    return out


def front(run_dir):
    with open(run_dir / "front.csv") as handle:
        return {row["policy"]: (float(row["success"]), float(row["cost"])) for row in csv.DictReader(handle)}


@pytest.mark.slow
def test_select_the_cheapest_policy_meeting_a_constraint(run_dir, tmp_path):
    values = front(run_dir)
    result = invoke(
        "select", run_dir, "--constraint", "success>=0.8", "--prefer", "cost", "--out", tmp_path / "c.json", "--json"
    )
    assert result.exit_code == 0, result.stderr
    chosen = json.loads(result.stdout)["policy"]
    feasible = {name: v for name, v in values.items() if v[0] >= 0.8}
    assert values[chosen][1] == min(v[1] for v in feasible.values())
    urc = URC.load(tmp_path / "c.json")
    assert urc.values == {"success": values[chosen][0], "cost": values[chosen][1]}
    # the controller's decisions are the policy's columns in policies.csv
    with open(run_dir / "policies.csv") as handle:
        row = next(r for r in csv.DictReader(handle) if r["policy"] == chosen)
    assert urc.decide({"xhat": 2, "yhat": 3}) == {"c": int(row["c_2_3"])}
    assert urc.decide([0, 0]) == {"c": int(row["c_0_0"])}


def test_select_the_knee_and_errors(run_dir, tmp_path):
    assert invoke("select", run_dir, "--knee", "--out", tmp_path / "k.json").exit_code == 0
    for args, message in (
        (["--constraint", "success>=1.5"], "no policy of the front meets success>=1.5"),
        (["--prefer", "speed"], "--prefer speed: no objective of that name"),
        (["--prefer", "cost", "--knee"], "give --prefer NAME or --knee, not both"),
        (["--constraint", "success>>1"], "malformed constraint"),
    ):
        result = invoke("select", run_dir, *args, "--out", tmp_path / "x.json")
        assert result.exit_code == 2 and message in result.stderr, result.stderr
    result = invoke("select", tmp_path / "nothing")
    assert result.exit_code == 2 and "run directory" in result.stderr


def test_the_runtime_urc_refuses_observations_it_was_not_made_for(run_dir, tmp_path):
    invoke("select", run_dir, "--out", tmp_path / "c.json")
    urc = URC.load(tmp_path / "c.json")
    with pytest.raises(ObservationError, match="outside the domain the controller was synthesized for"):
        urc.decide({"xhat": 6, "yhat": 0})
    with pytest.raises(ObservationError, match="missing yhat"):
        urc.decide({"xhat": 1})
    with pytest.raises(ObservationError, match="unknown zhat"):
        urc.decide({"xhat": 1, "yhat": 1, "zhat": 0})
    with pytest.raises(ObservationError, match="is not an integer"):
        urc.decide({"xhat": 1.5, "yhat": 1})
    left_out = URC(observation=["x"], services=[{"constant": "c"}], table={(0,): {"c": 1}}, left_out=[(1,)])
    with pytest.raises(ObservationError, match="no service is ever consulted there"):
        left_out.decide([1])
    (tmp_path / "bad.json").write_text("{not json")
    with pytest.raises(PolicyError, match="is not JSON"):
        URC.load(tmp_path / "bad.json")
    (tmp_path / "other.json").write_text('{"format": "something-else"}')
    with pytest.raises(PolicyError, match="is not a parley controller"):
        URC.load(tmp_path / "other.json")


def test_ten_thousand_simulated_episodes_agree_with_model_checking(run_dir, tmp_path):
    invoke("select", run_dir, "--knee", "--out", tmp_path / "c.json")
    result = invoke(
        "simulate", run_dir, "--policy", tmp_path / "c.json", "--episodes", "10000", "--seed", "7", "--json"
    )
    assert result.exit_code == 0, result.stderr
    estimates = {e["objective"]: e for e in json.loads(result.stdout)}
    assert set(estimates) == {"success", "cost"}
    for estimate in estimates.values():
        low, high = estimate["interval99"]
        assert low <= estimate["model_checked"] <= high, estimate
        assert high - low < 0.05 * max(1.0, abs(estimate["model_checked"])), "the interval is too wide to mean much"
    assert estimates["success"]["cut"] == 0


def test_simulating_a_policies_file(run_dir, tmp_path):
    with open(run_dir / "policies.csv") as handle:
        lines = handle.read().splitlines()
    (tmp_path / "one.csv").write_text("\n".join(lines[:2]) + "\n")
    result = invoke("simulate", run_dir, "--policy", tmp_path / "one.csv", "--episodes", "2000", "--json")
    assert result.exit_code == 0, result.stderr
    assert all(e["within_interval"] for e in json.loads(result.stdout))
    (tmp_path / "two.csv").write_text("\n".join(lines[:3]) + "\n")
    result = invoke("simulate", run_dir, "--policy", tmp_path / "two.csv", "--episodes", "10")
    assert result.exit_code == 2 and "holds 2 policies" in result.stderr
