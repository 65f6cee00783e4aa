"""The robot's shapes from a MuJoCo model: which bodies are drawn and each geom as a rerun shape.

Bodies are found by name prefix (``""`` for the bare robot, ``"servobot/"`` once
``dm_control.mjcf`` attached it into an arena); a body without geoms (the attachment frame,
which moves exactly as the torso) is not drawn. Each geom is logged once, static, in its
body's frame under ``<body entity>/geoms/<k>``: boxes, capsules, cylinders, spheres,
ellipsoids; meshes as their bounding box; planes are skipped.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
import rerun as rr

from servobot.recording.frames import mj_quat_to_xyzw

# mujoco.mjtGeom values, kept here so that table-only recordings need not import MuJoCo.
_SPHERE, _CAPSULE, _ELLIPSOID, _CYLINDER, _BOX, _MESH = 2, 3, 4, 5, 6, 7


@dataclass(frozen=True)
class Bodies:
    """The drawn bodies of one robot: MuJoCo body ids and their entity names."""

    ids: np.ndarray
    names: tuple[str, ...]

    @classmethod
    def of(cls, model: Any, prefix: str) -> Bodies:
        """Every body whose name starts with ``prefix`` and that holds at least one geom."""
        import mujoco

        ids, names = [], []
        for b in range(1, model.nbody):
            name = mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_BODY, b) or f"body{b}"
            if name.startswith(prefix) and model.body_geomnum[b] > 0:
                ids.append(b)
                names.append(rr.escape_entity_path_part(name[len(prefix) :] or f"body{b}"))
        if not ids:
            raise ValueError(f"the model has no body with geoms whose name starts with {prefix!r}")
        return cls(np.asarray(ids, dtype=np.int64), tuple(names))


def geom_rgba(model: Any, g: int) -> np.ndarray:
    """A geom's colour (RGBA 0–1): its material's when it has one."""
    if model.geom_matid[g] >= 0:
        return np.asarray(model.mat_rgba[model.geom_matid[g]])
    return np.asarray(model.geom_rgba[g])


def geom_archetype(model: Any, g: int, color: tuple[int, ...] | None = None) -> Any | None:
    """The rerun shape of MuJoCo geom ``g`` in its own frame, or None for planes/unknowns.

    ``color``: RGB or RGBA 0–255 instead of the model's colour.
    """
    gtype, size = int(model.geom_type[g]), np.asarray(model.geom_size[g], dtype=np.float64)
    if color is None:
        color = tuple(int(round(255 * c)) for c in geom_rgba(model, g))
    colors = [color]
    if gtype == _BOX:
        return rr.Boxes3D(half_sizes=[size], colors=colors, fill_mode="solid")
    if gtype == _SPHERE:
        return rr.Ellipsoids3D(half_sizes=[[size[0]] * 3], colors=colors, fill_mode="solid")
    if gtype == _ELLIPSOID:
        return rr.Ellipsoids3D(half_sizes=[size], colors=colors, fill_mode="solid")
    if gtype == _CAPSULE:  # MuJoCo: centred, half-length size[1]; rerun: from origin up +z
        return rr.Capsules3D(
            lengths=[2 * size[1]], radii=[size[0]], translations=[[0.0, 0.0, -size[1]]],
            colors=colors,
        )  # fmt: skip
    if gtype == _CYLINDER:  # both centred on the origin along z
        return rr.Cylinders3D(
            lengths=[2 * size[1]], radii=[size[0]], colors=colors, fill_mode="solid"
        )
    if gtype == _MESH:
        aabb = np.asarray(model.geom_aabb[g], dtype=np.float64)
        return rr.Boxes3D(
            centers=[aabb[:3]], half_sizes=[aabb[3:]], colors=colors, fill_mode="solid"
        )
    return None


def log_body_shapes(
    rec: rr.RecordingStream,
    model: Any,
    bodies: Bodies,
    base: str,
    *,
    groups: tuple[int, ...],
    color: tuple[int, ...] | None = None,
) -> None:
    """Static shapes of each body under ``<base>/<body>/geoms/<k>``, in the body's frame.

    Geoms of the ``groups`` are drawn; a body with none of those draws all its geoms.
    """
    wanted = set(groups)
    for b, name in zip(bodies.ids, bodies.names, strict=True):
        geoms = [g for g in range(model.ngeom) if model.geom_bodyid[g] == b]
        shown = [g for g in geoms if int(model.geom_group[g]) in wanted] or geoms
        for k, g in enumerate(shown):
            arch = geom_archetype(model, g, color)
            if arch is None:
                continue
            path = f"{base}/{name}/geoms/{k}"
            rec.log(
                path,
                rr.Transform3D(
                    translation=model.geom_pos[g], quaternion=mj_quat_to_xyzw(model.geom_quat[g])
                ),
                static=True,
            )
            rec.log(path, arch, static=True)


def log_ghost_shapes(
    rec: rr.RecordingStream,
    model: Any,
    data: Any,
    bodies: Bodies,
    torso: int,
    base: str,
    *,
    groups: tuple[int, ...],
    color: tuple[int, ...],
) -> None:
    """A translucent copy of the robot as ``data`` holds it, in the frame of its pose.

    The pose frame sits on the floor under the torso centre with x along the torso's heading
    (the frame ``world/robots/<robot>/<world>/pose`` moves to each step's pose). Each body's
    transform in that frame is logged static under ``<base>/<body>``.
    """
    import mujoco

    xmat = data.xmat[torso].reshape(3, 3)
    yaw = np.arctan2(xmat[1, 0], xmat[0, 0])
    c, s = np.cos(yaw), np.sin(yaw)
    rot_t = np.array([[c, s, 0.0], [-s, c, 0.0], [0.0, 0.0, 1.0]])  # world → pose frame
    origin = np.array([data.xpos[torso, 0], data.xpos[torso, 1], 0.0])
    for b, name in zip(bodies.ids, bodies.names, strict=True):
        pos = rot_t @ (data.xpos[b] - origin)
        mat = rot_t @ data.xmat[b].reshape(3, 3)
        quat = np.empty(4)
        mujoco.mju_mat2Quat(quat, mat.ravel())
        rec.log(
            f"{base}/{name}",
            rr.Transform3D(translation=pos, quaternion=mj_quat_to_xyzw(quat)),
            static=True,
        )
    log_body_shapes(rec, model, bodies, base, groups=groups, color=color)


__all__ = ["Bodies", "geom_archetype", "log_body_shapes", "log_ghost_shapes"]
