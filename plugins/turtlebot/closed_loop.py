"""The URC and the movement controller in closed loop on the MuJoCo robot (``parley validate``).

Each episode starts the robot at a random pose in the start cell (uniform, ``margin`` from
the edges, facing north with the heading noise), believing it is at the start cell's
centre facing north, as the DTMC starts. Then, move after move, as the DTMC's three steps
per move do:

1. the movement controller takes the move of the *estimated* cell (none once the estimate
   is the target: the episode ends) and MuJoCo drives it from the robot's true pose, open
   loop from the believed yaw: it turns by the angle from the believed yaw to the move's
   heading and drives one cell length (:class:`~parley_plugins.turtlebot.physics.Robot`);
   the move costs ``move_cost``; the estimate moves as if the move went as commanded, and
   the believed yaw becomes the move's heading;
2. the URC decides the localisation period for the estimate (cell and the move's heading);
   once the move counter reaches it, the localisation service reads the simulator's true
   pose into the estimate at ``localisation_cost``: its cell and the nearest of the four
   headings for the DTMC's variables, and for the next turn the yaw, with a Gaussian error
   of ``heading_noise`` degrees (the start pose's yaw has the same error); with
   ``loc_error`` > 0 it reads the cell wrong as the DTMC's localisation does
   (:func:`misread`), the heading and yaw as before; so a
   localisation also corrects the heading error that the weak wheel accumulates; a decision at a valuation the URC was not synthesized for (a
   cell the model never reaches) localises, and the episode's notes count it;
3. a crash (the chassis touched an obstacle) or leaving the area ends the episode, after
   that move's localisation decision (which the DTMC also takes and pays for).

Success is ending a move in the target cell without having crashed or left (the DTMC's
``goal``, which holds at the end of a move), at any time (``F "goal"`` has no bound; an
episode that has not ended after ``max_moves`` is cut and counts as failed); energy counts
what was spent within the energy objective's horizon (move ``k`` is step ``3k`` of the
DTMC, its decision step ``3k + 1``). Episodes run in lockstep, one MuJoCo rollout per round
of moves.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from attrs import frozen

from parley_core import URC, Episodes, ObservationError, SystemModel
from parley_plugins.turtlebot.physics import CELL, Physics, Robot
from parley_plugins.turtlebot.world import ANGLE, HEADINGS, STEP, World, heading_of

TRACED = 40
"""Episodes whose paths are kept for the plot."""


@frozen(kw_only=True)
class Trace:
    """The paths of the first :data:`TRACED` episodes (x, y in metres, one array per
    episode) and how each ended."""

    paths: tuple[np.ndarray, ...]
    endings: tuple[str, ...]


def run_episodes(
    world: World,
    physics: Physics,
    urc: URC,
    episodes: int,
    seed: int,
    *,
    horizon: int,
    move_cost: float,
    localisation_cost: float,
    heading_noise: float = 8.0,
    margin: float = 0.3,
    max_moves: int = 1000,
    loc_error: float = 0.0,
    progress=None,
) -> Episodes:
    rng = np.random.default_rng(seed)
    n = episodes
    sx, sy = world.start
    pose = np.column_stack(
        [
            (sx + rng.uniform(margin / CELL, 1 - margin / CELL, n)) * CELL,
            (sy + rng.uniform(margin / CELL, 1 - margin / CELL, n)) * CELL,
            ANGLE["north"] + rng.normal(0.0, math.radians(heading_noise), n),
        ]
    )
    estimate = np.tile([sx, sy, 0], (n, 1))  # xhat, yhat, directionhat (north)
    believed = np.full(n, ANGLE["north"])  # the yaw the UAC believes the robot has
    step = np.ones(n, dtype=int)
    energy = np.zeros(n)
    success = np.zeros(n, dtype=bool)
    done = np.zeros(n, dtype=bool)
    endings = np.full(n, "horizon", dtype=object)
    traced = min(n, TRACED)
    paths: list[list[np.ndarray]] = [[pose[i, :2].copy()] for i in range(traced)]
    unplanned = 0
    plan = {cell: HEADINGS.index(move) for cell, move in world.plan.items()}
    target = world.target
    reported = 0
    with Robot(world.size, world.obstacles, physics) as robot:
        for k in range(max_moves):
            if progress and int(done.sum()) > reported:
                progress(int(done.sum()) - reported)
                reported = int(done.sum())
            at_target = (estimate[:, 0] == target[0]) & (estimate[:, 1] == target[1])
            stopping = ~done & at_target
            endings[stopping] = np.where(success[stopping], "target", "believed at target")
            done |= stopping
            active = np.flatnonzero(~done)
            if not len(active):
                break
            command = np.array([plan.get((int(estimate[i, 0]), int(estimate[i, 1])), -1) for i in active])
            if (command < 0).any():  # an estimated cell without a move (cannot reach the target)
                stuck = active[command < 0]
                endings[stuck] = "no move"
                done[stuck] = True
                active, command = active[command >= 0], command[command >= 0]
                if not len(active):
                    break
            heading_yaw = math.pi / 2 - command * (math.pi / 2)  # 0 north -> pi/2, 1 east -> 0, ...
            controls = robot.controls(heading_yaw - believed[active], rng)
            keep = int(np.sum(active < traced))  # the traced episodes lead: active is sorted
            moved = robot.run(pose[active], controls, robot.frictions(rng, len(active)), keep_paths=keep)
            pose[active] = moved.poses
            if 3 * k < horizon:
                energy[active] += move_cost
            cell_x = np.floor(moved.poses[:, 0] / CELL).astype(int)
            cell_y = np.floor(moved.poses[:, 1] / CELL).astype(int)
            failed = moved.crashed | moved.out
            success[active] |= ~failed & (cell_x == target[0]) & (cell_y == target[1])
            dx = np.array([STEP[HEADINGS[c]][0] for c in command])
            dy = np.array([STEP[HEADINGS[c]][1] for c in command])
            top = world.size - 1
            estimate[active, 0] = np.clip(estimate[active, 0] + dx, 0, top)
            estimate[active, 1] = np.clip(estimate[active, 1] + dy, 0, top)
            estimate[active, 2] = command
            believed[active] = heading_yaw
            # the URC's decision for the estimate after the move
            period = np.empty(len(active), dtype=int)
            for j, i in enumerate(active):
                try:
                    period[j] = urc.decide(tuple(int(v) for v in estimate[i]))["c"]
                except ObservationError:
                    period[j] = 1
                    unplanned += 1
            localise = step[active] >= period
            if 3 * k + 1 < horizon:
                energy[active[localise]] += localisation_cost
            true_heading = heading_of(moved.poses[:, 2])
            chosen = active[localise]
            read = misread(np.column_stack([cell_x[localise], cell_y[localise]]), loc_error, world.size, rng)
            estimate[chosen, 0] = read[:, 0]
            estimate[chosen, 1] = read[:, 1]
            estimate[chosen, 2] = true_heading[localise]
            believed[chosen] = moved.poses[localise, 2] + rng.normal(0.0, math.radians(heading_noise), len(chosen))
            step[chosen] = 1
            step[active[~localise]] += 1
            endings[active[moved.crashed]] = "crashed"
            endings[active[moved.out]] = "left the area"
            done[active[failed]] = True
            if moved.paths is not None:
                for j, i in enumerate(active[:keep]):
                    paths[i].append(moved.paths[j, ::10, :2])
    if progress and n > reported:
        progress(n - reported)
    notes = []
    cut = int((~done).sum())
    if cut:
        notes.append(f"{cut} episodes were cut after {max_moves} moves (counted as not reaching the target)")
    if unplanned:
        notes.append(
            f"{unplanned} decisions at estimates the URC was not synthesized for (the model never reaches them): "
            "localised there"
        )
    return Episodes(
        values={"success": success.astype(float), "energy": energy},
        notes=tuple(notes),
        trace=Trace(paths=tuple(np.vstack(p) for p in paths), endings=tuple(str(e) for e in endings[:traced])),
    )


def misread(cells: np.ndarray, loc_error: float, size: int, rng: np.random.Generator) -> np.ndarray:
    """The cells a localisation reports for the true ``cells`` (rows x, y): each, with
    probability ``loc_error``, one of its 4-neighbors inside the square instead (equally
    likely), as the DTMC's erring localisation. Draws nothing when ``loc_error`` is 0, so
    that the episodes are those of an exact localisation. A cell outside the square (the
    robot left it; the episode ends) has no such neighbor and is kept."""
    if loc_error == 0 or not len(cells):
        return cells
    read = cells.copy()
    for i in np.flatnonzero(rng.random(len(cells)) < loc_error):
        x, y = (int(v) for v in cells[i])
        around = [(x + dx, y + dy) for dx, dy in _AROUND if 0 <= x + dx < size and 0 <= y + dy < size]
        if around and 0 <= x < size and 0 <= y < size:
            read[i] = around[rng.integers(len(around))]
    return read


_AROUND = (STEP["east"], STEP["north"], STEP["south"], STEP["west"])


def simulate(system: SystemModel, options: Any, urc: URC, episodes: int, seed: int, progress=None) -> Episodes:
    """The closed loop of a turtlebot run (its world, its options' physics and costs)."""
    from parley_plugins.turtlebot import physics_of

    world = system.context
    return run_episodes(
        world,
        physics_of(options),
        urc,
        episodes,
        seed,
        horizon=options.horizon,
        move_cost=options.move_cost,
        localisation_cost=options.localisation_cost,
        heading_noise=options.heading_noise,
        margin=options.margin,
        loc_error=options.loc_error,
        progress=progress,
    )


def draw(system: SystemModel, episodes: Episodes, ax) -> None:
    """The traced episodes from above on the map: obstacles, start and target, each path
    coloured by how it ended."""
    from matplotlib.patches import Rectangle

    world: World = system.context
    for x, y in world.obstacles:
        ax.add_patch(Rectangle((x * CELL, y * CELL), CELL, CELL, color="0.2"))
    for (x, y), colour in ((world.start, "tab:blue"), (world.target, "tab:green")):
        ax.add_patch(Rectangle((x * CELL, y * CELL), CELL, CELL, fill=False, edgecolor=colour, lw=2))
    colours = {"target": "tab:green", "crashed": "crimson", "left the area": "darkorange"}
    trace: Trace = episodes.trace
    for path, ending in zip(trace.paths, trace.endings):
        ax.plot(path[:, 0], path[:, 1], color=colours.get(ending, "0.5"), lw=0.8, alpha=0.7)
    extent = world.size * CELL
    ax.set_xlim(0, extent)
    ax.set_ylim(0, extent)
    ax.set_aspect("equal")
    ax.set_xticks(np.arange(0, extent + 0.1, CELL))
    ax.set_yticks(np.arange(0, extent + 0.1, CELL))
    ax.grid(alpha=0.3)
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")
