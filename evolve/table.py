"""Gait tables: the paper's Figure 4 (built in) and calibration files measured in MuJoCo.

A gait table is a float64 array of shape (16, 3): row g holds (F, T, dH) of gait g, with F
the forward and T the sideways displacement in cm (T < 0 = left) in the frame the robot had
when the cycle began, and dH the heading change in degrees (< 0 = left, i.e. anticlockwise).

A calibration file may also carry, per gait, the electrical energy of one cycle and the
capacitor voltage drop it causes (``ENERGY_COLUMNS``: ``energy_J``, ``energy_J_std``, ``dV``,
``dV_std``; J and V, mean and per-cycle std), measured by ``calibration.energy``: the
``table`` power model (``evolve.settings.with_table_power``) charges each gait its ``dV``.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from evolve.settings import WorldSettings, with_table_power
from infra.io import read_json

N_GAITS = 16
ROBOT_NAME = "servobot"
"""The ``robot`` field a calibration file must carry to be accepted."""

# Figure 4 of the paper, one row per gait: (F cm, T cm, dH deg).
PAPER_TABLE = np.array(
    [
        (11.6, -0.8, -1.3),  # 0  tripod, slight left
        (11.9, -1.5, -5.0),  # 1
        (10.4, -2.8, -10.3),  # 2
        (8.4, -4.3, -15.8),  # 3
        (6.3, -4.8, -20.3),  # 4
        (5.7, -3.7, -24.7),  # 5  sharpest left turn
        (0.0001, -0.0001, -27.0),  # 6  rotate left in place
        (0.0, 0.0, 0.0),  # 7  stand still
        (11.4, 0.8, 2.7),  # 8  tripod, slight right
        (10.1, 2.3, 6.2),  # 9
        (8.4, 3.5, 11.0),  # 10
        (5.3, 4.0, 16.7),  # 11
        (3.8, 4.3, 20.2),  # 12
        (3.7, 4.0, 24.3),  # 13 sharpest right turn
        (0.0001, 0.0001, 27.0),  # 14 rotate right in place
        (-12.4, 0.5, -1.8),  # 15 walk backwards
    ],
    dtype=np.float64,
)
PAPER_TABLE.setflags(write=False)


ENERGY_COLUMNS = ("energy_J", "energy_J_std", "dV", "dV_std")
"""Columns of ``GaitTable.energy``: energy per cycle (J) and capacitor voltage drop per cycle
(V), each mean and per-cycle standard deviation."""
DV = ENERGY_COLUMNS.index("dV")
"""Column of the mean voltage drop per cycle in ``GaitTable.energy``."""
DV_STD = ENERGY_COLUMNS.index("dV_std")
"""Column of its per-cycle standard deviation."""


class GaitTableError(ValueError):
    """A gait table or gait-table file is malformed."""


@dataclass(frozen=True)
class GaitTable:
    """A (16, 3) table of (F cm, T cm, dH deg) with optional per-cycle spread and provenance."""

    values: np.ndarray
    std: np.ndarray | None = None
    meta: dict[str, Any] = field(default_factory=dict)
    source: str = "paper"
    energy: np.ndarray | None = None
    """(16, 4) per gait, columns ``ENERGY_COLUMNS``; None when the file measured none."""

    @property
    def dv(self) -> np.ndarray | None:
        """Measured capacitor voltage drop per cycle of each gait, (16,) V, or None."""
        return None if self.energy is None else self.energy[:, DV]


def validate_table(values: Any, *, name: str = "gait table") -> np.ndarray:
    """Return ``values`` as a contiguous float64 (16, 3) array or raise ``GaitTableError``."""
    arr = np.asarray(values, dtype=np.float64)
    if arr.shape != (N_GAITS, 3):
        raise GaitTableError(f"{name}: expected shape (16, 3) of (F, T, dH), got {arr.shape}")
    bad = np.argwhere(~np.isfinite(arr))
    if bad.size:
        g, c = bad[0]
        raise GaitTableError(f"{name}: gait {g} has a non-finite {('F', 'T', 'dH')[c]}")
    return np.ascontiguousarray(arr)


def table_from_json(doc: dict[str, Any], *, name: str = "gait table") -> GaitTable:
    """Parse the calibration JSON layout (``{"gaits": [{"gait", "F", "T", "dH", ...}]}``)."""
    if not isinstance(doc, dict) or "gaits" not in doc:
        raise GaitTableError(f"{name}: not a gait-table file (no 'gaits' list)")
    robot = doc.get("robot", ROBOT_NAME)
    if robot != ROBOT_NAME:
        raise GaitTableError(f"{name}: table is for robot {robot!r}, not {ROBOT_NAME!r}")
    units = doc.get("units", {"F": "cm", "T": "cm", "dH": "deg"})
    if units != {"F": "cm", "T": "cm", "dH": "deg"}:
        raise GaitTableError(f"{name}: units must be F, T in cm and dH in deg, got {units}")
    rows = doc["gaits"]
    if not isinstance(rows, list):
        raise GaitTableError(f"{name}: 'gaits' must be a list of 16 rows")
    values = np.full((N_GAITS, 3), math.nan)
    std = np.full((N_GAITS, 3), math.nan)
    has_energy = bool(rows) and isinstance(rows[0], dict) and "dV" in rows[0]
    energy = np.full((N_GAITS, len(ENERGY_COLUMNS)), math.nan) if has_energy else None
    seen: set[int] = set()
    for i, row in enumerate(rows):
        try:
            g = int(row["gait"])
            ftdh = [float(row[k]) for k in ("F", "T", "dH")]
            spread = [float(row.get(k + "_std", math.nan)) for k in ("F", "T", "dH")]
            power = [float(row[k]) for k in ENERGY_COLUMNS] if has_energy else None
        except (KeyError, TypeError, ValueError) as exc:
            raise GaitTableError(f"{name}: row {i} is malformed ({exc!r})") from exc
        if not 0 <= g < N_GAITS:
            raise GaitTableError(f"{name}: row {i} names gait {g}, outside 0-15")
        values[g], std[g] = ftdh, spread
        if energy is not None:
            energy[g] = power
        if g in seen:
            raise GaitTableError(f"{name}: gait {g} appears twice")
        seen.add(g)
    missing = sorted(set(range(N_GAITS)) - seen)
    if missing:
        raise GaitTableError(f"{name}: missing gaits {missing}")
    if energy is not None and not (np.all(np.isfinite(energy)) and np.all(energy >= 0.0)):
        raise GaitTableError(f"{name}: energy and dV must be finite and >= 0 for every gait")
    meta = {k: v for k, v in doc.items() if k != "gaits"}
    return GaitTable(validate_table(values, name=name), std, meta, source=name, energy=energy)


def load_table(spec: str | Path | None = "paper") -> GaitTable:
    """Load a gait table: ``"paper"``/None for Figure 4, else a calibration JSON file path."""
    if spec is None or str(spec) == "paper":
        return GaitTable(PAPER_TABLE.copy(), None, {"source": "Parker & Zbeda, Figure 4"})
    doc = read_json(spec, what="gait-table file", error=GaitTableError)
    return table_from_json(doc, name=str(spec))


POWER_MODELS = ("paper", "table")
"""``WorldSettings.power_model`` choices (``servobot evolve --power``)."""


def with_power_model(world: WorldSettings, power: str, table: GaitTable) -> WorldSettings:
    """``world`` under the power model ``power``: ``"paper"`` (unchanged, SPEC §3) or ``"table"``
    (each gait costs ``table``'s measured ``dV``; ``GaitTableError`` if it has none)."""
    if power not in POWER_MODELS:
        raise GaitTableError(f"power model must be one of {POWER_MODELS}, got {power!r}")
    if power == "paper":
        return dataclasses.replace(world, power_model="paper")
    if table.dv is None:
        raise GaitTableError(
            f"power model 'table' needs a gait table with measured dV per gait; {table.source} "
            "has none (calibrate with servobot calibrate, which measures it)"
        )
    return with_table_power(world, table.dv)


def table_to_json(
    values: np.ndarray,
    std: np.ndarray | None = None,
    *,
    cycles: int = 0,
    energy: np.ndarray | None = None,
    **meta: Any,
) -> dict[str, Any]:
    """Build the calibration JSON document for a (16, 3) table (inverse of ``table_from_json``);
    ``energy`` (16, 4): the ``ENERGY_COLUMNS`` of every gait."""
    values = validate_table(values)
    rows = []
    for g in range(N_GAITS):
        row: dict[str, Any] = {"gait": g}
        row.update(F=float(values[g, 0]), T=float(values[g, 1]), dH=float(values[g, 2]))
        if std is not None:
            row.update(F_std=float(std[g, 0]), T_std=float(std[g, 1]), dH_std=float(std[g, 2]))
        if energy is not None:
            row.update(zip(ENERGY_COLUMNS, (float(v) for v in energy[g]), strict=True))
        row["cycles"] = int(cycles)
        rows.append(row)
    units = {"F": "cm", "T": "cm", "dH": "deg"}
    return {"robot": ROBOT_NAME, "gaits": rows, "units": units, **meta}
