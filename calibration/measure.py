"""Measure the gait table (F, T, dH per gait, Figure 4 layout) and each gait's energy per
cycle from MuJoCo physics.

Pure measurement, no file output. Each gait runs on its own fresh ``MjData``: the robot is
placed at the gait's start pose (``start_pose``), walks ``settle_cycles`` cycles that are not
measured, then ``cycles`` measured cycles; each cycle's (F, T, dH) is taken in the frame the
robot had when that cycle began (SPEC §1), and its electrical energy is integrated from the
servos' torques and speeds step by step (``calibration.energy``). The robot is the shipped
ServoBot or a model file (``CalibrationSettings.model``, e.g. a ``servobot variant``).
Servo-target noise (``noise_rad``) is drawn from ``np.random.default_rng([seed, gait])``, so a
gait's numbers do not depend on which other gaits run or on the number of worker processes:
same seed → same numbers, bit for bit.
"""

from __future__ import annotations

import dataclasses
import functools
from collections.abc import Callable, Iterable
from dataclasses import dataclass
from typing import Any

import mujoco
import numpy as np

from calibration.energy import HS311, EnergyMeter, ServoDatasheet
from infra.executors import Executor, SerialExecutor, make_executor, run_in_order, values_or_raise
from servo_mj.robot.bot import CycleResult, ServoBot
from servo_mj.robot.gaits import N_GAITS, GaitLibrary, check_gait
from servo_mj.robot.model import ModelFile, load_robot, model_sha256, scene_path
from servo_mj.robot.settings import CALIBRATION_NOISE_RAD, PhysicsSettings


@dataclass(frozen=True)
class WalkSettings:
    """How a gait walks to be measured: settling cycles, measured cycles, servo-target noise and
    its seed [chosen]. A calibration and each evaluation of a fit walk alike."""

    cycles: int = 20
    """Measured cycles per gait (long enough that the mean is within ~0.3° of a 100-cycle one)."""
    settle_cycles: int = 1
    """Unmeasured cycles before them."""
    seed: int = 0
    """Seed of the servo-target noise (per gait: ``default_rng([seed, gait])``)."""
    noise_rad: float = CALIBRATION_NOISE_RAD
    """Std of the noise on every new servo activation, rad."""

    def walk_kwargs(self) -> dict[str, Any]:
        """Keyword arguments of ``measure_gait`` for this walk."""
        return {f.name: getattr(self, f.name) for f in dataclasses.fields(WalkSettings)}


@dataclass(frozen=True)
class CalibrationSettings(WalkSettings):
    """Defaults of a calibration run (``servobot calibrate`` options) [chosen]."""

    start_spacing_cm: float = 400.0
    """Start poses of the 16 gaits lie on a 4 × 4 grid this far apart, heading north (so
    recordings do not overlap)."""
    model: str | None = None
    """The robot: None = the shipped ServoBot (``models/servobot/scene.xml``), else the path
    of a complete MJCF scene, e.g. a ``servobot variant`` file."""

    def to_dict(self) -> dict[str, Any]:
        return dataclasses.asdict(self)

    def measure_kwargs(self) -> dict[str, Any]:
        """Keyword arguments of ``measure_gait`` / ``measure_all`` for these settings."""
        return self.walk_kwargs() | {"model_file": self.model}


DEFAULTS = CalibrationSettings()
COLUMNS = ("F", "T", "dH", "energy_J")
"""Columns of a measured cycle: F, T cm, dH deg, electrical energy J."""

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
    model_file: ModelFile = None,
    servo: ServoDatasheet = HS311,
    on_cycle: CycleCallback | None = None,
    on_frame: FrameCallback | None = None,
) -> np.ndarray:
    """Per-cycle (F cm, T cm, dH deg, energy J) of ``cycles`` measured cycles of one gait,
    (cycles, 4) (``COLUMNS``). ``model`` (compiled) wins over ``model_file`` (a path; None =
    the shipped robot)."""
    g = check_gait(gait)
    if cycles < 1 or settle_cycles < 0:
        raise ValueError(f"need cycles >= 1 and settle_cycles >= 0, got {cycles}, {settle_cycles}")
    if not np.isfinite(noise_rad) or noise_rad < 0:
        raise ValueError(f"noise must be a finite angle >= 0 rad, got {noise_rad}")
    physics = dataclasses.replace(physics or PhysicsSettings(), servo_noise_rad=float(noise_rad))
    model = model if model is not None else calibration_scene(model_file)
    data = mujoco.MjData(model)
    bot = ServoBot(
        model, data, physics=physics, gaits=library, rng=np.random.default_rng([seed, g])
    )
    bot.place(*start_pose(g))
    frame_cb = None if on_frame is None else (lambda d: on_frame(g, d))
    for _ in range(settle_cycles):
        bot.run_gait(g, on_frame=frame_cb)
    meter = EnergyMeter(model, bot.actuators, servo)
    out = np.empty((cycles, len(COLUMNS)))
    for k in range(cycles):
        res = bot.run_gait(g, on_frame=frame_cb, on_step=meter.record)
        out[k, :3] = res.ftdh
        out[k, 3] = meter.take()
        if on_cycle is not None:
            on_cycle(g, res, bot)
    return out


def calibration_scene(model_file: ModelFile = None) -> mujoco.MjModel:
    """The calibration scene of ``model_file`` (None = the shipped robot), compiled once per
    process and file contents (each walk has its own ``MjData``)."""
    return _compiled_scene(str(scene_path(model_file)), model_sha256(model_file))


@functools.cache
def _compiled_scene(path: str, sha256: str) -> mujoco.MjModel:
    return load_robot(scene=True, model=path)[0]


def _measure_one(args: tuple) -> np.ndarray:
    gait, kwargs = args
    return measure_gait(gait, **kwargs)


def summarise(per_cycle: dict[int, np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
    """Mean and per-cycle standard deviation (ddof 0) per gait, each (16, 4) (``COLUMNS``);
    NaN rows for gaits not measured."""
    values = np.full((N_GAITS, len(COLUMNS)), np.nan)
    std = np.full((N_GAITS, len(COLUMNS)), np.nan)
    for g, a in per_cycle.items():
        values[g] = a.mean(axis=0)
        std[g] = a.std(axis=0)
    return values, std


def measure_all(
    gaits: Iterable[int] = range(N_GAITS),
    *,
    workers: int = 1,
    executor: Executor | None = None,
    **kwargs,
) -> dict[int, np.ndarray]:
    """Per-cycle arrays of several gaits (``measure_gait`` keyword arguments), each gait one
    run of ``executor`` (default ``make_executor(None, workers)``: 1 = here, k = a pool of k).
    Callbacks (``on_cycle``, ``on_frame``) run the gaits here, one after another. Raises
    ``infra.executors.BatchError`` naming each gait that failed (e.g. a ``PhysicsError``)."""
    gs = [check_gait(g) for g in gaits]
    if kwargs.get("on_cycle") or kwargs.get("on_frame"):
        executor = SerialExecutor()  # callbacks cannot cross processes
    outcomes = run_in_order(
        executor or make_executor(None, workers), _measure_one, [(g, kwargs) for g in gs]
    )
    arrays = values_or_raise(outcomes, [f"gait {g}" for g in gs])
    return dict(zip(gs, arrays, strict=True))


def measure_gaits(
    gaits: Iterable[int] = range(N_GAITS),
    cycles: int = DEFAULTS.cycles,
    seed: int = DEFAULTS.seed,
    *,
    workers: int = 1,
    executor: Executor | None = None,
    **kwargs: Any,
) -> tuple[np.ndarray, np.ndarray]:
    """The measured gait table: (values (16, 4), std (16, 4)) of (F cm, T cm, dH deg,
    energy J), mean and per-cycle standard deviation; rows of gaits not in ``gaits`` are NaN.
    ``kwargs``: the other keyword arguments of ``measure_gait`` (``settle_cycles``,
    ``noise_rad``, ``library``, ``physics``, ``model_file``, ``on_cycle``, ``on_frame``)."""
    per_cycle = measure_all(
        gaits, workers=workers, executor=executor, cycles=cycles, seed=seed, **kwargs
    )
    return summarise(per_cycle)
