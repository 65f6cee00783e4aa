"""The navigation and coverage stages (``evolve.stages``): fitness, start poses, determinism,
resume bit for bit, corrupt checkpoints, and a short evolution that measurably learns."""

from __future__ import annotations

import dataclasses
import math
from types import SimpleNamespace

import numpy as np
import pytest
from run_folder import result_files as _files

from evolve import evaluate, stages
from evolve import starts as starts_mod
from evolve.codec import read_chromosome
from evolve.settings import GASettings, NavigationSettings, WorldSettings, navigation_ga_settings
from evolve.table import load_table
from infra.rundir import RunDirError

WORLD = WorldSettings()
TABLE = load_table("paper")
TINY = GASettings(populations=2, population_size=12, generations=24, test_starts=20, seed=3)
"""24 generations: checkpoints at 0 and 16, saves at 0, 1 and 24."""


class Interrupt(Exception):
    """Raised from ``on_generation`` to simulate a killed run."""


# --------------------------------------------------------------------------- fitness, starts


def test_navigation_run_fitness_hand_worked():
    # dock point (465, 250); two starts 100 away at (365, 250), one 100 away at (465, 150)
    starts = np.array([[365.0, 250.0, 0.0], [365.0, 250.0, 0.0], [465.0, 150.0, 0.0]])
    ev = SimpleNamespace(
        end=np.array([[4, 0, 1]]),
        steps=np.array([[40, 100, 7]]),
        final_pose=np.array([[[460.0, 250.0, 90.0], [415.0, 250.0, 0.0], [465.0, 400.0, 0.0]]]),
    )
    fit = stages.navigation_run_fitness(ev, starts, WORLD)
    # docked in 40 steps: 2 − 40/100; half-way closer: 0.5·(1 − 50/100); farther away: 0
    np.testing.assert_allclose(fit, [[1.6, 0.25, 0.0]])


def test_coverage_run_fitness_is_squares():
    ev = SimpleNamespace(squares=np.array([[0, 17, 100]]))
    fit = stages.coverage_run_fitness(ev, np.zeros((3, 3)), WORLD)
    np.testing.assert_array_equal(fit, [[0.0, 17.0, 100.0]])


def test_start_poses_lie_in_their_regions():
    rng = np.random.default_rng(1)
    nav = starts_mod.navigation_starts(rng, 2000, WORLD)
    cov = starts_mod.coverage_starts(rng, 2000, WORLD)
    lo, hi = WORLD.navigation_start_xy
    assert nav.shape == cov.shape == (2000, 3)
    assert (nav[:, :2] >= lo).all() and (nav[:, :2] <= hi).all()
    assert (cov[:, 0] >= 350).all() and (cov[:, 0] <= 450).all()
    assert (cov[:, 1] >= 175).all() and (cov[:, 1] <= 325).all()
    for s in (nav, cov):
        assert (s[:, 2] >= 0).all() and (s[:, 2] < 360).all()
        # uniform headings: every quadrant holds about a quarter
        counts = np.histogram(s[:, 2], bins=4, range=(0, 360))[0]
        assert (counts > 400).all()


def test_unique_evaluation_equals_evaluating_everyone():
    rng = np.random.default_rng(5)
    base = rng.integers(0, 2, (6, 8, 30), dtype=np.uint8)
    pop = base[[0, 1, 0, 2, 3, 3, 4, 5, 0]]  # repeated individuals, as in a converged population
    starts = starts_mod.navigation_starts(rng, 7, WORLD)
    stage = stages.navigation_stage(WORLD)
    fit, ev, first, inverse = stages.evaluate_sections(pop, starts, stage, TABLE, WORLD)
    assert len(first) == 6
    full = evaluate(pop, starts, table=TABLE.values, mode="navigation")
    np.testing.assert_array_equal(fit, stages.navigation_run_fitness(full, starts, WORLD))
    np.testing.assert_array_equal(np.asarray(ev.steps)[inverse], full.steps)


def test_bad_settings_are_refused(tmp_path):
    for bad in (
        dataclasses.replace(TINY, population_size=1),
        dataclasses.replace(TINY, generations=0),
        dataclasses.replace(TINY, populations=0),
    ):
        with pytest.raises(stages.StageError):
            stages.run_navigation(tmp_path, table=TABLE, ga=bad)
    with pytest.raises(stages.StageError, match="navigation section"):
        stages.run_coverage(tmp_path, navigation=np.zeros((7, 30)), table=TABLE, ga=TINY)


# --------------------------------------------------------------------------- determinism, resume


def test_same_seed_same_populations_other_seed_differs(tmp_path):
    a, b, c = tmp_path / "a", tmp_path / "b", tmp_path / "c"
    stages.run_navigation(a, table=TABLE, ga=TINY)
    stages.run_navigation(b, table=TABLE, ga=TINY)
    stages.run_navigation(c, table=TABLE, ga=dataclasses.replace(TINY, seed=4, populations=1))
    fa, fb = _files(a), _files(b)
    assert "navigation/populations/pop1_gen0024.npz" in fa
    assert fa == fb
    # population 0 of seed 4 is not population 0 of seed 3
    pa = np.load(a / "navigation/populations/pop0_gen0000.npz")["population"]
    pc = np.load(c / "navigation/populations/pop0_gen0000.npz")["population"]
    assert not np.array_equal(pa, pc)


def test_population_does_not_depend_on_how_many_run(tmp_path):
    one = dataclasses.replace(TINY, populations=1)
    stages.run_navigation(tmp_path / "one", table=TABLE, ga=one)
    stages.run_navigation(tmp_path / "two", table=TABLE, ga=TINY)
    name = "navigation/populations/pop0_gen0024.npz"
    assert _files(tmp_path / "one")[name] == _files(tmp_path / "two")[name]


def test_resume_after_interruption_equals_uninterrupted_run(tmp_path):
    ref, cut = tmp_path / "ref", tmp_path / "cut"
    stages.run_navigation(ref, table=TABLE, ga=TINY)

    def kill_at(info):
        if info["population"] == 1 and info["generation"] == 20:
            raise Interrupt

    with pytest.raises(Interrupt):
        stages.run_navigation(cut, table=TABLE, ga=TINY, on_generation=kill_at)
    assert (cut / "navigation/checkpoints/pop0_final.npz").exists()
    assert (cut / "navigation/checkpoints/pop1.npz").exists()  # written at generation 16
    assert not (cut / "navigation/best.txt").exists()
    seen = []
    summary = stages.run_navigation(
        cut, table=TABLE, ga=TINY, resume=True, on_generation=seen.append
    )
    # population 0 is not re-run; population 1 restarts at its checkpoint (generation 16)
    assert [(i["population"], i["generation"]) for i in seen] == [(1, g) for g in range(16, 25)]
    assert summary["resumed"] is True
    assert _files(ref) == _files(cut)


def test_corrupt_checkpoint_is_a_clear_error(tmp_path):
    def kill_at(info):
        if info["generation"] == 3:
            raise Interrupt

    with pytest.raises(Interrupt):
        stages.run_navigation(tmp_path, table=TABLE, ga=TINY, on_generation=kill_at)
    ckpt = tmp_path / "navigation/checkpoints/pop0.npz"
    good = ckpt.read_bytes()
    ckpt.write_bytes(good[: len(good) // 2])  # truncated, as by a full disk
    with pytest.raises(stages.StageError, match=r"pop0\.npz: corrupt checkpoint"):
        stages.run_navigation(tmp_path, table=TABLE, ga=TINY, resume=True)
    ckpt.write_bytes(good)
    record = (tmp_path / "navigation/settings.json").read_text()
    with pytest.raises(RunDirError, match="GASettings.seed: 3 there, 9 here"):
        stages.run_navigation(
            tmp_path,
            table=TABLE,
            ga=dataclasses.replace(TINY, seed=9),
            resume=True,
        )
    assert (tmp_path / "navigation/settings.json").read_text() == record  # untouched
    assert ckpt.read_bytes() == good
    np.savez(ckpt, population=np.zeros(3))  # a valid npz that lacks the resume state
    with pytest.raises(stages.StageError, match="missing"):
        stages.run_navigation(tmp_path, table=TABLE, ga=TINY, resume=True)


# --------------------------------------------------------------------------- learning


@pytest.fixture(scope="module")
def learned_navigation(tmp_path_factory):
    out = tmp_path_factory.mktemp("learn")
    # 48 × 64, the start region grown to the whole arena by generation 32: seeds 0–4 all dock
    # from ≥ 49 % of the test starts (generation 0's best: ≤ 24 %), and the population's mean
    # fitness on the test starts rises 11.7–14×
    ga = navigation_ga_settings(populations=1, population_size=48, generations=64, seed=1)
    nav = NavigationSettings(start_ramp_fraction=0.5)
    summary = stages.run_navigation(out, table=TABLE, ga=ga, navigation=nav)
    return out, ga, summary


def test_short_navigation_evolution_learns_to_dock(learned_navigation):
    out, ga, summary = learned_navigation
    folder = out / "navigation"
    # generation 0's best, run from the same fresh test starts as the final best
    gen0 = np.load(folder / "populations/pop0_gen0000.npz")["best"]
    test_seq, _ = stages.stage_seeds(ga.seed, "navigation", ga.populations)
    starts = starts_mod.navigation_starts(
        np.random.Generator(np.random.PCG64(test_seq)), ga.test_starts, WORLD
    )
    ev = evaluate(gen0[None], starts, table=TABLE.values, mode="navigation")
    gen0_docked = float((ev.end == 4).mean())
    assert summary["dock_success"] >= 0.4
    assert summary["dock_success"] >= gen0_docked + 0.2
    # the population's mean fitness rises, on the same starts (the training starts of early
    # generations lie near the dock, so their fitness does not compare)
    stage = stages.navigation_stage(WORLD)
    pops = [np.load(folder / f)["population"] for f in
            ("populations/pop0_gen0000.npz", "checkpoints/pop0_final.npz")]  # fmt: skip
    mean0, mean1 = (stages.evaluate_sections(p, starts, stage, TABLE, WORLD)[0].mean()
                    for p in pops)  # fmt: skip
    assert mean1 > 5 * mean0
    # best.txt is the chosen section, and it docks as the summary says
    best = read_chromosome(folder / "best.txt")
    ev = evaluate(best[None], starts, table=TABLE.values, mode="navigation")
    assert math.isclose(float((ev.end == 4).mean()), summary["dock_success"])


def test_short_coverage_evolution_learns_to_cover(learned_navigation, tmp_path):
    out, _, _ = learned_navigation
    nav = read_chromosome(out / "navigation/best.txt")
    # 32 × 48: over seeds 0–4 the test fitness rose by 6–17 points to ≥ 22 % and the
    # population's mean training fitness by ≥ 2.2×
    ga = GASettings(populations=1, population_size=32, generations=48, test_starts=30, seed=2)
    summary = stages.run_coverage(tmp_path, navigation=nav, table=TABLE, ga=ga)
    assert summary["generations"] == [0, 1, 32, 48]
    first, last = summary["figure9_inner_percent"][0][0], summary["final_inner_percent"][0]
    assert last >= first + 5.0  # percentage points of the 64 inner squares
    assert last >= 15.0
    hist = np.loadtxt(tmp_path / "coverage/history_pop0.csv", delimiter=",", skiprows=1)
    assert hist[-8:, 2].mean() > 1.8 * hist[:8, 2].mean()
    best = read_chromosome(tmp_path / "coverage/best_pop0.txt")
    assert best.shape == (16, 30)
    np.testing.assert_array_equal(best[8:], nav)  # the navigation section stays fixed
