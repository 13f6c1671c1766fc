"""turtlebot: the paper's continuous robot (RQ4), a TurtleBot3 Waffle with a weak left wheel.

A robot crosses a 21 m x 21 m area of 3 m cells (7x7) to a target, past obstacles, by a
shortest-path movement controller that acts on its *estimated* cell; it has no sensors, and
its heading (four directions) is uncertain too: the left wheel runs at 99 % power, so the
robot drifts. A localisation service (energy 5, a move costs 1) sets the estimated cell and
heading to the true ones. The URC decides, per estimated cell and heading, after how many
moves to localise (1..5). The motion table comes from the paper's Gazebo samples (option
``model``: its ``models/turtlebot/model.prism``) or, by default, from a kinematic Monte
Carlo of its own. With ``loc_error`` > 0 the localisation errs: it puts the estimated cell
on a 4-neighbor of the true cell (the heading stays exact). Details and the comparison with
the paper: docs/turtlebot.md.
"""

from __future__ import annotations

from pathlib import Path

import attrs
from attrs import frozen, validators

from parley_core import (
    Baseline,
    CaseStudy,
    DecisionKind,
    Direction,
    Objective,
    OptionError,
    PolicyMap,
    PolicyTable,
    Reporter,
    Service,
    Simulator,
    SystemModel,
    hookimpl,
    option,
    positive,
    probability,
)
from parley_plugins.turtlebot import closed_loop, published
from parley_plugins.turtlebot.generator import prism_model
from parley_plugins.turtlebot.kinematics import simulate
from parley_plugins.turtlebot.physics import Physics
from parley_plugins.turtlebot.sampling import Sampling, cached, counts, motions_of, progress_units
from parley_plugins.turtlebot.world import World, check, complete, shortest_moves

PAPER_OBSTACLES = ((0, 3), (0, 4), (0, 5), (1, 3), (2, 3), (3, 3), (4, 0), (4, 1), (5, 1), (4, 4), (4, 6), (5, 6))
"""The cells where the paper's sampled motions crash (and which its model gives no motions)."""


_fraction = [validators.gt(0.0), validators.le(1.0)]


@frozen(kw_only=True)
class TurtlebotOptions:
    model: Path | None = option(
        None,
        "the paper's models/turtlebot/model.prism: use its Gazebo-sampled motions and controller; default: simulate",
    )
    motions: str = option(
        "kinematic",
        "how to simulate motions: kinematic (an arc per move, 0.4 s) or mujoco (the Waffle in MuJoCo; "
        "about a minute the first time, then cached)",
        validators.in_(("kinematic", "mujoco")),
    )
    repair: bool = option(True, "with model=: read its south moves as meant (the file sends them to the top row)")
    size: int = option(7, "cells per side (simulated motions)", validators.ge(2))
    start: tuple[int, int] = option((1, 0), "start cell X:Y (simulated motions)")
    target: tuple[int, int] = option((3, 5), "target cell X:Y (simulated motions)")
    obstacles: tuple[tuple[int, int], ...] = option(PAPER_OBSTACLES, "obstacle cells X:Y,X:Y,... (simulated motions)")
    left_wheel: float = option(0.99, "left wheel power relative to the right one", _fraction)
    margin: float = option(
        0.3,
        "a move starts at least this far (m) from its cell's edges; 1.5: at the centre",
        validators.ge(0.0),
        validators.le(1.5),
    )
    heading_noise: float = option(8.0, "heading error, standard deviation in degrees", validators.ge(0.0))
    turn_noise: float = option(5.0, "kinematic: extra heading error per quarter turn, degrees", validators.ge(0.0))
    distance_noise: float = option(
        0.05, "kinematic: error of a move's length, relative standard deviation", validators.ge(0.0)
    )
    wheel_noise: float = option(0.01, "mujoco: each wheel's speed error in a move, relative", validators.ge(0.0))
    friction: tuple[float, float] = option((0.7, 1.0), "mujoco: range LOW:HIGH of the floor's friction, drawn per move")
    speed: float = option(0.22, "mujoco: driving speed, m/s (the Waffle's maximum is 0.26)", positive)
    timestep: float = option(0.025, "mujoco: seconds per physics step", positive)
    heading_memory: bool = option(
        False,
        "mujoco: motions by the believed heading and the moves since the last localisation, "
        "over which the heading error adds up (see docs/turtlebot.md)",
    )
    samples: int = option(1000, "Monte Carlo draws per cell, heading and move", positive)
    motion_seed: int = option(0, "seed of the Monte Carlo draws of the motions (the search has its own, --seed)")
    max_period: int = option(5, "longest localisation period (moves)", positive)
    horizon: int = option(200, "steps of the energy objective C<=horizon (a move is 3 steps)", positive)
    move_cost: float = option(1.0, "energy of a move", validators.ge(0.0))
    localisation_cost: float = option(5.0, "energy of a localisation", validators.ge(0.0))
    loc_error: float = option(
        0.0,
        "probability that a localisation puts the estimated cell on one of the true cell's 4-neighbors "
        "inside the area (equally likely) instead of the true cell; the heading is always exact",
        probability,
    )


SIMULATION_OPTIONS = (
    "motions",
    "size",
    "start",
    "target",
    "obstacles",
    "left_wheel",
    "margin",
    "heading_noise",
    "turn_noise",
    "distance_noise",
    "samples",
    "motion_seed",
    "wheel_noise",
    "friction",
    "speed",
    "timestep",
    "heading_memory",
)
"""The options that shape simulated motions; the paper's model file fixes all of them."""

ONLY = {
    "kinematic": ("wheel_noise", "friction", "speed", "timestep", "heading_memory"),
    "mujoco": ("turn_noise", "distance_noise"),
}
"""The options each kind of simulated motions does not use (changing one is an error)."""


def world_of(options: TurtlebotOptions) -> World:
    defaults = {f.name: f.default for f in attrs.fields(TurtlebotOptions)}
    if options.model is not None:
        changed = [name for name in SIMULATION_OPTIONS if getattr(options, name) != defaults[name]]
        if changed:
            raise OptionError(
                f"option {changed[0]} shapes simulated motions, but model= gives the paper's; drop one of them"
            )
        return check(published.load(options.model, repair=options.repair))
    start, target, obstacles = options.start, options.target, frozenset(options.obstacles)
    world = World(
        size=options.size,
        start=start,
        target=target,
        obstacles=obstacles,
        motions={},
        plan={},
        source=f"simulated, left wheel {options.left_wheel:g}, motion seed {options.motion_seed}",
    )
    check(world)
    for name in ONLY[options.motions]:
        if getattr(options, name) != defaults[name]:
            raise OptionError(
                f"option {name} does not apply to motions={options.motions}; drop it or set motions="
                + ("mujoco" if options.motions == "kinematic" else "kinematic")
            )
    if options.motions == "mujoco":
        sampling = sampling_of(options)
        world = attrs.evolve(
            world, source=f"MuJoCo, left wheel {options.left_wheel:g}, motion seed {options.motion_seed}"
        )
        table = motions_of(counts(sampling), sampling.samples)
        plan = shortest_moves(options.size, obstacles, target)
        if sampling.memory:
            return check(attrs.evolve(world, motions={}, remembered=table, plan=plan))
        return check(attrs.evolve(world, motions=table, plan=plan))
    motions = simulate(
        options.size,
        obstacles,
        left_wheel=options.left_wheel,
        heading_noise=options.heading_noise,
        turn_noise=options.turn_noise,
        distance_noise=options.distance_noise,
        margin=options.margin,
        samples=options.samples,
        seed=options.motion_seed,
    )
    return check(attrs.evolve(world, motions=motions, plan=shortest_moves(options.size, obstacles, target)))


def physics_of(options: TurtlebotOptions) -> Physics:
    """The MuJoCo robot's physics that ``options`` set."""
    friction = options.friction
    if not 0 < friction[0] <= friction[1]:
        raise OptionError(
            f"option friction={friction[0]:g}:{friction[1]:g}: give LOW:HIGH with 0 < LOW <= HIGH, e.g. 0.7:1.0"
        )
    return Physics(
        left_wheel=options.left_wheel,
        speed=options.speed,
        wheel_noise=options.wheel_noise,
        friction=friction,
        timestep=options.timestep,
    )


def sampling_of(options: TurtlebotOptions) -> Sampling:
    """What the MuJoCo motion table of ``options`` depends on."""
    return Sampling(
        size=options.size,
        obstacles=tuple(sorted(set(options.obstacles))),
        physics=physics_of(options),
        heading_noise=options.heading_noise,
        margin=options.margin,
        samples=options.samples,
        seed=options.motion_seed,
        memory=options.max_period if options.heading_memory else 0,
    )


def warm_up(options: TurtlebotOptions, reporter: Reporter) -> None:
    """Sample the MuJoCo motion table with a progress bar, unless it is cached."""
    if options.model is not None or options.motions != "mujoco":
        return
    sampling = sampling_of(options)
    if cached(sampling) is None:
        reporter.stage("sample motions in MuJoCo", progress_units(sampling))
        counts(sampling, reporter.advance)


def build(options: TurtlebotOptions) -> SystemModel:
    world = world_of(options)
    if options.loc_error > 0:  # an erring localisation may put the estimate on any cell
        world = attrs.evolve(world, plan=complete(world.plan, world.size, world.target))
    text = prism_model(
        world,
        max_period=options.max_period,
        move_cost=options.move_cost,
        localisation_cost=options.localisation_cost,
        loc_error=options.loc_error,
    )
    return SystemModel(
        name="turtlebot",
        description=f"turtlebot on {world.size}x{world.size} cells, motions {world.source}",
        prism=text,
        services=[
            Service(
                name="localisation",
                constant="c",
                kind=DecisionKind.FREQUENCY,
                low=1,
                high=options.max_period,
                description="localise once the move counter reaches c (every c-th move)",
            )
        ],
        observation=("xhat", "yhat", "directionhat"),
        objectives=[
            Objective(
                name="success",
                formula='P=? [F "goal"]',
                direction=Direction.MAX,
                description="probability of reaching the target without crashing or leaving the area",
                reference=0.0,
            ),
            Objective(
                name="energy",
                formula=f'R{{"energy"}}=? [C<={options.horizon}]',
                direction=Direction.MIN,
                description=f"expected energy of moves and localisations within {options.horizon} steps",
            ),
        ],
        baselines=Baseline.sweep("c", range(1, options.max_period + 1), "period-{}"),
        context=world,
    )


def plot_policy(system: SystemModel, table: PolicyTable, path: Path) -> None:
    from parley_plugins.turtlebot.plot import draw_policy

    draw_policy(system.context, table.values_of("c"), path)


def policy_map(system: SystemModel) -> PolicyMap:
    world = system.context
    return PolicyMap(
        x="xhat",
        y="yhat",
        width=world.size,
        height=world.size,
        blocked=sorted(world.obstacles),
        marks=[("S", *world.start), ("T", *world.target)],
    )


CASE_STUDY = CaseStudy(
    name="turtlebot",
    description="TurtleBot3 with a drifting wheel: when to localise, per estimated cell and heading (the paper's RQ4)",
    options_type=TurtlebotOptions,
    build=build,
    warm_up=warm_up,
    simulator=Simulator(
        description="the TurtleBot3 Waffle in MuJoCo, closed loop",
        run=closed_loop.simulate,
        draw=closed_loop.draw,
    ),
    plot_policy=plot_policy,
    policy_map=policy_map,
    quick={"samples": "100", "horizon": "60", "max_period": "3"},
    # 160 of the 196 (xhat, yhat, directionhat) valuations are never consulted: after a move,
    # directionhat is always the heading of that move
    prune=True,
    # campaign reports: no requirement, a cheap one, a demanding one (success >=, energy <=);
    # they suit both the paper's motions (success up to 0.25) and the simulated ones (0.63)
    requirement_settings=[(0.0, 50.0), (0.1, 20.0), (0.2, 30.0)],
)


@hookimpl
def parley_case_studies() -> list[CaseStudy]:
    return [CASE_STUDY]
