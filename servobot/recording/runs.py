"""``RunRecorder``: the recording of one controller run, table world and (optionally) physics.

It is the set of hooks a run needs: ``table_event`` (the table world's ``on_event``),
``on_frame`` (``PhysicsWorld(on_frame=...)``), ``attach_physics`` (once the physics world is
placed), ``physics_event`` (the physics world's ``on_event``), ``error`` and ``close``.

Timelines: both worlds' events carry ``step`` and ``sim_time``. Physics events and frames
carry the physics world's simulated time; a table event at step k carries the time the same
step ends at in physics, ``settle_s + k × cycle_s`` (``cycle_s`` = 16 servo frames = 1.6 s),
so the two worlds line up on either timeline. A physics frame belongs to the step whose gait
cycle it is part of (the first cycle's frames to step 1); the state after placing is step 0.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from evolve.codec import format_chromosome
from evolve.interpreter import END_NAMES
from evolve.settings import WorldSettings
from servo_mj.robot.constants import CM_PER_M
from servo_mj.robot.gaits import PATTERN
from servo_mj.robot.settings import PhysicsSettings
from servobot.recording.provenance import provenance
from servobot.recording.recording import Recording
from servobot.recording.style import DEFAULT_ROBOT, RecordingSettings


def step_time_s(step: int, physics: PhysicsSettings) -> float:
    """Simulated time (s) at which interpreter step ``step`` ends in physics (nominal)."""
    return physics.settle_s + step * len(PATTERN) * physics.frame_s


def standing_robot() -> tuple[Any, Any]:
    """The bare robot on the calibration floor, placed and settled: (model, data)."""
    from servo_mj.robot.bot import ServoBot
    from servo_mj.robot.model import load_robot

    model, data = load_robot(scene=True)
    ServoBot(model, data).place(0.0, 0.0, 0.0)
    return model, data


def run_name(path: str | Path) -> str:
    """A run's recording name from its file: ``…/pop0/run3.rrd`` → ``pop0/run3``."""
    p = Path(path)
    return f"{p.parent.name}/{p.stem}" if p.parent.name else p.stem


class RunRecorder:
    """Records one run into ``path``: the arena, the start, properties, then the hooks.

    ``physics`` (default ``PhysicsSettings()``) sets the table world's nominal times.
    ``app_id``: recordings of one kind share it, and with it the viewer's layout.
    ``ghost``: draw the robot at the table world's pose (in physics runs the ghost is drawn
    from the physics robot by ``attach_physics``; here from the bare robot, standing).
    """

    def __init__(
        self,
        path: str | Path,
        *,
        world: WorldSettings,
        start: Sequence[float],
        physics: PhysicsSettings | None = None,
        name: str | None = None,
        app_id: str = "servobot-run",
        properties: dict[str, Any] | None = None,
        robot: str = DEFAULT_ROBOT,
        ghost: bool = False,
        settings: RecordingSettings | None = None,
    ) -> None:
        self.rec = Recording(path, name=name or run_name(path), app_id=app_id, settings=settings)
        self.robot = robot
        self.physics = physics or PhysicsSettings()
        self._pw: Any = None
        self._step = 0
        self.rec.log_properties(**(properties or {}))
        self.rec.log_arena(world)
        self.rec.log_start(start, world_name="table", robot=robot)
        if ghost:
            model, data = standing_robot()
            self.rec.log_ghost(model, data, robot=robot, world_name="table")

    @classmethod
    def for_validation(cls, job: Any) -> RunRecorder:
        """The recorder of one ``servobot.validation.lone.StartJob`` (it has ``rrd_path``)."""
        physics = job.physics or PhysicsSettings()
        return cls(
            job.rrd_path, world=job.world, start=job.start, physics=physics,
            app_id="servobot-validate", properties=validation_properties(job, physics),
        )  # fmt: skip

    @classmethod
    def for_trace(
        cls, path: str | Path, bits: np.ndarray, start: Sequence[float], *, mode: str,
        table: Any, world: WorldSettings, source: str | Path, command: str | None = None,
    ) -> RunRecorder:  # fmt: skip
        """The recorder of a table-only run (``servobot trace``), with the ghost robot (the
        shipped ServoBot); ``command`` the command line (None: ``sys.argv``)."""
        values = np.asarray(getattr(table, "values", table), dtype=np.float64)
        props = {
            "chromosome": {"text": format_chromosome(np.asarray(bits)), "file": str(source)},
            "start": dict(zip(("x_cm", "y_cm", "heading_deg"), start, strict=True)),
            "mode": mode,
            "gait_table": {"F_cm": values[:, 0], "T_cm": values[:, 1], "dH_deg": values[:, 2]},
            **provenance(model=None, table=values, table_source=getattr(table, "source", "array"),
                         command=command),
        }  # fmt: skip
        return cls(path, world=world, start=start, name=f"trace/{Path(source).stem}",
                   app_id="servobot-trace", properties=props, ghost=True)  # fmt: skip

    def __enter__(self) -> RunRecorder:
        return self

    def __exit__(self, exc_type: Any, exc: Any, tb: Any) -> None:
        self.close(save=exc_type is None)  # a no-op once closed

    # ----------------------------------------------------------------------------- hooks
    def table_event(self, event: Any) -> None:
        t = step_time_s(event.step, self.physics)
        self.rec.log_event(event, world_name="table", t_s=t, robot=self.robot)

    def attach_physics(self, pw: Any) -> None:
        """The physics world, placed: its robot, the ghost, and the state after placing."""
        self._pw = pw
        r = self.robot
        self.rec.log_robot_model(pw.model, prefix=pw.prefix, robot=r)
        self.rec.log_ghost(pw.model, pw.data, prefix=pw.prefix, robot=r, world_name="table")
        self.rec.log_start(pw.pose(), world_name="physics", robot=r)
        self.rec.log_robot_state(pw.data, t_s=pw.t_s, step=0, robot=r)
        self._log_rays(0)

    def on_frame(self, frame: Any) -> None:
        """``PhysicsWorld`` frame hook: the frame belongs to the step under way."""
        self.rec.log_robot_state(frame.data, t_s=frame.t_s, step=self._step + 1, robot=self.robot)

    def physics_event(self, event: Any) -> None:
        moved = event.step != self._step
        self._step = int(event.step)
        t = self._pw.t_s
        self.rec.log_event(event, world_name="physics", t_s=t, robot=self.robot)
        if moved:
            self._log_rays(self._step)

    def _log_rays(self, step: int) -> None:
        pw = self._pw
        left, right = (np.where(r < 0, -1.0, r / CM_PER_M) for r in pw.ray_ranges_cm())
        self.rec.log_rays(pw.data, left, right, t_s=pw.t_s, step=step, robot=self.robot)

    def error(self, text: str) -> None:
        """A physics failure: an ERROR line at the step under way."""
        pw, step = self._pw, self._step + 1
        t = step_time_s(step, self.physics) if pw is None else pw.t_s
        self.rec.log_error(text, step=step, t_s=t, robot=self.robot)

    def close(self, record: dict[str, Any] | None = None, *, save: bool = True) -> None:
        """Save the file; ``record`` (the run's result) becomes the ``result`` property."""
        if record is not None and save:
            self.rec.log_properties(result=result_fields(record))
        self.rec.close(save=save)


def validation_properties(job: Any, physics: PhysicsSettings) -> dict[str, Any]:
    """Properties of a validation run: chromosome, start, seed, gait table, settings, and the
    model, table and command that made it (``servobot.recording.provenance``). A colony run's
    job (``servobot.validation.colony.ColonyJob``) has R start poses and its
    ``ColonySettings``."""
    table = np.asarray(job.table, dtype=np.float64)
    keys = ("x_cm", "y_cm", "heading_deg")
    colony = getattr(job, "colony", None)
    if colony is None:
        start = dict(zip(keys, job.start, strict=True))
        rng = f"default_rng(({job.seed}, {job.index}))"
    else:
        start = {f"robot{i}_{k}": v for i, p in enumerate(job.start)
                 for k, v in zip(keys, p, strict=True)}  # fmt: skip
        rng = (f"robot 0: default_rng(({job.seed}, {job.index})), robot i: "
               f"default_rng(({job.seed}, {job.index}, i))")  # fmt: skip
    mode = getattr(job, "mode", "coverage")
    w = job.world
    default_steps = w.navigation_steps if mode == "navigation" else w.coverage_steps
    settings = {
        "WorldSettings": job.world, "ArenaSettings": job.arena, "PhysicsSettings": physics,
        "max_steps": job.max_steps if job.max_steps is not None else default_steps,
        "mode": mode,
    }  # fmt: skip
    if colony is not None:
        settings["ColonySettings"] = colony.to_dict()
    return {
        "chromosome": {"text": format_chromosome(np.asarray(job.bits))},
        "start": start | {"index": job.index},
        "seed": {"seed": job.seed, "servo_noise_rng": rng},
        "gait_table": {"F_cm": table[:, 0], "T_cm": table[:, 1], "dH_deg": table[:, 2]},
        "settings": settings,
        **provenance(model=job.model, table=table, table_source=job.table_source,
                     command=job.command),
    }  # fmt: skip


WORLDS = ("table", "physics")
"""The worlds of a run record, in the order their fields are listed."""


def world_fields(
    record: dict[str, Any], fields: Callable[[str, Any], dict[str, Any]]
) -> dict[str, Any]:
    """Flat property fields of a ``record`` that maps a world name (``WORLDS``) to its result
    and may hold an ``error``: ``fields(world, result)`` of each world that has a result, in
    ``WORLDS`` order, then the error if any."""
    out: dict[str, Any] = {}
    for world in WORLDS:
        res = record.get(world)
        if res:
            out |= fields(world, res)
    if record.get("error"):
        out["error"] = record["error"]
    return out


def run_fields(world: str, res: Any) -> dict[str, Any]:
    """One world's run result as ``{world}_squares`` … ``{world}_end`` (end by name)."""
    get = res.get if isinstance(res, dict) else lambda k: getattr(res, k)
    out = {
        f"{world}_{key}": int(get(key)) for key in ("squares", "inner_squares", "docks", "steps")
    }
    end = get("end")
    out[f"{world}_end"] = end["name"] if isinstance(end, dict) else END_NAMES[int(end)]
    return out


def result_fields(record: dict[str, Any]) -> dict[str, Any]:
    """A run's outcome as flat property fields: ``record`` maps a world name to its result —
    a ``servobot.validation.lone`` run record or an ``evolve.interpreter.RunResult`` — and may hold
    an ``error``."""
    return world_fields(record, run_fields)


__all__ = [
    "WORLDS",
    "RunRecorder",
    "result_fields",
    "run_fields",
    "run_name",
    "standing_robot",
    "step_time_s",
    "validation_properties",
    "world_fields",
]
