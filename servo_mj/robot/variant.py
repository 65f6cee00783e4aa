"""Robot variants as data: a complete MJCF scene of a changed ServoBot, built from the shipped one.

``build_variant(params)`` loads the shipped calibration scene (``models/servobot/scene.xml``,
which includes ``servobot.xml``) with ``dm_control.mjcf``, changes the elements each parameter
names (never the text), and records every parameter as an MJCF ``<custom><numeric>`` named
``variant_<field>``, so the compiled model carries them too (``variant_params``). The result is
one self-contained file: robot, floor, light and the physics options (2 ms, implicitfast,
elliptic cone); ``servobot calibrate/validate/reproduce --model FILE`` take it, and the colony
arena attaches its robot (``servo_mj.world.arena.robot_spec``).

What each parameter changes (units and defaults: ``VariantParams``, ``models/servobot/README.md``):

- ``torso_mass_kg``: the torso's inertial mass; its inertia scales by the same factor (the
  capacitors and electronics lumped into the torso grow in mass, not in size), kept valid
  by construction (``valid_inertia``: the shipped moments sit exactly on A + B = C).
- ``leg_length_m``: the horizontal reach of a foot centre from its thrust axis (7 cm shipped).
  Everything below the lift joint scales uniformly by ``leg_length_m / 0.07``: femur, shank,
  foot position (so the stride per cycle grows and the robot stands taller: the torso's home
  height rises by the extra shank drop), the leg's centre of mass (inertia by the square).
  Hips, foot radius, leg masses and the servo sweep angles stay.
- ``servo_torque_nm``: the twelve servos' torque limit (``forcerange`` ±, stall torque). Joint
  damping stays, so the no-load speed (torque / damping) scales with it.
- ``servo_kp``: the position servos' stiffness ``kp``, N·m/rad.
- ``foot_friction`` / ``floor_friction``: sliding friction of the feet / of the floor (torsional
  and rolling coefficients unchanged). MuJoCo uses the larger of the two geoms' coefficients
  for a contact, so the foot–floor coefficient is ``max(foot, floor)`` (``effective_friction``):
  a slippery floor needs both lowered.

``write_variant`` refuses a variant that cannot place, settle and walk one cycle of every gait
(``check_walks``: ``PhysicsError`` or an unstandable leg), and writes the file atomically.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import mujoco
import numpy as np
from dm_control import mjcf
from lxml import etree

from infra.errors import InputError
from infra.io import atomic_write_text, read_text
from servo_mj.robot import constants as C
from servo_mj.robot.bot import ServoBot
from servo_mj.robot.gaits import N_GAITS

NUMERIC_PREFIX = "variant_"
"""``<custom><numeric>`` names of the recorded parameters: ``variant_<field>``."""
SHIPPED_LEG_LENGTH_M = 0.07
"""Horizontal reach of a foot centre from its thrust axis in the shipped model, m (README)."""
FLOOR = "floor"
"""The scene's floor geom."""
SERVO_CLASS = "servobot"
"""Default class whose ``position`` element carries every servo's kp and forcerange."""
FOOT_CLASS = "foot"
"""Default class of the foot spheres (friction)."""
HEADER = (
    "<!-- ServoBot variant written by `servobot variant` from models/servobot/scene.xml.\n"
    '     Its parameters are the <custom><numeric name="variant_*"> entries; see\n'
    '     models/servobot/README.md ("Variants") for what each one changes. -->\n'
)


class VariantError(InputError, ValueError):
    """An impossible variant (bad value, a robot that cannot stand or walk); names the problem."""


@dataclass(frozen=True)
class VariantParams:
    """Parameters of a ServoBot variant. Defaults = the shipped model (tested against it)."""

    torso_mass_kg: float = 0.76
    """Torso mass incl. capacitors and electronics, kg (inertia scales with it)."""
    leg_length_m: float = SHIPPED_LEG_LENGTH_M
    """Horizontal reach of each foot centre from its thrust axis, m (whole leg scales)."""
    servo_torque_nm: float = 0.3
    """Torque limit (stall torque) of all 12 servos, N·m."""
    servo_kp: float = 6.0
    """Position-servo stiffness of all 12 servos, N·m/rad."""
    foot_friction: float = 1.0
    """Sliding friction coefficient of the feet (MuJoCo uses max(foot, floor))."""
    floor_friction: float = 1.0
    """Sliding friction coefficient of the floor (MuJoCo's default; the colony arena's walls
    and station block take it too)."""

    def __post_init__(self) -> None:
        for f in dataclasses.fields(self):
            v = getattr(self, f.name)
            if isinstance(v, bool) or not isinstance(v, int | float) or not math.isfinite(v):
                raise VariantError(f"{f.name} must be a finite number, got {v!r}")
            if v <= 0.0:
                raise VariantError(f"{f.name} must be > 0, got {v!r}")

    @property
    def effective_friction(self) -> float:
        """The foot–floor sliding coefficient MuJoCo uses: the larger of the two."""
        return max(self.foot_friction, self.floor_friction)

    def changed(self) -> dict[str, float]:
        """The parameters that differ from the shipped model's."""
        base = VariantParams()
        return {k: v for k, v in self.to_dict().items() if v != getattr(base, k)}

    def to_dict(self) -> dict[str, float]:
        return {k: float(v) for k, v in dataclasses.asdict(self).items()}


FIELDS = tuple(f.name for f in dataclasses.fields(VariantParams))


def valid_inertia(diag: np.ndarray) -> np.ndarray:
    """``diag`` (principal moments) made to satisfy the triangle inequality MuJoCo requires
    (A + B >= C for every ordering): a moment that exceeds the sum of the other two (by float
    rounding after a scale: the shipped torso's 0.0009 + 0.0049 = 0.0058 sits exactly on it,
    so 0.9 kg would fail) is set to that sum. A valid ``diag`` is returned unchanged, bit for
    bit, so the shipped model's output does not move."""
    d = np.asarray(diag, dtype=float).copy()
    for i in range(3):
        rest = d[(i + 1) % 3] + d[(i + 2) % 3]
        if d[i] > rest:
            d[i] = rest
    return d


def _scale_legs(root: mjcf.RootElement, scale: float) -> float:
    """Scale every leg below its lift joint by ``scale``; returns how much lower the feet
    reach (m), which the torso's home height gains."""
    drop = -float(root.find("geom", f"{C.LEGS[0]}_foot").pos[2])  # foot centre below the hip
    for leg in C.LEGS:
        body = root.find("body", f"{leg}_leg")
        body.inertial.pos = np.asarray(body.inertial.pos) * scale
        body.inertial.diaginertia = valid_inertia(np.asarray(body.inertial.diaginertia) * scale**2)
        for geom in body.find_all("geom"):
            if geom.fromto is not None:
                geom.fromto = np.asarray(geom.fromto) * scale
            if geom.pos is not None:
                geom.pos = np.asarray(geom.pos) * scale
        for site in body.find_all("site"):
            site.pos = np.asarray(site.pos) * scale
    return drop * (scale - 1.0)


def build_variant(params: VariantParams) -> mjcf.RootElement:
    """The shipped scene with ``params`` applied and recorded (an ``mjcf`` model, not compiled)."""
    root = mjcf.from_path(str(C.SCENE_XML))
    root.model = C.ROBOT_MODEL_NAME  # attached into an arena, names get the usual prefix
    torso = root.find("body", C.TORSO)
    mass_scale = params.torso_mass_kg / float(torso.inertial.mass)
    torso.inertial.mass = params.torso_mass_kg
    torso.inertial.diaginertia = valid_inertia(np.asarray(torso.inertial.diaginertia) * mass_scale)
    lower = _scale_legs(root, params.leg_length_m / SHIPPED_LEG_LENGTH_M)
    torso.pos = np.asarray(torso.pos) + (0.0, 0.0, lower)
    for key in root.keyframe.key:
        qpos = np.asarray(key.qpos, dtype=float).copy()
        qpos[2] += lower
        key.qpos = qpos
    servo = root.find("default", SERVO_CLASS).position
    servo.kp = params.servo_kp
    servo.forcerange = [-params.servo_torque_nm, params.servo_torque_nm]
    foot = root.find("default", FOOT_CLASS).geom
    foot.friction = [params.foot_friction, *np.asarray(foot.friction)[1:]]
    floor = root.find("geom", FLOOR)
    floor_rest = (0.005, 0.0001) if floor.friction is None else np.asarray(floor.friction)[1:]
    floor.friction = [params.floor_friction, *floor_rest]
    for name, value in params.to_dict().items():
        root.custom.add("numeric", name=NUMERIC_PREFIX + name, data=[value])
    return root


def variant_xml(params: VariantParams) -> str:
    """The variant as one MJCF document: a header comment, then ``build_variant``'s XML with
    floats in full precision (17 digits: the compiled model equals the source bit for bit)."""
    tree = _plain_mjcf(build_variant(params).to_xml())
    etree.indent(tree, space="  ")
    return HEADER + etree.tostring(tree, encoding="unicode") + "\n"


def _plain_mjcf(tree: etree._Element) -> etree._Element:
    """Undo dm_control's scoping marks, which its own parser refuses to read back: the main
    defaults wrapped in ``<default class="/">`` move up into the file's ``<default>``;
    ``class="/"`` (the main class) and generated ``//unnamed_*`` names are dropped. Only
    elements outside any ``childclass`` body carry them here (the floor, light, textures),
    and the compiled model is unchanged (tested against the shipped one)."""
    main = tree.find("default")
    wrapper = None if main is None else main.find("default[@class='/']")
    if wrapper is not None:
        at = main.index(wrapper)
        for k, child in enumerate(list(wrapper)):
            main.insert(at + k, child)
        main.remove(wrapper)
    for el in tree.iter():
        if el.get("class") == "/":
            del el.attrib["class"]
        if (el.get("name") or "").startswith("//unnamed_"):
            del el.attrib["name"]
    return tree


def variant_params(model: mujoco.MjModel, prefix: str = "") -> VariantParams | None:
    """The parameters recorded in a compiled model; None for a model that records none (the
    shipped one). ``VariantError`` if only some are recorded."""
    found: dict[str, float] = {}
    for name in FIELDS:
        i = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_NUMERIC, prefix + NUMERIC_PREFIX + name)
        if i >= 0:
            found[name] = float(model.numeric_data[model.numeric_adr[i]])
    if not found:
        return None
    missing = [f for f in FIELDS if f not in found]
    if missing:
        raise VariantError(f"model records variant parameters but not {missing}")
    return VariantParams(**found)


def read_variant(path: str | Path) -> VariantParams | None:
    """The parameters a model file records (None: not a variant file)."""
    read_text(path, what="model file")  # a named error (ReadError) for any unusable file
    try:
        model = mujoco.MjModel.from_xml_path(str(path))
    except ValueError as exc:
        raise VariantError(f"{path}: MuJoCo cannot compile it ({exc})") from exc
    return variant_params(model)


def _carried(model: mujoco.MjModel, data: mujoco.MjData, when: str) -> None:
    """``VariantError`` if the torso touches the floor (the legs do not carry it)."""
    torso = model.geom(C.TORSO).id
    geoms = zip(data.contact.geom1[: data.ncon], data.contact.geom2[: data.ncon], strict=True)
    if any(torso in pair for pair in geoms):
        raise VariantError(f"the torso touches the floor {when}: the legs do not carry it")


def check_stands(model: mujoco.MjModel) -> ServoBot:
    """Place the robot in its home posture and settle it (noise-free); returns the robot.
    Raises ``servo_mj.robot.bot.PhysicsError`` (NaN, warning, runaway, flipped) or
    ``VariantError`` when the torso touches the floor."""
    data = mujoco.MjData(model)
    bot = ServoBot(model, data, rng=np.random.default_rng(0))
    bot.place(0.0, 0.0, 0.0)
    _carried(model, data, "after settling")
    return bot


def check_walks(model: mujoco.MjModel) -> None:
    """Stand the robot (``check_stands``) and walk one cycle of every gait (noise-free);
    raises ``servo_mj.robot.bot.PhysicsError`` (NaN, warning, runaway, flipped) or
    ``VariantError`` when the torso touches the floor (the legs do not carry it)."""
    bot = check_stands(model)
    for g in range(N_GAITS):
        bot.run_gait(g)
        _carried(model, bot.data, f"while walking gait {g}")


def checked_variant(params: VariantParams, label: str | None = None) -> str:
    """The variant's MJCF text, once it compiled and its robot stood and walked one cycle of
    every gait (``check_walks``); ``VariantError`` naming the variant as ``label`` (default:
    its changed fields) otherwise."""
    label = label or f"variant {params.changed()}"
    xml = variant_xml(params)
    try:
        model = mujoco.MjModel.from_xml_string(xml)
    except ValueError as exc:
        raise VariantError(f"{label} does not compile: {exc}") from exc
    try:
        check_walks(model)
    except (RuntimeError, VariantError) as exc:
        raise VariantError(f"{label} cannot stand and walk: {exc}") from exc
    return xml


def write_variant(params: VariantParams, out: str | Path, label: str | None = None) -> Path:
    """Build, compile and walk-check the variant (``checked_variant``), then write it to
    ``out`` atomically."""
    return atomic_write_text(out, checked_variant(params, label))


def describe(params: VariantParams | None) -> dict[str, Any]:
    """JSON-ready provenance: the parameters (or None for the shipped robot) and what changed."""
    if params is None:
        return {"variant": None}
    return {"variant": params.to_dict(), "changed": params.changed()}


__all__ = [
    "FIELDS",
    "VariantError",
    "VariantParams",
    "build_variant",
    "check_stands",
    "check_walks",
    "checked_variant",
    "describe",
    "read_variant",
    "valid_inertia",
    "variant_params",
    "variant_xml",
    "write_variant",
]
