"""Start poses of runs (SPEC §5–7): the one home of every start-pose sampler.

A pose is (x, y, heading): x east, y north in arena units (cm), heading in degrees in
[0, 360), 0 = north, clockwise. Every sampler takes an explicit ``np.random.Generator`` and
draws three uniform numbers per pose (x, y, heading), in order, so the same generator state
gives the same poses bit for bit. The colony sampler draws its poses one at a time and
rejects those too close to the run's earlier robots; with one robot it gives exactly the
coverage sampler's poses.
"""

from __future__ import annotations

import functools
from collections.abc import Callable

import numpy as np

from evolve.settings import ColonySettings, WorldSettings

MAX_HEADING_DEG = 360.0
"""The largest |heading| a given start pose may have (degrees; one turn either way). A larger
one is a mistake, not a direction: 1e308's remainder modulo 360 is rounding noise."""


def _uniform_poses(
    rng: np.random.Generator, n: int, x: tuple[float, float], y: tuple[float, float]
) -> np.ndarray:
    (x0, x1), (y0, y1) = x, y
    u = rng.random((n, 3))
    return np.column_stack([x0 + (x1 - x0) * u[:, 0], y0 + (y1 - y0) * u[:, 1], 360.0 * u[:, 2]])


def navigation_starts(rng: np.random.Generator, n: int, world: WorldSettings) -> np.ndarray:
    """(n, 3) navigation start poses: x, y uniform in ``world.navigation_start_xy``, heading
    uniform in [0, 360) degrees (SPEC §6)."""
    return _uniform_poses(rng, n, world.navigation_start_xy, world.navigation_start_xy)


def pose_starts(
    rng: np.random.Generator, n: int, world: WorldSettings, *, poses: np.ndarray
) -> np.ndarray:
    """(n, 3) start poses drawn with replacement from ``poses`` (P, 3), e.g. a coverage run's
    hand-offs (``NavigationSettings.start_poses``); ``world`` is unused, as in every start
    function's signature."""
    return np.asarray(poses, dtype=np.float64)[rng.integers(0, len(poses), n)]


def navigation_training_starts(
    rng: np.random.Generator,
    n: int,
    world: WorldSettings,
    generation: int,
    *,
    first_radius: float,
    ramp_generations: int,
) -> np.ndarray:
    """(n, 3) training starts of a navigation generation whose start region grows (a
    curriculum, ``NavigationSettings``): navigation starts (SPEC §6 region) within a radius of
    ``world.dock_point`` that grows linearly from ``first_radius`` at generation 0 to the whole
    region at ``ramp_generations``, drawn by rejection in batches of n (once the radius
    covers the region, exactly ``navigation_starts``' poses)."""
    r2 = growing_radius(world, generation, first_radius, ramp_generations) ** 2
    dx, dy = world.dock_point
    return navigation_starts_where(
        rng, n, world, lambda p: (p[:, 0] - dx) ** 2 + (p[:, 1] - dy) ** 2 <= r2
    )


def navigation_starts_where(
    rng: np.random.Generator,
    n: int,
    world: WorldSettings,
    keep: Callable[[np.ndarray], np.ndarray],
) -> np.ndarray:
    """(n, 3) navigation starts (SPEC §6 region) that ``keep`` accepts, by rejection:
    ``navigation_starts`` batches of n, each filtered by ``keep(poses)`` (a boolean mask),
    until n are kept, in the order drawn."""
    out = np.empty((0, 3))
    while len(out) < n:
        poses = navigation_starts(rng, n, world)
        out = np.concatenate([out, poses[keep(poses)]])
    return out[:n]


def growing_radius(
    world: WorldSettings, generation: int, first_radius: float, ramp_generations: int
) -> float:
    """Radius (units) around ``world.dock_point`` of generation ``generation``'s navigation
    training starts: ``first_radius`` at 0, linearly up to the distance of the region's
    farthest corner at ``ramp_generations`` (and beyond)."""
    lo, hi = world.navigation_start_xy
    dx, dy = world.dock_point
    full = max(np.hypot(x - dx, y - dy) for x in (lo, hi) for y in (lo, hi))
    if ramp_generations <= 0 or generation >= ramp_generations:
        return float(full)
    return float(first_radius + (full - first_radius) * generation / ramp_generations)


def coverage_starts(rng: np.random.Generator, n: int, world: WorldSettings) -> np.ndarray:
    """(n, 3) coverage start poses: x in ``world.coverage_start_x``, y in
    ``world.coverage_start_y``, heading uniform in [0, 360) degrees (SPEC §5)."""
    return _uniform_poses(rng, n, world.coverage_start_x, world.coverage_start_y)


def _place_colony(
    rng: np.random.Generator, out: np.ndarray, world: WorldSettings, colony: ColonySettings
) -> int:
    """Fill ``out`` (R, 3) with one colony start by rejection; returns the robots placed (R,
    or the index of the robot that found no place in ``colony.start_attempts`` draws)."""
    sep2 = colony.start_separation**2
    for i in range(len(out)):
        for _ in range(colony.start_attempts):
            pose = _uniform_poses(rng, 1, world.coverage_start_x, world.coverage_start_y)[0]
            d = out[:i, :2] - pose[:2]
            if (d[:, 0] ** 2 + d[:, 1] ** 2 >= sep2).all():
                break
        else:
            return i
        out[i] = pose
    return len(out)


def colony_starts(
    rng: np.random.Generator, n: int, world: WorldSettings, colony: ColonySettings
) -> np.ndarray:
    """(n, R, 3) colony start poses (SPEC §7): for each of ``n`` runs, R = ``colony.robots``
    poses from the coverage start region, each centre at least ``colony.start_separation``
    from the run's earlier ones, by rejection (a rejected pose is redrawn).

    Raises ``ValueError`` when a robot cannot be placed in ``colony.start_attempts`` draws
    (too many robots for the region at that separation; ``colony_capacity`` says how many
    fit before any work)."""
    out = np.empty((n, colony.robots, 3))
    for run in range(n):
        placed = _place_colony(rng, out[run], world, colony)
        if placed < colony.robots:
            raise ValueError(
                f"cannot place robot {placed + 1} of {colony.robots} at least "
                f"{colony.start_separation:g} units from the others in the start region "
                f"x {world.coverage_start_x}, y {world.coverage_start_y} "
                f"({colony.start_attempts} draws)"
            )
    return out


CAPACITY_REHEARSALS = 512
"""Colony starts drawn (seeded) by ``colony_capacity`` for each robot count it tries."""


@functools.lru_cache(maxsize=64)
def _capacity(
    x: tuple[float, float], y: tuple[float, float], separation: float, attempts: int, robots: int
) -> int:
    world = WorldSettings(coverage_start_x=x, coverage_start_y=y)
    r = robots
    while r > 1:
        colony = ColonySettings(robots=r, start_separation=separation, start_attempts=attempts)
        rng = np.random.default_rng(20250419)
        out = np.empty((r, 3))
        placed = r
        for _ in range(CAPACITY_REHEARSALS):
            placed = _place_colony(rng, out, world, colony)
            if placed < r:
                break  # robot placed + 1 found no place: try that many fewer
        if placed == r:
            return r
        r = placed
    return r


def colony_capacity(world: WorldSettings, colony: ColonySettings) -> int:
    """The largest robot count, up to ``colony.robots``, that ``colony_starts`` placed in each
    of ``CAPACITY_REHEARSALS`` seeded colony starts (the same region, separation and draws).
    Placing robots one at a time at random can jam well before the region is full (defaults:
    8 robots jam in about 1 start in 70, 9 in 1 in 8), so a count above this one would fail
    part-way through an evolution; at or below it, none jammed in the rehearsal."""
    return _capacity(tuple(world.coverage_start_x), tuple(world.coverage_start_y),
                     float(colony.start_separation), int(colony.start_attempts),
                     int(colony.robots))  # fmt: skip


__all__ = [
    "CAPACITY_REHEARSALS",
    "MAX_HEADING_DEG",
    "colony_capacity",
    "colony_starts",
    "coverage_starts",
    "growing_radius",
    "navigation_starts",
    "navigation_starts_where",
    "navigation_training_starts",
    "pose_starts",
]
