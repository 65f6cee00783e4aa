"""The 16 gait cycles of the ServoBot as documented data (paper §III, Figure 4).

A gait cycle is a list of servo activation frames, each held ``PhysicsSettings.frame_s``
(100 ms). Every walking gait is the same 16-frame tripod pattern (``PATTERN``), which starts
and ends in the home posture: tripod A (LF, RM, LH) strides in the middle of the cycle,
tripod B (RF, LM, RH) in its first and last quarter. A gait is one row of five numbers:

- ``left``, ``right``: stride of each side's thrust servos, as a fraction of the full tripod
  sweep ``±stride_rad``. 1 = full stride; ``1 - p`` = the thrust activations of that side
  interrupted for a fraction ``p`` of the cycle (the paper's turn effectors; a continuous
  scale so that the fit is smooth); 0 = thrust fully interrupted; < 0 = reverse thrust.
- ``left_offset``, ``right_offset``: forward offset of each side's sweep, rad (the sweep runs
  ``offset ± stride * stride_rad``). A forward-shifted sweep moves the stance feet outward as
  they go back, pushing the body toward the other side: on the thrusting side of a turn it
  produces the sideways drift T of the turn gaits.
- ``lift``: scale of the lift pattern (1 = tripod lift, 0 = no lift: gait 7 stands still).

Targets, per leg and frame (``u``, ``l``, ``y`` from ``PATTERN`` for the leg's tripod):
``thrust = offset_side * y + stride_rad * stride_side * u``;
``lift = lift_rad * lift * l`` (positive thrust = foot forward,
positive lift = foot up, on both sides). ``GaitLibrary.frames`` expands a row into an
``(n_frames, 12)`` array in actuator order (``constants.actuator_names``).

``DEFAULT_ROWS`` is the hand-set starting point; the fitted rows ship in
``servo_mj/data/gait_params.json`` (``servobot calibrate --fit`` regenerates them).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from infra.errors import InputError
from infra.io import read_json
from servo_mj.robot.constants import LEGS, TRIPOD_A

N_GAITS = 16
PARAMS_JSON = Path(__file__).resolve().parent / "data" / "gait_params.json"
"""Shipped fitted gait parameters (loaded by default)."""

STRIDE_RAD = 0.47
"""Half sweep of a full-stride stance, rad [assumed; feasibility study: 11.7 cm/cycle]."""
LIFT_RAD = 0.35
"""Lift of a swinging leg, rad (about 2.8 cm foot clearance) [assumed]."""
MAX_TARGET_RAD = math.pi
"""Largest |servo target| a gait may command, rad [chosen: generous]. The joints reach
±1.05 rad (thrust) and −0.6…0.8 rad (lift) and clamp targets beyond; a target past half a
turn is not a gait but a broken parameter file."""

# The 16-frame tripod pattern, one line per frame (100 ms each). A gait cycle starts and ends
# in the home posture (all legs at 0, all feet down), as the paper defines a gait cycle: the
# legs "begin moving and eventually return to their original position". So a cycle does not
# depend on which gait ran before it. Per tripod: u = thrust position in units of the stride
# (+1 front, -1 back), l = lift (1 up, 0 down), y = share of the side's offset (0 at home).
# Tripod A swings home -> front, strides front -> back, swings back -> home; tripod B strides
# home -> back, swings back -> front, strides front -> home. Each tripod strides 2 units.
# fmt: off
PATTERN: tuple[tuple[float, ...], ...] = (
    # uA     lA   yA     uB     lB   yB        A            B
    (0.5,   1.0, 0.5,  -0.25,  0.0, 0.25),  # swing        stance
    (1.0,   1.0, 1.0,  -0.5,   0.0, 0.5),   # swing        stance
    (1.0,   1.0, 1.0,  -0.75,  0.0, 0.75),  # swing        stance
    (1.0,   0.0, 1.0,  -1.0,   0.0, 1.0),   # touch down   stance end
    (0.75,  0.0, 1.0,  -1.0,   1.0, 1.0),   # stance       lift
    (0.5,   0.0, 1.0,  -0.5,   1.0, 1.0),   # stance       swing
    (0.25,  0.0, 1.0,   0.0,   1.0, 1.0),   # stance       swing
    (0.0,   0.0, 1.0,   0.5,   1.0, 1.0),   # stance       swing
    (-0.25, 0.0, 1.0,   1.0,   1.0, 1.0),   # stance       swing
    (-0.5,  0.0, 1.0,   1.0,   1.0, 1.0),   # stance       swing
    (-0.75, 0.0, 1.0,   1.0,   1.0, 1.0),   # stance       swing
    (-1.0,  0.0, 1.0,   1.0,   0.0, 1.0),   # stance end   touch down
    (-1.0,  1.0, 1.0,   0.75,  0.0, 0.75),  # lift         stance
    (-0.5,  1.0, 0.5,   0.5,   0.0, 0.5),   # swing        stance
    (0.0,   1.0, 0.0,   0.25,  0.0, 0.25),  # swing        stance
    (0.0,   0.0, 0.0,   0.0,   0.0, 0.0),   # home         home
)
# fmt: on

PARAM_NAMES = ("left", "right", "left_offset", "right_offset", "lift")

# fmt: off
# gait: (left, right, left_offset, right_offset rad, lift)   [hand-set start, fitted in JSON]
DEFAULT_ROWS: dict[int, tuple[float, float, float, float, float]] = {
    0:  (0.95, 1.00, 0.00, 0.02, 1.0),    # tripod, slight left turn (left thrust 5 % cut)
    1:  (0.80, 1.05, 0.00, 0.10, 1.0),    # left turn
    2:  (0.55, 1.10, 0.00, 0.20, 1.0),    # left turn
    3:  (0.35, 1.15, 0.00, 0.35, 1.0),    # left turn
    4:  (0.15, 1.15, 0.00, 0.50, 1.0),    # left turn
    5:  (-0.05, 1.15, 0.00, 0.50, 1.0),   # sharpest left turn (a little reverse thrust)
    6:  (-0.65, 0.65, 0.00, 0.00, 1.0),   # rotate left in place (sides thrust oppositely)
    7:  (0.00, 0.00, 0.00, 0.00, 0.0),    # stand still
    8:  (1.00, 0.95, 0.02, 0.00, 1.0),    # tripod, slight right turn
    9:  (1.05, 0.80, 0.10, 0.00, 1.0),    # right turn
    10: (1.10, 0.55, 0.20, 0.00, 1.0),    # right turn
    11: (1.15, 0.35, 0.35, 0.00, 1.0),    # right turn
    12: (1.15, 0.15, 0.50, 0.00, 1.0),    # right turn
    13: (1.15, -0.05, 0.50, 0.00, 1.0),   # sharpest right turn
    14: (0.65, -0.65, 0.00, 0.00, 1.0),   # rotate right in place
    15: (-1.05, -1.05, 0.00, 0.00, 1.0),  # walk backwards
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


class GaitParamsError(InputError, ValueError):
    """A gait-parameter file or library is malformed; the message names it and the problem."""


def check_gait(gait: Any) -> int:
    """Return ``gait`` as an int in 0-15 or raise ``ValueError`` naming it."""
    try:
        if isinstance(gait, bool):
            raise TypeError("a boolean")
        g = int(gait)
    except (TypeError, ValueError, OverflowError) as exc:
        raise ValueError(f"gait must be an integer 0-15, got {gait!r}") from exc
    if g != gait or not 0 <= g < N_GAITS:
        raise ValueError(f"unknown gait {gait!r}: gaits are numbered 0-15")
    return g


def _number(v: Any, key: str) -> float:
    """A JSON number as a float (strings and booleans refused)."""
    if isinstance(v, bool) or not isinstance(v, int | float):
        raise ValueError(f"{key} must be a number, got {v!r:.40}")
    return float(v)


def _leg_phase_matrix() -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Per frame and leg (16, 6): pattern u, l, y; and the side sign (+1 left, -1 right)."""
    table = np.asarray(PATTERN)
    cols = [(0, 1, 2) if leg in TRIPOD_A else (3, 4, 5) for leg in LEGS]
    u = np.stack([table[:, c[0]] for c in cols], axis=1)
    lift = np.stack([table[:, c[1]] for c in cols], axis=1)
    y = np.stack([table[:, c[2]] for c in cols], axis=1)
    side = np.array([1.0 if leg[0] == "L" else -1.0 for leg in LEGS])
    return u, lift, y, side


@dataclass(frozen=True)
class GaitLibrary:
    """The 16 gait rows plus the pattern amplitudes; expands rows into servo frames."""

    rows: Mapping[int, tuple[float, ...]] = field(default_factory=lambda: dict(DEFAULT_ROWS))
    stride_rad: float = STRIDE_RAD
    lift_rad: float = LIFT_RAD
    meta: Mapping[str, Any] = field(default_factory=dict)

    def __post_init__(self) -> None:
        rows = {check_gait(g): tuple(float(v) for v in r) for g, r in dict(self.rows).items()}
        missing = sorted(set(range(N_GAITS)) - set(rows))
        if missing:
            raise GaitParamsError(f"gait library is missing gaits {missing}")
        for g, r in rows.items():
            if len(r) != len(PARAM_NAMES) or not np.all(np.isfinite(r)):
                raise GaitParamsError(f"gait {g}: expected finite numbers {PARAM_NAMES}, got {r}")
        for name in ("stride_rad", "lift_rad"):
            v = getattr(self, name)
            if not 0.0 < v <= MAX_TARGET_RAD:
                raise GaitParamsError(f"{name} must lie in (0, {MAX_TARGET_RAD:.4g}] rad, got {v}")
        object.__setattr__(self, "rows", rows)
        for g in range(N_GAITS):
            peak = float(np.abs(self.frames(g)).max())
            if peak > MAX_TARGET_RAD:
                raise GaitParamsError(
                    f"gait {g} commands a servo target of {peak:.3g} rad, beyond "
                    f"±{MAX_TARGET_RAD:.4g} rad"
                )

    @classmethod
    def default(cls) -> GaitLibrary:
        """The hand-set, unfitted rows of ``DEFAULT_ROWS``."""
        return cls()

    @classmethod
    def load(cls, path: str | Path | None = None) -> GaitLibrary:
        """Load gait parameters from JSON (default: the shipped fitted ``gait_params.json``)."""
        path = Path(path) if path is not None else PARAMS_JSON
        doc = read_json(path, what="gait-parameter file", error=GaitParamsError)
        return cls.from_dict(doc, name=str(path))

    @classmethod
    def from_dict(cls, doc: Mapping[str, Any], *, name: str = "gait parameters") -> GaitLibrary:
        """Parse the ``gait_params.json`` layout (inverse of ``to_dict``); ``GaitParamsError``
        naming ``name`` and the problem."""
        try:
            if not isinstance(doc, Mapping) or not isinstance(doc.get("gaits"), list):
                raise TypeError("not a gait-parameter file (no 'gaits' list)")
            rows = {}
            for r in doc["gaits"]:
                g = check_gait(r["gait"]) if isinstance(r, Mapping) else None
                if g is None or g in rows:
                    raise ValueError(f"gait row {r!r:.60} is not a new gait 0-15")
                rows[g] = tuple(_number(r[k], k) for k in PARAM_NAMES)
            stride = _number(doc["stride_rad"], "stride_rad")
            lift = _number(doc["lift_rad"], "lift_rad")
        except KeyError as exc:
            raise GaitParamsError(f"{name}: malformed gait-parameter file (no {exc})") from exc
        except (TypeError, ValueError, OverflowError) as exc:
            raise GaitParamsError(f"{name}: malformed gait-parameter file ({exc})") from exc
        if "legs" in doc and doc["legs"] != list(LEGS):
            raise GaitParamsError(f"{name}: leg order {doc['legs']!r:.80} is not {list(LEGS)}")
        if "pattern" in doc and doc["pattern"] != [list(r) for r in PATTERN]:
            raise GaitParamsError(f"{name}: fitted for a different tripod pattern; refit (--fit)")
        skip = ("gaits", "stride_rad", "lift_rad", "legs", "pattern", "pattern_columns")
        meta = {k: v for k, v in doc.items() if k not in skip}
        try:
            return cls(rows, stride, lift, meta)
        except ValueError as exc:
            raise GaitParamsError(f"{name}: {exc}") from exc

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready parameters: amplitudes, pattern, leg order and the 16 rows."""
        gaits = [
            {"gait": g, "kind": GAIT_KIND[g], **dict(zip(PARAM_NAMES, self.rows[g], strict=True))}
            for g in range(N_GAITS)
        ]
        return {
            **dict(self.meta),
            "legs": list(LEGS),
            "pattern": [list(r) for r in PATTERN],
            "pattern_columns": ["uA", "lA", "yA", "uB", "lB", "yB"],
            "stride_rad": self.stride_rad,
            "lift_rad": self.lift_rad,
            "gaits": gaits,
        }

    def with_row(self, gait: int, row: tuple[float, ...]) -> GaitLibrary:
        """A copy with one gait's row replaced."""
        rows = dict(self.rows)
        rows[check_gait(gait)] = tuple(float(v) for v in row)
        return GaitLibrary(rows, self.stride_rad, self.lift_rad, dict(self.meta))

    def frames(self, gait: int) -> np.ndarray:
        """Servo targets of one cycle of ``gait``: (n_frames, 12) rad, actuator order."""
        left, right, left_offset, right_offset, lift = self.rows[check_gait(gait)]
        u, lv, y, side = _leg_phase_matrix()
        stride = np.where(side > 0, left, right)
        offset = np.where(side > 0, left_offset, right_offset)
        thrust = offset * y + self.stride_rad * stride * u
        out = np.empty((u.shape[0], 2 * len(LEGS)))
        out[:, 0::2] = thrust
        out[:, 1::2] = self.lift_rad * lift * lv
        return out

    @staticmethod
    def home() -> np.ndarray:
        """Servo targets of the home posture (all joints at 0), (12,) rad."""
        return np.zeros(2 * len(LEGS))
