"""Fit the gait rows so that the physics reproduces Figure 4 (``servobot calibrate --fit``).

Each gait is fitted on its own (scipy.optimize Nelder-Mead) over four of its row parameters,
``(left, right, left_offset, right_offset)`` (see ``servo_mj.robot.gaits``); ``lift`` stays as set.
One evaluation runs the exact calibration walk of that gait (``measure.measure_gait``:
settling cycles, then ``cycles`` measured cycles, same seed and noise) and scores the mean
(F, T, dH) against the paper with residuals scaled by the tolerances (1 cm, 1 cm, 1.5°). The
search stops early once every scaled residual is below ``FitSettings.stop_residual``. Gait 7
(stand still) has no parameters to fit. A penalty keeps the sweeps inside the thrust servos'
ctrlrange.
"""

from __future__ import annotations

import contextlib
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from scipy.optimize import minimize

from calibration.measure import WalkSettings, measure_gait
from calibration.report import TOLERANCE
from evolve.table import PAPER_TABLE
from infra.executors import Executor, Failed, make_executor, values_or_raise
from servo_mj.robot.gaits import N_GAITS, GaitLibrary, check_gait
from servo_mj.robot.model import load_robot, thrust_limit_rad

FIXED_GAITS = (7,)
"""Gaits without fitted parameters (stand still)."""


@dataclass(frozen=True)
class FitSettings(WalkSettings):
    """How the per-gait fit searches [chosen]; each evaluation walks as a calibration
    (``WalkSettings``, its defaults those of the default calibration)."""

    max_evals: int = 160
    """Evaluations per gait at most."""
    stop_residual: float = 0.3
    """Stop once every |error| / tolerance is below this."""
    step: tuple[float, float, float, float] = (0.12, 0.12, 0.06, 0.06)
    """Initial simplex steps of (left, right, left_offset, right_offset)."""
    model: str | None = None
    """The robot the gaits are fitted on: None = the shipped ServoBot, else a model file."""


class _Done(Exception):
    pass


def scaled_residual(measured: np.ndarray, target: np.ndarray) -> np.ndarray:
    """(measured − target) / TOLERANCE for one gait's (F, T, dH)."""
    return (np.asarray(measured) - np.asarray(target)) / TOLERANCE


def fit_gait(
    gait: int,
    library: GaitLibrary,
    settings: FitSettings = FitSettings(),
    target: np.ndarray | None = None,
    log: Callable[[str], None] | None = None,
) -> tuple[tuple[float, ...], np.ndarray, int]:
    """Fit one gait's (left, right, left_offset, right_offset).

    Returns (row, measured mean (F, T, dH), evaluations)."""
    g = check_gait(gait)
    target = PAPER_TABLE[g] if target is None else np.asarray(target, dtype=float)
    lift = library.rows[g][4]
    model, _ = load_robot(scene=True, model=settings.model)
    limit = thrust_limit_rad(model)
    best: dict = {"cost": np.inf, "x": None, "mean": None, "n": 0}

    def cost(x: np.ndarray) -> float:
        params = tuple(float(v) for v in x)
        left, right, left_offset, right_offset = params
        reach = max(
            abs(left_offset) + library.stride_rad * abs(left),
            abs(right_offset) + library.stride_rad * abs(right),
        )
        penalty = 100.0 * max(0.0, reach - limit) ** 2
        lib = library.with_row(g, (*params, lift))
        per_cycle = measure_gait(g, library=lib, model=model, **settings.walk_kwargs())
        mean = per_cycle[:, :3].mean(axis=0)
        r = scaled_residual(mean, target)
        c = float(r @ r) + penalty
        best["n"] += 1
        if c < best["cost"]:
            best.update(cost=c, x=params, mean=mean)
            if log:
                log(f"gait {g} eval {best['n']}: row {np.round(x, 4)} -> {np.round(mean, 2)}")
            if penalty == 0.0 and np.all(np.abs(r) < settings.stop_residual):
                raise _Done
        if best["n"] >= settings.max_evals:
            raise _Done
        return c

    x0 = np.array(library.rows[g][:4])
    simplex = np.vstack([x0, x0 + np.diag(settings.step)])
    try:
        minimize(cost, x0, method="Nelder-Mead", options={"initial_simplex": simplex})
    except _Done:
        pass
    return (*best["x"], lift), best["mean"], best["n"]


def _fit_one(args: tuple) -> tuple[int, tuple, np.ndarray, int]:
    gait, library, settings = args
    row, mean, n = fit_gait(gait, library, settings)
    return gait, row, mean, n


def fit_library(
    library: GaitLibrary | None = None,
    settings: FitSettings = FitSettings(),
    *,
    gaits: list[int] | None = None,
    workers: int = 1,
    executor: Executor | None = None,
    log: Callable[[str], None] | None = None,
) -> tuple[GaitLibrary, dict]:
    """Fit every gait (or ``gaits``) independently, each one run of ``executor`` (default
    ``make_executor(None, workers)``); ``log`` gets a line as each gait finishes. Returns the
    fitted library and a report ``{gait: {"row", "measured", "evaluations"}}``; raises
    ``infra.executors.BatchError`` naming each gait whose fit failed."""
    library = library or GaitLibrary.load()
    todo = [g for g in (gaits if gaits is not None else range(N_GAITS)) if g not in FIXED_GAITS]
    outcomes: list = [None] * len(todo)
    ex = executor or make_executor(None, workers)
    jobs = [(g, library, settings) for g in todo]
    with contextlib.closing(ex.imap(_fit_one, jobs)) as finished:  # stops workers on Ctrl-C
        for i, outcome in finished:
            outcomes[i] = outcome
            if log is not None and not isinstance(outcome, Failed):
                g, _, mean, n = outcome.value
                log(f"gait {g}: {n} evaluations, measured {np.round(mean, 2)}")
    report = {}
    for g, row, mean, n in values_or_raise(outcomes, [f"gait {g}" for g in todo]):
        library = library.with_row(g, row)
        report[g] = {"row": list(row), "measured": [float(v) for v in mean], "evaluations": n}
    return library, report
