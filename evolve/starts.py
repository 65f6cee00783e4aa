"""Start poses of runs (SPEC §5, §6): the one home of every start-pose sampler.

A pose is (x, y, heading): x east, y north in arena units (cm), heading in degrees in
[0, 360), 0 = north, clockwise. Every sampler takes an explicit ``np.random.Generator`` and
draws ``rng.random((n, 3))`` once (x, y, heading per pose), so the same generator state gives
the same poses bit for bit.
"""

from __future__ import annotations

import numpy as np

from evolve.settings import WorldSettings


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


def coverage_starts(rng: np.random.Generator, n: int, world: WorldSettings) -> np.ndarray:
    """(n, 3) coverage start poses: x in ``world.coverage_start_x``, y in
    ``world.coverage_start_y``, heading uniform in [0, 360) degrees (SPEC §5)."""
    return _uniform_poses(rng, n, world.coverage_start_x, world.coverage_start_y)


__all__ = ["coverage_starts", "navigation_starts"]
