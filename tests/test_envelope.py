"""The envelope of variation (SPEC §9): ``none`` is the world of §3 bit for bit, the kernels
equal the interpreter with every aspect on, the draws are keyed as the SPEC says, each aspect
does what it claims (hand-worked scatter, the block seen at 49 and not 51 units, scatter and
bias statistics, bias held for a run, the block stopping a move), the stages report both
worlds and resume bit for bit, and bad inputs are refused by name."""

from __future__ import annotations

import dataclasses
import json
import math

import numpy as np
import pytest
from chromosome_text import LIGHT_FOLLOWER, B, G, chrom, gene
from envelope_workload import (
    COLONY,
    EXPECTED,
    LONE_FIELDS,
    START_POWER,
    WORLD,
    results,
    workload,
)
from run_folder import result_files

from evolve import evaluate, evaluate_colony, stages
from evolve.codec import OBJECT_LEFT, OBJECT_RIGHT, parse_chromosome
from evolve.colony_stage import run_colony_stage
from evolve.draws import MASK64, absorb, fold, mix64, normal3, unit
from evolve.envelope import (
    DEFAULT,
    NONE,
    SHIPPED_STD,
    Envelope,
    EnvelopeError,
    envelope_sigma,
    key_of_test,
    load_envelope,
    shipped_std,
    station_block,
)
from evolve.geometry import block_bits, block_stops, oval_box_gauge2, pack_world, wrap180
from evolve.interpreter import END_KILL_ZONE, END_POWER_EMPTY, run, run_colony
from evolve.population import PopulationRun, evaluate_sections
from evolve.settings import ColonySettings, GASettings
from evolve.table import PAPER_TABLE, GaitTable, load_table, table_to_json
from evolve.variation import (
    STATION_SEEN,
    STATION_STOPS,
    STREAM_SCATTER,
    Variation,
    scattered_row,
)  # fmt: skip
from evolve.world import TableColony, TableWorld
from infra.rundir import RunDirError

EVERYTHING = Envelope(
    scatter_scale=1.0, bias_scale=1.0, station_seen_p=0.5, reach_units=5.0, station_stops=True
)
"""Every aspect on, the station block stopping motion."""
LOUD = Envelope(scatter_scale=2.5, bias_scale=1.5, station_seen_p=0.8, reach_units=12.0)
"""Larger scales, a block that is only seen."""
IN_THE_WAY = Envelope(
    scatter_scale=1.0, station_seen_p=0.5, reach_units=5.0, station_stops="always"
)
"""The block seen in half the runs and in the way in every run, as in physics."""
HALF_IN_THE_WAY = dataclasses.replace(IN_THE_WAY, station_stops=True, unseen_stops_p=0.5)
"""The block in the way in every seen run and in half the unseen ones."""
SLIDING = dataclasses.replace(
    HALF_IN_THE_WAY, station_blocking="slide", pace_spread=0.15, turn_spread=0.3
)
"""As ``HALF_IN_THE_WAY``, a move the block stops sliding along it, pace and turn drawn."""
SHORT_STRIDES = PAPER_TABLE * np.array([0.85, 0.85, 1.1])
TURNS_LESS = PAPER_TABLE * np.array([1.0, 1.0, 0.7])
"""Two robot variants' tables: strides 15 % shorter and turns 10 % wider; turns 30 % smaller."""
VARIANTS = Envelope(variant_p=0.6, variant_tables=(SHORT_STRIDES.tolist(), TURNS_LESS.tolist()))
"""A run's robot one of the two variants in 60 % of the runs."""
EVERY_ENVELOPE = pytest.mark.parametrize(
    "envelope",
    [EVERYTHING, LOUD, IN_THE_WAY, HALF_IN_THE_WAY, SLIDING,
     dataclasses.replace(SLIDING, station_margin=3.0),
     dataclasses.replace(SLIDING, body_front=20.0, body_back=14.0, body_side=11.0),
     dataclasses.replace(SLIDING, bias_scale=1.0, variant_p=0.6,
                         variant_tables=VARIANTS.variant_tables)],
    ids=["everything", "loud", "in the way", "half in the way", "sliding, paced",
         "sliding, margin 3", "sliding, oval body", "sliding, biased robot variants"],
)  # fmt: skip
"""The kernel = interpreter cases: every aspect, loud scales, the block's stop rules."""
KEY = (7, 3)
SCATTER_ONLY = Envelope(scatter_scale=1.0)
BIAS_ONLY = Envelope(bias_scale=1.0)
BLOCK_ONLY = Envelope(station_seen_p=1.0)
STOPS_ONLY = Envelope(station_seen_p=1.0, station_stops=True)
SLIDES_ONLY = dataclasses.replace(STOPS_ONLY, station_blocking="slide")
OBJECT_BOTH_THEN_BACK = chrom(
    gene("00", B(3, 1), G(7), G(7), G(7)), gene("00", G(15), G(15), G(15), G(15))
)
"""Gene 0: if both object sensors are active go to gene 1 (walk backwards), else stand still."""


@pytest.fixture(scope="module")
def work():
    return workload()


def _lone_interpreted(genomes, starts, mode, **kw):
    """The interpreter's (squares, inner, steps, docks, end, final pose) per run, (P, S)."""
    env = {k: kw.pop(k) for k in ("envelope", "envelope_key") if k in kw}
    out = {f: np.zeros(genomes.shape[:1] + starts.shape[:1], dtype=object) for f in LONE_FIELDS}
    collisions = 0
    for i in range(genomes.shape[0]):
        for s in range(starts.shape[0]):
            r = run(genomes[i], TableWorld(PAPER_TABLE, *starts[s], start=s, **env), mode=mode,
                    **kw)  # fmt: skip
            vals = (r.squares, r.inner_squares, r.steps, r.docks, r.end, r.final_pose)
            for f, v in zip(LONE_FIELDS, vals, strict=True):
                out[f][i, s] = v
            collisions += r.collisions
    return out, collisions


def _assert_lone_equal(ev, ref, rows=slice(None)):
    for f in LONE_FIELDS[:-1]:
        np.testing.assert_array_equal(np.asarray(getattr(ev, f))[rows], ref[f].astype(np.int64),
                                      err_msg=f)  # fmt: skip
    poses = np.array(ref["final_pose"].tolist(), dtype=float)
    np.testing.assert_array_equal(ev.final_pose[rows], poses, err_msg="final_pose")


def _colony_interpreted(genomes, starts, ev, **kw):
    """Compare ``ev`` with ``run_colony`` run by run, robot by robot; block collisions."""
    env = {k: kw.pop(k) for k in ("envelope", "envelope_key") if k in kw}
    for i in range(genomes.shape[0]):
        for s in range(starts.shape[0]):
            world = TableColony(PAPER_TABLE, starts[s], None, COLONY, start=s, **env)
            res = run_colony(genomes[i], world, colony=COLONY, **kw)
            got = (ev.squares[i, s], ev.inner_squares[i, s], ev.colony_steps[i, s],
                   ev.steps[i, s].tolist(), ev.docks[i, s].tolist(), ev.end[i, s].tolist(),
                   ev.collisions[i, s].tolist(), ev.station_waits[i, s].tolist(),
                   ev.final_pose[i, s].tolist())  # fmt: skip
            want = (res.squares, res.inner_squares, res.colony_steps,
                    [r.steps for r in res.robots], [r.docks for r in res.robots],
                    [r.end for r in res.robots], [r.collisions for r in res.robots],
                    [r.station_waits for r in res.robots],
                    [list(r.final_pose) for r in res.robots])  # fmt: skip
            assert got == want, (i, s)


# --------------------------------------------------------------------------- none = §3


def test_none_is_the_stored_pre_envelope_world_bit_for_bit_in_the_kernels(work):
    """4000 runs (lone coverage near and far from the station, navigation, colonies of 3) equal
    the results the code computed before envelopes existed; with NONE given explicitly, by
    default, and whatever the key."""
    expected = np.load(EXPECTED)
    for kw in ({}, {"envelope": NONE}, {"envelope": NONE, "envelope_key": (99, -5, 3)}):
        got = results(work, **kw)
        assert set(got) == set(expected.files)
        for name in expected.files:
            if name.endswith("final_pose"):
                np.testing.assert_allclose(got[name], expected[name], rtol=0, atol=1e-9)
            else:
                np.testing.assert_array_equal(got[name], expected[name], err_msg=name)


def test_none_is_the_stored_pre_envelope_world_in_the_interpreter(work):
    expected = np.load(EXPECTED)
    lone, _ = _lone_interpreted(work.coverage, work.coverage_starts, "coverage",
                                start_power=START_POWER, envelope=NONE)  # fmt: skip
    nav, _ = _lone_interpreted(work.navigation, work.navigation_starts, "navigation")
    for prefix, ref in (("coverage", lone), ("navigation", nav)):
        for f in LONE_FIELDS[:-1]:
            np.testing.assert_array_equal(ref[f].astype(np.int64), expected[f"{prefix}_{f}"])
        poses = np.array(ref["final_pose"].tolist(), dtype=float)
        np.testing.assert_allclose(poses, expected[f"{prefix}_final_pose"], rtol=0, atol=1e-9)
    assert expected["coverage_docks"].sum() > 100  # the sample docks and backs up often


# --------------------------------------------------------------------------- kernel = interpreter


@EVERY_ENVELOPE
def test_lone_kernel_equals_interpreter_in_an_envelope(work, envelope):
    g, st = work.coverage[:300], work.coverage_starts
    ev = evaluate(g, st, table=PAPER_TABLE, mode="coverage", start_power=START_POWER,
                  envelope=envelope, envelope_key=KEY)  # fmt: skip
    ref, blocked = _lone_interpreted(g, st, "coverage", start_power=START_POWER,
                                     envelope=envelope, envelope_key=KEY)  # fmt: skip
    _assert_lone_equal(ev, ref)
    assert ev.docks.sum() > 20
    assert (blocked > 100) == bool(envelope.station_stops)  # only a block that stops stops
    nav = work.navigation[:400]
    ev = evaluate(nav, work.navigation_starts, table=PAPER_TABLE, mode="navigation",
                  envelope=envelope, envelope_key=KEY)  # fmt: skip
    ref, _ = _lone_interpreted(nav, work.navigation_starts, "navigation", envelope=envelope,
                               envelope_key=KEY)  # fmt: skip
    _assert_lone_equal(ev, ref)
    assert set(np.unique(ev.end).tolist()) == {0, 1, 2, 3, 4}


@EVERY_ENVELOPE
def test_colony_kernel_equals_interpreter_in_an_envelope(work, envelope):
    g, st = work.colony[:120], work.colony_starts
    ev = evaluate_colony(g, st, table=PAPER_TABLE, mode="coverage", start_power=START_POWER,
                         colony=COLONY, envelope=envelope, envelope_key=KEY)  # fmt: skip
    _colony_interpreted(g, st, ev, start_power=START_POWER, envelope=envelope, envelope_key=KEY)
    assert ev.collisions.sum() > 100 and ev.docks.sum() > 5


def test_one_robot_colony_equals_the_lone_kernel_in_an_envelope(work):
    one = ColonySettings(robots=1)
    starts = work.colony_starts[:, :1]
    kw = dict(table=PAPER_TABLE, mode="coverage", start_power=START_POWER, envelope=EVERYTHING,
              envelope_key=KEY)  # fmt: skip
    col = evaluate_colony(work.coverage, starts, colony=one, **kw)
    lone = evaluate(work.coverage, starts[:, 0], **kw)
    for f in ("steps", "docks", "end", "final_pose"):
        np.testing.assert_array_equal(getattr(col, f)[:, :, 0], getattr(lone, f), err_msg=f)
    np.testing.assert_array_equal(col.squares, lone.squares)


# --------------------------------------------------------------------------- keys


def test_draws_are_shared_by_individuals_and_differ_between_starts_and_generations():
    rng = np.random.default_rng(31)
    pop = rng.integers(0, 2, size=(40, 16, 30), dtype=np.uint8)
    pop[::4] = pop[0]  # ten copies of one genome, among others
    start = np.array([[400.0, 250.0, 30.0]])
    starts = np.repeat(start, 3, axis=0)  # one pose at three start indices
    kw = dict(table=PAPER_TABLE, mode="coverage", envelope=LOUD)
    ev = evaluate(pop, starts, envelope_key=(5, 0), **kw)
    # every copy, wherever it stands in the population, meets the same draws at each start
    for f in LONE_FIELDS:
        a = np.asarray(getattr(ev, f))
        assert (a[::4] == a[0]).all(), f
    alone = evaluate(pop[:1], starts, envelope_key=(5, 0), **kw)
    np.testing.assert_array_equal(alone.final_pose[0], ev.final_pose[0])
    # the same pose at another start index, or in another generation, meets other draws
    poses = ev.final_pose[0]
    assert len({tuple(p) for p in poses}) == 3
    other = evaluate(pop[:1], starts, envelope_key=(5, 1), **kw).final_pose[0]
    assert not (other == poses).all(axis=1).any()
    again = evaluate(pop[:1], starts, envelope_key=(5, 0), **kw).final_pose[0]
    np.testing.assert_array_equal(again, poses)  # and a run repeats alone


def test_the_counter_hash_is_splitmix64_with_uint64_wraparound():
    # splitmix64's first output from seed 0 (Vigna's reference implementation)
    assert mix64(0x9E3779B97F4A7C15) == 0xE220A8397B1DCDAF
    rng = np.random.default_rng(0)
    words = rng.integers(0, 2**63, size=200, dtype=np.uint64) * np.uint64(2) + np.uint64(1)
    with np.errstate(over="ignore"):
        for z in words:
            a = (z ^ (z >> np.uint64(30))) * np.uint64(0xBF58476D1CE4E5B9)
            b = (a ^ (a >> np.uint64(27))) * np.uint64(0x94D049BB133111EB)
            assert mix64(int(z)) == int(b ^ (b >> np.uint64(31)))
    assert all(0 <= absorb(h, -1) <= MASK64 for h in (0, MASK64))  # negative words wrap
    assert len({fold((3, g)) for g in range(1000)} | {fold(key_of_test(3, "figure9"))}) == 1001
    assert 0.0 <= unit(0) < unit(MASK64) < 1.0


def test_test_keys_never_meet_a_generation():
    for test in ("figure9", "selection", "docking", "colony_final", "punctuation"):
        key = key_of_test(4, test)
        assert key[0] == 4 and key[1] < 0
    assert key_of_test(4, "punctuation", 32) == (4, -5, 32)


# --------------------------------------------------------------------------- aspects


def test_hand_worked_scatter_of_one_cycle():
    """Gait 0 once from (250, 250) facing north: the pose is the row plus σ·z, z the cycle's
    draw computed here from the key by hand."""
    start, pose = 2, (250.0, 250.0, 0.0)
    key = absorb(absorb(absorb(fold(KEY), start), 0), STREAM_SCATTER)
    z = normal3(absorb(key, 0), 0)  # cycle 0
    sigma = shipped_std()
    f, t, dh = (PAPER_TABLE[0, c] + 1.0 * sigma[0, c] * z[c] for c in range(3))
    # facing north (h = 0): x += T, y += F, h = dH mod 360
    want = (250.0 + t, 250.0 + f, dh % 360.0)
    assert abs(f - PAPER_TABLE[0, 0]) > 1e-3 and want[2] > 300.0  # a real draw, a left turn
    world = TableWorld(PAPER_TABLE, *pose, envelope=SCATTER_ONLY, envelope_key=KEY, start=start)
    world.step(0)
    np.testing.assert_allclose(world.pose(), want, rtol=0, atol=1e-12)
    walk = chrom(gene("00", G(0), G(0), G(0), G(0)))
    starts = np.array([(300.0, 300.0, 0.0)] * start + [pose])
    ev = evaluate(walk[None], starts, table=PAPER_TABLE, mode="coverage", max_steps=1,
                  envelope=SCATTER_ONLY, envelope_key=KEY)  # fmt: skip
    np.testing.assert_allclose(ev.final_pose[0, start], want, rtol=0, atol=1e-12)


def test_station_block_seen_at_49_units_not_51():
    x0 = station_block(WORLD)[0]
    assert (x0, station_block(WORLD)[1:]) == (480.0, (220.0, 500.0, 280.0))
    for dist, seen in ((49.0, True), (51.0, False)):
        pose = (x0 - dist, 250.0, 90.0)
        world = TableWorld(PAPER_TABLE, *pose, envelope=BLOCK_ONLY)
        assert world.object_sensors() == (seen, seen)
        assert TableWorld(PAPER_TABLE, *pose).object_sensors() == (False, False)  # no block
        # the kernel: both object sensors active → gene 1 walks backwards
        ev = evaluate(OBJECT_BOTH_THEN_BACK[None], np.array([pose]), table=PAPER_TABLE,
                      mode="coverage", max_steps=1, envelope=BLOCK_ONLY)  # fmt: skip
        moved = ev.final_pose[0, 0, 0] != pose[0]
        assert moved == seen


def test_block_sensing_agrees_with_a_dense_sampling_of_the_block():
    """``block_bits`` against brute force: every point of the block's outline at 0.01 units,
    with a margin of 0.05 units and 0.1° for the sampling."""
    p = pack_world(WORLD)
    x0, y0, x1, y1 = station_block(WORLD)
    edge = np.arange(0.0, 1.0, 1e-4)
    pts = np.concatenate([
        np.column_stack([x0 + (x1 - x0) * edge, np.full_like(edge, y0)]),
        np.column_stack([x0 + (x1 - x0) * edge, np.full_like(edge, y1)]),
        np.column_stack([np.full_like(edge, x0), y0 + (y1 - y0) * edge]),
        np.column_stack([np.full_like(edge, x1), y0 + (y1 - y0) * edge]),
    ])  # fmt: skip
    spans = (WORLD.object_left_span_deg, WORLD.object_right_span_deg)
    rng = np.random.default_rng(41)
    checked = 0
    for _ in range(400):
        x, y, h = rng.uniform(400, 479), rng.uniform(170, 330), rng.uniform(0, 360)
        reach = rng.uniform(40, 60)
        bits = block_bits(x, y, h, x0, y0, x1, y1, reach, p)
        d = np.hypot(pts[:, 0] - x, pts[:, 1] - y)
        rel = (np.degrees(np.arctan2(pts[:, 0] - x, pts[:, 1] - y)) - h + 180.0) % 360.0 - 180.0
        for k, (a, b) in enumerate(spans):
            inner = ((d <= reach - 0.05) & (rel >= a + 0.1) & (rel <= b - 0.1)).any()
            outer = ((d <= reach + 0.05) & (rel >= a - 0.1) & (rel <= b + 0.1)).any()
            active = bool(bits & (OBJECT_LEFT, OBJECT_RIGHT)[k])
            assert (not inner or active) and (not active or outer), (x, y, h, reach, k)
            checked += inner
    assert checked > 50  # many poses do see it


def test_reach_is_drawn_per_run_within_its_range():
    var = Variation.of(Envelope(reach_units=5.0), PAPER_TABLE, WORLD, KEY, 15.0)
    reach = np.array([var.robot(s, r).reach for s in range(500) for r in range(3)])
    assert reach.min() >= 45.0 and reach.max() <= 55.0
    assert reach.min() < 45.2 and reach.max() > 54.8 and abs(reach.mean() - 50.0) < 0.3
    assert var.robot(3, 1).reach == var.robot(3, 1).reach != var.robot(3, 2).reach


def test_station_is_seen_in_about_p_of_the_runs_and_by_every_robot_of_a_colony():
    var = Variation.of(Envelope(station_seen_p=0.3), PAPER_TABLE, WORLD, KEY, 15.0)
    seen = np.array([var.station_seen(s) for s in range(4000)])
    assert abs(seen.mean() - 0.3) < 0.03
    s = int(np.argmax(seen))
    starts = np.array([[400.0, 200.0, 0.0], [400.0, 250.0, 90.0], [400.0, 300.0, 0.0]])
    starts[:, 0] = station_block(WORLD)[0] - 40.0
    colony = TableColony(PAPER_TABLE, starts, envelope=Envelope(station_seen_p=0.3),
                         envelope_key=KEY, start=s)  # fmt: skip
    assert colony.object_sensors(1) == (True, True)  # robot 1 faces the block 40 units away
    plain = TableColony(PAPER_TABLE, starts, envelope=Envelope(station_seen_p=0.3),
                        envelope_key=KEY, start=int(np.argmin(seen)))  # fmt: skip
    assert plain.object_sensors(1) == (False, False)


def test_cycle_scatter_mean_and_std_match_the_table_rows_and_sigma():
    sigma = shipped_std()
    n = 4000
    for g in range(16):
        rows = np.array([
            scattered_row(*PAPER_TABLE[g], *sigma[g], 1.0, absorb(fold(KEY), g), c)
            for c in range(n)
        ])  # fmt: skip
        for c in range(3):
            if sigma[g, c] < 1e-6:  # gait 7 stands still: no spread
                assert np.allclose(rows[:, c], PAPER_TABLE[g, c], atol=1e-6)
                continue
            assert abs(rows[:, c].mean() - PAPER_TABLE[g, c]) < 4.0 * sigma[g, c] / math.sqrt(n)
            assert abs(rows[:, c].std() / sigma[g, c] - 1.0) < 0.06, (g, c)


def test_bias_is_held_for_a_run_and_spread_as_sigma_over_runs():
    world = TableWorld(PAPER_TABLE, 250.0, 100.0, 0.0, envelope=BIAS_ONLY, envelope_key=KEY)
    moves = []
    for _ in range(8):
        x, y, h = world.pose()
        world.step(9)
        nx, ny, nh = world.pose()
        r = math.radians(h)
        dx, dy = nx - x, ny - y
        moves.append((dx * math.sin(r) + dy * math.cos(r), dx * math.cos(r) - dy * math.sin(r),
                      wrap180(nh - h)))  # fmt: skip
    moves = np.array(moves)
    np.testing.assert_allclose(moves, np.broadcast_to(moves[0], moves.shape), atol=1e-9)
    assert np.abs(moves[0] - PAPER_TABLE[9]).min() > 1e-4  # every column biased
    var = Variation.of(BIAS_ONLY, PAPER_TABLE, WORLD, KEY, 15.0)
    np.testing.assert_allclose(moves[0], var.robot(0, 0).rows[9], atol=1e-9)
    offsets = np.array([var.robot(s, 0).rows - PAPER_TABLE for s in range(3000)])
    sigma = shipped_std()
    ok = sigma > 1e-6
    assert np.all(np.abs(offsets.mean(axis=0)[ok]) < 4.0 * sigma[ok] / math.sqrt(3000))
    assert np.all(np.abs(offsets.std(axis=0)[ok] / sigma[ok] - 1.0) < 0.08)


def test_pace_and_turn_scale_every_gait_by_one_factor_per_run():
    """``pace_spread`` 0.2: F and T of all 16 gaits × one factor in [0.8, 1.2] per run and
    robot, uniform; ``turn_spread`` 0.3: dH × another in [0.7, 1.3]; held by the table world
    for the whole run."""
    env = Envelope(pace_spread=0.2, turn_spread=0.3)
    var = Variation.of(env, PAPER_TABLE, WORLD, KEY, 15.0)
    moving = np.abs(PAPER_TABLE) > 0.05
    factors = []
    for s in range(2000):
        rows = var.robot(s, s % 3).rows
        ratio = np.where(moving, rows / np.where(moving, PAPER_TABLE, 1.0), np.nan)
        pace, turn = np.nanmean(ratio[:, :2]), np.nanmean(ratio[:, 2])
        np.testing.assert_allclose(ratio[:, :2][moving[:, :2]], pace, rtol=1e-12)
        np.testing.assert_allclose(ratio[:, 2][moving[:, 2]], turn, rtol=1e-12)
        factors.append((pace, turn))
    f = np.array(factors)
    assert f[:, 0].min() >= 0.8 and f[:, 0].max() < 1.2 and f[:, 1].min() >= 0.7
    # uniform: mean 1, std spread / √3, the two factors independent
    assert abs(f.mean(axis=0) - 1.0).max() < 0.01
    np.testing.assert_allclose(f.std(axis=0), np.array([0.2, 0.3]) / math.sqrt(3), rtol=0.05)
    assert abs(np.corrcoef(f.T)[0, 1]) < 0.06
    assert var.robot(5, 1).rows.tolist() != var.robot(5, 2).rows.tolist()  # per robot
    # the table world walks the run's rows: 8 cycles of gait 8 turn 8 × dH × turn
    world = TableWorld(PAPER_TABLE, 250.0, 100.0, 0.0, envelope=env, envelope_key=KEY, start=5)
    for _ in range(8):
        world.step(8)
    rows = var.robot(5, 0).rows
    assert world.pose()[2] == pytest.approx(8 * rows[8, 2] % 360.0, abs=1e-9)


def test_robot_variants_are_drawn_per_run_and_robot_and_walked_exactly():
    """``variant_p`` 0.6 over two variant tables: a run's robot walks the first in 30 % of the
    runs, the second in 30 %, the stage's table in the rest, its rows exactly the table's; the
    draw is one per run and robot, the same for every individual (it depends on the key, the
    start and the robot only), and the table world walks the drawn rows."""
    var = Variation.of(VARIANTS, PAPER_TABLE, WORLD, KEY, 15.0)
    tables = [PAPER_TABLE, SHORT_STRIDES, TURNS_LESS]
    picks = []
    for s in range(3000):
        rows = var.robot(s, s % 3).rows
        match = [k for k, t in enumerate(tables) if np.array_equal(rows, t)]
        assert len(match) == 1, s
        picks.append(match[0])
    share = np.bincount(picks, minlength=3) / len(picks)
    np.testing.assert_allclose(share, [0.4, 0.3, 0.3], atol=0.03)  # 3.5 binomial s.e.
    robots = [[int(np.array_equal(var.robot(s, r).rows, PAPER_TABLE)) for r in range(3)]
              for s in range(200)]  # fmt: skip
    assert any(len(set(row)) > 1 for row in robots)  # robots of one run draw apart
    same = Variation.of(VARIANTS, PAPER_TABLE, WORLD, KEY, 15.0)
    assert all(np.array_equal(same.robot(s, 0).rows, var.robot(s, 0).rows) for s in range(50))
    # a run on the short-stride robot walks as the plain world of that table: 8 cycles of
    # gait 0 turn it 8 × 1.1 × the paper's dH
    s = next(i for i in range(3000) if np.array_equal(var.robot(i, 0).rows, SHORT_STRIDES))
    world = TableWorld(PAPER_TABLE, 250.0, 100.0, 0.0, envelope=VARIANTS, envelope_key=KEY,
                       start=s)  # fmt: skip
    plain = TableWorld(SHORT_STRIDES, 250.0, 100.0, 0.0)
    for _ in range(8):
        world.step(0), plain.step(0)
    assert world.pose() == plain.pose()
    assert world.pose()[2] == pytest.approx(8 * 1.1 * PAPER_TABLE[0, 2] % 360.0, abs=1e-9)


def test_variant_tables_load_from_calibration_files_and_are_recorded_as_rows(tmp_path):
    cal = tmp_path / "slippery.json"
    cal.write_text(json.dumps(table_to_json(SHORT_STRIDES)))
    path = tmp_path / "env.json"
    path.write_text(json.dumps({"variant_p": 0.5, "variant_tables": [str(cal)]}))
    env = load_envelope(path)
    np.testing.assert_array_equal(np.array(env.variant_tables[0]), SHORT_STRIDES)
    doc = json.loads(env.to_json())
    assert doc["variant_tables"] == [SHORT_STRIDES.tolist()] and env.varies
    assert Envelope.from_dict(doc) == env
    assert "variant_p" not in DEFAULT.to_dict() and "variant_tables" not in DEFAULT.to_dict()


def test_station_stops_cancels_a_move_into_the_block():
    pose = (460.0, 250.0, 90.0)  # gait 0 would bring the centre to 471.6: 8.4 from the block
    world = TableWorld(PAPER_TABLE, *pose, envelope=STOPS_ONLY)
    assert world.step(0) is True and world.pose() == pose
    assert world.step(15) is False and world.pose()[0] < pose[0]  # backing away is allowed
    seen_only = TableWorld(PAPER_TABLE, *pose, envelope=BLOCK_ONLY)
    assert seen_only.step(0) is False and seen_only.pose()[0] > 470.0
    # the step still counts and costs power, as a colony's cancelled move
    walk = chrom(gene("00", G(0), G(0), G(0), G(0)))
    r = run(walk, TableWorld(PAPER_TABLE, *pose, envelope=STOPS_ONLY), mode="coverage",
            max_steps=3)  # fmt: skip
    assert (r.steps, r.collisions, r.final_pose) == (3, 3, pose)
    ev = evaluate(walk[None], np.array([pose]), table=PAPER_TABLE, mode="coverage", max_steps=3,
                  start_power=2.75, envelope=STOPS_ONLY)  # fmt: skip
    assert ev.steps[0, 0] == 3 and tuple(ev.final_pose[0, 0]) == pose
    assert ev.end[0, 0] == END_POWER_EMPTY  # 3 × 0.0209 V spent standing at the block
    plain = evaluate(walk[None], np.array([pose]), table=PAPER_TABLE, mode="coverage",
                     max_steps=3, start_power=2.75)  # fmt: skip
    assert (plain.end[0, 0], plain.steps[0, 0]) == (END_KILL_ZONE, 2)  # walked into the wall


def test_a_block_always_in_the_way_stops_unseen_and_stays_unseen():
    """``station_stops = "always"``: the block of an unseen station still stops a move (the
    low block of physics' ``shipped``), and the object sensors still do not see it."""
    pose = (460.0, 250.0, 90.0)
    unseen = Envelope(station_seen_p=0.0, station_stops="always")
    world = TableWorld(PAPER_TABLE, *pose, envelope=unseen)
    assert world.step(0) is True and world.pose() == pose
    far = (station_block(WORLD)[0] - 49.0, 250.0, 90.0)  # the seen block is in reach here
    assert TableWorld(PAPER_TABLE, *far, envelope=unseen).object_sensors() == (False, False)
    when_seen = TableWorld(PAPER_TABLE, *pose, envelope=Envelope(station_stops=True))
    assert when_seen.step(0) is False and when_seen.pose()[0] > 470.0
    walk = chrom(gene("00", G(0), G(0), G(0), G(0)))
    ev = evaluate(walk[None], np.array([pose] * 3), table=PAPER_TABLE, mode="coverage",
                  max_steps=3, start_power=2.75, envelope=unseen)  # fmt: skip
    assert (ev.end[:, 0] == END_POWER_EMPTY).all() and (ev.final_pose[:, 0] == pose).all()


def test_an_unseen_block_stops_in_about_unseen_stops_p_of_the_runs():
    """``unseen_stops_p``: a seen block always stops; an unseen one in about that fraction of
    the runs, drawn per run apart from the seen draw; 0 is ``True`` and 1 is ``"always"``."""

    def stations(env, n=4000):
        var = Variation.of(env, PAPER_TABLE, WORLD, KEY, 15.0)
        return np.array([var.station(s) for s in range(n)])

    half = Envelope(station_seen_p=0.5, station_stops=True, unseen_stops_p=0.3)
    got = stations(half)
    seen, stops = (got & STATION_SEEN) > 0, (got & STATION_STOPS) > 0
    np.testing.assert_array_equal(seen, stations(Envelope(station_seen_p=0.5)) > 0)
    assert stops[seen].all() and abs(stops[~seen].mean() - 0.3) < 0.035
    for p, same in ((0.0, True), (1.0, "always")):
        np.testing.assert_array_equal(
            stations(dataclasses.replace(half, unseen_stops_p=p)),
            stations(dataclasses.replace(half, station_stops=same, unseen_stops_p=0.0)),
        )
    # one run of each kind: the unseen block that stops cancels the move and stays unseen
    pose = (460.0, 250.0, 90.0)
    far = (station_block(WORLD)[0] - 49.0, 250.0, 90.0)
    stopping, free = int(np.argmax(~seen & stops)), int(np.argmax(~seen & ~stops))
    for s, stopped in ((stopping, True), (free, False)):
        world = TableWorld(PAPER_TABLE, *pose, envelope=half, envelope_key=KEY, start=s)
        assert world.step(0) is stopped and (world.pose() == pose) is stopped
        sensors = TableWorld(PAPER_TABLE, *far, envelope=half, envelope_key=KEY, start=s)
        assert sensors.object_sensors() == (False, False)
    starts = np.array([pose, (300.0, 100.0, 0.0), (300.0, 400.0, 0.0)])
    colony = TableColony(PAPER_TABLE, starts, envelope=half, envelope_key=KEY, start=stopping)
    assert colony.step(0, 0) is True  # one station for the colony


def test_a_move_the_block_stops_slides_along_its_face_and_round_its_corner():
    """``station_blocking = "slide"``: the stopped move loses its component into the block, its
    component along the face shrinks by ``station_friction`` (0.5) × the lost one, and the
    heading stays. At the west face (x = 480) the robot keeps its x and walks on north; at the
    north-west corner (480, 280) the normal points from the corner to the robot."""
    x0, _, _, y1 = station_block(WORLD)
    for pose in [(460.0, 250.0, 45.0), (470.0, 292.0, 100.0)]:
        open_world = TableWorld(PAPER_TABLE, *pose)
        open_world.step(0)
        d = np.array(open_world.pose()[:2]) - pose[:2]
        cx, cy = max(pose[0], x0), min(pose[1], y1)  # the block's point nearest the start
        n = np.array([pose[0] - cx, pose[1] - cy]) / math.hypot(pose[0] - cx, pose[1] - cy)
        into = d @ n
        assert into < 0.0  # the open move ends 12.4 and 10.8 units from the block: stopped
        along = d - into * n
        want = pose[:2] + along * (np.linalg.norm(along) + 0.5 * into) / np.linalg.norm(along)
        world = TableWorld(PAPER_TABLE, *pose, envelope=SLIDES_ONLY)
        assert world.step(0) is True  # blocked: slid, not cancelled
        np.testing.assert_allclose(world.pose(), (*want, pose[2]), rtol=0, atol=1e-12)
        cancel = TableWorld(PAPER_TABLE, *pose, envelope=STOPS_ONLY)
        assert cancel.step(0) is True and cancel.pose() == pose
    # at the face: d = (7.64, 8.77), 7.64 into the block, so 8.77 − 3.82 = 4.95 units north
    face = TableWorld(PAPER_TABLE, 460.0, 250.0, 45.0, envelope=SLIDES_ONLY)
    face.step(0)
    np.testing.assert_allclose(face.pose(), (460.0, 254.95, 45.0), rtol=0, atol=0.01)
    no_friction = dataclasses.replace(SLIDES_ONLY, station_friction=0.0)
    face = TableWorld(PAPER_TABLE, 460.0, 250.0, 45.0, envelope=no_friction)
    face.step(0)
    np.testing.assert_allclose(face.pose(), (460.0, 258.77, 45.0), rtol=0, atol=0.01)
    head_on = TableWorld(PAPER_TABLE, 462.0, 250.0, 90.0, envelope=SLIDES_ONLY)
    assert head_on.step(0) is True and head_on.pose()[:2] == (462.0, 250.0)  # friction holds
    # the kernel slides the same runs: three cycles up the face, the step still costs
    walk = chrom(gene("00", G(0), G(0), G(0), G(0)))
    ev = evaluate(walk[None], np.array([(460.0, 250.0, 45.0)]), table=PAPER_TABLE,
                  mode="coverage", max_steps=3, envelope=SLIDES_ONLY)  # fmt: skip
    r = run(walk, TableWorld(PAPER_TABLE, 460.0, 250.0, 45.0, envelope=SLIDES_ONLY),
            mode="coverage", max_steps=3)  # fmt: skip
    assert r.collisions == 3 and r.final_pose[0] == 460.0 and r.final_pose[2] == 45.0
    assert tuple(ev.final_pose[0, 0]) == r.final_pose and ev.steps[0, 0] == 3


def test_the_block_stops_a_centre_within_radius_plus_margin():
    """``station_margin`` 3: the block stops a centre closer than 15 + 3 units. Head-on (east),
    gait 0's open move ending 16.5 units from the west face is stopped with the margin and not
    without; one ending 18.5 units away is stopped by neither. The kernel agrees."""
    x0 = station_block(WORLD)[0]
    margin = dataclasses.replace(STOPS_ONLY, station_margin=3.0)
    walk = chrom(gene("00", G(0), G(0), G(0), G(0)))
    for gap, stopped in ((16.5, True), (18.5, False)):
        probe = TableWorld(PAPER_TABLE, 400.0, 250.0, 90.0)
        probe.step(0)
        pose = (400.0 + (x0 - gap) - probe.pose()[0], 250.0, 90.0)  # the open end `gap` away
        open_world = TableWorld(PAPER_TABLE, *pose)
        open_world.step(0)
        assert x0 - open_world.pose()[0] == pytest.approx(gap, abs=1e-9)
        assert TableWorld(PAPER_TABLE, *pose, envelope=STOPS_ONLY).step(0) is False
        world = TableWorld(PAPER_TABLE, *pose, envelope=margin)
        assert world.step(0) is stopped
        assert world.pose() == (pose if stopped else open_world.pose())
        ev = evaluate(walk[None], np.array([pose]), table=PAPER_TABLE, mode="coverage",
                      max_steps=1, envelope=margin)  # fmt: skip
        assert tuple(ev.final_pose[0, 0]) == world.pose()


def test_the_oval_body_gauge_hand_worked_and_against_a_dense_sampling_of_the_block():
    """``oval_box_gauge2`` for a robot (front a = 20, back 14, side b = 10) d = 12 units west
    of the block's face (x0 = 480) at y = 250: facing it (east) (d/a)²; side on (north, south)
    (d/b)²; turned away (west) (d/14)²; heading 45° the least over the face's points (480,
    250 + s), u = (d + s)/√2, v = (d − s)/√2, is at s = d (a² − b²)/(a² + b²) = 7.2:
    2d²/(a² + b²) = 0.576. Any pose: the least over a dense grid of the box's points."""
    box = station_block(WORLD)
    body = (20.0, 14.0, 10.0)
    for h, want in ((90.0, (12 / 20) ** 2), (0.0, (12 / 10) ** 2), (180.0, (12 / 10) ** 2),
                    (270.0, (12 / 14) ** 2), (45.0, 0.576)):  # fmt: skip
        assert oval_box_gauge2(468.0, 250.0, h, *box, *body) == pytest.approx(want, rel=1e-12)
    assert oval_box_gauge2(490.0, 250.0, 33.0, *box, *body) == 0.0  # centre in the block
    gx, gy = np.meshgrid(np.linspace(box[0], box[2], 201), np.linspace(box[1], box[3], 601))
    rng = np.random.default_rng(5)
    poses = zip(rng.uniform(440, 479, 40), rng.uniform(190, 310, 40), rng.uniform(0, 360, 40),
                strict=True)  # fmt: skip
    for x, y, h in poses:
        r = math.radians(h)
        u = (gx - x) * math.sin(r) + (gy - y) * math.cos(r)
        v = (gx - x) * math.cos(r) - (gy - y) * math.sin(r)
        dense = ((u / np.where(u > 0, body[0], body[1])) ** 2 + (v / body[2]) ** 2).min()
        got = oval_box_gauge2(x, y, h, *box, *body)
        assert got <= dense + 1e-12 and got == pytest.approx(dense, rel=2e-3, abs=1e-6)


def test_an_oval_as_wide_as_long_stops_the_moves_the_disc_stops():
    """Body 15/15/15 is the 15-unit disc: over random moves near the block the two rules stop
    the same ones, and the oval stops none past its reach."""
    box = station_block(WORLD)
    rng = np.random.default_rng(11)
    x, nx = rng.uniform(440, 500, (2, 4000))
    y, ny = rng.uniform(180, 320, (2, 4000))
    h, nh = rng.uniform(0, 360, (2, 4000))
    stopped = 0
    for k in range(4000):
        disc = block_stops(x[k], y[k], h[k], nx[k], ny[k], nh[k], *box, 15.0, 0.0, 0.0, 0.0)
        oval = block_stops(x[k], y[k], h[k], nx[k], ny[k], nh[k], *box, 99.0, 15.0, 15.0, 15.0)
        assert disc == oval
        stopped += disc
    assert stopped > 100


def test_an_oval_body_passes_the_corner_the_disc_cannot_and_meets_the_face_further_out():
    """Body 20/15/12 (``Envelope.body_*``). Walking east 13 units north of the block's north
    end (y 280), gait 0's move past its corner is stopped by the 15-unit disc, not by the oval
    12 units wide; head-on, a move ending 17 units from the face is stopped by the oval 20
    units long, not by the disc. The kernel agrees with the interpreter."""
    x0, y1 = station_block(WORLD)[0], station_block(WORLD)[3]
    oval = dataclasses.replace(STOPS_ONLY, body_front=20.0, body_back=15.0, body_side=12.0)
    probe = TableWorld(PAPER_TABLE, 400.0, 250.0, 90.0)
    probe.step(0)
    stride = probe.pose()[0] - 400.0
    walk = chrom(gene("00", G(0), G(0), G(0), G(0)))
    corner = (x0 + 2.0 - stride, y1 + 13.0, 90.0)  # the open move ends 2 units past x0
    head_on = (x0 - 17.0 - stride, 250.0, 90.0)  # … 17 units short of the face
    for pose, disc_stops in ((corner, True), (head_on, False)):
        assert TableWorld(PAPER_TABLE, *pose, envelope=STOPS_ONLY).step(0) is disc_stops
        world = TableWorld(PAPER_TABLE, *pose, envelope=oval)
        assert world.step(0) is (not disc_stops)
        open_world = TableWorld(PAPER_TABLE, *pose)
        open_world.step(0)
        assert world.pose() == (open_world.pose() if disc_stops else pose)  # passes or cancelled
        ev = evaluate(walk[None], np.array([pose]), table=PAPER_TABLE, mode="coverage",
                      max_steps=1, envelope=oval)  # fmt: skip
        assert tuple(ev.final_pose[0, 0]) == world.pose()


def test_a_slid_move_that_another_robot_blocks_is_cancelled():
    """In a colony the end of a move slid along the block must also be clear of the others."""
    pose = (460.0, 250.0, 45.0)
    free = TableColony(PAPER_TABLE, np.array([pose, (300.0, 100.0, 0.0)]), envelope=SLIDES_ONLY)
    assert free.step(0, 0) is True
    np.testing.assert_allclose(free.pose(0), (460.0, 254.95, 45.0), rtol=0, atol=0.01)
    # robot 1 is 32.8 units from the start and 32.6 from the open move's end, but 29.0 from
    # the slid end: closer than two radii (30), so the slid move is cancelled
    crowded = np.array([pose, (440.0, 276.0, 180.0)])
    colony = TableColony(PAPER_TABLE, crowded, envelope=SLIDES_ONLY)
    assert colony.step(0, 0) is True and colony.pose(0) == pose
    ev = evaluate_colony(chrom(gene("00", G(0), G(0), G(0), G(0)))[None], crowded[None],
                         table=PAPER_TABLE, mode="coverage", max_steps=1,
                         colony=ColonySettings(robots=2), envelope=SLIDES_ONLY)  # fmt: skip
    assert tuple(ev.final_pose[0, 0, 0]) == pose


# --------------------------------------------------------------------------- inputs


def test_named_and_file_envelopes_load(tmp_path):
    assert load_envelope("none") is NONE and load_envelope("default") is DEFAULT
    path = tmp_path / "env.json"
    path.write_text(json.dumps({"scatter_scale": 2, "station_stops": True}))
    env = load_envelope(path)
    assert env == Envelope(scatter_scale=2.0, station_stops=True)
    assert Envelope.from_dict(json.loads(env.to_json())) == env
    path.write_text(json.dumps({"station_seen_p": 0.5, "station_stops": "always"}))
    env = load_envelope(path)
    assert env.station_stops == "always" and env.varies
    assert Envelope.from_dict(json.loads(env.to_json())) == env
    assert not NONE.varies and DEFAULT.varies and DEFAULT.scatter_scale == 1.0


OVAL = {"body_front": 20, "body_back": 15, "body_side": 12}
"""An oval body's fields (``Envelope.body_*``)."""


@pytest.mark.parametrize(
    ("doc", "match"),
    [
        ({"scatter_scale": -1.0}, "scatter_scale must be ≥ 0"),
        ({"bias_scale": "big"}, "bias_scale must be a finite number"),
        ({"station_seen_p": 1.5}, "station_seen_p must be a probability"),
        ({"reach_units": True}, "reach_units must be a finite number"),
        ({"station_stops": 1}, 'station_stops must be true, false or "always"'),
        ({"station_stops": "sometimes"}, 'station_stops must be true, false or "always"'),
        ({"unseen_stops_p": 1.5}, "unseen_stops_p must be a probability"),
        ({"station_stops": True, "unseen_stops_p": "half"}, "unseen_stops_p must be a probability"),
        ({"unseen_stops_p": 0.5}, "unseen_stops_p 0.5 needs station_stops true"),
        ({"station_stops": "always", "unseen_stops_p": 0.5}, "needs station_stops true"),
        ({"station_stops": True, "station_blocking": "push"}, "station_blocking must be one of"),
        ({"station_blocking": "slide"}, "station_blocking 'slide' needs station_stops"),
        ({"station_stops": True, "station_friction": -0.5}, "station_friction must be a finite"),
        ({"station_stops": True, "station_margin": -1}, "station_margin must be ≥ 0"),
        ({"station_stops": True, "station_margin": "far"}, "station_margin must be a finite"),
        ({"station_margin": 3}, "station_margin 3 needs station_stops"),
        ({"station_stops": True, "body_front": 20}, "body_front, body_back and body_side must all"),
        ({"station_stops": True, **OVAL, "body_side": -12}, "body_side must be ≥ 0"),
        (OVAL, "an oval body .* needs station_stops"),
        ({"station_stops": True, "station_margin": 3, **OVAL}, "station_margin 3 widens the disc"),
        ({"pace_spread": 1.0}, r"pace_spread must be in \[0, 1\)"),
        ({"variant_p": 0.5}, r"variant_p \(0.5\) and variant_tables \(0 tables\) go together"),
        ({"variant_tables": [PAPER_TABLE.tolist()]}, r"variant_p \(0\) and variant_tables"),
        ({"variant_p": 1.5, "variant_tables": [PAPER_TABLE.tolist()]}, "variant_p must be a prob"),
        ({"variant_p": 0.5, "variant_tables": [PAPER_TABLE[:15].tolist()]},
         r"variant_tables\[0\]: rows: expected shape \(16, 3\)"),
        ({"variant_p": 0.5, "variant_tables": ["no/such/table.json"]},
         r"variant_tables\[0\]: .*no/such/table.json"),
        ({"variant_p": 0.5, "variant_tables": "runs/cal/gait_table.json"},
         "variant_tables must be a list"),
        ({"turn_spread": -0.1}, "turn_spread must be ≥ 0"),
        ({"draws_per_start": 1.5}, "draws_per_start must be an integer ≥ 1"),
        ({"warmup_fraction": -0.1}, "warmup_fraction must be ≥ 0"),
        ({"station_strata": "yes"}, "station_strata must be true or false"),
        ({"draw_fitness": "median"}, "draw_fitness must be one of mean, min"),
        ({"scatter": 1.0}, "unknown field 'scatter'"),
        ([1, 2], "a JSON object"),
    ],
)
def test_bad_envelope_files_are_refused_by_field_and_file(tmp_path, doc, match):
    path = tmp_path / "bad.json"
    path.write_text(json.dumps(doc))
    with pytest.raises(EnvelopeError, match=match) as err:
        load_envelope(path)
    assert str(path) in str(err.value)


def test_unreadable_envelope_files_and_bad_keys_are_refused(tmp_path):
    with pytest.raises(EnvelopeError, match="missing.json"):
        load_envelope(tmp_path / "missing.json")
    (tmp_path / "nan.json").write_text('{"scatter_scale": NaN}')
    with pytest.raises(EnvelopeError, match="nan.json"):
        load_envelope(tmp_path / "nan.json")
    far = Envelope(reach_units=60.0)
    with pytest.raises(EnvelopeError, match="reach_units 60 exceeds"):
        evaluate(np.zeros((1, 16, 30), np.uint8), np.array([[250.0, 250.0, 0.0]]),
                 table=PAPER_TABLE, mode="coverage", envelope=far)  # fmt: skip
    with pytest.raises(EnvelopeError, match="envelope_key"):
        TableWorld(PAPER_TABLE, 250.0, 250.0, 0.0, envelope=DEFAULT, envelope_key=(1.5, 2))


def test_a_table_without_std_is_refused_by_name(tmp_path):
    path = tmp_path / "no_std.json"
    path.write_text(json.dumps(table_to_json(PAPER_TABLE)))  # no F_std, T_std, dH_std
    table = load_table(path)
    with pytest.raises(EnvelopeError, match=r"no_std\.json: .*per-cycle std"):
        envelope_sigma(SCATTER_ONLY, table)
    bits = np.zeros((1, 16, 30), np.uint8)
    with pytest.raises(EnvelopeError, match=r"no_std\.json"):
        evaluate(bits, np.array([[250.0, 250.0, 0.0]]), table=table, mode="coverage",
                 envelope=BIAS_ONLY)  # fmt: skip
    with pytest.raises(EnvelopeError, match=r"no_std\.json"):
        stages.run_coverage(tmp_path / "run", navigation=parse_chromosome(LIGHT_FOLLOWER),
                            table=table, ga=GASettings(populations=1, population_size=4,
                            generations=1, test_starts=2), envelope=DEFAULT)  # fmt: skip
    assert not (tmp_path / "run").exists()  # refused before the folder was made
    # without scatter or bias the table needs no σ; a table with σ uses its own
    np.testing.assert_array_equal(envelope_sigma(BLOCK_ONLY, table), np.zeros((16, 3)))
    with_std = tmp_path / "std.json"
    with_std.write_text(json.dumps(table_to_json(PAPER_TABLE, np.full((16, 3), 0.5))))
    np.testing.assert_array_equal(envelope_sigma(DEFAULT, load_table(with_std)), 0.5)


@pytest.mark.slow
def test_shipped_std_equals_a_fresh_calibration_of_the_shipped_robot():
    """``evolve/data/shipped_std.json`` is what ``servobot calibrate`` measures today."""
    from calibration.measure import CalibrationSettings, measure_all, summarise
    from servo_mj.robot.model import model_sha256

    doc = json.loads(SHIPPED_STD.read_text())
    assert doc["model_sha256"] == model_sha256(), "the robot changed: recalibrate the file"
    settings = CalibrationSettings()
    assert doc["calibration"] == settings.to_dict()
    _, std = summarise(measure_all(workers=2, **settings.measure_kwargs()))
    np.testing.assert_allclose(shipped_std(), std[:, :3], rtol=1e-9, atol=1e-12)


# --------------------------------------------------------------------------- stages


TINY = GASettings(populations=2, population_size=10, generations=18, test_starts=12, seed=5)
"""18 generations: checkpoints at 0 and 16, saves at 0, 1 and 18."""


class Interrupt(Exception):
    pass


def _coverage(out, envelope=DEFAULT, **kw):
    nav = parse_chromosome(LIGHT_FOLLOWER)
    return stages.run_coverage(out, navigation=nav, table=load_table("paper"), ga=TINY,
                               envelope=envelope, **kw)  # fmt: skip


def test_coverage_stage_in_an_envelope_reports_both_worlds_and_resumes_bit_for_bit(tmp_path):
    ref = _coverage(tmp_path / "ref")
    folder = tmp_path / "ref/coverage"
    settings = json.loads((folder / "settings.json").read_text())
    assert settings["Envelope"] == DEFAULT.to_dict()
    assert ref["envelope"] == DEFAULT.to_dict()
    for key in ("figure9_mean_inner_percent", "final_mean_inner_percent", "final_inner_percent"):
        assert f"envelope_{key}" in ref and key in ref
    assert ref["envelope_figure9_inner_percent"] != ref["figure9_inner_percent"]
    # the existing keys are the world of §3: the saved bests on the test starts without it
    stage = stages.coverage_stage(WORLD, parse_chromosome(LIGHT_FOLLOWER))
    test_seq, _ = stages.stage_seeds(TINY.seed, "coverage", TINY.populations)
    starts = stage.starts(np.random.Generator(np.random.PCG64(test_seq)), TINY.test_starts,
                          WORLD)  # fmt: skip
    plain = stages.figure9_test(folder, stage, load_table("paper"), WORLD, (0, 1, 18), 2, starts)
    np.testing.assert_array_equal(plain[0], ref["figure9_inner_percent"])
    csv_head = (folder / "figure9.csv").read_text().splitlines()[0]
    assert csv_head == "population,generation,inner_percent,envelope_inner_percent"
    assert "envelope_mean_inner_percent" in json.loads((folder / "figure9.json").read_text())

    def kill_at(info):
        if info["population"] == 1 and info["generation"] == 17:
            raise Interrupt

    cut = tmp_path / "cut"
    with pytest.raises(Interrupt):
        _coverage(cut, on_generation=kill_at)
    with pytest.raises(RunDirError, match="Envelope"):
        _coverage(cut, envelope=LOUD, resume=True)  # another envelope is another run
    _coverage(cut, resume=True)
    assert result_files(tmp_path / "ref") == result_files(cut)


def test_a_stage_without_an_envelope_writes_what_it_wrote_before(tmp_path):
    summary = _coverage(tmp_path, envelope=NONE)
    folder = tmp_path / "coverage"
    assert "Envelope" not in json.loads((folder / "settings.json").read_text())
    assert not any(k.startswith("envelope") for k in summary)
    assert (folder / "figure9.csv").read_text().splitlines()[0] == (
        "population,generation,inner_percent"
    )


def test_navigation_and_colony_stages_report_the_envelope_beside_the_plain_figures(tmp_path):
    ga = dataclasses.replace(TINY, generations=4, save_generations=(0, 4))
    nav = stages.run_navigation(tmp_path, table=load_table("paper"), ga=ga, envelope=LOUD)
    for key in ("dock_success", "mean_steps_to_dock", "test_fitness"):
        assert key in nav and f"envelope_{key}" in nav
    assert all("envelope_dock_rate" in p for p in nav["populations"])
    col = run_colony_stage(tmp_path, navigation=parse_chromosome(LIGHT_FOLLOWER),
                           table=load_table("paper"), ga=ga, envelope=LOUD)  # fmt: skip
    assert col["envelope"] == LOUD.to_dict()
    assert len(col["envelope_final_inner_percent"]) == len(col["final_inner_percent"]) == 2


def test_warmup_trains_the_first_generations_in_the_exact_world(tmp_path):
    # 18 generations, warm-up 0.5: generations 0-8 train as envelope none does, 9 on in LOUD.
    staged = dataclasses.replace(LOUD, warmup_fraction=0.5)
    assert staged.varies and staged.warmup_generations(TINY.generations) == 9
    assert not dataclasses.replace(NONE, warmup_fraction=0.5).varies

    def history(out, envelope):
        _coverage(out, envelope=envelope)
        return (out / "coverage" / "history_pop1.csv").read_text().splitlines()[1:]

    runs = (("none", NONE), ("loud", LOUD), ("warm", staged))
    exact, loud, warm = (history(tmp_path / name, env) for name, env in runs)
    assert warm[:9] == exact[:9] and loud[0] != exact[0]
    assert warm[9] != exact[9]  # same population at 9, scored in the envelope from then on
    with pytest.raises(EnvelopeError, match="warmup_fraction"):
        Envelope(warmup_fraction=1.0)


def _generation0(tmp_path, envelope):
    """Generation 0 of a population of the coverage stage trained in ``envelope``: the
    population run, its evaluation and the stage (envelope ``none``)."""
    ga = dataclasses.replace(TINY, populations=1, generations=1, save_generations=(0, 1))
    stage = stages.coverage_stage(WORLD, parse_chromosome(LIGHT_FOLLOWER))
    run = PopulationRun(0, dataclasses.replace(stage, envelope=envelope), tmp_path,
                        seed_seq=np.random.SeedSequence(3), table=load_table("paper"), ga=ga,
                        world=WORLD, settings_text="{}", resume=False)  # fmt: skip
    return run, run.evaluate(), stage


def _two_draws(tmp_path, envelope):
    """Generation 0 of a population trained in ``envelope`` (2 draws per start): its
    evaluation, and the run fitness (P, S) of each draw's key evaluated alone in ``LOUD``."""
    run, got, stage = _generation0(tmp_path, envelope)
    seed = run.ga.seed
    per_key = [evaluate_sections(run.pop, got.starts, dataclasses.replace(stage, envelope=LOUD),
                                 load_table("paper"), WORLD, key)[0]
               for key in ((seed, 0), (seed, 0, 1))]  # fmt: skip
    assert not np.array_equal(per_key[0], per_key[1])
    return got, per_key


def test_draws_per_start_average_the_draws_of_each_start(tmp_path):
    # Two draws per start: generation 0's fitness is the mean of the runs under key (seed, 0)
    # and key (seed, 0, 1) from the same starts; one draw is the envelope as before.
    twice = dataclasses.replace(LOUD, draws_per_start=2)
    assert twice.training_keys(5, 0) == [(5, 0), (5, 0, 1)]
    assert LOUD.training_keys(5, 3) == [(5, 3)] and NONE.training_keys(5, 3) == [(5, 3)]
    assert dataclasses.replace(NONE, draws_per_start=3).training_keys(5, 3) == [(5, 3)]
    got, per_key = _two_draws(tmp_path, twice)
    np.testing.assert_array_equal(got.fitness, ((per_key[0] + per_key[1]) / 2).mean(axis=1))
    with pytest.raises(EnvelopeError, match="draws_per_start"):
        Envelope(draws_per_start=0)


def test_an_envelope_recorded_before_the_training_fields_reads_back_as_it_was():
    old_record = {"scatter_scale": 1.0, "bias_scale": 0.0, "station_seen_p": 0.5,
                  "reach_units": 5.0, "station_stops": False}  # fmt: skip
    env = Envelope.from_dict(old_record)
    assert (env.draws_per_start, env.warmup_fraction) == (1, 0.0)
    assert env.to_dict() == old_record  # a folder made then still resumes
    half = old_record | {"station_stops": True, "unseen_stops_p": 0.5}
    assert Envelope.from_dict(half).to_dict() == half
    assert Envelope.from_dict(half).station_blocking == "cancel"  # recorded before the slide
    assert DEFAULT.to_dict() == half | {"station_blocking": "slide", "draws_per_start": 2,
                                        "station_strata": True}  # fmt: skip


def test_stratified_station_draws_split_each_start_between_the_worlds():
    # p = 0.5, 2 draws: draw 0 is the unstratified draw, draw 1 the other world, at every start;
    # 4 draws at p = 0.25: exactly one of them sees the block. Tests are never stratified.
    def seen(env, key, n=400):
        var = Variation.of(env, PAPER_TABLE, WORLD, key, 15.0)
        return np.array([var.station_seen(s) for s in range(n)])

    plain = Envelope(station_seen_p=0.5, draws_per_start=2)
    strata = dataclasses.replace(plain, station_strata=True)
    d0, d1 = seen(strata, (4, 7)), seen(strata, (4, 7, 1))
    np.testing.assert_array_equal(d0, seen(plain, (4, 7)))
    assert np.all(d0 != d1) and 0.4 < d0.mean() < 0.6
    independent = seen(plain, (4, 7, 1))
    assert np.any(d0 == independent)  # without strata the draws agree at some starts
    quarter = dataclasses.replace(strata, station_seen_p=0.25, draws_per_start=4)
    counts = sum(seen(quarter, (4, 7) + (() if d == 0 else (d,))).astype(int) for d in range(4))
    np.testing.assert_array_equal(counts, 1)
    test_key = key_of_test(4, "figure9", 1)
    np.testing.assert_array_equal(seen(strata, test_key), seen(plain, test_key))


def test_stratified_variant_draws_walk_every_robot_once_per_start_and_min_scores_the_worst(
    tmp_path,
):
    # Two variant tables at p = 2/3 with 3 stratified draws: at every start one draw walks the
    # stage's table and one each variant (draw 0 the unstratified draw); tests never stratify.
    # With draw_fitness min a start's fitness is then its worst robot's: the plain world of
    # each of the three tables run alone, the minimum taken by hand.
    tables = [PAPER_TABLE, SHORT_STRIDES, TURNS_LESS]
    plain = Envelope(variant_p=2 / 3, variant_tables=VARIANTS.variant_tables, draws_per_start=3)
    strata = dataclasses.replace(plain, variant_strata=True)

    def robot(env, key, n=300):
        var = Variation.of(env, PAPER_TABLE, WORLD, key, 15.0)
        return np.array([next(k for k, t in enumerate(tables)
                              if np.array_equal(var.robot(s, 0).rows, t)) for s in range(n)])

    keys = [(4, 7), (4, 7, 1), (4, 7, 2)]
    picks = np.stack([robot(strata, k) for k in keys], axis=1)
    np.testing.assert_array_equal(np.sort(picks, axis=1), np.broadcast_to([0, 1, 2], picks.shape))
    np.testing.assert_array_equal(picks[:, 0], robot(plain, keys[0]))
    independent = np.stack([robot(plain, k) for k in keys], axis=1)
    assert np.any(np.sort(independent, axis=1) != [0, 1, 2])  # by chance a robot twice
    test_key = key_of_test(4, "figure9", 1)
    np.testing.assert_array_equal(robot(strata, test_key), robot(plain, test_key))
    assert strata.to_dict()["variant_strata"] is True and "variant_strata" not in plain.to_dict()
    with pytest.raises(EnvelopeError, match="variant_strata must be true or false"):
        Envelope(variant_strata="yes")

    run, got, stage = _generation0(tmp_path, dataclasses.replace(strata, draw_fitness="min"))
    alone = [evaluate_sections(run.pop, got.starts, stage, GaitTable(np.asarray(t)), WORLD)[0]
             for t in tables]  # fmt: skip
    assert not np.array_equal(alone[0], alone[1])
    np.testing.assert_array_equal(got.fitness, np.minimum.reduce(alone).mean(axis=1))


def test_draw_fitness_min_scores_each_start_by_its_worst_draw(tmp_path):
    worst = dataclasses.replace(LOUD, draws_per_start=2, draw_fitness="min")
    got, per_key = _two_draws(tmp_path, worst)
    np.testing.assert_array_equal(got.fitness, np.minimum(*per_key).mean(axis=1))
    assert worst.to_dict()["draw_fitness"] == "min" and "draw_fitness" not in LOUD.to_dict()
