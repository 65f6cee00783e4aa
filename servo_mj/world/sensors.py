"""Physics sensors of the ServoBot in the colony arena (SPEC §3, "Object sensors", "Light").

Object sensors: each 45° span (left [−40°, +5°], right [−5°, +40°] relative to the heading,
clockwise positive) is a fan of MuJoCo ``rangefinder`` sensors on sites that this module adds
to the robot's torso, at the torso centre, raised above the legs and horizontal in the torso
frame. A span is active when any of its rays hits a geom within ``object_range`` (50 units =
0.50 m) of the site, i.e. of the robot centre. MuJoCo rangefinders read −1 when the ray hits
nothing and exclude the torso's own geoms; raising the sites above the legs keeps the rays off
the rest of the robot.

Light sensors follow the SPEC's geometric rule (``evolve.geometry.light_sensors``) on the
robot's physical pose: the pose, not the table, decides whether the robot is lit.

Cost: the 20 rays are read only when the controller asks (a branch testing an object sensor),
so the arena's model has MuJoCo's sensor stage switched off while it steps
(``sensors_on_demand``) and ``ray_ranges_m`` evaluates the rangefinders at the current state.
Sensors never act on the dynamics, so this changes no trajectory; computing 20 rays in each of
the 800 physics steps of a gait cycle cost about a quarter of the cycle (docs/validation.md).

Frames: arena units (cm) and degrees for poses; metres in MuJoCo. Heading 0 = north (+y),
clockwise positive.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import mujoco
import numpy as np

from evolve.settings import WorldSettings
from servo_mj.robot.constants import CM_PER_M

_SENSOR_STAGE = int(mujoco.mjtDisableBit.mjDSBL_SENSOR)

SIDES = ("left", "right")
"""Object-sensor sides, in the order the World protocol returns them."""


def ray_bearings_deg(span_deg: tuple[float, float], n_rays: int) -> np.ndarray:
    """Relative bearings (deg, clockwise positive) of ``n_rays`` rays covering ``span_deg``.

    Both span ends are included, so ``n_rays`` must be at least 2.
    """
    if n_rays < 2:
        raise ValueError(f"need at least 2 rays per span (both ends), got {n_rays}")
    lo, hi = span_deg
    if not lo < hi:
        raise ValueError(f"object-sensor span must be (low, high) with low < high, got {span_deg}")
    return np.linspace(lo, hi, n_rays)


def ray_direction(bearing_deg: float, forward: Sequence[float]) -> np.ndarray:
    """Unit ray direction in the torso frame for a relative bearing (deg, clockwise positive).

    ``forward`` is the robot's forward axis in the torso frame (horizontal, z up); a positive
    bearing turns the ray towards the robot's right (−(z × forward)).
    """
    f = np.asarray(forward, dtype=np.float64)
    f = f / np.linalg.norm(f)
    left = np.cross([0.0, 0.0, 1.0], f)
    b = np.deg2rad(bearing_deg)
    d = np.cos(b) * f - np.sin(b) * left
    return d / np.linalg.norm(d)


def sensor_name(side: str, i: int) -> str:
    """Name (unprefixed) of the site and rangefinder of ray ``i`` of an object-sensor side."""
    return f"rf_{side}_{i:02d}"


def add_object_sensors(
    robot,
    torso_body: str,
    *,
    world: WorldSettings,
    n_rays: int,
    height_m: float,
    forward: Sequence[float],
) -> dict[str, list[str]]:
    """Add the rangefinder fans to a robot ``mjcf.RootElement`` (before it is attached).

    Sites go on body ``torso_body`` at (0, 0, ``height_m``) in the torso frame with their z
    axis along each ray. Returns the unprefixed sensor names per side.
    """
    torso = robot.find("body", torso_body)
    if torso is None:
        raise ValueError(f"robot model has no body named {torso_body!r}")
    spans = {"left": world.object_left_span_deg, "right": world.object_right_span_deg}
    names: dict[str, list[str]] = {}
    for side in SIDES:
        names[side] = []
        for i, b in enumerate(ray_bearings_deg(spans[side], n_rays)):
            name = sensor_name(side, i)
            site = torso.add(
                "site",
                name=name,
                pos=[0.0, 0.0, height_m],
                zaxis=ray_direction(float(b), forward),
                size=[0.003],
                group=5,
                rgba=[1.0, 0.5, 0.0, 0.3],
            )
            robot.sensor.add("rangefinder", name=name, site=site)
            names[side].append(name)
    return names


@dataclass(frozen=True)
class ObjectSensorIndex:
    """Where the rangefinder readings of each side sit in ``data.sensordata``."""

    left: np.ndarray
    right: np.ndarray

    @classmethod
    def from_model(cls, model: mujoco.MjModel, prefix: str, n_rays: int) -> ObjectSensorIndex:
        """Look up the ``n_rays`` rangefinders of each side by name (``prefix`` + name)."""
        idx = {}
        for side in SIDES:
            adr = []
            for i in range(n_rays):
                name = prefix + sensor_name(side, i)
                sid = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_SENSOR, name)
                if sid < 0:
                    raise ValueError(f"model has no rangefinder {name!r}")
                adr.append(int(model.sensor_adr[sid]))
            idx[side] = np.asarray(adr, dtype=np.int64)
        return cls(idx["left"], idx["right"])


def sensors_on_demand(model: mujoco.MjModel) -> None:
    """Switch off the sensor stage of ``mj_step`` for ``model``: ``ray_ranges_m`` still reads
    the rangefinders, on demand. Other code reading ``data.sensordata`` of this model after a
    step would read stale values."""
    model.opt.disableflags |= _SENSOR_STAGE


def ray_ranges_m(
    model: mujoco.MjModel, data: mujoco.MjData, index: ObjectSensorIndex
) -> tuple[np.ndarray, np.ndarray]:
    """Rangefinder readings (m, −1 = no hit) of the left and right fans at the current state.

    Recomputes positions and position-stage sensors first, so the readings belong to the
    current ``qpos`` rather than to the start of the last physics step; the sensor stage runs
    here even when ``sensors_on_demand`` switched it off for stepping.
    """
    flags = model.opt.disableflags
    model.opt.disableflags = flags & ~_SENSOR_STAGE
    try:
        mujoco.mj_fwdPosition(model, data)
        mujoco.mj_sensorPos(model, data)
    finally:
        model.opt.disableflags = flags
    return data.sensordata[index.left].copy(), data.sensordata[index.right].copy()


def fan_active(ranges_m: np.ndarray, range_m: float) -> bool:
    """A fan is active when some ray hits a geom within ``range_m`` metres."""
    return bool(np.any((ranges_m >= 0.0) & (ranges_m <= range_m)))


def physics_object_sensors(
    model: mujoco.MjModel,
    data: mujoco.MjData,
    index: ObjectSensorIndex,
    world: WorldSettings,
) -> tuple[bool, bool]:
    """(left, right) object sensors from the rangefinder fans, activation at ``object_range``."""
    left, right = ray_ranges_m(model, data, index)
    r = world.object_range / CM_PER_M
    return fan_active(left, r), fan_active(right, r)


__all__ = [
    "CM_PER_M",
    "SIDES",
    "ObjectSensorIndex",
    "add_object_sensors",
    "fan_active",
    "physics_object_sensors",
    "ray_bearings_deg",
    "ray_direction",
    "ray_ranges_m",
    "sensor_name",
    "sensors_on_demand",
]
