"""Rerun recordings (``.rrd``) of calibration walks, table runs and physics runs.

One :class:`Recording` writes one ``.rrd`` file that a user opens with ``rerun FILE.rrd``: a
name (e.g. ``pop0/run3``) and properties (chromosome, start, seed, gait table, settings,
result, and the model, table and command that made it: ``provenance``), a static scene, one
or more robots (``robot=``, default ``"servobot"``) with their bodies, servos, contacts and
sensor rays every servo frame, the interpreter's events of each
world ("physics", "table") as tracks, squares, poses, sensor spans, plots and a text log, and
a blueprint that lays these out. :class:`RunRecorder` holds the hooks of one controller run;
``calibration_recorder`` those of a calibration.

Frames and units: metres in the MuJoCo world frame (x east, y north, z up); arena poses
(x, y cm; heading deg, 0 = north, clockwise) are converted here (``frames``). Timelines:
``sim_time`` (seconds of simulated time), ``step`` (interpreter gait steps), ``colony_step``
(colony steps) and ``cycle`` (calibration gait cycles); a recording opens on the step
timeline both worlds share (``blueprint``).

Modules: ``recording`` (the file), ``arena`` (scenery), ``shapes`` (robot geoms),
``robot`` (a physics robot over time), ``events`` (a world's interpreter events),
``calibration``, ``runs`` (one run's hooks), ``colony`` (one colony run's hooks),
``blueprint`` (the layout), ``provenance`` (model, table, command), ``columns`` (column
buffers), ``frames`` (units and rotations), ``style`` (display settings and colours).
"""

from servobot.recording.arena import dark_polygons
from servobot.recording.calibration import calibration_recorder, log_calibration_result
from servobot.recording.frames import arena_to_m, heading_to_yaw_rad, square_centre
from servobot.recording.recording import Recording
from servobot.recording.runs import RunRecorder
from servobot.recording.style import DEFAULT_ROBOT, SENSORS, RecordingSettings

__all__ = [
    "DEFAULT_ROBOT",
    "SENSORS",
    "Recording",
    "RecordingSettings",
    "RunRecorder",
    "arena_to_m",
    "calibration_recorder",
    "dark_polygons",
    "heading_to_yaw_rad",
    "log_calibration_result",
    "square_centre",
]
