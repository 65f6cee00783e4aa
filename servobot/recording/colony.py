"""``ColonyRecorder``: the recording of one colony run (SPEC §7), table world and physics.

One ``.rrd`` per colony run: every robot (``robot0`` … ``robot{R-1}``) in its own colour —
the colours of the colony figures (``evolve.figures.ROBOT_COLOURS``) — with its bodies,
servos and contacts (every servo frame of its own gait cycles; once at the end of each other
robot's cycle, while it stands), its rays after each of its steps, its shell (the disc the
others' rays see) as a translucent cylinder, both worlds' poses, tracks, squares, plots and
logs (``servobot.recording.events``; the table world lighter), a ghost at its table pose,
and the station on a timeline::

    colony/W/station          StateChange: "free" | "robotK charging" (from the dock on)
    colony/W/robotK           StateChange: "coverage" | "navigation" | "waiting" (docking
                              refused: the station is busy) | "charging" (charging and its
                              backup cycles) | "ended: <reason>"
    plots/colony/W/station_waits, plots/colony/W/blocked      counts so far

Timelines: ``sim_time``, ``colony_step`` and, for events, each robot's own ``step``. In
physics ``sim_time`` is the simulated time (one clock; each robot's gait cycle takes 1.6 s
while the others stand). The table world's events carry the time the same turn would end at
in physics if every robot took every turn, ``settle_s + ((c − 1)·R + i + 1) × cycle_s`` for
robot i in colony step c; ``colony_step`` lines the two worlds up exactly.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
import rerun as rr
from matplotlib.colors import to_rgb

from evolve.figures import ROBOT_COLOURS
from evolve.settings import WorldSettings
from servo_mj.robot.constants import CM_PER_M
from servo_mj.robot.gaits import PATTERN
from servo_mj.robot.settings import PhysicsSettings
from servobot.recording.columns import ColumnBuffer, Times, scalars, times_of
from servobot.recording.recording import Recording
from servobot.recording.runs import (
    WORLDS,
    run_fields,
    run_name,
    validation_properties,
    world_fields,
)
from servobot.recording.style import RecordingSettings, Rgb


def robot_name(i: int) -> str:
    """Recording name of colony robot ``i`` (entity paths ``world/robots/robot{i}/…``)."""
    return f"robot{i}"


def robot_color(i: int) -> Rgb:
    """Colony robot ``i``'s colour (RGB 0–255), as in the colony figures."""
    r, g, b = to_rgb(ROBOT_COLOURS[i % len(ROBOT_COLOURS)])
    return round(255 * r), round(255 * g), round(255 * b)


def robot_state(event: Any) -> str | None:
    """A robot's lane state after one interpreter event (None: no change of state)."""
    if event.kind == "gait":
        return str(event.mode)
    if event.kind == "wait":
        return "waiting"
    if event.kind == "charge":
        return "charging"
    if event.kind == "end":
        return "ended: " + event.text.removeprefix("end: ")
    return None


class StationTimeline:
    """One world's station occupancy and robot states, buffered; ``flush(rec)`` sends them."""

    def __init__(self, world_name: str, names: Sequence[str]) -> None:
        self.base = f"colony/{world_name}"
        self.plots = f"plots/colony/{world_name}"
        self.names = list(names)
        self.lanes = {path: ColumnBuffer(path) for path in self._paths()}
        self.counts = ColumnBuffer(f"{self.plots} counts")
        self.state: dict[str, str] = {}
        self.holder: int | None = None
        self.waits = self.blocked = 0
        self.dock_times: dict[int, Times] = {}

    def _paths(self) -> list[str]:
        return [f"{self.base}/station"] + [f"{self.base}/{n}" for n in self.names]

    def _set(self, path: str, state: str, times: Times) -> None:
        if self.state.get(path) != state:
            self.state[path] = state
            self.lanes[path].add(times, state=state)

    def start(self, times: Times) -> None:
        """Every lane's state before the first colony step."""
        self._set(f"{self.base}/station", "free", times)
        for n in self.names:
            self._set(f"{self.base}/{n}", "coverage", times)
        self.counts.add(times, values=(0.0, 0.0))

    def add(self, i: int, event: Any, times: Times) -> None:
        """Robot ``i``'s event at ``times``."""
        station = f"{self.base}/station"
        if event.kind == "charge" and self.holder != i:  # occupied since the dock
            self.holder = i
            self._set(station, f"{self.names[i]} charging", self.dock_times.get(i, times))
        if event.kind == "charge" and event.text.startswith("charging:"):  # the last one
            self.holder = None
            self._set(station, "free", times)
        state = robot_state(event)
        if state is not None:
            self._set(f"{self.base}/{self.names[i]}", state, times)
        if event.kind == "gait":
            self.dock_times[i] = times
        counted = event.kind == "wait" or (event.kind == "gait" and "(blocked)" in event.text)
        if counted:
            self.waits += event.kind == "wait"
            self.blocked += event.kind == "gait"
            self.counts.add(times, values=(float(self.waits), float(self.blocked)))

    def flush(self, rec: rr.RecordingStream, styled: bool) -> None:
        if not styled:
            names = ["station waits", "blocked moves"]
            rec.log(self.plots, rr.SeriesLines(names=names), static=True)
        for path, buf in self.lanes.items():
            if buf.n:
                states = rr.StateChange.columns(state=buf.rows["state"])
                rec.send_columns(path, indexes=buf.time_columns(), columns=states)
                buf.clear()
        if self.counts.n:
            scalars(rec, self.plots, self.counts.time_columns(), self.counts.array("values"))
            self.counts.clear()


class ColonyRecorder:
    """Records one colony run into ``path``: the arena, the starts, properties, then the hooks
    ``table_event`` and ``physics_event`` (``run_colony``'s ``on_event`` of each world),
    ``on_frame`` (``PhysicsColony(on_frame=...)``), ``attach_physics`` (once the physics
    colony is placed), ``error`` and ``close``."""

    def __init__(
        self,
        path: str | Path,
        *,
        world: WorldSettings,
        starts: Sequence[Sequence[float]],
        physics: PhysicsSettings | None = None,
        name: str | None = None,
        app_id: str = "servobot-colony",
        properties: dict[str, Any] | None = None,
        settings: RecordingSettings | None = None,
    ) -> None:
        self.rec = Recording(path, name=name or run_name(path), app_id=app_id, settings=settings)
        self.physics = physics or PhysicsSettings()
        self.n = len(starts)
        self.names = [robot_name(i) for i in range(self.n)]
        self._pc: Any = None
        self._last = (-1, 0, False)  # robot, colony step, branch? of the latest physics event
        self._styled = False
        self.rec.log_properties(**(properties or {}))
        self.rec.log_arena(world)
        self.timelines = {w: StationTimeline(w, self.names) for w in WORLDS}
        for i, (name, start) in enumerate(zip(self.names, starts, strict=True)):
            self.rec.set_robot_color(name, robot_color(i))
            self.rec.log_start(start, world_name="table", robot=name)
        self.timelines["table"].start(times_of(0.0, colony_step=0))
        self.rec.contents.colony = True

    @classmethod
    def for_validation(cls, job: Any) -> ColonyRecorder:
        """The recorder of one ``servobot.validation.colony.ColonyJob`` (it has ``rrd_path``)."""
        physics = job.physics or PhysicsSettings()
        props = validation_properties(job, physics)
        return cls(job.rrd_path, world=job.world, starts=job.start, physics=physics,
                   app_id="servobot-validate-colony", properties=props)  # fmt: skip

    def __enter__(self) -> ColonyRecorder:
        return self

    def __exit__(self, exc_type: Any, exc: Any, tb: Any) -> None:
        self.close(save=exc_type is None)

    # ----------------------------------------------------------------------------- hooks
    def _table_time(self, i: int, colony_step: int) -> float:
        cycle = len(PATTERN) * self.physics.frame_s
        return self.physics.settle_s + ((colony_step - 1) * self.n + i + 1) * cycle

    def table_event(self, e: Any) -> None:
        """``run_colony``'s ``on_event`` in the table world (a ``ColonyEvent``)."""
        t = self._table_time(e.robot, max(e.colony_step, 1))
        self._event(e, "table", t)

    def _event(self, e: Any, world_name: str, t_s: float) -> None:
        name = self.names[e.robot]
        self.rec.log_event(e.event, world_name=world_name, t_s=t_s, robot=name,
                           colony_step=e.colony_step)  # fmt: skip
        self.timelines[world_name].add(e.robot, e.event, times_of(t_s, colony_step=e.colony_step))

    def attach_physics(self, pc: Any) -> None:
        """The physics colony, placed: every robot, its ghost, and the state after placing."""
        self._pc = pc
        for i, name in enumerate(self.names):
            prefix = pc.prefixes[i]
            self.rec.log_robot_model(pc.model, prefix=prefix, robot=name, color=robot_color(i))
            self._log_shell(pc, i)
            self.rec.log_ghost(pc.model, pc.data, prefix=prefix, robot=name, world_name="table")
            self.rec.log_start(pc.pose(i), world_name="physics", robot=name)
            self.rec.log_robot_state(pc.data, t_s=pc.t_s, robot=name, colony_step=0)
            self._log_rays(i, step=0, colony_step=0)
        self.timelines["physics"].start(times_of(pc.t_s, colony_step=0))

    def _log_shell(self, pc: Any, i: int) -> None:
        """Robot ``i``'s shell (``servo_mj.world.arena.SHELL``), static in its torso's frame;
        none for robots the rangefinders do not see (``ColonySettings.robots_seen``)."""
        import mujoco

        from servo_mj.world.arena import SHELL

        name = pc.prefixes[i] + SHELL
        if mujoco.mj_name2id(pc.model, mujoco.mjtObj.mjOBJ_GEOM, name) < 0:
            return
        g = pc.model.geom(name)
        self.rec.rec.log(
            f"world/robots/{self.names[i]}/bodies/torso/shell",
            rr.Cylinders3D(
                lengths=[2 * g.size[1]], radii=[g.size[0]], centers=[g.pos],
                colors=[(*robot_color(i), 50)], fill_mode="solid",
            ),
            static=True,
        )  # fmt: skip

    def on_frame(self, frame: Any) -> None:
        """``PhysicsColony`` frame hook: the stepping robot's state, in the colony step under
        way (the standing robots are logged once its cycle ends, in ``physics_event``)."""
        # Robot i's cycle in colony step c follows its branches in c, the events of robots
        # before it in c, and those of itself and robots after it in c − 1.
        i = self._pc.prefixes.index(frame.prefix)
        robot, step, branch = self._last
        same = robot < i or (robot == i and branch)
        colony_step = step if same and step > 0 else step + 1
        self.rec.log_robot_state(frame.data, t_s=frame.t_s, robot=self.names[i],
                                 colony_step=colony_step)  # fmt: skip

    def physics_event(self, e: Any) -> None:
        """``run_colony``'s ``on_event`` in physics (a ``ColonyEvent``)."""
        self._last = (e.robot, e.colony_step, e.event.kind == "branch")
        pc = self._pc
        self._event(e, "physics", pc.t_s)
        if e.event.kind == "gait":
            self._log_rays(e.robot, step=int(e.event.step), colony_step=e.colony_step)
            for j, name in enumerate(self.names):
                if j != e.robot:  # standing (or pushed) while robot i walked
                    self.rec.log_robot_state(pc.data, t_s=pc.t_s, robot=name,
                                             colony_step=e.colony_step)  # fmt: skip

    def _log_rays(self, i: int, *, step: int, colony_step: int) -> None:
        pc = self._pc
        left, right = (np.where(r < 0, -1.0, r / CM_PER_M) for r in pc.ray_ranges_cm(i))
        self.rec.log_rays(pc.data, left, right, t_s=pc.t_s, step=step, robot=self.names[i],
                          colony_step=colony_step)  # fmt: skip

    def error(self, text: str) -> None:
        """A physics failure: an ERROR line in robot 0's physics log, at the step under way."""
        pc = self._pc
        t = self.physics.settle_s if pc is None else pc.t_s
        self.rec.log_error(text, step=0, t_s=t, robot=self.names[0], colony_step=self._last[1])

    def close(self, record: dict[str, Any] | None = None, *, save: bool = True) -> None:
        """Save the file; ``record`` (the run's result) becomes the ``result`` property."""
        if record is not None and save:
            self.rec.log_properties(result=colony_result_fields(record))
        if save:
            for tl in self.timelines.values():
                tl.flush(self.rec.rec, self._styled)
            self._styled = True
        self.rec.close(save=save)


def colony_result_fields(record: dict[str, Any]) -> dict[str, Any]:
    """A colony run's outcome as flat property fields: per world the colony's and each
    robot's numbers, and the error if any."""

    def fields(world: str, res: dict[str, Any]) -> dict[str, Any]:
        out = {f"{world}_colony_{key}": int(value) for key, value in res["colony"].items()}
        for i, robot in enumerate(res["robots"]):
            out |= {f"{robot_name(i)}_{k}": v for k, v in run_fields(world, robot).items()}
        return out

    return world_fields(record, fields)


__all__ = [
    "ColonyRecorder",
    "StationTimeline",
    "colony_result_fields",
    "robot_color",
    "robot_name",
    "robot_state",
]
