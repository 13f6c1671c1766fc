"""The URC in closed loop on the MuJoCo robot, against Storm, where the model is exact."""

from __future__ import annotations

import csv
import json

import numpy as np
import pytest

from parley_core import URC
from parley_core.testing import storm_values
from parley_plugins.turtlebot import CASE_STUDY as CASE
from parley_plugins.turtlebot.closed_loop import simulate

# an ideal robot started at cell centres: every move ends at the next cell's centre, so the
# sampled table is deterministic and the DTMC is the closed loop, cell for cell
IDEAL = [
    "motions=mujoco",
    "size=4",
    "start=0:0",
    "target=2:3",
    "obstacles=1:1,2:1",
    "wheel_noise=0",
    "friction=0.85:0.85",
    "heading_noise=0",
    "margin=1.5",
    "samples=4",
    "max_period=3",
]


@pytest.mark.parametrize(
    ("left_wheel", "horizon", "success"),
    [
        (1.0, 60, 1.0),  # the energy's horizon cuts the route short; success is unbounded
        (1.0, 12, 1.0),
        (0.9, 60, 0.0),  # drifts over the border or into an obstacle on the first move
    ],
)
def test_without_noise_the_closed_loop_is_what_storm_proves(left_wheel, horizon, success, tmp_path, monkeypatch):
    monkeypatch.setenv("PARLEY_CACHE", str(tmp_path))
    options = CASE.options([*IDEAL, f"left_wheel={left_wheel}", f"horizon={horizon}"])
    system = CASE.build(options)
    world = system.context
    assert all(len(outcomes) == 1 for outcomes in world.motions.values())  # deterministic
    valuations = [(x, y, h) for x in range(4) for y in range(4) for h in range(4)]
    for period in (1, 2, 3):
        urc = URC(
            observation=system.observation, services=system.services, table={v: {"c": period} for v in valuations}
        )
        storm = storm_values(system.prism, [o.formula for o in system.objectives], {"c": period})
        episodes = simulate(system, options, urc, episodes=3, seed=period)
        assert storm[0] == success
        np.testing.assert_array_equal(episodes.values["success"], [success] * 3)
        np.testing.assert_allclose(episodes.values["energy"], [storm[1]] * 3, rtol=0, atol=1e-9)


@pytest.mark.slow
def test_parley_validate_writes_intervals_next_to_storms_values(tmp_path, monkeypatch):
    from typer.testing import CliRunner

    from parley_core.cli import app

    monkeypatch.setenv("PARLEY_CACHE", str(tmp_path / "cache"))
    runner = CliRunner()
    small = ["--set", "motions=mujoco", "--set", "size=4", "--set", "start=0:0", "--set", "target=3:3"]
    small += ["--set", "obstacles=1:1,2:2", "--set", "samples=20", "--set", "max_period=3", "--set", "horizon=45"]
    out = tmp_path / "run"
    result = runner.invoke(
        app, ["run", "turtlebot", *small, "--population", "8", "--generations", "2", "--out", str(out)]
    )
    assert result.exit_code == 0, result.stderr
    result = runner.invoke(app, ["validate", str(out), "--episodes", "30", "--seed", "2"])
    assert result.exit_code == 0, result.stderr
    document = json.loads((out / "validation.json").read_text())
    assert (out / "validation.png").stat().st_size > 10_000
    roles = [p["role"] for p in document["policies"]]
    assert roles == ["chosen", "baseline", "baseline", "baseline"]  # the knee and period-1..3
    front = {row["policy"]: row for row in csv.DictReader(open(out / "front.csv"))}
    chosen = document["policies"][0]
    for estimate in chosen["estimates"]:
        assert estimate["episodes"] == 30
        assert estimate["storm"] == pytest.approx(float(front[chosen["policy"]][estimate["objective"]]), rel=1e-12)
        low, high = estimate["interval99"]
        assert low <= estimate["closed_loop"] <= high
    assert "Storm" in result.stdout
    # the same seed gives the same episodes
    again = runner.invoke(app, ["validate", str(out), "--episodes", "30", "--seed", "2", "--json"])
    assert json.loads(again.stdout)["policies"] == document["policies"]
    first = next(iter(front))
    by_row = runner.invoke(app, ["validate", str(out), "--policy", "1", "--episodes", "5", "--no-baselines", "--json"])
    assert [p["policy"] for p in json.loads(by_row.stdout)["policies"]] == [first]
    wrong = runner.invoke(app, ["validate", str(out), "--policy", "100000"])
    assert wrong.exit_code == 2 and "front.csv has rows 1.." in wrong.stderr


def test_validate_says_what_is_wrong(tmp_path, monkeypatch):
    from typer.testing import CliRunner

    from parley_core.cli import app

    monkeypatch.setenv("PARLEY_CACHE", str(tmp_path / "cache"))
    runner = CliRunner()
    result = runner.invoke(app, ["validate", str(tmp_path / "nowhere")])
    assert result.exit_code == 2 and "does not exist" in result.stderr
    out = tmp_path / "ids"
    result = runner.invoke(app, ["run", "web_ids", "--population", "6", "--generations", "1", "--out", str(out)])
    assert result.exit_code == 0, result.stderr
    result = runner.invoke(app, ["validate", str(out)])
    assert result.exit_code == 2 and "offers no simulator" in result.stderr
    assert "Traceback" not in result.stderr
