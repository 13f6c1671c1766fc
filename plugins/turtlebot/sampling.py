"""Motions from physics: the motion table sampled from the MuJoCo robot, as the paper sampled Gazebo.

For every free cell, true heading and commanded move, ``samples`` moves start from random
poses in the cell (uniform, ``margin`` metres from its edges; the yaw the heading's plus
Gaussian noise of ``heading_noise`` degrees) and are driven open loop by the UAC's move
(:mod:`parley_plugins.turtlebot.physics`): it believes it faces the true heading, turns to
the commanded one and drives one cell length. A move crashes when the chassis touches an
obstacle and leaves the area when the robot's centre crosses the border, whichever comes
first; otherwise it ends in the cell where it stops, with the heading (of four) nearest to
its yaw. The table's probabilities are counts / samples; the counts are kept.

How it is computed: the floor is flat and the same everywhere, and every move starts from
rest, so a move's trajectory relative to its start pose depends only on the angle it turns
(0, 90 degrees left or right, 180), the wheels' noise and the floor's friction, not on
where it starts. MuJoCo therefore drives ``samples`` moves per turning angle once, in an
empty world (:func:`trajectories`), and each (cell, heading, move) places them at its own
random start poses, rotated to its heading; the chassis' footprint along the path is then
tested against the obstacle boxes (:func:`classify`). That is what MuJoCo's contact of the
chassis box with an obstacle box would report (until the first contact the two worlds are
the same): ``tests/test_physics.py`` drives moves in the world with obstacles and compares
the touch sensor's verdict with this one. The trajectories of one turning angle are shared
by all cells (each with its own start poses), so the table's entries are not independent
of each other; each entry's distribution is still that of ``samples`` physical moves.

The table is cached on disk (:func:`cache_directory`), keyed by everything that determines
it, so a second run is instant.
"""

from __future__ import annotations

import hashlib
import json
import math
import os
from collections.abc import Callable, Iterable
from pathlib import Path

import numpy as np
from attrs import asdict, frozen

from parley_plugins.turtlebot.physics import CELL, Physics, Robot, Waffle
from parley_plugins.turtlebot.world import ANGLE, HEADINGS, Cell, Outcome, decode, heading_of

TURNS = (0.0, math.pi / 2, -math.pi / 2, math.pi)
"""The angles a move can turn by (counter-clockwise): straight on, left, right, about."""

CHECK_EVERY = 2
"""The footprint is tested at every second step of a path (1.1 cm at 0.22 m/s and 25 ms)."""

VERSION = 2
"""Bumped when the simulation changes, so that cached tables are recomputed."""


@frozen(kw_only=True)
class Sampling:
    """Everything the table depends on."""

    size: int
    obstacles: tuple[Cell, ...]
    physics: Physics
    robot: Waffle = Waffle()
    heading_noise: float = 8.0
    margin: float = 0.3
    samples: int = 1000
    seed: int = 0
    memory: int = 0
    """With heading memory: the longest localisation period; the table is then sampled per
    believed heading and per number of moves since the last localisation, 1..memory
    (:func:`sample`). 0: the paper's table, per true heading."""

    def key(self) -> str:
        import mujoco

        data = asdict(self, recurse=True)
        data["obstacles"] = sorted(list(c) for c in self.obstacles)
        data["version"] = VERSION
        data["mujoco"] = mujoco.__version__
        text = json.dumps(data, sort_keys=True, default=list)
        return hashlib.sha256(text.encode()).hexdigest()[:20]


@frozen(kw_only=True)
class Trajectories:
    """Per turning angle, ``samples`` paths relative to a start at the origin facing east:
    ``paths[turn]`` is ``[samples, points, 3]`` (x, y, yaw) at every :data:`CHECK_EVERY`-th
    step and the last one."""

    paths: dict[float, np.ndarray]


def trajectories(
    sampling: Sampling, rng: np.random.Generator, progress: Callable[[int], None] | None = None
) -> Trajectories:
    """MuJoCo drives ``samples`` moves per turning angle in a world without obstacles."""
    paths = {}
    with Robot(sampling.size + 4, (), sampling.physics, sampling.robot) as robot:
        origin = 2 * CELL  # far from the (unused) border
        for turn in TURNS:
            controls = robot.controls(np.full(sampling.samples, turn), rng)
            starts = np.tile([origin, origin, 0.0], (sampling.samples, 1))
            moves = robot.run(starts, controls, robot.frictions(rng, sampling.samples), keep_paths=True)
            assert moves.paths is not None
            paths[turn] = relative(moves.paths, origin)
            if progress:
                progress(1)
    return Trajectories(paths=paths)


def relative(paths: np.ndarray, origin: float) -> np.ndarray:
    """Paths ``[n, steps, 3]`` that started at (origin, origin) facing east, relative to their
    start, at every :data:`CHECK_EVERY`-th step and the last."""
    index = np.unique(np.r_[np.arange(0, paths.shape[1], CHECK_EVERY), paths.shape[1] - 1])
    out = paths[:, index].copy()
    out[:, :, :2] -= origin
    return out


def classify(
    paths: np.ndarray, starts: np.ndarray, cell: Cell, size: int, obstacles: Iterable[Cell], robot: Waffle
) -> np.ndarray:
    """Outcome codes (as :func:`parley_plugins.turtlebot.kinematics` makes them: -2 crash, -1
    out, else ``((dx + 2) * 5 + dy + 2) * 4 + heading``) of ``paths`` ``[n, points, 3]``
    relative to the origin facing east, placed at ``starts`` ``[n, 3]`` (x, y, yaw)."""
    c, s = np.cos(starts[:, 2])[:, None], np.sin(starts[:, 2])[:, None]
    x = starts[:, :1] + c * paths[:, :, 0] - s * paths[:, :, 1]
    y = starts[:, 1:2] + s * paths[:, :, 0] + c * paths[:, :, 1]
    yaw = starts[:, 2:3] + paths[:, :, 2]
    extent = size * CELL
    points = x.shape[1]
    outside = (x < 0.0) | (y < 0.0) | (x >= extent) | (y >= extent)
    first_out = np.where(outside.any(axis=1), outside.argmax(axis=1), points)
    hit = np.zeros_like(outside)
    near = [o for o in obstacles if abs(o[0] - cell[0]) <= 2 and abs(o[1] - cell[1]) <= 2]
    if near:
        cos, sin = np.cos(yaw), np.sin(yaw)
        # the chassis box: centred base_offset ahead of the axle, half extents a (along) and b
        cx = x + robot.base_offset * cos
        cy = y + robot.base_offset * sin
        a, b, h = robot.length / 2, robot.width / 2, CELL / 2
        ac, as_ = np.abs(cos), np.abs(sin)
        for ox, oy in near:
            dx = cx - (ox + 0.5) * CELL
            dy = cy - (oy + 0.5) * CELL
            overlap = (np.abs(dx) <= h + a * ac + b * as_) & (np.abs(dy) <= h + a * as_ + b * ac)
            overlap &= np.abs(dx * cos + dy * sin) <= a + h * (ac + as_)
            overlap &= np.abs(-dx * sin + dy * cos) <= b + h * (as_ + ac)
            hit |= overlap
    first_crash = np.where(hit.any(axis=1), hit.argmax(axis=1), points)
    heading = heading_of(yaw[:, -1])
    dx_cell = np.clip(np.floor(x[:, -1] / CELL).astype(int) - cell[0], -2, 2)
    dy_cell = np.clip(np.floor(y[:, -1] / CELL).astype(int) - cell[1], -2, 2)
    code = ((dx_cell + 2) * 5 + dy_cell + 2) * 4 + heading
    code = np.where(first_out < points, -1, code)
    return np.where(first_crash < first_out, -2, code)


def sample(sampling: Sampling, progress: Callable[[int], None] | None = None) -> dict[tuple, dict[int, int]]:
    """The counts of outcome codes per (x, y, true heading, move), or with heading memory per
    (x, y, believed heading, move, moves since the last localisation): ``len(TURNS)`` units
    of progress for the trajectories, then one per free cell.

    Without memory, a move starts facing its true heading with a Gaussian error of
    ``heading_noise`` degrees, which it also believes it faces exactly. With memory, the
    error of the true yaw from the believed heading after ``j`` moves since a localisation
    is that of the localisation (Gaussian, ``heading_noise``) plus the heading errors of
    ``j - 1`` moves drawn from the trajectories (of any turning angle): open-loop turns do
    not correct it, so the weak wheel's drift adds up."""
    rng = np.random.default_rng(sampling.seed)
    pool = trajectories(sampling, rng, progress)
    obstacles = set(sampling.obstacles)
    counts: dict[tuple, dict[int, int]] = {}
    n, m = sampling.samples, sampling.margin
    drift = np.concatenate(
        [np.remainder(p[:, -1, 2] - t + math.pi, 2 * math.pi) - math.pi for t, p in pool.paths.items()]
    )
    spread = math.radians(sampling.heading_noise)
    for x in range(sampling.size):
        for y in range(sampling.size):
            if (x, y) in obstacles:
                continue
            for heading, heading_name in enumerate(HEADINGS):
                for move in HEADINGS:
                    turn = math.remainder(ANGLE[move] - ANGLE[heading_name], 2 * math.pi)
                    turn = math.pi if abs(abs(turn) - math.pi) < 1e-9 else turn
                    paths = pool.paths[min(TURNS, key=lambda t: abs(t - turn))]
                    for step in range(1, sampling.memory + 1) if sampling.memory else (0,):
                        error = rng.normal(0.0, spread, n)
                        for _ in range(step - 1):
                            error += drift[rng.integers(0, len(drift), n)]
                        starts = np.column_stack(
                            [
                                (x + rng.uniform(m / CELL, 1 - m / CELL, n)) * CELL,
                                (y + rng.uniform(m / CELL, 1 - m / CELL, n)) * CELL,
                                ANGLE[heading_name] + error,
                            ]
                        )
                        order = rng.permutation(n)
                        codes = classify(paths[order], starts, (x, y), sampling.size, obstacles, sampling.robot)
                        values, found = np.unique(codes, return_counts=True)
                        key = (x, y, heading, move, step) if sampling.memory else (x, y, heading, move)
                        counts[key] = dict(zip(values.tolist(), found.tolist()))
            if progress:
                progress(1)
    return counts


def progress_units(sampling: Sampling) -> int:
    """How many units :func:`sample` reports."""
    return len(TURNS) + sampling.size**2 - len(set(sampling.obstacles))


def motions_of(counts: dict[tuple, dict[int, int]], samples: int) -> dict[tuple, tuple[tuple[Outcome, float], ...]]:
    """The motion table (probabilities) of the counts."""
    table = {}
    for key, found in counts.items():
        table[key] = tuple((decode(code), count / samples) for code, count in sorted(found.items()))
    return table


def cache_directory() -> Path:
    """Where sampled tables are kept: ``$PARLEY_CACHE``, else ``$XDG_CACHE_HOME/parley``,
    else ``~/.cache/parley``; a ``turtlebot`` folder in it."""
    root = os.environ.get("PARLEY_CACHE") or os.path.join(
        os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache"), "parley"
    )
    return Path(root) / "turtlebot"


def cache_path(sampling: Sampling) -> Path:
    return cache_directory() / f"motions-{sampling.key()}.json"


def cached(sampling: Sampling) -> dict[tuple, dict[int, int]] | None:
    """The counts stored for ``sampling``, or None."""
    path = cache_path(sampling)
    try:
        data = json.loads(path.read_text())
    except (OSError, ValueError):
        return None
    return {
        (int(key[0]), int(key[1]), int(key[2]), str(key[3]), *(int(k) for k in key[4:])): {
            int(code): int(count) for code, count in found
        }
        for *key, found in data["counts"]
    }


def counts(sampling: Sampling, progress: Callable[[int], None] | None = None) -> dict[tuple, dict[int, int]]:
    """The counts for ``sampling``: from the cache, else sampled and stored (written to a
    temporary file first, so an interrupted run leaves no broken table)."""
    found = cached(sampling)
    if found is not None:
        return found
    result = sample(sampling, progress)
    path = cache_path(sampling)
    path.parent.mkdir(parents=True, exist_ok=True)
    data = {
        "sampling": json.loads(json.dumps(asdict(sampling, recurse=True), default=list)),
        "samples": sampling.samples,
        "counts": [[*key, sorted(found.items())] for key, found in sorted(result.items())],
    }
    temporary = path.with_suffix(f".{os.getpid()}.tmp")
    temporary.write_text(json.dumps(data))
    temporary.replace(path)
    return result
