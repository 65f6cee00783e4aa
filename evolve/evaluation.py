"""Public entry of the table simulation: ``evaluate`` a population on shared start poses, one
robot per run, or ``evaluate_colony``: a colony of R robots per run (SPEC §7). Both run in an
envelope of variation (SPEC §9, ``evolve.envelope``; ``none`` by default: the world of §3).

Import them as ``from evolve import evaluate, evaluate_colony``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from evolve import kernel
from evolve.codec import FULL_GENES, SECTION_GENES, check_bits, decode
from evolve.envelope import NONE, ROBOT_RADIUS, Envelope
from evolve.geometry import pack_world
from evolve.interpreter import LIVE_ENDS, MODES
from evolve.settings import ALIVE_FITNESSES, DOCK_FITNESSES, ColonySettings, WorldSettings
from evolve.table import validate_table
from evolve.variation import KernelDraws, Variation

DEFAULT_SETTINGS = WorldSettings()
DEFAULT_COLONY = ColonySettings()


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


def _check_inputs(
    genomes: np.ndarray,
    table,
    mode: str,
    start_power: float,
    max_steps: int | None,
    settings: WorldSettings,
) -> tuple[np.ndarray, np.ndarray, int]:
    """(bits, table values, max_steps) checked, with the mode's default step limit."""
    if mode not in MODES:
        raise ValueError(f"mode must be 'coverage' or 'navigation', got {mode!r}")
    bits = check_bits(genomes, name="genomes", population=True)
    want = FULL_GENES if mode == "coverage" else SECTION_GENES
    if bits.shape[1] != want:
        raise ValueError(f"mode {mode!r} needs {want}-gene genomes, got {bits.shape[1]} genes")
    values = validate_table(getattr(table, "values", table))
    if max_steps is None:
        max_steps = settings.coverage_steps if mode == "coverage" else settings.navigation_steps
    if int(max_steps) != max_steps or max_steps < 0:
        raise ValueError(f"max_steps must be an integer ≥ 0, got {max_steps}")
    if not math.isfinite(start_power):
        raise ValueError(f"start_power must be finite, got {start_power}")
    return bits, values, int(max_steps)


def _decoded(bits: np.ndarray) -> tuple[np.ndarray, ...]:
    """(loops, ops, arg, target), contiguous, for the kernels."""
    return tuple(np.ascontiguousarray(a) for a in decode(bits))


def _draws(
    envelope: Envelope, table, settings: WorldSettings, key, radius: float, starts: int,
    robots: int,
) -> KernelDraws:  # fmt: skip
    """The batch's per-run envelope draws (``evolve.variation``) for the kernels."""
    if not isinstance(envelope, Envelope):
        raise TypeError(f"envelope must be an evolve.envelope.Envelope, got {envelope!r}")
    return Variation.of(envelope, table, settings, key, radius).kernel_draws(starts, robots)


def evaluate(
    genomes: np.ndarray,
    starts: np.ndarray,
    *,
    table,
    mode: str,
    start_power: float = 4.0,
    max_steps: int | None = None,
    settings: WorldSettings = DEFAULT_SETTINGS,
    envelope: Envelope = NONE,
    envelope_key: tuple[int, ...] = (0, 0),
) -> Evaluation:
    """Run every individual of ``genomes`` from every start pose on the table simulation.

    ``genomes``: uint8 bits (P, G, 30), G = 16 for mode "coverage", 8 for "navigation".
    ``starts``: (S, 3) of x, y (arena units, inside the arena) and heading (deg).
    ``table``: a (16, 3) array of (F cm, T cm, dH deg) or a ``GaitTable`` (whose ``std`` is
    the envelope's σ; an array or the paper's table borrow the shipped robot's).
    ``max_steps`` defaults to ``settings.coverage_steps`` (600) or ``navigation_steps`` (100).
    ``envelope`` varies the world (SPEC §9) with draws keyed by ``envelope_key`` (a stage's
    seed and generation, or ``evolve.envelope.key_of_test``), the start's index s and robot
    0: every individual meets the same draws at start s. ``envelope.NONE``: the world of §3.
    Equal to ``evolve.interpreter.run`` with a ``TableWorld`` (same envelope, key and start
    index), run by run.
    """
    bits, _, max_steps = _check_inputs(genomes, table, mode, start_power, max_steps, settings)
    start_arr = _check_starts(starts, settings)
    n_pop, n_start = bits.shape[0], start_arr.shape[0]
    draws = _draws(envelope, table, settings, envelope_key, ROBOT_RADIUS, n_start, 1)
    out_int, out_pose = kernel.run_flat(
        *_decoded(bits),
        start_arr,
        draws,
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


@dataclass(frozen=True)
class ColonyEvaluation:
    """Outcome of P individuals × S colony starts of R robots; arrays indexed [individual,
    start] for the colony and [individual, start, robot] per robot."""

    squares: np.ndarray
    """(P, S) int64: colony squares, reached by any robot."""
    inner_squares: np.ndarray
    """(P, S) int64: inner squares reached by any robot."""
    colony_steps: np.ndarray
    """(P, S) int64: colony steps the run lasted."""
    robot_squares: np.ndarray
    """(P, S, R) int64: squares each robot reached itself."""
    robot_inner_squares: np.ndarray
    """(P, S, R) int64: inner squares each robot reached itself."""
    steps: np.ndarray
    """(P, S, R) int64: gait steps each robot took."""
    docks: np.ndarray
    """(P, S, R) int64: times each robot docked."""
    end: np.ndarray
    """(P, S, R) int64: end code of each robot (as ``Evaluation.end``)."""
    final_pose: np.ndarray
    """(P, S, R, 3) float64: each robot's final x, y (arena units), heading (deg)."""
    collisions: np.ndarray
    """(P, S, R) int64: each robot's moves that another robot blocked (cancelled)."""
    station_waits: np.ndarray
    """(P, S, R) int64: each robot's steps that met the docking rule while another charged."""

    @property
    def live(self) -> np.ndarray:
        """(P, S, R) bool: each robot live at the end of its run (end code in
        ``evolve.interpreter.LIVE_ENDS``)."""
        return np.isin(self.end, LIVE_ENDS)


def colony_run_fitness(ev: ColonyEvaluation, colony: ColonySettings, max_steps: int) -> np.ndarray:
    """(P, S) float64: each colony run's fitness under ``colony.fitness``, in squares
    (``ColonySettings.fitness``); ``max_steps``: each robot's gait-step limit N of the runs.
    Equal to ``evolve.interpreter.colony_fitness`` run by run, bit for bit (the same float
    operations in the same order)."""
    fitness = np.asarray(ev.squares, dtype=np.float64)
    n = ev.end.shape[2]
    if colony.fitness == "per_step":
        steps = ev.steps.sum(axis=2)
        scaled = fitness * float(n * max_steps) / np.maximum(steps, 1)
        return np.where(steps == 0, 0.0, scaled)
    if colony.fitness in ALIVE_FITNESSES:
        fitness = fitness + float(colony.alive_weight) * ev.live.sum(axis=2) / n
    if colony.fitness in DOCK_FITNESSES:
        docks = np.minimum(ev.docks, colony.dock_cap).sum(axis=2)
        fitness = fitness + float(colony.dock_weight) * docks / n
    return fitness


def _check_partners(partners: np.ndarray, bits: np.ndarray, robots: int, role: int) -> np.ndarray:
    """``partners`` checked against the individuals' chromosomes and the colony's robots."""
    arr = check_bits(partners, name="partners", population=True)
    if arr.shape != (robots,) + bits.shape[1:]:
        raise ValueError(
            f"partners must hold one chromosome per robot, shaped {(robots,) + bits.shape[1:]} "
            f"like the genomes, got {arr.shape}"
        )
    if not 0 <= role < robots:
        raise ValueError(f"role must name a robot, 0 … {robots - 1}, got {role}")
    return arr


def _check_colony_starts(
    starts: np.ndarray, settings: WorldSettings, colony: ColonySettings
) -> np.ndarray:
    arr = np.asarray(starts)
    if arr.ndim != 3 or arr.shape[2] != 3 or 0 in arr.shape:
        raise ValueError(
            f"starts must be a float array (S, R, 3) of x, y, heading, got {arr.shape}"
        )
    if arr.shape[1] != colony.robots:
        raise ValueError(f"starts hold {arr.shape[1]} robots but colony.robots = {colony.robots}")
    flat = _check_starts(arr.reshape(-1, 3), settings).reshape(arr.shape)
    d = flat[:, :, None, :2] - flat[:, None, :, :2]
    dist = np.hypot(d[..., 0], d[..., 1])
    dist[:, np.arange(arr.shape[1]), np.arange(arr.shape[1])] = np.inf
    if (dist < colony.min_distance).any():
        s, a, b = (int(v) for v in np.argwhere(dist < colony.min_distance)[0])
        raise ValueError(
            f"start {s}: robots {a} and {b} are {dist[s, a, b]:.3g} units apart, closer than "
            f"two disc radii ({colony.min_distance:g})"
        )
    return flat


def evaluate_colony(
    genomes: np.ndarray,
    starts: np.ndarray,
    *,
    table,
    mode: str,
    start_power: float = 4.0,
    max_steps: int | None = None,
    settings: WorldSettings = DEFAULT_SETTINGS,
    colony: ColonySettings = DEFAULT_COLONY,
    envelope: Envelope = NONE,
    envelope_key: tuple[int, ...] = (0, 0),
    partners: np.ndarray | None = None,
    role: int = 0,
) -> ColonyEvaluation:
    """Run every individual of ``genomes`` as a colony from every colony start (SPEC §7).

    ``starts``: (S, R, 3), R = ``colony.robots`` poses per run (inside the arena, centres at
    least two disc radii apart). Every robot of a run carries the same chromosome, or, with
    ``partners`` (R, genes, 30), robot ``role`` carries the individual and robot j ≠ ``role``
    chromosome ``partners[j]`` (a team of coevolved sections, ``evolve.coevolution``); robot r
    starts with ``colony.start_powers(start_power, settings.charged_power_v)[r]``
    (``start_power`` for every robot unless ``colony.start_power_spread``); ``max_steps``
    bounds each robot's gait steps (default as ``evaluate``). Other arguments as
    ``evaluate``; robot r of start s draws with (key, s, r),
    the station block is the run's (robot 0's draw); ``colony.blocking`` says whether another
    robot cancels a blocked move or slides it along the contact tangent, ``colony.robots_seen``
    whether the object sensors see the other robots, ``colony.contact_yaw_deg`` how far a
    blocked move turns away from the contact. Equal to
    ``evolve.interpreter.run_colony`` with a ``TableColony``, run by run; with R = 1 equal to
    ``evaluate``.
    """
    bits, _, max_steps = _check_inputs(genomes, table, mode, start_power, max_steps, settings)
    start_arr = _check_colony_starts(starts, settings, colony)
    n_start, n_robots = start_arr.shape[:2]
    draws = _draws(envelope, table, settings, envelope_key, colony.disc_radius, n_start, n_robots)
    limit = -1 if colony.colony_step_limit is None else colony.colony_step_limit
    params = (colony.disc_radius, colony.min_distance, colony.charge_steps, limit,
              colony.blocking_code, int(colony.robots_seen),
              float(colony.contact_yaw_deg))  # fmt: skip
    team = None if partners is None else _decoded(_check_partners(partners, bits, n_robots, role))
    st, pose, out_run = kernel.run_colony_flat(
        *_decoded(bits),
        start_arr,
        draws,
        pack_world(settings),
        np.array(colony.start_powers(start_power, settings.charged_power_v), dtype=np.float64),
        max_steps,
        mode == "navigation",
        params,
        team,
        role,
    )
    shape = (bits.shape[0], start_arr.shape[0])
    per_robot = st.reshape(shape + st.shape[1:])
    per_run = out_run.reshape(shape + (3,))

    def robot(col: int) -> np.ndarray:
        return per_robot[..., col].copy()

    return ColonyEvaluation(
        squares=per_run[..., kernel.RUN_SQUARES].copy(),
        inner_squares=per_run[..., kernel.RUN_INNER].copy(),
        colony_steps=per_run[..., kernel.RUN_COLONY_STEPS].copy(),
        robot_squares=robot(kernel.S_SQUARES),
        robot_inner_squares=robot(kernel.S_INNER),
        steps=robot(kernel.S_STEPS),
        docks=robot(kernel.S_DOCKS),
        end=robot(kernel.S_END),
        final_pose=pose.reshape(shape + pose.shape[1:]),
        collisions=robot(kernel.S_COLLISIONS),
        station_waits=robot(kernel.S_WAITS),
    )


__all__ = [
    "ColonyEvaluation",
    "Evaluation",
    "colony_run_fitness",
    "evaluate",
    "evaluate_colony",
]
