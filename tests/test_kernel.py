"""The numba kernel (``evolve.evaluate``) equals the reference interpreter run by run."""

from __future__ import annotations

import contextlib
import dataclasses
from collections.abc import Iterator

import numba
import numpy as np
import pytest
from chromosome_text import STILL, B, G, chrom, gene

from evolve import evaluate
from evolve.envelope import NONE, Envelope
from evolve.geometry import apply_gait
from evolve.interpreter import (
    END_BRANCH_LIMIT,
    END_DOCKED,
    END_KILL_ZONE,
    END_POWER_EMPTY,
    END_STEP_LIMIT,
    run,
)
from evolve.settings import WorldSettings
from evolve.table import PAPER_TABLE, load_table
from evolve.world import TableWorld

ZERO_TABLE = np.zeros((16, 3))
DEFAULT_WORLD = WorldSettings()
SIDESTEP_TABLE = np.zeros((16, 3))
SIDESTEP_TABLE[15] = (0.0, -60.0, 0.0)
"""Backing up steps 60 to the left: from the dock facing east, north into the kill zone."""


def starts_in(rng, n, lo, hi) -> np.ndarray:
    return np.column_stack([rng.uniform(lo[0], hi[0], n), rng.uniform(lo[1], hi[1], n),
                            rng.uniform(0, 360, n)])  # fmt: skip


def assert_kernel_equals_interpreter(
    genomes, starts, *, mode, table=PAPER_TABLE, settings=DEFAULT_WORLD, envelope=NONE,
    envelope_key=(0, 0), **kw,
):  # fmt: skip
    """Compare every (individual, start) run, in ``envelope``; returns the Evaluation."""
    env = dict(envelope=envelope, envelope_key=envelope_key)
    ev = evaluate(genomes, starts, table=table, mode=mode, settings=settings, **env, **kw)
    for i in range(genomes.shape[0]):
        for s in range(starts.shape[0]):
            world = TableWorld(table, *starts[s], settings, start=s, **env)
            r = run(genomes[i], world, mode=mode, settings=settings, **kw)
            got = (ev.squares[i, s], ev.inner_squares[i, s], ev.steps[i, s], ev.docks[i, s])
            want = (r.squares, r.inner_squares, r.steps, r.docks)
            assert got == want and ev.end[i, s] == r.end, (i, s, got, want, ev.end[i, s], r.end)
            np.testing.assert_allclose(ev.final_pose[i, s], r.final_pose, rtol=0, atol=1e-9)
    return ev


def test_random_coverage_chromosomes_match() -> None:
    rng = np.random.default_rng(11)
    genomes = rng.integers(0, 2, size=(600, 16, 30), dtype=np.uint8)
    starts = starts_in(rng, 2, (350, 175), (450, 325))
    ev = assert_kernel_equals_interpreter(genomes, starts, mode="coverage")
    # The sample exercises every way a coverage run can end, and docking.
    ends = set(np.unique(ev.end).tolist())
    assert {END_STEP_LIMIT, END_KILL_ZONE, END_POWER_EMPTY, END_BRANCH_LIMIT} <= ends
    assert ev.docks.sum() > 0 and ev.inner_squares.max() > 0


def test_random_navigation_sections_match() -> None:
    rng = np.random.default_rng(12)
    genomes = rng.integers(0, 2, size=(600, 8, 30), dtype=np.uint8)
    starts = starts_in(rng, 2, (25, 25), (475, 475))
    ev = assert_kernel_equals_interpreter(genomes, starts, mode="navigation")
    assert set(np.unique(ev.end).tolist()) == {0, 1, 2, 3, 4}


def test_navigation_heavy_coverage_runs_match() -> None:
    """Coverage runs that go to the navigation section at once, from near the station, so that
    docking and the charging routine happen often; with a measured-like table and settings."""
    rng = np.random.default_rng(13)
    genomes = rng.integers(0, 2, size=(300, 16, 30), dtype=np.uint8)
    genomes[:, 0, :9] = [0, 0, 1, 1, 0, 0, 0, 0, 0]  # gene 0 ×∞, first: if low-power goto 8
    table = PAPER_TABLE * rng.uniform(0.8, 1.2, size=PAPER_TABLE.shape)
    starts = starts_in(rng, 3, (380, 200), (470, 300))
    ev = assert_kernel_equals_interpreter(
        genomes, starts, mode="coverage", table=table, start_power=3.95
    )
    assert ev.docks.max() >= 2
    world = WorldSettings(kill_margin=20.0, object_range=70.0, contact_half_width=22.0)
    assert_kernel_equals_interpreter(
        genomes[:100], starts, mode="coverage", table=table, settings=world, start_power=3.95
    )


HAND_CASES = [
    # (chromosome, start pose, mode, table, start_power, max_steps, expected end)
    (chrom(gene("00", B(4, 0), G(7), G(9), G(9)), *[STILL] * 7, STILL),
     (460, 250, 90), "coverage", PAPER_TABLE, 3.9, 7, END_STEP_LIMIT),
    (chrom(gene("00", B(4, 0), G(7), G(7), G(7))), (460, 250, 90), "coverage", ZERO_TABLE,
     3.9, 30, END_STEP_LIMIT),
    (chrom(gene("00", B(0, 0), G(1), G(1), G(1))), (250, 250, 270), "coverage", PAPER_TABLE,
     4.0, None, END_BRANCH_LIMIT),
    (chrom(gene("00", G(0), B(4, 3), G(0), G(0)), *[gene("00", *[G(5)] * 4)] * 7,
           gene("00", *[G(1)] * 4)), (250, 250, 0), "coverage", ZERO_TABLE, 4.05, 6,
     END_STEP_LIMIT),
    (chrom(gene("00", *[G(0)] * 4)), (30, 75, 270), "coverage", PAPER_TABLE, 4.0, None,
     END_KILL_ZONE),
    (chrom(gene("00", *[G(0)] * 4)), (250, 250, 0), "coverage", ZERO_TABLE, 2.75, None,
     END_POWER_EMPTY),
    (chrom(STILL, n=8), (460, 250, 90), "navigation", PAPER_TABLE, 4.0, None, END_DOCKED),
    (chrom(STILL), (250, 250, 0), "coverage", PAPER_TABLE, 4.0, None, END_STEP_LIMIT),
    (chrom(STILL), (250, 250, 0), "coverage", PAPER_TABLE, 4.0, 0, END_STEP_LIMIT),
    (chrom(gene("00", B(4, 0), G(7), G(7), G(7))), (460, 250, 90), "coverage", SIDESTEP_TABLE,
     3.9, None, END_KILL_ZONE),
]  # fmt: skip


@pytest.mark.parametrize("case", range(len(HAND_CASES)))
def test_hand_worked_cases_match(case: int) -> None:
    bits, pose, mode, table, power, max_steps, end = HAND_CASES[case]
    ev = assert_kernel_equals_interpreter(
        bits[None], np.array([pose], dtype=float), mode=mode, table=table,
        start_power=power, max_steps=max_steps,
    )  # fmt: skip
    assert ev.end[0, 0] == end


EVERY_ASPECT = Envelope(
    scatter_scale=1.5, bias_scale=1.0, station_seen_p=1.0, reach_units=5.0, station_stops=True
)
"""An envelope of variation (SPEC §9) with every aspect on, the station block always there."""


@pytest.mark.parametrize("case", range(len(HAND_CASES)))
def test_hand_worked_cases_match_in_an_envelope(case: int) -> None:
    """The same cases varied (scatter, bias, reach, a station block that stops): the kernel
    still equals the interpreter, from several start indices (different draws)."""
    bits, pose, mode, table, power, max_steps, _ = HAND_CASES[case]
    assert_kernel_equals_interpreter(
        bits[None], np.array([pose] * 4, dtype=float), mode=mode, table=table,
        start_power=power, max_steps=max_steps, envelope=EVERY_ASPECT, envelope_key=(1, case),
    )  # fmt: skip


def test_docking_case_values() -> None:
    bits, pose, mode, table, power, max_steps, _ = HAND_CASES[0]
    ev = evaluate(bits[None], np.array([pose]), table=load_table("paper"), mode=mode,
                  start_power=power, max_steps=max_steps)  # fmt: skip
    assert ev.docks[0, 0] == 1 and ev.steps[0, 0] == 7
    want = (460.0, 250.0, 90.0)
    for g in (15, 15, 15, 15, 9):  # the charging routine, then gene 0's gait 7 and gait 9
        want = apply_gait(*want, *PAPER_TABLE[g])
    np.testing.assert_allclose(ev.final_pose[0, 0], want, rtol=0, atol=1e-12)
    assert ev.final_pose[0, 0, 2] == pytest.approx(90 - 4 * 1.8 + 6.2)


@contextlib.contextmanager
def numba_threads(n: int) -> Iterator[None]:
    """The kernels run on ``n`` threads inside the block."""
    old = numba.get_num_threads()
    numba.set_num_threads(n)
    try:
        yield
    finally:
        numba.set_num_threads(old)


def test_deterministic_and_thread_count_independent() -> None:
    rng = np.random.default_rng(5)
    genomes = rng.integers(0, 2, size=(64, 16, 30), dtype=np.uint8)
    starts = starts_in(rng, 10, (350, 175), (450, 325))
    a = evaluate(genomes, starts, table=PAPER_TABLE, mode="coverage")
    with numba_threads(1):
        b = evaluate(genomes, starts, table=PAPER_TABLE, mode="coverage")
    c = evaluate(genomes, starts, table=PAPER_TABLE, mode="coverage")
    for f in dataclasses.fields(a):
        assert np.array_equal(getattr(a, f.name), getattr(b, f.name)), f.name
        assert np.array_equal(getattr(a, f.name), getattr(c, f.name)), f.name
    assert a.squares.shape == (64, 10) and a.final_pose.shape == (64, 10, 3)
    assert a.squares.dtype.kind == "i" and a.final_pose.dtype == np.float64


def test_input_validation() -> None:
    g16 = np.zeros((2, 16, 30), dtype=np.uint8)
    st = np.array([[400.0, 250.0, 0.0]])
    with pytest.raises(ValueError, match="mode"):
        evaluate(g16, st, table=PAPER_TABLE, mode="explore")
    with pytest.raises(ValueError, match="8-gene"):
        evaluate(g16, st, table=PAPER_TABLE, mode="navigation")
    with pytest.raises(ValueError, match=r"\(P, G, 30\)"):
        evaluate(g16[0], st, table=PAPER_TABLE, mode="coverage")
    with pytest.raises(ValueError, match="0 or 1"):
        evaluate(g16 + 2, st, table=PAPER_TABLE, mode="coverage")
    with pytest.raises(ValueError, match="integers"):
        evaluate(g16.astype(float), st, table=PAPER_TABLE, mode="coverage")
    with pytest.raises(ValueError, match=r"\(16, 3\)"):
        evaluate(g16, st, table=PAPER_TABLE[:15], mode="coverage")
    with pytest.raises(ValueError, match="outside the arena"):
        evaluate(g16, np.array([[400.0, 501.0, 0.0]]), table=PAPER_TABLE, mode="coverage")
    with pytest.raises(ValueError, match=r"\(S, 3\)"):
        evaluate(g16, st[:, :2], table=PAPER_TABLE, mode="coverage")
    with pytest.raises(ValueError, match="not finite"):
        evaluate(g16, np.array([[400.0, 250.0, np.nan]]), table=PAPER_TABLE, mode="coverage")
    with pytest.raises(ValueError, match="max_steps"):
        evaluate(g16, st, table=PAPER_TABLE, mode="coverage", max_steps=-1)
