"""The world: cells, controller, options that a user can get wrong, the kinematic table, and
reading the paper's model format."""

from __future__ import annotations

import pytest

from parley_core import OptionError
from parley_plugins.turtlebot import CASE_STUDY as CASE
from parley_plugins.turtlebot import published, world_of
from parley_plugins.turtlebot.kinematics import simulate
from parley_plugins.turtlebot.world import CRASH, OUT, STEP, Outcome, parse_cells, shortest_moves


def test_cells_parse_and_bad_cells_say_how_to_write_them():
    assert parse_cells("1:2, 2:2,", "obstacles") == {(1, 2), (2, 2)}
    assert parse_cells("", "obstacles") == frozenset()
    with pytest.raises(OptionError, match="write cells as X:Y"):
        parse_cells("1-2", "obstacles")


def test_the_controller_follows_a_shortest_path_round_obstacles():
    obstacles = frozenset({(1, 0), (1, 1)})
    plan = shortest_moves(3, obstacles, (2, 0))
    cell, moves = (0, 0), 0
    while cell != (2, 0):
        dx, dy = STEP[plan[cell]]
        cell = (cell[0] + dx, cell[1] + dy)
        assert cell not in obstacles
        moves += 1
    assert moves == 6  # up to row 2, across, down again
    assert (2, 0) not in plan and not obstacles & set(plan)


@pytest.mark.parametrize(
    ("setting", "message"),
    [
        ("start=9:9", "outside the 7x7 square"),
        ("target=1:3", "is an obstacle"),
        ("start=3:5", "same cell"),
        ("obstacles=2:0,2:1,2:2,2:3,2:4,2:5,2:6", "no obstacle-free path"),
        ("start=1", "start='1' for turtlebot: expected int:int"),
        ("start=1:0,2:0", "expected int:int"),
        ("obstacles=1-2", "expected a list X:Y,X:Y,... of int:int"),
        ("friction=0.7", "expected float:float"),
        ("left_wheel=0", "left_wheel"),
        ("samples=0", "samples must be positive"),
    ],
)
def test_bad_options_say_what_to_change(setting, message):
    with pytest.raises(OptionError, match=message):
        CASE.build(CASE.options([setting]))


def test_simulation_options_do_not_mix_with_the_papers_motions(tmp_path):
    with pytest.raises(OptionError, match="option heading_noise shapes simulated motions"):
        CASE.build(CASE.options([f"model={tmp_path / 'model.prism'}", "heading_noise=3"]))


def test_a_missing_published_model_is_a_clear_error(tmp_path):
    with pytest.raises(OptionError, match="models/turtlebot/model.prism"):
        CASE.build(CASE.options([f"model={tmp_path / 'nope.prism'}"]))
    wrong = tmp_path / "other.prism"
    wrong.write_text("dtmc\nmodule M x : [0..1] init 0; [] true -> true; endmodule\n")
    with pytest.raises(OptionError, match="declares no N"):
        CASE.build(CASE.options([f"model={wrong}"]))


def test_the_kinematic_table_is_a_distribution_and_reproducible():
    obstacles = frozenset({(1, 1)})
    table = simulate(3, obstacles, samples=300, seed=4)
    assert len(table) == (9 - 1) * 4 * 4
    for outcomes in table.values():
        assert sum(p for _, p in outcomes) == pytest.approx(1.0)
        assert all(p > 0 for _, p in outcomes)
    assert table == simulate(3, obstacles, samples=300, seed=4)
    assert table != simulate(3, obstacles, samples=300, seed=5)


def test_a_weak_left_wheel_drifts_left():
    def sideways(left_wheel):
        table = simulate(
            5, frozenset(), left_wheel=left_wheel, heading_noise=0, turn_noise=0, distance_noise=0, samples=400
        )
        outcomes = dict(table[(2, 0, 0, "north")])
        west = sum(p for o, p in outcomes.items() if o.kind == "move" and o.dx == -1)
        east = sum(p for o, p in outcomes.items() if o.kind == "move" and o.dx == 1)
        return west, east

    assert sideways(1.0) == (0, 0)
    west, east = sideways(0.9)  # curvature 0.37 per metre: about 1.7 m to the left over 3 m
    assert west > 0.2 and east == 0


def _published_text(world, slip: bool) -> str:
    """A model in the paper's format (as its generator writes them), written from ``world``."""

    def expression(variable, delta, move):
        if delta == 0:
            return variable
        if delta > 0:
            return f"min(N,{variable}+1)"
        bound = "N" if slip and move == "south" and variable == "y" else "0"
        return f"max({bound},{variable}-1)"

    lines = [
        "dtmc",
        f"const int N={world.size - 1};",
        f"const int startX = {world.start[0]};",
        f"const int startY = {world.start[1]};",
        f"const int targetX = {world.target[0]};",
        f"const int targetY = {world.target[1]};",
        "module Robot",
    ]
    for (x, y, heading, move), outcomes in sorted(world.motions.items()):
        for estimate in range(4):
            updates = []
            for outcome, p in outcomes:
                if outcome == CRASH:
                    updates.append(f"{p}:(crashed'=1)")
                elif outcome == OUT:
                    updates.append(f"{p}:(out'=1)")
                else:
                    updates.append(
                        f"{p}:(x'={expression('x', outcome.dx, move)})&(y'={expression('y', outcome.dy, move)})&(direction'={outcome.heading})"
                    )
            lines.append(
                f"[{move}] (ready=1) & (x={x}) & (y={y}) & (direction={heading}) & (directionhat={estimate}) -> "
            )
            lines.append("  " + " +\n  ".join(updates) + ";")
    lines.append("endmodule\nmodule Adaptation_MAPE_controller")
    lines += [
        f"  [{move}] (xhat={x}) & (yhat={y}) & (crashed=0) & (out=0) -> true;" for (x, y), move in world.plan.items()
    ]
    lines.append("endmodule")
    return "\n".join(lines) + "\n"


def test_the_papers_format_reads_back_and_its_south_slip_is_repaired_or_kept():
    world = world_of(
        CASE.options(["size=4", "start=0:0", "target=3:3", "obstacles=1:1", "samples=60", "heading_noise=25"])
    )
    # keep only moves by at most one cell (the paper's format cannot say more)
    motions = {k: v for k, v in world.motions.items() if all(abs(o.dx) <= 1 and abs(o.dy) <= 1 for o, _ in v)}
    world = type(world)(
        size=4, start=(0, 0), target=(3, 3), obstacles=world.obstacles, motions=motions, plan=world.plan
    )
    text = _published_text(world, slip=True)
    repaired = published.parse(text)
    assert repaired.motions == world.motions and repaired.plan == world.plan
    assert (repaired.size, repaired.start, repaired.target, repaired.obstacles) == (4, (0, 0), (3, 3), {(1, 1)})
    kept = published.parse(text, repair=False)
    slipped = [
        (key, outcome)
        for key, outcomes in world.motions.items()
        for outcome, _ in outcomes
        if key[3] == "south" and outcome.kind == "move" and outcome.dy == -1
    ]
    assert slipped
    for (x, y, heading, move), outcome in slipped:
        assert Outcome("move", outcome.dx, 3 - y, outcome.heading) in dict(kept.motions[(x, y, heading, move)])
    assert published.parse(_published_text(world, slip=False), repair=False).motions == world.motions


def test_a_table_that_depends_on_the_estimated_heading_is_refused():
    world = world_of(CASE.options(["size=3", "start=0:0", "target=2:2", "obstacles=", "samples=20"]))
    text = _published_text(world, slip=False)
    key = next(k for k in sorted(world.motions) if len(world.motions[k]) > 1)
    x, y, heading, move = key
    head = f"[{move}] (ready=1) & (x={x}) & (y={y}) & (direction={heading}) & (directionhat=3) -> \n  "
    start = text.index(head) + len(head)
    end = text.index(";", start)
    first, rest = text[start:end].split(":", 1)
    changed = text[:start] + f"{float(first) / 2}:" + rest + f" +\n  {float(first) / 2}:(out'=1)" + text[end:]
    with pytest.raises(OptionError, match="depends on the estimated heading"):
        published.parse(changed)


def test_sampled_probabilities_are_written_as_fractions_storm_can_multiply():
    from parley_core import testing
    from parley_plugins.turtlebot.generator import exact

    assert exact(7 / 3000) == "7/3000" and exact(1.0) == "1" and exact(0.0123) == "123/10000"
    assert exact(0.123456789) == "0.123456789"  # not a small fraction: as written
    # 3,001 draws: decimals such as 0.000333222... made the augmented model overflow Storm's integers
    fam = testing.family("turtlebot", ["size=4", "start=0:0", "target=3:3", "obstacles=1:1", "samples=3001"])
    assert "/ 3001)" in fam.prism  # the augmented text keeps the fractions
