"""The static scenery of a recording: the colony arena (SPEC §3) or a calibration floor.

Everything is logged once with ``static=True`` under ``world/arena/``, in metres on z ≈ 0:
``floor``, ``walls``, ``station``, ``lights``, ``squares``, ``contact_zones``, ``inner``,
``kill_zone``, ``cones`` (the lit cones' edges), ``dark`` (the dark area, filled), ``labels``
(the names of the lights and the station, beyond the east wall); or, for a
calibration, ``floor``, ``grid`` (1 m lines) and ``starts`` (each walk's start, labelled).
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Sequence

import numpy as np
import rerun as rr

from evolve.settings import WorldSettings
from servo_mj.robot.constants import CM_PER_M
from servobot.recording.frames import arena_to_m, rect_strip
from servobot.recording.style import RecordingSettings

FLOOR_COLOR = (225, 215, 190)
LABEL_OUTSIDE_M = 0.25
"""How far beyond the east wall the names of the lights and the station stand, m."""
LABEL_SPREAD_M = 0.45
"""How far the lights' names stand beyond their lights, away from the station (along y), m."""


def log_arena(rec: rr.RecordingStream, world: WorldSettings, s: RecordingSettings) -> None:
    """The whole arena: floor, walls, station, lights, grid, kill zone, lit cones, dark area."""
    log_walls(rec, world, s)
    log_grid(rec, world, s)
    log_light(rec, world, s)


def log_walls(rec: rr.RecordingStream, world: WorldSettings, s: RecordingSettings) -> None:
    """Floor, the four walls (outside the arena) and the station block on the east wall."""
    size = world.arena_size / CM_PER_M
    half, t, h = size / 2, s.wall_thickness_m, s.wall_height_m
    _floor(rec, (0.0, 0.0), (size, size))
    centres = [
        [half, -t / 2, h / 2],
        [half, size + t / 2, h / 2],
        [-t / 2, half, h / 2],
        [size + t / 2, half, h / 2],
    ]
    halves = [[half + t, t / 2, h / 2]] * 2 + [[t / 2, half + t, h / 2]] * 2
    rec.log(
        "world/arena/walls",
        rr.Boxes3D(centers=centres, half_sizes=halves, colors=[(120, 90, 60)], fill_mode="solid"),
        static=True,
    )
    sy, sw = world.station_y / CM_PER_M, world.station_width / CM_PER_M
    d, sh = s.station_depth_m, s.station_height_m
    rec.log(
        "world/arena/station",
        rr.Boxes3D(
            centers=[[size - d / 2, sy, sh / 2]],
            half_sizes=[[d / 2, sw / 2, sh / 2]],
            colors=[(90, 90, 200)],
            fill_mode="solid",
        ),
        static=True,
    )


def _floor(rec: rr.RecordingStream, lo: Sequence[float], hi: Sequence[float]) -> None:
    cx, cy = (lo[0] + hi[0]) / 2, (lo[1] + hi[1]) / 2
    hx, hy = (hi[0] - lo[0]) / 2, (hi[1] - lo[1]) / 2
    rec.log(
        "world/arena/floor",
        rr.Boxes3D(
            centers=[[cx, cy, -0.005]],
            half_sizes=[[hx, hy, 0.005]],
            colors=[FLOOR_COLOR],
            fill_mode="solid",
        ),
        static=True,
    )


def log_grid(rec: rr.RecordingStream, world: WorldSettings, s: RecordingSettings) -> None:
    """The squares, their contact zones, the inner 8 × 8 and the kill-zone edge."""
    n, q, hw = world.grid_n, world.square_size, world.contact_half_width
    z_cm = s.plane_z_m * CM_PER_M
    squares, zones = [], []
    for j, i in itertools.product(range(n), range(n)):
        x0, y0 = i * q, j * q
        cx, cy = x0 + q / 2, y0 + q / 2
        squares.append(rect_strip(x0, y0, x0 + q, y0 + q, z_cm) / CM_PER_M)
        zones.append(rect_strip(cx - hw, cy - hw, cx + hw, cy + hw, z_cm) / CM_PER_M)

    def log(path: str, strips: rr.LineStrips3D) -> None:
        rec.log(path, strips, static=True)

    log("world/arena/squares", rr.LineStrips3D(squares, radii=0.003, colors=[(90, 90, 90)]))
    log("world/arena/contact_zones", rr.LineStrips3D(zones, radii=0.0015, colors=[(160,) * 3]))
    lo, hi, k, far = q, (n - 1) * q, world.kill_margin, world.arena_size - world.kill_margin
    for path, strip, color in (
        ("inner", rect_strip(lo, lo, hi, hi, 2 * z_cm), (40, 160, 40)),
        ("kill_zone", rect_strip(k, k, far, far, 2 * z_cm), (220, 40, 40)),
    ):
        log(f"world/arena/{path}", rr.LineStrips3D([strip / CM_PER_M], radii=0.006, colors=[color]))


def log_light(rec: rr.RecordingStream, world: WorldSettings, s: RecordingSettings) -> None:
    """The light sources, the edges of each lit cone and the dark area (filled)."""
    lights = np.array([[*arena_to_m(x, y), 0.1] for x, y in world.lights])
    rec.log("world/arena/lights", rr.Points3D(lights, radii=0.03, colors=[(255, 230, 0)]),
            static=True)  # fmt: skip
    log_labels(rec, world)
    z = 3 * s.plane_z_m
    edges = []
    for lx, ly in world.lights:
        for sgn in (-1.0, 1.0):
            heading = world.light_axis_deg + sgn * world.light_half_angle_deg
            hx, hy = _ray_to_wall(lx, ly, heading, world.arena_size)
            edges.append([[*arena_to_m(lx, ly), z], [*arena_to_m(hx, hy), z]])
    rec.log(
        "world/arena/cones",
        rr.LineStrips3D(edges, radii=0.004, colors=[(240, 200, 0)]),
        static=True,
    )
    verts: list[list[float]] = []
    tris: list[list[int]] = []
    for poly in dark_polygons(world):
        base = len(verts)
        verts += [[*arena_to_m(px, py), 2 * s.plane_z_m] for px, py in poly]
        tris += [[base, base + m, base + m + 1] for m in range(1, len(poly) - 1)]
    if tris:
        rec.log(
            "world/arena/dark",
            rr.Mesh3D(
                vertex_positions=verts,
                triangle_indices=tris,
                vertex_colors=[(60, 60, 80)] * len(verts),
            ),
            static=True,
        )


def log_labels(rec: rr.RecordingStream, world: WorldSettings) -> None:
    """Names of the lights and the station beyond the east wall, each light's moved
    ``LABEL_SPREAD_M`` further from the station and higher than the station's, so that they
    cover neither each other nor a robot at the dock."""
    x = world.arena_size / CM_PER_M + LABEL_OUTSIDE_M
    sy = world.station_y / CM_PER_M
    pos, labels, colors = [[x, sy, 0.25]], ["station"], [(90, 90, 200)]
    for k, (lx, ly) in enumerate(world.lights):
        y = arena_to_m(lx, ly)[1]
        pos.append([x, y + math.copysign(LABEL_SPREAD_M, y - sy), 0.35])
        labels.append(f"light {k}")
        colors.append((255, 230, 0))
    rec.log(
        "world/arena/labels",
        rr.Points3D(pos, radii=0.01, colors=colors, labels=labels, show_labels=True),
        static=True,
    )


def log_calibration_floor(
    rec: rr.RecordingStream,
    starts_cm: Sequence[tuple[float, float]],
    labels: Sequence[str],
    *,
    margin_m: float = 2.5,
) -> None:
    """A floor under the calibration walks, 1 m grid lines on it and each walk's start point,
    labelled; ``starts_cm`` are (x, y) in cm, the floor reaches ``margin_m`` beyond them."""
    pts = np.array([arena_to_m(x, y) for x, y in starts_cm], dtype=np.float64)
    lo = np.floor(pts.min(axis=0) - margin_m)
    hi = np.ceil(pts.max(axis=0) + margin_m)
    _floor(rec, lo, hi)
    z = 0.001
    lines = [[[x, lo[1], z], [x, hi[1], z]] for x in np.arange(lo[0], hi[0] + 0.5)]
    lines += [[[lo[0], y, z], [hi[0], y, z]] for y in np.arange(lo[1], hi[1] + 0.5)]
    rec.log(
        "world/arena/grid",
        rr.LineStrips3D(lines, radii=0.003, colors=[(150, 140, 120)]),
        static=True,
    )
    rec.log(
        "world/arena/starts",
        rr.Points3D(
            np.c_[pts, np.full(len(pts), 2 * z)],
            radii=0.02,
            colors=[(90, 90, 200)],
            labels=list(labels),
        ),
        static=True,
    )


def _ray_to_wall(sx: float, sy: float, heading_deg: float, size: float) -> tuple[float, float]:
    """Where a ray from (sx, sy) along ``heading_deg`` leaves the arena [0, size]², cm."""
    dx, dy = math.sin(math.radians(heading_deg)), math.cos(math.radians(heading_deg))
    ts = []
    for d, p in ((dx, sx), (dy, sy)):
        if d > 1e-12:
            ts.append((size - p) / d)
        elif d < -1e-12:
            ts.append(-p / d)
    t = min(ts) if ts else 0.0
    return sx + t * dx, sy + t * dy


def _clip(poly: list[tuple[float, float]], a: float, b: float, c: float) -> list:
    """Sutherland–Hodgman: keep the part of convex ``poly`` with a·x + b·y + c ≥ 0."""
    out: list[tuple[float, float]] = []
    n = len(poly)
    for k in range(n):
        p, q = poly[k], poly[(k + 1) % n]
        fp, fq = a * p[0] + b * p[1] + c, a * q[0] + b * q[1] + c
        if fp >= 0:
            out.append(p)
        if (fp >= 0) != (fq >= 0):
            s = fp / (fp - fq)
            out.append((p[0] + s * (q[0] - p[0]), p[1] + s * (q[1] - p[1])))
    return out


def _area(poly: list[tuple[float, float]]) -> float:
    """Unsigned area of a simple polygon (shoelace), cm²."""
    s = 0.0
    for k in range(len(poly)):
        (x0, y0), (x1, y1) = poly[k], poly[(k + 1) % len(poly)]
        s += x0 * y1 - x1 * y0
    return abs(s) / 2


def dark_polygons(world: WorldSettings) -> list[list[tuple[float, float]]]:
    """Polygons (arena cm) covering the dark area: outside every source's lit cone (SPEC §3).

    A cone (apex at its source, opening 2·half-angle < 180°) is the intersection of two
    half-planes, so its outside is the union of the two opposite half-planes, one beyond each
    edge. The dark area is the intersection over sources of those unions: the union, over
    every choice of one edge per source, of the arena clipped by the chosen half-planes.
    """
    size = world.arena_size
    polys = []
    for sides in itertools.product((+1.0, -1.0), repeat=len(world.lights)):
        poly = [(0.0, 0.0), (size, 0.0), (size, size), (0.0, size)]
        for side, (sx, sy) in zip(sides, world.lights, strict=True):
            edge = math.radians(world.light_axis_deg + side * world.light_half_angle_deg)
            ex, ey = math.sin(edge), math.cos(edge)  # edge direction (heading convention)
            # Keep points beyond the edge, away from the axis: −side·cross(edge, p − s) ≥ 0.
            a, b = side * ey, -side * ex
            poly = _clip(poly, a, b, -(a * sx + b * sy))
            if not poly:
                break
        if len(poly) >= 3 and _area(poly) > 1e-9:
            polys.append(poly)
    return polys


__all__ = ["dark_polygons", "log_arena", "log_calibration_floor", "log_labels"]
