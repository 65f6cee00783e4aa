"""The ServoBot MJCF: compiles, is well-formed, survives random controls, attaches into an arena."""

from __future__ import annotations

import math

import mujoco
import numpy as np
import pytest

from evolve.settings import WorldSettings
from servo_mj.robot import constants as C
from servo_mj.robot.bot import ServoBot
from servo_mj.robot.model import free_joint_of, load_robot


def test_robot_and_scene_compile_with_12_servos_named_after_joints() -> None:
    for scene in (True, False):
        m, d = load_robot(scene=scene)
        assert m.nu == 12
        for i, name in enumerate(C.actuator_names()):
            assert m.actuator(i).name == name
            j = m.actuator_trnid[i, 0]
            assert m.joint(j).name == name
            # class defaults keep joint range and servo travel identical
            np.testing.assert_allclose(m.actuator_ctrlrange[i], m.jnt_range[j])
            assert m.actuator_forcerange[i, 1] == pytest.approx(0.3)
        assert all(w.number == 0 for w in d.warning)


def test_mass_dimensions_and_home_keyframe() -> None:
    m, d = load_robot()
    assert float(m.body_subtreemass[m.body(C.TORSO).id]) == pytest.approx(1.0, abs=0.02)
    assert m.key("home").qpos.shape == (m.nq,)
    # hips at x = ±10, 0 cm and y = ±6 cm (body frame)
    for leg in C.LEGS:
        pos = m.body(f"{leg}_coxa").pos
        assert abs(pos[1]) == pytest.approx(0.06) and np.sign(pos[1]) == C.LEG_SIDE[leg]
    # standing: every foot on the floor, torso level
    bot = ServoBot(m, d)
    bot.place(0.0, 0.0, 0.0)
    feet = bot.foot_positions()
    assert np.all(np.abs(feet[:, 2] - bot.foot_radius_m) < 0.003)
    assert bot.upright() > 0.99


def test_one_second_of_random_controls_inside_ctrlrange_is_finite_and_warning_free() -> None:
    m, d = load_robot()
    rng = np.random.default_rng(1234)
    lo, hi = m.actuator_ctrlrange[:, 0], m.actuator_ctrlrange[:, 1]
    for _ in range(50):  # 50 frames of 20 ms = 1 s at the 2 ms step
        d.ctrl[:] = rng.uniform(lo, hi)
        mujoco.mj_step(m, d, 10)
    assert d.time == pytest.approx(1.0)
    assert np.all(np.isfinite(d.qpos)) and np.all(np.isfinite(d.qvel))
    assert all(w.number == 0 for w in d.warning), [w.number for w in d.warning]


def _site_bearing_deg(m: mujoco.MjModel, d: mujoco.MjData, site: str) -> float:
    """Relative bearing (clockwise from the forward axis) of a site's +z axis, robot at h=0."""
    z = d.site(site).xmat.reshape(3, 3)[:, 2]
    return math.degrees(math.atan2(z[0], z[1]))  # heading convention: atan2(east, north)


def test_sensor_sites_point_at_their_spec_span_centres_and_probes_reach_the_station() -> None:
    m, d = load_robot()
    ServoBot(m, d).place(0.0, 0.0, 0.0)  # facing north
    w = WorldSettings()
    spans = {
        C.OBJECT_SENSOR_SITES[0]: w.object_left_span_deg,
        C.OBJECT_SENSOR_SITES[1]: w.object_right_span_deg,
        C.LIGHT_SENSOR_SITES[0]: w.light_left_span_deg,
        C.LIGHT_SENSOR_SITES[1]: w.light_right_span_deg,
    }
    for site, (a, b) in spans.items():
        assert _site_bearing_deg(m, d, site) == pytest.approx((a + b) / 2, abs=0.5)
    # Docking (SPEC §3: centre x >= 455, station face at x = 480) must be reachable head-on
    # with the probes pressed against the face: tips at most 24 cm ahead of the centre (1 cm
    # margin), and well beyond the torso (14 cm) and the front feet's forward swing.
    centre = d.body(C.TORSO).xpos
    for site in C.probe_sites():
        reach = d.site(site).xpos[1] - centre[1]
        assert 0.20 < reach <= 0.24, reach


def test_attaches_into_an_arena_with_dm_control_and_walks_with_a_prefix() -> None:
    from dm_control import mjcf

    robot = mjcf.from_path(str(C.ROBOT_XML))
    robot.find("joint", C.FREE_JOINT).remove()
    arena = mjcf.RootElement(model="arena")
    arena.option.timestep = 0.002
    arena.worldbody.add("geom", name="floor", type="plane", size=[5, 5, 0.1])
    frame = arena.attach(robot)
    frame.add("freejoint")
    physics = mjcf.Physics.from_mjcf_model(arena)
    m, d = physics.model.ptr, physics.data.ptr
    torso = m.body(C.torso_name(C.ATTACHED_PREFIX)).id
    # the free joint sits on the attachment frame above the torso, found by walking up
    assert m.jnt_bodyid[free_joint_of(m, torso)] == m.body_parentid[torso]
    bot = ServoBot(m, d, prefix=C.ATTACHED_PREFIX)
    bot.place(200.0, 150.0, 90.0)
    x, y, h = bot.pose()
    assert (x, y) == pytest.approx((200.0, 150.0), abs=0.5) and h == pytest.approx(90.0, abs=1.0)
    res = bot.run_gait(0)
    f, t, dh = res.ftdh
    assert f > 8.0  # walks forward, i.e. east
    assert bot.pose()[0] > x + 8.0
