"""The interpreter's events of one robot in one world ("physics", "table"): tracks, squares,
pose, sensors, plots and the instruction log.

Entities of robot ``R`` in world ``W`` (one row per event unless noted; timelines ``step``
and, when the caller gives times, ``sim_time``)::

    world/robots/R/W/pose                 Transform3D: the pose after the event (on the floor)
    world/robots/R/W/pose/heading         static arrow along the heading
    world/robots/R/W/pose/label           static: the world's name above the robot
    world/robots/R/W/pose/sensors         the active sensors' spans, drawn on the robot:
                                          object spans (red, 50 cm), light spans (yellow)
    world/robots/R/W/pose/ghost/<body>    static translucent robot (``Recording.log_ghost``)
    world/robots/R/W/track                one segment per move (trails)
    world/robots/R/W/squares              one box per square, when first reached (trails)
    plots/power/R/W, plots/mode/R/W, plots/squares/R/W, plots/pose/R/W (x cm, y cm, heading
    deg), plots/sensors/R/W/<sensor> (0/1)
    log/R/W                               one line per event; physics errors as ERROR
"""

from __future__ import annotations

from typing import Any

import numpy as np
import rerun as rr

from evolve.codec import LIGHT_LEFT, LIGHT_RIGHT, OBJECT_LEFT, OBJECT_RIGHT
from evolve.settings import WorldSettings
from servo_mj.robot.constants import CM_PER_M
from servobot.recording.columns import ColumnBuffer, Times, scalars
from servobot.recording.frames import bearing_dir, square_centre, yaw_quat_xyzw
from servobot.recording.style import (
    DEFAULT_ROBOT,
    LIGHT_SPAN_COLOR,
    MODES,
    OBJECT_SPAN_COLOR,
    SENSOR_COLORS,
    SENSOR_LABELS,
    SENSORS,
    RecordingSettings,
    Rgb,
    label_height_m,
)

_WARN_KINDS = ("end", "dock", "charge")
"""Event kinds logged at WARN level, so they stand out in the log."""


def sensor_wedges(world: WorldSettings, s: RecordingSettings) -> dict[int, np.ndarray]:
    """Per sensor bit, its span as a closed wedge in the robot's frame (x forward, y left, m):
    object sensors out to their range, light sensors to ``light_span_radius_m``."""
    spans = {
        OBJECT_RIGHT: (world.object_right_span_deg, world.object_range / CM_PER_M),
        OBJECT_LEFT: (world.object_left_span_deg, world.object_range / CM_PER_M),
        LIGHT_RIGHT: (world.light_right_span_deg, s.light_span_radius_m),
        LIGHT_LEFT: (world.light_left_span_deg, s.light_span_radius_m),
    }
    out = {}
    for bit, ((lo, hi), radius) in spans.items():
        arc = bearing_dir(np.linspace(lo, hi, 9)) * radius
        xy = np.vstack([[0.0, 0.0], arc, [0.0, 0.0]])
        out[bit] = np.c_[xy, np.full(len(xy), 2 * s.track_z_m)]
    return out


def event_line(event: Any) -> str:
    """The log line of one event: ``step, gene, instr, kind: text``."""
    e = event
    line = f"step {int(e.step):4d} gene {e.gene} instr {e.instruction} {e.kind}: {e.text}"
    return line + (f" (gait {e.gait})" if e.gait >= 0 and "gait" not in e.text else "")


class WorldEvents:
    """Buffers of one robot's events in one world; ``flush(rec)`` sends them."""

    def __init__(self, robot: str, world_name: str, color: Rgb, world: WorldSettings,
                 settings: RecordingSettings) -> None:  # fmt: skip
        self.robot, self.name, self.color = robot, world_name, color
        self.world, self.settings = world, settings
        self.base = f"world/robots/{robot}/{world_name}"
        self.plot = f"{robot}/{world_name}"
        what = f"robot {robot!r}, world {world_name!r}"
        self.main = ColumnBuffer(f"{what} events")
        self.moves = ColumnBuffer(f"{what} track")
        self.squares = ColumnBuffer(f"{what} squares")
        self.errors = ColumnBuffer(f"{what} errors")
        self.reached: set[int] = set()
        self.last: tuple[float, float] | None = None
        self.wedges = sensor_wedges(world, settings)
        self._styled = False

    def start(self, x_cm: float, y_cm: float) -> None:
        """Where the track begins (the start pose), so its first segment is the first move."""
        self.last = (float(x_cm), float(y_cm))

    def add(self, event: Any, times: Times) -> None:
        """One ``evolve.interpreter.StepEvent`` at ``times``."""
        x, y, h = (float(v) for v in event.pose)
        self.main.add(
            times,
            pose=(x, y, h),
            power=float(event.power),
            sensors=int(event.sensors),
            mode=float(MODES.get(event.mode, 0)),
            squares=float(event.squares),
            text=event_line(event),
            level="WARN" if event.kind in _WARN_KINDS else "INFO",
        )
        if self.last is not None and self.last != (x, y):
            self.moves.add(times, seg=(self.last, (x, y)))
        self.last = (x, y)
        new = event.new_square
        if new >= 0 and int(new) not in self.reached:
            self.reached.add(int(new))
            self.squares.add(times, square=int(new))

    def add_error(self, text: str, times: Times) -> None:
        self.errors.add(times, text=text)

    # --------------------------------------------------------------------------- sending
    def flush(self, rec: rr.RecordingStream) -> None:
        if not self._styled:
            self._log_styles(rec)
            self._styled = True
        if self.main.n:
            self._send_main(rec)
        if self.moves.n:
            seg = self.moves.array("seg") / CM_PER_M  # (n, 2, 2)
            z = np.full((self.moves.n, 2, 1), self.settings.track_z_m)
            rec.send_columns(
                f"{self.base}/track",
                indexes=self.moves.time_columns(),
                columns=rr.LineStrips3D.columns(strips=list(np.concatenate([seg, z], axis=2))),
            )
            self.moves.clear()
        if self.squares.n:
            self._send_squares(rec)
        if self.errors.n:
            rec.send_columns(
                f"log/{self.plot}",
                indexes=self.errors.time_columns(),
                columns=rr.TextLog.columns(
                    text=self.errors.rows["text"], level=["ERROR"] * self.errors.n
                ),
            )
            self.errors.clear()

    def _send_main(self, rec: rr.RecordingStream) -> None:
        m, p = self.main, self.plot
        index = m.time_columns()
        pose = m.array("pose")
        xyz = np.c_[pose[:, :2] / CM_PER_M, np.zeros(m.n)]
        rec.send_columns(
            f"{self.base}/pose",
            indexes=index,
            columns=rr.Transform3D.columns(translation=xyz, quaternion=yaw_quat_xyzw(pose[:, 2])),
        )
        bits = m.array("sensors", np.int64)
        active = [[b for b in self.wedges if row & b] for row in bits]
        strips = [self.wedges[b] for row in active for b in row]
        colors = [OBJECT_SPAN_COLOR if b & (OBJECT_LEFT | OBJECT_RIGHT) else LIGHT_SPAN_COLOR
                  for row in active for b in row]  # fmt: skip
        rec.send_columns(
            f"{self.base}/pose/sensors",
            indexes=index,
            columns=rr.LineStrips3D.columns(
                strips=strips, colors=np.asarray(colors, dtype=np.uint8).reshape(-1, 3)
            ).partition([len(row) for row in active]),
        )
        scalars(rec, f"plots/pose/{p}", index, pose)
        for path in ("power", "mode", "squares"):
            scalars(rec, f"plots/{path}/{p}", index, m.array(path))
        for sensor, bit in SENSORS:
            scalars(rec, f"plots/sensors/{p}/{sensor}", index, (bits & bit) != 0)
        rec.send_columns(
            f"log/{p}",
            indexes=index,
            columns=rr.TextLog.columns(text=m.rows["text"], level=m.rows["level"]),
        )
        m.clear()

    def _send_squares(self, rec: rr.RecordingStream) -> None:
        q = self.squares
        w, s = self.world, self.settings
        cent = np.array([square_centre(int(k), w) for k in q.rows["square"]]) / CM_PER_M
        half = w.square_size / 2 / CM_PER_M * (0.9 if self.name == "physics" else 0.55)
        rec.send_columns(
            f"{self.base}/squares",
            indexes=q.time_columns(),
            columns=rr.Boxes3D.columns(
                centers=np.c_[cent, np.full(q.n, 2 * s.plane_z_m)],
                half_sizes=np.tile([half, half, 0.001], (q.n, 1)),
            ),
        )
        q.clear()

    def _label(self) -> str:
        """The world's name, with the robot's when it is not the default robot."""
        return self.name if self.robot == DEFAULT_ROBOT else f"{self.robot} {self.name}"

    def _log_styles(self, rec: rr.RecordingStream) -> None:
        color, p = self.color, self.plot
        s = self.settings

        def log(path: str, arch: Any) -> None:
            rec.log(path, arch, static=True)

        log(f"{self.base}/squares", rr.Boxes3D.from_fields(colors=[(*color, 110)],
                                                           fill_mode="solid"))  # fmt: skip
        log(f"{self.base}/track", rr.LineStrips3D.from_fields(colors=[color], radii=0.006))
        log(
            f"{self.base}/pose/heading",
            rr.Arrows3D(
                origins=[[0.0, 0.0, 2 * s.track_z_m]], vectors=[[s.arrow_length_m, 0.0, 0.0]],
                colors=[color], radii=0.008,
            ),
        )  # fmt: skip
        # The world's name above the robot, each world at its own height, so the labels of
        # both worlds (and the lights' and station's, at the dock) do not cover each other.
        log(
            f"{self.base}/pose/label",
            rr.Points3D([[0.0, 0.0, label_height_m(self.name)]], radii=0.004, colors=[color],
                        labels=[self._label()], show_labels=True),
        )  # fmt: skip
        log(f"{self.base}/pose/sensors", rr.LineStrips3D.from_fields(radii=0.003))
        # Series names: the plot's title names the quantity (and the world, in a colony); the
        # mode shares a plot with the sensors of its robot and world.
        series = self.name if self.robot == DEFAULT_ROBOT else self.robot
        for path, name in (("power", series), ("squares", series), ("mode", "mode")):
            log(f"plots/{path}/{p}", rr.SeriesLines(colors=[color], names=[name]))
        for sensor, _ in SENSORS:
            log(
                f"plots/sensors/{p}/{sensor}",
                rr.SeriesLines(names=[SENSOR_LABELS[sensor]], colors=[SENSOR_COLORS[sensor]]),
            )
        log(
            f"plots/pose/{p}",
            rr.SeriesLines(names=[f"{a} {self.name}" for a in ("x", "y", "heading")]),
        )


__all__ = ["WorldEvents", "event_line", "sensor_wedges"]
