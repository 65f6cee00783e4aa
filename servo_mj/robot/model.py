"""Load the ServoBot MJCF and small accessors on a compiled model (names from ``constants``)."""

from __future__ import annotations

import hashlib
from pathlib import Path

import mujoco
import numpy as np

from servo_mj.robot import constants as C

ModelFile = str | Path | None
"""Which robot: None = the shipped ServoBot (``models/servobot``), else the path of a complete
MJCF scene such as a ``servobot variant`` file (robot + floor + options in one file)."""


def scene_path(model: ModelFile = None) -> Path:
    """The calibration scene of ``model``: the shipped ``scene.xml`` or the given file, which
    must exist (``FileNotFoundError`` naming it otherwise)."""
    if model is None:
        return C.SCENE_XML
    path = Path(model)
    if not path.is_file():
        raise FileNotFoundError(f"robot model {path}: no such file")
    return path


def model_label(model: ModelFile = None) -> str:
    """How messages and files name a model: ``shipped ServoBot (models/servobot)`` or the path."""
    return "shipped ServoBot (models/servobot)" if model is None else str(model)


def load_robot(scene: bool = True, model: ModelFile = None) -> tuple[mujoco.MjModel, mujoco.MjData]:
    """Compile the calibration scene (robot on a floor) or, for the shipped model only, the bare
    ``servobot.xml`` (``scene=False``); data at the ``home`` keyframe. ``model``: see
    ``ModelFile``."""
    if not scene and model is not None:
        raise ValueError("scene=False loads the shipped robot alone; a model file is a scene")
    path = scene_path(model) if scene else C.ROBOT_XML
    try:
        compiled = mujoco.MjModel.from_xml_path(str(path))
    except ValueError as exc:
        raise ValueError(f"robot model {path}: MuJoCo cannot compile it ({exc})") from exc
    data = mujoco.MjData(compiled)
    key = mujoco.mj_name2id(compiled, mujoco.mjtObj.mjOBJ_KEY, "home")
    if key >= 0:
        mujoco.mj_resetDataKeyframe(compiled, data, key)
    mujoco.mj_forward(compiled, data)
    return compiled, data


def model_sha256(model: ModelFile = None) -> str:
    """SHA-256 of the robot (provenance of a calibration): of the shipped robot and scene MJCF
    files (names and bytes), or of a model file's bytes (its name does not count)."""
    h = hashlib.sha256()
    if model is not None:
        h.update(scene_path(model).read_bytes())
        return h.hexdigest()
    for path in (C.ROBOT_XML, C.SCENE_XML):
        h.update(path.name.encode())
        h.update(path.read_bytes())
    return h.hexdigest()


def name_id(model: mujoco.MjModel, obj: mujoco.mjtObj, name: str) -> int:
    """Id of a named MuJoCo object or a ``KeyError`` naming what is missing."""
    i = mujoco.mj_name2id(model, obj, name)
    if i < 0:
        raise KeyError(f"model has no {obj.name.removeprefix('mjOBJ_').lower()} named {name!r}")
    return i


def free_joint_of(model: mujoco.MjModel, body: int) -> int:
    """The free joint that moves ``body``: walk up the parents to the first body that has one."""
    b = body
    while b > 0:
        for j in range(model.body_jntadr[b], model.body_jntadr[b] + model.body_jntnum[b]):
            if model.jnt_type[j] == mujoco.mjtJoint.mjJNT_FREE:
                return j
        b = int(model.body_parentid[b])
    raise KeyError(f"no free joint above body {model.body(body).name!r}")


def heading_deg_from_xmat(xmat: np.ndarray) -> float:
    """SPEC heading (0 = north/+y, clockwise) of a body whose +x axis is its forward axis."""
    fx, fy = float(xmat[0]), float(xmat[3])
    return float(np.degrees(np.arctan2(fx, fy)) % 360.0)


def thrust_limit_rad(model: mujoco.MjModel, prefix: str = "") -> float:
    """Smallest |ctrlrange| bound of the six thrust servos, rad: how far a thrust sweep may
    reach (the MJCF's ``thrust`` default class is its one home)."""
    ids = [name_id(model, mujoco.mjtObj.mjOBJ_ACTUATOR, C.actuator_name(leg, "thrust", prefix))
           for leg in C.LEGS]  # fmt: skip
    return float(np.abs(model.actuator_ctrlrange[ids]).min())
