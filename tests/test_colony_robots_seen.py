"""Whether the object sensors see the other robots (``ColonySettings.robots_seen``, issue 17):
True is SPEC §7; False leaves the walls and a seen station block in the object sensors, and the
other robots still block. Hand-worked colonies in the interpreter and the kernel, the kernel
against the interpreter on random colonies with the robots unseen (cancel and slide, in an
envelope), the physics colony's rays passing above the robots, the setting's validation and
record, and the CLI options."""

from __future__ import annotations

import json

import numpy as np
import pytest
from chromosome_text import B, G, chrom, gene
from test_colony_fitness import tiny_colony_cli
from test_colony_kernel import (
    assert_colony_kernel_equals_interpreter,
    assert_station_colonies_match,
)

from evolve import evaluate_colony
from evolve.codec import write_chromosome
from evolve.settings import ColonySettings, SettingsError, WorldSettings, settings_json
from evolve.starts import colony_starts
from evolve.table import PAPER_TABLE
from evolve.world import TableColony
from infra.errors import InputError

WORLD = WorldSettings()
SEEN = ColonySettings(robots=2)
UNSEEN = ColonySettings(robots=2, robots_seen=False)
TURNS = np.zeros((16, 3))
TURNS[0] = (0.0, 0.0, 15.0)  # gait 0: turn 15° right on the spot
TURNS[1] = (0.0, 0.0, -15.0)  # gait 1: turn 15° left on the spot
TURNS[8] = (10.0, 0.0, 0.0)  # gait 8: 10 units straight ahead
LOOK = chrom(gene("00", B(3, 1), G(0), G(0), G(0)), gene("00", G(1), G(1), G(1), G(1)))
"""If both object sensors are active, turn left (gene 1), else turn right."""
AHEAD = np.array([[250.0, 250.0, 90.0], [288.0, 250.0, 270.0]])
"""Robot 1's centre 38 units east of robot 0, which faces it: the nearest point of its disc 23
units away, inside both object spans' 50, and no wall within 50 units of robot 0."""


def first_heading(chromosome, starts, colony):
    """Robot 0's heading after its first gait step, from the kernel and the interpreter's
    ``TableColony`` (which must agree), and whether the move was blocked."""
    table = TableColony(TURNS, starts, WORLD, colony)
    sees = table.object_sensors(0)
    ev = evaluate_colony(chromosome[None], starts[None], table=TURNS, mode="coverage",
                         max_steps=1, colony=colony)  # fmt: skip
    return float(ev.final_pose[0, 0, 0, 2]), bool(ev.collisions[0, 0, 0]), sees


def test_a_robot_ahead_is_seen_or_not_and_the_branch_follows():
    assert first_heading(LOOK, AHEAD, SEEN) == (75.0, False, (True, True))
    assert first_heading(LOOK, AHEAD, UNSEEN) == (105.0, False, (False, False))
    # A wall stays seen: 30 units from the east wall, facing it, with no robot near.
    wall = np.array([[470.0, 100.0, 90.0], [100.0, 400.0, 0.0]])
    assert first_heading(LOOK, wall, UNSEEN) == (75.0, False, (True, True))


def test_an_unseen_robot_still_blocks():
    walk = chrom(gene("00", G(8), G(8), G(8), G(8)))
    for colony in (UNSEEN, ColonySettings(robots=2, robots_seen=False, blocking="slide")):
        # gait 8 would end 28 units from robot 1's centre: cancelled (head-on, slid by nothing)
        assert first_heading(walk, AHEAD, colony)[:2] == (90.0, True)
        ev = evaluate_colony(walk[None], AHEAD[None], table=TURNS, mode="coverage",
                             max_steps=1, colony=colony)  # fmt: skip
        np.testing.assert_array_equal(ev.final_pose[0, 0, 0], AHEAD[0])


@pytest.mark.parametrize("blocking", ["cancel", "slide"])
def test_random_unseen_colonies_match_the_interpreter(blocking):
    rng = np.random.default_rng(311)
    colony = ColonySettings(robots_seen=False, blocking=blocking)
    genomes = rng.integers(0, 2, size=(300, 16, 30), dtype=np.uint8)
    starts = colony_starts(rng, 2, WORLD, colony)
    unseen = assert_colony_kernel_equals_interpreter(genomes, starts, colony=colony)
    assert unseen.collisions.sum() > 50
    seen = evaluate_colony(genomes, starts, table=PAPER_TABLE, mode="coverage",
                           colony=ColonySettings(blocking=blocking))  # fmt: skip
    # the sensors change what the robots do in some runs, not in all
    differ = (seen.final_pose != unseen.final_pose).any(axis=(2, 3))
    assert 0 < differ.mean() < 1


def test_unseen_colonies_meeting_at_the_station_match_in_an_envelope():
    """Robots that dock, wait, slide and bump into a seen, stopping station block."""
    colony = ColonySettings(robots_seen=False, blocking="slide", start_power_spread=0.5)
    ev = assert_station_colonies_match(312, colony, (4, 1))
    assert ev.docks.sum() > 20 and ev.collisions.sum() > 50 and ev.station_waits.sum() > 0


def test_the_physics_rays_pass_above_unseen_robots():
    from servo_mj.world.arena import SHELL
    from servo_mj.world.physics_colony import PhysicsColony

    starts = [[200.0, 250.0, 90.0], [240.0, 250.0, 0.0]]  # nearest point of robot 1: 25 cm
    seen = PhysicsColony(starts, colony_settings=SEEN)
    unseen = PhysicsColony(starts, colony_settings=UNSEEN)
    assert seen.object_sensors(0) == (True, True) and unseen.object_sensors(0) == (False, False)
    ranges = np.concatenate(unseen.ray_ranges_cm(0))
    assert ranges[ranges >= 0].min(initial=np.inf) > 250.0  # the west face of the east wall
    with pytest.raises(KeyError):
        unseen.model.geom("servobot1/" + SHELL)
    bumper = unseen.bumpers[1]
    assert unseen.model.geom_rgba[bumper, 3] == 0.0  # rangefinders skip alpha-0 geoms
    # Pushing into robot 1, robot 0 is blocked and still does not see it.
    for _ in range(3):
        assert unseen.step(0, 8) is True
        assert unseen.object_sensors(0) == (False, False)
    assert 29.5 < unseen.min_distance_cm < 30.5


def test_an_unseen_colony_validates_and_records_without_shells(tmp_path):
    from servobot.validation.colony import validate_colony
    from tests.test_recording import Rrd

    starts = np.array([[[200.0, 250.0, 90.0], [240.0, 250.0, 0.0]]])
    rep = validate_colony(chrom(gene("00", G(8), G(8), G(8), G(8))), starts, table=PAPER_TABLE,
                          colony=UNSEEN, workers=1, max_steps=2, out_dir=tmp_path,
                          rrd=True)  # fmt: skip
    assert rep["runs"][0]["error"] is None
    assert rep["settings"]["ColonySettings"]["robots_seen"] is False
    assert rep["runs"][0]["physics"]["colony"]["collisions"] > 0  # robot 0 pushes robot 1
    rrd = Rrd(tmp_path / "run0.rrd")
    assert not [k for k in rrd.static if k.endswith("/shell")]  # seen: one per robot
    assert rrd.rows["/world/robots/robot1/bodies/torso"] > 0


def test_the_setting_is_validated_and_recorded_only_when_false():
    with pytest.raises(SettingsError, match="robots_seen must be true or false, got 'no'"):
        ColonySettings(robots_seen="no")
    assert "robots_seen" not in json.loads(settings_json(ColonySettings()))["ColonySettings"]
    record = json.loads(settings_json(UNSEEN))["ColonySettings"]
    assert record["robots_seen"] is False and ColonySettings(**record) == UNSEEN


def test_the_cli_options(tmp_path, capsys):
    from servobot.cli import validate as validate_cli
    from servobot.cli.evolve import main

    tiny = tiny_colony_cli(tmp_path)
    out = tmp_path / "run"
    assert main(["colony", *tiny, "--robots-unseen", "--out", str(out)]) == 0
    summary = json.loads((out / "colony/summary.json").read_text())
    assert summary["settings"]["ColonySettings"]["robots_seen"] is False
    capsys.readouterr()
    assert main(["coverage", *tiny, "--robots-unseen", "--out", str(tmp_path / "no")]) == 2
    assert "--robots-unseen is an option of the colony stage" in capsys.readouterr().err
    chromosome = write_chromosome(tmp_path / "c.txt", LOOK)
    parse = validate_cli.build_parser().parse_args
    args = parse([str(chromosome), "--robots", "2", "--robots-unseen"])
    assert validate_cli._colony(args) == UNSEEN
    with pytest.raises(InputError, match=r"--robots-unseen is an option of a colony \(--robots"):
        validate_cli._colony(parse([str(chromosome), "--robots-unseen"]))
