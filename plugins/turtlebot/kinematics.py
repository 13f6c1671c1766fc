"""A motion table of its own: Monte Carlo of a differential-drive robot with a weak left wheel.

The paper sampled its motion table from Gazebo runs of a TurtleBot3 Waffle; those samples
are only published inside its PRISM model (read it with ``model=...``, see
:mod:`parley_plugins.turtlebot.published`). Without it, this module estimates the table from
a kinematic model, deterministically (a seeded generator):

- the robot starts a move anywhere in its cell (uniformly, ``margin`` metres from the edges),
  its heading the cell's heading plus Gaussian noise (``heading_noise`` degrees);
- it turns on the spot to the commanded heading; the turn errs by Gaussian noise growing
  with the angle turned (``turn_noise`` degrees per quarter turn) on top of the heading noise;
- it drives one cell length (Gaussian length error, ``distance_noise`` relative); the left
  wheel runs at ``left_wheel`` of the right one's speed, so the path is an arc curving left
  with curvature ``2 (1 - left_wheel) / (wheel_base (1 + left_wheel))`` per metre;
- the move crashes if its path meets an obstacle cell, and leaves the area if its path
  crosses the border (whichever comes first along the path); otherwise it ends in the cell
  where the path ends, with the heading (of four) nearest to its final direction.

Each (cell, heading, command) gets ``samples`` draws; probabilities are counts / samples.
"""

from __future__ import annotations

import math

import numpy as np

from parley_plugins.turtlebot.world import ANGLE, HEADINGS, Cell, Motions, Outcome, decode

PATH_POINTS = 15
"""Points per path at which obstacles and the border are checked (one every 20 cm for 3 m cells)."""


def simulate(
    size: int,
    obstacles: frozenset[Cell],
    *,
    cell_length: float = 3.0,
    left_wheel: float = 0.99,
    wheel_base: float = 0.287,
    heading_noise: float = 8.0,
    turn_noise: float = 5.0,
    distance_noise: float = 0.05,
    margin: float = 0.3,
    samples: int = 1000,
    seed: int = 0,
) -> Motions:
    """The motion table for every free cell, true heading and commanded move."""
    rng = np.random.default_rng(seed)
    curvature = 2.0 * (1.0 - left_wheel) / (wheel_base * (1.0 + left_wheel))
    fraction = np.linspace(0.0, 1.0, PATH_POINTS + 1)[1:]
    extent = size * cell_length
    blocked = np.zeros((size, size), dtype=bool)
    for ox, oy in obstacles:
        blocked[ox, oy] = True
    motions: dict = {}
    for x in range(size):
        for y in range(size):
            if (x, y) in obstacles:
                continue
            for heading, heading_name in enumerate(HEADINGS):
                for command in HEADINGS:
                    start = np.column_stack(
                        [
                            (c + rng.uniform(margin, cell_length - margin, samples) / cell_length) * cell_length
                            for c in (x, y)
                        ]
                    )
                    facing = ANGLE[heading_name] + rng.normal(0.0, math.radians(heading_noise), samples)
                    turned = np.abs(np.angle(np.exp(1j * (ANGLE[command] - facing))))
                    spread = math.radians(heading_noise) + math.radians(turn_noise) * turned / (math.pi / 2)
                    theta = ANGLE[command] + rng.normal(0.0, 1.0, samples) * spread
                    length = cell_length * (1.0 + rng.normal(0.0, distance_noise, samples))
                    s = length[:, None] * fraction[None, :]
                    px, py = _arc(start, theta, s, curvature)
                    outcomes = _classify(px, py, theta + curvature * length, (x, y), blocked, cell_length, extent)
                    motions[(x, y, heading, command)] = _distribution(outcomes, samples)
    return motions


def _arc(start: np.ndarray, theta: np.ndarray, s: np.ndarray, curvature: float) -> tuple[np.ndarray, np.ndarray]:
    """Points at arc lengths ``s`` along arcs from ``start`` with initial direction ``theta``."""
    t = theta[:, None]
    if abs(curvature) < 1e-12:
        return start[:, :1] + s * np.cos(t), start[:, 1:] + s * np.sin(t)
    turn = t + curvature * s
    return (
        start[:, :1] + (np.sin(turn) - np.sin(t)) / curvature,
        start[:, 1:] - (np.cos(turn) - np.cos(t)) / curvature,
    )


def _classify(px, py, final_theta, cell: Cell, obstacles: np.ndarray, cell_length: float, extent: float):
    """Each draw's outcome as a code: -2 crash, -1 out, else ``((dx + 2) * 5 + dy + 2) * 4 + heading``.

    ``obstacles[x, y]`` is true for obstacle cells."""
    outside = (px < 0.0) | (py < 0.0) | (px >= extent) | (py >= extent)
    cx = np.floor(px / cell_length).astype(int)
    cy = np.floor(py / cell_length).astype(int)
    blocked = obstacles[np.clip(cx, 0, obstacles.shape[0] - 1), np.clip(cy, 0, obstacles.shape[1] - 1)] & ~outside
    points = px.shape[1]
    first_out = np.where(outside.any(axis=1), outside.argmax(axis=1), points)
    first_crash = np.where(blocked.any(axis=1), blocked.argmax(axis=1), points)
    quarter = np.rint(final_theta / (math.pi / 2)).astype(int) % 4  # 0 east, 1 north, 2 west, 3 south
    heading = np.array([1, 0, 3, 2])[quarter]
    dx = np.clip(cx[:, -1] - cell[0], -2, 2)
    dy = np.clip(cy[:, -1] - cell[1], -2, 2)
    code = ((dx + 2) * 5 + dy + 2) * 4 + heading
    code = np.where(first_out < points, -1, code)
    return np.where(first_crash < first_out, -2, code)


def _distribution(codes: np.ndarray, samples: int) -> tuple[tuple[Outcome, float], ...]:
    values, counts = np.unique(codes, return_counts=True)
    return tuple((decode(value), count / samples) for value, count in zip(values.tolist(), counts.tolist()))
