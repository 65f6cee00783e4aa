"""Rerun recordings: geometry of the drawn arena, and .rrd files that load back complete."""

from __future__ import annotations

import math
import os
from pathlib import Path

import mujoco
import numpy as np
import pytest
import rerun as rr
from matplotlib.path import Path as PolyPath

from evolve import geometry
from evolve.codec import parse_chromosome
from evolve.interpreter import StepEvent, run
from evolve.settings import WorldSettings
from evolve.table import PAPER_TABLE
from evolve.world import TableWorld
from servobot.recording import (
    Recording,
    arena_to_m,
    dark_polygons,
    heading_to_yaw_rad,
    square_centre,
)

REPO = Path(__file__).resolve().parents[1]

TINY_MJCF = """
<mujoco>
  <worldbody>
    <geom name="floor" type="plane" size="3 3 0.1"/>
    <body name="bot/torso" pos="1 1 0.1">
      <freejoint/>
      <geom type="box" size="0.14 0.06 0.01"/>
      <body name="bot/leg" pos="0.1 0.06 0">
        <joint name="hip" type="hinge" axis="0 0 1"/>
        <geom type="capsule" size="0.01 0.03" pos="0 0 -0.03"/>
        <geom type="cylinder" size="0.005 0.01"/>
        <geom type="sphere" size="0.01"/>
      </body>
    </body>
    <body name="other" pos="2 2 0.1"><geom type="box" size="0.1 0.1 0.1"/></body>
  </worldbody>
</mujoco>
"""

ALWAYS_GAIT_8 = "\n".join(["00 0100000 0100000 0100000 0100000"] * 16)
"""Every gene: loop forever, four times gait 8 (SPEC §4 text form)."""


def _load(path: Path) -> tuple[dict[str, int], dict[str, int], dict[str, set[str]], int]:
    """Temporal rows, static rows and timelines per entity, and the number of blueprints."""
    reader = rr.chunk.RrdReader(path)
    rows: dict[str, int] = {}
    static: dict[str, int] = {}
    timelines: dict[str, set[str]] = {}
    for chunk in reader.stream().collect().stream():
        target = static if chunk.is_static else rows
        target[chunk.entity_path] = target.get(chunk.entity_path, 0) + chunk.num_rows
        timelines.setdefault(chunk.entity_path, set()).update(chunk.timeline_names)
    return rows, static, timelines, len(reader.blueprints())


def _column(path: Path, entity: str, column: str) -> list:
    """All temporal values of ``entity``'s ``column`` (e.g. "Scalars:scalars"), in step order."""
    out: list[tuple[int, object]] = []
    for chunk in rr.chunk.RrdReader(path).stream().collect().stream():
        if chunk.entity_path != entity or chunk.is_static:
            continue
        rb = chunk.to_record_batch()
        steps = rb.column(rb.schema.names.index("step")).to_pylist()
        vals = rb.column(rb.schema.names.index(column)).to_pylist()
        out += list(zip(steps, vals, strict=True))
    return [v for _, v in sorted(out, key=lambda sv: sv[0])]


def test_frames_and_squares_hand_worked() -> None:
    assert arena_to_m(415.0, 252.0) == (4.15, 2.52)
    assert heading_to_yaw_rad(0.0) == pytest.approx(math.pi / 2)  # north = +y
    assert heading_to_yaw_rad(90.0) == pytest.approx(0.0)  # east = +x
    w = WorldSettings()
    assert square_centre(0, w) == (25.0, 25.0)
    assert square_centre(23, w) == (175.0, 125.0)  # i = 3, j = 2
    assert square_centre(99, w) == (475.0, 475.0)


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


def _events(max_steps: int) -> tuple[list[StepEvent], object]:
    bits = parse_chromosome(ALWAYS_GAIT_8)
    events: list[StepEvent] = []
    result = run(
        bits,
        TableWorld(PAPER_TABLE, 250.0, 100.0, 0.0),
        mode="coverage",
        max_steps=max_steps,
        on_event=events.append,
    )
    return events, result


def test_recording_loads_back_with_expected_entities(tmp_path: Path) -> None:
    model = mujoco.MjModel.from_xml_string(TINY_MJCF)
    data = mujoco.MjData(model)
    events, result = _events(12)
    assert result.squares >= 2  # 12 × 11.4 cm north crosses squares: the test needs some
    n_frames = 30
    path = tmp_path / "run.rrd"
    with Recording(path) as rec:
        rec.log_arena(WorldSettings())
        rec.log_robot_model(model, prefix="bot/")
        for _ in range(n_frames):
            mujoco.mj_step(model, data)
            rec.log_robot_state(data, t_s=data.time, prefix="bot/")
            rec.log_feet(data.time, np.zeros((6, 3)))
        for k, ev in enumerate(events):
            rec.log_event(ev, world_name="physics", t_s=1.6 * k)
            rec.log_event(ev, world_name="table")
        assert not path.exists()  # written only on close
    rows, static, timelines, blueprints = _load(path)
    assert blueprints == 1
    for part in ("floor", "walls", "station", "lights", "squares", "kill_zone", "cones", "dark"):
        assert f"/world/arena/{part}" in static
    # Robot: one entity per body of the prefix, one transform per frame; shapes static.
    assert rows["/world/robot/torso"] == n_frames
    assert rows["/world/robot/leg"] == n_frames
    assert "/world/robot/other" not in rows
    assert {f"/world/robot/leg/geoms/{k}" for k in range(3)} <= set(static)
    assert rows["/world/feet"] == n_frames
    for world in ("physics", "table"):
        assert rows[f"/world/track/{world}"] == len(events)
        assert rows[f"/plots/power/{world}"] == len(events)
        assert rows[f"/log/{world}"] == len(events)
        for sensor in ("object_right", "object_left", "low_power", "light_right", "light_left"):
            assert rows[f"/plots/sensors/{world}/{sensor}"] == len(events)
        # One row each time a square is first reached.
        assert rows[f"/world/squares/{world}"] == result.squares
        assert rows[f"/plots/pose/{world}/heading_deg"] == len(events)
    # Values survive the round trip: power per event, and the squares reached, in metres.
    power = _column(path, "/plots/power/table", "Scalars:scalars")
    assert [p[0] for p in power] == pytest.approx([e.power for e in events])
    reached = _column(path, "/world/squares/physics", "Boxes3D:centers")
    want = [square_centre(e.new_square, WorldSettings()) for e in events if e.new_square >= 0]
    assert [tuple(np.round(np.array(c[-1][:2]) * 100, 6)) for c in reached] == want
    assert [len(c) for c in reached] == list(range(1, len(want) + 1))  # accumulating
    assert timelines["/world/track/physics"] == {"step", "sim_time"}
    assert timelines["/world/track/table"] == {"step"}
    assert timelines["/world/robot/torso"] == {"sim_time"}
    assert not list(tmp_path.glob(".*"))  # no temporary file left behind
    umask = os.umask(0)
    os.umask(umask)
    assert path.stat().st_mode & 0o777 == 0o666 & ~umask  # the usual mode, not 0600


def test_calibration_cycles_and_buffer_flushes(tmp_path: Path) -> None:
    from servobot.recording import RecordingSettings

    path = tmp_path / "calib.rrd"
    model = mujoco.MjModel.from_xml_string(TINY_MJCF)
    data = mujoco.MjData(model)
    with Recording(path, settings=RecordingSettings(max_buffer_rows=7)) as rec:
        for gait in (3, 15):
            for cycle in range(4):
                rec.log_calibration_cycle(gait, cycle, 8.4, -4.3, -15.8, t_s=1.6 * cycle)
        for _ in range(20):  # 20 frames through a 7-row buffer: flushed in pieces, none lost
            mujoco.mj_step(model, data)
            rec.log_robot_state(data, t_s=data.time, prefix="bot/")
    rows, _, timelines, _ = _load(path)
    for comp in ("F", "T", "dH"):
        assert rows[f"/plots/calibration/{comp}/gait_3"] == 4
        assert rows[f"/plots/calibration/{comp}/gait_15"] == 4
    assert timelines["/plots/calibration/F/gait_3"] == {"cycle", "sim_time"}
    assert rows["/log/calibration"] == 8
    assert rows["/world/robot/torso"] == 20


def test_failed_run_leaves_no_file(tmp_path: Path) -> None:
    path = tmp_path / "broken.rrd"
    with pytest.raises(RuntimeError), Recording(path) as rec:
        rec.log_arena(WorldSettings())
        raise RuntimeError("physics blew up")
    assert not path.exists()
    assert list(tmp_path.iterdir()) == []


def test_servobot_model_bodies_are_recorded(tmp_path: Path) -> None:
    xml = REPO / "models" / "servobot" / "servobot.xml"
    if not xml.exists():
        pytest.skip("models/servobot/servobot.xml not present")
    model = mujoco.MjModel.from_xml_path(str(xml))
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    path = tmp_path / "bot.rrd"
    with Recording(path) as rec:
        rec.log_robot_model(model)
        rec.log_robot_state(data, t_s=0.0)
    rows, static, _, _ = _load(path)
    bodies = {mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_BODY, b) for b in range(1, model.nbody)}
    recorded = {e.split("/")[3] for e in rows if e.startswith("/world/robot/")}
    assert len(recorded) == model.nbody - 1
    assert all(rr.escape_entity_path_part(b) in recorded for b in bodies if b)
    # Every body with a drawable geom carries at least one static shape.
    assert any(e.startswith("/world/robot/") and "/geoms/" in e for e in static)


def test_mixed_sim_time_in_one_world_is_refused(tmp_path: Path) -> None:
    events, _ = _events(3)
    with pytest.raises(ValueError, match="t_s"), Recording(tmp_path / "mixed.rrd") as rec:
        rec.log_event(events[0], world_name="physics", t_s=1.6)
        rec.log_event(events[1], world_name="physics")
    assert not (tmp_path / "mixed.rrd").exists()
