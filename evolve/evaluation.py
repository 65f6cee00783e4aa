"""Public entry of the table simulation: ``evaluate`` a population on shared start poses.

Import it as ``from evolve import evaluate`` (or ``from evolve.evaluation import evaluate``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from evolve import kernel
from evolve.codec import FULL_GENES, SECTION_GENES, check_bits, decode
from evolve.geometry import pack_world
from evolve.interpreter import MODES
from evolve.settings import WorldSettings
from evolve.table import validate_table

DEFAULT_SETTINGS = WorldSettings()


@dataclass(frozen=True)
class Evaluation:
    """Outcome of P individuals × S start poses; every array is indexed [individual, start]."""

    squares: np.ndarray
    """(P, S) int64: squares reached."""
    inner_squares: np.ndarray
    """(P, S) int64: inner squares reached."""
    steps: np.ndarray
    """(P, S) int64: gait steps taken."""
    docks: np.ndarray
    """(P, S) int64: times docked."""
    end: np.ndarray
    """(P, S) int64: 0 step limit, 1 kill zone, 2 power empty, 3 branch limit, 4 docked."""
    final_pose: np.ndarray
    """(P, S, 3) float64: final x, y (arena units), heading (deg)."""


def _check_starts(starts: np.ndarray, settings: WorldSettings) -> np.ndarray:
    arr = np.asarray(starts)
    if arr.ndim != 2 or arr.shape[1] != 3 or arr.shape[0] == 0:
        raise ValueError(f"starts must be a float array (S, 3) of x, y, heading, got {arr.shape}")
    if arr.dtype.kind not in "fiu":
        raise ValueError(f"starts must be numbers, got dtype {arr.dtype}")
    arr = np.ascontiguousarray(arr, dtype=np.float64)
    if not np.isfinite(arr).all():
        bad = int(np.argwhere(~np.isfinite(arr))[0, 0])
        raise ValueError(f"start {bad} is not finite: {arr[bad].tolist()}")
    size = settings.arena_size
    outside = (arr[:, :2] < 0.0) | (arr[:, :2] > size)
    if outside.any():
        bad = int(np.argwhere(outside)[0, 0])
        raise ValueError(
            f"start {bad} at {arr[bad, :2].tolist()} lies outside the arena [0, {size}]"
        )
    return arr


def evaluate(
    genomes: np.ndarray,
    starts: np.ndarray,
    *,
    table,
    mode: str,
    start_power: float = 4.0,
    max_steps: int | None = None,
    settings: WorldSettings = DEFAULT_SETTINGS,
) -> Evaluation:
    """Run every individual of ``genomes`` from every start pose on the table simulation.

    ``genomes``: uint8 bits (P, G, 30), G = 16 for mode "coverage", 8 for "navigation".
    ``starts``: (S, 3) of x, y (arena units, inside the arena) and heading (deg).
    ``table``: a (16, 3) array of (F cm, T cm, dH deg) or a ``GaitTable``.
    ``max_steps`` defaults to ``settings.coverage_steps`` (600) or ``navigation_steps`` (100).
    Equal to ``evolve.interpreter.run`` with a ``TableWorld``, run by run.
    """
    if mode not in MODES:
        raise ValueError(f"mode must be 'coverage' or 'navigation', got {mode!r}")
    bits = check_bits(genomes, name="genomes", population=True)
    want = FULL_GENES if mode == "coverage" else SECTION_GENES
    if bits.shape[1] != want:
        raise ValueError(f"mode {mode!r} needs {want}-gene genomes, got {bits.shape[1]} genes")
    start_arr = _check_starts(starts, settings)
    values = validate_table(getattr(table, "values", table))
    if max_steps is None:
        max_steps = settings.coverage_steps if mode == "coverage" else settings.navigation_steps
    if int(max_steps) != max_steps or max_steps < 0:
        raise ValueError(f"max_steps must be an integer ≥ 0, got {max_steps}")
    if not math.isfinite(start_power):
        raise ValueError(f"start_power must be finite, got {start_power}")
    loops, ops, arg, target = (np.ascontiguousarray(a) for a in decode(bits))
    n_pop, n_start = bits.shape[0], start_arr.shape[0]
    out_int, out_pose = kernel.run_flat(
        loops,
        ops,
        arg,
        target,
        start_arr,
        values,
        pack_world(settings),
        float(start_power),
        int(max_steps),
        mode == "navigation",
    )
    ints = out_int.reshape(n_pop, n_start, 5)
    return Evaluation(
        squares=ints[:, :, kernel.OUT_SQUARES].copy(),
        inner_squares=ints[:, :, kernel.OUT_INNER].copy(),
        steps=ints[:, :, kernel.OUT_STEPS].copy(),
        docks=ints[:, :, kernel.OUT_DOCKS].copy(),
        end=ints[:, :, kernel.OUT_END].copy(),
        final_pose=out_pose.reshape(n_pop, n_start, 3),
    )


__all__ = ["Evaluation", "evaluate"]
