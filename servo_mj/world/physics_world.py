"""The physics world: the ``evolve.world.World`` protocol over the MuJoCo colony and ServoBot.

The interpreter (``evolve.interpreter.run``) is the only controller; this world only walks the
robot, reports its physical pose and reads its sensors:

- ``step(gait)``: one gait cycle of the MuJoCo ServoBot (``ServoBot.run_gait``);
- ``pose()``: the torso centre projected on the floor and the heading of its forward axis, in
  arena units (cm) and degrees (0 = north, clockwise) — squares, the kill zone and docking are
  judged by the interpreter on this pose;
- ``object_sensors()``: the rangefinder fans (``servo_mj.world.sensors``);
- ``light_sensors()``: the SPEC's geometric rule on the physical pose.

Power is the interpreter's (SPEC §3 power model), not the world's.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import mujoco
import numpy as np

from evolve import geometry
from evolve.settings import ColonySettings, WorldSettings
from servo_mj.robot.bot import ServoBot
from servo_mj.robot.constants import CM_PER_M
from servo_mj.world.arena import ArenaModel, ArenaSettings, RobotSpec, compile_arena
from servo_mj.world.sensors import physics_object_sensors, ray_ranges_m

_CACHE: dict[tuple, ArenaModel] = {}


def colony(
    world: WorldSettings | None = None,
    arena: ArenaSettings | None = None,
    robot: RobotSpec | None = None,
    colony_settings: ColonySettings | None = None,
) -> ArenaModel:
    """The compiled arena for these settings, compiled once per process and reused: one robot
    (``colony_settings`` None), or ``colony_settings.robots`` robots with bumpers.

    Each ``PhysicsWorld`` (``PhysicsColony``) makes its own ``MjData``, so runs never share
    state.
    """
    world = world or WorldSettings()
    arena = arena or ArenaSettings()
    robots = None
    if colony_settings is not None:  # only these three shape the model
        c = colony_settings
        robots = (c.robots, c.disc_radius, c.robots_seen)
    key = (repr(world), repr(arena), repr(robot), robots)
    if key not in _CACHE:
        _CACHE[key] = compile_arena(world, arena, robot, colony_settings)
    return _CACHE[key]


@dataclass
class Frame:
    """What ``on_frame`` receives after each control frame: the live model/data and the prefix."""

    model: mujoco.MjModel
    data: mujoco.MjData
    prefix: str

    @property
    def t_s(self) -> float:
        """Simulated time, seconds."""
        return float(self.data.time)


class PhysicsWorld:
    """A ServoBot placed at (x, y cm, heading deg) in the MuJoCo colony.

    ``physics`` is ``servo_mj.robot.settings.PhysicsSettings`` (default if None);
    ``on_frame(frame)`` is called with a :class:`Frame` after every control frame of every
    gait cycle (recording).
    Raises ``servo_mj.robot.bot.PhysicsError`` from ``step`` when the simulation blows up.
    """

    def __init__(
        self,
        x: float,
        y: float,
        h: float,
        *,
        world: WorldSettings | None = None,
        arena: ArenaSettings | None = None,
        physics: Any = None,
        robot: RobotSpec | None = None,
        on_frame: Callable[[Frame], None] | None = None,
        rng: np.random.Generator | None = None,
    ) -> None:
        self.colony = colony(world, arena, robot)
        self.world = self.colony.world
        self.model = self.colony.model
        self.data = mujoco.MjData(self.model)
        self.prefix = self.colony.prefix
        kwargs: dict[str, Any] = {"prefix": self.prefix, "rng": rng}
        if physics is not None:
            kwargs["physics"] = physics
        self.bot = ServoBot(self.model, self.data, **kwargs)
        self.on_frame = on_frame
        self.cycles = 0
        self.bot.place(float(x), float(y), float(h))

    @property
    def t_s(self) -> float:
        """Simulated time, seconds."""
        return float(self.data.time)

    def _frame_hook(self) -> Callable[..., None] | None:
        if self.on_frame is None:
            return None
        frame = Frame(self.model, self.data, self.prefix)
        hook = self.on_frame

        def call(*_args: Any, **_kwargs: Any) -> None:
            hook(frame)

        return call

    def pose(self) -> tuple[float, float, float]:
        """Physical (x, y cm; heading deg in [0, 360))."""
        x, y, h = self.bot.pose()
        return float(x), float(y), float(h) % 360.0

    def step(self, gait: int) -> None:
        """One gait cycle of the physics robot."""
        self.bot.run_gait(int(gait), on_frame=self._frame_hook())
        self.cycles += 1

    def object_sensors(self) -> tuple[bool, bool]:
        """(left, right) object sensors from the rangefinder fans."""
        return physics_object_sensors(self.model, self.data, self.colony.object_index, self.world)

    def light_sensors(self) -> tuple[bool, bool]:
        """(left, right) light sensors: SPEC rule on the physical pose."""
        x, y, h = self.pose()
        return geometry.light_sensors(x, y, h, self.world)

    def ray_ranges_cm(self) -> tuple[np.ndarray, np.ndarray]:
        """Rangefinder readings (cm; −1 = no hit) of the left and right fans."""
        left, right = ray_ranges_m(self.model, self.data, self.colony.object_index)
        return tuple(np.where(r < 0, -1.0, r * CM_PER_M) for r in (left, right))


__all__ = ["Frame", "PhysicsWorld", "colony"]
