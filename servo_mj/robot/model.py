"""Load the ServoBot MJCF and small accessors on a compiled model (names from ``constants``)."""

from __future__ import annotations

import hashlib
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import mujoco
import numpy as np
from lxml import etree

from infra.errors import InputError
from infra.io import ReadError, read_text
from servo_mj.robot import constants as C


class ModelFileError(InputError, ValueError):
    """A robot model file that cannot be used (missing, not a regular text file, not MJCF, an
    include outside its folder, does not compile, not a ServoBot); the message names it."""


ModelFile = str | Path | None
"""Which robot: None = the shipped ServoBot (``models/servobot``), else the path of a complete
MJCF scene such as a ``servobot variant`` file (robot + floor + options in one file)."""

WHAT = "robot model file"
"""How read errors name a model file (``infra.io.read_text``'s ``what``)."""
SCENE_FLOOR = "floor"
"""The floor geom every model file (a complete scene) must have."""


@dataclass(frozen=True)
class CheckedModel:
    """A robot model that ``check_model`` read, compiled and found to be a ServoBot.

    ``path``: the top file (``scene.xml`` for the shipped robot); ``files``: (relative name,
    path) of the top file and of every file it includes, directly or not, in hash order
    (``model_sha256``); ``sha256``: their hash."""

    path: Path
    files: tuple[tuple[str, Path], ...]
    sha256: str


def _label(model: ModelFile, option: str | None) -> str:
    return f"{option} {model}" if option else f"robot model {model}"


def _parse_mjcf(text: str, path: Path, label: str) -> etree._Element:
    """The XML tree of an MJCF file (no entities, no network, no DTD), or ``ModelFileError``
    (``label`` names the model, and ``path`` too when it is an included file)."""
    parser = etree.XMLParser(resolve_entities=False, no_network=True, load_dtd=False,
                             huge_tree=False, remove_comments=True)  # fmt: skip
    try:
        root = etree.fromstring(text.encode("utf-8"), parser)
    except (etree.XMLSyntaxError, ValueError) as exc:
        raise ModelFileError(f"{label}: not well-formed XML ({exc})") from exc
    if root is None or not isinstance(root.tag, str) or root.tag != "mujoco":
        tag = getattr(root, "tag", None)
        raise ModelFileError(
            f"{label}: not an MJCF model (its root element is <{tag}>, not <mujoco>)"
        )
    return root


def model_files(model: ModelFile = None, option: str | None = None) -> list[tuple[str, Path]]:
    """The top file of ``model`` and every file it includes (``<include file=...>``, nested
    ones too), as (name relative to the top file's folder, path): each read with the project's
    rules (``infra.io.read_text``: a regular UTF-8 text file of at most 64 MB), each an MJCF
    document. MuJoCo resolves every include against the top file's folder; an include that
    leaves it (absolute, ``..``) is refused, so a model never reads a system file. The top
    file comes first, then the includes in the order met. ``ModelFileError`` naming
    ``option`` (e.g. ``--model``) and the file otherwise."""
    top = C.SCENE_XML if model is None else Path(model)
    label = _label(model if model is not None else top, option)
    base = top.parent.resolve()
    files: list[tuple[str, Path]] = []
    todo: list[tuple[str, Path, str | None]] = [(top.name, top, None)]
    seen: set[str] = set()
    while todo:
        rel, path, included_by = todo.pop(0)
        where = label if included_by is None else f"{label}: {path} (included by {included_by})"
        try:
            text = read_text(path, what=WHAT)
        except ReadError as exc:
            raise ModelFileError(f"{where}: {exc.reason}") from exc
        files.append((rel, path))
        root = _parse_mjcf(text, path, where)
        for el in root.iter("include"):
            name = el.get("file")
            if not name:
                raise ModelFileError(f"{where}: an <include> without a file")
            target = (base / name).resolve()
            if Path(name).is_absolute() or not target.is_relative_to(base):
                raise ModelFileError(
                    f"{where}: includes {name}, outside the model's folder {base}; "
                    "a model may include only files in its own folder or below"
                )
            inc_rel = target.relative_to(base).as_posix()
            if inc_rel in seen or inc_rel == top.name:
                continue  # MuJoCo itself refuses a repeated include, with a named error
            seen.add(inc_rel)
            todo.append((inc_rel, base / inc_rel, str(path)))
    return files


def _files_sha256(files: Sequence[tuple[str, Path]], shipped: bool) -> str:
    h = hashlib.sha256()
    top, includes = files[0], sorted(files[1:])
    if not includes and not shipped:
        h.update(top[1].read_bytes())  # a one-file model: its bytes (its name does not count)
        return h.hexdigest()
    for rel, path in [*includes, top]:
        h.update(rel.encode())
        h.update(path.read_bytes())
    return h.hexdigest()


def model_sha256(model: ModelFile = None) -> str:
    """SHA-256 of the robot (provenance of a calibration, a validation, a recording), over
    every file of the model (``model_files``): a one-file model by its bytes (its name does
    not count); a model that includes files by each included file's relative name and bytes,
    in name order, then the top file's name and bytes. So an included file that changed after
    a calibration changes the hash. The shipped robot is ``scene.xml`` including
    ``servobot.xml`` (its hash is the one recorded in the shipped data files)."""
    return _files_sha256(model_files(model), shipped=model is None)


_CHECKED: dict[tuple[str, str], CheckedModel] = {}
"""``check_model``'s results by (top file, content hash): each model compiles once."""


def _needed_names() -> list[tuple[mujoco.mjtObj, str]]:
    obj = mujoco.mjtObj
    return [
        (obj.mjOBJ_BODY, C.TORSO),
        (obj.mjOBJ_GEOM, C.TORSO),
        (obj.mjOBJ_JOINT, C.FREE_JOINT),
        *((obj.mjOBJ_JOINT, n) for n in C.joint_names()),
        *((obj.mjOBJ_SITE, n) for n in C.foot_sites()),
        (obj.mjOBJ_GEOM, f"{C.LEGS[0]}_foot"),
        *((obj.mjOBJ_SITE, n) for n in C.probe_sites()),
        (obj.mjOBJ_GEOM, SCENE_FLOOR),
    ]


def check_model(model: ModelFile = None, option: str | None = None) -> CheckedModel:
    """Read, compile and check a robot model once, before any work: the one gate every
    command's ``--model`` (and every library function given a model file) goes through.

    Reads the file and its includes (``model_files``), compiles it with MuJoCo, and checks
    that it is a ServoBot scene: the 12 servos (``constants.actuator_names``, in order), the
    torso body and geom, its free joint, the leg joints, foot and probe sites, and a floor.
    ``ModelFileError`` naming ``option`` and the file otherwise (a folder, ``/dev/null``, a
    binary or 70 MB file, an HTML page, an MJCF without actuators, an include of a system
    file, a missing file). Results are kept per content, so a second call costs one read."""
    files = model_files(model, option)
    top = files[0][1]
    label = _label(model if model is not None else top, option)
    sha = _files_sha256(files, shipped=model is None)
    key = (str(top.resolve()), sha)
    if key in _CHECKED:
        return _CHECKED[key]
    try:
        compiled = mujoco.MjModel.from_xml_path(str(top))
    except ValueError as exc:
        first = " ".join(str(exc).split())[:400]
        raise ModelFileError(f"{label}: MuJoCo cannot compile it ({first})") from exc
    want = C.actuator_names()
    have = tuple(compiled.actuator(i).name for i in range(compiled.nu))
    if have != want:
        raise ModelFileError(
            f"{label}: not a ServoBot model: its {compiled.nu} actuators are not the "
            f"ServoBot's 12 servos ({', '.join(want)}, in this order)"
        )
    missing = [f"{o.name.removeprefix('mjOBJ_').lower()} {n!r}"
               for o, n in _needed_names() if mujoco.mj_name2id(compiled, o, n) < 0]  # fmt: skip
    if missing:
        raise ModelFileError(f"{label}: not a ServoBot model: it has no {', '.join(missing)}")
    checked = CheckedModel(top, tuple(files), sha)
    _CHECKED[key] = checked
    return checked


def scene_path(model: ModelFile = None) -> Path:
    """The calibration scene of ``model``: the shipped ``scene.xml`` or the given file, which
    must be a usable ServoBot model (``check_model``; ``ModelFileError`` naming it)."""
    if model is None:
        return C.SCENE_XML
    return check_model(model).path


def model_label(model: ModelFile = None) -> str:
    """How messages and files name a model: ``shipped ServoBot (models/servobot)`` or the path."""
    return "shipped ServoBot (models/servobot)" if model is None else str(model)


def load_robot(scene: bool = True, model: ModelFile = None) -> tuple[mujoco.MjModel, mujoco.MjData]:
    """Compile the calibration scene (robot on a floor) or, for the shipped model only, the bare
    ``servobot.xml`` (``scene=False``); data at the ``home`` keyframe. ``model``: see
    ``ModelFile``."""
    if not scene and model is not None:
        raise ValueError("scene=False loads the shipped robot alone; a model file is a scene")
    path = scene_path(model) if scene else C.ROBOT_XML
    try:
        compiled = mujoco.MjModel.from_xml_path(str(path))
    except ValueError as exc:
        raise ModelFileError(f"robot model {path}: MuJoCo cannot compile it ({exc})") from exc
    data = mujoco.MjData(compiled)
    key = mujoco.mj_name2id(compiled, mujoco.mjtObj.mjOBJ_KEY, "home")
    if key >= 0:
        mujoco.mj_resetDataKeyframe(compiled, data, key)
    mujoco.mj_forward(compiled, data)
    return compiled, data


def name_id(model: mujoco.MjModel, obj: mujoco.mjtObj, name: str) -> int:
    """Id of a named MuJoCo object or a ``KeyError`` naming what is missing."""
    i = mujoco.mj_name2id(model, obj, name)
    if i < 0:
        raise KeyError(f"model has no {obj.name.removeprefix('mjOBJ_').lower()} named {name!r}")
    return i


def free_joint_of(model: mujoco.MjModel, body: int) -> int:
    """The free joint that moves ``body``: walk up the parents to the first body that has one."""
    b = body
    while b > 0:
        for j in range(model.body_jntadr[b], model.body_jntadr[b] + model.body_jntnum[b]):
            if model.jnt_type[j] == mujoco.mjtJoint.mjJNT_FREE:
                return j
        b = int(model.body_parentid[b])
    raise KeyError(f"no free joint above body {model.body(body).name!r}")


def heading_deg_from_xmat(xmat: np.ndarray) -> float:
    """SPEC heading (0 = north/+y, clockwise) of a body whose +x axis is its forward axis."""
    fx, fy = float(xmat[0]), float(xmat[3])
    return float(np.degrees(np.arctan2(fx, fy)) % 360.0)


def thrust_limit_rad(model: mujoco.MjModel, prefix: str = "") -> float:
    """Smallest |ctrlrange| bound of the six thrust servos, rad: how far a thrust sweep may
    reach (the MJCF's ``thrust`` default class is its one home)."""
    ids = [name_id(model, mujoco.mjtObj.mjOBJ_ACTUATOR, C.actuator_name(leg, "thrust", prefix))
           for leg in C.LEGS]  # fmt: skip
    return float(np.abs(model.actuator_ctrlrange[ids]).min())
