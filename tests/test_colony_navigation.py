"""The colony stage that learns the navigation section (``ColonySettings.sections =
"navigation"``): population k evolves navigation sections behind the fixed coverage section of
a shared run's finalist k, every individual starting as the given section. Checked against
independent evaluations: generation 0 is the source colony, the finalists keep their coverage
genes, the final test redone; resume bit for bit, settings recorded and checked, bad inputs
named."""

from __future__ import annotations

import json

import numpy as np
import pytest
from chromosome_text import LIGHT_FOLLOWER
from test_colony_stage import NAV, TABLE, TINY, WORLD, assert_resumes_bit_for_bit

from evolve import evaluate_colony
from evolve.codec import read_chromosome, write_chromosome
from evolve.colony_stage import finalists_coverage, run_colony_stage
from evolve.population import StageError, stage_seeds
from evolve.settings import ColonySettings
from evolve.starts import colony_starts
from infra.errors import InputError

LEARN_NAV = ColonySettings(sections="navigation")


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    """A tiny shared colony run, then navigation learned behind its finalists' coverage."""
    root = tmp_path_factory.mktemp("colony_nav")
    shared = run_colony_stage(root / "shared", navigation=NAV, table=TABLE, ga=TINY)
    coverage = finalists_coverage(root / "shared", TINY.populations)
    learned = run_colony_stage(root / "nav", navigation=NAV, table=TABLE, ga=TINY,
                               colony=LEARN_NAV, coverage=coverage)  # fmt: skip
    return root, shared, learned, coverage


def test_generation_zero_is_the_source_colony_and_coverage_stays_fixed(runs):
    root, shared, learned, coverage = runs
    folder = root / "nav/colony"
    for k in range(TINY.populations):
        source = read_chromosome(root / f"shared/colony/best_pop{k}.txt")
        np.testing.assert_array_equal(coverage[k], source[:8])
        gen0 = np.load(folder / f"populations/pop{k}_gen0000.npz")
        assert (gen0["population"] == NAV).all()  # every individual starts as the section
        final = read_chromosome(folder / f"best_pop{k}.txt")
        np.testing.assert_array_equal(final[:8], source[:8])
    # Generation 0's best is the source finalist itself, run from the same colony test starts
    # (same seed, same stage name): Figure 9 starts where the shared run ended.
    np.testing.assert_array_equal(
        np.asarray(learned["figure9_inner_percent"])[:, 0],
        np.asarray(shared["figure9_inner_percent"])[:, -1],
    )
    settings = json.loads((folder / "settings.json").read_text())
    assert settings["ColonySettings"]["sections"] == "navigation"
    assert "navigation_section" not in settings
    assert settings["initial_section"] == ["".join(map(str, g)) for g in NAV.tolist()]
    assert len(settings["coverage_sections"]) == TINY.populations


def test_the_final_test_redone_independently(runs):
    root, _, learned, _ = runs
    test_seq, _ = stage_seeds(TINY.seed, "colony", TINY.populations)
    starts = colony_starts(np.random.Generator(np.random.PCG64(test_seq)), TINY.test_starts,
                           WORLD, LEARN_NAV)  # fmt: skip
    bests = np.stack([read_chromosome(root / f"nav/colony/best_pop{k}.txt")
                      for k in range(TINY.populations)])  # fmt: skip
    ev = evaluate_colony(bests, starts, table=TABLE.values, mode="coverage")
    for k, t in enumerate(learned["final_test"]):
        assert t["colony_inner_percent"] == pytest.approx(100 * ev.inner_squares[k].mean() / 64)
        assert t["docks_per_robot"] == pytest.approx(ev.docks[k].mean())


def test_resume_is_bit_for_bit_and_other_coverage_is_refused(runs, tmp_path):
    root, _, _, coverage = runs
    assert_resumes_bit_for_bit(root / "nav", tmp_path, "pop1.npz", colony=LEARN_NAV,
                               coverage=coverage)  # fmt: skip
    other = coverage.copy()
    other[1, 0, 0] ^= 1
    with pytest.raises(InputError, match="coverage_sections"):
        run_colony_stage(tmp_path, navigation=NAV, table=TABLE, ga=TINY, colony=LEARN_NAV,
                         coverage=other, resume=True)  # fmt: skip


def test_bad_coverage_sources_are_named(runs, tmp_path):
    root, _, _, coverage = runs
    with pytest.raises(StageError, match="given exactly when the colony stage learns"):
        run_colony_stage(tmp_path / "a", navigation=NAV, table=TABLE, ga=TINY, coverage=coverage)
    with pytest.raises(StageError, match="given exactly when the colony stage learns"):
        run_colony_stage(tmp_path / "b", navigation=NAV, table=TABLE, ga=TINY, colony=LEARN_NAV)
    with pytest.raises(StageError, match="1 coverage sections for 2 populations"):
        run_colony_stage(tmp_path / "c", navigation=NAV, table=TABLE, ga=TINY, colony=LEARN_NAV,
                         coverage=coverage[:1])  # fmt: skip
    with pytest.raises(StageError, match=r"must be \(populations, 8, 30\) bits, got \(2, 7, 30\)"):
        run_colony_stage(tmp_path / "d", navigation=NAV, table=TABLE, ga=TINY, colony=LEARN_NAV,
                         coverage=coverage[:, :7])  # fmt: skip
    with pytest.raises(StageError, match="best_pop2.txt: no such file; --coverage-from needs"):
        finalists_coverage(root / "shared", 3)
    write_chromosome(tmp_path / "e/colony/best_pop0.txt", NAV)
    with pytest.raises(StageError, match="8 genes, but --coverage-from takes"):
        finalists_coverage(tmp_path / "e", 1)


def test_the_command_line(runs, tmp_path, capsys):
    from servobot.cli import main

    root, _, _, _ = runs
    nav = tmp_path / "nav.txt"
    nav.write_text(LIGHT_FOLLOWER)
    common = ["--populations", "2", "--generations", "2", "--population-size", "4",
              "--starts-per-generation", "2", "--navigation", str(nav)]  # fmt: skip
    assert main(["evolve", "colony", "--sections", "navigation", *common,
                 "--out", str(tmp_path / "x")]) == 2  # fmt: skip
    assert "--sections navigation needs --coverage-from DIR" in capsys.readouterr().err
    assert main(["evolve", "colony", "--coverage-from", str(root / "shared"), *common,
                 "--out", str(tmp_path / "y")]) == 2  # fmt: skip
    assert "--coverage-from is an option of the colony stage" in capsys.readouterr().err
    out = tmp_path / "z"
    learn = ["--sections", "navigation", "--coverage-from", str(root / "shared")]
    assert main(["evolve", "colony", *learn, *common, "--out", str(out), "--no-progress"]) == 0
    for k in range(2):
        final = read_chromosome(out / f"colony/best_pop{k}.txt")
        np.testing.assert_array_equal(final[:8], read_chromosome(
            root / f"shared/colony/best_pop{k}.txt")[:8])  # fmt: skip
    assert "navigation (learned as a colony)" in (out / "colony/best_pop0.txt").read_text()
    assert json.loads((out / "colony/summary.json").read_text())["generations"] == [0, 1, 2]
