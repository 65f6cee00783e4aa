"""The world a controller runs in (SPEC §3–4), and the world a colony runs in (SPEC §7).

The controller semantics have one home, the interpreter (``evolve.interpreter``), which runs
against any object with this interface. ``TableWorld`` applies gait-table rows; the physics
world (``servo_mj.world.physics_world``) walks the MuJoCo ServoBot. Power, squares, the kill zone,
docking and the low-power sensor belong to the interpreter, not to the world.

A colony of R robots runs against a ``ColonyWorld``: the same four calls with a robot index.
The colony world decides movement (including moves that another robot blocks) and what each
robot's sensors see of the others; the interpreter keeps everything else per robot (power,
mode, program counter, loops, branch counter) and for the colony (the order of steps, the
station's occupancy, squares). ``TableColony`` is the table world's colony: robots are discs
of ``ColonySettings.disc_radius``, a move that would overlap another disc is cancelled.
"""

from __future__ import annotations

from typing import Protocol

import numpy as np

from evolve import geometry
from evolve.codec import LIGHT_LEFT, LIGHT_RIGHT, OBJECT_LEFT, OBJECT_RIGHT
from evolve.settings import ColonySettings, WorldSettings
from evolve.table import validate_table


class World(Protocol):
    """Pose, sensors and locomotion of one robot. Units: arena units (cm), degrees."""

    def pose(self) -> tuple[float, float, float]:
        """Current (x, y, heading): x east, y north, heading in [0, 360), 0 = north, clockwise."""
        ...

    def step(self, gait: int) -> bool | None:
        """Execute one gait cycle of gait 0–15. A colony robot's view (``RobotView``) returns
        whether another robot blocked the move; a lone robot's world returns None."""
        ...

    def object_sensors(self) -> tuple[bool, bool]:
        """(left, right) object sensors at the current pose."""
        ...

    def light_sensors(self) -> tuple[bool, bool]:
        """(left, right) light sensors at the current pose."""
        ...


class TableWorld:
    """The table simulation's world: gait cycles apply rows of a (16, 3) gait table (SPEC §1);
    sensors are the exact geometric rules of SPEC §3 (``evolve.geometry``).

    ``table`` rows are (F cm, T cm, dH deg); (x, y) in arena units, heading ``h`` in degrees
    (wrapped into [0, 360)).
    """

    def __init__(
        self,
        table: np.ndarray,
        x: float,
        y: float,
        h: float,
        world: WorldSettings | None = None,
    ) -> None:
        self.table = validate_table(getattr(table, "values", table))
        self.world = WorldSettings() if world is None else world
        self._p = geometry.packed_tuple(self.world)
        self._rows = [tuple(float(v) for v in row) for row in self.table]
        self._x = float(x)
        self._y = float(y)
        self._h = geometry.wrap360(float(h))

    def pose(self) -> tuple[float, float, float]:
        """Current (x, y, heading)."""
        return (self._x, self._y, self._h)

    def step(self, gait: int) -> None:
        """Apply one cycle of ``gait`` (0–15)."""
        f, t, dh = self._rows[gait]
        self._x, self._y, self._h = geometry.move(self._x, self._y, self._h, f, t, dh)

    def object_sensors(self) -> tuple[bool, bool]:
        """(left, right) object sensors."""
        bits = geometry.object_bits(self._x, self._y, self._h, self._p)
        return bool(bits & OBJECT_LEFT), bool(bits & OBJECT_RIGHT)

    def light_sensors(self) -> tuple[bool, bool]:
        """(left, right) light sensors."""
        bits = geometry.light_bits(self._x, self._y, self._h, self._p)
        return bool(bits & LIGHT_LEFT), bool(bits & LIGHT_RIGHT)


class ColonyWorld(Protocol):
    """Poses, sensors and locomotion of R robots sharing one arena (SPEC §7). Robot ``i`` is
    0 … R − 1; units: arena units (cm), degrees. The interpreter calls these one robot at a
    time, in colony-step order; a robot that has ended is never stepped again but stays in
    the world as an obstacle that the others bump into and sense."""

    @property
    def robots(self) -> int:
        """R, the number of robots."""
        ...

    def pose(self, i: int) -> tuple[float, float, float]:
        """Robot ``i``'s (x, y, heading): as ``World.pose``."""
        ...

    def step(self, i: int, gait: int) -> bool:
        """Robot ``i`` executes one gait cycle while the others stand. Returns True when
        another robot blocked it (the table world cancels the whole move; a physics world
        reports a contact with another robot during the cycle), else False."""
        ...

    def object_sensors(self, i: int) -> tuple[bool, bool]:
        """Robot ``i``'s (left, right) object sensors: walls and the other robots."""
        ...

    def light_sensors(self, i: int) -> tuple[bool, bool]:
        """Robot ``i``'s (left, right) light sensors (other robots cast no shadow)."""
        ...


class RobotView:
    """Robot ``i`` of a ``ColonyWorld`` seen as a one-robot ``World``: what the interpreter's
    per-robot run talks to."""

    def __init__(self, colony: ColonyWorld, i: int) -> None:
        self.colony = colony
        self.i = i

    def pose(self) -> tuple[float, float, float]:
        return self.colony.pose(self.i)

    def step(self, gait: int) -> bool:
        return self.colony.step(self.i, gait)

    def object_sensors(self) -> tuple[bool, bool]:
        return self.colony.object_sensors(self.i)

    def light_sensors(self) -> tuple[bool, bool]:
        return self.colony.light_sensors(self.i)


class TableColony:
    """The table simulation's colony (SPEC §7): R robots, each a disc of
    ``colony.disc_radius``, moving by gait-table rows as in ``TableWorld``.

    A move that would bring a robot's centre closer than two radii to another robot's
    centre is cancelled (the robot keeps its whole pose). Object sensors see the walls and
    every point of the other robots' discs (``geometry.disc_bits``); light sensors are the
    lone robot's. ``starts`` is (R, 3): x, y (arena units), heading (deg) per robot.
    """

    def __init__(
        self,
        table: np.ndarray,
        starts: np.ndarray,
        world: WorldSettings | None = None,
        colony: ColonySettings | None = None,
    ) -> None:
        self.table = validate_table(getattr(table, "values", table))
        self.world = WorldSettings() if world is None else world
        self.colony = ColonySettings() if colony is None else colony
        arr = np.asarray(starts, dtype=np.float64)
        if arr.ndim != 2 or arr.shape[1] != 3 or arr.shape[0] == 0:
            raise ValueError(f"starts must be (R, 3) of x, y, heading, got {arr.shape}")
        self._p = geometry.packed_tuple(self.world)
        self._rows = [tuple(float(v) for v in row) for row in self.table]
        self._poses = [(float(x), float(y), geometry.wrap360(float(h))) for x, y, h in arr]
        self._radius = float(self.colony.disc_radius)
        self._min_dist = float(self.colony.min_distance)

    @property
    def robots(self) -> int:
        return len(self._poses)

    def pose(self, i: int) -> tuple[float, float, float]:
        return self._poses[i]

    def step(self, i: int, gait: int) -> bool:
        """Apply one cycle of ``gait`` to robot ``i`` unless it would come too close to
        another robot; returns True when the move was cancelled."""
        x, y, h = self._poses[i]
        nx, ny, nh = geometry.move(x, y, h, *self._rows[gait])
        for j, (ox, oy, _) in enumerate(self._poses):
            if j != i and geometry.too_close(nx, ny, ox, oy, self._min_dist):
                return True
        self._poses[i] = (nx, ny, nh)
        return False

    def object_sensors(self, i: int) -> tuple[bool, bool]:
        x, y, h = self._poses[i]
        bits = geometry.object_bits(x, y, h, self._p)
        for j, (ox, oy, _) in enumerate(self._poses):
            if j != i:
                bits |= geometry.disc_bits(x, y, h, ox, oy, self._radius, self._p)
        return bool(bits & OBJECT_LEFT), bool(bits & OBJECT_RIGHT)

    def light_sensors(self, i: int) -> tuple[bool, bool]:
        x, y, h = self._poses[i]
        bits = geometry.light_bits(x, y, h, self._p)
        return bool(bits & LIGHT_LEFT), bool(bits & LIGHT_RIGHT)
