"""One physics robot in a recording: its bodies, servos, contacts and sensor rays over time.

Entities of robot ``R`` (every servo frame unless noted; all on ``sim_time`` plus ``step`` or
``cycle``, whichever the caller gives)::

    world/robots/R/bodies/<body>[/geoms/<k>]   Transform3D (world pose); static shapes
    world/robots/R/follow                      Transform3D: the torso's place on the floor
                                               (translation only), the frame of the
                                               blueprint's follow view
    world/robots/R/contacts                    Arrows3D: force on the robot at each contact
                                               (feet green, any other body red), m per N,
                                               at most ``force_max_length_m`` long
    world/robots/R/feet                        Points3D, when ``log_feet`` is used (trails)
    world/robots/R/rays                        LineStrips3D per step: the rangefinder rays,
                                               red to a hit within range, grey otherwise
    plots/joints/R/<leg>                       servo target and measured angle, thrust and
                                               lift (deg)
    plots/foot_force/R                         normal force on each foot (N; 0 = no contact)
    plots/attitude/R                           torso roll and pitch (deg)

Nothing is sent per call: rows are buffered and sent with ``send_columns`` by ``flush``.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
import rerun as rr

from servo_mj.robot import constants as C
from servobot.recording.columns import ColumnBuffer, Times, scalars
from servobot.recording.frames import mj_quat_to_xyzw, roll_pitch_deg
from servobot.recording.shapes import Bodies
from servobot.recording.style import (
    BODY_CONTACT_COLOR,
    FOOT_CONTACT_COLOR,
    RAY_FREE_COLOR,
    RAY_HIT_COLOR,
    RecordingSettings,
)

JOINT_SERIES = ("thrust target", "thrust angle", "lift target", "lift angle")
"""The four series of each leg's joint plot, in order (the plot's title names the leg)."""
_JOINT_COLORS = ((120, 170, 255), (20, 70, 200), (255, 180, 110), (210, 90, 0))


def _ids(model: Any, kind: Any, names: tuple[str, ...]) -> np.ndarray | None:
    import mujoco

    ids = [mujoco.mj_name2id(model, kind, n) for n in names]
    return None if min(ids) < 0 else np.asarray(ids, dtype=np.int64)


@dataclass(frozen=True)
class RobotIndex:
    """Where one ServoBot's parts sit in a MuJoCo model (by name, with the robot's prefix).

    Parts a model lacks (a test model without servos, an arena without rangefinders) are None
    and are simply not recorded.
    """

    prefix: str
    bodies: Bodies
    torso_row: int | None
    """Row of the torso in ``bodies`` (for roll and pitch)."""
    actuators: np.ndarray | None
    joint_qadr: np.ndarray | None
    foot_of_geom: np.ndarray
    """(ngeom,) the leg (row in ``LEGS``) whose foot each geom is, −1 for any other geom."""
    robot_geom: np.ndarray
    """(ngeom,) bool: the geom belongs to this robot."""
    rays: tuple[np.ndarray, np.ndarray] | None
    """Site ids of the left and right rangefinder fans."""
    elliptic: bool
    """The model uses elliptic friction cones (contact forces read straight from ``efc_force``)."""

    @classmethod
    def of(cls, model: Any, prefix: str = "") -> RobotIndex:
        import mujoco

        from servo_mj.world.sensors import SIDES, sensor_name

        obj = mujoco.mjtObj
        bodies = Bodies.of(model, prefix)
        torso = mujoco.mj_name2id(model, obj.mjOBJ_BODY, C.torso_name(prefix))
        rows = np.flatnonzero(bodies.ids == torso)
        actuators = _ids(model, obj.mjOBJ_ACTUATOR, C.actuator_names(prefix))
        joints = _ids(model, obj.mjOBJ_JOINT, C.joint_names(prefix))
        feet = _ids(model, obj.mjOBJ_GEOM, C.foot_sites(prefix))
        foot_of_geom = np.full(model.ngeom, -1, dtype=np.int64)
        if feet is not None:
            foot_of_geom[feet] = np.arange(len(feet))
        mine = np.array(
            [b > 0 and (mujoco.mj_id2name(model, obj.mjOBJ_BODY, b) or "").startswith(prefix)
             for b in range(model.nbody)]
        )  # fmt: skip
        fans = []
        for side in SIDES:
            names, i = [], 0
            while mujoco.mj_name2id(model, obj.mjOBJ_SITE, prefix + sensor_name(side, i)) >= 0:
                names.append(prefix + sensor_name(side, i))
                i += 1
            fans.append(_ids(model, obj.mjOBJ_SITE, tuple(names)) if names else None)
        return cls(
            prefix=prefix,
            bodies=bodies,
            torso_row=int(rows[0]) if len(rows) else None,
            actuators=actuators,
            joint_qadr=None if joints is None else model.jnt_qposadr[joints].copy(),
            foot_of_geom=foot_of_geom,
            robot_geom=mine[model.geom_bodyid],
            rays=None if fans[0] is None or fans[1] is None else (fans[0], fans[1]),
            elliptic=model.opt.cone == mujoco.mjtCone.mjCONE_ELLIPTIC,
        )


def force_arrows(forces_n: np.ndarray, m_per_n: float, max_m: float) -> np.ndarray:
    """Drawn arrows (n, 3) m of forces (n, 3) N: ``m_per_n`` metres per newton, none longer
    than ``max_m`` (a longer one keeps its direction)."""
    v = np.asarray(forces_n, dtype=np.float64).reshape(-1, 3) * m_per_n
    length = np.linalg.norm(v, axis=1, keepdims=True)
    return v * np.minimum(1.0, max_m / np.maximum(length, 1e-300))


class RobotRecorder:
    """Buffers of one physics robot ``name``; ``flush(rec)`` sends them."""

    def __init__(self, name: str, index: RobotIndex, settings: RecordingSettings) -> None:
        self.name, self.index, self.settings = name, index, settings
        self.base = f"world/robots/{name}"
        self.frames = ColumnBuffer(f"robot {name!r} frames")
        self.feet = ColumnBuffer(f"robot {name!r} feet")
        self.rays = ColumnBuffer(f"robot {name!r} rays")
        self.detail = settings.servo_detail
        self._styled: set[str] = set()

    # --------------------------------------------------------------------------- buffering
    def add_frame(self, model: Any, data: Any, times: Times) -> None:
        """One servo frame: body poses, and with ``servo_detail`` servos and contacts."""
        ix = self.index
        row: dict[str, Any] = {
            "pos": data.xpos[ix.bodies.ids].copy(),
            "quat": data.xquat[ix.bodies.ids].copy(),
        }
        if self.detail and ix.actuators is not None and ix.joint_qadr is not None:
            row["target"] = data.ctrl[ix.actuators].copy()
            row["angle"] = data.qpos[ix.joint_qadr].copy()
        if self.detail:
            row["contacts"] = self._contacts(model, data)
        self.frames.add(times, **row)

    def _contacts(self, model: Any, data: Any) -> tuple[np.ndarray, ...]:
        """The frame's contacts as MuJoCo holds them: geom pairs (n, 2), points (n, 3) m,
        contact frames (n, 9) and forces in those frames (n, 3: normal, tangents) N. The
        robot's share is picked at flush time, when all frames are at hand."""
        import mujoco

        con = data.contact
        local = np.zeros((data.ncon, 3))
        if self.index.elliptic and data.nefc:
            # Elliptic cones keep a contact's force in its own frame: efc rows adr … adr + dim.
            adr, k = con.efc_address[:, None], np.arange(3)
            valid = (k < con.dim[:, None]) & (adr >= 0)
            local = np.where(valid, data.efc_force[np.clip(adr + k, 0, data.nefc - 1)], 0.0)
        else:
            f6 = np.empty(6)
            for i in range(data.ncon):
                mujoco.mj_contactForce(model, data, i, f6)
                local[i] = f6[:3]
        return con.geom.copy(), con.pos.copy(), con.frame.copy(), local

    def add_feet(self, feet_xyz_m: np.ndarray, times: Times) -> None:
        """Foot positions (n, 3) m, drawn as trails."""
        self.feet.add(times, pos=np.asarray(feet_xyz_m, dtype=np.float64).reshape(-1, 3).copy())

    def add_rays(self, data: Any, left_m: np.ndarray, right_m: np.ndarray, times: Times, *,
                 range_m: float) -> None:  # fmt: skip
        """The rangefinder rays at the current state; readings in m (−1 = no hit)."""
        if self.index.rays is None:
            raise ValueError(f"robot {self.name!r}: the model has no rangefinder sites")
        sites = np.concatenate(self.index.rays)
        reads = np.concatenate([np.asarray(left_m), np.asarray(right_m)]).astype(np.float64)
        start = data.site_xpos[sites]
        direction = data.site_xmat[sites].reshape(-1, 3, 3)[:, :, 2]
        hit = (reads >= 0.0) & (reads <= range_m)
        end = start + direction * np.where(hit, reads, range_m)[:, None]
        self.rays.add(times, strips=np.stack([start, end], axis=1), hit=hit)

    # --------------------------------------------------------------------------- sending
    def flush(self, rec: rr.RecordingStream) -> None:
        if self.frames.n:
            self._send_frames(rec)
        if self.feet.n:
            self._style(rec, "feet")
            lens = [len(p) for p in self.feet.rows["pos"]]
            rec.send_columns(
                f"{self.base}/feet",
                indexes=self.feet.time_columns(),
                columns=rr.Points3D.columns(positions=np.concatenate(self.feet.rows["pos"]))
                .partition(lens),
            )  # fmt: skip
            self.feet.clear()
        if self.rays.n:
            self._style(rec, "rays")
            strips = self.rays.array("strips")  # (n, rays, 2, 3)
            hit = self.rays.array("hit", bool).ravel()
            colors = np.where(hit[:, None], [(*RAY_HIT_COLOR, 255)], [RAY_FREE_COLOR])
            rec.send_columns(
                f"{self.base}/rays",
                indexes=self.rays.time_columns(),
                columns=rr.LineStrips3D.columns(
                    strips=list(strips.reshape(-1, 2, 3)), colors=colors.astype(np.uint8)
                ).partition([strips.shape[1]] * strips.shape[0]),
            )
            self.rays.clear()

    def _send_frames(self, rec: rr.RecordingStream) -> None:
        f, ix, base = self.frames, self.index, self.base
        index = f.time_columns()
        pos = f.array("pos")  # (n, bodies, 3)
        quat = f.array("quat")  # (n, bodies, 4), MuJoCo order
        xyzw = mj_quat_to_xyzw(quat)
        for k, name in enumerate(ix.bodies.names):
            rec.send_columns(
                f"{base}/bodies/{name}",
                indexes=index,
                columns=rr.Transform3D.columns(translation=pos[:, k], quaternion=xyzw[:, k]),
            )
        if ix.torso_row is not None:  # the frame a follow view sits in: not turning
            follow = pos[:, ix.torso_row].copy()
            follow[:, 2] = 0.0
            rec.send_columns(f"{base}/follow", indexes=index,
                             columns=rr.Transform3D.columns(translation=follow))  # fmt: skip
        if self.detail and ix.torso_row is not None:
            self._style(rec, "attitude")
            roll, pitch = roll_pitch_deg(quat[:, ix.torso_row])
            scalars(rec, f"plots/attitude/{self.name}", index, np.stack([roll, pitch], axis=1))
        if "target" in f.rows:
            self._style(rec, "joints")
            target = np.degrees(f.array("target")).reshape(f.n, len(C.LEGS), 2)
            angle = np.degrees(f.array("angle")).reshape(f.n, len(C.LEGS), 2)
            for k, leg in enumerate(C.LEGS):
                vals = np.stack([target[:, k, 0], angle[:, k, 0], target[:, k, 1], angle[:, k, 1]])
                scalars(rec, f"plots/joints/{self.name}/{leg}", index, vals.T)
        if "contacts" in f.rows:
            self._style(rec, "contacts")
            self._send_contacts(rec, index)
        f.clear()

    def _send_contacts(self, rec: rr.RecordingStream, index: list[rr.TimeColumn]) -> None:
        """Arrows of the force on the robot at each of its contacts with anything else, and the
        normal force on each foot."""
        ix, rows = self.index, self.frames.rows["contacts"]
        n = len(rows)
        geom, pos, frame, local = (np.concatenate([r[k] for r in rows]) for k in range(4))
        geom, frame = geom.reshape(-1, 2).astype(np.int64), frame.reshape(-1, 3, 3)
        row_of = np.repeat(np.arange(n), [len(r[0]) for r in rows])
        mine = ix.robot_geom[geom]
        keep = mine[:, 0] != mine[:, 1]  # the robot against something else
        on_second = mine[keep, 1]  # the normal points from geom1 to geom2
        sign = np.where(on_second, 1.0, -1.0)[:, None]
        forces = sign * np.einsum("kij,ki->kj", frame[keep], local[keep])  # world frame, N
        foot = ix.foot_of_geom[np.where(on_second, geom[keep, 1], geom[keep, 0])]
        colors = np.where((foot >= 0)[:, None], [FOOT_CONTACT_COLOR], [BODY_CONTACT_COLOR])
        s = self.settings
        rec.send_columns(
            f"{self.base}/contacts",
            indexes=index,
            columns=rr.Arrows3D.columns(
                origins=pos.reshape(-1, 3)[keep],
                vectors=force_arrows(forces, s.force_scale_m_per_n, s.force_max_length_m),
                colors=colors.astype(np.uint8),
            ).partition(np.bincount(row_of[keep], minlength=n)),
        )
        normal = np.zeros((n, len(C.LEGS)))
        on_foot = foot >= 0
        np.add.at(normal, (row_of[keep][on_foot], foot[on_foot]), local[keep][on_foot, 0])
        scalars(rec, f"plots/foot_force/{self.name}", index, normal)

    def _style(self, rec: rr.RecordingStream, part: str) -> None:
        """Static display settings of one part, logged before its first rows."""
        if part in self._styled:
            return
        self._styled.add(part)
        r, log = self.name, rec.log
        if part == "attitude":
            log(f"plots/attitude/{r}", rr.SeriesLines(names=["roll", "pitch"]), static=True)
        elif part == "joints":
            for leg in C.LEGS:
                series = rr.SeriesLines(names=JOINT_SERIES, colors=_JOINT_COLORS)
                log(f"plots/joints/{r}/{leg}", series, static=True)
        elif part == "contacts":
            log(f"{self.base}/contacts", rr.Arrows3D.from_fields(radii=0.003), static=True)
            log(f"plots/foot_force/{r}", rr.SeriesLines(names=list(C.LEGS)), static=True)
        elif part == "rays":
            log(f"{self.base}/rays", rr.LineStrips3D.from_fields(radii=0.0015), static=True)
        elif part == "feet":
            log(f"{self.base}/feet", rr.Points3D.from_fields(radii=0.004, colors=[(60, 60, 60)]),
                static=True)  # fmt: skip


__all__ = ["JOINT_SERIES", "RobotIndex", "RobotRecorder", "force_arrows"]
