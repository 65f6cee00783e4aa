"""How a run meets an envelope (SPEC §9): its per-run draws and each cycle's scatter, for the
table worlds (``evolve.world``, plain Python) and the kernels (``evolve.kernel``) alike.

A batch of runs shares one ``Variation``: the envelope resolved for a gait table (its σ), a
world (the station block, the activation distance) and a key, ``envelope_key`` (the stage's
seed and the generation or test, ``evolve.envelope``). Every draw is a function of that key
and of where it is used (``evolve.draws``), never of a stream's state:

- a robot's run key: the key folded, then the start index s, then the robot r (0 alone);
- per run (``RobotDraws``, from the run key and a stream tag): the bias of each gait's row,
  ``STREAM_BIAS`` (triple g of ``normal3``), the activation distance, ``STREAM_REACH``, and
  the pace and turn factors, words 0 and 1 of ``STREAM_PACE``, and whether and which robot
  variant it is, one uniform u of ``STREAM_VARIANT`` (a variant when u < ``variant_p``: table
  ⌊u / variant_p × K⌋ of the K ``variant_tables``; stratified draws of a training start share
  draw 0's u, offset by d / draws, ``Envelope.variant_stratum``);
- per run of the whole colony: whether the station block is there, ``STREAM_STATION`` of robot
  0's run key, and whether an unseen block stops motion, ``STREAM_STOPS`` of it (one station
  for every robot: ``Variation.station``);
- per cycle: the scatter of cycle c, ``normal3`` of the ``STREAM_SCATTER`` key absorbing c,
  where c counts the robot's executed gait cycles before this one, from 0: every gait cycle
  it executes, the charging routine's backup cycles and cancelled moves included (the
  interpreter's and the kernels' ``steps``), a colony's charging steps not.

Per-run draws do not depend on the individual, so they are made once per batch, in Python
(``Variation.robot``, ``Variation.kernel_draws``), and the kernels read them; only the cycle
scatter is drawn inside the kernels, by the very function the Python worlds call
(``scattered_row``, ``register_jitable``).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, NamedTuple

import numpy as np
from numba.extending import register_jitable

from evolve import geometry as geo
from evolve.draws import absorb, fold, normal3, unit
from evolve.envelope import (
    NONE,
    STOPS_ALWAYS,
    Envelope,
    EnvelopeError,
    envelope_sigma,
    station_block,
)
from evolve.settings import WorldSettings
from evolve.table import N_GAITS, validate_table

(STREAM_SCATTER, STREAM_BIAS, STREAM_REACH, STREAM_STATION, STREAM_STOPS, STREAM_PACE,
 STREAM_VARIANT) = range(1, 8)  # fmt: skip
"""Stream tags: what a draw of a run is for."""
E_SCATTER, E_X0, E_Y0, E_X1, E_Y1, E_RADIUS, E_SLIDE, E_FRICTION, E_FRONT, E_BACK, E_SIDE = (
    range(11))  # fmt: skip
"""Layout of the packed envelope vector the kernels read (``Variation.packed``): the scatter
scale, the block's box (units), the robot radius (units) that the block stops, 1 when a move
it stops slides along it (``Envelope.station_blocking``) else 0, the slide's friction, and
the oval body's reach ahead, behind and sideways (units; 0: the disc)."""
E_SIZE = 11
STATION_SEEN, STATION_STOPS = 1, 2
"""Bits of a run's station (``Variation.station``): the block is there for the object sensors;
it stops motion."""


@register_jitable
def scattered_row(f, t, dh, sf, st, sdh, scale, scatter_key, cycle):
    """The row (F, T cm; dH deg) that cycle ``cycle`` executes: the run's row (f, t, dh) plus
    ``scale`` × σ (sf, st, sdh) × the cycle's three standard normals."""
    z1, z2, z3 = normal3(absorb(scatter_key, cycle), 0)
    return f + scale * sf * z1, t + scale * st * z2, dh + scale * sdh * z3


@dataclass(frozen=True)
class RobotDraws:
    """One robot's draws for one run."""

    rows: np.ndarray
    """(16, 3) its gait table for the run: the table's rows plus the bias (F, T cm; dH deg)."""
    reach: float
    """Its object sensors' activation distance, units."""
    scatter_key: int
    """The key its cycles' scatter absorbs the cycle counter into (uint64 as a Python int)."""


class KernelDraws(NamedTuple):
    """A batch's per-run draws for S starts × R robots, as the kernels read them."""

    rows: np.ndarray
    """(S, R, 16, 3) float64: each robot's gait table for the run."""
    reach: np.ndarray
    """(S, R) float64: each robot's activation distance."""
    station: np.ndarray
    """(S,) int64: each run's station bits (``STATION_SEEN``, ``STATION_STOPS``)."""
    keys: np.ndarray
    """(S, R) uint64: each robot's scatter key."""
    sigma: np.ndarray
    """(16, 3) float64: σ of the cycle scatter."""
    packed: np.ndarray
    """(E_SIZE,) float64: ``Variation.packed``."""


def _check_key(key: Any) -> tuple[int, ...]:
    words = tuple(key) if isinstance(key, tuple | list) else None
    if not words or any(isinstance(w, bool) or not isinstance(w, int | np.integer) for w in words):
        raise EnvelopeError(f"envelope_key must be a tuple of integers (seed, trial), got {key!r}")
    return tuple(int(w) for w in words)


@dataclass(frozen=True)
class Variation:
    """An envelope resolved for one gait table, world and key: what every run of a batch
    draws from (``Variation.of``)."""

    envelope: Envelope
    table: np.ndarray
    """(16, 3) the gait table (F, T cm; dH deg)."""
    sigma: np.ndarray
    """(16, 3) its per-cycle std (``envelope_sigma``)."""
    trial: int
    """The folded ``envelope_key``."""
    block: tuple[float, float, float, float]
    """The station block (x0, y0, x1, y1), units."""
    radius: float
    """Distance from the block within which it stops a robot's centre (``station_stops``):
    the robot radius + ``Envelope.station_margin``, units."""
    object_range: float
    """The world's activation distance, units: the centre of the reach draws."""
    station_trial: int
    """The folded key of the station draws (``Envelope.station_stratum``)."""
    station_offset: float
    """Added (mod 1) to each run's station uniform (``Envelope.station_stratum``)."""
    variant_trial: int
    """The folded key of the robot-variant draws (``Envelope.variant_stratum``)."""
    variant_offset: float
    """Added (mod 1) to each run's robot-variant uniform (``Envelope.variant_stratum``)."""

    @classmethod
    def of(
        cls, envelope: Envelope, table: Any, world: WorldSettings, key: Any, radius: float
    ) -> Variation:
        """Resolve ``envelope`` for ``table`` (a ``GaitTable`` or a (16, 3) array), ``world``,
        ``key`` (a tuple of integers) and the robots' ``radius``; ``EnvelopeError`` for a
        table without σ, a reach that could fall below 0 or a bad key."""
        if envelope.reach_units > world.object_range:
            raise EnvelopeError(
                f"reach_units {envelope.reach_units:g} exceeds the activation distance "
                f"object_range {world.object_range:g}: a run could draw a negative reach"
            )
        values = validate_table(getattr(table, "values", table))
        sigma = envelope_sigma(envelope, table)
        words = _check_key(key)
        station_key, offset = envelope.station_stratum(words)
        variant_key, variant_offset = envelope.variant_stratum(words)
        return cls(envelope, values, sigma, fold(words), station_block(world),
                   float(radius) + envelope.station_margin, float(world.object_range),
                   fold(station_key), offset, fold(variant_key), variant_offset)  # fmt: skip

    def run_key(self, start: int, robot: int, trial: int | None = None) -> int:
        """Robot ``robot``'s run key at start index ``start`` (of ``trial``; default the
        batch's folded key)."""
        return absorb(absorb(self.trial if trial is None else trial, int(start)), int(robot))

    def robot(self, start: int, robot: int) -> RobotDraws:
        """Robot ``robot``'s draws for the run from start index ``start``."""
        env = self.envelope
        key = self.run_key(start, robot)
        table = self.table
        if env.variant_p > 0.0:
            u = unit(absorb(self.run_key(start, robot, self.variant_trial), STREAM_VARIANT))
            u = (u + self.variant_offset) % 1.0
            if u < env.variant_p:
                k = len(env.variant_tables)
                table = np.asarray(env.variant_tables[min(int(u / env.variant_p * k), k - 1)])
        rows = np.array(table, dtype=np.float64)
        if env.bias_scale > 0.0:
            h = absorb(key, STREAM_BIAS)
            for g in range(N_GAITS):
                z = normal3(h, g)
                for c in range(3):
                    rows[g, c] = (
                        float(table[g, c]) + env.bias_scale * float(self.sigma[g, c]) * z[c]
                    )
        for cols, spread, word in (([0, 1], env.pace_spread, 0), ([2], env.turn_spread, 1)):
            if spread > 0.0:
                u = unit(absorb(absorb(key, STREAM_PACE), word))
                rows[:, cols] = rows[:, cols] * (1.0 + spread * (2.0 * u - 1.0))
        reach = self.object_range
        if env.reach_units > 0.0:
            reach = reach + env.reach_units * (2.0 * unit(absorb(key, STREAM_REACH)) - 1.0)
        return RobotDraws(rows, reach, absorb(key, STREAM_SCATTER))

    def station_seen(self, start: int) -> bool:
        """Whether the run from start index ``start`` has the station block (robot 0's draw,
        one station for the colony)."""
        p = self.envelope.station_seen_p
        if p <= 0.0:
            return False
        key = self.run_key(start, 0, self.station_trial)
        return (unit(absorb(key, STREAM_STATION)) + self.station_offset) % 1.0 < p

    def station(self, start: int) -> int:
        """The station bits of the run from start index ``start``: ``STATION_SEEN`` when its
        block is there for the sensors, ``STATION_STOPS`` when the block stops motion
        (``Envelope.station_stops``, ``unseen_stops_p``)."""
        env = self.envelope
        seen = self.station_seen(start)
        if env.station_stops == STOPS_ALWAYS:
            stops = True
        elif env.station_stops is True:
            p = env.unseen_stops_p
            stops = seen or p >= 1.0 or (
                p > 0.0 and unit(absorb(self.run_key(start, 0), STREAM_STOPS)) < p
            )
        else:
            stops = False
        return STATION_SEEN * seen + STATION_STOPS * stops

    def packed(self) -> np.ndarray:
        """The ``E_*`` vector the kernels read."""
        out = np.zeros(E_SIZE)
        out[E_SCATTER] = self.envelope.scatter_scale
        out[E_X0], out[E_Y0], out[E_X1], out[E_Y1] = self.block
        out[E_RADIUS] = self.radius
        out[E_SLIDE] = self.envelope.station_blocking == "slide"
        out[E_FRICTION] = self.envelope.station_friction
        out[E_FRONT], out[E_BACK], out[E_SIDE] = self.envelope.body
        return out

    def kernel_draws(self, starts: int, robots: int) -> KernelDraws:
        """Every robot's draws for ``starts`` × ``robots`` runs (the envelope ``none``: the
        table's rows, the world's reach, no block, no scatter)."""
        rows = np.empty((starts, robots, N_GAITS, 3))
        reach = np.empty((starts, robots))
        keys = np.zeros((starts, robots), dtype=np.uint64)
        station = np.zeros(starts, dtype=np.int64)
        if not self.envelope.varies:
            rows[...] = self.table
            reach[...] = self.object_range
        else:
            for s in range(starts):
                station[s] = self.station(s)
                for r in range(robots):
                    d = self.robot(s, r)
                    rows[s, r], reach[s, r], keys[s, r] = d.rows, d.reach, d.scatter_key
        return KernelDraws(rows, reach, station, keys, np.ascontiguousarray(self.sigma),
                           self.packed())  # fmt: skip


class RobotRun:
    """One robot's run in a table world (``TableWorld``, ``TableColony``) under an envelope:
    the row each cycle executes, what its object sensors see of the walls and the station
    block, and whether the block stops a move. ``variation`` None: the world of §3."""

    def __init__(
        self, variation: Variation | None, table: np.ndarray, p: tuple[float, ...],
        start: int, robot: int, station: int,
    ) -> None:  # fmt: skip
        self.p = p
        self.cycle = 0
        """Gait cycles executed so far (the scatter's counter)."""
        if variation is None or not variation.envelope.varies:
            self.rows = [tuple(float(v) for v in row) for row in table]
            self.reach = p[geo.P_OBJ_RANGE]
            self.scale, self.block, self.stops = 0.0, None, False
            self.slides = False
            return
        d = variation.robot(start, robot)
        self.rows = [tuple(float(v) for v in row) for row in d.rows]
        self.sigma = [tuple(float(v) for v in row) for row in variation.sigma]
        self.reach = d.reach
        self.key = d.scatter_key
        self.scale = variation.envelope.scatter_scale
        self.block = variation.block if station & STATION_SEEN else None
        self.stops = bool(station & STATION_STOPS)
        self.stop_block = variation.block
        self.radius = variation.radius
        self.body = variation.envelope.body
        self.slides = variation.envelope.station_blocking == "slide"
        self.friction = variation.envelope.station_friction

    def row(self, gait: int) -> tuple[float, float, float]:
        """The row of the next cycle of ``gait`` (counts the cycle)."""
        f, t, dh = self.rows[gait]
        if self.scale > 0.0:
            sf, st, sdh = self.sigma[gait]
            f, t, dh = scattered_row(f, t, dh, sf, st, sdh, self.scale, self.key, self.cycle)
        self.cycle += 1
        return f, t, dh

    def station_move(
        self, x: float, y: float, h: float, nx: float, ny: float, nh: float
    ) -> tuple[float, float, float, bool]:
        """The move from pose (x, y, h) to (nx, ny, nh) past the station block: (end pose,
        blocked). A move the block stops ends at (x, y, h) (cancelled), or slid along the
        block with the heading kept (``geometry.block_slide_end``)."""
        if not (
            self.stops
            and geo.block_stops(x, y, h, nx, ny, nh, *self.stop_block, self.radius, *self.body)
        ):
            return nx, ny, nh, False
        if not self.slides:
            return x, y, h, True
        sx, sy = geo.block_slide_end(x, y, nx, ny, *self.stop_block, self.friction)
        return sx, sy, h, True

    def object_bits(self, x: float, y: float, h: float) -> int:
        """Object-sensor bits of the walls and the station block at (x, y, h)."""
        bits = geo.wall_bits(x, y, h, self.reach, self.p)
        if self.block is not None:
            bits |= geo.block_bits(x, y, h, *self.block, self.reach, self.p)
        return bits


def variation_for(
    envelope: Envelope, table: Any, world: WorldSettings, key: Any, radius: float
) -> Variation | None:
    """``Variation.of``, or None for the envelope ``none`` (the world of §3's code path)."""
    if envelope == NONE:
        return None
    return Variation.of(envelope, table, world, key, radius)


__all__ = [
    "E_BACK",
    "E_FRICTION",
    "E_FRONT",
    "E_RADIUS",
    "E_SCATTER",
    "E_SIDE",
    "E_SIZE",
    "E_SLIDE",
    "E_X0",
    "E_X1",
    "E_Y0",
    "E_Y1",
    "KernelDraws",
    "RobotDraws",
    "RobotRun",
    "STATION_SEEN",
    "STATION_STOPS",
    "Variation",
    "scattered_row",
    "variation_for",
]
