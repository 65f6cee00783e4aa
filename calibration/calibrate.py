"""``calibrate(out, settings)``: re-measure Figure 4 in MuJoCo, optionally fitting the gaits first.

The library function under ``servobot calibrate`` and the pipeline's first stage. It writes
``out/gait_table.json`` (``evolve.table.table_to_json`` with each gait's energy and voltage drop
per cycle, plus provenance: the model's label, hash and variant parameters, MuJoCo version,
settings, servo model, gait parameters), ``out/figure4.png`` and, with a fit,
``out/gait_params.json`` (and ``params_out``, e.g. the shipped file). Every file is written
atomically once all physics has finished, so a failed or interrupted run loses nothing
already written. Before any physics, the sizes are checked against the machine
(``calibration_need``) and ``out`` is taken as a run folder (``infra.rundir``: a lock, and
``settings.json`` recording the settings and gait parameters; a folder holding a calibration
made otherwise is refused unless ``force``, which deletes only ``CALIBRATION_FILES``).

Recording is a consumer of the callbacks ``on_frame(gait, data)`` and
``on_cycle(gait, result, bot)``; with either, the gaits run one after another in this process.
"""

from __future__ import annotations

import dataclasses
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import mujoco
import numpy as np

from calibration.energy import HS311, energy_columns, power_model_doc
from calibration.fit import FitSettings, fit_library
from calibration.measure import (
    DEFAULTS,
    CalibrationSettings,
    CycleCallback,
    FrameCallback,
    measure_all,
    summarise,
)
from calibration.report import save_figure, within_tolerance
from evolve.settings import WorldSettings
from evolve.table import table_to_json
from infra.bounds import LIMITS, Need, check_need
from infra.executors import Executor
from infra.io import atomic_write_json, check_output_file
from infra.rundir import run_folder
from servo_mj.robot.gaits import N_GAITS, GaitLibrary
from servo_mj.robot.model import ModelFile, model_label, model_sha256, scene_path
from servo_mj.robot.settings import PhysicsSettings
from servo_mj.robot.variant import describe, read_variant

TABLE_FILE = "gait_table.json"
FIGURE_FILE = "figure4.png"
PARAMS_FILE = "gait_params.json"
CALIBRATION_FILES = (TABLE_FILE, FIGURE_FILE, PARAMS_FILE)
"""What a calibration writes into its folder besides ``settings.json``."""


@dataclass(frozen=True)
class CalibrationResult:
    """What a calibration measured and wrote."""

    values: np.ndarray
    """(16, 3) mean (F cm, T cm, dH deg) per gait."""
    std: np.ndarray
    """(16, 3) per-cycle standard deviation."""
    energy: np.ndarray
    """(16, 4) energy per cycle J and voltage drop per cycle V, mean and per-cycle std
    (``evolve.table.ENERGY_COLUMNS``)."""
    table_path: Path
    figure_path: Path
    params_path: Path | None
    """The fitted gait parameters (``out/gait_params.json``), None without a fit."""
    library: GaitLibrary
    """The gait parameters the table was measured with."""
    wall_s: float


def fitted_library(
    library: GaitLibrary,
    fit: FitSettings,
    *,
    workers: int = 1,
    executor: Executor | None = None,
    log: Callable[[str], None] | None = None,
) -> GaitLibrary:
    """Fit the 15 walking gaits to Figure 4 and record the fit's provenance in ``meta``."""
    fitted, report = fit_library(library, fit, workers=workers, executor=executor, log=log)
    return GaitLibrary(
        fitted.rows,
        fitted.stride_rad,
        fitted.lift_rad,
        {
            "fitted": True,
            "fit_settings": fit.__dict__ | {"step": list(fit.step)},
            "fit_report": {str(g): r for g, r in report.items()},
            "model": model_label(fit.model),
            "model_sha256": model_sha256(fit.model),
            "mujoco_version": mujoco.__version__,
        },
    )


def calibration_need(
    settings: CalibrationSettings, fit: FitSettings | None, workers: int = 1
) -> Need:
    """Optimistic wall time of a calibration (16 gaits, and 15 fitted gaits × ``max_evals``
    evaluations with a fit); memory is one physics process per worker."""
    cycles = N_GAITS * (settings.settle_cycles + settings.cycles)
    if fit is not None:
        cycles += (N_GAITS - 1) * fit.max_evals * (fit.settle_cycles + fit.cycles)
    speed = LIMITS.physics_cycles_per_s * max(1, workers)
    return Need(max(1, workers) * LIMITS.physics_process_bytes, cycles / speed)


def calibrate(
    out: str | Path,
    settings: CalibrationSettings = DEFAULTS,
    *,
    library: GaitLibrary | None = None,
    fit: FitSettings | None = None,
    params_out: str | Path | None = None,
    workers: int = 1,
    executor: Executor | None = None,
    model: mujoco.MjModel | None = None,
    world: WorldSettings | None = None,
    on_frame: FrameCallback | None = None,
    on_cycle: CycleCallback | None = None,
    log: Callable[[str], None] | None = None,
    command: str = "",
    force: bool = False,
) -> CalibrationResult:
    """Measure the 16 gaits (after fitting them when ``fit`` is given) and write the table.

    The robot is ``settings.model`` (None = the shipped ServoBot; a fit is made on it too);
    ``model``, an already compiled copy of it, saves compiling it again. ``library`` defaults to
    the shipped gait parameters. ``params_out``: a second place for the fitted parameters (with
    ``fit`` only). ``world`` gives the capacitor bank that converts energy to voltage drop. The
    gaits (and fits) are runs of ``executor`` (default ``make_executor(None, workers)``; with
    callbacks, here). Raises ``infra.errors.InputError`` subclasses for sizes the machine
    cannot give, a missing model file or an unusable ``out``/``params_out`` (before any
    physics), ``infra.executors.BatchError`` naming the gaits whose simulation blew up
    (nothing is written then).
    """
    scene_path(settings.model)  # a missing model file fails before any physics
    library = library if library is not None else GaitLibrary.load()
    check_need(calibration_need(settings, fit, workers), "the calibration's cycles and --fit-evals")
    if fit is not None and params_out is not None:
        check_output_file(params_out, option="--params-out")
    record = {
        "CalibrationSettings": settings.to_dict(),
        "FitSettings": None if fit is None else fit.__dict__ | {"step": list(fit.step)},
        "gait_params": library.to_dict(),
        "model_sha256": model_sha256(settings.model),
    }
    with run_folder(out, record, owned=CALIBRATION_FILES, resumable=False, force=force,
                    command="calibrate"):
        return _measure(
            Path(out), settings, library, fit, params_out, workers=workers, executor=executor,
            model=model, world=world, on_frame=on_frame, on_cycle=on_cycle, log=log,
            command=command,
        )  # fmt: skip


def _measure(
    out: Path, settings: CalibrationSettings, library: GaitLibrary, fit: FitSettings | None,
    params_out: str | Path | None, *, workers: int, executor: Executor | None,
    model: mujoco.MjModel | None, world: WorldSettings | None, on_frame: FrameCallback | None,
    on_cycle: CycleCallback | None, log: Callable[[str], None] | None, command: str,
) -> CalibrationResult:  # fmt: skip
    t0 = time.perf_counter()
    if fit is not None:
        fit = dataclasses.replace(fit, model=settings.model)
        library = fitted_library(library, fit, workers=workers, executor=executor, log=log)
    per_cycle = measure_all(
        range(N_GAITS),
        workers=workers,
        executor=executor,
        model=model,
        on_frame=on_frame,
        on_cycle=on_cycle,
        library=library,
        **settings.measure_kwargs(),
    )
    mean, spread = summarise(per_cycle)
    values, std = mean[:, :3], spread[:, :3]
    energy = energy_columns(mean[:, 3], spread[:, 3], world or WorldSettings())
    wall_s = time.perf_counter() - t0
    doc = table_document(
        values, std, settings, library, energy=energy, world=world, wall_s=wall_s, command=command
    )
    params_path = None
    if fit is not None:
        params_path = atomic_write_json(out / PARAMS_FILE, library.to_dict())
        if params_out is not None:
            atomic_write_json(params_out, library.to_dict())
    table_path = atomic_write_json(out / TABLE_FILE, doc)
    figure_path = save_figure(out / FIGURE_FILE, values, std, energy=energy)
    return CalibrationResult(
        values, std, energy, table_path, figure_path, params_path, library, wall_s
    )


def model_document(model: ModelFile) -> dict[str, Any]:
    """Which robot a table was measured on: label, hash and variant parameters."""
    variant = None if model is None else read_variant(model)
    return {"model": model_label(model), "model_sha256": model_sha256(model), **describe(variant)}


def table_document(
    values: np.ndarray,
    std: np.ndarray,
    settings: CalibrationSettings,
    library: GaitLibrary,
    *,
    energy: np.ndarray | None = None,
    world: WorldSettings | None = None,
    wall_s: float,
    command: str = "",
) -> dict[str, Any]:
    """The ``gait_table.json`` document: the table, its energy columns and how it was
    measured."""
    return table_to_json(
        values,
        std,
        cycles=settings.cycles,
        energy=energy,
        source="MuJoCo calibration (servobot calibrate)",
        **model_document(settings.model),
        power=power_model_doc(HS311, world or WorldSettings()),
        mujoco_version=mujoco.__version__,
        calibration=settings.to_dict(),
        seed=settings.seed,
        noise_rad=settings.noise_rad,
        settle_cycles=settings.settle_cycles,
        physics=PhysicsSettings().to_dict(),
        gait_params=library.to_dict(),
        within_tolerance=int(within_tolerance(values).sum()),
        wall_time_s=round(wall_s, 3),
        command=command,
    )


__all__ = [
    "CALIBRATION_FILES",
    "CalibrationResult",
    "calibrate",
    "calibration_need",
    "fitted_library",
    "model_document",
    "table_document",
]
