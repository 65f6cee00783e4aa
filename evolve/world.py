"""The world a controller runs in (SPEC §3–4).

The controller semantics have one home, the interpreter (``evolve.interpreter``), which runs
against any object with this interface. ``TableWorld`` applies gait-table rows; the physics
world (``servo_mj.world.physics_world``) walks the MuJoCo ServoBot. Power, squares, the kill zone,
docking and the low-power sensor belong to the interpreter, not to the world.
"""

from __future__ import annotations

from typing import Protocol

import numpy as np

from evolve import geometry
from evolve.codec import LIGHT_LEFT, LIGHT_RIGHT, OBJECT_LEFT, OBJECT_RIGHT
from evolve.settings import WorldSettings
from evolve.table import validate_table


class World(Protocol):
    """Pose, sensors and locomotion of one robot. Units: arena units (cm), degrees."""

    def pose(self) -> tuple[float, float, float]:
        """Current (x, y, heading): x east, y north, heading in [0, 360), 0 = north, clockwise."""
        ...

    def step(self, gait: int) -> None:
        """Execute one gait cycle of gait 0–15."""
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
