"""Frames and units of a recording: arena (cm, SPEC heading) → MuJoCo world (m, yaw), rotations.

Everything 3D in a recording is in metres in the MuJoCo world frame (x east, y north, z up;
100 arena units = 1 m). The SPEC heading (deg, 0 = north, clockwise) becomes a yaw about +z
(rad, 0 = +x, anticlockwise): yaw = 90° − heading. rerun quaternions are (x, y, z, w); MuJoCo's
are (w, x, y, z).
"""

from __future__ import annotations

import math

import numpy as np

from evolve.settings import WorldSettings
from servo_mj.robot.constants import CM_PER_M


def arena_to_m(x_cm: float, y_cm: float) -> tuple[float, float]:
    """Arena (x, y) in cm → MuJoCo world (x, y) in metres."""
    return x_cm / CM_PER_M, y_cm / CM_PER_M


def heading_to_yaw_rad(heading_deg: float) -> float:
    """SPEC heading (deg, 0 = north, clockwise) → yaw about +z (rad, 0 = +x, anticlockwise)."""
    return math.radians(90.0 - heading_deg)


def square_centre(index: int, world: WorldSettings) -> tuple[float, float]:
    """Centre (x, y cm) of square ``index = i + grid_n * j`` (i column along x, j row along y)."""
    i, j = index % world.grid_n, index // world.grid_n
    return (world.square_size * (i + 0.5), world.square_size * (j + 0.5))


def mj_quat_to_xyzw(q: np.ndarray) -> np.ndarray:
    """MuJoCo quaternions (w, x, y, z) → rerun (x, y, z, w); works on (..., 4)."""
    return np.concatenate([q[..., 1:4], q[..., 0:1]], axis=-1)


def yaw_quat_xyzw(headings_deg: np.ndarray) -> np.ndarray:
    """Rotations about +z for SPEC headings (deg), (n,) → (n, 4) rerun quaternions."""
    half = np.radians(90.0 - np.asarray(headings_deg, dtype=np.float64)) / 2
    z = np.zeros_like(half)
    return np.stack([z, z, np.sin(half), np.cos(half)], axis=-1)


def roll_pitch_deg(q_wxyz: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Roll and pitch (deg) of MuJoCo body quaternions (..., 4), z-y-x Euler angles.

    Roll is about the body's forward (+x) axis, > 0 when the left side is up; pitch about its
    left (+y) axis, > 0 when the nose is down.
    """
    w, x, y, z = (q_wxyz[..., k] for k in range(4))
    roll = np.arctan2(2 * (w * x + y * z), 1 - 2 * (x * x + y * y))
    pitch = np.arcsin(np.clip(2 * (w * y - z * x), -1.0, 1.0))
    return np.degrees(roll), np.degrees(pitch)


def bearing_dir(bearing_deg: np.ndarray) -> np.ndarray:
    """Unit vectors in a robot's frame (x forward, y left) for relative bearings (deg,
    clockwise positive, as the SPEC's sensor spans), (n,) → (n, 2)."""
    b = np.radians(np.asarray(bearing_deg, dtype=np.float64))
    return np.stack([np.cos(b), -np.sin(b)], axis=-1)


def rect_strip(x0: float, y0: float, x1: float, y1: float, z: float) -> np.ndarray:
    """A closed rectangle as a 5-point line strip (same units in, same out)."""
    return np.array([[x0, y0, z], [x1, y0, z], [x1, y1, z], [x0, y1, z], [x0, y0, z]])


__all__ = [
    "arena_to_m",
    "bearing_dir",
    "heading_to_yaw_rad",
    "mj_quat_to_xyzw",
    "rect_strip",
    "roll_pitch_deg",
    "square_centre",
    "yaw_quat_xyzw",
]
