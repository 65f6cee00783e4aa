"""Colonies whose robots carry different chromosomes (a team, ``evolve.coevolution``): the
kernel (``evaluate_colony(..., partners=, role=)``) equals the interpreter's ``run_colony``
given one chromosome per robot, run by run and robot by robot; a team of one chromosome is
the colony of that chromosome bit for bit."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from chromosome_text import chrom
from test_colony_kernel import COLONY, NEAR_STATION, WORLD, assert_colony_kernel_equals_interpreter

from evolve import evaluate_colony
from evolve.envelope import Envelope
from evolve.settings import ColonySettings
from evolve.starts import colony_starts
from evolve.table import PAPER_TABLE

STAND = chrom()
"""A chromosome that stands still for ever (gait 7 in every gene)."""
EVALUATION_FIELDS = ("squares", "inner_squares", "colony_steps", "robot_squares", "steps",
                     "docks", "end", "collisions", "station_waits", "final_pose")  # fmt: skip


@pytest.mark.parametrize("role", [0, 1, 2])
def test_random_teams_match_the_interpreter(role):
    rng = np.random.default_rng(40 + role)
    genomes = rng.integers(0, 2, size=(150, 16, 30), dtype=np.uint8)
    partners = rng.integers(0, 2, size=(3, 16, 30), dtype=np.uint8)
    ev = assert_colony_kernel_equals_interpreter(
        genomes, colony_starts(rng, 2, WORLD, COLONY), partners=partners, role=role
    )
    assert ev.collisions.sum() > 20


def test_teams_meeting_at_the_station_match_in_an_envelope():
    """Partners that head for the station at once (low power, gene 0 jumps to navigation)
    and individuals that do the same, a wide docking box and long charges: docking, waits
    and collisions between different programs, sliding, with every envelope aspect on."""
    rng = np.random.default_rng(44)
    genomes = rng.integers(0, 2, size=(100, 16, 30), dtype=np.uint8)
    partners = rng.integers(0, 2, size=(3, 16, 30), dtype=np.uint8)
    for bits in (genomes, partners):
        bits[:, 0, :9] = [0, 0, 1, 1, 0, 0, 0, 0, 0]  # gene 0 ×∞, first: if low-power goto 8
    starts = colony_starts(rng, 3, NEAR_STATION, COLONY)
    envelope = Envelope(scatter_scale=1.0, bias_scale=1.0, station_seen_p=1.0, reach_units=8.0,
                        station_stops=True)  # fmt: skip
    ev = assert_colony_kernel_equals_interpreter(
        genomes, starts, start_power=3.95, envelope=envelope, envelope_key=(2, 9),
        partners=partners, role=1, world=dataclasses.replace(NEAR_STATION, dock_y_half_width=60.0),
        colony=ColonySettings(blocking="slide", charge_steps=40),
    )  # fmt: skip
    assert ev.docks.sum() > 20 and ev.station_waits.sum() > 0


def test_a_team_of_one_chromosome_is_its_colony_bit_for_bit():
    rng = np.random.default_rng(45)
    genomes = rng.integers(0, 2, size=(60, 16, 30), dtype=np.uint8)
    starts = colony_starts(rng, 3, WORLD, COLONY)
    alone = evaluate_colony(genomes, starts, table=PAPER_TABLE, mode="coverage")
    for i in (0, 7, 59):
        team = np.repeat(genomes[i : i + 1], 3, axis=0)
        for role in range(3):
            got = evaluate_colony(genomes[i : i + 1], starts, table=PAPER_TABLE,
                                  mode="coverage", partners=team, role=role)  # fmt: skip
            for f in EVALUATION_FIELDS:
                np.testing.assert_array_equal(getattr(got, f)[0], getattr(alone, f)[i], f)


def test_standing_partners_leave_the_colony_to_the_individual():
    """Partners that stand still never leave their start poses or dock, and reach at most
    their start squares, whatever the individual does: robot ``role`` is the only one that
    moves."""
    rng = np.random.default_rng(46)
    genomes = rng.integers(0, 2, size=(40, 16, 30), dtype=np.uint8)
    starts = colony_starts(rng, 2, WORLD, COLONY)
    partners = np.repeat(STAND[None], 3, axis=0)
    ev = evaluate_colony(genomes, starts, table=PAPER_TABLE, mode="coverage",
                         partners=partners, role=2)  # fmt: skip
    others = [0, 1]
    np.testing.assert_array_equal(ev.final_pose[:, :, others], np.broadcast_to(
        starts[None, :, others], ev.final_pose[:, :, others].shape))  # fmt: skip
    still = ev.robot_squares[:, :, others]
    assert (still <= 1).all() and (still == still[:1]).all()
    assert (ev.docks[:, :, others] == 0).all()
    assert (ev.robot_squares[:, :, 2] > 1).any()


@pytest.mark.parametrize(
    ("partners", "role", "message"),
    [
        (np.zeros((2, 16, 30), np.uint8), 0, "one chromosome per robot"),
        (np.zeros((3, 8, 30), np.uint8), 0, "one chromosome per robot"),
        (np.zeros((3, 16, 30), np.uint8), 3, "role must name a robot"),
        (np.full((3, 16, 30), 2, np.uint8), 0, "partners"),
    ],
)
def test_bad_partners_are_named(partners, role, message):
    rng = np.random.default_rng(47)
    starts = colony_starts(rng, 1, WORLD, COLONY)
    with pytest.raises(ValueError, match=message):
        evaluate_colony(np.zeros((1, 16, 30), np.uint8), starts, table=PAPER_TABLE,
                        mode="coverage", partners=partners, role=role)  # fmt: skip


def test_the_interpreter_refuses_a_team_of_the_wrong_size():
    from evolve.interpreter import run_colony
    from evolve.world import TableColony

    rng = np.random.default_rng(48)
    start = colony_starts(rng, 1, WORLD, COLONY)[0]
    world = TableColony(PAPER_TABLE, start, WORLD, COLONY)
    with pytest.raises(ValueError, match="a team of 2 chromosomes for a colony of 3"):
        run_colony(np.zeros((2, 16, 30), np.uint8), world)
