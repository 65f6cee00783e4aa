"""The contact yaw (``ColonySettings.contact_yaw_deg``, issue 17): a move that robots block
also turns the robot away from them. Hand-worked turns in ``geometry``, the interpreter and
the kernel; the kernel against the interpreter on random colonies (cancel and slide, in an
envelope at the station); MuJoCo turning a robot away from the robot it walks into (what the
rule models, ``calibration.contact_yaw``); the setting's validation, record and options."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from chromosome_text import G, chrom, gene
from test_colony_fitness import tiny_colony_cli
from test_colony_kernel import (
    assert_colony_kernel_equals_interpreter,
    assert_station_colonies_match,
)

from evolve import evaluate_colony, geometry
from evolve.codec import write_chromosome
from evolve.settings import ColonySettings, SettingsError, WorldSettings, settings_json
from evolve.starts import colony_starts
from evolve.table import PAPER_TABLE
from evolve.world import TableColony
from infra.errors import InputError

WORLD = WorldSettings()
AHEAD10 = np.zeros((16, 3))
AHEAD10[8] = (10.0, 0.0, 0.0)  # gait 8: 10 units straight ahead, no turn
WALK = chrom(gene("00", G(8), G(8), G(8), G(8)))
START = np.array([[200.0, 200.0, 0.0], [221.0, 224.0, 0.0]])
"""Robot 1 front-right of robot 0 (facing north): 31.9 units apart, 25.2 after robot 0's step
of gait 8 (to (200, 210)): blocked. Bearing b with sin b = 21 / 31.9 (clockwise, + = right)."""
TURN = -10.0 * 21.0 / math.hypot(21.0, 24.0)
"""Robot 0's turn with ``contact_yaw_deg`` 10: −10 · sin b ≈ −6.58° (away, to the left)."""


def test_contact_yaw_turns_away_from_the_contact():
    at = (100.0, 100.0)
    assert geometry.contact_yaw(*at, 0.0, 130.0, 100.0, 9.0) == -9.0  # abeam right: turn left
    assert geometry.contact_yaw(*at, 0.0, 70.0, 100.0, 9.0) == 9.0  # abeam left: turn right
    assert geometry.contact_yaw(*at, 0.0, 100.0, 130.0, 9.0) == 0.0  # dead ahead: no turn
    assert geometry.contact_yaw(*at, 90.0, 100.0, 70.0, 9.0) == pytest.approx(-9.0)  # facing east
    assert geometry.contact_yaw(*at, 0.0, 110.0, 110.0, 9.0) == pytest.approx(-9.0 / math.sqrt(2))
    assert geometry.contact_yaw(*at, 0.0, *at, 9.0) == 0.0


def first_pose(colony):
    """Robot 0's pose after one step of gait 8 from ``START``, kernel and interpreter."""
    table = TableColony(AHEAD10, START, WORLD, colony)
    blocked = table.step(0, 8)
    ev = evaluate_colony(WALK[None], START[None], table=AHEAD10, mode="coverage", max_steps=1,
                         colony=colony)  # fmt: skip
    np.testing.assert_array_equal(ev.final_pose[0, 0, 0], table.pose(0))
    assert blocked and ev.collisions[0, 0, 0] == 1
    return table.pose(0)


@pytest.mark.parametrize("blocking", ["cancel", "slide"])
def test_a_blocked_move_turns_by_the_hand_worked_angle(blocking):
    plain = first_pose(ColonySettings(robots=2, blocking=blocking))
    turned = first_pose(ColonySettings(robots=2, blocking=blocking, contact_yaw_deg=10.0))
    assert turned[:2] == plain[:2]  # where the move ends is the blocking rule's
    assert plain[2] == 0.0 and turned[2] == pytest.approx(360.0 + TURN, abs=1e-12)
    if blocking == "cancel":
        assert plain[:2] == (200.0, 200.0)
    else:  # slid along the contact tangent, to the left of robot 1
        assert plain[0] < 200.0 and plain[1] > 200.0


def test_an_unblocked_move_does_not_turn():
    free = np.array([[200.0, 200.0, 0.0], [300.0, 300.0, 0.0]])
    table = TableColony(AHEAD10, free, WORLD, ColonySettings(robots=2, contact_yaw_deg=10.0))
    assert table.step(0, 8) is False and table.pose(0) == (200.0, 210.0, 0.0)


@pytest.mark.parametrize("blocking", ["cancel", "slide"])
def test_random_colonies_with_the_contact_yaw_match_the_interpreter(blocking):
    rng = np.random.default_rng(411)
    colony = ColonySettings(blocking=blocking, contact_yaw_deg=9.3, robots_seen=False)
    genomes = rng.integers(0, 2, size=(300, 16, 30), dtype=np.uint8)
    starts = colony_starts(rng, 2, WORLD, colony)
    yawed = assert_colony_kernel_equals_interpreter(genomes, starts, colony=colony)
    assert yawed.collisions.sum() > 50
    plain_colony = ColonySettings(blocking=blocking, robots_seen=False)
    plain = evaluate_colony(genomes, starts, table=PAPER_TABLE, mode="coverage",
                            colony=plain_colony)  # fmt: skip
    differ = (plain.final_pose != yawed.final_pose).any(axis=(2, 3))
    assert 0 < differ.mean() < 1  # the runs whose robots touch change, and only those


def test_colonies_at_the_station_with_the_contact_yaw_match_in_an_envelope():
    colony = ColonySettings(blocking="slide", contact_yaw_deg=9.3, start_power_spread=0.5)
    ev = assert_station_colonies_match(412, colony, (5, 2))
    assert ev.docks.sum() > 20 and ev.collisions.sum() > 50


def test_mujoco_turns_a_robot_away_from_the_robot_it_walks_into():
    """What the rule models: gait 8 (straight ahead) into a robot 45° front-right turns the
    walker left of its free turn, into one front-left turns it right (or not left), in
    physics (mean over the three headings)."""
    from calibration.contact_yaw import measure, summary_lines

    turns = measure((8,))
    right = np.mean([t.extra_deg for t in turns if t.bearing > 0])
    left = np.mean([t.extra_deg for t in turns if t.bearing < 0])
    assert right < -3.0 and left > -0.5
    assert len(turns) == 6 and all(abs(t.free_deg) < 3.0 for t in turns)  # gait 8 walks straight
    assert summary_lines(turns)[-1].startswith("contact yaw abeam Y = ")


def test_the_setting_is_validated_and_recorded_only_when_not_zero():
    for bad in (-1.0, math.nan, math.inf, "9"):
        with pytest.raises(SettingsError, match="contact_yaw_deg must be a finite number ≥ 0"):
            ColonySettings(contact_yaw_deg=bad)
    assert "contact_yaw_deg" not in json.loads(settings_json(ColonySettings()))["ColonySettings"]
    yawed = ColonySettings(contact_yaw_deg=9.3)
    record = json.loads(settings_json(yawed))["ColonySettings"]
    assert record["contact_yaw_deg"] == 9.3 and ColonySettings(**record) == yawed


def test_the_cli_options(tmp_path, capsys):
    from servobot.cli import validate as validate_cli
    from servobot.cli.evolve import main

    tiny = tiny_colony_cli(tmp_path)
    out = tmp_path / "run"
    assert main(["colony", *tiny, "--contact-yaw", "9.3", "--out", str(out)]) == 0
    summary = json.loads((out / "colony/summary.json").read_text())
    assert summary["settings"]["ColonySettings"]["contact_yaw_deg"] == 9.3
    capsys.readouterr()
    assert main(["coverage", *tiny, "--contact-yaw", "9", "--out", str(tmp_path / "no")]) == 2
    assert "--contact-yaw is an option of the colony stage" in capsys.readouterr().err
    assert main(["colony", *tiny, "--contact-yaw", "-2", "--out", str(tmp_path / "no")]) == 2
    assert "--contact-yaw must be a finite number ≥ 0 (degrees), got -2" in capsys.readouterr().err
    chromosome = write_chromosome(tmp_path / "c.txt", WALK)
    parse = validate_cli.build_parser().parse_args
    args = parse([str(chromosome), "--robots", "2", "--contact-yaw", "9.3"])
    assert validate_cli._colony(args) == ColonySettings(robots=2, contact_yaw_deg=9.3)
    with pytest.raises(InputError, match=r"--contact-yaw is an option of a colony \(--robots"):
        validate_cli._colony(parse([str(chromosome), "--contact-yaw", "9"]))
