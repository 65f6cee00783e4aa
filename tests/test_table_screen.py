"""``python -m servobot.robustness.table_screen``: a coverage run's final populations screened
in the table world across robot tables — each population's best by its worst table, the
scores those of the table world's own runs, copies and equal behaviours kept once, the rank
0 beside them — on a hand-made run folder, and bad inputs."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from chromosome_text import LIGHT_FOLLOWER, B, G, chrom, gene

from evolve.codec import parse_chromosome, read_chromosome, write_chromosome
from evolve.envelope import NONE
from evolve.evaluation import evaluate
from evolve.settings import WorldSettings
from evolve.starts import coverage_starts
from evolve.table import PAPER_TABLE, table_to_json
from servobot.robustness.table_screen import SCREEN_STREAM, kept, main, ranked

NAV = parse_chromosome(LIGHT_FOLLOWER)
SECTIONS = {
    "circle": chrom(gene("00", G(3), G(3), G(3), G(3)), n=8),
    "bounce": chrom(
        gene("00", B(3, 1), B(1, 1), B(2, 1), G(0)), gene("01", G(14), G(14), G(14), G(14)), n=8
    ),
    "wide": chrom(gene("00", G(1), G(1), G(1), G(2)), n=8),
    "still": chrom(n=8),
    "still too": chrom(gene("00", *["0011101"] * 4), n=8),  # gait 7, other unused bits
}
"""Coverage sections: a tight circle, a wall bouncer, a wide curve and two that stand still
(different bits, one behaviour)."""
STARTS = 6


@pytest.fixture
def run(tmp_path: Path) -> Path:
    """Population 0: circle (rank 0), bounce, circle again; population 1: wide (rank 0),
    still, still too."""
    cov = tmp_path / "run" / "coverage"
    (cov / "populations").mkdir(parents=True)
    pops = [(["circle", "bounce", "circle"], [3.0, 2.0, 1.0]),
            (["still", "wide", "still too"], [0.5, 4.0, 0.2])]  # fmt: skip
    for k, (names, fitness) in enumerate(pops):
        bits = np.stack([SECTIONS[n] for n in names])
        np.savez(cov / "populations" / f"pop{k}_gen0004.npz", population=bits,
                 fitness=np.array(fitness), best=bits[int(np.argmax(fitness))])  # fmt: skip
        np.savez(cov / "populations" / f"pop{k}_gen0000.npz", population=bits[::-1],
                 fitness=np.zeros(3), best=bits[0])  # fmt: skip
    write_chromosome(cov / "best_pop0.txt", np.concatenate([SECTIONS["circle"], NAV]))
    return tmp_path / "run"


@pytest.fixture
def variant(tmp_path: Path) -> Path:
    """A robot whose strides are 40 % shorter than the paper's table says."""
    path = tmp_path / "short.json"
    path.write_text(json.dumps(table_to_json(PAPER_TABLE * np.array([0.6, 0.6, 1.0]))))
    return path


def expected(name: str, tables: list[np.ndarray]) -> list[float]:
    """Inner coverage % of one section on each table, from the table world's own runs."""
    poses = coverage_starts(np.random.default_rng([3, SCREEN_STREAM]), STARTS, WorldSettings())
    bits = np.concatenate([SECTIONS[name], NAV])[None]
    return [100.0 * evaluate(bits, poses, table=t, mode="coverage", envelope=NONE)
            .inner_squares.mean() / 64 for t in tables]  # fmt: skip


def test_ranked_and_kept_by_hand():
    score = np.array([[50.0, 40.0], [45.0, 45.0], [60.0, 40.0], [45.0, 45.0], [10.0, 90.0]])
    # worst: 40, 45, 40, 45, 10; ties by the mean (45 vs 50), then the row; row 3 = row 1
    assert ranked(score) == [1, 2, 0, 4]
    rows = [{"population": p} for p in (1, 0, 0, 1, 0)]
    # population 0: rows 1, 2, 4 in that order; population 1: row 0 (row 3 is row 1's behaviour)
    assert kept(rows, score, 1) == [1, 0] and kept(rows, score, 2) == [1, 2, 0]
    assert kept(rows, score, 2, top=2) == [1, 2]  # the best two of those, best first


def test_each_population_s_best_by_its_worst_table(run, variant, tmp_path, capsys):
    out = tmp_path / "screen"
    args = [str(run), "--variants", str(variant), "--envelope", "none", "--starts", str(STARTS),
            "--draws", "1", "--seed", "3", "--out", str(out)]  # fmt: skip
    assert main(args) == 0
    doc = json.loads((out / "screen.json").read_text())
    tables = [PAPER_TABLE, PAPER_TABLE * np.array([0.6, 0.6, 1.0])]
    want = {n: expected(n, tables) for n in SECTIONS}
    # the copy (circle twice) and the equal behaviours (still, still too) once; only the last
    # saved generation is a candidate
    assert doc["candidates"] == 5 and doc["behaviours"] == 4
    for k, names in ((0, ["circle", "bounce"]), (1, ["wide", "still"])):
        best = max(names, key=lambda n: (min(want[n]), np.mean(want[n])))
        row = next(r for r in doc["written"] if r["population"] == k)
        assert list(row["inner_percent"].values()) == pytest.approx(want[best], abs=1e-3)
        np.testing.assert_array_equal(read_chromosome(row["file"]),
                                      np.concatenate([SECTIONS[best], NAV]))  # fmt: skip
    assert [r["name"] for r in doc["rank0"]] == ["p0i000", "p1i001"]  # circle, wide
    assert sorted(p.name for p in out.glob("*.txt")) == sorted(r["name"] + ".txt"
                                                               for r in doc["written"])  # fmt: skip
    assert "| p0i000 (rank 0) |" in capsys.readouterr().out
    # a second screen into the same folder would mix its files with these
    assert main(args) == 2
    assert "already holds a screen" in capsys.readouterr().err


def test_bad_inputs_exit_2_naming_them(run, variant, tmp_path, capsys):
    base = [str(run), "--variants", str(variant), "--out", str(tmp_path / "o")]
    cases = [
        (base[:2] + [str(tmp_path / "missing.json")] + base[3:], "missing.json"),
        (base + ["--per-population", "0"], "--per-population must be ≥ 1"),
        (base + ["--top", "-1"], "--top must be ≥ 0"),
        ([str(tmp_path)] + base[1:], "best_pop0.txt: missing"),
        (base[:2] + [","] + base[3:], "--variants names no calibration file"),
        (base + ["--table", str(variant)], "a gait table is named twice"),
    ]
    for argv, match in cases:
        assert main(argv) == 2, argv
        assert match in capsys.readouterr().err
