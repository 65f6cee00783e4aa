"""A colony of robots (SPEC §7) on hand-worked cases: cancelled moves, other robots seen by the
object sensors, the station held while one robot charges, dead robots as obstacles, the union
of squares; each case run by the reference interpreter and by the numba kernel. Also the
colony start sampler and the colony settings and inputs that are refused."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
from chromosome_text import STILL, B, G, chrom, gene

from evolve import evaluate_colony
from evolve.interpreter import (
    END_KILL_ZONE,
    END_STEP_LIMIT,
    ColonyEvent,
    run_colony,
)
from evolve.settings import ColonySettings, WorldSettings
from evolve.starts import colony_starts, coverage_starts
from evolve.world import TableColony

WORLD = WorldSettings()
COST = WORLD.gait_cost_v
STEP10 = np.zeros((16, 3))
STEP10[0] = (10.0, 0.0, 0.0)  # gait 0: 10 units straight ahead
STEP10[14] = (0.0, 0.0, 90.0)  # gait 14: a quarter turn right on the spot
FORWARD = chrom(gene("00", G(0), G(0), G(0), G(0)))
"""Every robot walks gait 0 forever."""


def both(bits, starts, *, table=STEP10, colony=None, events=None, **kw):
    """Run one colony in the interpreter and in the kernel; check they agree; return both."""
    starts = np.asarray(starts, dtype=float)
    colony = colony or ColonySettings(robots=len(starts))
    world = TableColony(table, starts, WORLD, colony)
    res = run_colony(bits, world, colony=colony, on_event=events, **kw)
    ev = evaluate_colony(bits[None], starts[None], table=table, colony=colony, **kw)
    robots = res.robots
    assert (ev.squares[0, 0], ev.inner_squares[0, 0]) == (res.squares, res.inner_squares)
    assert ev.colony_steps[0, 0] == res.colony_steps
    for name, want in (
        ("robot_squares", [r.squares for r in robots]),
        ("steps", [r.steps for r in robots]),
        ("docks", [r.docks for r in robots]),
        ("end", [r.end for r in robots]),
        ("collisions", [r.collisions for r in robots]),
        ("station_waits", [r.station_waits for r in robots]),
    ):
        assert getattr(ev, name)[0, 0].tolist() == want, name
    np.testing.assert_array_equal(ev.final_pose[0, 0], [r.final_pose for r in robots])
    return res, ev


# --------------------------------------------------------------------------- collisions


def test_a_move_closer_than_two_radii_is_cancelled():
    # Face to face along y = 275, 50 apart. Step 1: robot 0 to x = 210 (40 apart), robot 1 to
    # x = 240: exactly 30 = two radii apart, allowed. Step 2 on: each move would end 20 apart,
    # so it is cancelled; the step still counts and costs power.
    events: list[ColonyEvent] = []
    res, _ = both(
        FORWARD, [(200, 275, 90), (250, 275, 270)], mode="coverage", max_steps=5,
        events=events.append,
    )  # fmt: skip
    r0, r1 = res.robots
    assert r0.final_pose == pytest.approx((210, 275, 90), abs=1e-12)
    assert r1.final_pose == pytest.approx((240, 275, 270), abs=1e-12)
    assert (r0.collisions, r1.collisions) == (4, 4)
    assert (r0.steps, r1.steps) == (5, 5) and r0.end == r1.end == END_STEP_LIMIT
    np.testing.assert_allclose(res.track[2], [(210, 275, 90), (240, 275, 270)], atol=1e-12)
    gaits = [e for e in events if e.robot == 0 and e.event.kind == "gait"]
    assert [e.event.text for e in gaits] == ["gait 0"] + ["gait 0 (blocked)"] * 4
    assert [e.colony_step for e in gaits] == [1, 2, 3, 4, 5]
    assert gaits[-1].event.power == pytest.approx(4.0 - 5 * COST)
    # Both stand in square (4, 5)'s contact zone (|210 − 225|, |240 − 225| ≤ 19): one
    # colony square, one per robot.
    assert (res.squares, r0.squares, r1.squares) == (1, 1, 1)
    assert res.reached == {54}


def test_dead_robot_stays_as_an_obstacle():
    # Robot 1 walks west from x = 30 into the kill zone (x = 20) at once and ends there.
    # Robot 0 follows from x = 70: 60, 50 (30 from the dead robot, allowed), then blocked.
    res, _ = both(FORWARD, [(70, 275, 270), (30, 275, 270)], mode="coverage", max_steps=6)
    r0, r1 = res.robots
    assert r1.end == END_KILL_ZONE and r1.steps == 1
    assert r1.final_pose == pytest.approx((20, 275, 270), abs=1e-12)
    assert r0.end == END_STEP_LIMIT and r0.steps == 6 and r0.collisions == 4
    assert r0.final_pose == pytest.approx((50, 275, 270), abs=1e-12)
    # x = 60 is in square (1, 5)'s contact zone, x = 50 is not; the dead robot's last
    # position is not counted (kill zone).
    assert (res.squares, res.inner_squares, r0.squares, r1.squares) == (1, 1, 1, 0)
    assert res.colony_steps == 6  # robot 1 is no longer live after step 1


# --------------------------------------------------------------------------- object sensors


@pytest.mark.parametrize(
    ("other", "want"),
    [
        ((250, 314), (True, True)),  # dead ahead: nearest point of the disc 64 − 15 = 49 away
        ((250, 316), (False, False)),  # 66 − 15 = 51 away: out of range
        # 40 away at bearing 60°: the right span's edge (40°) is δ = 20° off; that ray passes
        # 40·sin 20° = 13.7 ≤ 15 from the centre and enters the disc at
        # 40·cos 20° − √(15² − 13.7²) = 31.4 ≤ 50. The left span's edge (5°) is 55° off.
        ((250 + 40 * math.sin(math.radians(60)), 250 + 40 * math.cos(math.radians(60))),
         (False, True)),
        # bearing 70°: δ = 30°, the ray passes 40·sin 30° = 20 > 15 from the centre
        ((250 + 40 * math.sin(math.radians(70)), 250 + 40 * math.cos(math.radians(70))),
         (False, False)),
    ],
)  # fmt: skip
def test_object_sensors_see_other_robots(other, want):
    world = TableColony(STEP10, [(250, 250, 0), (*other, 180)], WORLD, ColonySettings(robots=2))
    assert world.object_sensors(0) == want
    assert world.light_sensors(0) == (False, False)  # facing north, away from the lights


@pytest.mark.parametrize(("y1", "taken"), [(314, True), (316, False)])
def test_a_branch_reads_the_other_robot(y1, taken):
    # Gene 0 (once): if both-object goto 1, else stand; gene 1: quarter turns. After one
    # step robot 0 faces east if it saw robot 1 (49 units away) and north if not (51).
    bits = chrom(gene("01", B(3, 1), G(7), G(7), G(7)), gene("00", *[G(14)] * 4))
    res, _ = both(bits, [(250, 250, 0), (250, y1, 0)], mode="coverage", max_steps=1)
    assert res.robots[0].final_pose[2] == (90.0 if taken else 0.0)
    assert res.robots[1].final_pose[2] == 0.0  # robot 1 sees nothing ahead


# --------------------------------------------------------------------------- the station

LOW_TO_NAV = chrom(gene("00", B(4, 0), G(7), G(7), G(7)))
"""Gene 0: on low power go to the navigation section, which stands still (gait 7)."""


def at_the_station(colony=None, events=None):
    """Two LOW_TO_NAV robots 30 apart in the docking box on low power, 20 steps at most, in
    both worlds (``both``)."""
    return both(
        LOW_TO_NAV, [(460, 250, 90), (460, 220, 90)], table=np.zeros((16, 3)), colony=colony,
        events=events, mode="coverage", start_power=3.9, max_steps=20,
    )  # fmt: skip


def test_second_robot_is_kept_from_docking_while_the_first_charges():
    # Both robots stand in the docking box, 30 apart, on low power. Colony step 1: robot 0
    # docks; robot 1 meets the rule but must wait. Robot 0 charges in steps 2–11 (power
    # rising linearly from 3.9 to 5.0 V) and leaves the station free during step 11, so
    # robot 1 docks in step 11 after 10 waits. Gait 15 does not move here, but costs power.
    events: list[ColonyEvent] = []
    res, _ = at_the_station(events=events.append)
    r0, r1 = res.robots
    assert (r0.docks, r1.docks) == (1, 1)
    assert (r0.station_waits, r1.station_waits) == (0, 10)
    assert (r0.steps, r1.steps) == (20, 20) and res.colony_steps == 30
    charge0 = [(e.colony_step, e.event.power) for e in events if e.robot == 0 and
               e.event.kind == "charge"]  # fmt: skip
    assert [t for t, _ in charge0] == list(range(2, 12))
    np.testing.assert_allclose([v for _, v in charge0], 3.9 + 1.1 * np.arange(1, 11) / 10)
    assert charge0[-1][1] == 5.0
    waits = [e.colony_step for e in events if e.robot == 1 and e.event.kind == "wait"]
    assert waits == list(range(1, 11))
    charge1 = [e.colony_step for e in events if e.robot == 1 and e.event.kind == "charge"]
    assert charge1 == list(range(12, 22))


def test_charging_at_once_leaves_the_station_free():
    # With charge_steps = 0 robot 0 charges within its own step, so robot 1 docks at once.
    colony = ColonySettings(robots=2, charge_steps=0)
    res, _ = at_the_station(colony)
    assert [r.docks for r in res.robots] == [1, 1]
    assert [r.station_waits for r in res.robots] == [0, 0]
    assert res.colony_steps == 20


def test_colony_step_limit_ends_every_robot():
    # The SPEC read literally: the run ends after 15 colony steps, charging steps included.
    colony = ColonySettings(robots=2, colony_step_limit=15)
    res, _ = at_the_station(colony)
    assert res.colony_steps == 15
    assert [r.end for r in res.robots] == [END_STEP_LIMIT] * 2
    assert [r.steps for r in res.robots] == [5, 11]  # 1 + 4 backups; 11 (docks, charging)


# --------------------------------------------------------------------------- squares


def test_colony_squares_are_the_union():
    # Robots 0 and 1 stand 30 apart inside square (1, 1)'s contact zone, robot 2 in (3, 1).
    res, ev = both(
        chrom(STILL), [(60, 75, 0), (90, 75, 0), (175, 75, 0)], mode="coverage", max_steps=3
    )
    assert [r.squares for r in res.robots] == [1, 1, 1]
    assert res.reached == {11, 13} and (res.squares, res.inner_squares) == (2, 2)
    assert ev.robot_inner_squares[0, 0].tolist() == [1, 1, 1]


def test_one_robot_colony_run_is_the_lone_run():
    from evolve.interpreter import run
    from evolve.world import TableWorld

    rng = np.random.default_rng(4)
    for _ in range(20):
        bits = rng.integers(0, 2, (16, 30), dtype=np.uint8)
        bits[0, :9] = [0, 0, 1, 1, 0, 0, 0, 0, 0]  # low power → navigation: docking happens
        pose = (rng.uniform(400, 470), rng.uniform(200, 300), rng.uniform(0, 360))
        lone = run(bits, TableWorld(STEP10 + 1.0, *pose), mode="coverage", start_power=3.95)
        col = run_colony(
            bits, TableColony(STEP10 + 1.0, [pose], WORLD, ColonySettings(robots=1)),
            colony=ColonySettings(robots=1), start_power=3.95,
        ).robots[0]  # fmt: skip
        for f in ("squares", "inner_squares", "steps", "docks", "end", "final_pose", "reached"):
            assert getattr(col, f) == getattr(lone, f), f
        np.testing.assert_array_equal(col.track, lone.track)


# --------------------------------------------------------------------------- starts, settings


def test_colony_starts_are_separated_and_seeded():
    colony = ColonySettings()
    a = colony_starts(np.random.default_rng(7), 500, WORLD, colony)
    b = colony_starts(np.random.default_rng(7), 500, WORLD, colony)
    np.testing.assert_array_equal(a, b)
    assert a.shape == (500, 3, 3)
    assert (a[..., 0] >= 350).all() and (a[..., 0] <= 450).all()
    assert (a[..., 1] >= 175).all() and (a[..., 1] <= 325).all()
    assert (a[..., 2] >= 0).all() and (a[..., 2] < 360).all()
    d = np.linalg.norm(a[:, :, None, :2] - a[:, None, :, :2], axis=-1)
    pairs = d[:, [0, 0, 1], [1, 2, 2]]
    assert pairs.min() >= 40.0 and pairs.min() < 41.0  # rejection, not a wider spacing
    # one robot: exactly the coverage sampler's poses
    one = colony_starts(np.random.default_rng(7), 50, WORLD, ColonySettings(robots=1))
    np.testing.assert_array_equal(one[:, 0], coverage_starts(np.random.default_rng(7), 50, WORLD))


def test_impossible_colony_settings_and_inputs_are_refused():
    with pytest.raises(ValueError, match="cannot place robot"):
        colony_starts(np.random.default_rng(0), 1, WORLD, ColonySettings(robots=40))
    for bad, message in (
        (dict(robots=0), "robots"),
        (dict(charge_steps=-1), "charge_steps"),
        (dict(start_separation=20.0), "two disc radii"),
        (dict(colony_step_limit=-5), "colony_step_limit"),
    ):
        with pytest.raises(ValueError, match=message):
            ColonySettings(**bad)
    g = np.zeros((1, 16, 30), dtype=np.uint8)
    two = np.array([[[300.0, 250.0, 0.0], [340.0, 250.0, 0.0]]])
    kw = dict(table=STEP10, mode="coverage")
    with pytest.raises(ValueError, match="colony.robots = 3"):
        evaluate_colony(g, two, **kw)
    with pytest.raises(ValueError, match=r"\(S, R, 3\)"):
        evaluate_colony(g, two[0], **kw)
    close = dataclasses.replace(ColonySettings(), robots=2)
    with pytest.raises(ValueError, match="robots 0 and 1 are 20 units apart"):
        evaluate_colony(g, two - [[[0, 0, 0], [20, 0, 0]]], colony=close, **kw)
    with pytest.raises(ValueError, match="outside the arena"):
        evaluate_colony(g, two + [[[0, 300, 0], [0, 0, 0]]], colony=close, **kw)
    with pytest.raises(ValueError, match="colony.robots = 3"):
        run_colony(g[0], TableColony(STEP10, two[0], WORLD), colony=ColonySettings())
