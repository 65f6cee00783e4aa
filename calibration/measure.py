"""Measure the gait table (F, T, dH per gait, Figure 4 layout) from MuJoCo physics.

Pure measurement, no file output. Each gait runs on its own fresh ``MjData``: the robot is
placed at the gait's start pose (``start_pose``), walks ``settle_cycles`` cycles that are not
measured, then ``cycles`` measured cycles; each cycle's (F, T, dH) is taken in the frame the
robot had when that cycle began (SPEC §1). Servo-target noise (``noise_rad``) is drawn from
``np.random.default_rng([seed, gait])``, so a gait's numbers do not depend on which other gaits
run or on the number of worker processes: same seed → same numbers, bit for bit.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Iterable
from dataclasses import dataclass
from typing import Any

import mujoco
import numpy as np

from infra.executors import process_pool, spawning
from servo_mj.robot.bot import CycleResult, ServoBot
from servo_mj.robot.gaits import N_GAITS, GaitLibrary, check_gait
from servo_mj.robot.model import load_robot
from servo_mj.robot.settings import CALIBRATION_NOISE_RAD, PhysicsSettings


@dataclass(frozen=True)
class CalibrationSettings:
    """Defaults of a calibration run (``servobot calibrate`` options) [chosen]."""

    cycles: int = 20
    """Measured cycles per gait (long enough that the mean is within ~0.3° of a 100-cycle one)."""
    settle_cycles: int = 1
    """Unmeasured cycles before them."""
    seed: int = 0
    """Seed of the servo-target noise (per gait: ``default_rng([seed, gait])``)."""
    noise_rad: float = CALIBRATION_NOISE_RAD
    """Std of the noise on every new servo activation, rad."""
    start_spacing_cm: float = 400.0
    """Start poses of the 16 gaits lie on a 4 × 4 grid this far apart, heading north (so
    recordings do not overlap)."""

    def to_dict(self) -> dict[str, Any]:
        return dataclasses.asdict(self)

    def measure_kwargs(self) -> dict[str, Any]:
        """Keyword arguments of ``measure_gait`` / ``measure_all`` for these settings."""
        return {
            "cycles": self.cycles,
            "settle_cycles": self.settle_cycles,
            "seed": self.seed,
            "noise_rad": self.noise_rad,
        }


DEFAULTS = CalibrationSettings()

CycleCallback = Callable[[int, CycleResult, ServoBot], None]
"""``on_cycle(gait, result, bot)``, called after every measured cycle."""
FrameCallback = Callable[[int, mujoco.MjData], None]
"""``on_frame(gait, data)``, called after every 100 ms servo frame (settling included)."""


def start_pose(
    gait: int, spacing_cm: float = DEFAULTS.start_spacing_cm
) -> tuple[float, float, float]:
    """Start pose (x cm, y cm, heading deg) of a gait's calibration walk."""
    return (spacing_cm * (gait % 4), spacing_cm * (gait // 4), 0.0)


def measure_gait(
    gait: int,
    *,
    cycles: int = DEFAULTS.cycles,
    settle_cycles: int = DEFAULTS.settle_cycles,
    seed: int = DEFAULTS.seed,
    noise_rad: float = DEFAULTS.noise_rad,
    library: GaitLibrary | None = None,
    physics: PhysicsSettings | None = None,
    model: mujoco.MjModel | None = None,
    on_cycle: CycleCallback | None = None,
    on_frame: FrameCallback | None = None,
) -> np.ndarray:
    """Per-cycle (F cm, T cm, dH deg) of ``cycles`` measured cycles of one gait, (cycles, 3)."""
    g = check_gait(gait)
    if cycles < 1 or settle_cycles < 0:
        raise ValueError(f"need cycles >= 1 and settle_cycles >= 0, got {cycles}, {settle_cycles}")
    if not np.isfinite(noise_rad) or noise_rad < 0:
        raise ValueError(f"noise must be a finite angle >= 0 rad, got {noise_rad}")
    physics = dataclasses.replace(physics or PhysicsSettings(), servo_noise_rad=float(noise_rad))
    if model is None:
        model, _ = load_robot(scene=True)
    data = mujoco.MjData(model)
    bot = ServoBot(
        model, data, physics=physics, gaits=library, rng=np.random.default_rng([seed, g])
    )
    bot.place(*start_pose(g))
    frame_cb = None if on_frame is None else (lambda d: on_frame(g, d))
    for _ in range(settle_cycles):
        bot.run_gait(g, on_frame=frame_cb)
    out = np.empty((cycles, 3))
    for k in range(cycles):
        res = bot.run_gait(g, on_frame=frame_cb)
        out[k] = res.ftdh
        if on_cycle is not None:
            on_cycle(g, res, bot)
    return out


def _measure_one(args: tuple) -> np.ndarray:
    gait, kwargs = args
    return measure_gait(gait, **kwargs)


def summarise(per_cycle: dict[int, np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
    """Mean and per-cycle standard deviation (ddof 0) per gait, each (16, 3); NaN rows for
    gaits not measured."""
    values = np.full((N_GAITS, 3), np.nan)
    std = np.full((N_GAITS, 3), np.nan)
    for g, a in per_cycle.items():
        values[g] = a.mean(axis=0)
        std[g] = a.std(axis=0)
    return values, std


def measure_all(
    gaits: Iterable[int] = range(N_GAITS), *, workers: int = 1, **kwargs
) -> dict[int, np.ndarray]:
    """Per-cycle arrays of several gaits (``measure_gait`` keyword arguments), optionally in a
    process pool of ``workers``. Callbacks force ``workers = 1``."""
    gs = [check_gait(g) for g in gaits]
    if workers > 1 and len(gs) > 1 and not kwargs.get("on_cycle") and not kwargs.get("on_frame"):
        kwargs.pop("model", None)
        with process_pool(min(workers, len(gs))) as pool:
            with spawning():
                results = pool.map(_measure_one, [(g, kwargs) for g in gs])
            arrays = list(results)
        return dict(zip(gs, arrays, strict=True))
    if kwargs.get("model") is None:
        kwargs["model"], _ = load_robot(scene=True)
    return {g: measure_gait(g, **kwargs) for g in gs}


def measure_gaits(
    gaits: Iterable[int] = range(N_GAITS),
    cycles: int = DEFAULTS.cycles,
    seed: int = DEFAULTS.seed,
    *,
    settle_cycles: int = DEFAULTS.settle_cycles,
    noise_rad: float = DEFAULTS.noise_rad,
    library: GaitLibrary | None = None,
    physics: PhysicsSettings | None = None,
    workers: int = 1,
    on_cycle: CycleCallback | None = None,
    on_frame: FrameCallback | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """The measured gait table: (values (16, 3), std (16, 3)) of (F cm, T cm, dH deg), mean
    and per-cycle standard deviation; rows of gaits not in ``gaits`` are NaN."""
    per_cycle = measure_all(
        gaits,
        workers=workers,
        cycles=cycles,
        settle_cycles=settle_cycles,
        seed=seed,
        noise_rad=noise_rad,
        library=library,
        physics=physics,
        on_cycle=on_cycle,
        on_frame=on_frame,
    )
    return summarise(per_cycle)
