"""The colony's blocking rule (``ColonySettings.blocking``, issue 17): ``"cancel"`` (SPEC §7)
keeps a blocked robot's pose; ``"slide"`` keeps the move's component along the contact
tangent. Hand-worked cases in the interpreter's ``TableColony`` and the kernel, the kernel
against the interpreter on random colonies, one robot against the lone kernel, and the
setting's validation and record."""

from __future__ import annotations

import dataclasses
import json
import math

import numpy as np
import pytest
from chromosome_text import G, chrom, gene
from test_colony_kernel import NEAR_STATION, assert_colony_kernel_equals_interpreter

from evolve import evaluate, evaluate_colony
from evolve.envelope import Envelope
from evolve.interpreter import run_colony
from evolve.settings import ColonySettings, SettingsError, WorldSettings, settings_json
from evolve.starts import colony_starts
from evolve.table import PAPER_TABLE
from evolve.world import TableColony

WORLD = WorldSettings()
CANCEL = ColonySettings(robots=2)
SLIDE = ColonySettings(robots=2, blocking="slide")
TURN = 15.0
STEP = np.zeros((16, 3))
STEP[0] = (10.0, 0.0, TURN)  # gait 0: 10 units straight ahead, then 15° right
FORWARD = chrom(gene("00", G(0), G(0), G(0), G(0)))
"""Every robot walks gait 0 forever."""
C = (200.0, 275.0)
"""Robot 0's centre; it faces east (heading 90°), so gait 0's d = (10, 0)."""
R2 = math.sqrt(0.5)


def first_move(starts, colony):
    """Robot 0's pose after its first gait 0 (the others not yet moved), from the interpreter's
    ``TableColony`` and from the kernel (one colony step of one gait step each, robot 0
    first); checks that the two agree; returns (pose, blocked)."""
    starts = np.asarray(starts, dtype=float)
    colony = dataclasses.replace(colony, robots=len(starts))
    world = TableColony(STEP, starts, WORLD, colony)
    blocked = world.step(0, 0)
    ev = evaluate_colony(
        FORWARD[None], starts[None], table=STEP, mode="coverage", max_steps=1, colony=colony
    )
    np.testing.assert_array_equal(ev.final_pose[0, 0, 0], world.pose(0))
    assert ev.collisions[0, 0, 0] == blocked
    return world.pose(0), blocked


def test_a_move_blocked_at_45_degrees_slides_along_the_tangent():
    # The other robot 31 units from C at 45° south of east: n = (−1/√2, 1/√2); the move's end
    # (210, 275) is 24.9 from it. d·n = −10/√2, so d' = d − (d·n) n = (10, 0) + (10/√2)·n =
    # (5, 5): the robot ends at (205, 280), 31.8 from the other, heading 90 + 15.
    other = (C[0] + 31 * R2, C[1] - 31 * R2, 0.0)
    starts = [(*C, 90.0), other]
    pose, blocked = first_move(starts, SLIDE)
    assert blocked
    assert pose[:2] == pytest.approx((205.0, 280.0), abs=1e-9)
    assert pose[2] == pytest.approx(90.0 + TURN, abs=1e-12)
    # by the formula, with n from the centres as given
    n = np.subtract(C, other[:2]) / np.linalg.norm(np.subtract(C, other[:2]))
    d = np.array([10.0, 0.0])
    assert pose[:2] == pytest.approx(tuple(C + d - (d @ n) * n), abs=1e-9)
    # cancel: the whole pose is kept
    pose, blocked = first_move(starts, CANCEL)
    assert blocked and pose == (*C, 90.0)


def test_a_head_on_move_slides_by_nothing():
    # d = (10, 0) = −10 n: its tangential component is 0; the heading still turns.
    pose, blocked = first_move([(*C, 90.0), (C[0] + 31, C[1], 0.0)], SLIDE)
    assert blocked
    assert pose[:2] == pytest.approx(C, abs=1e-12)
    assert pose[2] == 90.0 + TURN


@pytest.mark.parametrize("colony", [CANCEL, SLIDE])
def test_a_move_away_is_never_blocked(colony):
    # facing west, away from a robot 31 units east: it walks 10 west
    pose, blocked = first_move([(*C, 270.0), (C[0] + 31, C[1], 0.0)], colony)
    assert not blocked
    assert pose == pytest.approx((C[0] - 10, C[1], 270 + TURN), abs=1e-12)


def test_two_blockers_or_a_slid_end_that_still_overlaps_cancel():
    # two robots 31 from C, 45° either side of east: both block the end (210, 275)
    a = (C[0] + 31 * R2, C[1] - 31 * R2, 0.0)
    b = (C[0] + 31 * R2, C[1] + 31 * R2, 0.0)
    pose, blocked = first_move([(*C, 90.0), a, b], SLIDE)
    assert blocked and pose == (*C, 90.0)
    # one blocks the end; the slid end (205, 280) is 29 from a robot at (205, 309), which does
    # not block the move's own end (34.4 away)
    pose, blocked = first_move([(*C, 90.0), a, (205.0, 309.0, 0.0)], SLIDE)
    assert blocked and pose == (*C, 90.0)
    # without that third robot the move slides
    pose, _ = first_move([(*C, 90.0), a, (205.0, 312.0, 0.0)], SLIDE)
    assert pose[:2] == pytest.approx((205.0, 280.0), abs=1e-9)


def test_slide_unlocks_two_robots_walking_into_each_other():
    # Face to face, offset 10 north-south: under cancel they lock for good (SPEC §7), under
    # slide they pass each other.
    starts = np.array([[[200.0, 270.0, 90.0], [250.0, 280.0, 270.0]]])
    kw = dict(table=STEP * [1, 1, 0], mode="coverage", max_steps=12)
    cancel = evaluate_colony(FORWARD[None], starts, colony=CANCEL, **kw)
    slide = evaluate_colony(FORWARD[None], starts, colony=SLIDE, **kw)
    assert cancel.collisions[0, 0].tolist() == [11, 11]  # from their second step on
    assert cancel.final_pose[0, 0, :, 0].tolist() == pytest.approx([210, 240], abs=1e-12)
    assert slide.collisions[0, 0].tolist() == [3, 2]  # they slide round each other
    assert slide.final_pose[0, 0, 0, 0] > 290 and slide.final_pose[0, 0, 1, 0] < 150


# --------------------------------------------------------------------------- kernel = interpreter


@pytest.mark.parametrize("robots", [2, 3])
def test_random_colonies_slide_alike_in_kernel_and_interpreter(robots):
    rng = np.random.default_rng(170 + robots)
    colony = ColonySettings(robots=robots, blocking="slide")
    genomes = rng.integers(0, 2, size=(300, 16, 30), dtype=np.uint8)
    genomes[:100, 0, :9] = [0, 0, 1, 1, 0, 0, 0, 0, 0]  # gene 0 ×∞, first: if low-power goto 8
    starts = np.concatenate(
        [colony_starts(rng, 2, WORLD, colony), colony_starts(rng, 2, NEAR_STATION, colony)]
    )
    ev = assert_colony_kernel_equals_interpreter(genomes, starts, colony=colony, start_power=3.95)
    assert ev.collisions.sum() > 500 and ev.docks.sum() > 0
    cancel = evaluate_colony(genomes, starts, table=PAPER_TABLE, mode="coverage",
                             colony=dataclasses.replace(colony, blocking="cancel"),
                             start_power=3.95)  # fmt: skip
    assert (cancel.final_pose != ev.final_pose).any(axis=(2, 3)).mean() > 0.05
    assert cancel.collisions.sum() > ev.collisions.sum()


def test_sliding_colonies_in_an_envelope_match():
    """Every envelope aspect on, the station block seen and stopping: a slid move into the
    block is cancelled alike."""
    rng = np.random.default_rng(179)
    colony = ColonySettings(blocking="slide")
    genomes = rng.integers(0, 2, size=(100, 16, 30), dtype=np.uint8)
    genomes[:, 0, :9] = [0, 0, 1, 1, 0, 0, 0, 0, 0]
    starts = colony_starts(rng, 3, NEAR_STATION, colony)
    envelope = Envelope(scatter_scale=1.0, bias_scale=1.0, station_seen_p=1.0, reach_units=8.0,
                        station_stops=True)  # fmt: skip
    ev = assert_colony_kernel_equals_interpreter(
        genomes, starts, colony=colony, start_power=3.95, envelope=envelope, envelope_key=(2, 9)
    )
    assert ev.docks.sum() > 20 and ev.collisions.sum() > 100


def test_one_sliding_robot_is_the_lone_kernel_bit_for_bit():
    rng = np.random.default_rng(178)
    one = ColonySettings(robots=1, blocking="slide")
    genomes = rng.integers(0, 2, size=(500, 16, 30), dtype=np.uint8)
    genomes[:200, 0, :9] = [0, 0, 1, 1, 0, 0, 0, 0, 0]
    starts = colony_starts(rng, 8, NEAR_STATION, one)
    kw = dict(table=PAPER_TABLE, mode="coverage", start_power=3.95)
    col = evaluate_colony(genomes, starts, colony=one, **kw)
    lone = evaluate(genomes, starts[:, 0], **kw)
    for f in ("squares", "inner_squares"):
        np.testing.assert_array_equal(getattr(col, f), getattr(lone, f), err_msg=f)
    for f in ("steps", "docks", "end", "final_pose"):
        np.testing.assert_array_equal(getattr(col, f)[:, :, 0], getattr(lone, f), err_msg=f)
    assert lone.docks.sum() > 100 and col.collisions.sum() == 0
    res = run_colony(genomes[0], TableColony(PAPER_TABLE, starts[0], WORLD, one), colony=one,
                     start_power=3.95)  # fmt: skip
    assert res.robots[0].final_pose == tuple(lone.final_pose[0, 0])


# --------------------------------------------------------------------------- the setting


def test_blocking_is_validated_and_recorded_only_when_not_cancel():
    with pytest.raises(SettingsError, match="blocking must be one of 'cancel', 'slide'"):
        ColonySettings(blocking="bounce")
    assert ColonySettings().blocking == "cancel" and ColonySettings().blocking_code == 0
    assert SLIDE.blocking_code == 1
    # cancel: the record of a colony made before the field existed, so old run folders resume
    record = json.loads(settings_json(ColonySettings()))["ColonySettings"]
    assert "blocking" not in record
    assert record == {k: v for k, v in dataclasses.asdict(ColonySettings()).items()
                      if k not in ("blocking", "fitness", "alive_weight", "dock_weight",
                                   "dock_cap", "start_power_spread", "sections",
                                   "robots_seen", "contact_yaw_deg")}  # fmt: skip
    assert json.loads(settings_json(SLIDE))["ColonySettings"]["blocking"] == "slide"


def test_the_comparison_command_runs(tmp_path, capsys):
    from evolve.blocking_compare import main
    from evolve.codec import write_chromosome

    path = write_chromosome(tmp_path / "c.txt", FORWARD)
    assert main([str(path), "--starts", "4", "--robots", "2"]) == 0
    out = capsys.readouterr().out
    assert "4 colony starts of 2" in out and "cancel: colony inner" in out
    assert "slide : colony inner" in out and "of them cancelled" in out
