"""The Waffle in MuJoCo: moves, crashes, and the motion table sampled from it (small worlds)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from parley_core import OptionError
from parley_plugins.turtlebot import CASE_STUDY as CASE
from parley_plugins.turtlebot.physics import CELL, Physics, Robot, Waffle
from parley_plugins.turtlebot.sampling import TURNS, Sampling, cached, classify, counts, motions_of, relative, sample

IDEAL = Physics(left_wheel=1.0, wheel_noise=0.0, friction=(0.85, 0.85))


def centre(x: int, y: int, yaw: float = 0.0) -> list[float]:
    return [(x + 0.5) * CELL, (y + 0.5) * CELL, yaw]


def test_an_ideal_robot_drives_straight_into_the_commanded_cell():
    rng = np.random.default_rng(0)
    with Robot(4, (), IDEAL) as robot:
        # from (1, 1) facing east: straight on (east), left (north), right (south), about (west)
        turns = np.array([0.0, math.pi / 2, -math.pi / 2, math.pi])
        moves = robot.run(np.array([centre(1, 1)] * 4), robot.controls(turns, rng), robot.frictions(rng, 4))
    ends = [centre(2, 1), centre(1, 2), centre(1, 0), centre(0, 1)]
    assert not moves.crashed.any() and not moves.out.any()
    np.testing.assert_allclose(moves.poses[:, :2], np.array(ends)[:, :2], atol=0.02)
    yaw_error = np.remainder(
        moves.poses[:, 2] - np.array([0.0, math.pi / 2, -math.pi / 2, math.pi]) + math.pi, 2 * math.pi
    )
    np.testing.assert_allclose(yaw_error - math.pi, 0.0, atol=math.radians(1.0))


def test_with_a_weak_left_wheel_the_robot_ends_left_of_its_line():
    rng = np.random.default_rng(0)
    with Robot(4, (), Physics(left_wheel=0.97, wheel_noise=0.0)) as robot:
        east = robot.run(np.array([centre(1, 1)]), robot.controls(np.zeros(1), rng), np.zeros(1, dtype=int))
        north = robot.run(
            np.array([centre(1, 1, math.pi / 2)]), robot.controls(np.zeros(1), rng), np.zeros(1, dtype=int)
        )
    # left of east is north (+y); left of north is west (-x); and it turned left
    assert east.poses[0, 1] > centre(1, 1)[1] + 0.2
    assert north.poses[0, 0] < centre(1, 1)[0] - 0.2
    assert east.poses[0, 2] > math.radians(5)


def test_driving_into_an_obstacle_is_a_crash_and_over_the_border_is_out():
    rng = np.random.default_rng(0)
    with Robot(3, [(2, 1)], IDEAL) as robot:
        starts = np.array([centre(1, 1), centre(1, 1, math.pi / 2), centre(1, 2, math.pi / 2)])
        moves = robot.run(starts, robot.controls(np.zeros(3), rng), robot.frictions(rng, 3))
    assert moves.crashed.tolist() == [True, False, False]
    assert moves.out.tolist() == [False, False, True]
    # the crash stopped the robot at the obstacle's face (x = 6 m), its chassis 7.7 cm ahead of the axle
    assert 6.0 - 0.10 < moves.poses[0, 0] < 6.0 - 0.05


@pytest.mark.slow
def test_the_footprint_test_agrees_with_mujocos_contacts():
    """The table's crash test (the chassis box swept along a path driven in an empty world)
    against the touch sensor of the world with the obstacles, for the same moves (controls
    and friction) started at the same poses, on moves that pass close to obstacles."""
    rng = np.random.default_rng(3)
    obstacles = [(2, 2), (0, 3), (1, 3)]
    n = 48
    with Robot(5, (), Physics()) as free, Robot(5, obstacles, Physics()) as world:
        crashes = 0
        for turn in TURNS:
            controls = free.controls(np.full(n, turn), rng)
            friction = free.frictions(rng, n)
            origin = 2.5 * CELL
            driven = free.run(np.tile([origin, origin, 0.0], (n, 1)), controls, friction, keep_paths=True)
            assert driven.paths is not None
            starts = np.column_stack([rng.uniform(3.3, 5.7, n), rng.uniform(6.3, 8.7, n), rng.normal(0.0, 0.4, n)])
            codes = classify(relative(driven.paths, origin), starts, (1, 2), 5, obstacles, Waffle())
            physical = world.run(starts, controls, friction)
            np.testing.assert_array_equal(codes == -2, physical.crashed)
            np.testing.assert_array_equal(codes == -1, physical.out)
            crashes += int(physical.crashed.sum())
    assert crashes >= 20  # the comparison is about crashes, not only free moves


@pytest.mark.slow
def test_the_sampled_table_is_a_distribution_per_move_and_the_same_for_the_same_seed(tmp_path, monkeypatch):
    monkeypatch.setenv("PARLEY_CACHE", str(tmp_path))
    sampling = Sampling(size=3, obstacles=((1, 1),), physics=Physics(), samples=30, seed=4)
    first = counts(sampling)
    assert cached(sampling) == first
    assert sample(sampling) == first  # sampled again, not read back
    assert len(first) == 8 * 4 * 4  # free cells x headings x moves
    table = motions_of(first, sampling.samples)
    for outcomes in table.values():
        assert math.isclose(sum(p for _, p in outcomes), 1.0)
        assert all(p > 0 for _, p in outcomes)
    other = sample(Sampling(size=3, obstacles=((1, 1),), physics=Physics(), samples=30, seed=5))
    assert other != first


def test_mujoco_options_are_checked(tmp_path, monkeypatch):
    monkeypatch.setenv("PARLEY_CACHE", str(tmp_path))
    with pytest.raises(OptionError, match="does not apply to motions=kinematic"):
        CASE.build(CASE.options(["wheel_noise=0.02"]))
    with pytest.raises(OptionError, match="does not apply to motions=mujoco"):
        CASE.build(CASE.options(["motions=mujoco", "turn_noise=2"]))
    with pytest.raises(OptionError, match="give LOW:HIGH"):
        CASE.build(CASE.options(["motions=mujoco", "friction=1:0.5"]))
    with pytest.raises(OptionError, match="motions"):
        CASE.build(CASE.options(["motions=gazebo"]))
