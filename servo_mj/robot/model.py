"""Load the ServoBot MJCF and small accessors on a compiled model (names from ``constants``)."""

from __future__ import annotations

import hashlib

import mujoco
import numpy as np

from servo_mj.robot import constants as C


def load_robot(scene: bool = True) -> tuple[mujoco.MjModel, mujoco.MjData]:
    """Compile ``scene.xml`` (robot on a floor) or the bare ``servobot.xml``; data at ``home``."""
    path = C.SCENE_XML if scene else C.ROBOT_XML
    model = mujoco.MjModel.from_xml_path(str(path))
    data = mujoco.MjData(model)
    key = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_KEY, "home")
    if key >= 0:
        mujoco.mj_resetDataKeyframe(model, data, key)
    mujoco.mj_forward(model, data)
    return model, data


def model_sha256() -> str:
    """SHA-256 of the robot and scene MJCF files (provenance of a calibration)."""
    h = hashlib.sha256()
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
