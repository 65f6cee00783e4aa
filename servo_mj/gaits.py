"""The 16 gait cycles of the ServoBot as documented data (paper §III, Figure 4).

A gait cycle is a list of servo activation frames, each held ``PhysicsSettings.frame_s``
(100 ms). Every walking gait is the same 16-frame tripod pattern (``PATTERN``): tripod A
(LF, RM, LH) is in stance during frames 0-7 while tripod B (RF, LM, RH) swings, then they swap
(B runs the pattern 8 frames later). A gait is one row of four numbers:

- ``left``, ``right``: stride of each side's thrust servos, as a fraction of the full tripod
  sweep ``±stride_rad``. 1 = full stride; ``1 - p`` = the thrust activations of that side
  interrupted for a fraction ``p`` of the cycle (the paper's turn effectors; a continuous
  scale so that the fit is smooth); 0 = thrust fully interrupted; < 0 = reverse thrust.
- ``yaw``: offset of every stance sweep, rad, as if all hips were turned anticlockwise by it
  (left sweeps shift back, right sweeps forward). It makes the feet move sideways during
  stance and so produces the sideways drift T of the turn gaits.
- ``lift``: scale of the lift pattern (1 = tripod lift, 0 = no lift: gait 7 stands still).

Targets, per leg and frame (``u``, ``l`` from ``PATTERN`` at the leg's phase):
``thrust = side * (-yaw) + stride_rad * stride_side * u`` with the left-side centre ``-yaw`` and
the right-side centre ``+yaw``; ``lift = lift_rad * lift * l`` (positive thrust = foot forward,
positive lift = foot up, on both sides). ``GaitLibrary.frames`` expands a row into an
``(n_frames, 12)`` array in actuator order (``constants.actuator_names``).

``DEFAULT_ROWS`` is the hand-set starting point; the fitted rows ship in
``servo_mj/data/gait_params.json`` (``servobot calibrate --fit`` regenerates them).
"""

from __future__ import annotations

import json
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from servo_mj.constants import LEGS, TRIPOD_A

N_GAITS = 16
PARAMS_JSON = Path(__file__).resolve().parent / "data" / "gait_params.json"
"""Shipped fitted gait parameters (loaded by default)."""

STRIDE_RAD = 0.47
"""Half sweep of a full-stride stance, rad [assumed; feasibility study: 11.7 cm/cycle]."""
LIFT_RAD = 0.35
"""Lift of a swinging leg, rad (about 2.8 cm foot clearance) [assumed]."""

# One leg's 16-frame tripod pattern, frame by frame (tripod A's phase; tripod B is shifted 8):
#   u = thrust position in units of the stride (+1 front, -1 back), l = lift (1 up, 0 down).
#   Frames 0-7 stance: sweep front -> back on the ground. Frames 8-15 swing: lift, carry the
#   foot forward in the air, put it down at the front in the last frame.
# fmt: off
#            |------------------ stance -----------------|------------------ swing -------------|
PATTERN_U = (0.75, 0.5, 0.25, 0.0, -0.25, -0.5, -0.75, -1.0, -1.0, -0.5, 0.0, 0.5, 1.0, 1.0, 1.0,
             1.0)
PATTERN_L = (0.0,  0.0, 0.0,  0.0, 0.0,   0.0,  0.0,   0.0,  1.0,  1.0,  1.0, 1.0, 1.0, 1.0, 1.0,
             0.0)
# fmt: on
TRIPOD_SHIFT = 8
"""Tripod B runs the pattern this many frames after tripod A."""

PARAM_NAMES = ("left", "right", "yaw", "lift")

# fmt: off
# gait: (left, right, yaw rad, lift)   kind                     [hand-set start, fitted in JSON]
DEFAULT_ROWS: dict[int, tuple[float, float, float, float]] = {
    0:  (0.95, 1.00, 0.02, 1.0),   # tripod, slight left turn (left thrust 5 % interrupted)
    1:  (0.80, 1.00, 0.05, 1.0),   # left turn
    2:  (0.55, 1.00, 0.10, 1.0),   # left turn
    3:  (0.30, 1.00, 0.15, 1.0),   # left turn
    4:  (0.05, 1.00, 0.20, 1.0),   # left turn
    5:  (-0.20, 1.00, 0.20, 1.0),  # sharpest left turn (a little reverse thrust on the left)
    6:  (-0.60, 0.60, 0.00, 1.0),  # rotate left in place (sides thrust in opposite directions)
    7:  (0.00, 0.00, 0.00, 0.0),   # stand still
    8:  (1.00, 0.95, -0.02, 1.0),  # tripod, slight right turn
    9:  (1.00, 0.80, -0.05, 1.0),  # right turn
    10: (1.00, 0.55, -0.10, 1.0),  # right turn
    11: (1.00, 0.30, -0.15, 1.0),  # right turn
    12: (1.00, 0.05, -0.20, 1.0),  # right turn
    13: (1.00, -0.20, -0.20, 1.0), # sharpest right turn
    14: (0.60, -0.60, 0.00, 1.0),  # rotate right in place
    15: (-1.00, -1.00, 0.00, 1.0), # walk backwards
}
# fmt: on
GAIT_KIND = {
    **{g: "left turn" for g in range(6)},
    6: "rotate left",
    7: "stand still",
    **{g: "right turn" for g in range(8, 14)},
    14: "rotate right",
    15: "backwards",
}


def check_gait(gait: Any) -> int:
    """Return ``gait`` as an int in 0-15 or raise ``ValueError`` naming it."""
    try:
        g = int(gait)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"gait must be an integer 0-15, got {gait!r}") from exc
    if g != gait or not 0 <= g < N_GAITS:
        raise ValueError(f"unknown gait {gait!r}: gaits are numbered 0-15")
    return g


def _leg_phase_matrix() -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per frame and leg: pattern u, pattern l (16, 6), and side sign (+1 left, -1 right)."""
    n = len(PATTERN_U)
    u = np.empty((n, len(LEGS)))
    lift = np.empty((n, len(LEGS)))
    for j, leg in enumerate(LEGS):
        shift = 0 if leg in TRIPOD_A else TRIPOD_SHIFT
        idx = (np.arange(n) + shift) % n
        u[:, j] = np.asarray(PATTERN_U)[idx]
        lift[:, j] = np.asarray(PATTERN_L)[idx]
    side = np.array([1.0 if leg[0] == "L" else -1.0 for leg in LEGS])
    return u, lift, side


@dataclass(frozen=True)
class GaitLibrary:
    """The 16 gait rows plus the pattern amplitudes; expands rows into servo frames."""

    rows: Mapping[int, tuple[float, float, float, float]] = field(
        default_factory=lambda: dict(DEFAULT_ROWS)
    )
    stride_rad: float = STRIDE_RAD
    lift_rad: float = LIFT_RAD
    meta: Mapping[str, Any] = field(default_factory=dict)

    def __post_init__(self) -> None:
        rows = {check_gait(g): tuple(float(v) for v in r) for g, r in dict(self.rows).items()}
        missing = sorted(set(range(N_GAITS)) - set(rows))
        if missing:
            raise ValueError(f"gait library is missing gaits {missing}")
        for g, r in rows.items():
            if len(r) != len(PARAM_NAMES) or not np.all(np.isfinite(r)):
                raise ValueError(f"gait {g}: expected 4 finite numbers {PARAM_NAMES}, got {r}")
        object.__setattr__(self, "rows", rows)

    @classmethod
    def default(cls) -> GaitLibrary:
        """The hand-set, unfitted rows of ``DEFAULT_ROWS``."""
        return cls()

    @classmethod
    def load(cls, path: str | Path | None = None) -> GaitLibrary:
        """Load gait parameters from JSON (default: the shipped fitted ``gait_params.json``)."""
        path = Path(path) if path is not None else PARAMS_JSON
        try:
            doc = json.loads(path.read_text())
        except FileNotFoundError as exc:
            raise ValueError(f"{path}: no such gait-parameter file") from exc
        except json.JSONDecodeError as exc:
            raise ValueError(f"{path}: not valid JSON ({exc})") from exc
        return cls.from_dict(doc, name=str(path))

    @classmethod
    def from_dict(cls, doc: Mapping[str, Any], *, name: str = "gait parameters") -> GaitLibrary:
        """Parse the ``gait_params.json`` layout (inverse of ``to_dict``)."""
        try:
            rows = {int(r["gait"]): tuple(float(r[k]) for k in PARAM_NAMES) for r in doc["gaits"]}
            stride, lift = float(doc["stride_rad"]), float(doc["lift_rad"])
        except (KeyError, TypeError, ValueError) as exc:
            raise ValueError(f"{name}: malformed gait-parameter file ({exc!r})") from exc
        meta = {k: v for k, v in doc.items() if k not in ("gaits", "stride_rad", "lift_rad")}
        try:
            return cls(rows, stride, lift, meta)
        except ValueError as exc:
            raise ValueError(f"{name}: {exc}") from exc

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready parameters: amplitudes, pattern, leg order and the 16 rows."""
        gaits = [
            {"gait": g, "kind": GAIT_KIND[g], **dict(zip(PARAM_NAMES, self.rows[g], strict=True))}
            for g in range(N_GAITS)
        ]
        return {
            **dict(self.meta),
            "legs": list(LEGS),
            "pattern_u": list(PATTERN_U),
            "pattern_l": list(PATTERN_L),
            "stride_rad": self.stride_rad,
            "lift_rad": self.lift_rad,
            "gaits": gaits,
        }

    def with_row(self, gait: int, row: tuple[float, float, float, float]) -> GaitLibrary:
        """A copy with one gait's row replaced."""
        rows = dict(self.rows)
        rows[check_gait(gait)] = tuple(float(v) for v in row)
        return GaitLibrary(rows, self.stride_rad, self.lift_rad, dict(self.meta))

    def frames(self, gait: int) -> np.ndarray:
        """Servo targets of one cycle of ``gait``: (n_frames, 12) rad, actuator order."""
        left, right, yaw, lift = self.rows[check_gait(gait)]
        u, lv, side = _leg_phase_matrix()
        stride = np.where(side > 0, left, right)
        thrust = -side * yaw + self.stride_rad * stride * u
        out = np.empty((u.shape[0], 2 * len(LEGS)))
        out[:, 0::2] = thrust
        out[:, 1::2] = self.lift_rad * lift * lv
        return out

    @staticmethod
    def home() -> np.ndarray:
        """Servo targets of the home posture (all joints at 0), (12,) rad."""
        return np.zeros(2 * len(LEGS))
