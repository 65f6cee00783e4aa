"""The layout a recording opens with (rerun blueprint), built from what was recorded.

Left: the whole scene (``arena``), seen from the south-west above, and below it a close-up
that follows the robot (``follow``; in a colony one per robot, in a calibration one per gait
in its tab). Tracks, reached squares and feet are drawn from the start to the cursor
(per-entity visible time ranges: trails) while the robot, its contacts, rays and sensor spans
show the state at the cursor. Right: tabs of plots above the text log — ``run`` (power,
squares reached), ``pose``, ``sensors`` (the five sensors and the mode, per robot and world),
the servos of each physics robot (servo targets and angles per leg, torso roll and pitch,
foot forces; in a calibration one tab per gait with its F, T, dH), ``colony`` (station and
robots as lanes, waits and blocked moves). A plot draws at most
``RecordingSettings.max_plot_series`` series (more are split over several plots), over the
whole run, with its legend small in a corner.

The time panel opens on the step timeline both worlds share: ``colony_step`` in a colony run,
``step`` in a lone run (the table world and physics at the same interpreter step), played at
``playback_speed`` × simulated time; a calibration (one world) opens on ``sim_time``.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import rerun as rr
import rerun.blueprint as rrb

from servo_mj.robot.constants import LEGS
from servo_mj.robot.gaits import PATTERN
from servo_mj.robot.settings import PhysicsSettings
from servobot.recording.calibration import gait_robot
from servobot.recording.style import RecordingSettings

STEP_TIMELINES = ("colony_step", "step")
"""Sequence timelines both worlds share, in order of preference for the time panel."""


@dataclass
class Contents:
    """What a recording holds, as far as its layout cares."""

    timelines: set[str] = field(default_factory=set)
    robots: list[str] = field(default_factory=list)
    """Physics robots (bodies), in the order they were added."""
    follow: set[str] = field(default_factory=set)
    """Physics robots with a ``follow`` frame (their torso's place on the floor)."""
    detail: bool = False
    """Whether joints, contacts and attitude were recorded."""
    worlds: list[tuple[str, str]] = field(default_factory=list)
    """(robot, world) pairs with interpreter events."""
    feet: list[str] = field(default_factory=list)
    """Robots whose feet were recorded."""
    gaits: list[int] = field(default_factory=list)
    """Gaits with measured calibration cycles (``plots/calibration/…/gait_<gg>``)."""
    colony: bool = False
    """Whether station occupancy and robot states were recorded (``colony/…``)."""
    scene: tuple[tuple[float, float], tuple[float, float]] | None = None
    """Floor extent ((x0, y0), (x1, y1)) in metres, for the initial camera."""

    @property
    def calibration(self) -> bool:
        return bool(self.gaits)


def trail_entities(c: Contents) -> list[str]:
    """Entities drawn from the start of the timeline to the cursor."""
    out = [f"world/robots/{r}/{w}/{part}" for r, w in c.worlds for part in ("track", "squares")]
    return out + [f"world/robots/{r}/feet" for r in c.feet]


def default_timeline(c: Contents) -> str | None:
    """The timeline the time panel opens on: a step timeline both worlds share
    (``colony_step``, else ``step``), else ``sim_time`` (a calibration), else any."""
    for name in (*STEP_TIMELINES, "sim_time", "cycle"):
        if name in c.timelines:
            return name
    return min(c.timelines) if c.timelines else None


def playback_fps(c: Contents, s: RecordingSettings) -> float | None:
    """Steps a second on the default timeline, when it is a step timeline: ``playback_speed``
    × simulated time (a colony step takes every robot's turn)."""
    timeline = default_timeline(c)
    if timeline not in STEP_TIMELINES:
        return None
    physics = PhysicsSettings()
    cycle_s = len(PATTERN) * physics.frame_s
    robots = len({r for r, _ in c.worlds}) if timeline == "colony_step" else 1
    return s.playback_speed / (cycle_s * max(robots, 1))


def follow_entity(c: Contents, robot: str) -> str:
    """The frame a follow view of ``robot`` sits in: its ``follow`` frame (the torso's place on
    the floor, not turning with it), else its first world's pose (a table-only run)."""
    if robot in c.follow:
        return f"world/robots/{robot}/follow"
    world = next(w for r, w in c.worlds if r == robot)
    return f"world/robots/{robot}/{world}/pose"


def followed(c: Contents) -> list[str]:
    """Robots a follow view shows: the physics robots, then robots with only events."""
    out = list(c.robots)
    return out + [r for r in dict.fromkeys(r for r, _ in c.worlds) if r not in out]


# ----------------------------------------------------------------------------- 3D views
def _trails(c: Contents, robot: str | None = None) -> dict[str, Any]:
    """Overrides drawing the trail entities (of ``robot`` only, when given) as trails."""
    start, end = rr.TimeRangeBoundary.infinite(), rr.TimeRangeBoundary.cursor_relative()
    trails = rrb.VisibleTimeRanges(
        [rr.VisibleTimeRange(tl, start=start, end=end) for tl in sorted(c.timelines)]
    )
    mine = f"world/robots/{robot}/"
    return {e: trails for e in trail_entities(c) if robot is None or e.startswith(mine)}


def arena_view(c: Contents, *, near: bool = False) -> rrb.Spatial3DView:
    """The whole scene, seen from the south-west above (``near``: closer, for a view that
    shares its column with follow views), with the names of the lights and the station (the
    robots' names are in their follow views)."""
    eye = None
    if c.scene is not None:
        (x0, y0), (x1, y1) = c.scene
        cx, cy, span = (x0 + x1) / 2, (y0 + y1) / 2, max(x1 - x0, y1 - y0)
        d = 0.85 if near else 1.0
        eye = rrb.EyeControls3D(
            position=[cx - 0.35 * d * span, cy - 0.9 * d * span, 0.8 * d * span],
            look_target=[cx, cy, 0.0],
        )
    hidden = [f"- /world/robots/{r}/{w}/pose/label" for r, w in c.worlds]
    return rrb.Spatial3DView(
        origin="world", contents=["$origin/**", *hidden], name="arena", overrides=_trails(c),
        eye_controls=eye,
    )  # fmt: skip


def follow_view(c: Contents, robot: str, s: RecordingSettings, name: str) -> rrb.Spatial3DView:
    """A close-up that follows ``robot``: the view's frame is the robot's follow frame, so the
    camera (``follow_eye_m`` from it) moves with the robot; the whole world is drawn, with the
    names of ``robot``'s worlds (not the arena's names, nor other robots')."""
    eye = rrb.EyeControls3D(position=list(s.follow_eye_m), look_target=[0.0, 0.0, 0.05])
    hidden = ["- /world/arena/labels", "- /world/arena/starts"]
    hidden += [f"- /world/robots/{r}/{w}/pose/label" for r, w in c.worlds if r != robot]
    return rrb.Spatial3DView(
        origin=follow_entity(c, robot), contents=["/world/**", *hidden], name=name,
        overrides=_trails(c, robot if c.calibration else None),
        eye_controls=eye,
    )  # fmt: skip


# ----------------------------------------------------------------------------- plots
def whole_run() -> rrb.TimeAxis:
    """A plot's time axis over the whole run (a plot draws every time by default, but its axis
    would show a window around the cursor)."""
    inf = rr.TimeRangeBoundary.infinite()
    return rrb.TimeAxis(view_range=rr.TimeRange(inf, inf))


def plot(c: Contents, name: str, paths: Sequence[str], *, legend: bool = True) -> Any:
    """A time series view of the entities ``paths`` (their series) over the whole run; the
    legend (short series names) in the viewer's default corner, or hidden."""
    return rrb.TimeSeriesView(
        origin="/", contents=[f"/{p}" for p in paths], name=name, axis_x=whole_run(),
        plot_legend=None if legend else rrb.PlotLegend(visible=False),
    )  # fmt: skip


def chunks(items: Sequence[Any], most: int) -> list[list[Any]]:
    """``items`` in order, split into the fewest runs of at most ``most``, sizes within one."""
    n = max(1, -(-len(items) // max(most, 1)))
    size, extra = divmod(len(items), n)
    out, k = [], 0
    for i in range(n):
        m = size + (i < extra)
        out.append(list(items[k : k + m]))
        k += m
    return [x for x in out if x]


def _per_world_plots(c: Contents, s: RecordingSettings, quantity: str, title: str) -> list[Any]:
    """``plots/<quantity>/R/W`` of every (robot, world): one robot's worlds in one plot; several
    robots' one plot per world (split further past ``max_plot_series`` robots)."""
    robots = _robots_of_worlds(c)
    if len(robots) == 1:
        return [plot(c, title, [f"plots/{quantity}/{r}/{w}" for r, w in c.worlds])]
    out = []
    for world in dict.fromkeys(w for _, w in c.worlds):
        mine = [r for r, w in c.worlds if w == world]
        for part in chunks(mine, s.max_plot_series):
            some = f" ({part[0]}–{part[-1]})" if len(part) < len(mine) else ""
            out.append(
                plot(c, f"{title}, {world}{some}", [f"plots/{quantity}/{r}/{world}" for r in part])
            )
    return out


def _robots_of_worlds(c: Contents) -> list[str]:
    return list(dict.fromkeys(r for r, _ in c.worlds))


def _run_tabs(c: Contents, s: RecordingSettings) -> list[Any]:
    """``run`` (power, squares), ``pose`` and ``sensors`` of the interpreter's events."""
    robots = _robots_of_worlds(c)
    one = len(robots) == 1
    run = _per_world_plots(c, s, "power", "power (V)") + _per_world_plots(
        c, s, "squares", "squares reached"
    )
    pose = []
    for r in robots:
        worlds = [w for rr_, w in c.worlds if rr_ == r]
        for part in chunks(worlds, max(1, s.max_plot_series // 3)):
            title = "pose (cm, deg)" if one else f"{r} pose (cm, deg)"
            pose.append(plot(c, title, [f"plots/pose/{r}/{w}" for w in part]))
    sensors = []
    for r, w in c.worlds:
        title = f"{w} sensors, mode" if one else f"{r} {w}"
        sensors.append(plot(c, title, [f"plots/sensors/{r}/{w}/**", f"plots/mode/{r}/{w}"]))
    n_worlds = len(dict.fromkeys(w for _, w in c.worlds))
    return [
        rrb.Vertical(*run, name="run"),
        rrb.Vertical(*pose, name="pose"),
        rrb.Grid(*sensors, grid_columns=n_worlds, name="sensors"),
    ]


def _servo_views(c: Contents, r: str) -> tuple[Any, list[Any]]:
    """One physics robot's joints (a grid, one plot per leg) and body plots."""
    # No legends on these small plots: thrust blue, lift orange, target light, angle dark.
    legs = [plot(c, f"{g} servo (deg)", [f"plots/joints/{r}/{g}"], legend=False) for g in LEGS]
    body = [
        plot(c, "torso roll, pitch (deg)", [f"plots/attitude/{r}"]),
        plot(c, "foot normal force (N)", [f"plots/foot_force/{r}"]),
    ]
    return rrb.Grid(*legs, grid_columns=2), body


def _servo_tabs(c: Contents) -> list[Any]:
    """A tab per physics robot (not a calibration's): its joints, roll and pitch, foot forces."""
    tabs = []
    for r in c.robots:
        joints, body = _servo_views(c, r)
        name = "servos" if len(c.robots) == 1 else f"{r} servos"
        tabs.append(rrb.Vertical(joints, rrb.Horizontal(*body), name=name, row_shares=[3, 1]))
    return tabs


def _gait_tabs(c: Contents, s: RecordingSettings) -> list[Any]:
    """A calibration: a tab per gait — its walk followed close up, its F, T, dH per cycle, its
    joints, roll and pitch and foot forces."""
    tabs = []
    for g in c.gaits:
        r = gait_robot(g)
        ftdh = plot(
            c, "F, T (cm), dH (deg)", [f"plots/calibration/{k}/{r}" for k in ("F", "T", "dH")]
        )
        top: list[Any] = [ftdh]
        views: list[Any] = []
        if r in c.robots:
            top.insert(0, follow_view(c, r, s, f"follow gait {g}"))
            if c.detail:
                joints, body = _servo_views(c, r)
                views = [joints, rrb.Horizontal(*body)]
        shares = [2, 3, 1][: 1 + len(views)]
        tabs.append(rrb.Vertical(rrb.Horizontal(*top), *views, name=f"gait {g}", row_shares=shares))
    return tabs


def _colony_tab(c: Contents) -> Any:
    return rrb.Vertical(
        rrb.StateTimelineView(origin="colony", name="station and robots", time_view=whole_run()),
        plot(c, "station waits, blocked moves (so far)", ["plots/colony/**"]),
        name="colony",
        row_shares=[2, 1],
    )  # fmt: skip


def _tabs(c: Contents, s: RecordingSettings) -> list[Any]:
    tabs: list[Any] = []
    if c.worlds:
        tabs += _run_tabs(c, s)
    if c.calibration:
        tabs += _gait_tabs(c, s)
    elif c.detail:
        tabs += _servo_tabs(c)
    if c.colony:
        tabs.append(_colony_tab(c))
    return tabs


def _left(c: Contents, s: RecordingSettings) -> Any:
    """The arena and, unless a calibration (whose tabs follow each gait), the follow views."""
    robots = [] if c.calibration else followed(c)
    if not robots:
        return arena_view(c)
    one = len(robots) == 1
    follows = [follow_view(c, r, s, "follow" if one else f"follow {r}") for r in robots]
    below = follows[0] if one else rrb.Grid(*follows, grid_columns=min(len(follows), 3))
    return rrb.Vertical(arena_view(c, near=True), below, row_shares=[3, 2])


def make_blueprint(c: Contents, s: RecordingSettings) -> rrb.Blueprint:
    """The layout for a recording with contents ``c``."""
    tabs, log = _tabs(c, s), rrb.TextLogView(origin="log", name="log")
    right = rrb.Vertical(rrb.Tabs(*tabs), log, row_shares=[3, 1]) if tabs else log
    return rrb.Blueprint(
        rrb.Horizontal(_left(c, s), right, column_shares=[3, 2]),
        rrb.BlueprintPanel(state="expanded"),
        rrb.SelectionPanel(state="expanded"),
        rrb.TimePanel(
            state="expanded",
            timeline=default_timeline(c),
            playback_speed=s.playback_speed,
            fps=playback_fps(c, s),
        ),  # fmt: skip
        collapse_panels=False,
    )


__all__ = [
    "Contents",
    "chunks",
    "default_timeline",
    "follow_entity",
    "make_blueprint",
    "playback_fps",
    "trail_entities",
]
