"""Paths, leg order and MJCF names of the ServoBot, written once.

Every joint, actuator, body and site name used by Python code is built here from ``LEGS`` and
the role names, never typed twice. Every builder takes an optional ``prefix``: ``""`` for the
bare robot (``models/servobot/servobot.xml``), ``"servobot/"`` when ``dm_control.mjcf`` has
attached the robot into an arena (MJCF model name ``servobot``).

Robot body frame: +x forward, +y left, +z up (metres). Leg order: left front, left middle, left
hind, right front, right middle, right hind. Each leg has a thrust joint (fore/aft swing about
a vertical axis; positive = foot forward on both sides) and a lift joint (about the body's long
axis; positive = foot up on both sides).
"""

from __future__ import annotations

from pathlib import Path

MODEL_DIR = Path(__file__).resolve().parents[2] / "models" / "servobot"
"""Folder of the robot's MJCF files."""
ROBOT_XML = MODEL_DIR / "servobot.xml"
"""The robot alone (attachable with ``dm_control.mjcf``)."""
SCENE_XML = MODEL_DIR / "scene.xml"
"""The robot on a floor with a light (calibration scene)."""

CM_PER_M = 100.0
"""Arena units (1 unit = 1 cm) per MuJoCo metre (SPEC §1) [chosen]."""

ROBOT_MODEL_NAME = "servobot"
"""MJCF ``model`` attribute; ``dm_control.mjcf`` prefixes attached names with ``servobot/``."""
ATTACHED_PREFIX = ROBOT_MODEL_NAME + "/"
"""Prefix of every name once the robot is attached into an arena by ``dm_control.mjcf``."""

LEGS: tuple[str, ...] = ("LF", "LM", "LH", "RF", "RM", "RH")
"""Leg order, used for actuator order and gait frames: left front/middle/hind, right ..."""
LEG_SIDE: dict[str, int] = {leg: (1 if leg[0] == "L" else -1) for leg in LEGS}
"""+1 for left legs (+y), -1 for right legs."""
TRIPOD_A: tuple[str, ...] = ("LF", "RM", "LH")
"""Legs in stance during the first half of a tripod gait cycle."""
TRIPOD_B: tuple[str, ...] = ("RF", "LM", "RH")
"""Legs in stance during the second half of a tripod gait cycle."""
ROLES: tuple[str, ...] = ("thrust", "lift")
"""Joint roles of one leg, in actuator order."""

TORSO = "torso"
"""Torso body name (bare robot)."""
FREE_JOINT = "root"
"""The torso's free joint in the bare robot (removed when attached into an arena)."""

OBJECT_SENSOR_SITES: tuple[str, str] = ("object_left", "object_right")
"""Marker sites of the (left, right) object sensors, x axis along the span centre: decoration
only. The object sensors in physics are the rangefinder fans that ``servo_mj.world.sensors``
adds to the torso."""
LIGHT_SENSOR_SITES: tuple[str, str] = ("light_left", "light_right")
"""Marker sites of the (left, right) light sensors, x axis along the span centre: decoration
only. Light sensing is the SPEC's geometric rule on the physical pose (MuJoCo has no light
sensor)."""
PROBE_SITES: tuple[str, str] = ("probe_left", "probe_right")
"""Sites at the tips of the two metal docking probes."""


def joint_name(leg: str, role: str, prefix: str = "") -> str:
    """Name of a leg joint, e.g. ``joint_name("LF", "thrust") == "LF_thrust"``."""
    if leg not in LEGS:
        raise ValueError(f"unknown leg {leg!r}; legs are {LEGS}")
    if role not in ROLES:
        raise ValueError(f"unknown joint role {role!r}; roles are {ROLES}")
    return f"{prefix}{leg}_{role}"


def actuator_name(leg: str, role: str, prefix: str = "") -> str:
    """Name of a servo: actuators are named after their joints."""
    return joint_name(leg, role, prefix)


def joint_names(prefix: str = "") -> tuple[str, ...]:
    """The 12 leg joints in actuator order (leg by leg, thrust then lift)."""
    return tuple(joint_name(leg, role, prefix) for leg in LEGS for role in ROLES)


def actuator_names(prefix: str = "") -> tuple[str, ...]:
    """The 12 servos in actuator order (same as ``joint_names``)."""
    return joint_names(prefix)


def torso_name(prefix: str = "") -> str:
    """Torso body name."""
    return prefix + TORSO


def foot_site_name(leg: str, prefix: str = "") -> str:
    """Site at the centre of a foot sphere."""
    if leg not in LEGS:
        raise ValueError(f"unknown leg {leg!r}; legs are {LEGS}")
    return f"{prefix}{leg}_foot"


def foot_sites(prefix: str = "") -> tuple[str, ...]:
    """The six foot sites in leg order."""
    return tuple(foot_site_name(leg, prefix) for leg in LEGS)


def probe_sites(prefix: str = "") -> tuple[str, str]:
    """(left, right) probe-tip site names."""
    return (prefix + PROBE_SITES[0], prefix + PROBE_SITES[1])
