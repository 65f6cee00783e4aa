"""Rerun recordings (``.rrd``) of calibration walks, table runs and physics runs.

One :class:`Recording` writes one ``.rrd`` file that a user opens with ``rerun FILE.rrd``. It
holds a static arena, the robot's bodies moving every frame, the tracks of one or more
*worlds* ("physics", "table") drawn over the same arena, squares turning coloured as they are
first reached, time series of power, the five sensors, mode and squares, and a text log of
the instructions executed, plus a blueprint that lays these out.

Frames and units: everything 3D is in metres in the MuJoCo world frame (x east, y north, z up;
100 arena units = 1 m). Arena poses (x, y cm; heading deg, 0 = north, clockwise) are converted
here. Timelines: ``step`` (sequence: interpreter step), ``sim_time`` (duration, seconds of
simulated time) and ``cycle`` (sequence: calibration cycle).

Speed: nothing is sent per call. Robot states, feet, events and calibration cycles are
buffered as arrays and sent column-wise with ``send_columns`` when a buffer is full and on
:meth:`Recording.close`. Static geometry is logged once with ``static=True``.

Entity layout::

    world/arena/{floor,walls,station,lights,squares,contact_zones,inner,kill_zone,cones,dark}
    world/<entity>/<body>[/geoms/<k>]     robot bodies (Transform3D per frame) and their shapes
    world/feet                            foot positions per frame (trace via visible range)
    world/track/<world_name>              one segment per step (trace via visible range)
    world/squares/<world_name>            squares reached so far
    plots/power/<world_name>              volts
    plots/sensors/<world_name>/<sensor>   0/1 per sensor
    plots/mode/<world_name>               0 coverage, 1 navigation, 2 charging
    plots/squares/<world_name>            squares reached so far
    plots/pose/<world_name>/{x_cm,y_cm,heading_deg}   pose after each step
    plots/calibration/{F,T,dH}/gait_<g>   per measured cycle
    log/<world_name>, log/calibration     text log
"""

from __future__ import annotations

import itertools
import math
import os
import uuid
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import rerun as rr
import rerun.blueprint as rrb

from evolve import geometry
from evolve.codec import LIGHT_LEFT, LIGHT_RIGHT, LOW_POWER, OBJECT_LEFT, OBJECT_RIGHT
from evolve.settings import WorldSettings
from servo_mj.robot.constants import CM_PER_M

SENSORS: tuple[tuple[str, int], ...] = (
    ("object_right", OBJECT_RIGHT),
    ("object_left", OBJECT_LEFT),
    ("low_power", LOW_POWER),
    ("light_right", LIGHT_RIGHT),
    ("light_left", LIGHT_LEFT),
)
"""The five sensors: (series name, bit in a StepEvent's ``sensors`` mask)."""

MODES: dict[str, int] = {"coverage": 0, "navigation": 1, "charging": 2, "charge": 2}
"""Numeric value plotted for each controller mode name."""

# mujoco.mjtGeom values, kept here so that table-only recordings need not import MuJoCo.
_GEOM_SPHERE, _GEOM_CAPSULE, _GEOM_ELLIPSOID, _GEOM_CYLINDER, _GEOM_BOX, _GEOM_MESH = (
    2,
    3,
    4,
    5,
    6,
    7,
)


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
    """Buffered frames per entity before they are sent (bounds memory on long runs)."""
    robot_geom_groups: tuple[int, ...] = (0, 1, 2)
    """MuJoCo geom groups drawn for the robot (visual groups); others only if a body has none."""


WORLD_COLORS: dict[str, tuple[int, int, int]] = {
    "physics": (230, 120, 30),
    "table": (40, 120, 230),
}
"""Track/squares colour per world name; other names get grey."""
_OTHER_COLOR = (150, 150, 150)


def arena_to_m(x_cm: float, y_cm: float) -> tuple[float, float]:
    """Arena (x, y) in cm → MuJoCo world (x, y) in metres."""
    return x_cm / CM_PER_M, y_cm / CM_PER_M


def heading_to_yaw_rad(heading_deg: float) -> float:
    """SPEC heading (deg, 0 = north, clockwise) → yaw about +z (rad, 0 = +x, anticlockwise)."""
    return math.radians(90.0 - heading_deg)


def square_centre(index: int, world: WorldSettings) -> tuple[float, float]:
    """Centre (x, y cm) of square ``index = i + grid_n * j`` (i column along x, j row along y)."""
    i, j = index % world.grid_n, index // world.grid_n
    return (world.square_size * (i + 0.5), world.square_size * (j + 0.5))


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


def dark_polygons(world: WorldSettings) -> list[list[tuple[float, float]]]:
    """Polygons (arena cm) covering the dark area: outside every source's lit cone (SPEC §3).

    A cone (apex at its source, opening 2·half-angle < 180°) is the intersection of two
    half-planes, so its outside is the union of the two opposite half-planes, one beyond each
    edge. The dark area is the intersection over sources of those unions: the union, over
    every choice of one edge per source, of the arena clipped by the chosen half-planes.
    """
    size = world.arena_size
    polys = []
    n = len(world.lights)
    for sides in itertools.product((+1.0, -1.0), repeat=n):
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


def _area(poly: list[tuple[float, float]]) -> float:
    """Unsigned area of a simple polygon (shoelace), cm²."""
    s = 0.0
    for k in range(len(poly)):
        (x0, y0), (x1, y1) = poly[k], poly[(k + 1) % len(poly)]
        s += x0 * y1 - x1 * y0
    return abs(s) / 2


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


def _rect_strip(x0: float, y0: float, x1: float, y1: float, z: float) -> np.ndarray:
    return np.array([[x0, y0, z], [x1, y0, z], [x1, y1, z], [x0, y1, z], [x0, y0, z]])


def _mj_quat_to_xyzw(q: np.ndarray) -> np.ndarray:
    """MuJoCo quaternions (w, x, y, z) → rerun (x, y, z, w); works on (..., 4)."""
    return np.concatenate([q[..., 1:4], q[..., 0:1]], axis=-1)


def _color(world_name: str) -> tuple[int, int, int]:
    return WORLD_COLORS.get(world_name, _OTHER_COLOR)


def _entity_part(name: str) -> str:
    return rr.escape_entity_path_part(name) if name else "unnamed"


class _Series:
    """Column buffer of one entity: times per timeline plus named per-row payloads."""

    def __init__(self) -> None:
        self.times: dict[str, list[float | int]] = {}
        self.rows: dict[str, list[Any]] = {}
        self.n = 0

    def add(self, times: dict[str, float | int], **payload: Any) -> None:
        if not self.times:
            self.times = {k: [] for k in times}
            self.rows = {k: [] for k in payload}
        for k, v in times.items():
            self.times[k].append(v)
        for k, v in payload.items():
            self.rows[k].append(v)
        self.n += 1

    def time_columns(self) -> list[rr.TimeColumn]:
        cols = []
        for name, vals in self.times.items():
            if name == "sim_time":
                cols.append(rr.TimeColumn(name, duration=np.asarray(vals, dtype=np.float64)))
            else:
                cols.append(rr.TimeColumn(name, sequence=np.asarray(vals, dtype=np.int64)))
        return cols

    def clear(self) -> None:
        self.times, self.rows, self.n = {}, {}, 0


class Recording:
    """One ``.rrd`` file; use as a context manager. ``close()`` sends buffers and saves atomically.

    The file appears at ``path`` only when the recording closes (written to a temporary file
    beside it, then renamed), so an interrupted run never leaves a half-written ``.rrd``.
    """

    def __init__(
        self,
        path: str | Path,
        *,
        app_id: str = "servobot",
        blueprint: bool = True,
        settings: RecordingSettings | None = None,
    ) -> None:
        self.path = Path(path)
        self.settings = settings or RecordingSettings()
        self._blueprint = blueprint
        self.path.parent.mkdir(parents=True, exist_ok=True)
        # A unique hidden name beside the target; rerun creates it with the usual file mode.
        self._tmp = self.path.parent / f".{self.path.stem}.{uuid.uuid4().hex}.rrd"
        self.rec = rr.RecordingStream(app_id, recording_id=uuid.uuid4())
        self.rec.save(str(self._tmp))
        self._closed = False
        self._world: WorldSettings | None = None
        self._bodies: dict[str, tuple[list[int], list[str]]] = {}  # entity → (body ids, names)
        self._states: dict[str, _Series] = {}
        self._feet = _Series()
        self._events: dict[str, dict[str, Any]] = {}
        self._calib: dict[int, _Series] = {}
        self._calib_log = _Series()
        self._static_worlds: set[str] = set()
        self.rec.log("world", rr.ViewCoordinates.RIGHT_HAND_Z_UP, static=True)

    # ----------------------------------------------------------------------------- context
    def __enter__(self) -> Recording:
        return self

    def __exit__(self, exc_type: Any, exc: Any, tb: Any) -> None:
        self.close(save=exc_type is None)

    # ----------------------------------------------------------------------------- arena
    def log_arena(self, world: WorldSettings) -> None:
        """Static arena: floor, walls, station, lights, squares and contact zones, inner squares,
        kill zone, lit-cone edges and the dark area, all in metres on z ≈ 0."""
        self._world = world
        s, log = self.settings, self.rec.log
        size = world.arena_size / CM_PER_M
        z = s.plane_z_m
        half = size / 2
        log(
            "world/arena/floor",
            rr.Boxes3D(
                centers=[[half, half, -0.005]],
                half_sizes=[[half, half, 0.005]],
                colors=[(225, 215, 190)],
                fill_mode="solid",
            ),
            static=True,
        )
        t, h = s.wall_thickness_m, s.wall_height_m
        walls_c = [
            [half, -t / 2, h / 2],
            [half, size + t / 2, h / 2],
            [-t / 2, half, h / 2],
            [size + t / 2, half, h / 2],
        ]
        walls_h = [[half + t, t / 2, h / 2]] * 2 + [[t / 2, half + t, h / 2]] * 2
        log(
            "world/arena/walls",
            rr.Boxes3D(
                centers=walls_c, half_sizes=walls_h, colors=[(120, 90, 60)], fill_mode="solid"
            ),
            static=True,
        )
        sy = world.station_y / CM_PER_M
        sw = world.station_width / CM_PER_M
        d, sh = s.station_depth_m, s.station_height_m
        log(
            "world/arena/station",
            rr.Boxes3D(
                centers=[[size - d / 2, sy, sh / 2]],
                half_sizes=[[d / 2, sw / 2, sh / 2]],
                colors=[(90, 90, 200)],
                fill_mode="solid",
                labels=["station"],
            ),
            static=True,
        )
        lights = np.array([[*arena_to_m(x, y), 0.1] for x, y in world.lights])
        log(
            "world/arena/lights",
            rr.Points3D(
                lights,
                radii=0.03,
                colors=[(255, 230, 0)],
                labels=[f"light {k}" for k in range(len(lights))],
            ),
            static=True,
        )
        # Squares, their contact zones, the inner 8 × 8 and the kill zone.
        n, q, hw = world.grid_n, world.square_size, world.contact_half_width
        sq, cz, inner_centres = [], [], []
        for j in range(n):
            for i in range(n):
                x0, y0 = i * q, j * q
                sq.append(_rect_strip(x0, y0, x0 + q, y0 + q, z * CM_PER_M) / CM_PER_M)
                cx, cy = x0 + q / 2, y0 + q / 2
                cz.append(_rect_strip(cx - hw, cy - hw, cx + hw, cy + hw, z * CM_PER_M) / CM_PER_M)
                if 1 <= i <= n - 2 and 1 <= j <= n - 2:
                    inner_centres.append((cx, cy))
        log(
            "world/arena/squares",
            rr.LineStrips3D(sq, radii=0.003, colors=[(90, 90, 90)]),
            static=True,
        )
        log(
            "world/arena/contact_zones",
            rr.LineStrips3D(cz, radii=0.0015, colors=[(160, 160, 160)]),
            static=True,
        )
        lo, hi = q, (n - 1) * q
        log(
            "world/arena/inner",
            rr.LineStrips3D(
                [_rect_strip(lo, lo, hi, hi, 2 * z * CM_PER_M) / CM_PER_M],
                radii=0.006,
                colors=[(40, 160, 40)],
                labels=["inner 64"],
            ),
            static=True,
        )
        k = world.kill_margin
        size_cm = world.arena_size
        log(
            "world/arena/kill_zone",
            rr.LineStrips3D(
                [_rect_strip(k, k, size_cm - k, size_cm - k, 2 * z * CM_PER_M) / CM_PER_M],
                radii=0.006,
                colors=[(220, 40, 40)],
                labels=["kill zone edge"],
            ),
            static=True,
        )
        # Lit cones (edges from each source) and the dark area (filled).
        edges = []
        for lx, ly in world.lights:
            for sgn in (-1.0, 1.0):
                hx, hy = _ray_to_wall(
                    lx, ly, world.light_axis_deg + sgn * world.light_half_angle_deg, size_cm
                )
                edges.append(
                    np.array([[lx, ly, 3 * z * CM_PER_M], [hx, hy, 3 * z * CM_PER_M]]) / CM_PER_M
                )
        log(
            "world/arena/cones",
            rr.LineStrips3D(edges, radii=0.004, colors=[(240, 200, 0)]),
            static=True,
        )
        verts, tris = [], []
        for poly in dark_polygons(world):
            base = len(verts)
            verts += [[px / CM_PER_M, py / CM_PER_M, 2 * z] for px, py in poly]
            tris += [[base, base + m, base + m + 1] for m in range(1, len(poly) - 1)]
        if tris:
            log(
                "world/arena/dark",
                rr.Mesh3D(
                    vertex_positions=verts,
                    triangle_indices=tris,
                    vertex_colors=[(60, 60, 80)] * len(verts),
                ),
                static=True,
            )

    # ----------------------------------------------------------------------------- robot
    def _body_ids(self, model: Any, prefix: str) -> tuple[list[int], list[str]]:
        import mujoco

        ids, names = [], []
        for b in range(1, model.nbody):
            name = mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_BODY, b) or f"body{b}"
            if name.startswith(prefix):
                ids.append(b)
                # The body named exactly ``prefix`` is an attachment frame (dm_control.mjcf).
                names.append(_entity_part(name[len(prefix) :] or "attachment_frame"))
        return ids, names

    def log_robot_model(self, model: Any, *, prefix: str = "", entity: str = "robot") -> None:
        """Static shapes of every body whose name starts with ``prefix`` (boxes, capsules,
        cylinders, spheres, ellipsoids; meshes as their bounding box), in body frames, under
        ``world/<entity>/<body>/geoms/<k>``. Planes are skipped."""
        ids, names = self._body_ids(model, prefix)
        self._bodies[entity] = (ids, names)
        groups = set(self.settings.robot_geom_groups)
        for b, name in zip(ids, names, strict=True):
            geoms = [g for g in range(model.ngeom) if model.geom_bodyid[g] == b]
            shown = [g for g in geoms if int(model.geom_group[g]) in groups] or geoms
            for k, g in enumerate(shown):
                arch = _geom_archetype(model, g)
                if arch is None:
                    continue
                path = f"world/{entity}/{name}/geoms/{k}"
                self.rec.log(
                    path,
                    rr.Transform3D(
                        translation=model.geom_pos[g],
                        quaternion=_mj_quat_to_xyzw(model.geom_quat[g]),
                    ),
                    static=True,
                )
                self.rec.log(path, arch, static=True)

    def log_robot_state(
        self, data: Any, *, t_s: float, prefix: str = "", entity: str = "robot"
    ) -> None:
        """Buffer the world poses of the robot's bodies at simulated time ``t_s`` (seconds)."""
        if entity not in self._bodies:
            self._bodies[entity] = self._body_ids(data.model, prefix)
        ids, _ = self._bodies[entity]
        series = self._states.setdefault(entity, _Series())
        series.add({"sim_time": float(t_s)}, pos=data.xpos[ids].copy(), quat=data.xquat[ids].copy())
        if series.n >= self.settings.max_buffer_rows:
            self._flush_states()

    def log_feet(self, t_s: float, feet_xyz_m: np.ndarray) -> None:
        """Buffer the feet positions (n, 3) in metres at ``t_s``; drawn as traces."""
        feet = np.asarray(feet_xyz_m, dtype=np.float64).reshape(-1, 3)
        self._feet.add({"sim_time": float(t_s)}, pos=feet.copy())
        if self._feet.n >= self.settings.max_buffer_rows:
            self._flush_feet()

    def log_calibration_cycle(
        self, gait: int, cycle: int, F: float, T: float, dH: float, t_s: float
    ) -> None:
        """One measured calibration cycle of ``gait``: F, T (cm) and dH (deg) at ``t_s``."""
        times = {"cycle": int(cycle), "sim_time": float(t_s)}
        self._calib.setdefault(int(gait), _Series()).add(times, F=F, T=T, dH=dH)
        self._calib_log.add(
            times, text=f"gait {gait} cycle {cycle}: F={F:.2f} cm T={T:.2f} cm dH={dH:.2f} deg"
        )

    # ----------------------------------------------------------------------------- events
    def log_event(
        self, event: Any, *, world_name: str = "physics", t_s: float | None = None
    ) -> None:
        """Buffer one interpreter ``StepEvent`` of ``world_name`` (see module docstring).

        Reads ``step``, ``pose`` (x, y cm, heading deg), ``power`` (V), ``mode``, ``sensors``
        (bitmask), ``squares`` (count), ``new_square`` (index, or -1/None/False if none; True
        means the square under the pose), and for the text log ``kind``, ``gene``,
        ``instruction``, ``text``, ``gait``.
        """
        w = self._world or WorldSettings()
        buf = self._events.get(world_name)
        if buf is None:
            buf = {"main": _Series(), "reached": [], "sq": _Series(), "last": None}
            self._events[world_name] = buf
        step = int(getattr(event, "step", buf["main"].n))
        times: dict[str, float | int] = {"step": step}
        if t_s is not None:
            times["sim_time"] = float(t_s)
        if buf["main"].times and set(buf["main"].times) != set(times):
            raise ValueError(
                f"world {world_name!r}: give t_s for every event or for none "
                f"(got {sorted(times)} after {sorted(buf['main'].times)})"
            )
        x, y, h = (float(v) for v in getattr(event, "pose", (np.nan, np.nan, 0.0)))
        sensors = int(getattr(event, "sensors", 0) or 0)
        mode = getattr(event, "mode", 0)
        mode_v = float(MODES.get(str(mode).lower(), 0)) if isinstance(mode, str) else float(mode)
        kind = str(getattr(event, "kind", ""))
        text = str(getattr(event, "text", "") or "")
        gene, instr = getattr(event, "gene", ""), getattr(event, "instruction", "")
        gait = getattr(event, "gait", None)
        line = f"step {step:4d} gene {gene} instr {instr} {kind}: {text}"
        if gait is not None and "gait" not in text:
            line += f" (gait {gait})"
        prev = buf["last"] if buf["last"] is not None else (x, y)
        buf["last"] = (x, y)
        buf["main"].add(
            times,
            seg=((prev[0], prev[1]), (x, y)),
            pose=(x, y, h),
            power=float(getattr(event, "power", np.nan)),
            sensors=sensors,
            mode=mode_v,
            squares=float(getattr(event, "squares", 0) or 0),
            text=line,
            level="WARN" if kind in ("end", "dock", "charge") else "INFO",
        )
        new = getattr(event, "new_square", None)
        idx: int | None
        if isinstance(new, bool) or new is None:
            idx = geometry.square_index(x, y, w) if new else None
            idx = None if idx is not None and idx < 0 else idx
        else:
            idx = int(new) if int(new) >= 0 else None
        if idx is not None and idx not in buf["reached"]:
            buf["reached"].append(idx)
            buf["sq"].add(times, reached=list(buf["reached"]))

    # ----------------------------------------------------------------------------- flushing
    def _flush_states(self) -> None:
        for entity, series in self._states.items():
            if not series.n:
                continue
            ids, names = self._bodies[entity]
            pos = np.stack(series.rows["pos"])  # (n, bodies, 3)
            quat = _mj_quat_to_xyzw(np.stack(series.rows["quat"]))
            idx = series.time_columns()
            for k, name in enumerate(names):
                self.rec.send_columns(
                    f"world/{entity}/{name}",
                    indexes=idx,
                    columns=rr.Transform3D.columns(translation=pos[:, k], quaternion=quat[:, k]),
                )
            series.clear()

    def _flush_feet(self) -> None:
        f = self._feet
        if not f.n:
            return
        pts = np.concatenate(f.rows["pos"])
        lens = [len(p) for p in f.rows["pos"]]
        self.rec.send_columns(
            "world/feet",
            indexes=f.time_columns(),
            columns=rr.Points3D.columns(positions=pts).partition(lens),
        )
        f.clear()

    def _flush_calibration(self) -> None:
        for gait, series in sorted(self._calib.items()):
            idx = series.time_columns()
            for comp in ("F", "T", "dH"):
                self.rec.send_columns(
                    f"plots/calibration/{comp}/gait_{gait}",
                    indexes=idx,
                    columns=rr.Scalars.columns(scalars=np.asarray(series.rows[comp], float)),
                )
            series.clear()
        if self._calib_log.n:
            self.rec.send_columns(
                "log/calibration",
                indexes=self._calib_log.time_columns(),
                columns=rr.TextLog.columns(text=self._calib_log.rows["text"]),
            )
            self._calib_log.clear()

    def _flush_events(self) -> None:
        w = self._world or WorldSettings()
        s = self.settings
        for name, buf in self._events.items():
            color = _color(name)
            if name not in self._static_worlds:
                self._static_worlds.add(name)
                self._log_series_styles(name, color)
            main: _Series = buf["main"]
            if main.n:
                idx = main.time_columns()
                seg = np.array(main.rows["seg"], dtype=np.float64) / CM_PER_M  # (n, 2, 2)
                strips = np.concatenate([seg, np.full((main.n, 2, 1), s.track_z_m)], axis=2)
                self.rec.send_columns(
                    f"world/track/{name}",
                    indexes=idx,
                    columns=rr.LineStrips3D.columns(strips=list(strips)),
                )
                pose = np.array(main.rows["pose"], dtype=np.float64)
                plots = {
                    f"plots/pose/{name}/x_cm": pose[:, 0],
                    f"plots/pose/{name}/y_cm": pose[:, 1],
                    f"plots/pose/{name}/heading_deg": pose[:, 2],
                    f"plots/power/{name}": main.rows["power"],
                    f"plots/mode/{name}": main.rows["mode"],
                    f"plots/squares/{name}": main.rows["squares"],
                }
                bits = np.asarray(main.rows["sensors"], dtype=np.int64)
                for sensor, bit in SENSORS:
                    plots[f"plots/sensors/{name}/{sensor}"] = ((bits & bit) != 0).astype(float)
                for path, vals in plots.items():
                    self.rec.send_columns(
                        path,
                        indexes=idx,
                        columns=rr.Scalars.columns(scalars=np.asarray(vals, dtype=np.float64)),
                    )
                self.rec.send_columns(
                    f"log/{name}",
                    indexes=idx,
                    columns=rr.TextLog.columns(text=main.rows["text"], level=main.rows["level"]),
                )
                main.clear()
            sq: _Series = buf["sq"]
            if sq.n:
                cent, lens = [], []
                for reached in sq.rows["reached"]:
                    lens.append(len(reached))
                    for r in reached:
                        cx, cy = square_centre(r, w)
                        cent.append([cx / CM_PER_M, cy / CM_PER_M, s.plane_z_m * 2])
                half = w.square_size / 2 / CM_PER_M * (0.9 if name == "physics" else 0.55)
                self.rec.send_columns(
                    f"world/squares/{name}",
                    indexes=sq.time_columns(),
                    columns=rr.Boxes3D.columns(
                        centers=np.asarray(cent),
                        half_sizes=np.tile([half, half, 0.001], (len(cent), 1)),
                    ).partition(lens),
                )
                sq.clear()

    def _log_series_styles(self, name: str, color: tuple[int, int, int]) -> None:
        log = self.rec.log
        log(
            f"world/squares/{name}",
            rr.Boxes3D.from_fields(colors=[(*color, 110)], fill_mode="solid"),
            static=True,
        )
        log(
            f"world/track/{name}",
            rr.LineStrips3D.from_fields(colors=[color], radii=0.006),
            static=True,
        )
        for path, label in (("power", "power V"), ("mode", "mode"), ("squares", "squares")):
            log(
                f"plots/{path}/{name}",
                rr.SeriesLines(colors=[color], names=[f"{label} {name}"]),
                static=True,
            )
        for k, (sensor, _) in enumerate(SENSORS):
            log(
                f"plots/sensors/{name}/{sensor}",
                rr.SeriesLines(names=[f"{sensor} {name}"], widths=[2.0 if k % 2 else 1.0]),
                static=True,
            )
        for axis in ("x_cm", "y_cm", "heading_deg"):
            log(
                f"plots/pose/{name}/{axis}",
                rr.SeriesLines(colors=[color], names=[f"{axis} {name}"]),
                static=True,
            )

    def flush(self) -> None:
        """Send every buffered frame now (also done by ``close``)."""
        self._flush_states()
        self._flush_feet()
        self._flush_calibration()
        self._flush_events()

    def _make_blueprint(self) -> rrb.Blueprint:
        trails = rrb.VisibleTimeRanges(
            [
                rr.VisibleTimeRange(
                    tl,
                    start=rr.TimeRangeBoundary.infinite(),
                    end=rr.TimeRangeBoundary.cursor_relative(),
                )
                for tl in ("step", "sim_time")
            ]
        )
        # Trails: the 3D view shows everything from the start up to the time cursor, so the
        # track segments and feet draw trails and the reached squares accumulate; transforms
        # (the robot's bodies) are resolved at the cursor, static geometry always shows.
        view3d = rrb.Spatial3DView(origin="world", name="arena", time_ranges=trails)
        panels: list[Any] = []
        if self._events or self._static_worlds:
            panels += [
                rrb.TimeSeriesView(origin="plots/power", name="power (V)"),
                rrb.TimeSeriesView(
                    origin="plots/sensors",
                    name="sensors and mode",
                    contents=["plots/sensors/**", "plots/mode/**"],
                ),
                rrb.TimeSeriesView(origin="plots/squares", name="squares reached"),
                rrb.TimeSeriesView(origin="plots/pose", name="pose (cm, deg)"),
            ]
        if self._has_calibration:
            panels += [
                rrb.TimeSeriesView(origin=f"plots/calibration/{c}", name=f"calibration {c}")
                for c in ("F", "T", "dH")
            ]
        panels.append(rrb.TextLogView(origin="log", name="instructions"))
        return rrb.Blueprint(
            rrb.Horizontal(view3d, rrb.Vertical(*panels), column_shares=[3, 2]),
            collapse_panels=True,
        )

    _has_calibration = False

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
            self._has_calibration = bool(self._calib)
            if save:
                self.flush()
                if self._blueprint:
                    self.rec.send_blueprint(self._make_blueprint())
            self.rec.flush()
            ok = save
        finally:
            self.rec.disconnect()
            if ok:
                os.replace(self._tmp, self.path)
            self._tmp.unlink(missing_ok=True)


def calibration_recorder(rec: Recording, settings: Any) -> dict[str, Any]:
    """Keyword arguments of ``calibration.calibrate.calibrate`` that record its walks in
    ``rec``: the calibration scene's model (``settings.model``), ``on_frame`` (bodies and feet
    every servo frame) and ``on_cycle`` (F, T, dH of each measured cycle). Gait g's walk is
    shifted to start at g × (its duration + 1 s) on ``sim_time``, so the 16 walks follow one
    another."""
    import mujoco

    from servo_mj.robot import constants as C
    from servo_mj.robot.gaits import GaitLibrary
    from servo_mj.robot.model import load_robot
    from servo_mj.robot.settings import PhysicsSettings

    model, _ = load_robot(scene=True, model=settings.model)
    feet = [mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_SITE, n) for n in C.foot_sites()]
    physics = PhysicsSettings()
    cycle_s = len(GaitLibrary().frames(0)) * physics.frame_s
    per_gait_s = physics.settle_s + (settings.settle_cycles + settings.cycles) * cycle_s + 1.0
    rec.log_robot_model(model, prefix="")

    def on_frame(g: int, d: Any) -> None:
        t = g * per_gait_s + d.time
        rec.log_robot_state(d, prefix="", t_s=t)
        rec.log_feet(t, d.site_xpos[feet])

    def on_cycle(g: int, res: Any, bot: Any) -> None:
        f, t, dh = res.ftdh
        k = res.cycle - settings.settle_cycles
        rec.log_calibration_cycle(g, k, f, t, dh, g * per_gait_s + res.t_end_s)

    return {"model": model, "on_frame": on_frame, "on_cycle": on_cycle}


def _geom_archetype(model: Any, g: int) -> Any | None:
    """The rerun shape of MuJoCo geom ``g`` in its own frame, or None for planes/unknowns."""
    gtype, size = int(model.geom_type[g]), np.asarray(model.geom_size[g], dtype=np.float64)
    rgba = np.asarray(model.geom_rgba[g])
    if model.geom_matid[g] >= 0:
        rgba = np.asarray(model.mat_rgba[model.geom_matid[g]])
    color = [tuple(int(round(255 * c)) for c in rgba)]
    if gtype == _GEOM_BOX:
        return rr.Boxes3D(half_sizes=[size], colors=color, fill_mode="solid")
    if gtype == _GEOM_SPHERE:
        return rr.Ellipsoids3D(half_sizes=[[size[0]] * 3], colors=color, fill_mode="solid")
    if gtype == _GEOM_ELLIPSOID:
        return rr.Ellipsoids3D(half_sizes=[size], colors=color, fill_mode="solid")
    if gtype == _GEOM_CAPSULE:  # MuJoCo: centred, half-length size[1]; rerun: from origin up +z
        return rr.Capsules3D(
            lengths=[2 * size[1]],
            radii=[size[0]],
            translations=[[0.0, 0.0, -size[1]]],
            colors=color,
        )
    if gtype == _GEOM_CYLINDER:  # both centred on the origin along z
        return rr.Cylinders3D(
            lengths=[2 * size[1]], radii=[size[0]], colors=color, fill_mode="solid"
        )
    if gtype == _GEOM_MESH:
        aabb = np.asarray(model.geom_aabb[g], dtype=np.float64)
        return rr.Boxes3D(
            centers=[aabb[:3]], half_sizes=[aabb[3:]], colors=color, fill_mode="solid"
        )
    return None


__all__ = [
    "Recording",
    "RecordingSettings",
    "SENSORS",
    "arena_to_m",
    "dark_polygons",
    "heading_to_yaw_rad",
    "square_centre",
]
