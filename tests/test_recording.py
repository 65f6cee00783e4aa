"""Rerun recordings: the drawn geometry, and .rrd files that load back with what a robotics user
needs — both timelines, squares once, name and properties, poses, servos, contacts, rays, the
ghost, physics errors, a calibration without jumps, and the layout."""

from __future__ import annotations

import math
import os
import shlex
import subprocess
import sys
from collections import defaultdict
from pathlib import Path

import mujoco
import numpy as np
import pyarrow as pa
import pytest
import rerun as rr
from matplotlib.path import Path as PolyPath

from evolve import geometry
from evolve.codec import parse_chromosome
from evolve.interpreter import StepEvent, run
from evolve.settings import WorldSettings
from evolve.table import PAPER_TABLE
from evolve.world import TableWorld
from servo_mj.robot.gaits import GaitLibrary
from servo_mj.robot.settings import PhysicsSettings
from servo_mj.world.arena import ArenaSettings
from servobot.recording import (
    Recording,
    RecordingSettings,
    arena_to_m,
    dark_polygons,
    heading_to_yaw_rad,
    square_centre,
)
from servobot.recording.frames import bearing_dir, roll_pitch_deg, yaw_quat_xyzw
from servobot.recording.runs import step_time_s
from servobot.validation.lone import StartJob, run_start

REPO = Path(__file__).resolve().parents[1]
ROBOT = "/world/robots/servobot"

TINY_MJCF = """
<mujoco>
  <worldbody>
    <geom name="floor" type="plane" size="3 3 0.1"/>
    <body name="bot/" pos="1 1 0.1">
      <freejoint/>
      <body name="bot/torso">
        <geom type="box" size="0.14 0.06 0.01"/>
        <body name="bot/leg" pos="0.1 0.06 0">
          <joint name="hip" type="hinge" axis="0 0 1"/>
          <geom type="capsule" size="0.01 0.03" pos="0 0 -0.03"/>
          <geom type="cylinder" size="0.005 0.01"/>
          <geom type="sphere" size="0.01"/>
        </body>
      </body>
    </body>
    <body name="other" pos="2 2 0.1"><geom type="box" size="0.1 0.1 0.1"/></body>
  </worldbody>
</mujoco>
"""
"""A robot ``bot/`` with an attachment frame (``bot/``, no geoms), as dm_control attaches one."""

ALWAYS_GAIT_8 = "\n".join(["00 0100000 0100000 0100000 0100000"] * 16)
"""Every gene: loop forever, four times gait 8 (SPEC §4 text form)."""
ROTATE_THEN_STAND = "\n".join(
    ["01 0111000 0011100 0011100 0011100"] + ["01 0011100 0011100 0011100 0011100"] * 15
)
"""Gene 0: gait 14 (rotate right) once, then gait 7 (stand still); every other gene: stand."""


class Rrd:
    """A recording read back: rows, timelines and columns per entity, properties, blueprint."""

    def __init__(self, path: Path) -> None:
        reader = rr.chunk.RrdReader(path)
        self.rows: dict[str, int] = defaultdict(int)
        self.static: dict[str, int] = defaultdict(int)
        self.timelines: dict[str, set[str]] = defaultdict(set)
        self.chunks: dict[str, list] = defaultdict(list)
        for chunk in reader.stream().collect().stream():
            (self.static if chunk.is_static else self.rows)[chunk.entity_path] += chunk.num_rows
            self.timelines[chunk.entity_path].update(chunk.timeline_names)
            self.chunks[chunk.entity_path].append(chunk)
        self.blueprint: dict[str, dict[str, list]] = {}
        (bp,) = reader.blueprints()
        for chunk in reader.stream(store=bp).collect().stream():
            self.blueprint[chunk.entity_path] = _columns(chunk)

    def column(self, entity: str, column: str, order: str = "step") -> list:
        """Every temporal value of ``entity``'s ``column``, sorted by ``order`` (stable)."""
        out = []
        for chunk in self.chunks[entity]:
            if chunk.is_static:
                continue
            cols = _columns(chunk)
            out += list(zip(cols[order], cols[column], strict=True))
        return [v for _, v in sorted(out, key=lambda tv: tv[0])]

    def static_column(self, entity: str, column: str) -> list:
        cols = [_columns(c) for c in self.chunks[entity] if c.is_static]
        return [c[column] for c in cols if column in c][0]

    def texts(self, entity: str, column: str = "TextLog:text") -> list:
        """A text column, one string per row."""
        return [v[0] for v in self.column(entity, column)]

    def blueprint_value(self, suffix: str, column: str) -> list:
        (hit,) = self.blueprint_values(suffix, column)
        return hit

    def blueprint_values(self, suffix: str, column: str) -> list:
        """``column`` of every blueprint entity ending in ``suffix`` (e.g. one per view)."""
        return [v[column] for k, v in self.blueprint.items() if k.endswith(suffix) and column in v]


def _columns(chunk) -> dict[str, list]:
    rb = chunk.to_record_batch()
    names = rb.schema.names
    out = {}
    for n in names:
        if "RowId" in n:
            continue
        col = rb.column(names.index(n))  # durations and timestamps as integer nanoseconds
        out[n] = (col.cast("int64") if pa.types.is_temporal(col.type) else col).to_pylist()
    return out


def assert_provenance(rrd: Rrd, *, table, source: str, command: str, model=None) -> None:
    """The recording names its model (label, sha256), table (source, sha256) and command."""
    from servo_mj.robot.model import model_label, model_sha256
    from servobot.recording.provenance import table_sha256

    prop = rrd.static_column
    assert prop("/__properties/model", "label") == [[model_label(model)]]
    assert prop("/__properties/model", "sha256") == [[model_sha256(model)]]
    assert prop("/__properties/table", "source") == [[source]]
    assert prop("/__properties/table", "sha256") == [[table_sha256(table)]]
    assert prop("/__properties/command", "text") == [[command]]


# --------------------------------------------------------------------------- geometry
def test_frames_and_squares_hand_worked() -> None:
    assert arena_to_m(415.0, 252.0) == (4.15, 2.52)
    assert heading_to_yaw_rad(0.0) == pytest.approx(math.pi / 2)  # north = +y
    assert heading_to_yaw_rad(90.0) == pytest.approx(0.0)  # east = +x
    w = WorldSettings()
    assert square_centre(0, w) == (25.0, 25.0)
    assert square_centre(23, w) == (175.0, 125.0)  # i = 3, j = 2
    assert square_centre(99, w) == (475.0, 475.0)
    # Heading 0 (north) is a yaw of +90°: quaternion (0, 0, sin 45°, cos 45°).
    np.testing.assert_allclose(yaw_quat_xyzw([0.0])[0], [0, 0, math.sqrt(0.5), math.sqrt(0.5)])
    # Relative bearing +90° (clockwise) is the robot's right: −y in its frame.
    np.testing.assert_allclose(bearing_dir([0.0, 90.0]), [[1, 0], [0, -1]], atol=1e-12)
    # 10° about the forward axis lifts the left side (roll +10); 10° about the left axis
    # lowers the nose (pitch +10).
    s, c = math.sin(math.radians(5)), math.cos(math.radians(5))
    roll, pitch = roll_pitch_deg(np.array([[c, s, 0, 0], [c, 0, s, 0]]))
    np.testing.assert_allclose(roll, [10, 0], atol=1e-9)
    np.testing.assert_allclose(pitch, [0, 10], atol=1e-9)


def test_dark_area_matches_the_spec_cone_rule() -> None:
    w = WorldSettings()
    polys = dark_polygons(w)
    # Hand-worked: beyond the northern source's north edge (heading 330°) the dark triangle
    # reaches the north wall at x = 500 − 235·tan 30°.
    north = [p for p in polys if max(y for _, y in p) == pytest.approx(500.0)]
    assert len(north) == 1
    xs = sorted(x for x, y in north[0] if y == pytest.approx(500.0))
    assert xs[0] == pytest.approx(500.0 - 235.0 * math.tan(math.radians(30.0)))
    paths = [PolyPath(p) for p in polys]
    rng = np.random.default_rng(7)
    for x, y in rng.uniform(0.0, 500.0, size=(4000, 2)):
        dark = not any(geometry.lit(x, y, w))
        assert any(p.contains_point((x, y)) for p in paths) == dark, (x, y)


# --------------------------------------------------------------------------- a table run
def _events(max_steps: int, start=(250.0, 100.0, 0.0)) -> tuple[list[StepEvent], object]:
    bits = parse_chromosome(ALWAYS_GAIT_8)
    events: list[StepEvent] = []
    result = run(
        bits, TableWorld(PAPER_TABLE, *start), mode="coverage", max_steps=max_steps,
        on_event=events.append,
    )  # fmt: skip
    return events, result


@pytest.fixture(scope="module")
def table_rrd(tmp_path_factory) -> tuple[Rrd, list[StepEvent], object, Path]:
    """12 steps of gait 8 north from (250, 100), both as "physics" (with times) and "table"."""
    events, result = _events(12)
    model = mujoco.MjModel.from_xml_string(TINY_MJCF)
    data = mujoco.MjData(model)
    path = tmp_path_factory.mktemp("rrd") / "pop0" / "run3.rrd"
    with Recording(path, name="pop0/run3") as rec:
        rec.log_properties(chromosome={"text": ALWAYS_GAIT_8}, start={"x_cm": 250.0})
        rec.log_arena(WorldSettings())
        rec.log_robot_model(model, prefix="bot/")
        for k in range(30):
            mujoco.mj_step(model, data)
            rec.log_robot_state(data, t_s=data.time, step=k // 16)
        for world in ("physics", "table"):
            rec.log_start((250.0, 100.0, 0.0), world_name=world)
        for ev in events:
            rec.log_event(ev, world_name="physics", t_s=0.5 + 1.6 * ev.step)
            rec.log_event(ev, world_name="table", t_s=0.5 + 1.6 * ev.step)
        rec.log_error("PhysicsError: boom", step=12, t_s=0.5 + 1.6 * 12)
        assert not path.exists()  # written only on close
    return Rrd(path), events, result, path


def test_recording_holds_the_arena_the_robot_and_both_worlds(table_rrd) -> None:
    rrd, events, result, path = table_rrd
    for part in ("floor", "walls", "station", "lights", "squares", "kill_zone", "cones", "dark"):
        assert f"/world/arena/{part}" in rrd.static
    # One entity per body with geoms, one transform per frame; no attachment frame.
    bodies = {e.split("/")[-1] for e in rrd.rows if e.startswith(f"{ROBOT}/bodies/")}
    assert bodies == {"torso", "leg"}
    assert rrd.rows[f"{ROBOT}/bodies/torso"] == 30
    assert {f"{ROBOT}/bodies/leg/geoms/{k}" for k in range(3)} <= set(rrd.static)
    for world in ("physics", "table"):
        base = f"{ROBOT}/{world}"
        assert rrd.rows[f"{base}/pose"] == len(events)
        assert rrd.rows[f"/plots/power/servobot/{world}"] == len(events)
        assert rrd.rows[f"/plots/sensors/servobot/{world}/light_left"] == len(events)
        # Both timelines on everything that has both.
        for e in (f"{base}/pose", f"{base}/track", f"/log/servobot/{world}"):
            assert rrd.timelines[e] == {"step", "sim_time"}, e
    assert rrd.timelines[f"{ROBOT}/bodies/torso"] == {"step", "sim_time"}
    assert not list(path.parent.glob(".*"))  # no temporary file left behind
    umask = os.umask(0)
    os.umask(umask)
    assert path.stat().st_mode & 0o777 == 0o666 & ~umask  # the usual mode, not 0600


def test_squares_are_logged_once_when_reached(table_rrd) -> None:
    rrd, events, result, _ = table_rrd
    assert result.squares >= 2  # 12 × 11.4 cm north crosses squares: the test needs some
    want = [square_centre(e.new_square, WorldSettings()) for e in events if e.new_square >= 0]
    for world in ("physics", "table"):
        centres = rrd.column(f"{ROBOT}/{world}/squares", "Boxes3D:centers")
        assert [len(c) for c in centres] == [1] * result.squares  # one box per row
        got = [tuple(np.round(np.array(c[0][:2]) * 100, 6)) for c in centres]
        assert got == want
        steps = rrd.column(f"{ROBOT}/{world}/squares", "step")
        assert steps == [e.step for e in events if e.new_square >= 0]


def test_track_starts_at_the_start_and_has_no_empty_segment(table_rrd) -> None:
    rrd, events, _, _ = table_rrd
    strips = rrd.column(f"{ROBOT}/table/track", "LineStrips3D:strips")
    segs = np.array([s[0] for s in strips])  # (n, 2, 3)
    assert len(segs) == sum(1 for e in events if e.kind == "gait")  # every step moves north
    np.testing.assert_allclose(segs[0, 0, :2], [2.5, 1.0])
    np.testing.assert_allclose(segs[1:, 0], segs[:-1, 1])  # connected
    assert np.all(np.linalg.norm(segs[:, 1] - segs[:, 0], axis=1) > 0.05)


def test_poses_arrows_and_log_lines(table_rrd) -> None:
    rrd, events, _, _ = table_rrd
    tr = rrd.column(f"{ROBOT}/physics/pose", "Transform3D:translation")
    np.testing.assert_allclose([t[0][:2] for t in tr], [np.array(e.pose[:2]) / 100 for e in events])
    vec = rrd.static_column(f"{ROBOT}/physics/pose/heading", "Arrows3D:vectors")
    assert vec[0][0][0] > 0 and vec[0][0][1] == 0  # along the pose frame's x = the heading
    lines = rrd.texts("/log/servobot/table")
    assert len(lines) == len(events) and not any("gait -1" in line for line in lines)
    assert lines[0] == "step    1 gene 0 instr 0 gait: gait 8"
    levels = rrd.texts("/log/servobot/physics", "TextLog:level")
    assert levels.count("ERROR") == 1  # the physics error
    assert "PhysicsError: boom" in rrd.texts("/log/servobot/physics")


def test_name_and_properties(table_rrd) -> None:
    rrd, *_ = table_rrd
    assert rrd.static_column("/__properties", "RecordingInfo:name") == [["pop0/run3"]]
    assert rrd.static_column("/__properties/chromosome", "text") == [[ALWAYS_GAIT_8]]
    assert rrd.static_column("/__properties/start", "x_cm") == [[250.0]]


def test_blueprint_opens_expanded_on_the_step_timeline_with_trails(table_rrd) -> None:
    rrd, *_ = table_rrd
    # ``step``: the timeline both worlds share, played at 8 × 1.6 s a step = 5 steps a second.
    assert rrd.blueprint_value("time_panel", "TimePanelBlueprint:timeline") == [["step"]]
    assert rrd.blueprint_value("time_panel", "TimePanelBlueprint:fps") == [[pytest.approx(5.0)]]
    for panel in ("time_panel", "blueprint_panel", "selection_panel"):
        (state,) = [v for k, v in rrd.blueprint[f"/{panel}"].items() if k.endswith(":state")]
        assert np.ravel(state).tolist() == [3], panel  # PanelState.Expanded
    for world in ("physics", "table"):
        for part in ("track", "squares"):
            ranges = rrd.blueprint_values(
                f"/overrides/world/robots/servobot/{world}/{part}/visualizers",
                "VisibleTimeRanges:ranges",
            )
            assert len(ranges) == 2  # the arena and the follow view
            for r in ranges:
                assert {tr["timeline"] for tr in r[0]} == {"step", "sim_time"}
    # The robot's own state is not a trail: no override on its bodies.
    assert not [k for k in rrd.blueprint if "overrides/world/robots/servobot/bodies" in k]


def test_rerun_verifies_the_file(table_rrd) -> None:
    *_, path = table_rrd
    res = subprocess.run(
        [sys.executable, "-m", "rerun", "rrd", "verify", str(path)],
        capture_output=True, text=True, timeout=120,
    )  # fmt: skip
    if "unrecognized subcommand" in res.stderr:
        pytest.skip("this rerun has no `rrd verify`")
    assert res.returncode == 0, res.stderr[-2000:]


# --------------------------------------------------------------------------- physics runs
def _job(tmp: Path | None, bits: str, start, steps: int, physics=None) -> StartJob:
    return StartJob(
        index=0, bits=parse_chromosome(bits), start=start, table=np.asarray(PAPER_TABLE),
        world=WorldSettings(), arena=ArenaSettings(), physics=physics, max_steps=steps,
        rrd_path=None if tmp is None else str(tmp / "pop2" / "run0.rrd"),
    )  # fmt: skip


@pytest.fixture(scope="module")
def physics_rrd(tmp_path_factory) -> tuple[Rrd, dict]:
    """A noise-free validation run facing the north wall 40 cm away: rotate once, then stand."""
    tmp = tmp_path_factory.mktemp("phys")
    job = _job(tmp, ROTATE_THEN_STAND, (250.0, 460.0, 0.0), 6, PhysicsSettings(servo_noise_rad=0))
    out = run_start(job)
    assert out["error"] is None
    return Rrd(Path(job.rrd_path)), out


def test_recording_does_not_change_the_physics(tmp_path: Path) -> None:
    plain = run_start(_job(None, ALWAYS_GAIT_8, (300.0, 300.0, 45.0), 4))
    with_rrd = run_start(_job(tmp_path, ALWAYS_GAIT_8, (300.0, 300.0, 45.0), 4))
    for world in ("table", "physics"):
        np.testing.assert_array_equal(plain["tracks"][world], with_rrd["tracks"][world])


def test_validation_run_name_properties_and_timelines(physics_rrd) -> None:
    rrd, out = physics_rrd
    assert rrd.static_column("/__properties", "RecordingInfo:name") == [["pop2/run0"]]
    assert rrd.static_column("/__properties/start", "y_cm") == [[460.0]]
    assert rrd.static_column("/__properties/result", "physics_steps") == [[6]]
    f = rrd.static_column("/__properties/gait_table", "F_cm")[0]
    np.testing.assert_allclose(f, np.asarray(PAPER_TABLE)[:, 0])
    assert "01 0111000" in rrd.static_column("/__properties/chromosome", "text")[0][0]
    assert_provenance(rrd, table=PAPER_TABLE, source="array", command=shlex.join(sys.argv))
    # The table world's times are those of the same steps in physics.
    table_t = rrd.column(f"{ROBOT}/table/pose", "sim_time")
    steps = rrd.column(f"{ROBOT}/table/pose", "step")
    assert table_t == [round(step_time_s(s, PhysicsSettings()) * 1e9) for s in steps]
    phys_t = np.array(rrd.column(f"{ROBOT}/physics/pose", "sim_time")) / 1e9
    phys_s = rrd.column(f"{ROBOT}/physics/pose", "step")
    np.testing.assert_allclose(phys_t, [step_time_s(s, PhysicsSettings()) for s in phys_s])
    # Frames: the state after placing (step 0), then 16 frames per step.
    frame_steps = rrd.column(f"{ROBOT}/bodies/torso", "step")
    assert frame_steps == [0] + [s for s in range(1, 7) for _ in range(16)]
    assert not [e for e in rrd.rows if e.endswith("attachment_frame")]


def test_servo_targets_are_the_gait_frames_and_angles_follow(physics_rrd) -> None:
    rrd, _ = physics_rrd
    lib = GaitLibrary.load()
    want = np.vstack([np.zeros((1, 12)), lib.frames(14)] + [lib.frames(7)] * 5)  # rad
    for k, leg in enumerate(("LF", "LM", "LH", "RF", "RM", "RH")):
        vals = np.array(rrd.column(f"/plots/joints/servobot/{leg}", "Scalars:scalars"))
        np.testing.assert_allclose(vals[:, 0], np.degrees(want[:, 2 * k]), atol=1e-9)
        np.testing.assert_allclose(vals[:, 2], np.degrees(want[:, 2 * k + 1]), atol=1e-9)
        # The servos track their targets: within 10° at the end of every 100 ms frame.
        assert np.max(np.abs(vals[:, 1] - vals[:, 0])) < 10.0
        assert np.max(np.abs(vals[:, 3] - vals[:, 2])) < 10.0


def test_contacts_carry_the_robots_weight_and_it_stands_level(physics_rrd) -> None:
    rrd, _ = physics_rrd
    force = np.array(rrd.column("/plots/foot_force/servobot", "Scalars:scalars"))  # (n, 6) N
    weight = 1.0 * 9.81  # models/servobot: total mass 1.0 kg
    standing = force[-16:]  # the last step: gait 7, at rest
    np.testing.assert_allclose(standing.sum(axis=1), weight, rtol=0.02)
    assert (standing > 0).sum(axis=1).min() >= 3  # on at least three feet
    vectors = np.array(rrd.column(f"{ROBOT}/contacts", "Arrows3D:vectors")[-1])
    s = RecordingSettings()
    assert np.linalg.norm(vectors, axis=1).max() < s.force_max_length_m  # none clamped
    assert vectors[:, 2].sum() / s.force_scale_m_per_n == pytest.approx(weight, rel=0.02)
    att = np.array(rrd.column("/plots/attitude/servobot", "Scalars:scalars"))
    assert np.abs(att[-16:]).max() < 3.0  # roll and pitch, deg


def test_rays_end_on_the_wall_they_see(physics_rrd) -> None:
    rrd, _ = physics_rrd
    strips = rrd.column(f"{ROBOT}/rays", "LineStrips3D:strips")
    colors = rrd.column(f"{ROBOT}/rays", "LineStrips3D:colors")
    assert len(strips) == 7 and len(strips[0]) == 20  # step 0 and after each step; 2 × 10 rays
    ends = np.array([s[1] for s in strips[0]])
    hit = np.array([(c >> 24) & 0xFF for c in colors[0]]) > 200  # red rays hit within range
    assert hit.any()  # facing north, 40 cm from the wall: the fans see it
    np.testing.assert_allclose(ends[hit, 1], 5.0, atol=0.002)  # ending on the wall's face
    lengths = np.linalg.norm(ends - np.array([s[0] for s in strips[0]]), axis=1)
    assert lengths.max() <= 0.5 + 1e-6  # nothing drawn beyond the 50 cm range (float32)


def test_ghost_and_sensor_spans_sit_on_the_table_pose(physics_rrd) -> None:
    rrd, _ = physics_rrd
    base = f"{ROBOT}/table/pose/ghost"
    torso = rrd.static_column(f"{base}/torso", "Transform3D:translation")[0][0]
    assert abs(torso[0]) < 0.01 and abs(torso[1]) < 0.01 and 0.03 < torso[2] < 0.15
    assert any(e.startswith(f"{base}/torso/geoms/") for e in rrd.static)
    spans = rrd.column(f"{ROBOT}/table/pose/sensors", "LineStrips3D:strips")
    # 40 cm from the north wall, heading north: both object sensors see it at the start.
    assert len(spans[0]) >= 2


def test_a_physics_error_is_in_the_log(tmp_path, monkeypatch) -> None:
    from servo_mj.world import physics_world

    original = physics_world.PhysicsWorld.step

    def step(self, gait):
        if self.cycles == 1:
            self.data.qvel[0] = np.nan
        return original(self, gait)

    monkeypatch.setattr(physics_world.PhysicsWorld, "step", step)
    job = _job(tmp_path, ALWAYS_GAIT_8, (250.0, 250.0, 0.0), 5)
    out = run_start(job)
    assert "PhysicsError" in out["error"]
    rrd = Rrd(Path(job.rrd_path))
    levels = rrd.texts("/log/servobot/physics", "TextLog:level")
    text = rrd.texts("/log/servobot/physics")
    assert levels[-1] == "ERROR" and text[-1] == out["error"]
    assert rrd.column("/log/servobot/physics", "step")[-1] == 2  # the step that failed
    assert rrd.static_column("/__properties/result", "error") == [[out["error"]]]


# --------------------------------------------------------------------------- calibration
def test_calibration_walks_side_by_side_without_jumps(tmp_path) -> None:
    from calibration.calibrate import calibrate
    from calibration.measure import CalibrationSettings, start_pose
    from servobot.recording import calibration_recorder, log_calibration_result

    settings = CalibrationSettings(cycles=1, settle_cycles=1)
    path = tmp_path / "calibration.rrd"
    with Recording.for_calibration(path) as rec:
        res = calibrate(tmp_path, settings, **calibration_recorder(rec, settings))
        log_calibration_result(rec, res)
    rrd = Rrd(path)
    assert {"/world/arena/floor", "/world/arena/grid", "/world/arena/starts"} <= set(rrd.static)
    for g in range(16):
        torso = f"/world/robots/gait_{g:02d}/bodies/torso"
        assert rrd.timelines[torso] == {"sim_time", "cycle"}
        pos = np.array([p[0] for p in rrd.column(torso, "Transform3D:translation", "sim_time")])
        assert len(pos) == 32  # 2 cycles × 16 frames
        np.testing.assert_allclose(pos[0, :2], np.array(start_pose(g)[:2]) / 100, atol=0.05)
        assert np.linalg.norm(np.diff(pos, axis=0), axis=1).max() < 0.03  # no jump, m/frame
        assert rrd.rows[f"/plots/calibration/F/gait_{g:02d}"] == 1
    np.testing.assert_allclose(rrd.static_column("/__properties/result", "F_cm")[0],
                               res.values[:, 0])  # fmt: skip
    assert_provenance(rrd, table=res.values, source=str(res.table_path),
                      command=shlex.join(sys.argv))  # fmt: skip
    # The settings name the model (not a bare None, which the viewer shows as "null").
    assert "shipped ServoBot" in rrd.static_column("/__properties/calibration", "model")[0][0]
    # One world: the time panel opens on the smooth ``sim_time``; a tab per gait.
    assert rrd.blueprint_value("time_panel", "TimePanelBlueprint:timeline") == [["sim_time"]]
    tabs = {v[0][0] for v in rrd.blueprint_values("", "ContainerBlueprint:display_name")}
    assert {f"gait {g}" for g in range(16)} <= tabs


# --------------------------------------------------------------------------- display rules
def test_force_arrows_scale_then_clamp_keeping_the_direction() -> None:
    from servobot.recording.robot import force_arrows

    f = np.array([[0.0, 0.0, 2.0], [3.0, 4.0, 0.0], [0.0, 0.0, 0.0], [-2770.0, 0.0, 0.0]])
    a = force_arrows(f, 0.02, 0.10)
    np.testing.assert_allclose(a[0], [0.0, 0.0, 0.04])  # 2 N: 4 cm
    np.testing.assert_allclose(a[1], [0.06, 0.08, 0.0])  # 5 N: exactly the 10 cm bound
    np.testing.assert_allclose(a[2], 0.0)
    np.testing.assert_allclose(a[3], [-0.10, 0.0, 0.0])  # 2770 N (a colony run): 10 cm


def test_plots_split_into_runs_of_at_most_the_bound() -> None:
    from servobot.recording.blueprint import chunks

    assert chunks(list(range(6)), 6) == [list(range(6))]
    assert chunks(list(range(7)), 6) == [[0, 1, 2, 3], [4, 5, 6]]
    assert chunks(list(range(16)), 6) == [list(range(6)), list(range(6, 11)), list(range(11, 16))]
    assert chunks([], 6) == []


def test_blueprint_plots_hold_few_series_and_follow_each_robot() -> None:
    from servobot.recording.blueprint import Contents, make_blueprint, playback_fps

    c = Contents(timelines={"sim_time", "step", "colony_step"}, colony=True, detail=True)
    for i in range(5):
        c.robots.append(f"robot{i}")
        c.follow.add(f"robot{i}")
        c.worlds += [(f"robot{i}", "table"), (f"robot{i}", "physics")]
    s = RecordingSettings()
    assert playback_fps(c, s) == pytest.approx(8.0 / (1.6 * 5))  # a colony step: 5 turns
    path = Path(os.environ.get("TMPDIR", "/tmp")) / f"bp_{os.getpid()}.rrd"
    make_blueprint(c, s).save("servobot-test", str(path))
    try:
        reader = rr.chunk.RrdReader(path)
        (bp,) = reader.blueprints()
        views = {}
        for chunk in reader.stream(store=bp).collect().stream():
            cols = _columns(chunk)
            if "ViewBlueprint:class_identifier" in cols:
                views.setdefault(chunk.entity_path, {}).update(cols)
            elif "ViewContents:query" in cols:
                views.setdefault(chunk.entity_path.rsplit("/", 1)[0], {}).update(cols)
    finally:
        path.unlink(missing_ok=True)
    names = {v["ViewBlueprint:display_name"][0][0]: v for v in views.values()
             if "ViewBlueprint:display_name" in v}  # fmt: skip
    assert {f"follow robot{i}" for i in range(5)} <= set(names)
    follow = names["follow robot3"]
    assert follow["ViewBlueprint:space_origin"] == [["world/robots/robot3/follow"]]
    # Power of 5 robots × 2 worlds: one plot per world, 5 series each.
    power = [n for n in names if n.startswith("power")]
    assert sorted(power) == ["power (V), physics", "power (V), table"]
    for n in power:
        (query,) = names[n]["ViewContents:query"]
        assert len(query) == 5 <= s.max_plot_series


# --------------------------------------------------------------------------- API
def test_buffers_flush_in_pieces_without_loss(tmp_path: Path) -> None:
    path = tmp_path / "calib.rrd"
    model = mujoco.MjModel.from_xml_string(TINY_MJCF)
    data = mujoco.MjData(model)
    with Recording(path, settings=RecordingSettings(max_buffer_rows=7)) as rec:
        for gait in (3, 15):
            for cycle in range(4):
                rec.log_calibration_cycle(gait, cycle, 8.4, -4.3, -15.8, t_s=1.6 * cycle)
        rec.log_robot_model(model, prefix="bot/")
        for _ in range(20):  # 20 frames through a 7-row buffer: flushed in pieces, none lost
            mujoco.mj_step(model, data)
            rec.log_robot_state(data, t_s=data.time)
    rrd = Rrd(path)
    for comp in ("F", "T", "dH"):
        assert rrd.rows[f"/plots/calibration/{comp}/gait_03"] == 4
        assert rrd.rows[f"/plots/calibration/{comp}/gait_15"] == 4
    assert rrd.timelines["/plots/calibration/F/gait_03"] == {"cycle", "sim_time"}
    assert rrd.rows["/log/calibration"] == 8
    assert rrd.rows[f"{ROBOT}/bodies/torso"] == 20
    t = rrd.column(f"{ROBOT}/bodies/torso", "sim_time", order="sim_time")
    assert t == sorted(set(t))


def test_two_robots_share_one_recording(tmp_path: Path) -> None:
    """Colony use: each robot has its own bodies, colour, tracks, plots and log."""
    model = mujoco.MjModel.from_xml_string(TINY_MJCF)
    data = mujoco.MjData(model)
    events, _ = _events(3)
    path = tmp_path / "colony.rrd"
    with Recording(path) as rec:
        rec.log_arena(WorldSettings())
        for name, color in (("r0", (200, 0, 0)), ("r1", (0, 0, 200))):
            rec.log_robot_model(model, prefix="bot/", robot=name, color=color)
            rec.log_robot_state(data, t_s=0.0, step=0, robot=name)
            for ev in events:
                rec.log_event(ev, t_s=1.6 * ev.step, robot=name)
    rrd = Rrd(path)
    for name, color in (("r0", (200, 0, 0)), ("r1", (0, 0, 200))):
        assert rrd.rows[f"/world/robots/{name}/bodies/torso"] == 1
        assert rrd.rows[f"/log/{name}/physics"] == len(events)
        assert rrd.rows[f"/plots/power/{name}/physics"] == len(events)
        rgba = rrd.static_column(f"/world/robots/{name}/physics/track", "LineStrips3D:colors")
        assert rgba[0][0] >> 8 == (color[0] << 16) | (color[1] << 8) | color[2]
        assert all(rrd.blueprint_values(
            f"/overrides/world/robots/{name}/physics/track/visualizers", "VisibleTimeRanges:ranges"
        ))  # fmt: skip


def test_failed_run_leaves_no_file(tmp_path: Path) -> None:
    path = tmp_path / "broken.rrd"
    with pytest.raises(RuntimeError), Recording(path) as rec:
        rec.log_arena(WorldSettings())
        raise RuntimeError("physics blew up")
    assert not path.exists()
    assert list(tmp_path.iterdir()) == []


def test_bad_calls_are_named(tmp_path: Path) -> None:
    events, _ = _events(3)
    with pytest.raises(ValueError, match="t_s"), Recording(tmp_path / "mixed.rrd") as rec:
        rec.log_event(events[0], world_name="physics", t_s=1.6)
        rec.log_event(events[1], world_name="physics")
    with pytest.raises(ValueError, match="log_robot_model"), Recording(tmp_path / "x.rrd") as rec:
        rec.log_robot_state(mujoco.MjData(mujoco.MjModel.from_xml_string(TINY_MJCF)), t_s=0.0)
    assert not list(tmp_path.iterdir())


def test_servobot_model_bodies_are_recorded(tmp_path: Path) -> None:
    model = mujoco.MjModel.from_xml_path(str(REPO / "models" / "servobot" / "servobot.xml"))
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    path = tmp_path / "bot.rrd"
    with Recording(path) as rec:
        rec.log_robot_model(model)
        rec.log_robot_state(data, t_s=0.0)
    rrd = Rrd(path)
    with_geoms = {
        rr.escape_entity_path_part(mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_BODY, b))
        for b in range(1, model.nbody) if model.body_geomnum[b] > 0
    }  # fmt: skip
    recorded = {e.split("/")[-1] for e in rrd.rows if e.startswith(f"{ROBOT}/bodies/")}
    assert recorded == with_geoms and len(recorded) == 13
    assert all(any(s.startswith(f"{ROBOT}/bodies/{b}/geoms/") for s in rrd.static)
               for b in with_geoms)  # fmt: skip
