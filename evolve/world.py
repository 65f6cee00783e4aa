"""The world a controller runs in (SPEC §3–4).

The controller semantics have one home, the interpreter (``evolve.interpreter``), which runs
against any object with this interface. ``TableWorld`` applies gait-table rows; the physics
world (``servo_mj.physics_world``) walks the MuJoCo ServoBot. Power, squares, the kill zone,
docking and the low-power sensor belong to the interpreter, not to the world.
"""

from __future__ import annotations

from typing import Protocol


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
