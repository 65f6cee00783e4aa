"""Physics settings of the MuJoCo ServoBot (how gaits are executed), as a frozen dataclass.

Every value is [chosen] for this reproduction unless its docstring says otherwise; the robot's
own dimensions, masses and servo parameters live in ``models/servobot/servobot.xml`` (their
provenance is in that folder's README). Units: seconds, radians, metres where stated.
Override with ``dataclasses.replace``.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import Any


@dataclass(frozen=True)
class PhysicsSettings:
    """How the executor drives the physics (SPEC §3 "In MuJoCo")."""

    timestep_s: float = 0.002
    """MuJoCo time step, s [chosen]. The executor sets ``model.opt.timestep`` to it."""
    frame_s: float = 0.1
    """Duration of one servo activation frame, s [paper: activations held 100 ms]."""
    settle_s: float = 0.5
    """After ``place``: time standing in the home posture before the first gait, s [chosen]."""
    servo_noise_rad: float = 0.02
    """Std of Gaussian noise added to every *new* servo target, rad [chosen]; 0 = off (exactly
    repeatable cycles). Default = ``CALIBRATION_NOISE_RAD``: the gait table is the mean of
    cycles measured under this noise, so physics runs (validation) walk under the conditions the
    table describes; each run's noise comes from its own seeded generator, so results stay
    repeatable bit for bit. Measured (docs/validation.md "Reality gap"): 5 finalists × 20
    starts, gap +4.1 pp with 0.02 vs +9.0 pp noise-free. Calibration sets its own ``--noise``."""
    upright_min: float = 0.3
    """Torso up-axis z component below this counts as flipped (PhysicsError) [chosen]."""
    max_speed_m_s: float = 20.0
    """Any joint speed above this (m/s or rad/s) counts as diverged (PhysicsError) [chosen]."""
    floor_z_m: float = 0.0
    """Height of the floor the robot is placed on, m [chosen]."""
    drop_clearance_m: float = 0.0005
    """``place`` puts the lowest foot this far above the floor before settling, m [chosen]."""

    @property
    def substeps(self) -> int:
        """Physics steps per servo frame (``frame_s / timestep_s``, must be a whole number)."""
        n = round(self.frame_s / self.timestep_s)
        if n < 1 or abs(n * self.timestep_s - self.frame_s) > 1e-9:
            raise ValueError(
                f"frame_s={self.frame_s} is not a whole number of timestep_s={self.timestep_s}"
            )
        return n

    def to_dict(self) -> dict[str, Any]:
        return dataclasses.asdict(self)


CALIBRATION_NOISE_RAD = 0.02
"""Default servo-target noise of a calibration, rad (about a hobby servo's 1° deadband)
[chosen]: it makes the per-cycle standard deviation a real spread rather than 0."""

__all__ = ["PhysicsSettings", "CALIBRATION_NOISE_RAD"]
