"""``Recording``: one ``.rrd`` file — its name and properties, the scene, robots and events.

Every robot has a name (``robot=``, default ``"servobot"``), so several robots can share one
recording (entity paths ``world/robots/<robot>/…``, plots ``plots/<quantity>/<robot>/…``,
logs ``log/<robot>/<world>``). Nothing is sent per call: rows are buffered and sent column-wise
(``send_columns``) when a buffer holds ``RecordingSettings.max_buffer_rows`` rows and on
:meth:`Recording.close`, which also writes the blueprint and moves the file into place.
"""

from __future__ import annotations

import json
import os
import uuid
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np
import rerun as rr

from evolve.settings import WorldSettings
from infra.io import OutputError, partial_path
from servo_mj.robot.constants import CM_PER_M
from servobot.recording.arena import log_arena, log_calibration_floor
from servobot.recording.blueprint import Contents, make_blueprint
from servobot.recording.calibration import CalibrationCycles
from servobot.recording.columns import times_of
from servobot.recording.events import WorldEvents
from servobot.recording.frames import arena_to_m
from servobot.recording.robot import RobotIndex, RobotRecorder
from servobot.recording.shapes import log_body_shapes, log_ghost_shapes
from servobot.recording.style import DEFAULT_ROBOT, RecordingSettings, Rgb, tint, world_color

NONE_TEXT = "none"
"""How a property field that is None reads in the viewer (JSON's ``null`` reads as missing)."""


def property_values(value: Any) -> rr.AnyValues:
    """A property as rerun ``AnyValues``: a mapping gives one field per key (numbers, text
    and number arrays as they are, None as ``NONE_TEXT``, anything else as JSON text); any
    other value one field ``value``."""
    fields = value if isinstance(value, Mapping) else {"value": value}
    out: dict[str, Any] = {}
    for k, v in fields.items():
        if v is None:
            out[str(k)] = NONE_TEXT
        elif isinstance(v, np.ndarray | list | tuple) and np.asarray(v).dtype.kind in "biuf":
            out[str(k)] = np.asarray(v)
        elif isinstance(v, str | bool | int | float | np.generic):
            out[str(k)] = v
        else:
            out[str(k)] = json.dumps(v, default=_json_default)
    return rr.AnyValues(**out)


def _json_default(obj: Any) -> Any:
    if isinstance(obj, np.ndarray | np.generic):
        return obj.tolist()
    if hasattr(obj, "__dataclass_fields__"):
        return {k: getattr(obj, k) for k in obj.__dataclass_fields__}
    return str(obj)


class Recording:
    """One ``.rrd`` file; use as a context manager. ``close()`` sends buffers and saves atomically.

    The file appears at ``path`` only when the recording closes (written to a temporary file
    beside it, then renamed), so an interrupted run never leaves a half-written ``.rrd``.
    ``name`` is the recording's name in the viewer (e.g. ``"pop0/run3"``).
    """

    def __init__(
        self,
        path: str | Path,
        *,
        name: str | None = None,
        app_id: str = "servobot",
        blueprint: bool = True,
        settings: RecordingSettings | None = None,
    ) -> None:
        self.path = Path(path)
        self.settings = settings or RecordingSettings()
        self._blueprint = blueprint
        self.path.parent.mkdir(parents=True, exist_ok=True)
        # A unique hidden name beside the target; rerun creates it with the usual file mode.
        self._tmp = partial_path(self.path)
        self.rec = rr.RecordingStream(app_id, recording_id=uuid.uuid4())
        self.rec.save(str(self._tmp))
        if name:
            self.rec.send_recording_name(name)
        self._closed = False
        self._world = WorldSettings()
        self._robots: dict[str, RobotRecorder] = {}
        self._colors: dict[str, Rgb] = {}
        self._events: dict[tuple[str, str], WorldEvents] = {}
        self._calibration = CalibrationCycles()
        self.contents = Contents()
        self.rec.log("world", rr.ViewCoordinates.RIGHT_HAND_Z_UP, static=True)

    @classmethod
    def for_calibration(cls, path: str | Path) -> Recording:
        """A calibration's recording (see ``calibration_recorder``)."""
        return cls(path, name="calibration", app_id="servobot-calibration")

    # ----------------------------------------------------------------------------- context
    def __enter__(self) -> Recording:
        return self

    def __exit__(self, exc_type: Any, exc: Any, tb: Any) -> None:
        self.close(save=exc_type is None)

    # ----------------------------------------------------------------------------- metadata
    def log_properties(self, **properties: Any) -> None:
        """Recording properties shown in the viewer (``send_property``), one per keyword:
        e.g. ``chromosome="..."``, ``start={"x_cm": ..., ...}``, ``settings={...}``."""
        for key, value in properties.items():
            self.rec.send_property(key, property_values(value))

    # ----------------------------------------------------------------------------- scene
    def log_arena(self, world: WorldSettings) -> None:
        """The static colony arena (``servobot.recording.arena``) for ``world``."""
        self._world = world
        log_arena(self.rec, world, self.settings)
        size = world.arena_size / CM_PER_M
        self.contents.scene = ((0.0, 0.0), (size, size))

    def log_calibration_floor(
        self, starts_cm: Sequence[tuple[float, float]], labels: Sequence[str]
    ) -> None:
        """A floor with a 1 m grid under calibration walks starting at ``starts_cm`` (x, y)."""
        log_calibration_floor(self.rec, starts_cm, labels)
        pts = np.array([arena_to_m(x, y) for x, y in starts_cm])
        self.contents.scene = (tuple(pts.min(axis=0) - 1.0), tuple(pts.max(axis=0) + 1.0))

    # ----------------------------------------------------------------------------- robots
    def log_robot_model(
        self, model: Any, *, prefix: str = "", robot: str = DEFAULT_ROBOT,
        color: Rgb | None = None,
    ) -> None:  # fmt: skip
        """Add physics robot ``robot``: the bodies whose names start with ``prefix`` (e.g.
        ``servobot/`` once attached into an arena), drawn from the model's geoms (static, in
        body frames), tinted ``color`` when given (its tracks take that colour too)."""
        index = RobotIndex.of(model, prefix)
        if color is not None:
            self._colors[robot] = color
        log_body_shapes(
            self.rec, model, index.bodies, f"world/robots/{robot}/bodies",
            groups=self.settings.robot_geom_groups, color=color,
        )  # fmt: skip
        self._robots[robot] = RobotRecorder(robot, index, self.settings)
        if robot not in self.contents.robots:
            self.contents.robots.append(robot)
        if index.torso_row is not None:
            self.contents.follow.add(robot)
        self.contents.detail = self.settings.servo_detail

    def set_robot_color(self, robot: str, color: Rgb) -> None:
        """Give ``robot``'s tracks, squares and poses ``color`` (lighter for a non-physics
        world) before any of its events (``log_robot_model(color=...)`` does it too)."""
        self._colors[robot] = color

    def _robot(self, robot: str) -> RobotRecorder:
        if robot not in self._robots:
            raise ValueError(f"robot {robot!r}: call log_robot_model before logging its state")
        return self._robots[robot]

    def log_robot_state(
        self, data: Any, *, t_s: float, step: int | None = None, cycle: int | None = None,
        robot: str = DEFAULT_ROBOT, colony_step: int | None = None,
    ) -> None:  # fmt: skip
        """Buffer one servo frame of ``robot`` at simulated time ``t_s`` (s), with the
        interpreter ``step``, calibration ``cycle`` or ``colony_step`` it belongs to when
        given."""
        r = self._robot(robot)
        times = times_of(t_s, step=step, cycle=cycle, colony_step=colony_step)
        r.add_frame(data.model, data, times)
        self._timelines(times)
        if r.frames.n >= self.settings.max_buffer_rows:
            r.flush(self.rec)

    def log_feet(
        self, feet_xyz_m: np.ndarray, *, t_s: float, step: int | None = None,
        cycle: int | None = None, robot: str = DEFAULT_ROBOT,
    ) -> None:  # fmt: skip
        """Buffer the feet positions (n, 3) in metres at ``t_s``; drawn as trails."""
        r = self._robot(robot)
        times = times_of(t_s, step=step, cycle=cycle)
        r.add_feet(feet_xyz_m, times)
        self._timelines(times)
        if robot not in self.contents.feet:
            self.contents.feet.append(robot)
        if r.feet.n >= self.settings.max_buffer_rows:
            r.flush(self.rec)

    def log_rays(
        self, data: Any, left_m: np.ndarray, right_m: np.ndarray, *, t_s: float, step: int,
        robot: str = DEFAULT_ROBOT, colony_step: int | None = None,
    ) -> None:  # fmt: skip
        """Buffer the rangefinder rays of ``robot`` in ``data``'s state; readings ``left_m``
        and ``right_m`` in metres (−1 = no hit), as ``servo_mj.world.sensors.ray_ranges_m``."""
        r = self._robot(robot)
        range_m = self._world.object_range / CM_PER_M
        times = times_of(t_s, step=step, colony_step=colony_step)
        r.add_rays(data, left_m, right_m, times, range_m=range_m)
        if r.rays.n >= self.settings.max_buffer_rows:
            r.flush(self.rec)

    def log_ghost(
        self, model: Any, data: Any, *, prefix: str = "", robot: str = DEFAULT_ROBOT,
        world_name: str = "table",
    ) -> None:  # fmt: skip
        """Draw a translucent copy of the robot in ``data``'s posture at ``world_name``'s pose
        (e.g. the table world's robot beside the physics one)."""
        import mujoco

        from servo_mj.robot.constants import torso_name

        index = RobotIndex.of(model, prefix)
        torso = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, torso_name(prefix))
        color = (*self._world_color(robot, world_name), self.settings.ghost_alpha)
        log_ghost_shapes(
            self.rec, model, data, index.bodies, torso,
            f"world/robots/{robot}/{world_name}/pose/ghost",
            groups=self.settings.robot_geom_groups, color=color,
        )  # fmt: skip

    # ----------------------------------------------------------------------------- events
    def _world_color(self, robot: str, world_name: str) -> Rgb:
        own = self._colors.get(robot)
        return tint(own, world_name) if own is not None else world_color(world_name)

    def _world_events(self, robot: str, world_name: str) -> WorldEvents:
        key = (robot, world_name)
        if key not in self._events:
            color = self._world_color(robot, world_name)
            self._events[key] = WorldEvents(robot, world_name, color, self._world, self.settings)
            self.contents.worlds.append(key)
        return self._events[key]

    def log_start(
        self, pose: Sequence[float], *, world_name: str = "physics", robot: str = DEFAULT_ROBOT
    ) -> None:
        """The start pose (x, y cm, heading deg) of a world's track: its first segment runs
        from there to the pose after the first step."""
        self._world_events(robot, world_name).start(pose[0], pose[1])

    def log_event(
        self, event: Any, *, world_name: str = "physics", t_s: float | None = None,
        robot: str = DEFAULT_ROBOT, colony_step: int | None = None,
    ) -> None:  # fmt: skip
        """Buffer one interpreter ``StepEvent`` of ``robot`` in ``world_name`` at its ``step``
        and, when given, simulated time ``t_s`` (s) and ``colony_step``. Give each for every
        event of a world or for none (``ValueError`` otherwise)."""
        ev = self._world_events(robot, world_name)
        times = times_of(t_s, step=int(event.step), colony_step=colony_step)
        ev.add(event, times)
        self._timelines(times)
        if ev.main.n >= self.settings.max_buffer_rows:
            ev.flush(self.rec)

    def log_error(
        self, text: str, *, step: int, t_s: float | None = None, world_name: str = "physics",
        robot: str = DEFAULT_ROBOT, colony_step: int | None = None,
    ) -> None:  # fmt: skip
        """A line at ERROR level in ``log/<robot>/<world_name>`` (e.g. a physics failure)."""
        times = times_of(t_s, step=step, colony_step=colony_step)
        self._world_events(robot, world_name).add_error(text, times)

    def log_calibration_cycle(
        self, gait: int, cycle: int, F: float, T: float, dH: float, *, t_s: float
    ) -> None:
        """One measured calibration cycle of ``gait``: F, T (cm) and dH (deg) at ``t_s``."""
        times = times_of(t_s, cycle=cycle)
        self._calibration.add(gait, F, T, dH, times)
        self._timelines(times)
        if int(gait) not in self.contents.gaits:
            self.contents.gaits.append(int(gait))
            self.contents.gaits.sort()

    def _timelines(self, times: Mapping[str, Any]) -> None:
        self.contents.timelines.update(times)

    # ----------------------------------------------------------------------------- closing
    def flush(self) -> None:
        """Send every buffered row now (also done by ``close``)."""
        for r in self._robots.values():
            r.flush(self.rec)
        for ev in self._events.values():
            ev.flush(self.rec)
        self._calibration.flush(self.rec)

    def close(self, *, save: bool = True) -> None:
        """Send buffers, write the blueprint, and move the file into place (atomic).

        With ``save=False`` (an exception escaped the ``with`` block) the temporary file is
        removed and nothing appears at ``path``.
        """
        if self._closed:
            return
        self._closed = True
        ok = False
        try:
            if save:
                self.flush()
                if self._blueprint:
                    self.rec.send_blueprint(make_blueprint(self.contents, self.settings))
            self.rec.flush()
            ok = save
        finally:
            self.rec.disconnect()
            try:
                if ok:
                    os.replace(self._tmp, self.path)
            except OSError as exc:
                raise OutputError(f"cannot write {self.path}: {exc.strerror or exc}") from exc
            finally:
                self._tmp.unlink(missing_ok=True)


__all__ = ["NONE_TEXT", "Recording", "property_values"]
