"""The layout a recording opens with (rerun blueprint), built from what was recorded.

Left: the 3D scene, seen from the south-west above, at the time cursor (latest values), with
tracks, reached squares and feet drawn from the start to the cursor (per-entity visible time
ranges, so they draw trails while the robot, its contacts, rays and sensor spans show only the
current state). Right: tabs of time series — ``run`` (power, sensors and mode, squares, pose),
``joints`` (servo target vs angle per leg), ``body`` (torso roll and pitch, foot forces),
``colony`` (station occupancy and each robot's state as lanes, waits and blocked moves),
``calibration`` (F, T, dH per cycle) — above the text log. The blueprint, selection and time
panels open expanded, the time panel on ``sim_time`` when the recording has it.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import rerun as rr
import rerun.blueprint as rrb

from servo_mj.robot.constants import LEGS
from servobot.recording.style import RecordingSettings


@dataclass
class Contents:
    """What a recording holds, as far as its layout cares."""

    timelines: set[str] = field(default_factory=set)
    robots: list[str] = field(default_factory=list)
    """Physics robots (bodies), in the order they were added."""
    detail: bool = False
    """Whether joints, contacts and attitude were recorded."""
    worlds: list[tuple[str, str]] = field(default_factory=list)
    """(robot, world) pairs with interpreter events."""
    feet: list[str] = field(default_factory=list)
    """Robots whose feet were recorded."""
    calibration: bool = False
    colony: bool = False
    """Whether station occupancy and robot states were recorded (``colony/…``)."""
    scene: tuple[tuple[float, float], tuple[float, float]] | None = None
    """Floor extent ((x0, y0), (x1, y1)) in metres, for the initial camera."""


def trail_entities(c: Contents) -> list[str]:
    """Entities drawn from the start of the timeline to the cursor."""
    out = [f"world/robots/{r}/{w}/{part}" for r, w in c.worlds for part in ("track", "squares")]
    return out + [f"world/robots/{r}/feet" for r in c.feet]


def default_timeline(c: Contents) -> str | None:
    """``sim_time`` when present (smooth motion), else ``step``, else any."""
    for name in ("sim_time", "step", "cycle"):
        if name in c.timelines:
            return name
    return min(c.timelines) if c.timelines else None


def _view3d(c: Contents) -> rrb.Spatial3DView:
    start, end = rr.TimeRangeBoundary.infinite(), rr.TimeRangeBoundary.cursor_relative()
    trails = rrb.VisibleTimeRanges(
        [rr.VisibleTimeRange(tl, start=start, end=end) for tl in sorted(c.timelines)]
    )
    eye = None
    if c.scene is not None:
        (x0, y0), (x1, y1) = c.scene
        cx, cy, span = (x0 + x1) / 2, (y0 + y1) / 2, max(x1 - x0, y1 - y0)
        eye = rrb.EyeControls3D(
            position=[cx - 0.35 * span, cy - 0.9 * span, 0.8 * span], look_target=[cx, cy, 0.0]
        )
    overrides: dict[str, Any] = {e: trails for e in trail_entities(c)}
    return rrb.Spatial3DView(origin="world", name="3D", overrides=overrides, eye_controls=eye)


def _tabs(c: Contents) -> list[Any]:
    ts = rrb.TimeSeriesView
    tabs: list[Any] = []
    if c.worlds:
        tabs.append(
            rrb.Vertical(
                ts(origin="plots/power", name="power (V)"),
                ts(name="sensors (0/1) and mode", contents=["plots/sensors/**", "plots/mode/**"]),
                ts(origin="plots/squares", name="squares reached"),
                ts(origin="plots/pose", name="pose (cm, deg)"),
                name="run",
            )
        )
    if c.robots and c.detail:
        r = c.robots[0]
        legs = [ts(origin=f"plots/joints/{r}/{g}", name=f"{g} servo (deg), {r}") for g in LEGS]
        tabs.append(rrb.Grid(*legs, grid_columns=2, name="joints"))
        tabs.append(
            rrb.Vertical(
                ts(origin=f"plots/attitude/{r}", name=f"torso roll, pitch (deg), {r}"),
                ts(origin=f"plots/foot_force/{r}", name=f"foot normal force (N), {r}"),
                name="body",
            )
        )
    if c.colony:
        tabs.append(
            rrb.Vertical(
                rrb.StateTimelineView(origin="colony", name="station and robots"),
                ts(origin="plots/colony", name="station waits, blocked moves (so far)"),
                name="colony",
                row_shares=[2, 1],
            )
        )
    if c.calibration:
        tabs.append(
            rrb.Vertical(
                *[
                    ts(origin=f"plots/calibration/{k}", name=f"calibration {k} ({unit})")
                    for k, unit in (("F", "cm"), ("T", "cm"), ("dH", "deg"))
                ],
                name="calibration",
            )  # fmt: skip
        )
    return tabs


def make_blueprint(c: Contents, s: RecordingSettings) -> rrb.Blueprint:
    """The layout for a recording with contents ``c``."""
    tabs, log = _tabs(c), rrb.TextLogView(origin="log", name="log")
    right = rrb.Vertical(rrb.Tabs(*tabs), log, row_shares=[3, 1]) if tabs else log
    return rrb.Blueprint(
        rrb.Horizontal(_view3d(c), right, column_shares=[3, 2]),
        rrb.BlueprintPanel(state="expanded"),
        rrb.SelectionPanel(state="expanded"),
        rrb.TimePanel(
            state="expanded", timeline=default_timeline(c), playback_speed=s.playback_speed
        ),
        collapse_panels=False,
    )


__all__ = ["Contents", "default_timeline", "make_blueprint", "trail_entities"]
