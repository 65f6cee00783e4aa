"""The colony arena in MuJoCo, composed around the robot with ``dm_control.mjcf`` (SPEC §3).

World frame: metres, x east, y north, z up, origin at the arena's south-west corner (so arena
unit u sits at u / 100 m). The arena holds a floor, four walls whose inner faces are the arena
edges, the power-station block (``station_width`` wide, protruding ``station_depth_m`` from the
east wall, centred at ``station_y``; low enough for the sensor rays to pass over), and the two
light sources (a MuJoCo ``light`` each, with a non-colliding marker above the wall tops so the
rangefinder rays never see it).

The robot MJCF is attached through an attachment frame that carries the free joint: the
robot's own free joint is removed and the torso's placement moved onto the frame, so that the
frame's free-joint qpos means what the robot's did (keyframes stay valid). The object-sensor
rangefinder fans (``servo_mj.world.sensors``) are added to the torso before attaching.

A colony arena (``build_arena(..., colony=ColonySettings(...))``, SPEC §7) holds R robots,
attached as ``servobot0/`` … ``servobot{R-1}/``, each with a bumper (a sphere that collides
with the other robots' bumpers only) and a shell (a cylinder that the other robots'
rangefinders see), both of the table world's disc radius; see ``ArenaSettings``. A lone
robot's arena (``colony`` None) has neither and is what it always was.

Physics options (timestep, integrator, friction cone, solver, ...) and the floor's contact
parameters are copied from the calibration scene (``models/servobot/scene.xml``) after
compiling, so that the gaits walk in the arena as they did when the gait table was measured.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import mujoco
import numpy as np
from dm_control import mjcf

from evolve.settings import ColonySettings, WorldSettings
from servo_mj.world import sensors as _sensors
from servo_mj.world.sensors import CM_PER_M, ObjectSensorIndex

BUMPER = "bumper"
"""Name (unprefixed) of a colony robot's bumper geom (collisions)."""
SHELL = "bumper_shell"
"""Name (unprefixed) of a colony robot's shell geom (what other robots' rays see)."""


@dataclass(frozen=True)
class ArenaSettings:
    """Geometry of the MuJoCo colony and of the physics object sensors [chosen].

    Lengths in metres unless the name says otherwise; horizontal layout (arena size, station
    position and width, light positions, sensor spans and range) comes from ``WorldSettings``.
    """

    wall_height_m: float = 0.30
    """Wall height; well above the rangefinder sites so a slightly tilted ray still meets it."""
    wall_thickness_m: float = 0.05
    """Wall thickness, built outwards from the arena edge."""
    station_depth_m: float = 0.20
    """How far the station block protrudes from the east wall (front face x = 4.80 m)."""
    station_height_m: float = 0.10
    """Height of the station block: above the docking probes (0.072 m) so they meet its
    face, below the rangefinder rays (≈ 0.15 m) so the object sensors see the wall behind it,
    as the table simulation does. A block taller than the rays makes the sensors see it up
    to 20 units before the table sees the wall (SPEC §3 "In MuJoCo", accepted difference)."""
    light_height_m: float = 0.40
    """Height of the light sources and their markers (above the walls and the ray sites)."""
    light_marker_radius_m: float = 0.02
    """Radius of the visual (non-colliding) light markers."""
    floor_margin_m: float = 0.5
    """How far the floor plane extends beyond the arena on each side."""
    rays_per_span: int = 10
    """Rangefinder rays per object-sensor span, both span ends included."""
    sensor_height_m: float = 0.09
    """Height of the rangefinder sites above the torso frame origin (≈ 0.15 m above the
    floor): above the servos and lifted legs (≤ 0.045 m), 5 cm above the station block, and
    a ray must pitch down ~17° to meet the floor within 0.5 m."""
    robot_clearance_cm: float = 26.0
    """A robot centre closer than this to the station block overlaps it (probe reach 23.7 cm,
    plus a margin): such start poses are refused."""
    shell_bottom_m: float = -0.04
    """Colony arenas: bottom of each robot's shell in the torso frame (the torso origin
    stands ≈ 0.06 m above the floor, so ≈ 0.02 m above it). The shell is a massless,
    non-colliding vertical cylinder of radius ``ColonySettings.disc_radius`` (the table
    world's disc) on the torso: what the other robots' rangefinders see of a robot."""
    shell_top_m: float = 0.14
    """Colony arenas: top of the shell in the torso frame (≈ 0.20 m above the floor). The
    rangefinder rays leave 0.09 m above the torso origin; the shell reaches 0.05 m above and
    0.13 m below them, so another robot's ray still meets it 0.5 m away (the object range)
    when either robot pitches 5.7°, or 0.2 m away at 14° (a robot pushing another pitches
    up to ≈ 10°)."""
    bumper_bit: int = 4
    """Colony arenas: ``contype`` and ``conaffinity`` of each robot's bumper — a massless
    sphere of radius ``ColonySettings.disc_radius`` centred on the torso origin — a bit no
    other geom uses (robot geoms 2/1, arena 1/1): bumpers collide with other robots' bumpers
    only, never with their own robot, the arena, or the other robots' legs and probes. Two
    robots therefore touch only bumper to bumper, centres two radii apart, as the table
    world's discs. A sphere at the torso centre pushes through the torso, level: a vertical
    cylinder spanning the rays' height pitched a pushing robot up by 19°, the sphere 10–12°."""
    colours: dict[str, tuple[float, float, float, float]] = field(
        default_factory=lambda: {
            "floor": (0.82, 0.80, 0.75, 1.0),
            "wall": (0.55, 0.45, 0.35, 1.0),
            "station": (0.85, 0.65, 0.10, 1.0),
            "light": (1.0, 1.0, 0.6, 1.0),
        }
    )
    """RGBA of the arena parts (visual only)."""

    def to_dict(self) -> dict[str, Any]:
        return asdict(self)


@dataclass(frozen=True)
class RobotSpec:
    """Where the robot model is and how to find its torso and forward axis."""

    xml: Path
    """Robot MJCF file with its own free joint: the robot alone, or a scene whose worldbody
    holds the robot's torso beside floor and lights (only the torso is attached)."""
    torso_body: str
    """Name of the torso body in the robot MJCF."""
    free_joint: str | None
    """Name of the robot's free joint (removed on attach); None = the torso's first joint."""
    forward_axis: tuple[float, float, float] = (1.0, 0.0, 0.0)
    """The robot's forward axis in the torso frame."""
    scene_xml: Path | None = None
    """The calibration scene: the arena copies its physics options (timestep, integrator,
    friction cone, solver ...) and its floor's contact parameters, so that gaits behave in the
    arena as they did when the gait table was measured. None = MuJoCo defaults."""


def default_robot(model: str | Path | None = None) -> RobotSpec:
    """The ServoBot of ``servo_mj.robot.constants``; ``model``: a complete scene file of a
    ServoBot (a ``servobot variant``), which is both the robot and the calibration scene."""
    from servo_mj.robot import constants as c
    from servo_mj.robot.model import scene_path

    # constants: "Robot body frame: +x forward, +y left, +z up".
    return RobotSpec(
        xml=Path(c.ROBOT_XML) if model is None else scene_path(model),
        torso_body=c.TORSO,
        free_joint=c.FREE_JOINT,
        scene_xml=scene_path(model),
    )


def station_distance_cm(x: float, y: float, world: WorldSettings, arena: ArenaSettings) -> float:
    """Distance (cm) from (x, y) to the station block's footprint (0 inside it)."""
    x0 = world.arena_size - arena.station_depth_m * CM_PER_M
    y0 = world.station_y - world.station_width / 2
    y1 = world.station_y + world.station_width / 2
    dx = max(x0 - x, 0.0, x - world.arena_size)
    dy = max(y0 - y, 0.0, y - y1)
    return float(np.hypot(dx, dy))


def overlaps_station(x: float, y: float, world: WorldSettings, arena: ArenaSettings) -> bool:
    """Whether a robot centred at (x, y) would overlap the station block (any heading)."""
    return station_distance_cm(x, y, world, arena) < arena.robot_clearance_cm


def _m(units: float) -> float:
    return float(units) / CM_PER_M


def add_arena(root: mjcf.RootElement, world: WorldSettings, arena: ArenaSettings) -> None:
    """Add floor, walls, station block and lights to ``root``'s worldbody."""
    size = _m(world.arena_size)
    half = size / 2.0
    t, h = arena.wall_thickness_m, arena.wall_height_m
    col = arena.colours
    wb = root.worldbody
    root.asset.add(
        "texture", name="grid", type="2d", builtin="checker", width=512, height=512,
        rgb1=col["floor"][:3], rgb2=[c * 0.92 for c in col["floor"][:3]],
    )  # fmt: skip
    cells = world.grid_n
    root.asset.add("material", name="grid", texture="grid", texrepeat=[cells / 2, cells / 2])
    wb.add(
        "geom", name="floor", type="plane", material="grid",
        pos=[half, half, 0.0], size=[half + arena.floor_margin_m] * 2 + [0.05],
    )  # fmt: skip
    walls = {
        "wall_west": ([-t / 2, half, h / 2], [t / 2, half + t, h / 2]),
        "wall_east": ([size + t / 2, half, h / 2], [t / 2, half + t, h / 2]),
        "wall_south": ([half, -t / 2, h / 2], [half + t, t / 2, h / 2]),
        "wall_north": ([half, size + t / 2, h / 2], [half + t, t / 2, h / 2]),
    }
    for name, (pos, hs) in walls.items():
        wb.add("geom", name=name, type="box", pos=pos, size=hs, rgba=col["wall"])
    d, sh = arena.station_depth_m, arena.station_height_m
    wb.add(
        "geom", name="station", type="box", rgba=col["station"],
        pos=[size - d / 2, _m(world.station_y), sh / 2],
        size=[d / 2, _m(world.station_width) / 2, sh / 2],
    )  # fmt: skip
    axis = np.deg2rad(world.light_axis_deg)
    direction = [np.sin(axis), np.cos(axis), -0.3]
    for i, (lx, ly) in enumerate(world.lights):
        pos = [_m(lx), _m(ly), arena.light_height_m]
        wb.add(
            "light", name=f"light_{i}", pos=pos, dir=direction, directional="false",
            cutoff=world.light_half_angle_deg, diffuse=[0.4, 0.4, 0.3],
        )  # fmt: skip
        wb.add("site", name=f"light_{i}", pos=pos, size=[arena.light_marker_radius_m])
        wb.add(
            "geom", name=f"light_marker_{i}", type="sphere", pos=pos,
            size=[arena.light_marker_radius_m], rgba=col["light"], contype=0, conaffinity=0,
        )  # fmt: skip


def _detach_free_joint(robot: mjcf.RootElement, spec: RobotSpec) -> mjcf.Element:
    """Remove the robot's free joint and anything beside the torso in the file's worldbody (a
    scene file's floor and lights); return the torso."""
    torso = robot.find("body", spec.torso_body)
    if torso is None:
        raise ValueError(f"{spec.xml}: no body named {spec.torso_body!r}")
    for element in list(robot.worldbody.all_children()):
        if element is not torso:
            element.remove()
    joints = [j for j in robot.find_all("joint") if j.tag == "freejoint" or j.type == "free"]
    if spec.free_joint is not None:
        joints = [j for j in joints if j.name == spec.free_joint] or joints
    for j in joints:
        if j.parent is not torso:
            raise ValueError(f"{spec.xml}: free joint {j.name!r} is not on {spec.torso_body!r}")
        j.remove()
    return torso


def colony_robot_names(robots: int) -> tuple[str, ...]:
    """MJCF model names of a colony's robots: ``servobot0`` … (their prefixes add ``/``)."""
    from servo_mj.robot.constants import ROBOT_MODEL_NAME

    return tuple(f"{ROBOT_MODEL_NAME}{i}" for i in range(robots))


def _add_bumper(torso: mjcf.Element, radius_m: float, arena: ArenaSettings, seen: bool) -> None:
    """A colony robot's bumper (a sphere that collides with other robots' bumpers only) and,
    when the other robots' rangefinders are to see it (``seen``), its shell (a cylinder they
    see), both massless, of radius ``radius_m`` (``ArenaSettings.bumper_bit``,
    ``shell_bottom_m``, ``shell_top_m``). An unseen robot's bumper is transparent: MuJoCo's
    rangefinders skip geoms of alpha 0, and its rays pass above the robots' bodies."""
    lo, hi = arena.shell_bottom_m, arena.shell_top_m
    torso.add(
        "geom", name=BUMPER, type="sphere", size=[radius_m], contype=arena.bumper_bit,
        conaffinity=arena.bumper_bit, condim=1, density=0, group=3,
        rgba=[0.3, 0.6, 1.0, 0.1 if seen else 0.0],
    )  # fmt: skip
    if not seen:
        return
    torso.add(
        "geom", name=SHELL, type="cylinder", size=[radius_m, (hi - lo) / 2],
        pos=[0.0, 0.0, (hi + lo) / 2], contype=0, conaffinity=0, density=0, group=3,
        rgba=[0.3, 0.6, 1.0, 0.15],
    )  # fmt: skip


def _attach_robot(
    root: mjcf.RootElement,
    spec: RobotSpec,
    world: WorldSettings,
    arena: ArenaSettings,
    *,
    name: str | None = None,
    bumper_m: float | None = None,
    seen: bool = True,
) -> None:
    """Attach one robot (renamed ``name`` when given; with a bumper of radius ``bumper_m``,
    and a shell when ``seen``)."""
    bot = mjcf.from_path(str(spec.xml))
    if name is not None:
        bot.model = name
    torso = _detach_free_joint(bot, spec)
    _sensors.add_object_sensors(
        bot, spec.torso_body, world=world, n_rays=arena.rays_per_span,
        height_m=arena.sensor_height_m, forward=spec.forward_axis,
    )  # fmt: skip
    if bumper_m is not None:
        _add_bumper(torso, bumper_m, arena, seen)
    # Move the torso's placement onto the frame, so the frame's free joint is the torso's.
    pos = np.zeros(3) if torso.pos is None else np.asarray(torso.pos, dtype=float)
    quat = None if torso.quat is None else np.asarray(torso.quat, dtype=float)
    torso.pos = None
    torso.quat = None
    frame = root.attach(bot)
    frame.pos = pos
    if quat is not None:
        frame.quat = quat
    frame.add("freejoint")


def build_arena(
    world: WorldSettings | None = None,
    arena: ArenaSettings | None = None,
    robot: RobotSpec | None = None,
    colony: ColonySettings | None = None,
) -> mjcf.RootElement:
    """Compose the colony arena and the robot (free joint on the attachment frame).

    ``colony`` None: one robot, as the model file names it (prefix ``servobot/``), no bumper.
    Else ``colony.robots`` robots named by ``colony_robot_names``, each with a bumper of
    radius ``colony.disc_radius`` and, when ``colony.robots_seen``, a shell the other robots'
    rangefinders see.
    """
    world = world or WorldSettings()
    arena = arena or ArenaSettings()
    spec = robot or default_robot()
    root = mjcf.RootElement(model="colony")
    add_arena(root, world, arena)
    if colony is None:
        _attach_robot(root, spec, world, arena)
    else:
        radius = colony.disc_radius / CM_PER_M
        for name in colony_robot_names(colony.robots):
            _attach_robot(root, spec, world, arena, name=name, bumper_m=radius,
                          seen=colony.robots_seen)  # fmt: skip
    return root


@dataclass
class ArenaModel:
    """A compiled colony: MuJoCo model and data, each robot's name prefix and sensor indices,
    and (colony arenas) each robot's bumper geom."""

    model: mujoco.MjModel
    data: mujoco.MjData
    prefixes: tuple[str, ...]
    object_indices: tuple[ObjectSensorIndex, ...]
    bumpers: np.ndarray
    """(R,) geom id of each robot's bumper; empty for a lone robot's arena."""
    world: WorldSettings
    arena: ArenaSettings
    xml: str

    @property
    def prefix(self) -> str:
        """Robot 0's name prefix (the lone robot's)."""
        return self.prefixes[0]

    @property
    def object_index(self) -> ObjectSensorIndex:
        """Robot 0's rangefinder indices (the lone robot's)."""
        return self.object_indices[0]


def compile_arena(
    world: WorldSettings | None = None,
    arena: ArenaSettings | None = None,
    robot: RobotSpec | None = None,
    colony: ColonySettings | None = None,
) -> ArenaModel:
    """Build and compile the arena (``build_arena``); returns model, data, prefixes."""
    world = world or WorldSettings()
    arena = arena or ArenaSettings()
    spec = robot or default_robot()
    root = build_arena(world, arena, spec, colony)
    xml = root.to_xml_string()
    model = mujoco.MjModel.from_xml_string(xml, root.get_assets())
    if spec.scene_xml is not None:
        match_scene(model, mujoco.MjModel.from_xml_path(str(spec.scene_xml)))
    _sensors.sensors_on_demand(model)
    data = mujoco.MjData(model)
    if colony is None:
        prefixes: tuple[str, ...] = (_robot_prefix(root),)
        bumpers = np.zeros(0, dtype=np.int64)
    else:
        prefixes = tuple(name + "/" for name in colony_robot_names(colony.robots))
        bumpers = np.array([model.geom(p + BUMPER).id for p in prefixes], dtype=np.int64)
    mujoco.mj_forward(model, data)
    n = arena.rays_per_span
    index = tuple(ObjectSensorIndex.from_model(model, p, n) for p in prefixes)
    return ArenaModel(model, data, prefixes, index, bumpers, world, arena, xml)


SCENE_FLOOR = "floor"
"""Name of the floor geom in the calibration scene (and in the arena)."""
ARENA_SURFACES = ("floor", "wall_west", "wall_east", "wall_south", "wall_north", "station")
"""Arena geoms that take the calibration floor's contact parameters."""
_CONTACT_FIELDS = ("friction", "solref", "solimp", "solmix", "condim", "priority", "margin", "gap")


def match_scene(model: mujoco.MjModel, scene: mujoco.MjModel) -> None:
    """Copy the scene's physics options and its floor's contact parameters into ``model``."""
    for name in dir(scene.opt):
        if not name.startswith("_"):
            setattr(model.opt, name, getattr(scene.opt, name))
    src = mujoco.mj_name2id(scene, mujoco.mjtObj.mjOBJ_GEOM, SCENE_FLOOR)
    if src < 0:
        raise ValueError(f"calibration scene has no geom named {SCENE_FLOOR!r}")
    for surface in ARENA_SURFACES:
        dst = model.geom(surface).id
        for f in _CONTACT_FIELDS:
            getattr(model, "geom_" + f)[dst] = getattr(scene, "geom_" + f)[src]


def _robot_prefix(root: mjcf.RootElement) -> str:
    """The name prefix that ``attach`` gave the robot (e.g. ``"servobot/"``)."""
    for b in root.worldbody.all_children():
        if b.tag == "body":
            return b.full_identifier
    raise ValueError("composed arena holds no robot body")


def warnings_raised(data: mujoco.MjData) -> dict[str, int]:
    """MuJoCo warnings counted so far, by name (empty = none)."""
    out = {}
    for name, w in mujoco.mjtWarning.__members__.items():
        if name == "mjNWARNING":
            continue
        n = int(data.warning[int(w)].number)
        if n:
            out[name] = n
    return out


__all__ = [
    "BUMPER",
    "SHELL",
    "ArenaModel",
    "ArenaSettings",
    "RobotSpec",
    "add_arena",
    "build_arena",
    "colony_robot_names",
    "compile_arena",
    "default_robot",
    "match_scene",
    "overlaps_station",
    "station_distance_cm",
    "warnings_raised",
]
