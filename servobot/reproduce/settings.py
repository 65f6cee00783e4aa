"""Budgets of one reproduction (``ReproduceSettings``) and which of them each stage depends on."""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from calibration.calibrate import TABLE_FILE
from calibration.measure import CalibrationSettings
from evolve.envelope import NONE, Envelope, load_envelope
from evolve.settings import (
    BLOCKING_RULES,
    ColonySettings,
    GASettings,
    SettingsError,
    coverage_ga_settings,
    navigation_ga_settings,
)
from infra.errors import InputError
from servo_mj.robot.model import check_model, model_sha256
from servobot.robustness.matrix import RobustnessSettings
from servobot.robustness.worlds import BUILT_IN

COLONY_STAGES = ("colony", "colony_validation")
"""The colony stages (SPEC §7), run only with ``ReproduceSettings.robots`` ≥ 2."""
STAGES = ("calibration", "navigation", "coverage", "validation", "robustness", *COLONY_STAGES)
"""The stages of a reproduction, in order (the report is always rewritten)."""
COLONY_OPTIONS = ("colony_fitness", "colony_start_power_spread", "colony_robots_seen",
                  "colony_contact_yaw_deg")
"""The colony's learning options (``ColonySettings`` fields): left out of
``ReproduceSettings.to_dict`` at their defaults, so a colony run folder made before they
existed resumes."""
COLONY_FIELDS = ("robots", "colony_blocking", "colony_validate_starts", *COLONY_OPTIONS)
"""The settings of the colony stages: left out of ``ReproduceSettings.to_dict`` (so of
``settings.json`` and every stage key) without a colony, as before they existed."""
ROBUSTNESS_WORLDS = tuple(BUILT_IN)
"""The physics worlds of the robustness stage: every built-in world of the test matrix."""


class ReproduceError(InputError, RuntimeError):
    """The run folder cannot be used (other settings, missing inputs); the message says why."""


@dataclass(frozen=True)
class ReproduceSettings:
    """Budgets of one reproduction. Defaults = the paper's scale (SPEC §5, §6), in the exact
    table world (``envelope`` ``none``), with a robustness matrix of 2 starts × 6 worlds × 5
    finalists (``robustness_starts``)."""

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
    robustness_starts: int = 2
    """Start poses per finalist per physics world in the robustness stage (the physics test
    matrix, SPEC §9: coverage finalists × every built-in world of
    ``servobot.robustness.worlds``, ``robustness_steps`` steps, the table world beside).
    Default 2: 2 × 6 worlds × 5 finalists = 60 physics runs, 10 per world. Budget: the whole
    reproduction within 1.3 × its wall time without the stage (issue 16), ≈ 30 % more physics
    than the validation stage's 100 coverage + 50 navigation runs: the matrix's runs go to
    the workers as one batch (``servobot.validation.lone.execute``), so it costs its runs'
    CPU time over the workers, and the heavy, weak and slippery robots' runs end early.
    Measured: 219 s of a 16.6-min reproduction, 1.28 × the stages before it (docs/robustness.md,
    "Why 2 starts")."""
    robustness_steps: int = 600
    """Steps of a robustness run (SPEC §5: 600, as the validation's)."""
    robustness_finalists: int = 5
    """How many coverage finalists the robustness stage runs (at most ``coverage_populations``),
    the best first by their Figure 9 test at the last generation (``coverage/summary.json``
    ``final_inner_percent``; ties by population index). Default every one of the 5."""

    def matrix_finalists(self) -> int:
        """The finalists the robustness matrix runs."""
        return min(self.robustness_finalists, self.coverage_populations)
    envelope: str = "none"
    """Envelope of variation (SPEC §9) that navigation and coverage evolve in: ``none`` (the
    exact world of SPEC §3: the reproduction as before, bit for bit), ``default``
    (``evolve.envelope.DEFAULT``) or a JSON file of ``Envelope`` fields. The stages then report
    Figure 9 and docking in the envelope beside the exact world; calibration, validation and
    the robustness matrix are unchanged (the finalists they run differ)."""
    seed: int = 0
    """Seed of every random draw (calibration noise, GA, test, validation and matrix starts)."""
    model: str | None = None
    """The robot: None = the shipped ServoBot, else a model file (``servobot variant``) that
    the calibration measures and the validation walks."""
    robots: int = 1
    """Robots of the colony stages (SPEC §7), R. 1 (default): no colony stages, the
    reproduction as before, bit for bit (``settings.json`` too: ``COLONY_FIELDS`` are left
    out). R ≥ 2 adds, after robustness, ``colony`` (coverage learned by a colony of R sharing
    the station, as ``servobot evolve colony``: the coverage stage's GA budget and test starts,
    the navigation section of ``navigation/best.txt`` fixed, the calibrated table, the
    envelope) and ``colony_validation`` (each colony finalist as a colony of R in physics, as
    ``servobot validate --robots R``)."""
    colony_blocking: str = ColonySettings().blocking
    """The table world's rule for a move another robot blocks (``ColonySettings.blocking``):
    ``cancel`` (SPEC §7) or ``slide``; the colony evolves under it and the colony validation's
    table side runs it (physics blocks by contacts either way)."""
    colony_fitness: str = ColonySettings().fitness
    """What a colony run scores in the colony stage (``ColonySettings.fitness``, its weights at
    their defaults): ``squares`` (SPEC §7, default), ``alive``, ``per_step``, ``docks`` or
    ``alive_docks``."""
    colony_start_power_spread: float = ColonySettings().start_power_spread
    """Volts between the robots' start powers (``ColonySettings.start_power_spread``; 0,
    default: every robot on 4.0 V), in the colony stage and both worlds of its validation."""
    colony_robots_seen: bool = ColonySettings().robots_seen
    """Whether the object sensors see the other robots (``ColonySettings.robots_seen``; True,
    default, SPEC §7), in the colony stage and both worlds of its validation."""
    colony_contact_yaw_deg: float = ColonySettings().contact_yaw_deg
    """How far a blocked move turns the robot away from a robot abeam, degrees
    (``ColonySettings.contact_yaw_deg``; 0, default), in the colony stage and the table side
    of its validation."""
    colony_validate_starts: int = 3
    """Colony starts (R poses each, ``evolve.starts.colony_starts``, seeded) per colony
    finalist in the physics colony validation, ``validate_max_steps`` gait steps per robot at
    most. Default 3: 5 finalists × 3 = 15 colony runs. A colony-of-3 run costs about 6.6 lone
    runs of physics (each robot step ≈ 2.2 lone gait cycles, the standing robots simulated
    too: docs/colony.md, "Cost"), so ≈ 100 lone runs: the physics of the validation stage's
    100 coverage runs, not more; the gap it measures is a mean over 15 colony runs (45 robot
    runs), against 30 in docs/colony.md's measurement."""

    def colony(self) -> ColonySettings | None:
        """The colony of the colony stages; None without them (``robots`` < 2)."""
        return self._colony_settings() if self.robots >= 2 else None

    def _colony_settings(self) -> ColonySettings:
        """The ``ColonySettings`` of the colony fields (``SettingsError`` naming a bad one)."""
        return ColonySettings(
            robots=self.robots, blocking=self.colony_blocking, fitness=self.colony_fitness,
            start_power_spread=self.colony_start_power_spread,
            robots_seen=self.colony_robots_seen, contact_yaw_deg=self.colony_contact_yaw_deg,
        )  # fmt: skip

    def stages(self) -> tuple[str, ...]:
        """The stages this reproduction runs, in order: the colony stages only with a colony."""
        return STAGES if self.colony() is not None else STAGES[: -len(COLONY_STAGES)]

    def calibration(self) -> CalibrationSettings:
        """Settings of the calibration stage (the shipped gait parameters, no fit)."""
        return CalibrationSettings(
            cycles=self.calibration_cycles,
            settle_cycles=self.calibration_settle_cycles,
            seed=self.seed,
            model=self.model,
        )

    def _ga(self, base: GASettings, populations: int, size: int, generations: int) -> GASettings:
        """``base`` (a stage's GA settings) with the stage's budget — ``populations`` of
        ``size`` individuals over ``generations`` — and the shared test starts and seed."""
        return dataclasses.replace(
            base, populations=populations, population_size=size, generations=generations,
            test_starts=self.test_starts, seed=self.seed,
        )  # fmt: skip

    def navigation_ga(self) -> GASettings:
        """GA settings of the navigation stage."""
        return self._ga(
            navigation_ga_settings(), self.navigation_populations,
            self.navigation_population_size, self.navigation_generations,
        )  # fmt: skip

    def coverage_ga(self) -> GASettings:
        """GA settings of the coverage stage."""
        return self._ga(
            coverage_ga_settings(in_envelope=self.envelope_value() != NONE),
            self.coverage_populations, self.coverage_population_size, self.coverage_generations,
        )  # fmt: skip

    def envelope_value(self) -> Envelope:
        """The ``Envelope`` of ``envelope`` (``EnvelopeError`` naming a bad file)."""
        return load_envelope(self.envelope)

    def robustness(self, out: Path) -> RobustnessSettings:
        """Settings of the robustness stage's matrix into ``out/robustness``: every built-in
        world, ``robustness_starts`` starts of ``robustness_steps`` steps, the run's seed, the
        calibrated table ``out/calibration/gait_table.json``, no recordings."""
        return RobustnessSettings(
            worlds=ROBUSTNESS_WORLDS,
            starts=self.robustness_starts,
            steps=self.robustness_steps,
            seed=self.seed,
            table=str(Path(out) / "calibration" / TABLE_FILE),
            rrd=False,
        )

    def to_dict(self) -> dict[str, Any]:
        """The fields as a dict; without a colony, not ``COLONY_FIELDS``; ``COLONY_OPTIONS``
        only where they differ from their defaults."""
        d = dataclasses.asdict(self)
        defaults = ReproduceSettings()
        for f in COLONY_FIELDS if self.robots < 2 else COLONY_OPTIONS:
            if self.robots < 2 or d[f] == getattr(defaults, f):
                del d[f]
        return d


def quick_settings(**overrides: Any) -> ReproduceSettings:
    """A first look in a few minutes on 2 cores: the paper's 5 populations but of 64
    individuals, 256 navigation and 128 coverage generations, 5 calibration cycles, and 3
    full-length (600-step) validation starts per finalist, so that docking and recharging
    show in physics, 5 + 5 navigation runs, a robustness matrix of 1 start of 300 steps
    of the best finalist per world (6 runs, ≈ 30 % of the validation's physics steps: 1.3 ×
    the wall time without the matrix was the budget), and with a colony 1 colony start per
    colony finalist (5 colony runs)."""
    base = ReproduceSettings(
        calibration_cycles=5,
        navigation_population_size=64,
        navigation_generations=256,
        coverage_population_size=64,
        coverage_generations=128,
        validate_starts=3,
        validate_navigation_starts=5,
        robustness_starts=1,
        robustness_finalists=1,
        robustness_steps=300,
        colony_validate_starts=1,
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
    "robustness": ("robustness_starts", "robustness_steps", "robustness_finalists"),
    "colony": ("robots", "colony_blocking", *COLONY_OPTIONS),
    "colony_validation": ("colony_validate_starts", "validate_max_steps"),
}
_ENVELOPE_STAGES = STAGES[STAGES.index("navigation") :]
"""The stages an envelope affects: navigation, coverage and those after them."""


def _depends_on(stage: str) -> tuple[str, ...]:
    """The stages whose settings ``stage``'s result depends on, itself last: those before it;
    the colony stages branch off after coverage (the colony evolves from the coverage stage's
    budgets, not from the validation's or the matrix's)."""
    if stage in COLONY_STAGES:
        return (*STAGES[: STAGES.index("coverage") + 1],
                *COLONY_STAGES[: COLONY_STAGES.index(stage) + 1])  # fmt: skip
    return STAGES[: STAGES.index(stage) + 1]


def stage_key(settings: ReproduceSettings, stage: str) -> dict[str, Any]:
    """The settings a stage's result depends on: its own fields and those of earlier stages
    (``_depends_on``);
    with a model file, its path and content hash too (every stage depends on the robot); from
    navigation on, an envelope other than ``none``: its spec and its fields (a stage of the
    exact world keeps the key it had before envelopes existed)."""
    d = settings.to_dict()
    key: dict[str, Any] = {}
    for s in _depends_on(stage):
        key.update({f: d[f] for f in _STAGE_FIELDS[s] if f in d})
    if settings.model is not None:
        key.update(model=settings.model, model_sha256=model_sha256(settings.model))
    envelope = settings.envelope_value()
    if stage in _ENVELOPE_STAGES and envelope != NONE:
        key.update(envelope=settings.envelope, envelope_fields=envelope.to_dict())
    return key


def check_settings(s: ReproduceSettings) -> None:
    """Every budget is an integer ≥ 1 (settle cycles and seed ≥ 0; ``robots`` 1 = no colony),
    the blocking rule one of ``BLOCKING_RULES`` and the colony options valid
    (``ColonySettings``), else ``ReproduceError``;
    a model file must be a usable ServoBot model (``check_model``); the envelope must load
    (``EnvelopeError`` naming it)."""
    if s.model is not None:
        check_model(s.model)  # ModelFileError (an InputError) naming the file
    if not isinstance(s.envelope, str):
        raise ReproduceError(f"setting envelope must be none, default or a file, got "
                             f"{s.envelope!r}")  # fmt: skip
    s.envelope_value()
    if s.colony_blocking not in BLOCKING_RULES:
        raise ReproduceError(f"setting colony_blocking must be one of {', '.join(BLOCKING_RULES)}"
                             f", got {s.colony_blocking!r}")  # fmt: skip
    try:
        s._colony_settings()
    except SettingsError as exc:
        raise ReproduceError(f"colony settings: {exc}") from None
    for f in dataclasses.fields(s):
        if f.name in ("model", "envelope", "colony_blocking", *COLONY_OPTIONS):
            continue
        v = getattr(s, f.name)
        low = 0 if f.name in ("calibration_settle_cycles", "seed") else 1
        if not isinstance(v, int) or v < low:
            raise ReproduceError(f"setting {f.name} must be an integer ≥ {low}, got {v!r}")


__all__ = [
    "COLONY_FIELDS",
    "COLONY_OPTIONS",
    "COLONY_STAGES",
    "ROBUSTNESS_WORLDS",
    "STAGES",
    "ReproduceError",
    "ReproduceSettings",
    "check_settings",
    "quick_settings",
    "stage_key",
]
