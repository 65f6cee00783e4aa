"""Electrical energy of a gait cycle from the servos' torques and speeds, and the capacitor
voltage drop it causes.

Servo model (``ServoDatasheet``): each of the 12 servos is a permanent-magnet DC motor behind
a lossless gear train, driven by its H-bridge from the supply. Four datasheet values fix it:
supply voltage V, stall torque τ_s, no-load speed ω₀ and idle current I₀ (the control
electronics). At the output shaft the torque constant equals the back-EMF constant,
``k = V / ω₀`` (N·m/A = V·s/rad), and the winding resistance is ``R = V·k / τ_s`` (so the stall
current is ``V / R = τ_s / k``). A servo that exerts torque τ at joint speed ω draws the
motor current ``i = τ / k`` at the motor voltage ``u = R·i + k·ω``, and takes from the supply

    P = V·I₀ + max(0, u·i) = V·I₀ + max(0, R·τ²/k² + τ·ω)        (W)

— idle electronics, copper loss and mechanical power. Power a back-driven servo would generate
(u·i < 0) is not returned to the capacitors (a hobby servo's bridge brakes it away). τ is
MuJoCo's ``actuator_force`` (the servo torque on its joint) and ω its ``actuator_velocity``;
the joint damping the servo works against (``models/servobot``: 0.04 N·m·s/rad, its gear and
motor losses) is part of τ·ω.

Energy of a cycle: ``E = Σ_steps Σ_servos P·Δt`` over the cycle's 800 physics steps (2 ms, the
rectangle rule on MuJoCo's own step). Voltage drop: the capacitor bank (``WorldSettings``:
150 F) holds ``½CV²``; a cycle costing E at voltage V drops it by ``ΔV = E / (C·V)`` to first
order. ``voltage_drop`` linearises at ``V_ref = (charged + empty)/2 = 3.85 V``, the middle of
the SPEC's working range (5.0 → 2.7 V): with it a constant ``ΔV`` per cycle empties a full bank
in exactly the number of cycles the exact ``½CV²`` law gives
(``½C(5.0² − 2.7²) = C·3.85·(5.0 − 2.7)``). At 5.0 V the true drop is 23 % smaller than
``ΔV``, at 2.7 V 43 % larger.

The supply is taken at the datasheet's 4.8 V throughout (the paper's bank is charged to 4.6 V):
the servo model does not follow the capacitor voltage down, and the MuJoCo servos' own torque
and speed limits are the model's (``forcerange``, damping), not this sheet's.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from typing import Any

import mujoco
import numpy as np

from evolve.settings import WorldSettings

KGF_CM_NM = 0.0980665
"""N·m per kgf·cm (servo datasheets give torque in kg·cm)."""


@dataclass(frozen=True)
class ServoDatasheet:
    """One hobby servo's electrical model. Defaults: Hitec HS-311 (the standard analog servo)
    at 4.8 V, from Hitec's datasheet: stall torque 3.0 kg·cm, 0.19 s/60° at no load, idle
    current 7.4 mA."""

    name: str = "Hitec HS-311 at 4.8 V"
    """Which servo and supply the values are for."""
    supply_v: float = 4.8
    """Supply voltage, V [datasheet operating point]."""
    stall_torque_nm: float = 3.0 * KGF_CM_NM
    """Stall torque, N·m (3.0 kg·cm) [datasheet]."""
    no_load_speed_rad_s: float = (math.pi / 3.0) / 0.19
    """No-load speed, rad/s (0.19 s per 60°) [datasheet]."""
    idle_current_a: float = 0.0074
    """Current of a powered servo holding no load, A (7.4 mA) [datasheet]."""

    def __post_init__(self) -> None:
        for f in ("supply_v", "stall_torque_nm", "no_load_speed_rad_s"):
            v = getattr(self, f)
            if not (math.isfinite(v) and v > 0.0):
                raise ValueError(f"servo datasheet: {f} must be a finite number > 0, got {v!r}")
        if not (math.isfinite(self.idle_current_a) and self.idle_current_a >= 0.0):
            raise ValueError(
                f"servo datasheet: idle_current_a must be >= 0, got {self.idle_current_a}"
            )

    @property
    def motor_constant(self) -> float:
        """Torque constant = back-EMF constant at the output shaft, N·m/A (= V·s/rad)."""
        return self.supply_v / self.no_load_speed_rad_s

    @property
    def resistance_ohm(self) -> float:
        """Winding resistance, Ω (stall current = supply / resistance)."""
        return self.supply_v * self.motor_constant / self.stall_torque_nm

    def power_w(self, torque_nm: np.ndarray, speed_rad_s: np.ndarray) -> np.ndarray:
        """Supply power of servos exerting ``torque_nm`` at ``speed_rad_s`` (same shape), W."""
        k, r = self.motor_constant, self.resistance_ohm
        drive = r * (torque_nm / k) ** 2 + torque_nm * speed_rad_s
        return self.supply_v * self.idle_current_a + np.maximum(drive, 0.0)

    def to_dict(self) -> dict[str, Any]:
        derived = {"motor_constant_nm_per_a": self.motor_constant}
        derived["resistance_ohm"] = self.resistance_ohm
        derived["stall_current_a"] = self.supply_v / self.resistance_ohm
        return dataclasses.asdict(self) | derived


HS311 = ServoDatasheet()
"""The default servo model."""


def reference_voltage(world: WorldSettings) -> float:
    """Voltage at which ``voltage_drop`` linearises ½CV²: the middle of the working range, V."""
    return 0.5 * (world.charged_power_v + world.empty_power_v)


def voltage_drop(energy_j: Any, world: WorldSettings | None = None) -> np.ndarray:
    """Capacitor voltage drop of spending ``energy_j`` (J): ``E / (C·V_ref)``, V."""
    world = world or WorldSettings()
    return np.asarray(energy_j, dtype=float) / (world.capacitance_f * reference_voltage(world))


class EnergyMeter:
    """Integrates the 12 servos' supply power step by step (pass ``record`` as ``on_step``).

    ``take()`` returns the energy since the last ``take`` (J) and starts again.
    """

    def __init__(
        self, model: mujoco.MjModel, actuators: np.ndarray, servo: ServoDatasheet = HS311
    ) -> None:
        self.actuators = np.asarray(actuators)
        self.servo = servo
        self.dt = float(model.opt.timestep)
        self._torque: list[np.ndarray] = []
        self._speed: list[np.ndarray] = []

    def record(self, data: mujoco.MjData) -> None:
        """After a physics step: the servos' torque and speed during that step."""
        self._torque.append(data.actuator_force[self.actuators])  # fancy index: a copy
        self._speed.append(data.actuator_velocity[self.actuators])

    def take(self) -> float:
        """Energy drawn from the supply since the last ``take``, J."""
        if not self._torque:
            return 0.0
        power = self.servo.power_w(np.array(self._torque), np.array(self._speed))
        self._torque.clear()
        self._speed.clear()
        return float(power.sum() * self.dt)


def energy_columns(
    energy_j: np.ndarray, energy_std: np.ndarray, world: WorldSettings
) -> np.ndarray:
    """(16, 4) ``evolve.table.ENERGY_COLUMNS`` from per-gait mean and std energy per cycle."""
    return np.column_stack(
        [energy_j, energy_std, voltage_drop(energy_j, world), voltage_drop(energy_std, world)]
    )


def power_model_doc(servo: ServoDatasheet, world: WorldSettings) -> dict[str, Any]:
    """Provenance of the energy columns, saved in the gait table."""
    return {
        "servo": servo.to_dict(),
        "servos": 12,
        "capacitance_f": world.capacitance_f,
        "reference_voltage_v": reference_voltage(world),
        "method": "E per cycle = sum over 12 servos and 2 ms steps of "
        "(V*I_idle + max(0, R*(tau/k)^2 + tau*omega))*dt; dV = E / (C * V_ref)",
    }


__all__ = [
    "HS311",
    "EnergyMeter",
    "ServoDatasheet",
    "energy_columns",
    "power_model_doc",
    "reference_voltage",
    "voltage_drop",
]
