"""Budgets of one reproduction (``ReproduceSettings``) and which of them each stage depends on."""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from calibration.measure import CalibrationSettings
from evolve.settings import GASettings, navigation_ga_settings
from infra.errors import InputError
from servo_mj.robot.model import model_sha256

STAGES = ("calibration", "navigation", "coverage", "validation")
"""The stages of a reproduction, in order (the report is always rewritten)."""


class ReproduceError(InputError, RuntimeError):
    """The run folder cannot be used (other settings, missing inputs); the message says why."""


@dataclass(frozen=True)
class ReproduceSettings:
    """Budgets of one reproduction. Defaults = the paper's scale (SPEC §5, §6)."""

    calibration_cycles: int = 20
    """Measured gait cycles per gait (after ``calibration_settle_cycles``)."""
    calibration_settle_cycles: int = 1
    """Unmeasured cycles each gait walks first."""
    navigation_populations: int = 5
    """Independent navigation populations (SPEC §6)."""
    navigation_population_size: int = 256
    """Individuals per navigation population (SPEC §6)."""
    navigation_generations: int = 1024
    """Navigation generations (SPEC §6)."""
    coverage_populations: int = 5
    """Independent coverage populations; each final best is a finalist (SPEC §5)."""
    coverage_population_size: int = 256
    """Individuals per coverage population (SPEC §5)."""
    coverage_generations: int = 512
    """Coverage generations (SPEC §5)."""
    test_starts: int = 100
    """Fresh start poses of the navigation report and of Figure 9 (SPEC §5, §6)."""
    validate_starts: int = 20
    """Coverage start poses per finalist in the physics validation (issue 4: ≥ 20)."""
    validate_max_steps: int = 600
    """Steps of a validation run (SPEC §5: 600)."""
    validate_navigation_starts: int = 25
    """Navigation runs in the physics validation of the navigation section, twice: from this
    many fresh navigation starts (SPEC §6 region, clear of the station block) and from this
    many of the coverage finalists' hand-off poses and powers (``coverage/handoffs.csv``)."""
    seed: int = 0
    """Seed of every random draw (calibration noise, GA, test and validation starts)."""
    model: str | None = None
    """The robot: None = the shipped ServoBot, else a model file (``servobot variant``) that
    the calibration measures and the validation walks."""

    def calibration(self) -> CalibrationSettings:
        """Settings of the calibration stage (the shipped gait parameters, no fit)."""
        return CalibrationSettings(
            cycles=self.calibration_cycles,
            settle_cycles=self.calibration_settle_cycles,
            seed=self.seed,
            model=self.model,
        )

    def navigation_ga(self) -> GASettings:
        """GA settings of the navigation stage."""
        return navigation_ga_settings(
            populations=self.navigation_populations,
            population_size=self.navigation_population_size,
            generations=self.navigation_generations,
            test_starts=self.test_starts,
            seed=self.seed,
        )

    def coverage_ga(self) -> GASettings:
        """GA settings of the coverage stage."""
        return dataclasses.replace(
            GASettings(),
            populations=self.coverage_populations,
            population_size=self.coverage_population_size,
            generations=self.coverage_generations,
            test_starts=self.test_starts,
            seed=self.seed,
        )

    def to_dict(self) -> dict[str, Any]:
        return dataclasses.asdict(self)


def quick_settings(**overrides: Any) -> ReproduceSettings:
    """A first look in a few minutes on 2 cores: the paper's 5 populations but of 64
    individuals, 256 navigation and 128 coverage generations, 5 calibration cycles, and 3
    full-length (600-step) validation starts per finalist, so that docking and recharging
    show in physics, and 5 + 5 navigation runs."""
    base = ReproduceSettings(
        calibration_cycles=5,
        navigation_population_size=64,
        navigation_generations=256,
        coverage_population_size=64,
        coverage_generations=128,
        validate_starts=3,
        validate_navigation_starts=5,
    )
    return dataclasses.replace(base, **overrides)


_STAGE_FIELDS: dict[str, tuple[str, ...]] = {
    "calibration": ("calibration_cycles", "calibration_settle_cycles", "seed"),
    "navigation": (
        "navigation_populations",
        "navigation_population_size",
        "navigation_generations",
        "test_starts",
    ),
    "coverage": ("coverage_populations", "coverage_population_size", "coverage_generations"),
    "validation": ("validate_starts", "validate_max_steps", "validate_navigation_starts"),
}


def stage_key(settings: ReproduceSettings, stage: str) -> dict[str, Any]:
    """The settings a stage's result depends on: its own fields and those of earlier stages;
    with a model file, its path and content hash too (every stage depends on the robot)."""
    d = settings.to_dict()
    key: dict[str, Any] = {}
    for s in STAGES[: STAGES.index(stage) + 1]:
        key.update({f: d[f] for f in _STAGE_FIELDS[s]})
    if settings.model is not None:
        key.update(model=settings.model, model_sha256=model_sha256(settings.model))
    return key


def check_settings(s: ReproduceSettings) -> None:
    """Every budget is an integer ≥ 1 (settle cycles and seed ≥ 0), else ``ReproduceError``;
    a model file must exist."""
    if s.model is not None and not Path(s.model).is_file():
        raise ReproduceError(f"robot model {s.model}: no such file")
    for f in dataclasses.fields(s):
        if f.name == "model":
            continue
        v = getattr(s, f.name)
        low = 0 if f.name in ("calibration_settle_cycles", "seed") else 1
        if not isinstance(v, int) or v < low:
            raise ReproduceError(f"setting {f.name} must be an integer ≥ {low}, got {v!r}")


__all__ = [
    "STAGES",
    "ReproduceError",
    "ReproduceSettings",
    "check_settings",
    "quick_settings",
    "stage_key",
]
