"""The physics colony: the ``evolve.world.ColonyWorld`` protocol over R ServoBots in one arena.

SPEC §7 "In MuJoCo": the robots share one MuJoCo model and one ``MjData`` (each attached
with its own prefix, ``servobot0/`` …; ``servo_mj.world.arena`` with a ``ColonySettings``).
The interpreter (``evolve.interpreter.run_colony``) is the only controller, as for one robot;
this world walks the robots, reports their poses and reads their sensors:

- ``step(i, gait)``: robot i runs one gait cycle while the others stand in the posture
  their last cycle left them (a cycle ends in the home posture); the whole model steps, so a
  standing robot can be pushed. Returns True when another robot blocked robot i: its
  bumper touched another robot's in a contact that began during the cycle or lasted to its
  end, checked at the end of each of the cycle's 16 servo frames (a robot moves < 1 cm per
  frame, and a pushing robot keeps its contact: steady penetration ≈ 0.5 mm). The robot
  keeps whatever pose physics left it.
- ``pose(i)``, ``light_sensors(i)``: as ``PhysicsWorld``; ``object_sensors(i)``: robot i's
  rangefinder fans, which see the walls and the other robots' shells (a ray never sees its
  own robot: MuJoCo rangefinders exclude the site's body, and the shell is on the torso).

Each robot is a disc in the table world (``ColonySettings.disc_radius``); here it carries a
bumper sphere of that radius, which collides only with the other robots' bumpers, and a
shell cylinder of that radius, which the rays see (``ArenaSettings``). Its legs, torso and
probes still collide with the arena alone, so two robots touch only bumper to bumper, with
centres ``2 × disc_radius`` apart, as in the table world.

Power, squares, docking and the station belong to the interpreter. With R = 1 the robot
walks exactly as ``PhysicsWorld``'s does (same placement, same steps; its bumper touches
nothing; tested bit for bit).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import Any

import mujoco
import numpy as np

from evolve import geometry
from evolve.settings import ColonySettings, WorldSettings
from servo_mj.robot.bot import PhysicsError, ServoBot
from servo_mj.robot.constants import CM_PER_M
from servo_mj.world.arena import ArenaSettings, RobotSpec
from servo_mj.world.physics_world import Frame, colony
from servo_mj.world.sensors import physics_object_sensors, ray_ranges_m


def robot_rngs(seed: int, index: int, robots: int) -> list[np.random.Generator]:
    """The servo-noise generators of run ``index``'s robots: robot 0 draws what a lone run's
    robot draws (``default_rng((seed, index))``), robot i ≥ 1 ``default_rng((seed, index, i))``."""
    return [np.random.default_rng((seed, index) if i == 0 else (seed, index, i))
            for i in range(robots)]  # fmt: skip


class PhysicsColony:
    """R ServoBots placed at ``starts`` ((R, 3): x, y cm, heading deg) in one MuJoCo arena.

    ``colony_settings`` (default ``ColonySettings(robots=len(starts))``) must hold R robots;
    ``physics`` is a ``PhysicsSettings`` (default if None); ``rngs`` one servo-noise generator
    per robot (default ``robot_rngs(0, 0, R)``). ``on_frame(frame)`` is called with a
    ``Frame`` after every control frame of every robot's gait cycle (recording).
    Raises ``servo_mj.robot.bot.PhysicsError`` when the simulation blows up or a robot flips.
    """

    def __init__(
        self,
        starts: Any,
        *,
        world: WorldSettings | None = None,
        arena: ArenaSettings | None = None,
        colony_settings: ColonySettings | None = None,
        physics: Any = None,
        robot: RobotSpec | None = None,
        rngs: Sequence[np.random.Generator] | None = None,
        on_frame: Callable[[Frame], None] | None = None,
    ) -> None:
        poses = np.asarray(starts, dtype=np.float64)
        if poses.ndim != 2 or poses.shape[1] != 3 or len(poses) == 0:
            raise ValueError(f"starts must be (R, 3) of x, y, heading, got {poses.shape}")
        n = len(poses)
        settings = colony_settings or ColonySettings(robots=n)
        if settings.robots != n:
            raise ValueError(f"{n} start poses for a colony of {settings.robots} robots")
        rngs = list(rngs) if rngs is not None else robot_rngs(0, 0, n)
        if len(rngs) != n:
            raise ValueError(f"{len(rngs)} noise generators for {n} robots")
        self.arena_model = colony(world, arena, robot, settings)
        self.world = self.arena_model.world
        self.model = self.arena_model.model
        self.data = mujoco.MjData(self.model)
        self.prefixes = self.arena_model.prefixes
        self.bumpers = self.arena_model.bumpers
        kwargs: dict[str, Any] = {} if physics is None else {"physics": physics}
        self.bots = [
            ServoBot(self.model, self.data, prefix=p, rng=g, **kwargs)
            for p, g in zip(self.prefixes, rngs, strict=True)
        ]
        self.on_frame = on_frame
        self.cycles = 0
        """Gait cycles run by all robots together."""
        self.min_distance_cm = float("inf")
        """Closest centre distance between two robots seen after placing and at the end of
        any servo frame, cm (inf for one robot)."""
        for bot, (x, y, h) in zip(self.bots, poses, strict=True):
            bot.place(float(x), float(y), float(h), settle=False)
        self.bots[0].settle()
        self._check_upright("settling")
        self._track_distance()

    @property
    def robots(self) -> int:
        """R, the number of robots."""
        return len(self.bots)

    @property
    def t_s(self) -> float:
        """Simulated time, seconds (one clock for all robots)."""
        return float(self.data.time)

    def pose(self, i: int) -> tuple[float, float, float]:
        """Robot ``i``'s physical (x, y cm; heading deg in [0, 360))."""
        x, y, h = self.bots[i].pose()
        return float(x), float(y), float(h) % 360.0

    def step(self, i: int, gait: int) -> bool:
        """One gait cycle of robot ``i`` while the others stand. True when another robot
        blocked it: at the end of some servo frame its bumper touched another robot's in a
        contact that began during the cycle, or lasted to the cycle's end (a robot walking
        away from a robot it touched at the start is not blocked)."""
        bumper = int(self.bumpers[i]) if len(self.bumpers) else -1
        hook = self.on_frame
        frame = Frame(self.model, self.data, self.prefixes[i])
        touching = [self._touching(bumper)]

        def after_frame(_data: Any) -> None:
            touching.append(self._touching(bumper))
            self._track_distance()
            if hook is not None:
                hook(frame)

        self.bots[i].run_gait(int(gait), on_frame=after_frame)
        self.cycles += 1
        self._check_upright(f"robot {i}'s gait {gait}")
        began = any(now and not before for before, now in zip(touching, touching[1:], strict=False))
        return began or touching[-1]

    def _touching(self, bumper: int) -> bool:
        """Whether the bumper is in a contact (bumpers touch only bumpers) after the last step."""
        return bool(self.data.ncon and (self.data.contact.geom == bumper).any())

    def object_sensors(self, i: int) -> tuple[bool, bool]:
        """Robot ``i``'s (left, right) object sensors: its rangefinder fans."""
        index = self.arena_model.object_indices[i]
        return physics_object_sensors(self.model, self.data, index, self.world)

    def light_sensors(self, i: int) -> tuple[bool, bool]:
        """Robot ``i``'s (left, right) light sensors: SPEC rule on its physical pose."""
        x, y, h = self.pose(i)
        return geometry.light_sensors(x, y, h, self.world)

    def ray_ranges_cm(self, i: int) -> tuple[np.ndarray, np.ndarray]:
        """Robot ``i``'s rangefinder readings (cm; −1 = no hit), left and right fans."""
        index = self.arena_model.object_indices[i]
        left, right = ray_ranges_m(self.model, self.data, index)
        return tuple(np.where(r < 0, -1.0, r * CM_PER_M) for r in (left, right))

    def centre_distances_cm(self) -> np.ndarray:
        """(R, R) distances between the robots' torso centres on the floor, cm (after the
        last step; the diagonal is 0)."""
        xy = self.data.xpos[[b.torso for b in self.bots], :2] * CM_PER_M
        return np.linalg.norm(xy[:, None, :] - xy[None, :, :], axis=-1)

    def _track_distance(self) -> None:
        if len(self.bots) > 1:
            d = self.centre_distances_cm()
            d[np.diag_indices_from(d)] = np.inf
            self.min_distance_cm = min(self.min_distance_cm, float(d.min()))

    def _check_upright(self, during: str) -> None:
        """Every robot stands (the stepping robot's own check covers only itself)."""
        for j, bot in enumerate(self.bots):
            if bot.upright() < bot.physics.upright_min:
                raise PhysicsError(
                    f"robot {j}'s torso flipped (up-axis z = {bot.upright():.2f}) during "
                    f"{during}, t = {self.t_s:.3f} s"
                )


__all__ = ["PhysicsColony", "robot_rngs"]
