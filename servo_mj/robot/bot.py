"""Run gait cycles on a MuJoCo model that contains the ServoBot (bare scene or composed arena).

Poses are in the SPEC frame (§1): x east, y north in cm (arena units), heading in degrees in
[0, 360), 0 = north (+y), clockwise positive; MuJoCo works in metres (100 cm = 1 m). The pose
is the torso centre projected on the floor and the heading of the torso's forward (+x) axis.

Stepping: one gait frame = ``PhysicsSettings.substeps`` physics steps in one native call
(``mujoco.mj_step(model, data, nstep)``); ``MjData`` is reused.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import mujoco
import numpy as np

from servo_mj.robot import constants as C
from servo_mj.robot.gaits import GaitLibrary, check_gait
from servo_mj.robot.model import free_joint_of, heading_deg_from_xmat, name_id
from servo_mj.robot.settings import PhysicsSettings

Pose = tuple[float, float, float]
CM_PER_M = C.CM_PER_M
_DEFAULT_PHYSICS = PhysicsSettings()


class PhysicsError(RuntimeError):
    """The simulation diverged (NaN, MuJoCo warning, runaway speed) or the torso flipped."""


def displacement(before: Pose, after: Pose) -> tuple[float, float, float]:
    """(F, T, dH) of a move in the frame the robot had at ``before`` (SPEC §1, inverse of the
    table update): F forward cm, T sideways cm (> 0 = right), dH degrees in (-180, 180]."""
    x0, y0, h0 = before
    x1, y1, h1 = after
    dx, dy = x1 - x0, y1 - y0
    h = math.radians(h0)
    f = dx * math.sin(h) + dy * math.cos(h)
    t = dx * math.cos(h) - dy * math.sin(h)
    dh = (h1 - h0 + 180.0) % 360.0 - 180.0
    if dh == -180.0:
        dh = 180.0
    return f, t, dh


@dataclass(frozen=True)
class CycleResult:
    """One executed gait cycle: poses (x cm, y cm, heading deg) before and after, sim times s."""

    gait: int
    cycle: int
    pose_before: Pose
    pose_after: Pose
    t_start_s: float
    t_end_s: float

    @property
    def ftdh(self) -> tuple[float, float, float]:
        """(F cm, T cm, dH deg) of this cycle in the frame the robot had when it began."""
        return displacement(self.pose_before, self.pose_after)


class ServoBot:
    """The ServoBot inside ``model``/``data``: place it, read its pose, run gait cycles.

    ``prefix`` is the name prefix of the robot's elements (``""`` for ``scene.xml``,
    ``"servobot/"`` when attached by ``dm_control.mjcf``). The free joint is found from the
    torso by walking up its parents. Sets ``model.opt.timestep`` to ``physics.timestep_s``.
    Servo-target noise (``physics.servo_noise_rad``) is drawn from ``rng``
    (default ``np.random.default_rng(0)``) for all 12 servos every frame, and applied only to
    the servos that receive a new activation (target changed since the previous frame): a
    held servo keeps its previous command, so standing still (gait 7) stays still.
    """

    def __init__(
        self,
        model: mujoco.MjModel,
        data: mujoco.MjData,
        *,
        prefix: str = "",
        physics: PhysicsSettings = _DEFAULT_PHYSICS,
        gaits: GaitLibrary | None = None,
        rng: np.random.Generator | None = None,
    ) -> None:
        self.model, self.data, self.prefix, self.physics = model, data, prefix, physics
        self.gaits = gaits if gaits is not None else GaitLibrary.load()
        self.rng = rng if rng is not None else np.random.default_rng(0)
        self.substeps = physics.substeps
        model.opt.timestep = physics.timestep_s
        obj = mujoco.mjtObj
        self.torso = name_id(model, obj.mjOBJ_BODY, C.torso_name(prefix))
        self.free_joint = free_joint_of(model, self.torso)
        self.free_qadr = int(model.jnt_qposadr[self.free_joint])
        self.free_dadr = int(model.jnt_dofadr[self.free_joint])
        self.actuators = np.array(
            [name_id(model, obj.mjOBJ_ACTUATOR, n) for n in C.actuator_names(prefix)]
        )
        joints = [name_id(model, obj.mjOBJ_JOINT, n) for n in C.joint_names(prefix)]
        self.joint_qadr = np.array([model.jnt_qposadr[j] for j in joints])
        self.joint_dadr = np.array([model.jnt_dofadr[j] for j in joints])
        self.feet = np.array([name_id(model, obj.mjOBJ_SITE, n) for n in C.foot_sites(prefix)])
        foot_geom = name_id(model, obj.mjOBJ_GEOM, prefix + f"{C.LEGS[0]}_foot")
        self.foot_radius_m = float(model.geom_size[foot_geom, 0])
        self.cycles = 0
        """Gait cycles run since construction (for error messages)."""
        self._nominal = GaitLibrary.home()  # last commanded target without noise, rad
        self._command = GaitLibrary.home()  # last command sent (with noise), rad
        self._warnings = data.warning.number  # live view of MuJoCo's warning counters

    # --- accessors -------------------------------------------------------------------------
    def pose(self) -> Pose:
        """Torso centre projected on the floor (x, y cm) and heading (deg), SPEC frame."""
        mujoco.mj_kinematics(self.model, self.data)
        p = self.data.xpos[self.torso]
        return (
            float(p[0] * CM_PER_M),
            float(p[1] * CM_PER_M),
            heading_deg_from_xmat(self.data.xmat[self.torso]),
        )

    def foot_positions(self) -> np.ndarray:
        """World positions of the six foot centres, (6, 3) m, leg order (after the last step)."""
        return self.data.site_xpos[self.feet].copy()

    def upright(self) -> float:
        """z component of the torso's up axis (1 = level, < 0 = upside down)."""
        return float(self.data.xmat[self.torso, 8])

    # --- placement -------------------------------------------------------------------------
    def place(self, x_cm: float, y_cm: float, heading_deg: float, *, settle: bool = True) -> None:
        """Stand the robot in its home posture at (x, y, heading), at rest, then settle.

        ``settle=False`` only puts the robot there (several robots of one model are put first
        and then settled together with ``settle``, so that none settles while another still
        sits where the model file put it).
        """
        m, d = self.model, self.data
        if not all(math.isfinite(v) for v in (x_cm, y_cm, heading_deg)):
            raise ValueError(f"place: pose must be finite, got {(x_cm, y_cm, heading_deg)}")
        yaw = math.radians(90.0 - heading_deg)  # anticlockwise from +x
        q = self.free_qadr
        d.qpos[q : q + 3] = (x_cm / CM_PER_M, y_cm / CM_PER_M, 0.0)
        d.qpos[q + 3 : q + 7] = (math.cos(yaw / 2), 0.0, 0.0, math.sin(yaw / 2))
        d.qpos[self.joint_qadr] = GaitLibrary.home()
        d.qvel[self.free_dadr : self.free_dadr + 6] = 0.0
        d.qvel[self.joint_dadr] = 0.0
        d.qacc_warmstart[:] = 0.0
        d.ctrl[self.actuators] = GaitLibrary.home()
        self._nominal, self._command = GaitLibrary.home(), GaitLibrary.home()
        mujoco.mj_kinematics(m, d)
        # Shift so that the torso centre is over (x, y) and the lowest foot just above the floor.
        torso = d.xpos[self.torso]
        lowest = float(d.site_xpos[self.feet, 2].min()) - self.foot_radius_m
        d.qpos[q] += x_cm / CM_PER_M - torso[0]
        d.qpos[q + 1] += y_cm / CM_PER_M - torso[1]
        d.qpos[q + 2] += self.physics.floor_z_m + self.physics.drop_clearance_m - lowest
        if settle:
            self.settle()

    def settle(self) -> None:
        """Stand ``PhysicsSettings.settle_s`` in the current posture (every robot of the model
        steps), then the fault checks."""
        m, d = self.model, self.data
        mujoco.mj_forward(m, d)
        self._clear_warnings()
        n = round(self.physics.settle_s / self.physics.timestep_s)
        if n > 0:
            mujoco.mj_step(m, d, n)
            self._check("settle", self.cycles, d.time)

    # --- gaits -----------------------------------------------------------------------------
    def run_gait(
        self,
        gait: int,
        *,
        on_frame: Callable[[mujoco.MjData], None] | None = None,
        on_step: Callable[[mujoco.MjData], None] | None = None,
    ) -> CycleResult:
        """Run one cycle of ``gait``; ``on_frame(data)`` is called after every 100 ms frame,
        ``on_step(data)`` after every physics step (then the frame's steps are taken one call
        at a time, with the same result bit for bit).

        Raises ``PhysicsError`` (naming gait, cycle and time) on NaN, a MuJoCo warning,
        runaway speed or a flipped torso.
        """
        g = check_gait(gait)
        frames = self.gaits.frames(g)
        before, t0 = self.pose(), float(self.data.time)
        noise = self.physics.servo_noise_rad
        m, d = self.model, self.data
        self._clear_warnings()
        for target in frames:
            command = target
            if noise > 0.0:
                jitter = self.rng.normal(0.0, noise, size=target.shape)
                command = np.where(target != self._nominal, target + jitter, self._command)
            self._nominal, self._command = target, command
            d.ctrl[self.actuators] = command
            if on_step is None:
                mujoco.mj_step(m, d, self.substeps)
            else:
                for _ in range(self.substeps):
                    mujoco.mj_step(m, d)
                    on_step(d)
            self._check(f"gait {g}", self.cycles, d.time)
            if on_frame is not None:
                on_frame(d)
        result = CycleResult(g, self.cycles, before, self.pose(), t0, float(d.time))
        self.cycles += 1
        return result

    def servo_state(self) -> tuple[np.ndarray, np.ndarray, int]:
        """What a cycle depends on besides MuJoCo's state and the noise generator: the last
        nominal target and command (rad) and the cycle count (``set_servo_state``)."""
        return self._nominal.copy(), self._command.copy(), self.cycles

    def set_servo_state(self, state: tuple[np.ndarray, np.ndarray, int]) -> None:
        """Restore a ``servo_state``."""
        nominal, command, self.cycles = state
        self._nominal, self._command = nominal.copy(), command.copy()

    # --- faults ----------------------------------------------------------------------------
    def _clear_warnings(self) -> None:
        self._warnings[:] = 0

    def _check(self, what: str, cycle: int, t: float) -> None:
        # Runs after every frame: array tests only; the message is built when one fails.
        d = self.data
        if self._warnings.any():
            warned = [mujoco.mjtWarning(int(i)).name for i in np.flatnonzero(self._warnings)]
            problem = f"MuJoCo warning {', '.join(warned)}"
        elif not (np.isfinite(d.qpos).all() and np.isfinite(d.qvel).all()):
            problem = "non-finite state (NaN/inf)"
        elif float(np.abs(d.qvel).max()) > self.physics.max_speed_m_s:
            problem = f"simulation diverged (speed > {self.physics.max_speed_m_s})"
        elif self.upright() < self.physics.upright_min:
            problem = f"torso flipped (up-axis z = {self.upright():.2f})"
        else:
            return
        raise PhysicsError(f"{problem} during {what}, cycle {cycle}, t = {t:.3f} s")
