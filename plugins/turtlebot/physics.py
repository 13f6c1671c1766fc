"""The TurtleBot3 Waffle in MuJoCo: its MJCF model, and moves driven open loop on it.

:func:`mjcf` writes the world as MuJoCo XML: the floor of the ``size`` x ``size`` area of
3 m cells with its border drawn on it (a line, not a wall: crossing it is leaving the area),
each obstacle cell a box that fills the cell, and the robot:

- the chassis, a box of the Waffle's footprint and height (281 x 306 x 141 mm, 1.8 kg with
  its computer, battery and sensors; ROBOTIS e-Manual, TurtleBot3 specifications), on a
  free joint; a frictionless ball caster at its rear;
- two driven wheels of radius 0.033 m, 0.287 m apart (the ``turtlebot3_waffle.urdf`` of
  ROBOTIS' turtlebot3_description), each on a hinge with a velocity actuator; the left one
  reaches only ``left_wheel`` of the commanded speed (0.99, the paper's weak wheel). A wheel
  touches the floor as a sphere of its radius: one contact point, where MuJoCo's cylinder
  makes two at the tyre's edges, which scrub when the robot turns on the spot, and costs
  40 % more time a step (measured: 5.7 against 3.9 microseconds a robot and step on two
  threads; the drift per move is the same within half a degree);
- a touch sensor over the chassis: a crash is a contact of the chassis with an obstacle.
  Only the chassis and the obstacles collide with each other; only the wheels and the
  caster touch the floor.

A move (:class:`Mover`) is the paper's UAC driving open loop from the pose it believes: it
turns on the spot by the angle from the believed heading to the commanded one, then drives
one cell length straight ahead, at the Waffle's speeds (turning with the wheels at
``turn_speed``, driving at ``speed``; the Waffle's maximum is 0.26 m/s). Noise a real robot
has, drawn per move: each wheel's speed off by a relative Gaussian error (``wheel_noise``),
and the floor's friction drawn uniformly from ``friction`` (per move, one model per friction
value). MuJoCo's own rollouts (:mod:`mujoco.rollout`) run many moves at once, in threads.
"""

from __future__ import annotations

import math
from collections.abc import Iterable

import attrs
import numpy as np
from attrs import frozen

Cell = tuple[int, int]

CELL = 3.0
"""A cell's side in metres (the paper's 21 m x 21 m area of 7 x 7 cells)."""


@frozen(kw_only=True)
class Waffle:
    """The robot's body and drive. Footprint, height and mass: the ROBOTIS e-Manual's
    TurtleBot3 Waffle specifications (281 x 306 x 141 mm, 1.8 kg with its computer, battery
    and sensors, at most 0.26 m/s). The rest from ROBOTIS' ``turtlebot3_waffle`` URDF
    (turtlebot3_description): wheels of radius 0.033 m and width 0.018 m, 0.287 m apart
    (``wheel_separation`` of its diff-drive plugin), 0.0285 kg each; the base 0.064 m behind
    the wheel axle and 0.010 m above the floor; two ball casters 0.177 m behind the axle,
    0.064 m left and right of the middle."""

    length: float = 0.281
    width: float = 0.306
    height: float = 0.141
    mass: float = 1.8
    clearance: float = 0.010
    base_offset: float = -0.064
    wheel_radius: float = 0.033
    wheel_width: float = 0.018
    wheel_separation: float = 0.287
    wheel_mass: float = 0.0285
    caster_x: float = -0.177
    caster_y: float = 0.064
    max_speed: float = 0.26
    """m/s; turning on the spot at this wheel speed is the Waffle's 1.82 rad/s maximum."""


@frozen(kw_only=True)
class Physics:
    """What the simulated robot does that the Waffle's data sheet does not fix. The defaults
    are this plugin's assumptions, except ``left_wheel`` (the paper's)."""

    left_wheel: float = 0.99
    speed: float = 0.22
    """Driving speed, m/s (a common TurtleBot3 teleoperation speed, below the 0.26 maximum)."""
    turn_speed: float = 0.1
    """Wheel speed while turning on the spot, m/s (0.7 rad/s of the robot)."""
    wheel_noise: float = 0.01
    """Relative standard deviation of each wheel's speed in a move."""
    friction: tuple[float, float] = (0.7, 1.0)
    """Range of the floor's sliding friction (rubber on indoor floors), drawn per move."""
    timestep: float = 0.025
    """Seconds per physics step. Against 0.01, the mean heading error of a move differs by at
    most 0.35 degrees and its mean end by at most 2 cm (400 moves per turning angle; 0.03
    drifts by 0.7 degrees)."""
    kv: float = 0.05
    """Velocity actuators' gain (N m s/rad): with ``armature`` (the gearbox's reflected
    inertia) a wheel under load follows a new speed within about 0.05 s."""
    armature: float = 0.0005
    max_torque: float = 1.5
    """N m, half the stall torque of the Waffle's Dynamixel XM430-W210 at 12 V (3.0 N m)."""


def mjcf(size: int, obstacles: Iterable[Cell], robot: Waffle = Waffle(), physics: Physics = Physics()) -> str:
    """The world as MuJoCo XML (module docstring). The robot's body frame is on the wheel
    axle, x forward; it starts at the origin (the caller sets its pose through the free
    joint's ``qpos``)."""
    extent = size * CELL
    r = robot.wheel_radius
    bottom = robot.clearance - r  # heights relative to the axle
    half_height = (robot.height - robot.clearance) / 2
    caster = 0.0125
    axle_y = robot.wheel_separation / 2
    obstacle_geoms = "\n".join(
        f'    <geom name="obstacle_{x}_{y}" type="box" pos="{(x + 0.5) * CELL} {(y + 0.5) * CELL} 0.25" '
        f'size="{CELL / 2} {CELL / 2} 0.25" contype="2" conaffinity="2" rgba="0.45 0.35 0.3 1"/>'
        for x, y in sorted(set(obstacles))
    )
    lines = [(extent / 2, 0, extent / 2, 0.02), (extent / 2, extent, extent / 2, 0.02)]
    lines += [(0, extent / 2, 0.02, extent / 2), (extent, extent / 2, 0.02, extent / 2)]
    border = "\n".join(
        f'    <geom name="border_{i}" type="box" pos="{px} {py} 0.001" size="{sx} {sy} 0.001" '
        'contype="0" conaffinity="0" rgba="0.8 0.1 0.1 1"/>'
        for i, (px, py, sx, sy) in enumerate(lines)
    )
    chassis_mass = robot.mass - 2 * robot.wheel_mass - 0.01
    gain, torque = physics.kv, physics.max_torque
    casters = "\n".join(
        f'      <geom name="caster_{side}" type="sphere" pos="{robot.caster_x} {sign * robot.caster_y} {caster - r}" '
        f'size="{caster}" mass="0.005" condim="1" priority="1" contype="1" conaffinity="1"/>'
        for side, sign in (("left", 1), ("right", -1))
    )
    wheels = "\n".join(
        f'''      <body name="{side}_wheel" pos="0 {sign * axle_y} 0">
        <joint name="{side}_wheel" type="hinge" axis="0 1 0" armature="{physics.armature}"/>
        <geom type="sphere" size="{r}" mass="{robot.wheel_mass}"/>
      </body>'''
        for side, sign in (("left", 1), ("right", -1))
    )
    box = f"{robot.base_offset} 0 {bottom + half_height}"
    return f"""<mujoco model="turtlebot3_waffle">
  <option timestep="{physics.timestep}" integrator="implicitfast"/>
  <default>
    <geom contype="1" conaffinity="1" condim="3" friction="{physics.friction[1]} 0.005 0.0001"/>
  </default>
  <worldbody>
    <geom name="floor" type="plane" pos="{extent / 2} {extent / 2} 0" size="{extent} {extent} 0.1" rgba="0.85 0.85 0.8 1"/>
{border}
{obstacle_geoms}
    <body name="chassis" pos="0 0 {r}">
      <freejoint name="base"/>
      <geom name="chassis" type="box" pos="{box}" size="{robot.length / 2} {robot.width / 2} {half_height}"
            mass="{chassis_mass}" contype="2" conaffinity="2" rgba="0.2 0.2 0.25 1"/>
      <site name="bumper" type="box" pos="{box}" size="{robot.length / 2 + 0.002} {robot.width / 2 + 0.002} {half_height + 0.002}"/>
{casters}
{wheels}
    </body>
  </worldbody>
  <actuator>
    <general name="left_wheel" joint="left_wheel" gainprm="{gain * physics.left_wheel}" biastype="affine" biasprm="0 0 {-gain}"
             forcelimited="true" forcerange="{-torque} {torque}"/>
    <general name="right_wheel" joint="right_wheel" gainprm="{gain}" biastype="affine" biasprm="0 0 {-gain}"
             forcelimited="true" forcerange="{-torque} {torque}"/>
  </actuator>
  <sensor>
    <touch name="bumper" site="bumper"/>
  </sensor>
</mujoco>
"""


@frozen(kw_only=True)
class Moves:
    """Where a batch of moves ended: poses ``[n, 3]`` (x, y in metres, yaw in radians from
    east, counter-clockwise), and whether each crashed (the chassis touched an obstacle) or
    left the area (the robot's centre crossed the border) first; ``paths`` ``[kept, steps, 3]``
    (the pose after every step) when asked for."""

    poses: np.ndarray
    crashed: np.ndarray
    out: np.ndarray
    paths: np.ndarray | None = None


FRICTION_LEVELS = 8
"""The floor's friction takes this many equally spaced values of its range (one compiled
model each); a move draws one of them."""

PAUSE = 0.2
"""Seconds the robot stands between turning and driving, and after driving."""

BATCH = 2048
CHUNK = 100
"""Moves per rollout call, and steps per call (memory: BATCH x CHUNK states)."""


class Robot:
    """The compiled world, and moves driven on it with MuJoCo's rollouts in ``threads``
    threads. Use as a context manager (it owns a thread pool).

    The UAC's open-loop timing is calibrated once, as one would calibrate a real robot's:
    on an ideal robot (both wheels at full power, no noise, the middle of the friction
    range), how many steps of turning make a quarter and a half turn, and how many steps of
    driving make one cell length (turning and driving fall a few per cent short of the
    nominal time's angle and distance: the wheels take time to speed up, and slip a little). The weak left wheel is then the only systematic error, as in the paper.
    """

    def __init__(
        self,
        size: int,
        obstacles: Iterable[Cell],
        physics: Physics = Physics(),
        robot: Waffle = Waffle(),
        threads: int = 2,
    ) -> None:
        import mujoco
        from mujoco import rollout

        self.size, self.physics, self.robot = size, physics, robot
        self.extent = size * CELL
        xml = mjcf(size, obstacles, robot, physics)
        base = mujoco.MjModel.from_xml_string(xml)
        self.models = []
        for friction in np.linspace(physics.friction[0], physics.friction[1], FRICTION_LEVELS):
            model = mujoco.MjModel.from_xml_string(xml)
            model.geom_friction[:, 0] = friction
            self.models.append(model)
        self.datas = [mujoco.MjData(base) for _ in range(threads)]
        self.spec = mujoco.mjtState.mjSTATE_FULLPHYSICS
        data = mujoco.MjData(base)
        mujoco.mj_forward(base, data)
        self.template = np.empty(mujoco.mj_stateSize(base, self.spec))
        mujoco.mj_getState(base, data, self.template, self.spec)
        self.z = float(data.qpos[2])
        self._pool = rollout.Rollout(nthread=threads)
        self.turn_steps: dict[int, int] = {}
        self.drive_steps = int(round(CELL / physics.speed / physics.timestep))
        self._calibrate(mujoco)

    def _calibrate(self, mujoco) -> None:
        p = self.physics
        ideal = mujoco.MjModel.from_xml_string(
            mjcf(2, (), self.robot, attrs.evolve(p, left_wheel=1.0, friction=(sum(p.friction) / 2,) * 2))
        )
        start = np.array([[CELL, CELL, 0.0]])
        nominal = abs(self.physics.turn_speed / self.robot.wheel_radius)
        for quarters in (1, 2):
            angle = quarters * math.pi / 2
            steps = int(round(angle * self.robot.wheel_separation / 2 / p.turn_speed / p.timestep))
            for _ in range(3):
                controls = np.zeros((1, steps + 2 * int(round(PAUSE / p.timestep)), 2))
                controls[0, :steps] = [-nominal, nominal]
                turned = self._run([ideal], start, controls).poses[0, 2]
                steps = int(round(steps * angle / (turned % (2 * math.pi))))  # counter-clockwise
            self.turn_steps[quarters] = steps
        for _ in range(3):
            controls = np.zeros((1, self.drive_steps + int(round(PAUSE / p.timestep)), 2))
            controls[0, : self.drive_steps] = p.speed / self.robot.wheel_radius
            moved = self._run([ideal], start, controls).poses[0, 0] - CELL
            self.drive_steps = int(round(self.drive_steps * CELL / moved))

    def __enter__(self) -> Robot:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def close(self) -> None:
        self._pool.close()

    def controls(self, turn: np.ndarray, rng: np.random.Generator) -> np.ndarray:
        """Wheel speeds [n, steps, 2] (rad/s, left and right) of moves that turn on the spot
        by ``turn`` radians (counter-clockwise positive, at most half a turn either way) and
        then drive one cell length, open loop with the calibrated timing (interpolated
        between no turn, a quarter and a half turn), with each wheel's speed noise drawn per
        move; padded with standing still."""
        p, r = self.physics, self.robot.wheel_radius
        turn = np.asarray(turn, dtype=float)
        wrapped = np.remainder(turn + math.pi, 2 * math.pi) - math.pi  # in [-pi, pi)
        wrapped = np.where(np.isclose(wrapped, -math.pi), math.pi, wrapped)  # half a turn goes left
        angle, direction = np.abs(wrapped), np.sign(wrapped)
        turn_steps = np.rint(
            np.interp(angle, [0.0, math.pi / 2, math.pi], [0.0, self.turn_steps[1], self.turn_steps[2]])
        ).astype(int)
        pause = int(round(PAUSE / p.timestep))
        steps = int(turn_steps.max(initial=0)) + self.drive_steps + 2 * pause
        n = len(turn)
        noise = 1.0 + rng.normal(0.0, p.wheel_noise, (n, 2))
        out = np.zeros((n, steps, 2))
        spin = direction[:, None] * np.array([-1.0, 1.0]) * p.turn_speed / r
        index = np.arange(steps)[None, :]
        turning = index < turn_steps[:, None]
        start = turn_steps[:, None] + pause
        driving = (index >= start) & (index < start + self.drive_steps)
        out += turning[:, :, None] * spin[:, None, :]
        out += driving[:, :, None] * (p.speed / r)
        return out * noise[:, None, :]

    def frictions(self, rng: np.random.Generator, n: int) -> np.ndarray:
        """Each of ``n`` moves' floor friction, as an index into :attr:`models`."""
        return rng.integers(0, FRICTION_LEVELS, n)

    def run(
        self, starts: np.ndarray, controls: np.ndarray, friction: np.ndarray, keep_paths: bool | int = False
    ) -> Moves:
        """Drive each robot from its start pose ``[n, 3]`` with its wheel speeds ``[n, steps,
        2]`` on a floor of its friction (:meth:`frictions`). ``keep_paths``: keep every
        robot's path (True) or the first ``keep_paths`` robots'."""
        return self._run([self.models[k] for k in friction], starts, controls, keep_paths)

    def _run(self, models: list, starts: np.ndarray, controls: np.ndarray, keep_paths: bool | int = False) -> Moves:
        n, steps = controls.shape[:2]
        poses = np.empty((n, 3))
        crashed = np.zeros(n, dtype=bool)
        out = np.zeros(n, dtype=bool)
        kept = n if keep_paths is True else int(keep_paths)
        paths = np.empty((kept, steps, 3)) if kept else None
        for begin in range(0, n, BATCH):
            end = min(n, begin + BATCH)
            state = np.tile(self.template, (end - begin, 1))
            state[:, 1] = starts[begin:end, 0]
            state[:, 2] = starts[begin:end, 1]
            state[:, 3] = self.z
            half = starts[begin:end, 2] / 2
            state[:, 4:8] = np.column_stack([np.cos(half), np.zeros_like(half), np.zeros_like(half), np.sin(half)])
            batch = models[begin:end] if len(models) > 1 else models * (end - begin)
            first_crash = np.full(end - begin, steps)
            first_out = np.full(end - begin, steps)
            for t0 in range(0, steps, CHUNK):
                t1 = min(steps, t0 + CHUNK)
                states, touch = self._pool.rollout(batch, self.datas, state, controls[begin:end, t0:t1])
                xy = states[:, :, 1:3]
                outside = ((xy < 0.0) | (xy >= self.extent)).any(axis=2)
                hit = touch[:, :, 0] > 0.0
                first_out = np.minimum(first_out, np.where(outside.any(axis=1), t0 + outside.argmax(axis=1), steps))
                first_crash = np.minimum(first_crash, np.where(hit.any(axis=1), t0 + hit.argmax(axis=1), steps))
                if paths is not None and begin < kept:
                    last = min(end, kept) - begin
                    paths[begin : begin + last, t0:t1, :2] = xy[:last]
                    paths[begin : begin + last, t0:t1, 2] = yaw_of(states[:last, :, 4:8])
                state = states[:, -1].copy()
            poses[begin:end, 0:2] = state[:, 1:3]
            poses[begin:end, 2] = yaw_of(state[:, 4:8])
            crashed[begin:end] = first_crash < first_out
            out[begin:end] = (first_out <= first_crash) & (first_out < steps)
        return Moves(poses=poses, crashed=crashed, out=out, paths=paths)


def yaw_of(quat: np.ndarray) -> np.ndarray:
    """The yaw of unit quaternions ``[..., 4]`` (w, x, y, z) of a robot that stays level."""
    w, x, y, z = (quat[..., i] for i in range(4))
    return np.arctan2(2 * (w * z + x * y), 1 - 2 * (y * y + z * z))
