"""The physics world: the ``evolve.world.World`` protocol over the MuJoCo colony and ServoBot.

The interpreter (``evolve.interpreter.run``) is the only controller; this world only walks the
robot, reports its physical pose and reads its sensors:

- ``step(gait)``: one gait cycle of the MuJoCo ServoBot (``ServoBot.run_gait``);
- ``pose()``: the torso centre projected on the floor and the heading of its forward axis, in
  arena units (cm) and degrees (0 = north, clockwise) — squares, the kill zone and docking are
  judged by the interpreter on this pose;
- ``object_sensors()``: the rangefinder fans (``servo_mj.sensors``);
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
from evolve.settings import WorldSettings
from servo_mj.arena import ArenaModel, ArenaSettings, RobotSpec, compile_arena, overlaps_station
from servo_mj.constants import CM_PER_M
from servo_mj.sensors import physics_object_sensors, ray_ranges_m

_CACHE: dict[tuple, ArenaModel] = {}


def colony(
    world: WorldSettings | None = None,
    arena: ArenaSettings | None = None,
    robot: RobotSpec | None = None,
) -> ArenaModel:
    """The compiled colony for these settings, compiled once per process and reused.

    Each ``PhysicsWorld`` makes its own ``MjData``, so runs never share state.
    """
    world = world or WorldSettings()
    arena = arena or ArenaSettings()
    key = (repr(world), repr(arena), repr(robot))
    if key not in _CACHE:
        _CACHE[key] = compile_arena(world, arena, robot)
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

    ``physics`` is ``servo_mj.settings.PhysicsSettings`` (default if None); ``on_frame(frame)``
    is called with a :class:`Frame` after every control frame of every gait cycle (recording).
    Raises ``servo_mj.executor.PhysicsError`` from ``step`` when the simulation blows up.
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
        from servo_mj.executor import ServoBot

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


def sample_poses(
    n: int,
    rng: np.random.Generator,
    world: WorldSettings,
    arena: ArenaSettings | None = None,
    *,
    band: float | None = None,
) -> np.ndarray:
    """(n, 3) poses outside the kill zone and clear of the station block: uniform over the
    arena, or (``band`` cm) with the centre within ``band`` of the kill-zone edge, i.e. near a
    wall, where the sensors change."""
    arena = arena or ArenaSettings()
    lo, hi = world.kill_margin, world.arena_size - world.kill_margin
    out = []
    while len(out) < n:
        x, y, h = rng.uniform(lo, hi), rng.uniform(lo, hi), rng.uniform(0.0, 360.0)
        if overlaps_station(x, y, world, arena):
            continue
        if band is None or min(x - lo, hi - x, y - lo, hi - y) <= band:
            out.append((x, y, h))
    return np.asarray(out)


def near_station(x: float, y: float, world: WorldSettings, arena: ArenaSettings) -> bool:
    """Whether the station block can be within object range while the wall behind it is not."""
    depth = arena.station_depth_m * CM_PER_M
    reach = world.object_range + depth
    return x > world.arena_size - reach and abs(y - world.station_y) < (
        world.station_width / 2 + world.object_range
    )


def sensor_agreement(
    poses: np.ndarray, *, world: WorldSettings | None = None, arena: ArenaSettings | None = None
) -> dict[str, Any]:
    """Place the robot at each pose and compare its physics object sensors with the SPEC's
    geometric sensors at its physical pose (after settling). Light sensors use the SPEC rule
    on the same pose in both worlds, so they agree by construction and are not counted."""
    world = world or WorldSettings()
    arena = arena or ArenaSettings()
    n = agree = 0
    n_far = agree_far = 0
    misses: list[dict[str, Any]] = []
    for x, y, h in np.asarray(poses, dtype=float):
        pw = PhysicsWorld(x, y, h, world=world, arena=arena)
        px, py, ph = pw.pose()
        got, want = pw.object_sensors(), geometry.object_sensors(px, py, ph, world)
        n += 1
        agree += got == want
        if not near_station(px, py, world, arena):
            n_far += 1
            agree_far += got == want
        if got != want:
            left, right = pw.ray_ranges_cm()
            hits = [r[r >= 0].min(initial=np.inf) for r in (left, right)]
            misses.append(
                {"pose": [px, py, ph], "physics": got, "geometry": want, "nearest_cm": hits}
            )
    return {
        "poses": n,
        "agree": agree / n if n else float("nan"),
        "poses_away_from_station": n_far,
        "agree_away_from_station": agree_far / n_far if n_far else float("nan"),
        "disagreements": misses,
    }


def run_agreement(
    bits: np.ndarray, starts: np.ndarray, *, world: WorldSettings | None = None
) -> dict[str, Any]:
    """Run ``bits`` (coverage mode) from each start in physics and compare the object sensors
    of every ``StepEvent`` with the geometric sensors at the event's physical pose."""
    from evolve.codec import OBJECT_LEFT, OBJECT_RIGHT
    from evolve.interpreter import run

    world = world or WorldSettings()
    n = agree = 0
    misses: list[dict[str, Any]] = []
    for x, y, h in np.asarray(starts, dtype=float):
        events: list[Any] = []
        run(bits, PhysicsWorld(x, y, h, world=world), mode="coverage", settings=world,
            on_event=events.append)  # fmt: skip
        for e in events:
            got = (bool(e.sensors & OBJECT_LEFT), bool(e.sensors & OBJECT_RIGHT))
            want = geometry.object_sensors(*e.pose, world)
            n += 1
            agree += got == want
            if got != want:
                misses.append({"pose": list(e.pose), "physics": got, "geometry": want})
    return {"events": n, "agree": agree / n if n else float("nan"), "disagreements": misses}


def main(argv: list[str] | None = None) -> int:
    """``python -m servo_mj.physics_world [N] [SEED]``: sensor agreement on N sampled poses;
    ``python -m servo_mj.physics_world --runs CHROMOSOME N [SEED]``: along N coverage runs."""
    import json
    import sys

    args = list(sys.argv[1:] if argv is None else argv)
    if args and args[0] == "--runs":
        from evolve.codec import read_chromosome
        from servo_mj.validate_cli import draw_starts

        world = WorldSettings()
        seed = int(args[3]) if len(args) > 3 else 0
        starts = draw_starts(int(args[2]), np.random.default_rng(seed), world)
        res = run_agreement(read_chromosome(args[1]), starts, world=world)
        res["disagreements"] = res["disagreements"][:10]
        print(json.dumps(res, default=float, indent=1))
        return 0
    n = int(args[0]) if args else 200
    seed = int(args[1]) if len(args) > 1 else 0
    world = WorldSettings()
    rng = np.random.default_rng(seed)
    for name, band in (("uniform", None), ("near a wall (within 75 cm of the kill zone)", 75.0)):
        res = sensor_agreement(sample_poses(n, rng, world, band=band), world=world)
        res["disagreements"] = res["disagreements"][:10]
        print(name, json.dumps(res, default=float, indent=1))
    return 0


__all__ = [
    "Frame",
    "PhysicsWorld",
    "colony",
    "near_station",
    "run_agreement",
    "sample_poses",
    "sensor_agreement",
]


if __name__ == "__main__":
    raise SystemExit(main())
