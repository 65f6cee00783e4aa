"""``python -m servobot.robustness.nav_candidates``: a navigation stage's candidate sections
written for the test matrix — the distinct ones that docked most in the table world, then
every population's final best — on a hand-made stage folder, and bad inputs."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from evolve.codec import read_chromosome, write_chromosome
from servobot.robustness.nav_candidates import candidates, main


def bits(seed: int) -> np.ndarray:
    return np.random.default_rng(seed).integers(0, 2, (8, 30)).astype(np.uint8)


@pytest.fixture
def stage(tmp_path: Path) -> Path:
    """Two populations, saved generations 0 and 2, final 4; population 0's generation-2 best
    is its final best."""
    sections = {(0, 0): bits(1), (0, 2): bits(2), (0, 4): bits(2),
                (1, 0): bits(3), (1, 2): bits(4), (1, 4): bits(5)}  # fmt: skip
    docks = {(0, 0): 0.5, (0, 2): 0.8, (0, 4): 0.8, (1, 0): 0.6, (1, 2): 0.7, (1, 4): 0.65}
    fitness = {(0, 2): 1.0, (0, 4): 1.1}
    (tmp_path / "populations").mkdir()
    rows = []
    for (k, g), b in sections.items():
        if g == 4:
            write_chromosome(tmp_path / f"best_pop{k}.txt", b)
        else:
            np.savez(tmp_path / "populations" / f"pop{k}_gen{g:04d}.npz", best=b)
        rows.append({"population": k, "generation": g, "selection_dock_rate": docks[k, g],
                     "selection_fitness": fitness.get((k, g), 0.5)})  # fmt: skip
    (tmp_path / "summary.json").write_text(json.dumps({"stage": "navigation", "candidates": rows}))
    return tmp_path


def test_the_top_distinct_sections_then_every_final_best(stage):
    # docking: p0g2 = p0g4 (0.8; p0g4's fitness is higher), p1g2 0.7, p1g4 0.65, p1g0, p0g0
    order = [(c["population"], c["generation"]) for c in candidates(stage, top=3)]
    assert order == [(0, 4), (1, 2), (1, 4)]  # p0g2 is p0g4's section: once
    # a smaller top still brings every population's final best
    assert [(c["population"], c["generation"]) for c in candidates(stage, top=1)] == [
        (0, 4), (1, 4)
    ]  # fmt: skip
    c = candidates(stage, top=2)
    np.testing.assert_array_equal(c[1]["bits"], bits(4))


def test_the_files_written(stage, tmp_path, capsys):
    out = tmp_path / "c"
    assert main([str(stage), "--top", "2", "--out", str(out)]) == 0
    names = ["p0g0004.txt", "p1g0002.txt", "p1g0004.txt"]
    assert sorted(p.name for p in out.iterdir()) == names
    assert capsys.readouterr().out.split() == [str(out / n) for n in names]
    np.testing.assert_array_equal(read_chromosome(out / "p1g0002.txt"), bits(4))
    assert "docked from 70.0% of the stage's selection starts" in (out / "p1g0002.txt").read_text()


def test_bad_input_exits_2_naming_it(stage, tmp_path, capsys):
    assert main([str(stage), "--top", "0", "--out", str(tmp_path / "c")]) == 2
    assert "--top must be ≥ 1" in capsys.readouterr().err
    (stage / "populations" / "pop1_gen0002.npz").unlink()
    assert main([str(stage), "--out", str(tmp_path / "c")]) == 2
    assert "pop1_gen0002.npz" in capsys.readouterr().err
    (stage / "summary.json").write_text(json.dumps({"stage": "coverage", "candidates": []}))
    assert main([str(stage), "--out", str(tmp_path / "c")]) == 2
    assert "not a finished navigation stage's summary" in capsys.readouterr().err
