"""Issue 19, models, executors and variants: every command that takes ``--model`` refuses a
model it cannot use before any work (``servo_mj.robot.model.check_model``, exit 2 naming
``--model`` and the file); a model's sha256 covers every file it includes; ``--executor`` is
parsed and its Ray cluster reached within seconds before any work; variants compile and
stand over a sweep of torso masses and leg lengths, and name their options as typed.
Each CLI case runs in-process (``servobot.cli.main(argv)``)."""

from __future__ import annotations

import json
import shutil
import socket
import threading
import time
from pathlib import Path

import mujoco
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from evolve.table import PAPER_TABLE, table_to_json
from infra.executors import (
    ExecutorError,
    ExecutorSpec,
    ExecutorSpecError,
    make_executor,
    parse_spec,
)
from servo_mj.robot import constants as C
from servo_mj.robot.model import ModelFileError, check_model, model_files, model_sha256
from servo_mj.robot.variant import (
    VariantParams,
    check_stands,
    checked_variant,
    valid_inertia,
    variant_xml,
)
from servobot.cli import main as servobot
from servobot.validation.lone import ValidationError, load_checked_table

GENE = "01 0100000 0100000 0100000 0100000\n"
SHIPPED_SHA256 = "8bacc789e3de2f44b9e28adc4188e0b10e747c096edf4de30e4dfa56ef838dc5"
"""The shipped robot's hash, as recorded in servo_mj/robot/data/gait_params.json."""


def _run(argv: list[str], capsys: pytest.CaptureFixture) -> tuple[int, str, float]:
    t0 = time.monotonic()
    try:
        code = servobot(argv)
    except SystemExit as exc:  # argparse
        code = exc.code
    return code, capsys.readouterr().err, time.monotonic() - t0


MODEL_TEXTS = {
    "chrom8": ("c8.txt", GENE * 8),
    "chrom16": ("c16.txt", GENE * 16),
    "html": ("page.xml", "<!DOCTYPE html>\n<html><body>x</body></html>"),
    "no_actuators": ("bare.xml", '<mujoco><worldbody><geom name="floor" type="plane" '
                                 'size="1 1 0.1"/></worldbody></mujoco>'),
    "system_include": ("passwd.xml", '<mujoco><include file="/etc/passwd"/></mujoco>'),
    "missing_include": ("dangling.xml", '<mujoco><include file="gone.xml"/></mujoco>'),
    "not_xml": ("not_xml.xml", "<mujoco><worldbody></mujoco>"),
}  # fmt: skip
"""Input files by kind: (file name, text)."""


@pytest.fixture(scope="module")
def inputs(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    """Every kind of bad model file (``MODEL_TEXTS``, a folder, ``/dev/null``, 70 MB, binary,
    missing) and two chromosomes."""
    d = tmp_path_factory.mktemp("models")
    f = {kind: d / name for kind, (name, _) in MODEL_TEXTS.items()}
    for kind, (_, text) in MODEL_TEXTS.items():
        f[kind].write_text(text)
    f["folder"] = d / "a_folder"
    f["folder"].mkdir()
    f["devnull"] = Path("/dev/null")
    f["big"] = d / "big.xml"
    with open(f["big"], "wb") as fh:  # sparse: 70 MB on paper, nothing on disk
        fh.truncate(70 * 2**20)
    f["binary"] = d / "binary.xml"
    f["binary"].write_bytes(bytes(range(256)) * 8)
    f["missing"] = d / "missing.xml"
    return f


# (model kind, what the message says after "--model FILE: ")
BAD_MODELS = [
    ("html", "not an MJCF model (its root element is <html>, not <mujoco>)"),
    ("no_actuators", "not a ServoBot model: its 0 actuators are not the ServoBot's 12 servos"),
    ("system_include", "includes /etc/passwd, outside the model's folder"),
    ("missing_include", "gone.xml (included by"),
    ("folder", "is a folder, not a robot model file"),
    ("devnull", "is not a regular file, so not a robot model file"),
    ("big", "is 73,400,320 bytes, too large for a robot model file"),
    ("binary", "holds binary data, not a robot model file"),
    ("missing", "no such robot model file"),
    ("not_xml", "not well-formed XML"),
]
MODEL_COMMANDS = {
    "anytime": ["--navigation", "{chrom8}"],
    "validate": ["{chrom16}"],
    "calibrate": [],
    "reproduce": [],
}


@pytest.mark.parametrize("command", sorted(MODEL_COMMANDS))
@pytest.mark.parametrize(("kind", "reason"), BAD_MODELS, ids=[k for k, _ in BAD_MODELS])
def test_a_bad_model_is_refused_before_any_work(command, kind, reason, inputs, tmp_path, capsys):
    out = tmp_path / "out"
    args = [a.format(**{k: str(v) for k, v in inputs.items()}) for a in MODEL_COMMANDS[command]]
    model = str(inputs[kind])
    code, err, wall = _run([command, *args, "--model", model, "--out", str(out)], capsys)
    assert code == 2, err
    assert f"--model {model}: " in err and reason in err, err
    assert "Traceback" not in err
    assert kind == "missing" or "no such file" not in err  # a folder or /dev/null exists
    assert not out.exists()  # refused before anything was created
    assert wall < 30


def test_the_shipped_model_and_a_variant_pass_the_gate(tmp_path):
    shipped = check_model()
    assert shipped.sha256 == SHIPPED_SHA256 == model_sha256()
    assert [rel for rel, _ in shipped.files] == ["scene.xml", "servobot.xml"]
    variant = tmp_path / "v.xml"
    variant.write_text(variant_xml(VariantParams(torso_mass_kg=0.9)))
    checked = check_model(variant, option="--model")
    assert checked.path == variant and len(checked.files) == 1
    assert checked.sha256 == model_sha256(variant)  # a one-file model: its bytes
    assert check_model(variant) is checked  # compiled once


def _copy_shipped(folder: Path) -> Path:
    folder.mkdir()
    shutil.copy(C.SCENE_XML, folder / "scene.xml")
    shutil.copy(C.ROBOT_XML, folder / "servobot.xml")
    return folder / "scene.xml"


def test_the_hash_covers_every_included_file(tmp_path):
    top = _copy_shipped(tmp_path / "copy")
    # the same files under the same names: the shipped robot's hash
    assert model_sha256(top) == SHIPPED_SHA256
    table = tmp_path / "table.json"
    doc = table_to_json(PAPER_TABLE, provenance={"model_sha256": SHIPPED_SHA256})
    table.write_text(json.dumps(doc))
    assert load_checked_table(str(table), top)[1] is None  # the table fits this robot
    # the included robot changes after the calibration: detected
    robot = tmp_path / "copy" / "servobot.xml"
    robot.write_text(robot.read_text().replace('mass="0.76"', 'mass="0.86"'))
    changed = model_sha256(top)
    assert changed != SHIPPED_SHA256
    with pytest.raises(ValidationError, match="calibrated on another robot model"):
        load_checked_table(str(table), top)
    assert check_model(top).sha256 == changed
    # nested includes, relative to the top file's folder, in name order
    (tmp_path / "copy" / "parts").mkdir()
    (tmp_path / "copy" / "parts" / "extra.xml").write_text("<mujoco><size memory='1M'/></mujoco>")
    (tmp_path / "copy" / "parts" / "more.xml").write_text(
        '<mujoco><include file="parts/extra.xml"/></mujoco>'
    )
    top.write_text(top.read_text().replace('<include file="servobot.xml"/>',
                                           '<include file="servobot.xml"/>'
                                           '<include file="parts/more.xml"/>'))  # fmt: skip
    assert [rel for rel, _ in model_files(top)] == [
        "scene.xml", "servobot.xml", "parts/more.xml", "parts/extra.xml"
    ]  # fmt: skip
    before = check_model(top).sha256
    (tmp_path / "copy" / "parts" / "extra.xml").write_text("<mujoco><size memory='2M'/></mujoco>")
    assert model_sha256(top) != before


def test_an_include_that_leaves_the_folder_is_refused(tmp_path):
    (tmp_path / "outside.xml").write_text("<mujoco/>")
    (tmp_path / "in").mkdir()
    top = tmp_path / "in" / "m.xml"
    top.write_text('<mujoco><include file="../outside.xml"/></mujoco>')
    with pytest.raises(ModelFileError, match=r"--model .*m.xml: includes \.\./outside.xml, out"):
        check_model(top, option="--model")


# --------------------------------------------------------------------------- executors

EXECUTOR_COMMANDS = {
    "anytime": ["--navigation", "{chrom8}"],
    "validate": ["{chrom16}"],
    "calibrate": [],
    "evolve": ["navigation"],
    "robustness": ["{chrom16}"],
    "reproduce": [],
}
BAD_EXECUTORS = [
    ("ray:BADADDRESS", "argument --executor: ray:BADADDRESS: ADDRESS must be auto, HOST:PORT"),
    ("ray:127.0.0.1:0", "port '0' is not a number 1-65535"),
    ("ray:127.0.0.1:65536", "port '65536' is not a number 1-65535"),
    ("ray:bad host:80", "'bad host' is not a host name or IP address"),
    ("ray:127.0.0.1:1", "--executor ray:127.0.0.1:1: no Ray cluster answers at 127.0.0.1:1 ("),
    ("ray:ray://127.0.0.1:1", "no Ray cluster answers at 127.0.0.1:1"),
    ("cloud", "executor must be serial, process, ray or ray:ADDRESS"),
]


@pytest.mark.parametrize("command", sorted(EXECUTOR_COMMANDS))
@pytest.mark.parametrize(("spec", "message"), BAD_EXECUTORS, ids=[s for s, _ in BAD_EXECUTORS])
def test_a_bad_executor_is_refused_within_seconds(command, spec, message, inputs, tmp_path,
                                                  capsys):  # fmt: skip
    out = tmp_path / "out"
    args = [a.format(**{k: str(v) for k, v in inputs.items()}) for a in EXECUTOR_COMMANDS[command]]
    code, err, wall = _run([command, *args, "--executor", spec, "--out", str(out)], capsys)
    assert code == 2, err
    assert message in err and "--executor" in err, err
    assert "Traceback" not in err and "ValueError" not in err
    assert not out.exists()
    assert wall < 10


def test_parse_spec_checks_kinds_and_addresses():
    assert parse_spec("serial") == ExecutorSpec("serial")
    assert parse_spec("ray:auto") == ExecutorSpec("ray", "auto")
    assert parse_spec("ray:10.0.0.5:6379") == ExecutorSpec("ray", "10.0.0.5:6379", "10.0.0.5",
                                                           6379)  # fmt: skip
    assert parse_spec("ray:ray://head.local:10001").host == "head.local"
    assert parse_spec("ray:[::1]:6379").host == "::1"
    assert str(parse_spec("ray:head:6379")) == "ray:head:6379"
    for bad in ("ray:head", "ray:head:", "ray::6379", "ray:head:+80", "ray:head:6379x",
                "ray:[zz]:1", "ray:ray://", "ray:a..b:1", "ray:-a:1", "ray: head:1"):  # fmt: skip
        with pytest.raises(ExecutorSpecError, match="ADDRESS must be auto, HOST:PORT"):
            parse_spec(bad)
    with pytest.raises(ValueError):  # make_executor keeps raising ValueError on a bad spec
        make_executor("ray:BADADDRESS")


def _serve_once(reply: bytes | None, hold_s: float = 0.0) -> tuple[int, threading.Thread]:
    """A one-connection TCP server on 127.0.0.1 answering ``reply`` (None: silence)."""
    srv = socket.create_server(("127.0.0.1", 0))

    def serve() -> None:
        with srv:
            conn, _ = srv.accept()
            with conn:
                conn.recv(64)
                if reply is not None:
                    conn.sendall(reply)
                time.sleep(hold_s)

    t = threading.Thread(target=serve, daemon=True)
    t.start()
    return srv.getsockname()[1], t


def test_reach_tells_a_grpc_server_from_a_silent_port_or_another_server():
    port, t = _serve_once(bytes([0, 0, 0, 4, 0, 0, 0, 0, 0]))  # an HTTP/2 SETTINGS frame
    parse_spec(f"ray:127.0.0.1:{port}").reach(timeout_s=2.0)
    t.join(5)
    port, t = _serve_once(b"HTTP/1.1 400 Bad Request\r\n\r\n")
    with pytest.raises(ExecutorError, match="the port answers, but not as a Ray"):
        parse_spec(f"ray:127.0.0.1:{port}").reach(timeout_s=2.0)
    t.join(5)
    port, t = _serve_once(None, hold_s=2.0)
    t0 = time.monotonic()
    with pytest.raises(ExecutorError, match=r"no Ray cluster answers .* \(timed out after 0.5 s"):
        parse_spec(f"ray:127.0.0.1:{port}").reach(timeout_s=0.5)
    assert time.monotonic() - t0 < 1.5
    t.join(5)
    parse_spec("process").reach()  # nothing to reach


# --------------------------------------------------------------------------- variants

MASSES = np.linspace(0.3, 2.0, 8)
LEG_SCALES = (0.7, 0.85, 1.0, 1.15, 1.3)


def test_a_variant_sweep_always_compiles_and_stands():
    """Torso mass 0.3-2.0 kg x leg length ±30 %: every variant compiles (0.45, 0.9, 1.8 kg
    used to break MuJoCo's A + B >= C) and stands; those of the shipped legs or mass also
    walk every gait."""
    for mass in [*MASSES, 0.45, 0.9, 1.8, 2.45]:
        for scale in LEG_SCALES:
            params = VariantParams(torso_mass_kg=float(mass), leg_length_m=0.07 * scale)
            model = mujoco.MjModel.from_xml_string(variant_xml(params))
            bot = check_stands(model)
            assert bot.upright() > 0.95, (mass, scale)
    for mass in (0.3, 0.9, 1.757):
        checked_variant(VariantParams(torso_mass_kg=mass))
    for scale in (0.7, 0.85, 1.15, 1.3):
        checked_variant(VariantParams(leg_length_m=0.07 * scale))


@settings(max_examples=60, deadline=None)
@given(diag=st.tuples(*[st.floats(1e-9, 1.0)] * 3), scale=st.floats(1e-3, 1e3))
def test_valid_inertia_satisfies_the_triangle_and_keeps_a_valid_one(diag, scale):
    d = valid_inertia(np.asarray(diag) * scale)
    for i in range(3):
        assert d[(i + 1) % 3] + d[(i + 2) % 3] >= d[i]
    shipped = np.array([0.0009, 0.0049, 0.0058])
    assert valid_inertia(shipped).tobytes() == shipped.tobytes()


def test_variant_cli_names_options_and_refuses_an_existing_file(tmp_path, capsys):
    out = tmp_path / "v.xml"
    code, err, _ = _run(["variant", "--torso-mass", "0.9", "--out", str(out)], capsys)
    assert code == 0, err
    first = out.read_bytes()
    code, err, _ = _run(["variant", "--torso-mass", "0.8", "--out", str(out)], capsys)
    assert code == 2 and f"--out {out}: the file exists; pass --force" in err
    assert out.read_bytes() == first
    code, err, _ = _run(["variant", "--torso-mass", "0.8", "--out", str(out), "--force"], capsys)
    assert code == 0, err
    assert out.read_bytes() != first
    code, err, _ = _run(["variant", "--servo-kp", "0", "--out", str(tmp_path / "w.xml")], capsys)
    assert code == 2 and "--servo-kp must be a finite number > 0, got 0" in err
    code, err, _ = _run(["variant", "--torso-mass", "2.0", "--leg-length", "0.091", "--out",
                         str(tmp_path / "w.xml")], capsys)  # fmt: skip
    assert code == 2 and "variant --torso-mass 2 --leg-length 0.091 cannot stand and walk" in err
    assert "torso_mass_kg" not in err and not (tmp_path / "w.xml").exists()
