"""The physics world: its sensors agree with the SPEC's geometric sensors, and a hand-written
controller run by the one interpreter behaves alike in the table world and in physics."""

from __future__ import annotations

import math

import mujoco
import numpy as np
import pytest

from evolve import geometry
from evolve.codec import parse_chromosome
from evolve.interpreter import END_STEP_LIMIT, run
from evolve.settings import WorldSettings
from evolve.table import PAPER_TABLE
from evolve.world import TableWorld
from servo_mj.robot.bot import displacement
from servo_mj.world.arena import ArenaSettings
from servo_mj.world.physics_world import PhysicsWorld

W = WorldSettings()


def wall_distance_ahead(x: float, y: float, h: float) -> float:
    """Distance (cm) from (x, y) to the arena edge straight along heading h (no station)."""
    dx, dy = math.sin(math.radians(h)), math.cos(math.radians(h))
    ts = []
    for pos, d in ((x, dx), (y, dy)):
        if d > 1e-12:
            ts.append((W.arena_size - pos) / d)
        elif d < -1e-12:
            ts.append(-pos / d)
    return min(ts)


# --------------------------------------------------------------------------- object sensors
@pytest.mark.parametrize(
    ("pose", "expected"),
    [
        ((460.0, 100.0, 90.0), (True, True)),  # facing the east wall at 40 cm: both spans
        ((440.0, 100.0, 90.0), (False, False)),  # at 60 cm: neither
        ((100.0, 453.0, 330.0), (False, True)),  # north wall 47 cm off at −30°: right span only
        ((100.0, 453.0, 30.0), (True, False)),  # mirrored: north wall at +30°, left span only
        ((250.0, 250.0, 0.0), (False, False)),  # open middle
        ((40.0, 40.0, 225.0), (True, True)),  # SW corner, walls 40 cm away at ±45°
        ((60.0, 60.0, 225.0), (False, False)),  # walls 60 cm away: nearest rays at ±40° too far
    ],
)
def test_object_sensors_hand_worked_poses(pose, expected):
    pw = PhysicsWorld(*pose)
    x, y, h = pw.pose()
    assert abs(x - pose[0]) < 1.0 and abs(y - pose[1]) < 1.0
    assert pw.object_sensors() == expected
    assert geometry.object_sensors(x, y, h, W) == expected


def test_rays_pass_over_the_low_station_block_and_a_tall_one_is_seen():
    # 40 cm from the block's face, 60 from the wall behind it.
    pw = PhysicsWorld(440.0, 250.0, 90.0)
    assert pw.object_sensors() == geometry.object_sensors(*pw.pose(), W) == (False, False)
    tall = PhysicsWorld(440.0, 250.0, 90.0, arena=ArenaSettings(station_height_m=0.30))
    assert tall.object_sensors() == (True, True)  # SPEC's "accepted difference" variant
    left, right = tall.ray_ranges_cm()
    assert left[left >= 0].min() == pytest.approx(40.0, abs=1.0)


def test_the_station_block_stops_the_robot_at_its_probes():
    """Walking east into the station the robot stops with its probe tips on the block face
    (x = 480): its centre ends about one probe reach (0.237 m) short of the face, inside the
    SPEC's docking rule (x >= 455) with a margin, so head-on docking works."""
    pw = PhysicsWorld(400.0, 250.0, 90.0)
    xs = []
    for _ in range(9):
        pw.step(8)
        xs.append(pw.pose()[0])
    assert 455.5 < max(xs) < 460.0
    assert abs(xs[-1] - xs[-2]) < 1.0  # pushing against the block, not walking


def test_object_sensors_agree_on_sampled_poses():
    """Random poses near the walls (station included): physics and geometry agree, except
    within 2 cm of the 50 cm threshold (ray spacing, settle drift)."""
    rng = np.random.default_rng(7)
    agree, n = 0, 0
    for _ in range(40):
        # Near a wall, so that both answers occur.
        side = rng.integers(4)
        d = rng.uniform(28.0, 80.0)
        t = rng.uniform(30.0, 470.0)
        x, y = [(d, t), (W.arena_size - d, t), (t, d), (t, W.arena_size - d)][side]
        pw = PhysicsWorld(x, y, rng.uniform(0.0, 360.0))
        px, py, ph = pw.pose()
        got, want = pw.object_sensors(), geometry.object_sensors(px, py, ph, W)
        n += 1
        if got == want:
            agree += 1
            continue
        # Disagreement only at the threshold: the span's nearest wall distance is ~50 cm.
        left, right = pw.ray_ranges_cm()
        for k in range(2):
            if got[k] != want[k]:
                rays = (left, right)[k]
                hit = rays[rays >= 0]
                assert hit.size and abs(hit.min() - W.object_range) < 2.0, (px, py, ph, rays)
    assert n == 40
    assert agree / n >= 0.9


# --------------------------------------------------------------------------- light sensors
@pytest.mark.parametrize(
    ("pose", "expected"),
    [
        ((300.0, 250.0, 90.0), (True, True)),  # lit, facing the sources
        ((300.0, 250.0, 270.0), (False, False)),  # lit, facing away
        ((300.0, 250.0, 135.0), (True, False)),  # sources at ≈ −45°: left span only
        ((300.0, 250.0, 45.0), (False, True)),  # sources at ≈ +45°: right span only
        ((450.0, 60.0, 20.0), (False, False)),  # dark area: facing the sources, unlit
    ],
)
def test_light_sensors_in_and_out_of_the_cones(pose, expected):
    pw = PhysicsWorld(*pose)
    assert pw.light_sensors() == expected


# --------------------------------------------------------------------------- controllers
def _measured_table(gaits: tuple[int, ...], h: float, cycles: int = 4) -> np.ndarray:
    """The paper table with the given gaits' rows replaced by physics means over ``cycles``
    cycles from rest at heading ``h`` (the gaits' turn rate depends a little on the heading
    under MuJoCo's default pyramidal friction cone)."""
    table = PAPER_TABLE.copy()
    for g in gaits:
        pw = PhysicsWorld(250.0, 250.0, h)
        rows = []
        for _ in range(cycles):
            before = pw.bot.pose()
            pw.step(g)
            rows.append(displacement(before, pw.bot.pose()))
        table[g] = np.mean(rows, axis=0)
    return table


ALWAYS_8 = "01 0100000 0100000 0100000 0100000\n" * 16
# Gene 0: gait 8, then if object-left & object-right goto gene 1; gene 1: rotate right
# (gait 14) three times, then back to gene 0 by wrapping... gene 1 loops 3x, genes 2-7 walk.
BRANCHY = (
    "00 0100000 1011001 0100000 1011001\n"  # forever: gait 8, if both-object goto 1, ...
    "11 0111000 0111000 0111000 1000000\n"  # 3x: gait 14 x3, if always goto 0
    + "01 0100000 0100000 0100000 0100000\n"
    * 14
)


def _both(bits_text: str, start: tuple[float, float, float], table: np.ndarray, steps: int):
    bits = parse_chromosome(bits_text)
    tw = TableWorld(table, *start, W)
    pw = PhysicsWorld(*start)
    ev_t, ev_p = [], []
    rt = run(bits, tw, mode="coverage", max_steps=steps, on_event=ev_t.append)
    rp = run(bits, pw, mode="coverage", max_steps=steps, on_event=ev_p.append)
    return rt, rp, ev_t, ev_p


def test_always_gait_8_alike_in_both_worlds():
    table = _measured_table((8,), 80.0)
    rt, rp, _, _ = _both(ALWAYS_8, (150.0, 240.0, 80.0), table, 6)
    assert rt.end == rp.end == END_STEP_LIMIT and rt.steps == rp.steps == 6
    gap = np.hypot(*(rt.track[:, :2] - rp.track[:, :2]).T)
    assert gap.max() < 4.0, gap
    dh = (rt.track[:, 2] - rp.track[:, 2] + 180.0) % 360.0 - 180.0
    assert np.abs(dh).max() < 4.0, dh
    assert rt.reached == rp.reached and len(rt.reached) >= 1


def test_branching_controller_alike_in_both_worlds():
    """Walk towards the east wall until both object sensors fire, then rotate away: the same
    instructions execute in the same order in both worlds."""
    table = _measured_table((8, 14), 90.0)
    f = table[8, 0]
    # After 2 cycles of gait 8 the wall is ≈ 42 cm ahead: clear of the 50 cm threshold.
    start = (W.arena_size - 42.0 - 2 * f, 120.0, 90.0 - table[8, 2])
    rt, rp, ev_t, ev_p = _both(BRANCHY, start, table, 9)
    texts_t = [e.text for e in ev_t]
    texts_p = [e.text for e in ev_p]
    assert texts_t == texts_p
    assert texts_t.index("if both-object goto 1: taken") == 3  # after two gait-8 cycles
    assert "if always goto 0: taken" in texts_t
    assert any(e.gait == 14 for e in ev_p)
    assert rt.reached == rp.reached
    assert np.hypot(*(rt.final_pose[:2] - np.asarray(rp.final_pose[:2]))) < 6.0


def test_physics_run_is_deterministic_and_recording_hooks_do_not_change_it():
    bits = parse_chromosome(BRANCHY)
    start = (300.0, 300.0, 45.0)
    a = run(bits, PhysicsWorld(*start), mode="coverage", max_steps=8)
    frames = []
    events = []
    b = run(
        bits,
        PhysicsWorld(*start, on_frame=frames.append),
        mode="coverage",
        max_steps=8,
        on_event=events.append,
    )
    assert np.array_equal(a.track, b.track)
    assert len(frames) >= 8 and len(events) >= 8


def test_sensors_read_on_demand_change_no_record():
    """The arena steps with MuJoCo's sensor stage off and reads its rays when asked: the same
    run with the rangefinders evaluated at every physics step gives the same track, sensor
    readings and events, bit for bit."""
    bits = parse_chromosome(BRANCHY)
    table = _measured_table((8, 14), 90.0)
    start = (W.arena_size - 42.0 - 2 * table[8, 0], 120.0, 90.0 - table[8, 2])
    bit = int(mujoco.mjtDisableBit.mjDSBL_SENSOR)

    def one_run() -> tuple[np.ndarray, list, list]:
        pw = PhysicsWorld(*start, rng=np.random.default_rng(7))
        events: list = []
        res = run(bits, pw, mode="coverage", max_steps=9, on_event=events.append)
        return res.track, [(e.text, e.sensors) for e in events], pw.ray_ranges_cm()

    pw = PhysicsWorld(*start)
    assert pw.model.opt.disableflags & bit  # stepping skips the sensors
    on_demand = one_run()
    pw.model.opt.disableflags &= ~bit  # the shared model: restored below
    try:
        every_step = one_run()
    finally:
        pw.model.opt.disableflags |= bit
    assert np.array_equal(on_demand[0], every_step[0])
    assert on_demand[1] == every_step[1]
    assert "if both-object goto 1: taken" in [t for t, _ in on_demand[1]]
    for a, b in zip(on_demand[2], every_step[2], strict=True):
        assert np.array_equal(a, b)
