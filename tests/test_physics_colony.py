"""The physics colony (SPEC §7 "In MuJoCo"): robots never interpenetrate, their rangefinders
see each other, bumper contacts block them, and one robot walks as the lone physics world does,
bit for bit."""

from __future__ import annotations

import numpy as np
import pytest

from evolve import geometry
from evolve.interpreter import run, run_colony
from evolve.settings import ColonySettings, WorldSettings
from evolve.world import TableColony
from servo_mj.world.arena import BUMPER, SHELL, ArenaSettings, compile_arena
from servo_mj.world.physics_colony import PhysicsColony, robot_rngs
from servo_mj.world.physics_world import PhysicsWorld
from tests.chromosome_text import STILL, B, G, chrom, gene

W = WorldSettings()
TOLERANCE_CM = 0.5
"""How far two robots' centres may come inside two disc radii (30 units): the bumpers are
soft MuJoCo contacts, which a pushing robot compresses by ≈ 0.05 cm (measured: centres ≥
29.86 cm in a three-robot jam, every physics step), and the distance is measured on the
floor while the spheres touch in 3D (a 2 cm height difference between two torsos shortens
it by 0.07 cm). A contact that failed would let a robot walk 5–12 cm into another per
cycle."""


def test_arena_of_a_colony_gives_each_robot_its_bumper_and_shell():
    settings = ColonySettings(robots=3)
    a = compile_arena(colony=settings)
    m = a.model
    assert a.prefixes == ("servobot0/", "servobot1/", "servobot2/")
    free = [j for j in range(m.njnt) if m.jnt_type[j] == 0]
    assert len(free) == 3
    arena = ArenaSettings()
    for p, bumper in zip(a.prefixes, a.bumpers, strict=True):
        assert m.geom(p + BUMPER).id == bumper
        assert m.geom_size[bumper, 0] == pytest.approx(settings.disc_radius / 100)
        shell = m.geom(p + SHELL).id
        assert m.geom_contype[shell] == m.geom_conaffinity[shell] == 0
    # Bumpers collide with each other only: no other geom shares their bit.
    bit = arena.bumper_bit
    others = np.setdiff1d(np.arange(m.ngeom), a.bumpers)
    assert not np.any((m.geom_contype[others] & bit) | (m.geom_conaffinity[others] & bit))
    assert np.all(m.geom_contype[a.bumpers] & m.geom_conaffinity[a.bumpers] & bit)
    # A lone robot's arena is today's: one robot, no bumper.
    lone = compile_arena()
    assert lone.prefixes == ("servobot/",) and len(lone.bumpers) == 0
    assert m.body_mass.sum() == pytest.approx(3 * lone.model.body_mass.sum())


def _min_distance_every_step(c: PhysicsColony, plan: list[tuple[int, int]]) -> float:
    """Run ``(robot, gait)`` cycles directly on the bots, measuring after every physics step."""
    low = [np.inf]

    def measure(_data) -> None:
        d = c.centre_distances_cm()
        d[np.diag_indices_from(d)] = np.inf
        low[0] = min(low[0], float(d.min()))

    for i, gait in plan:
        c.bots[i].run_gait(gait, on_step=measure)
    return low[0]


def test_robots_never_interpenetrate():
    """Three robots walk into each other (head-on, into a side, a turning robot against two)
    for 15 cycles: at no physics step do two centres come closer than two disc radii minus
    the tolerance, although without bumpers they would overlap by ≥ 20 cm."""
    starts = [[220.0, 250.0, 90.0], [252.0, 250.0, 270.0], [236.0, 280.0, 180.0]]
    plan = [(i, g) for g in (8, 8, 0, 8, 14) for i in range(3)]
    low = _min_distance_every_step(PhysicsColony(starts), plan)
    assert 30.0 - TOLERANCE_CM < low < 30.5  # they did touch, and did not overlap
    # The same plan with 0.5 cm bumpers: the robots walk into each other.
    tiny = ColonySettings(robots=3, disc_radius=0.5, start_separation=1.0)
    ghosts = PhysicsColony(starts, colony_settings=tiny)
    assert _min_distance_every_step(ghosts, plan) < 10.0


def test_contacts_block_and_step_reports_them():
    """Robot 0 walks at robot 1, which stands 50 cm ahead: it is stopped at two radii, the
    cycles in contact report a block, a free cycle does not."""
    c = PhysicsColony([[200.0, 250.0, 90.0], [250.0, 250.0, 90.0]])
    x0 = c.pose(0)[0]
    blocked = [c.step(0, 8) for _ in range(4)]
    assert blocked[0] is False and blocked[-1] is True
    assert c.pose(0)[0] - x0 < 4 * 11.0 - 10.0  # walked freely it would go ≈ 11 cm a cycle
    assert 30.0 - TOLERANCE_CM < c.min_distance_cm < 30.5
    assert c.step(1, 8) is False  # robot 1 walks away from robot 0 (it faces east too)
    far = PhysicsColony([[150.0, 250.0, 90.0], [350.0, 250.0, 90.0]])
    assert far.step(0, 8) is False and far.min_distance_cm > 150.0


@pytest.mark.parametrize(
    ("distance", "seen"),
    [(62.0, (True, True)), (68.0, (False, False))],
)
def test_rangefinders_see_another_robot_as_its_disc(distance, seen):
    """Robot 1 straight ahead of robot 0: seen while the nearest point of its disc (centre
    distance − 15) lies within the 50 cm object range, as the table world's rule says."""
    c = PhysicsColony([[200.0, 250.0, 90.0], [200.0 + distance, 250.0, 0.0]])
    assert c.object_sensors(0) == seen
    table = TableColony(np.zeros((16, 3)), [c.pose(0), c.pose(1)], W, ColonySettings(robots=2))
    assert table.object_sensors(0) == seen
    left, right = c.ray_ranges_cm(0)
    ahead = np.concatenate([left, right])
    assert ahead.min() == pytest.approx(distance - 15.0, abs=1.0)  # the shell's face
    # Robot 1 faces north: robot 0 lies to its left, outside both spans (−40° … +40°).
    assert c.object_sensors(1) == geometry.object_sensors(*c.pose(1), W) == (False, False)


def test_a_robot_off_to_one_side_fires_only_that_side():
    # Robot 1 at bearing −30° (left of robot 0's heading), 45 cm: only the left span sees it.
    b = np.radians(90.0 - 30.0)
    c = PhysicsColony([[200.0, 250.0, 90.0], [200.0 + 45 * np.sin(b), 250.0 + 45 * np.cos(b), 0.0]])
    assert c.object_sensors(0) == (True, False)
    table = TableColony(np.zeros((16, 3)), [c.pose(0), c.pose(1)], W, ColonySettings(robots=2))
    assert table.object_sensors(0) == (True, False)


def test_a_robot_never_sees_itself_while_walking():
    """Alone in the open middle, in a colony arena: no ray of the robot hits anything within
    0.6 m while it walks (its own bumper and shell are on its torso, which its rays skip)."""
    c = PhysicsColony([[250.0, 250.0, 45.0], [60.0, 440.0, 0.0]])
    nearest = []
    for gait in (8, 3, 14, 15):
        c.step(0, gait)
        r = np.concatenate(c.ray_ranges_cm(0))
        nearest.append(r[r >= 0].min(initial=np.inf))
    assert min(nearest) > 60.0


DOCKER = chrom(
    gene("00", B(4, 0), G(8), B(3, 1), G(9)),  # low power → 8; walk; both objects → 1
    gene("01", G(14), G(14), G(14), B(0, 0)),  # rotate right 3 ×, back to gene 0
    *[STILL] * 6,
    gene("00", G(8), G(8), G(8), G(8)),  # navigation: walk ahead (into the station)
)
"""Docks from (430, 250, 90) on low power, charges, backs off, then walks and turns at walls:
docking, charging, backing up, object sensors and branches, in 14 steps."""


def test_one_robot_colony_walks_exactly_as_the_lone_physics_world():
    start = (430.0, 250.0, 90.0)
    lone_world = PhysicsWorld(*start, rng=np.random.default_rng((5, 2)))
    lone_events: list = []
    lone = run(DOCKER, lone_world, mode="coverage", start_power=3.95, max_steps=14,
               on_event=lone_events.append)  # fmt: skip
    world = PhysicsColony([start], rngs=robot_rngs(5, 2, 1))
    events: list = []
    res = run_colony(DOCKER, world, colony=ColonySettings(robots=1), start_power=3.95,
                     max_steps=14, on_event=events.append)  # fmt: skip
    one = res.robots[0]
    assert lone.docks == 1 and lone.steps == 14
    for f in ("squares", "inner_squares", "steps", "docks", "end", "final_pose", "reached"):
        assert getattr(one, f) == getattr(lone, f), f
    np.testing.assert_array_equal(one.track, lone.track)
    np.testing.assert_array_equal(world.data.qpos, lone_world.data.qpos)
    assert world.t_s == lone_world.t_s
    gaits = [e.event.text for e in events if e.event.kind != "charge"]
    assert gaits == [e.text for e in lone_events if e.kind != "charge"]
    assert "if both-object goto 1: taken" in gaits
