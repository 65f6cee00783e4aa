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
of ``ColonySettings.disc_radius``, a move that would overlap another disc is cancelled (or
slid along it: ``ColonySettings.blocking``).

Both table worlds take an envelope of variation (SPEC §9, ``evolve.envelope``) with the key of
its draws and the start's index in the batch (``evaluate``'s column): the world carries the
variation (rows, scatter, reach, the station block; ``evolve.variation.RobotRun``) and the
interpreter runs unchanged. The envelope ``none`` (the default) is the world of §3.
"""

from __future__ import annotations

from typing import Protocol

import numpy as np

from evolve import geometry
from evolve.codec import LIGHT_LEFT, LIGHT_RIGHT, OBJECT_LEFT, OBJECT_RIGHT
from evolve.envelope import NONE, ROBOT_RADIUS, Envelope
from evolve.settings import ColonySettings, WorldSettings
from evolve.table import validate_table
from evolve.variation import RobotRun, variation_for


class World(Protocol):
    """Pose, sensors and locomotion of one robot. Units: arena units (cm), degrees."""

    def pose(self) -> tuple[float, float, float]:
        """Current (x, y, heading): x east, y north, heading in [0, 360), 0 = north, clockwise."""
        ...

    def step(self, gait: int) -> bool | None:
        """Execute one gait cycle of gait 0–15. Returns whether the move was cancelled
        (another robot of a colony, an envelope's station block); a world that never cancels
        may return None."""
        ...

    def object_sensors(self) -> tuple[bool, bool]:
        """(left, right) object sensors at the current pose."""
        ...

    def light_sensors(self) -> tuple[bool, bool]:
        """(left, right) light sensors at the current pose."""
        ...


def _robot_runs(
    table: np.ndarray, world: WorldSettings | None, envelope: Envelope,
    envelope_key: tuple[int, ...], start: int, radius: float, robots: int,
) -> tuple[np.ndarray, WorldSettings, tuple, list[RobotRun]]:  # fmt: skip
    """What a table world's robots run on: the checked (16, 3) gait ``table``, the world
    (None: ``WorldSettings()``), packed (``geometry.packed_tuple``), and the ``envelope``
    draws of each of ``robots`` robots (discs of ``radius`` units) at start index ``start``
    of the draws of ``envelope_key``, one seen or unseen station block for all."""
    values = validate_table(getattr(table, "values", table))
    world = WorldSettings() if world is None else world
    p = geometry.packed_tuple(world)
    var = variation_for(envelope, table, world, envelope_key, radius)
    station = 0 if var is None else var.station(start)
    return values, world, p, [RobotRun(var, values, p, start, i, station) for i in range(robots)]


class TableWorld:
    """The table simulation's world: gait cycles apply rows of a (16, 3) gait table (SPEC §1);
    sensors are the exact geometric rules of SPEC §3 (``evolve.geometry``).

    ``table`` rows are (F cm, T cm, dH deg) (a ``GaitTable`` or an array); (x, y) in arena
    units, heading ``h`` in degrees (wrapped into [0, 360)). ``envelope`` varies the world
    (SPEC §9) with the draws of ``envelope_key`` (seed, generation or test) at start index
    ``start``, as ``evolve.evaluate`` does for that column; a move into a station block that
    stops motion is cancelled or slid along it (``step`` returns True).
    """

    def __init__(
        self,
        table: np.ndarray,
        x: float,
        y: float,
        h: float,
        world: WorldSettings | None = None,
        *,
        envelope: Envelope = NONE,
        envelope_key: tuple[int, ...] = (0, 0),
        start: int = 0,
    ) -> None:
        self.table, self.world, self._p, (self._run,) = _robot_runs(
            table, world, envelope, envelope_key, start, ROBOT_RADIUS, 1
        )
        self._x = float(x)
        self._y = float(y)
        self._h = geometry.wrap360(float(h))

    def pose(self) -> tuple[float, float, float]:
        """Current (x, y, heading)."""
        return (self._x, self._y, self._h)

    def step(self, gait: int) -> bool:
        """Apply one cycle of ``gait`` (0–15); True when the station block stopped it
        (cancelled, or slid along it: ``Envelope.station_blocking``)."""
        pose = self._x, self._y, self._h
        end = geometry.move(*pose, *self._run.row(gait))
        self._x, self._y, self._h, blocked = self._run.station_move(*pose, *end)
        return blocked

    def object_sensors(self) -> tuple[bool, bool]:
        """(left, right) object sensors."""
        bits = self._run.object_bits(self._x, self._y, self._h)
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
    centre is cancelled (the robot keeps its whole pose), or with ``colony.blocking`` =
    ``"slide"`` slid along the contact tangent (``ColonySettings.blocking``). Object sensors
    see the walls and every point of the other robots' discs (``geometry.disc_bits``; not the
    discs with ``colony.robots_seen`` False); light
    sensors are the lone robot's. ``starts`` is (R, 3): x, y (arena units), heading (deg) per robot.
    ``envelope``, ``envelope_key``, ``start``: as ``TableWorld``, robot i drawing as robot i
    of ``evolve.evaluate_colony``'s column ``start``; a seen station block is one for all.
    """

    def __init__(
        self,
        table: np.ndarray,
        starts: np.ndarray,
        world: WorldSettings | None = None,
        colony: ColonySettings | None = None,
        *,
        envelope: Envelope = NONE,
        envelope_key: tuple[int, ...] = (0, 0),
        start: int = 0,
    ) -> None:
        self.colony = ColonySettings() if colony is None else colony
        arr = np.asarray(starts, dtype=np.float64)
        if arr.ndim != 2 or arr.shape[1] != 3 or arr.shape[0] == 0:
            raise ValueError(f"starts must be (R, 3) of x, y, heading, got {arr.shape}")
        self._radius = float(self.colony.disc_radius)
        self._min_dist = float(self.colony.min_distance)
        self._slide = self.colony.blocking == "slide"
        self.table, self.world, self._p, self._runs = _robot_runs(
            table, world, envelope, envelope_key, start, self._radius, len(arr)
        )
        self._poses = [(float(x), float(y), geometry.wrap360(float(h))) for x, y, h in arr]

    @property
    def robots(self) -> int:
        return len(self._poses)

    def pose(self, i: int) -> tuple[float, float, float]:
        return self._poses[i]

    def step(self, i: int, gait: int) -> bool:
        """Apply one cycle of ``gait`` to robot ``i``. A move that would end closer than two
        radii to another robot is cancelled, or slid along the contact tangent, as
        ``ColonySettings.blocking`` says, and turned away from the robots that block it by
        ``ColonySettings.contact_yaw_deg``; a move into a station block that stops is
        cancelled or slid along it (``Envelope.station_blocking``), and a slid end that
        another robot blocks is cancelled. Returns True when another robot or the station
        block blocked the move (cancelled or slid)."""
        x, y, h = self._poses[i]
        nx, ny, nh = geometry.move(x, y, h, *self._runs[i].row(gait))
        blockers = self._blockers(i, nx, ny)
        end, by_block = self._moved(i, x, y, h, nx, ny, nh, blockers)
        yaw = float(self.colony.contact_yaw_deg)
        if blockers and yaw != 0.0:
            turn = 0.0
            for ox, oy in blockers:  # in robot order, as the kernel's ``_yaw``
                turn += geometry.contact_yaw(x, y, h, ox, oy, yaw)
            if turn != 0.0:
                ex, ey, eh = end
                end = (ex, ey, geometry.wrap360(eh + turn))
        self._poses[i] = end
        return bool(blockers) or by_block

    def _moved(
        self, i: int, x: float, y: float, h: float, nx: float, ny: float, nh: float,
        blockers: list[tuple[float, float]],
    ) -> tuple[tuple[float, float, float], bool]:  # fmt: skip
        """Where robot ``i``'s move from (x, y, h) to (nx, ny, nh) that ``blockers`` block
        ends (``step``'s rules but the contact yaw: (x, y, h) when cancelled), and whether a
        station block stopped it."""
        if blockers:
            if not self._slide or len(blockers) > 1:
                return (x, y, h), False
            nx, ny = geometry.slide_end(x, y, nx, ny, *blockers[0])
            if self._blockers(i, nx, ny):
                return (x, y, h), False
        run = self._runs[i]
        nx, ny, nh, by_block = run.station_move(x, y, h, nx, ny, nh)
        if by_block and run.slides and self._blockers(i, nx, ny):
            return (x, y, h), True
        return (nx, ny, nh), by_block

    def _blockers(self, i: int, x: float, y: float) -> list[tuple[float, float]]:
        """Centres of the robots but ``i`` closer than two radii to (x, y)."""
        return [
            (ox, oy)
            for j, (ox, oy, _) in enumerate(self._poses)
            if j != i and geometry.too_close(x, y, ox, oy, self._min_dist)
        ]

    def object_sensors(self, i: int) -> tuple[bool, bool]:
        x, y, h = self._poses[i]
        run = self._runs[i]
        bits = run.object_bits(x, y, h)
        others = self._poses if self.colony.robots_seen else []
        for j, (ox, oy, _) in enumerate(others):
            if j != i:
                bits |= geometry.disc_bits_within(x, y, h, ox, oy, self._radius, run.reach, self._p)
        return bool(bits & OBJECT_LEFT), bool(bits & OBJECT_RIGHT)

    def light_sensors(self, i: int) -> tuple[bool, bool]:
        x, y, h = self._poses[i]
        bits = geometry.light_bits(x, y, h, self._p)
        return bool(bits & LIGHT_LEFT), bool(bits & LIGHT_RIGHT)
