"""Display choices of a recording (``RecordingSettings``), colours, and the names it plots.

None of these affects a simulation result.
"""

from __future__ import annotations

from dataclasses import dataclass

from evolve.codec import LIGHT_LEFT, LIGHT_RIGHT, LOW_POWER, OBJECT_LEFT, OBJECT_RIGHT

DEFAULT_ROBOT = "servobot"
"""Name of the robot when a recording holds one (entity paths ``world/robots/<robot>/…``)."""

SENSORS: tuple[tuple[str, int], ...] = (
    ("object_right", OBJECT_RIGHT),
    ("object_left", OBJECT_LEFT),
    ("low_power", LOW_POWER),
    ("light_right", LIGHT_RIGHT),
    ("light_left", LIGHT_LEFT),
)
"""The five sensors: (series name, bit in a StepEvent's ``sensors`` mask)."""

SENSOR_LABELS: dict[str, str] = {
    "object_right": "object R", "object_left": "object L", "low_power": "low power",
    "light_right": "light R", "light_left": "light L",
}  # fmt: skip
"""Each sensor's name in a plot's legend."""
SENSOR_COLORS: dict[str, tuple[int, int, int]] = {
    "object_right": (230, 60, 60), "object_left": (150, 20, 20), "low_power": (160, 160, 160),
    "light_right": (250, 210, 0), "light_left": (230, 140, 0),
}  # fmt: skip
"""Each sensor's line colour in the plots."""

MODES: dict[str, int] = {"coverage": 0, "navigation": 1, "charging": 2, "charge": 2}
"""Numeric value plotted for each controller mode name."""

Rgb = tuple[int, int, int]

WORLD_COLORS: dict[str, Rgb] = {"physics": (230, 120, 30), "table": (40, 120, 230)}
"""Track, squares and pose colour per world name; other names get grey."""
OTHER_COLOR: Rgb = (150, 150, 150)
FOOT_CONTACT_COLOR: Rgb = (40, 170, 60)
BODY_CONTACT_COLOR: Rgb = (220, 40, 40)
RAY_HIT_COLOR: Rgb = (230, 30, 30)
RAY_FREE_COLOR: tuple[int, int, int, int] = (170, 170, 170, 60)
OBJECT_SPAN_COLOR: Rgb = (230, 30, 30)
LIGHT_SPAN_COLOR: Rgb = (250, 210, 0)


@dataclass(frozen=True)
class RecordingSettings:
    """Display choices of a recording. None of these affects a simulation result."""

    wall_height_m: float = 0.15
    """Height of the drawn walls, m (display only; the physics arena has its own)."""
    wall_thickness_m: float = 0.02
    """Thickness of the drawn walls, outside the arena, m (display only)."""
    station_depth_m: float = 0.20
    """Station block protrudes this far from the east wall, m (SPEC §3 'In MuJoCo')."""
    station_height_m: float = 0.10
    """Height of the drawn station block, m (display only)."""
    plane_z_m: float = 0.001
    """Height of the floor markings above z = 0, m, so they do not fight with the floor."""
    track_z_m: float = 0.01
    """Height of the drawn tracks, m."""
    max_buffer_rows: int = 20_000
    """Buffered rows per entity before they are sent (bounds memory on long runs)."""
    robot_geom_groups: tuple[int, ...] = (0, 1, 2)
    """MuJoCo geom groups drawn for the robot (visual groups); others only if a body has none."""
    servo_detail: bool = True
    """Record joint targets and angles, contacts with their forces and the torso's roll and
    pitch every servo frame (False: only the bodies' poses, a smaller file)."""
    arrow_length_m: float = 0.20
    """Length of the heading arrow drawn at each world's pose, m."""
    force_scale_m_per_n: float = 0.02
    """Drawn length of a contact force arrow per newton, m/N (the robot weighs ≈ 9.8 N)."""
    force_max_length_m: float = 0.10
    """Longest drawn contact force arrow, m: a longer one (a force above 5 N at 0.02 m/N, e.g.
    a stiff contact against the station block) is drawn this long, along its direction."""
    light_span_radius_m: float = 0.30
    """Drawn radius of the light-sensor span wedges, m (their range is unlimited)."""
    ghost_alpha: int = 80
    """Opacity (0–255) of the ghost robot drawn at the table world's pose."""
    playback_speed: float = 8.0
    """Initial playback speed of the time panel (× simulated time); on a step timeline the
    time panel plays the steps at the rate this speed gives them (8×: 5 steps a second, a
    colony step of R robots R times slower)."""
    max_plot_series: int = 6
    """Most series drawn in one plot; more are split over several plots."""
    follow_eye_m: tuple[float, float, float] = (-0.45, -0.55, 0.40)
    """Where a follow view's camera sits relative to the robot it follows (x east, y north,
    z up), m."""


LABEL_HEIGHTS_M: dict[str, float] = {"physics": 0.28, "table": 0.38}
"""Height of a world's name above its pose, m (other worlds: 0.48)."""


def label_height_m(world_name: str) -> float:
    """Height of a world's name above its pose, m: each world its own, so none covers another."""
    return LABEL_HEIGHTS_M.get(world_name, 0.48)


def world_color(world_name: str) -> Rgb:
    """The colour of a world's track, squares and pose."""
    return WORLD_COLORS.get(world_name, OTHER_COLOR)


def tint(color: Rgb, world_name: str) -> Rgb:
    """A robot's own colour for its physics world, lighter for any other world."""
    if world_name == "physics":
        return color
    return tuple(int(c + (255 - c) * 0.5) for c in color)  # type: ignore[return-value]


__all__ = [
    "DEFAULT_ROBOT",
    "MODES",
    "SENSORS",
    "WORLD_COLORS",
    "RecordingSettings",
    "label_height_m",
    "tint",
    "world_color",
]
