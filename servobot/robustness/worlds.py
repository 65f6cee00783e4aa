"""The physics worlds of the test matrix (SPEC §9, last bullet): a small frozen registry.

A world is the MuJoCo colony of ``servo_mj.world.arena`` (``ArenaSettings``) with a robot in
it: the shipped ServoBot (``variant`` None) or a ``servobot variant`` (``VariantParams``). A
controller runs in each world unchanged, beside the same table world (SPEC §3).

Built-in worlds (``BUILT_IN``), each changing one thing of ``shipped``:

- ``shipped``: SPEC §3 "In MuJoCo", the shipped robot, the station block 0.10 m tall;
- ``station-seen``: the station block ``STATION_SEEN_HEIGHT_M`` (0.30 m) tall, which the
  rangefinders see;
- ``heavy``: torso mass × ``HEAVY_TORSO_SCALE`` (+50 %);
- ``weak``: servo torque limit × ``WEAK_TORQUE_SCALE`` (−25 %);
- ``slippery``: floor friction × ``SLIPPERY_FRICTION_SCALE`` (−40 %), the feet's too, since
  MuJoCo takes the larger of the two coefficients for a contact;
- ``long-legs``: leg length × ``LONG_LEGS_SCALE`` (+10 %), held out (``HELD_OUT``).

Scales are relative to ``VariantParams()`` (the shipped robot). Any other world is a variant
MJCF file (``servobot variant --out FILE.xml``) named by its file stem (``world_from_file``).
"""

from __future__ import annotations

import dataclasses
import hashlib
from dataclasses import dataclass
from pathlib import Path

import mujoco

from infra.errors import InputError
from servo_mj.robot.model import ModelFileError, check_model, model_sha256
from servo_mj.robot.variant import (
    VariantError,
    VariantParams,
    check_walks,
    read_variant,
    variant_xml,
    write_variant,
)
from servo_mj.world.arena import ArenaSettings

SHIPPED = "shipped"
"""The world every other world's drop is measured against."""
STATION_SEEN_HEIGHT_M = 0.30
"""Station block height of ``station-seen``, m: above the rangefinder rays (≈ 0.15 m above
the floor), so the object sensors see the block (``ArenaSettings.station_height_m``)."""
HEAVY_TORSO_SCALE = 1.5
"""``heavy``: torso mass (capacitors, electronics) × this."""
WEAK_TORQUE_SCALE = 0.75
"""``weak``: the twelve servos' torque limit × this."""
SLIPPERY_FRICTION_SCALE = 0.6
"""``slippery``: the floor's and the feet's sliding friction × this."""
LONG_LEGS_SCALE = 1.1
"""``long-legs``: leg length (foot reach from the thrust axis) × this."""
_BASE = VariantParams()


class WorldError(InputError, ValueError):
    """A ``--worlds`` entry that names no built-in world and no usable variant file."""


@dataclass(frozen=True)
class PhysicsWorldSpec:
    """One physics world of the matrix: the arena and the robot standing in it."""

    name: str
    """Its name: a built-in's, or a variant file's stem (folder names and tables use it)."""
    description: str
    """What it changes from ``shipped``, in words."""
    arena: ArenaSettings
    """The MuJoCo colony (station block height, ...)."""
    variant: VariantParams | None
    """The robot: None = the shipped ServoBot, else a variant (built into ``DIR/models``)."""
    source: Path | None = None
    """A variant MJCF file given by the user (None for a built-in world)."""


def _variant(**changes: float) -> VariantParams:
    return dataclasses.replace(_BASE, **changes)


HELD_OUT = PhysicsWorldSpec(
    "long-legs",
    f"leg length x{LONG_LEGS_SCALE:g} ({_BASE.leg_length_m:g} -> "
    f"{_BASE.leg_length_m * LONG_LEGS_SCALE:g} m); held out: never used for tuning",
    ArenaSettings(),
    _variant(leg_length_m=_BASE.leg_length_m * LONG_LEGS_SCALE),
)
"""The held-out world, for honest evaluation: it is kept out of any tuning — no choice of a
controller, an envelope (SPEC §9) or a setting may look at its results; report it only."""

BUILT_IN: dict[str, PhysicsWorldSpec] = {
    w.name: w
    for w in (
        PhysicsWorldSpec(
            SHIPPED, "the shipped robot and arena (SPEC §3 'In MuJoCo')", ArenaSettings(), None
        ),  # fmt: skip
        PhysicsWorldSpec(
            "station-seen",
            f"station block {STATION_SEEN_HEIGHT_M:g} m tall (shipped "
            f"{ArenaSettings().station_height_m:g} m): the rangefinders see it",
            ArenaSettings(station_height_m=STATION_SEEN_HEIGHT_M),
            None,
        ),
        PhysicsWorldSpec(
            "heavy",
            f"torso mass x{HEAVY_TORSO_SCALE:g} ({_BASE.torso_mass_kg:g} -> "
            f"{_BASE.torso_mass_kg * HEAVY_TORSO_SCALE:g} kg)",
            ArenaSettings(),
            _variant(torso_mass_kg=_BASE.torso_mass_kg * HEAVY_TORSO_SCALE),
        ),
        PhysicsWorldSpec(
            "weak",
            f"servo torque x{WEAK_TORQUE_SCALE:g} ({_BASE.servo_torque_nm:g} -> "
            f"{_BASE.servo_torque_nm * WEAK_TORQUE_SCALE:g} N·m)",
            ArenaSettings(),
            _variant(servo_torque_nm=_BASE.servo_torque_nm * WEAK_TORQUE_SCALE),
        ),
        PhysicsWorldSpec(
            "slippery",
            f"floor and foot friction x{SLIPPERY_FRICTION_SCALE:g} "
            f"({_BASE.effective_friction:g} -> "
            f"{_BASE.effective_friction * SLIPPERY_FRICTION_SCALE:g})",
            ArenaSettings(),
            _variant(
                floor_friction=_BASE.floor_friction * SLIPPERY_FRICTION_SCALE,
                foot_friction=_BASE.foot_friction * SLIPPERY_FRICTION_SCALE,
            ),
        ),
        HELD_OUT,
    )
}
"""The built-in worlds by name (module docstring)."""


def built_in_list() -> str:
    """The built-in worlds' names, comma-separated (for messages)."""
    return ", ".join(BUILT_IN)


def world_from_file(path: Path) -> PhysicsWorldSpec:
    """A world whose robot is the variant MJCF file ``path`` (named by its stem), after checking
    that it is a usable ServoBot model (``servo_mj.robot.model.check_model``) and that the
    robot stands and walks one cycle of every gait; ``WorldError`` naming the file otherwise."""
    try:
        check_model(path, option="--worlds")  # the one gate of model files
    except ModelFileError as exc:
        raise WorldError(str(exc)) from exc
    try:
        params = read_variant(path)
        check_walks(mujoco.MjModel.from_xml_path(str(path)))
    except (InputError, ValueError, RuntimeError) as exc:
        named = str(exc) if str(path) in str(exc) else f"{path}: {exc}"
        raise WorldError(f"--worlds: {named}") from exc
    what = "a robot model file" if params is None else f"variant {params.changed() or 'shipped'}"
    return PhysicsWorldSpec(path.stem, f"{what} ({path})", ArenaSettings(), params, path)


def resolve_worlds(entries: list[str] | tuple[str, ...]) -> list[PhysicsWorldSpec]:
    """The worlds of ``entries``: built-in names, or paths of variant files. ``WorldError``
    for an entry that is neither (naming it and listing the built-ins), or a name twice."""
    if not entries:
        raise WorldError(f"--worlds: no world given; built-in worlds: {built_in_list()}")
    worlds: list[PhysicsWorldSpec] = []
    for entry in entries:
        if entry in BUILT_IN:
            worlds.append(BUILT_IN[entry])
        elif Path(entry).is_file():
            worlds.append(world_from_file(Path(entry)))
        else:
            raise WorldError(
                f"--worlds: {entry!r} is neither a built-in world nor an existing variant file; "
                f"built-in worlds: {built_in_list()}"
            )
    names = [w.name for w in worlds]
    twice = sorted({n for n in names if names.count(n) > 1})
    if twice:
        raise WorldError(f"--worlds: world {twice[0]!r} given twice (a file is named by its stem)")
    return worlds


def model_path(world: PhysicsWorldSpec, models: Path) -> Path | None:
    """The robot model file of ``world`` (None = the shipped robot): a built-in variant's file
    in ``models``, or the user's file."""
    if world.source is not None:
        return world.source.resolve()
    if world.variant is None:
        return None
    return models.resolve() / f"{world.name}.xml"


def world_sha256(world: PhysicsWorldSpec) -> str:
    """SHA-256 of the world's robot model, as ``servo_mj.robot.model.model_sha256`` hashes it:
    a built-in variant's by the bytes ``write_variant`` will write (known before writing)."""
    if world.source is not None or world.variant is None:
        return model_sha256(world.source)
    return hashlib.sha256(variant_xml(world.variant).encode()).hexdigest()


def materialise(world: PhysicsWorldSpec, models: Path) -> Path | None:
    """The world's model file, a built-in variant written (``write_variant``: it must stand
    and walk, else ``VariantError``) unless ``models`` already holds it with the same bytes."""
    path = model_path(world, models)
    if path is None or world.source is not None:
        return path
    assert world.variant is not None
    try:
        if path.is_file() and model_sha256(path) == world_sha256(world):
            return path
    except ModelFileError:
        pass
    models.mkdir(parents=True, exist_ok=True)
    try:
        return write_variant(world.variant, path)
    except VariantError as exc:
        raise VariantError(f"world {world.name}: {exc}") from exc


__all__ = [
    "BUILT_IN",
    "HEAVY_TORSO_SCALE",
    "HELD_OUT",
    "LONG_LEGS_SCALE",
    "SHIPPED",
    "SLIPPERY_FRICTION_SCALE",
    "STATION_SEEN_HEIGHT_M",
    "WEAK_TORQUE_SCALE",
    "PhysicsWorldSpec",
    "WorldError",
    "built_in_list",
    "materialise",
    "model_path",
    "resolve_worlds",
    "world_from_file",
    "world_sha256",
]
