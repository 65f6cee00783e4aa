"""Recording a calibration (``calibration.calibrate.calibrate``): 16 robots, one per gait.

Each gait's walk is its own robot ``gait_<gg>`` standing at its own start on the 4 × 4 grid
of ``CalibrationSettings.start_spacing_cm``, so no robot jumps from one walk to the next; all
16 walk at once on ``sim_time`` (each walk's own simulated time) and ``cycle`` (gait cycles
since the robot was placed, settling cycles first). A floor with a 1 m grid and the labelled
starts lies under them. Measured cycles go to ``plots/calibration/{F,T,dH}/gait_<gg>`` and to
the text log ``log/calibration``.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import rerun as rr

from servobot.recording.columns import ColumnBuffer, Times, scalars
from servobot.recording.provenance import command_text, table_sha256

SERIES = (("F", "cm"), ("T", "cm"), ("dH", "deg"))
"""The measured quantities of a calibration cycle and their units."""


def gait_robot(gait: int) -> str:
    """Robot name of a gait's calibration walk."""
    return f"gait_{int(gait):02d}"


class CalibrationCycles:
    """Buffers of the measured cycles (F, T cm; dH deg) per gait; ``flush(rec)`` sends them."""

    def __init__(self) -> None:
        self.per_gait: dict[int, ColumnBuffer] = {}
        self.log = ColumnBuffer("calibration log")
        self.styled: set[int] = set()

    def add(self, gait: int, F: float, T: float, dH: float, times: Times) -> None:
        """One measured cycle at ``times`` (``cycle`` and ``sim_time``)."""
        buf = self.per_gait.setdefault(int(gait), ColumnBuffer(f"calibration gait {gait}"))
        buf.add(times, F=F, T=T, dH=dH)
        text = f"gait {gait} cycle {times['cycle']}: F={F:.2f} cm T={T:.2f} cm dH={dH:.2f} deg"
        self.log.add(times, text=text)

    def flush(self, rec: rr.RecordingStream) -> None:
        for gait, buf in sorted(self.per_gait.items()):
            if not buf.n:
                continue
            index = buf.time_columns()
            for comp, unit in SERIES:
                path = f"plots/calibration/{comp}/{gait_robot(gait)}"
                if gait not in self.styled:  # each cycle a point, joined by lines
                    name = [f"{comp} {unit}"]
                    rec.log(path, rr.SeriesLines(names=name), static=True)
                    rec.log(path, rr.SeriesPoints(names=name, marker_sizes=[3.0]), static=True)
                scalars(rec, path, index, buf.array(comp))
            self.styled.add(gait)
            buf.clear()
        if self.log.n:
            rec.send_columns(
                "log/calibration",
                indexes=self.log.time_columns(),
                columns=rr.TextLog.columns(text=self.log.rows["text"]),
            )
            self.log.clear()


def calibration_recorder(rec: Any, settings: Any, command: str | None = None) -> dict[str, Any]:
    """Keyword arguments of ``calibration.calibrate.calibrate`` that record its walks in the
    ``Recording`` ``rec``: the calibration scene's model, ``on_frame`` (each gait robot's
    bodies, servos, contacts and feet every servo frame) and ``on_cycle`` (F, T, dH of each
    measured cycle). Also logs the floor, the starts, and the settings, the model and
    ``command`` (None: ``sys.argv``) as properties; ``log_calibration_result`` adds the
    measured table."""
    import mujoco

    from calibration.measure import start_pose
    from servo_mj.robot import constants as C
    from servo_mj.robot.gaits import GAIT_KIND, N_GAITS, PATTERN
    from servo_mj.robot.model import load_robot, model_label, model_sha256

    model, _ = load_robot(scene=True, model=settings.model)
    feet = [mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_SITE, n) for n in C.foot_sites()]
    starts = [start_pose(g, settings.start_spacing_cm)[:2] for g in range(N_GAITS)]
    rec.log_calibration_floor(starts, [f"gait {g}: {GAIT_KIND[g]}" for g in range(N_GAITS)])
    rec.log_properties(
        calibration=settings.to_dict() | {"model": model_label(settings.model)},
        model={"label": model_label(settings.model), "sha256": model_sha256(settings.model)},
        command={"text": command_text(command)},
    )
    for g in range(N_GAITS):
        rec.log_robot_model(model, robot=gait_robot(g))
    frames = np.zeros(N_GAITS, dtype=np.int64)

    def on_frame(g: int, d: Any) -> None:
        cycle = int(frames[g]) // len(PATTERN)
        frames[g] += 1
        rec.log_robot_state(d, t_s=d.time, cycle=cycle, robot=gait_robot(g))
        rec.log_feet(d.site_xpos[feet], t_s=d.time, cycle=cycle, robot=gait_robot(g))

    def on_cycle(g: int, res: Any, bot: Any) -> None:
        f, t, dh = res.ftdh
        rec.log_calibration_cycle(g, res.cycle, f, t, dh, t_s=res.t_end_s)

    return {"model": model, "on_frame": on_frame, "on_cycle": on_cycle}


def log_calibration_result(rec: Any, result: Any) -> None:
    """The measured gait table (a ``CalibrationResult``) as the recording's ``result``, and
    the file it was written to as its ``table`` (source, sha256 of the values)."""
    from calibration.report import within_tolerance

    values, std = np.asarray(result.values), np.asarray(result.std)
    rec.log_properties(table={"source": str(result.table_path), "sha256": table_sha256(values)})
    rec.log_properties(
        result={
            "F_cm": values[:, 0], "T_cm": values[:, 1], "dH_deg": values[:, 2],
            "F_std_cm": std[:, 0], "T_std_cm": std[:, 1], "dH_std_deg": std[:, 2],
            "within_tolerance": int(within_tolerance(values).sum()),
            "wall_s": float(result.wall_s),
        }
    )  # fmt: skip


__all__ = ["CalibrationCycles", "calibration_recorder", "gait_robot", "log_calibration_result"]
