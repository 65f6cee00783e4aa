"""The colony kernel (``evolve.evaluate_colony``) equals the reference interpreter's
``run_colony`` run by run, robot by robot; with one robot it equals the lone kernel
(``evolve.evaluate``) bit for bit."""

from __future__ import annotations

import dataclasses

import numpy as np
from chromosome_text import LIGHT_FOLLOWER
from test_kernel import numba_threads

from evolve import evaluate, evaluate_colony
from evolve.codec import parse_chromosome
from evolve.envelope import NONE, Envelope
from evolve.ga import next_generation, random_sections
from evolve.interpreter import END_BRANCH_LIMIT, END_KILL_ZONE, END_POWER_EMPTY, run_colony
from evolve.settings import ColonySettings, GASettings, WorldSettings, with_table_power
from evolve.starts import colony_starts
from evolve.table import PAPER_TABLE
from evolve.world import TableColony

WORLD = WorldSettings()
COLONY = ColonySettings()
NEAR_STATION = dataclasses.replace(WORLD, coverage_start_x=(400, 470), coverage_start_y=(190, 310))
"""Colony starts close to the station, so that robots dock, meet there and wait."""
ROBOT_FIELDS = ("robot_squares", "robot_inner_squares", "steps", "docks", "end", "collisions",
                "station_waits")  # fmt: skip


def _robot_values(res, field):
    name = {"robot_squares": "squares", "robot_inner_squares": "inner_squares",
            "station_waits": "station_waits"}.get(field, field)  # fmt: skip
    return [getattr(r, name) for r in res.robots]


def assert_colony_kernel_equals_interpreter(
    genomes, starts, *, mode="coverage", table=PAPER_TABLE, world=WORLD, colony=COLONY,
    envelope=NONE, envelope_key=(0, 0), partners=None, role=0, **kw,
):  # fmt: skip
    """Compare every (individual, colony start) run, robot by robot, in ``envelope`` (with
    ``partners``: robot ``role`` carries the individual, the others their partner); returns
    the evaluation."""
    env = dict(envelope=envelope, envelope_key=envelope_key)
    team = {} if partners is None else dict(partners=partners, role=role)
    ev = evaluate_colony(
        genomes, starts, table=table, mode=mode, settings=world, colony=colony, **env, **team,
        **kw,
    )  # fmt: skip
    for i in range(genomes.shape[0]):
        bits = genomes[i]
        if partners is not None:
            bits = partners.copy()
            bits[role] = genomes[i]
        for s in range(starts.shape[0]):
            res = run_colony(
                bits, TableColony(table, starts[s], world, colony, start=s, **env),
                mode=mode, settings=world, colony=colony, **kw,
            )  # fmt: skip
            got = (ev.squares[i, s], ev.inner_squares[i, s], ev.colony_steps[i, s])
            want = (res.squares, res.inner_squares, res.colony_steps)
            assert got == want, (i, s, got, want)
            for f in ROBOT_FIELDS:
                assert getattr(ev, f)[i, s].tolist() == _robot_values(res, f), (i, s, f)
            final = [r.final_pose for r in res.robots]
            np.testing.assert_array_equal(ev.final_pose[i, s], final, err_msg=f"{i} {s}")
    return ev


STATION_ENVELOPE = Envelope(scatter_scale=1.0, bias_scale=1.0, station_seen_p=1.0,
                            reach_units=8.0, station_stops=True,
                            station_blocking="slide")  # fmt: skip
"""Every aspect on, the station block seen and stopping, slid along."""


def assert_station_colonies_match(seed, colony, envelope_key):
    """150 random colonies of 3 starting near the station on low power (gene 0 first: if
    low power go to the navigation section), in ``STATION_ENVELOPE``: the kernel equals the
    interpreter; returns the evaluation."""
    rng = np.random.default_rng(seed)
    genomes = rng.integers(0, 2, size=(150, 16, 30), dtype=np.uint8)
    genomes[:, 0, :9] = [0, 0, 1, 1, 0, 0, 0, 0, 0]  # gene 0 ×∞, first: if low-power goto 8
    return assert_colony_kernel_equals_interpreter(
        genomes, colony_starts(rng, 3, NEAR_STATION, colony), colony=colony, start_power=3.95,
        envelope=STATION_ENVELOPE, envelope_key=envelope_key,
    )  # fmt: skip

def test_random_colonies_match():
    rng = np.random.default_rng(21)
    genomes = rng.integers(0, 2, size=(400, 16, 30), dtype=np.uint8)
    ev = assert_colony_kernel_equals_interpreter(genomes, colony_starts(rng, 2, WORLD, COLONY))
    assert {END_KILL_ZONE, END_POWER_EMPTY, END_BRANCH_LIMIT} <= set(np.unique(ev.end).tolist())
    assert ev.collisions.sum() > 100 and ev.docks.sum() > 0
    # the union is at least each robot's own squares and at most their sum
    assert (ev.squares >= ev.robot_squares.max(axis=2)).all()
    assert (ev.squares <= ev.robot_squares.sum(axis=2)).all()
    assert (ev.squares < ev.robot_squares.sum(axis=2)).any()


def test_colonies_meeting_at_the_station_match():
    """Coverage runs that switch to navigation at once, near the station: docking, charging
    and waiting happen often; with a wider docking box and long charges very often."""
    rng = np.random.default_rng(22)
    genomes = rng.integers(0, 2, size=(250, 16, 30), dtype=np.uint8)
    genomes[:, 0, :9] = [0, 0, 1, 1, 0, 0, 0, 0, 0]  # gene 0 ×∞, first: if low-power goto 8
    starts = colony_starts(rng, 3, NEAR_STATION, COLONY)
    ev = assert_colony_kernel_equals_interpreter(genomes, starts, start_power=3.95)
    assert ev.docks.sum() > 100 and ev.station_waits.sum() > 0
    wide = dataclasses.replace(NEAR_STATION, dock_y_half_width=60.0)
    long = ColonySettings(charge_steps=40)
    ev = assert_colony_kernel_equals_interpreter(
        genomes[:120], starts, world=wide, colony=long, start_power=3.95
    )
    assert ev.station_waits.sum() > 100 and (ev.station_waits.sum(axis=2) > 0).sum() > 30


def test_colonies_meeting_at_the_station_match_in_an_envelope():
    """As above in an envelope of variation (SPEC §9) with every aspect on, the station block
    always there and stopping: robots dock, wait, bump into each other and into the block."""
    rng = np.random.default_rng(27)
    genomes = rng.integers(0, 2, size=(120, 16, 30), dtype=np.uint8)
    genomes[:, 0, :9] = [0, 0, 1, 1, 0, 0, 0, 0, 0]  # gene 0 ×∞, first: if low-power goto 8
    starts = colony_starts(rng, 3, NEAR_STATION, COLONY)
    envelope = Envelope(scatter_scale=1.0, bias_scale=1.0, station_seen_p=1.0, reach_units=8.0,
                        station_stops=True)  # fmt: skip
    ev = assert_colony_kernel_equals_interpreter(
        genomes, starts, start_power=3.95, envelope=envelope, envelope_key=(2, 9)
    )
    assert ev.docks.sum() > 20 and ev.collisions.sum() > 100


def test_other_colony_sizes_settings_and_navigation_mode_match():
    rng = np.random.default_rng(23)
    sections = rng.integers(0, 2, size=(200, 8, 30), dtype=np.uint8)
    nav = dataclasses.replace(COLONY, robots=4)
    starts = colony_starts(rng, 2, dataclasses.replace(WORLD, coverage_start_x=(250, 450)), nav)
    ev = assert_colony_kernel_equals_interpreter(sections, starts, mode="navigation", colony=nav)
    assert set(np.unique(ev.end).tolist()) == {0, 1, 2, 3, 4}
    genomes = rng.integers(0, 2, size=(150, 16, 30), dtype=np.uint8)
    two = ColonySettings(robots=2, disc_radius=25.0, start_separation=55.0, charge_steps=3,
                         colony_step_limit=250)  # fmt: skip
    table = PAPER_TABLE * rng.uniform(0.8, 1.2, size=PAPER_TABLE.shape)
    per_gait = with_table_power(WORLD, rng.uniform(0.005, 0.04, 16))  # issue 10's power model
    assert_colony_kernel_equals_interpreter(
        genomes, colony_starts(rng, 2, WORLD, two), table=table, world=per_gait, colony=two
    )


def test_evolved_colonies_match():
    """A colony population evolved for 20 generations on colony squares, with a navigation
    section that docks, then the kernel against the interpreter on its best individuals."""
    rng = np.random.default_rng(24)
    nav = np.broadcast_to(parse_chromosome(LIGHT_FOLLOWER), (48, 8, 30))
    pop = random_sections(rng, 48)
    pop[:, 0, :9] = [0, 0, 1, 1, 0, 0, 0, 0, 0]  # gene 0 ×∞, first: if low-power goto 8
    ga = GASettings(population_size=48)
    for _ in range(20):
        genomes = np.concatenate([pop, nav], axis=1)
        ev = evaluate_colony(genomes, colony_starts(rng, 4, WORLD, COLONY), table=PAPER_TABLE,
                             mode="coverage")  # fmt: skip
        fitness = ev.squares.mean(axis=1).astype(float)
        pop = next_generation(pop, fitness, rng, ga)
    best = np.argsort(-fitness)[:12]
    genomes = np.concatenate([pop[best], nav[:12]], axis=1)
    ev = assert_colony_kernel_equals_interpreter(genomes, colony_starts(rng, 3, WORLD, COLONY))
    # selected for colony squares: about 18 a run, against 4–6 for random chromosomes
    assert ev.squares.mean() > 15 and ev.docks.sum() >= 5 and ev.collisions.sum() > 0


def test_one_robot_colony_equals_the_lone_kernel_bit_for_bit():
    rng = np.random.default_rng(25)
    one = ColonySettings(robots=1)
    genomes = rng.integers(0, 2, size=(1500, 16, 30), dtype=np.uint8)
    genomes[:500, 0, :9] = [0, 0, 1, 1, 0, 0, 0, 0, 0]  # these dock and charge
    for world, power in ((WORLD, 4.0), (NEAR_STATION, 3.95)):
        starts = colony_starts(rng, 8, world, one)
        col = evaluate_colony(genomes, starts, table=PAPER_TABLE, mode="coverage",
                              start_power=power, colony=one)  # fmt: skip
        lone = evaluate(genomes, starts[:, 0], table=PAPER_TABLE, mode="coverage",
                        start_power=power)  # fmt: skip
        for f in ("squares", "inner_squares"):
            np.testing.assert_array_equal(getattr(col, f), getattr(lone, f), err_msg=f)
        for f in ("steps", "docks", "end", "final_pose"):
            np.testing.assert_array_equal(getattr(col, f)[:, :, 0], getattr(lone, f), err_msg=f)
        np.testing.assert_array_equal(col.robot_squares[:, :, 0], lone.squares)
        assert lone.docks.sum() > 500
        assert col.collisions.sum() == col.station_waits.sum() == 0


def test_deterministic_and_thread_count_independent():
    rng = np.random.default_rng(26)
    genomes = rng.integers(0, 2, size=(64, 16, 30), dtype=np.uint8)
    starts = colony_starts(rng, 10, WORLD, COLONY)
    a = evaluate_colony(genomes, starts, table=PAPER_TABLE, mode="coverage")
    with numba_threads(1):
        b = evaluate_colony(genomes, starts, table=PAPER_TABLE, mode="coverage")
    for f in dataclasses.fields(a):
        assert np.array_equal(getattr(a, f.name), getattr(b, f.name)), f.name
    assert a.squares.shape == (64, 10) and a.final_pose.shape == (64, 10, 3, 3)
    assert a.steps.shape == (64, 10, 3) and a.steps.dtype.kind == "i"
