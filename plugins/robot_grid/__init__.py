"""robot_grid: the paper's running example.

A robot crosses a grid map from the lower-left to the upper-right corner, following a
Dijkstra movement controller that acts on its *estimated* position; each move may deviate.
A localisation service (cost 5) sets the estimate to the true position. The URC decides,
per estimated cell, after how many moves to localise (1..10). With ``loc_error`` > 0 the
localisation errs: it puts the estimate on a 4-neighbor of the true cell (docs/robot_grid.md).
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
    PolicyMap,
    PolicyTable,
    Service,
    SystemModel,
    hookimpl,
    option,
    positive,
    probability,
)
from parley_plugins.robot_grid import grid as grids
from parley_plugins.robot_grid.events import SLIP
from parley_plugins.robot_grid.generator import prism_model
from parley_plugins.robot_grid.planner import complete, plan


@frozen(kw_only=True)
class RobotGridOptions:
    map: Path | None = option(None, "CSV map in the paper's package format; default: generate one")
    size: int = option(10, "side of a generated map", validators.ge(2))
    seed: int = option(0, "seed of a generated map")
    p: float = option(
        0.01,
        "probability that a move deviates to each of the three other directions",
        validators.ge(0.0),
        validators.le(1 / 3),
    )
    horizon: int = option(100, "steps of the cost objective C<=horizon (a move is 3 steps)", positive)
    max_interval: int = option(10, "largest localisation interval (moves)", positive)
    move_cost: float = option(1.0, "cost of a move", validators.ge(0.0))
    localisation_cost: float = option(5.0, "cost of a localisation", validators.ge(0.0))
    loc_error: float = option(
        0.0,
        "probability that a localisation puts the estimate on one of the true cell's 4-neighbors "
        "inside the map (equally likely) instead of the true cell",
        probability,
    )


def build(options: RobotGridOptions) -> SystemModel:
    grid = grids.load_csv(options.map) if options.map is not None else grids.generate(options.size, options.seed)
    moves = plan(grid) if options.loc_error == 0 else complete(grid, plan(grid))
    text = prism_model(
        grid,
        moves,
        p=options.p,
        max_interval=options.max_interval,
        move_cost=options.move_cost,
        localisation_cost=options.localisation_cost,
        loc_error=options.loc_error,
    )
    return SystemModel(
        name="robot_grid",
        description=f"robot on {grid.width}x{grid.height} map {grid.source}",
        prism=text,
        services=[
            Service(
                name="localisation",
                constant="c",
                kind=DecisionKind.FREQUENCY,
                low=1,
                high=options.max_interval,
                description="localise once the move counter reaches c (every c-th move)",
            )
        ],
        observation=("xhat", "yhat"),
        objectives=[
            Objective(
                name="success",
                formula='P=? [F "goal"]',
                direction=Direction.MAX,
                description="probability of reaching the target without crashing",
                reference=0.0,
            ),
            Objective(
                name="cost",
                formula=f'R{{"cost"}}=? [C<={options.horizon}]',
                direction=Direction.MIN,
                description=f"expected cost of moves and localisations within {options.horizon} steps",
            ),
        ],
        baselines=Baseline.sweep("c", range(1, options.max_interval + 1), "interval-{}"),
        context=(grid, moves),
    )


def plot_policy(system: SystemModel, table: PolicyTable, path: Path) -> None:
    from parley_plugins.robot_grid.plot import draw_policy

    grid, moves = system.context
    draw_policy(grid, moves, table.values_of("c"), path)


def policy_map(system: SystemModel) -> PolicyMap:
    grid, _moves = system.context
    return PolicyMap(
        x="xhat",
        y="yhat",
        width=grid.width,
        height=grid.height,
        blocked=grid.obstacles(),
        marks=[("S", *grid.start), ("T", *grid.target)],
    )


CASE_STUDY = CaseStudy(
    name="robot_grid",
    description="Robot on a grid map: when to localise, per estimated cell (the paper's running example)",
    options_type=RobotGridOptions,
    build=build,
    plot_policy=plot_policy,
    policy_map=policy_map,
    events={"p": SLIP},
    quick={"size": "5", "seed": "1", "horizon": "45", "max_interval": "4"},
    # the paper's nine requirement settings: min success x max cost
    requirement_settings=[(s, c) for s in (0.6, 0.7, 0.8) for c in (60, 80, 100)],
    figure_setting=(0.7, 80),  # the paper's Fig. 4
)


@hookimpl
def parley_case_studies() -> list[CaseStudy]:
    return [CASE_STUDY]
