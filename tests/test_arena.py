"""The colony arena in MuJoCo: geometry per SPEC §3 "In MuJoCo", compiles and runs clean."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest

from evolve.settings import WorldSettings
from servo_mj.robot import constants as C
from servo_mj.world.arena import ArenaSettings, compile_arena, warnings_raised
from servo_mj.world.sensors import SIDES, ray_bearings_deg, ray_direction, ray_ranges_m, sensor_name


@pytest.fixture(scope="module")
def colony():
    return compile_arena()


def _geom_aabb(model, name):
    g = model.geom(name)
    d = mujoco.MjData(model)
    mujoco.mj_forward(model, d)
    centre = d.geom_xpos[g.id]
    return centre - g.size, centre + g.size


def test_walls_station_and_lights_where_the_spec_puts_them(colony):
    m = colony.model
    lo, hi = _geom_aabb(m, "wall_west")
    assert hi[0] == pytest.approx(0.0)
    lo, hi = _geom_aabb(m, "wall_east")
    assert lo[0] == pytest.approx(5.0)
    lo, hi = _geom_aabb(m, "wall_south")
    assert hi[1] == pytest.approx(0.0)
    lo, hi = _geom_aabb(m, "wall_north")
    assert lo[1] == pytest.approx(5.0)
    # Walls span the whole arena side and rise above the rangefinder rays.
    assert hi[0] - lo[0] >= 5.0
    lo, hi = _geom_aabb(m, "station")
    assert lo[0] == pytest.approx(4.80)  # front face 0.20 m out from the east wall
    assert hi[0] == pytest.approx(5.00)
    assert (lo[1] + hi[1]) / 2 == pytest.approx(2.50)
    assert hi[1] - lo[1] == pytest.approx(0.60)
    d = mujoco.MjData(m)
    mujoco.mj_forward(m, d)
    lights = sorted(tuple(np.round(d.light_xpos[i][:2], 6)) for i in range(m.nlight))
    assert lights == [(5.0, 2.35), (5.0, 2.65)]
    # The light markers never collide.
    for i in range(2):
        g = m.geom(f"light_marker_{i}")
        assert g.contype == 0 and g.conaffinity == 0


def test_robot_attached_with_one_free_joint_on_the_frame(colony):
    m = colony.model
    assert colony.prefix == C.ATTACHED_PREFIX
    free = [j for j in range(m.njnt) if m.jnt_type[j] == mujoco.mjtJoint.mjJNT_FREE]
    assert len(free) == 1
    torso = m.body(C.torso_name(colony.prefix)).id
    # The free joint moves the torso (it sits on the torso's parent, the attachment frame).
    assert m.jnt_bodyid[free[0]] == m.body_parentid[torso]
    assert m.nu == 12 and m.nq == 7 + 12
    # Placement moved onto the frame: the torso sits at the frame's origin.
    assert np.allclose(m.body_pos[torso], 0.0)


def test_fan_bearings_include_both_span_ends_and_rays_are_horizontal():
    w = WorldSettings()
    b = ray_bearings_deg(w.object_left_span_deg, 10)
    assert b[0] == -40.0 and b[-1] == 5.0 and len(b) == 10
    with pytest.raises(ValueError, match="at least 2 rays"):
        ray_bearings_deg(w.object_left_span_deg, 1)
    # Bearing +90 (clockwise) from forward +x, with +y left, is −y.
    assert np.allclose(ray_direction(90.0, (1, 0, 0)), (0, -1, 0), atol=1e-12)
    assert np.allclose(ray_direction(-40.0, (1, 0, 0))[2], 0.0)


def test_compiles_and_stands_a_second_with_no_warnings(colony):
    from servo_mj.robot.bot import ServoBot

    m = colony.model
    d = mujoco.MjData(m)
    bot = ServoBot(m, d, prefix=colony.prefix)
    bot.place(250.0, 250.0, 0.0)
    for _ in range(3):
        bot.run_gait(7)
    mujoco.mj_step(m, d, 200)
    assert warnings_raised(d) == {}
    assert np.all(np.isfinite(d.qpos))
    x, y, h = bot.pose()
    assert abs(x - 250.0) < 1.0 and abs(y - 250.0) < 1.0


def test_rays_never_hit_the_robot_while_it_walks(colony):
    """In the open middle of the arena (walls 2.5 m away) no ray hits anything within 0.6 m
    (object range 0.5 m; the robot's own legs and probes lie within 0.26 m of the sites).
    While the torso pitches a few degrees mid-cycle a ray may pass over a far wall (−1) or meet
    the floor beyond 1 m; neither can fire an object sensor."""
    from servo_mj.robot.bot import ServoBot

    m = colony.model
    d = mujoco.MjData(m)
    bot = ServoBot(m, d, prefix=colony.prefix)
    bot.place(250.0, 250.0, 45.0)
    nearest = []

    def check(_data):
        left, right = ray_ranges_m(m, d, colony.object_index)
        r = np.concatenate([left, right])
        nearest.append(r[r >= 0].min(initial=np.inf))

    for gait in (8, 3, 14, 15):
        bot.run_gait(gait, on_frame=check)
    assert len(nearest) > 10
    assert min(nearest) > 0.6
    assert np.isfinite(nearest).mean() > 0.5


def test_ray_count_is_a_setting():
    colony = compile_arena(arena=ArenaSettings(rays_per_span=4))
    m = colony.model
    for side in SIDES:
        assert len(getattr(colony.object_index, side)) == 4
        assert (
            m.sensor(colony.prefix + sensor_name(side, 3)).type
            == mujoco.mjtSensor.mjSENS_RANGEFINDER
        )


def test_physics_options_and_floor_contact_match_the_calibration_scene(colony):
    scene = mujoco.MjModel.from_xml_path(str(C.SCENE_XML))
    m = colony.model
    for name in ("timestep", "integrator", "cone", "impratio", "solver", "iterations"):
        assert np.all(getattr(m.opt, name) == getattr(scene.opt, name)), name
    src, dst = scene.geom("floor").id, m.geom("floor").id
    assert np.array_equal(m.geom_friction[dst], scene.geom_friction[src])
    assert np.array_equal(m.geom_solref[dst], scene.geom_solref[src])
    assert m.geom_condim[dst] == scene.geom_condim[src]
