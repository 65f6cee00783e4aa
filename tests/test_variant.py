"""Robot variants: built from the shipped model, recording their parameters, walking as the
physics says (heavier torso turns less, longer legs stride further, the default variant is the
shipped robot), through calibration, the arena, validation and the whole pipeline."""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path

import mujoco
import numpy as np
import pytest
from chromosome_text import chrom

from calibration.measure import measure_gait
from evolve.codec import write_chromosome
from evolve.table import load_table
from infra.errors import InputError
from servo_mj.robot import constants as C
from servo_mj.robot.model import load_robot, model_sha256
from servo_mj.robot.variant import (
    FIELDS,
    VariantError,
    VariantParams,
    build_variant,
    read_variant,
    variant_params,
    write_variant,
)
from servo_mj.world.arena import default_robot
from servo_mj.world.physics_world import PhysicsWorld
from servobot.cli import main as servobot
from servobot.reproduce.run import ReproduceSettings, reproduce
from servobot.validation.lone import ValidationError, load_checked_table

HEAVY = VariantParams(torso_mass_kg=1.14)
"""The issue's example: the torso 50 % heavier."""


@pytest.fixture(scope="module")
def files(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    d = tmp_path_factory.mktemp("variants")
    return {
        "default": write_variant(VariantParams(), d / "default.xml"),
        "heavy": write_variant(HEAVY, d / "heavy.xml"),
    }


def _shipped_values() -> dict[str, float]:
    """The parameters as the shipped MJCF states them (independent of ``VariantParams``)."""
    m, _ = load_robot()
    foot = m.geom(f"{C.LEGS[0]}_foot")  # in the leg body, whose origin is on the thrust axis
    return {
        "torso_mass_kg": float(m.body(C.TORSO).mass[0]),
        "leg_length_m": float(np.hypot(foot.pos[0], foot.pos[1])),
        "servo_torque_nm": float(m.actuator_forcerange[0, 1]),
        "servo_kp": float(m.actuator_gainprm[0, 0]),
        "foot_friction": float(foot.friction[0]),
        "floor_friction": float(m.geom("floor").friction[0]),
    }


def test_defaults_are_the_shipped_model() -> None:
    shipped = _shipped_values()
    assert VariantParams().to_dict() == pytest.approx({k: shipped[k] for k in FIELDS})


def test_a_variant_file_round_trips_its_parameters(tmp_path: Path) -> None:
    params = VariantParams(1.3, 0.08, 0.4, 7.5, 1.2, 0.9)
    path = write_variant(params, tmp_path / "v.xml")
    assert read_variant(path) == params
    assert read_variant(C.SCENE_XML) is None  # the shipped scene records none
    assert params.changed() == params.to_dict()  # every value differs from the shipped one
    # the values are applied where they belong, not only recorded
    m = mujoco.MjModel.from_xml_path(str(path))
    assert m.body(C.TORSO).mass[0] == params.torso_mass_kg
    assert np.all(m.actuator_forcerange[:, 1] == params.servo_torque_nm)
    assert np.all(m.actuator_gainprm[:, 0] == params.servo_kp)
    assert m.geom("floor").friction[0] == params.floor_friction
    assert m.geom("LF_foot").friction[0] == params.foot_friction
    assert abs(m.geom("LF_foot").pos[1]) == pytest.approx(params.leg_length_m)
    # ... and the CLI shows them back
    assert servobot(["variant", "--show", str(path)]) == 0


def test_default_variant_is_the_shipped_robot_bit_for_bit(files) -> None:
    for g in (2, 15):
        shipped = measure_gait(g, cycles=2, seed=5)
        variant = measure_gait(g, cycles=2, seed=5, model_file=files["default"])
        np.testing.assert_array_equal(variant, shipped)


def test_heavier_torso_turns_less(files) -> None:
    """Issue 10: with the torso 50 % heavier the interruption turns lose turn rate."""
    for g in (3, 11):
        shipped = measure_gait(g, cycles=3, noise_rad=0.0)[:, 2].mean()
        heavy = measure_gait(g, cycles=3, noise_rad=0.0, model_file=files["heavy"])[:, 2].mean()
        assert abs(heavy) < abs(shipped) - 1.0, (g, shipped, heavy)


def test_longer_legs_stride_further(tmp_path: Path) -> None:
    """Same sweep angles, feet further from the thrust axes: a longer straight step."""
    long_legs = write_variant(VariantParams(leg_length_m=0.085), tmp_path / "long.xml")
    shipped = measure_gait(0, cycles=2, noise_rad=0.0)[:, 0].mean()
    longer = measure_gait(0, cycles=2, noise_rad=0.0, model_file=long_legs)[:, 0].mean()
    assert longer > shipped * 1.1


@pytest.mark.parametrize(
    ("params", "message"),
    [
        ({"torso_mass_kg": -1.0}, "torso_mass_kg must be > 0"),
        ({"servo_kp": float("nan")}, "servo_kp must be a finite number"),
        ({"servo_torque_nm": 0.005}, "torso touches the floor while walking"),
        ({"leg_length_m": 0.005}, "torso touches the floor after settling"),
    ],
)
def test_impossible_variants_are_refused_and_nothing_is_written(tmp_path, params, message) -> None:
    out = tmp_path / "bad.xml"
    with pytest.raises(VariantError, match=message):
        write_variant(VariantParams(**params), out)
    assert not out.exists()


def test_variant_cli_writes_and_rejects(tmp_path: Path, capsys) -> None:
    out = tmp_path / "v.xml"
    assert servobot(["variant", "--leg-length", "0.08", "--out", str(out)]) == 0
    assert read_variant(out) == VariantParams(leg_length_m=0.08)
    assert servobot(["variant", "--torso-mass", "0", "--out", str(tmp_path / "x.xml")]) == 2
    assert "--torso-mass must be a finite number > 0, got 0" in capsys.readouterr().err


def test_a_variant_walks_in_the_colony_arena(files) -> None:
    spec = default_robot(files["heavy"])
    pw = PhysicsWorld(400.0, 250.0, 270.0, robot=spec)
    assert variant_params(pw.model, pw.prefix) == HEAVY
    assert pw.model.body(pw.prefix + C.TORSO).mass[0] == HEAVY.torso_mass_kg
    assert pw.model.geom("floor").friction[0] == HEAVY.floor_friction
    x0, y0, _ = pw.pose()
    pw.step(0)
    x1, y1, _ = pw.pose()
    assert x1 < x0 - 5.0 and abs(y1 - y0) < 3.0  # facing west, one forward cycle


def test_mjcf_built_not_text_substituted() -> None:
    """The variant is the shipped model's element tree with attributes changed."""
    root = build_variant(HEAVY)
    assert root.find("body", C.TORSO).inertial.mass == HEAVY.torso_mass_kg
    assert root.find("geom", "floor") is not None  # a complete scene


@pytest.fixture(scope="module")
def heavy_table(files, tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("cal_heavy")
    args = ["calibrate", "--model", str(files["heavy"]), "--cycles", "1", "--workers", "1"]
    assert servobot([*args, "--out", str(out)]) == 0
    return out / "gait_table.json"


def test_calibrate_model_records_the_model_and_its_parameters(files, heavy_table) -> None:
    doc = json.loads(heavy_table.read_text())
    assert doc["model_sha256"] == model_sha256(files["heavy"]) != model_sha256()
    assert doc["model"] == str(files["heavy"])
    assert doc["variant"] == HEAVY.to_dict() and doc["changed"] == {"torso_mass_kg": 1.14}
    assert doc["calibration"]["model"] == str(files["heavy"])
    table = load_table(heavy_table)
    assert table.energy is not None and table.dv.shape == (16,)


def test_a_table_of_another_model_is_refused_naming_both(files, heavy_table) -> None:
    with pytest.raises(ValidationError) as err:
        load_checked_table(str(heavy_table))  # heavy table, shipped robot
    msg = str(err.value)
    assert str(files["heavy"]) in msg and "shipped ServoBot" in msg and model_sha256() in msg
    with pytest.raises(ValidationError, match="calibrated on another robot model"):
        load_checked_table(str(heavy_table), files["default"])
    table, warning = load_checked_table(str(heavy_table), files["heavy"])
    assert warning is None and table.meta["variant"]["torso_mass_kg"] == 1.14


def test_validate_cli_refuses_a_mismatched_model(files, heavy_table, tmp_path, capsys) -> None:
    path = tmp_path / "c.txt"
    write_chromosome(path, chrom())
    args = ["validate", str(path), "--table", str(heavy_table), "--starts", "1"]
    assert servobot([*args, "--model", str(files["default"]), "--out", str(tmp_path)]) == 2
    err = capsys.readouterr().err
    assert "calibrated on another robot model" in err and str(files["default"]) in err


def test_reproduce_model_runs_the_whole_pipeline_for_the_variant(files, tmp_path) -> None:
    settings = ReproduceSettings(
        calibration_cycles=1, calibration_settle_cycles=0, navigation_populations=1,
        navigation_population_size=6, navigation_generations=2, coverage_populations=1,
        coverage_population_size=6, coverage_generations=2, test_starts=2, validate_starts=1,
        validate_max_steps=4, seed=1, model=str(files["heavy"]),
    )  # fmt: skip
    out = tmp_path / "run"
    res = reproduce(out, settings=settings, workers=1, log=lambda _m: None)
    assert set(res["stages"]) == {
        "calibration", "navigation", "coverage", "validation", "robustness",
    }  # fmt: skip
    assert "not run" in res["stages"]["robustness"]["note"]  # its worlds vary the shipped robot
    assert not (out / "robustness" / "robustness.json").exists()
    doc = json.loads((out / "calibration" / "gait_table.json").read_text())
    assert doc["model_sha256"] == model_sha256(files["heavy"])
    assert doc["variant"] == HEAVY.to_dict()
    rep = json.loads((out / "validation" / "pop0" / "report.json").read_text())
    assert rep["settings"]["model_sha256"] == model_sha256(files["heavy"])
    assert rep["summary"]["physics_errors"] == 0
    assert f"Robot: {files['heavy']}" in (out / "REPORT.md").read_text()
    # the folder belongs to this model: the shipped robot may not resume into it
    shipped = dataclasses.replace(settings, model=None)
    with pytest.raises(InputError, match="other settings"):
        reproduce(out, settings=shipped, workers=1, log=lambda _m: None)


def test_fit_on_a_variant_never_replaces_the_shipped_parameters(files, tmp_path) -> None:
    from servo_mj.robot.gaits import PARAMS_JSON

    shipped = PARAMS_JSON.read_bytes()
    args = ["calibrate", "--model", str(files["heavy"]), "--fit", "--fit-evals", "1"]
    assert servobot([*args, "--cycles", "1", "--workers", "1", "--out", str(tmp_path)]) == 0
    assert PARAMS_JSON.read_bytes() == shipped
    fitted = json.loads((tmp_path / "gait_params.json").read_text())
    assert fitted["model_sha256"] == model_sha256(files["heavy"])
