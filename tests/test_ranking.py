"""The ranking measurement's pieces (issue 16): genome samples from a run folder, the table's
prediction in an envelope, the agreement measures — on hand-made folders, no physics."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from evolve.codec import expressed_mask, format_chromosome, read_chromosome
from evolve.envelope import DEFAULT, NONE
from evolve.evaluation import evaluate
from evolve.settings import WorldSettings
from evolve.starts import coverage_starts
from evolve.table import PAPER_TABLE
from servobot.robustness import cross, ranking

RNG = np.random.default_rng(11)
SIZE = 20


def _run_folder(tmp_path: Path, clone: bool = False) -> tuple[Path, dict[int, np.ndarray]]:
    """Two populations × generations 0 and 7; fitness = individual index (pop 0) or its
    reverse (pop 1); pop 0's two fittest are twins, and with ``clone`` its fourth fittest is
    the fittest with one unexpressed bit flipped (another genome, the same behaviour)."""
    pops = tmp_path / "coverage" / "populations"
    pops.mkdir(parents=True)
    nav = RNG.integers(0, 2, (8, 30), dtype=np.uint8)
    (tmp_path / "coverage" / "best_pop0.txt").write_text(
        format_chromosome(np.concatenate([RNG.integers(0, 2, (8, 30), dtype=np.uint8), nav]))
    )
    finals = {}
    for p in range(2):
        for gen in (0, 7):
            pop = RNG.integers(0, 2, (SIZE, 8, 30), dtype=np.uint8)
            fit = np.arange(SIZE, dtype=float) if p == 0 else np.arange(SIZE, dtype=float)[::-1]
            if p == 0:
                pop[SIZE - 2] = pop[SIZE - 1]  # the two fittest are the same genome
            if p == 0 and clone:
                mask = expressed_mask(np.concatenate([pop[SIZE - 1], nav]))[:8]
                pop[SIZE - 4] = pop[SIZE - 1]
                pop[SIZE - 4][tuple(np.argwhere(~mask)[0])] ^= 1
            best = pop[int(np.argmax(fit))]
            np.savez(pops / f"pop{p}_gen{gen:04d}.npz", population=pop, fitness=fit, best=best)
            if gen == 7:
                finals[p] = pop
    return tmp_path, finals


def test_top_genomes_come_from_the_top_fraction_distinct_best_first(tmp_path: Path) -> None:
    run, finals = _run_folder(tmp_path)
    genomes = ranking.top_genomes(run, per_population=3, fraction=0.2)  # top 4 of 20 → 3 distinct
    assert [g.label for g in genomes][:1] == ["p0g7r0"]
    pop0 = [g.bits[:8] for g in genomes if g.label.startswith("p0")]
    expect = [finals[0][19], finals[0][17], finals[0][16]]  # 18 is 19's twin: skipped
    assert all(np.array_equal(a, b) for a, b in zip(pop0, expect, strict=True))
    pop1 = [g.bits[:8] for g in genomes if g.label.startswith("p1")]
    assert np.array_equal(pop1[0], finals[1][0])  # pop 1's fitness is reversed
    nav = genomes[0].bits[8:]
    assert all(np.array_equal(g.bits[8:], nav) and g.bits.shape == (16, 30) for g in genomes)


def test_generation_bests_one_per_saved_generation(tmp_path: Path) -> None:
    run, _ = _run_folder(tmp_path)
    assert [g.label for g in ranking.generation_bests(run)] == [
        "p0g0best", "p0g7best", "p1g0best", "p1g7best",
    ]  # fmt: skip


def test_a_folder_without_what_it_needs_names_the_file(tmp_path: Path) -> None:
    with pytest.raises(ranking.RankingError, match="best_pop0.txt: missing"):
        ranking.top_genomes(tmp_path, 2)
    run, _ = _run_folder(tmp_path)
    for f in (run / "coverage" / "populations").iterdir():
        f.unlink()
    with pytest.raises(ranking.RankingError, match="no saved populations"):
        ranking.top_genomes(run, 2)


def test_agreement_hand_worked() -> None:
    table = np.array([[10.0, 12.0], [20.0, 20.0], [30.0, 34.0]])
    physics = np.array([[9.0, 9.0], [25.0, 21.0], [20.0, 24.0]])
    a = ranking.agreement(table, physics)
    # means: table 11, 20, 32; physics 9, 23, 22 → ranks (1,2,3) vs (1,3,2): ρ = 1 − 6·2/24
    assert a["spearman"] == pytest.approx(0.5)
    assert a["mean_abs_delta"] == pytest.approx((1 + 3 + 5 + 1 + 10 + 10) / 6)
    assert a["table_mean"] == pytest.approx(21.0) and a["physics_mean"] == pytest.approx(18.0)
    flat = ranking.agreement(np.ones((3, 2)), physics)
    assert math.isnan(flat["spearman"])


def test_table_runs_none_is_one_exact_run_and_an_envelope_the_mean_of_its_draws() -> None:
    bits = RNG.integers(0, 2, (3, 16, 30), dtype=np.uint8)
    genomes = [ranking.Genome(str(k), b) for k, b in enumerate(bits)]
    starts = coverage_starts(np.random.default_rng(1), 4, WorldSettings())
    exact = evaluate(bits, starts, table=PAPER_TABLE, mode="coverage").inner_squares
    assert np.array_equal(ranking.table_runs(genomes, starts, table=PAPER_TABLE), exact)
    got = ranking.table_runs(genomes, starts, table=PAPER_TABLE, envelope=DEFAULT, seed=3, draws=3)
    from evolve.envelope import key_of_test

    draws = [evaluate(bits, starts, table=PAPER_TABLE, mode="coverage", envelope=DEFAULT,
                      envelope_key=key_of_test(3, "ranking", d)).inner_squares
             for d in range(3)]  # fmt: skip
    assert np.allclose(got, np.mean(draws, axis=0))


def test_table_end_shares_count_every_start_and_draw_by_end() -> None:
    """Each genome's end shares count its runs from every start in every draw, by end code."""
    from evolve.envelope import key_of_test
    from evolve.interpreter import END_NAMES

    bits = RNG.integers(0, 2, (4, 16, 30), dtype=np.uint8)
    genomes = [ranking.Genome(str(k), b) for k, b in enumerate(bits)]
    starts = coverage_starts(np.random.default_rng(2), 6, WorldSettings())
    runs = ranking.table_evaluations(
        genomes, starts, table=PAPER_TABLE, envelope=DEFAULT, seed=1, draws=3, steps=80
    )
    got = ranking.table_end_shares(runs)
    ends = np.stack([evaluate(bits, starts, table=PAPER_TABLE, mode="coverage", max_steps=80,
                              envelope=DEFAULT, envelope_key=key_of_test(1, "ranking", d)).end
                     for d in range(3)], axis=1)  # (G, draws, S)  # fmt: skip
    assert got.shape == (4, len(END_NAMES))
    for g in range(4):
        for code in range(len(END_NAMES)):
            assert got[g, code] == np.count_nonzero(ends[g] == code) / 18
    exact = ranking.table_end_shares(
        ranking.table_evaluations(genomes, starts, table=PAPER_TABLE, steps=80)
    )
    one = evaluate(bits, starts, table=PAPER_TABLE, mode="coverage", max_steps=80).end
    assert exact[:, 0].tolist() == [np.count_nonzero(e == 0) / 6 for e in one]


def test_end_agreement_by_hand() -> None:
    """Shares of (step limit, kill zone, power empty, branch limit, docked) for 4 genomes of
    2 populations: the kill zone's shares rise together on both sides (r = 1), power empty
    only in physics; ends neither side has are left out."""
    table = np.array([[0.9, 0.1, 0, 0, 0], [0.8, 0.2, 0, 0, 0],
                      [0.7, 0.3, 0, 0, 0], [0.6, 0.4, 0, 0, 0]])  # fmt: skip
    physics = np.array([[1.0, 0.0, 0, 0, 0], [0.8, 0.1, 0.1, 0, 0],
                        [0.7, 0.2, 0.1, 0, 0], [0.4, 0.3, 0.3, 0, 0]])  # fmt: skip
    got = ranking.end_agreement(table, physics, np.array([0, 0, 1, 1]))
    assert list(got) == ["step limit", "kill zone", "power empty"]
    kill = got["kill zone"]
    assert kill["table"] == pytest.approx(0.25) and kill["physics"] == pytest.approx(0.15)
    assert kill["r"] == pytest.approx(1.0)
    assert kill["table_by_population"] == pytest.approx([0.15, 0.35])
    assert kill["physics_by_population"] == pytest.approx([0.05, 0.25])
    assert math.isnan(got["power empty"]["r"])  # the table has no spread there
    # step limit: table 0.9, 0.8, 0.7, 0.6 against physics 1.0, 0.8, 0.7, 0.4
    assert got["step limit"]["r"] == pytest.approx(np.corrcoef([9, 8, 7, 6], [10, 8, 7, 4])[0, 1])


def test_end_shares_of_cells_leave_out_physics_errors() -> None:
    from servobot.robustness.measure import end_shares

    def run(code):
        return {"physics": None if code is None else {"end": {"code": code}}}

    cells = [[run(0), run(2), run(None), run(2)], [run(1)]]
    got = end_shares(cells, "physics")
    assert got[0].tolist() == pytest.approx([1 / 3, 0, 2 / 3, 0, 0])
    assert got[1].tolist() == [0, 1, 0, 0, 0]


def test_seen_forces_the_block() -> None:
    assert ranking.seen(DEFAULT, True).station_seen_p == 1.0
    assert ranking.seen(DEFAULT, False).station_seen_p == 0.0
    assert ranking.seen(NONE, False) == NONE


def test_cross_prints_every_world_for_every_run(tmp_path: Path, capsys) -> None:
    run, _ = _run_folder(tmp_path)
    assert cross.main([str(run), "--starts", "3", "--draws", "2"]) == 0
    out = capsys.readouterr().out
    for name in cross.WORLDS:
        assert f"| {name} |" in out
    # the last world has no random aspect: every draw is the one run, % of the 64 inner squares
    bits = np.stack([read_chromosome(run / "coverage" / "best_pop0.txt")])
    starts = coverage_starts(np.random.default_rng(7), 3, WorldSettings())
    want = evaluate(bits, starts, table=PAPER_TABLE, mode="coverage", envelope=cross.SEEN,
                    envelope_key=(7, 0)).inner_squares.mean() / 64 * 100  # fmt: skip
    row = next(line for line in out.splitlines() if line.startswith("| block always seen"))
    assert row == f"| block always seen, exact moves | {want:.1f} ({want:.1f}) |"
    assert "kill zone" in out and "navigation docks" in out


def test_the_measurement_end_to_end_on_a_tiny_case(tmp_path: Path, capsys) -> None:
    """``python -m servobot.robustness.measure``: 2 genomes × 1 start × 3 steps in both physics
    worlds; every table side's numbers redone here (the matched world: the envelope with the
    block never seen for ``shipped``, always for ``station-seen``), a rerun reads its physics
    back, and another sample in the same folder is refused."""
    import json

    from servobot.robustness import measure

    run, _ = _run_folder(tmp_path / "run")
    out = tmp_path / "rank"
    argv = ["--run", str(run), "--envelope", "default", "--per-population", "1", "--starts",
            "1", "--steps", "3", "--draws", "2", "--workers", "1", "--out", str(out)]  # fmt: skip
    assert measure.main(argv) == 0
    doc = json.loads((out / "ranking.json").read_text())
    assert doc["genomes"] == 2 and set(doc["agreement"]["top20"]) == {
        "own world", "exact world", "matched world", "ceiling"}  # fmt: skip
    genomes = ranking.top_genomes(run, 1)
    starts = np.asarray(
        json.loads((out / "matrix" / "robustness.json").read_text())["start_poses"]["coverage"]
    )
    for world, block in (("shipped", False), ("station-seen", True)):
        want = ranking.table_runs(genomes, starts, table=PAPER_TABLE, seed=0, draws=2, steps=3,
                                  envelope=ranking.seen(DEFAULT, block))  # fmt: skip
        got = doc["agreement"]["top20"]["matched world"][world]["table_mean"]
        assert got == pytest.approx(want.mean())
    assert "| top20 | matched world | station-seen |" in (out / "ranking.md").read_text()
    assert set(doc["by_population"]["top20"]) == {"shipped", "station-seen"}
    assert doc["by_population"]["top20"]["shipped"]["populations"] == [0, 1]
    # 3 steps end every run at the step limit, on both sides
    for world in ("shipped", "station-seen"):
        ends = doc["ends"]["top20"][world]
        assert list(ends) == ["step limit"]
        assert ends["step limit"]["table"] == ends["step limit"]["physics"] == 1.0
        assert ends["step limit"]["physics_by_population"] == [1.0, 1.0]
    assert "| shipped | step limit | 100.0 % | 100.0 % | nan |" in (out / "ranking.md").read_text()
    capsys.readouterr()
    assert measure.main(argv) == 0  # the physics cells are read back
    assert json.loads((out / "ranking.json").read_text()) == doc
    assert measure.main([*argv[:4], "--per-population", "2", *argv[6:]]) == 2
    assert "holds a run made with other settings" in capsys.readouterr().err


def test_clones_run_in_physics_once(tmp_path: Path) -> None:
    """Two genomes of one behaviour (equal expressed bits) share one physics cell: the matrix
    holds 3 cells per world for 4 genomes, and ``runs_as`` names the clone's stand-in."""
    import json

    from servobot.robustness import measure

    run, _ = _run_folder(tmp_path / "run", clone=True)
    out = tmp_path / "rank"
    argv = ["--run", str(run), "--per-population", "2", "--starts", "1", "--steps", "3",
            "--draws", "1", "--workers", "1", "--out", str(out)]  # fmt: skip
    assert measure.main(argv) == 0
    doc = json.loads((out / "ranking.json").read_text())
    assert (doc["genomes"], doc["behaviours"]) == (4, 3)
    assert doc["runs_as"] == {"p0g7r2": "p0g7r0"}
    for world in measure.WORLDS:
        assert sorted(p.name for p in (out / "matrix" / "runs" / world).iterdir()) == [
            "p0g7r0", "p1g7r0", "p1g7r3"]  # fmt: skip
    assert "4 genomes (3 behaviours" in (out / "ranking.md").read_text()


def test_the_bests_alone_and_an_empty_sample(tmp_path: Path, capsys) -> None:
    """``--per-population 0 --bests`` measures every saved generation's best and nothing else;
    ``--per-population 0`` alone, a negative count, or ``--tune`` without the top-20 % sample
    exit 2 naming the option."""
    import json

    from servobot.robustness import measure

    run, _ = _run_folder(tmp_path / "run")
    argv = ["--run", str(run), "--starts", "1", "--steps", "2", "--draws", "1", "--workers",
            "1", "--out", str(tmp_path / "rank")]  # fmt: skip
    for bad in (["--per-population", "0"], ["--per-population", "-1", "--bests"],
                ["--per-population", "0", "--bests", "--tune"]):  # fmt: skip
        with pytest.raises(SystemExit) as e:
            measure.main([*argv, *bad])
        assert e.value.code == 2
        assert "--per-population" in capsys.readouterr().err
    assert measure.main([*argv, "--per-population", "0", "--bests"]) == 0
    doc = json.loads((tmp_path / "rank" / "ranking.json").read_text())
    assert doc["genomes"] == 4 and list(doc["agreement"]) == ["generation_bests"]
    names = sorted(p.stem for p in (tmp_path / "rank" / "genomes").glob("*.txt"))
    assert names == ["p0g0best", "p0g7best", "p1g0best", "p1g7best"]


def test_the_executor_option(tmp_path: Path, capsys) -> None:
    """``--executor serial`` gives the pool's numbers; an executor that names nothing and a
    worker count outside [1, 4 × cores] exit 2 naming the option, before anything is written."""
    import json

    from servobot.robustness import measure

    run, _ = _run_folder(tmp_path / "run")
    argv = ["--run", str(run), "--per-population", "1", "--starts", "1", "--steps", "2",
            "--draws", "1"]  # fmt: skip
    assert measure.main([*argv, "--executor", "serial", "--out", str(tmp_path / "a")]) == 0
    assert measure.main([*argv, "--workers", "2", "--out", str(tmp_path / "b")]) == 0
    doc_a, doc_b = (json.loads((tmp_path / d / "ranking.json").read_text()) for d in "ab")
    assert doc_a["agreement"] == doc_b["agreement"]
    capsys.readouterr()
    assert measure.main([*argv, "--executor", "cluster", "--out", str(tmp_path / "c")]) == 2
    assert "cluster" in capsys.readouterr().err
    assert not (tmp_path / "c").exists()  # refused before anything is written
    for workers in ("0", "1000000"):
        assert measure.main([*argv, "--workers", workers, "--out", str(tmp_path / "d")]) == 2
        assert "--workers must be an integer between 1 and" in capsys.readouterr().err
    assert not (tmp_path / "d").exists()


def test_a_measurement_grown_to_more_starts_reuses_the_earlier_runs(tmp_path: Path, capsys):
    """``--reuse``: 1 start grown to 2 takes each cell's first run and gives the numbers of
    the 2-start measurement run in full; a folder that is no measurement exits 2, before
    anything is written."""
    import json

    from servobot.robustness import measure

    run, _ = _run_folder(tmp_path / "run")
    argv = ["--run", str(run), "--per-population", "1", "--steps", "3", "--draws", "1",
            "--workers", "1"]  # fmt: skip
    assert measure.main([*argv, "--starts", "1", "--out", str(tmp_path / "one")]) == 0
    grown = [*argv, "--starts", "2", "--reuse", str(tmp_path / "one")]
    assert measure.main([*grown, "--out", str(tmp_path / "grown")]) == 0
    assert measure.main([*argv, "--starts", "2", "--out", str(tmp_path / "full")]) == 0
    doc_g, doc_f = (json.loads((tmp_path / d / "ranking.json").read_text())
                    for d in ("grown", "full"))  # fmt: skip
    assert doc_g["agreement"] == doc_f["agreement"]
    cells = sorted((tmp_path / "grown" / "matrix" / "runs").glob("*/*/report.json"))
    assert len(cells) == 4
    for c in cells:
        assert json.loads(c.read_text())["meta"]["reused_runs"] == 1
    capsys.readouterr()
    assert measure.main([*grown[:-1], str(run), "--out", str(tmp_path / "bad")]) == 2
    assert "not a robustness matrix folder" in capsys.readouterr().err
    assert not (tmp_path / "bad").exists()


def test_ctrl_c_during_the_physics_says_what_it_kept(tmp_path: Path, capsys, monkeypatch):
    """Ctrl-C during the physics ends the measurement as every ``servobot`` command ends: exit
    130, the finished runs kept, the command that resumes."""
    from servobot.robustness import measure

    run, _ = _run_folder(tmp_path / "run")

    def interrupted(*_a, **_k):
        raise KeyboardInterrupt

    monkeypatch.setattr(measure, "run_matrix", interrupted)
    argv = ["--run", str(run), "--per-population", "1", "--starts", "1", "--steps", "2",
            "--workers", "1", "--out", str(tmp_path / "rank")]  # fmt: skip
    assert measure.main(argv) == 130
    err = capsys.readouterr().err
    assert f"kept: the finished physics runs in {tmp_path / 'rank' / 'matrix'}" in err
    assert "resume with: python -m servobot.robustness.measure --run" in err


def test_agreement_by_population_by_hand():
    """Population 0 is ranked backwards, 1 and 2 exactly; their means in the same order."""
    table = np.array([1, 2, 3, 10, 20, 30, 5, 6, 7], dtype=float)[:, None]
    physics = np.array([3, 2, 1, 10, 20, 30, 5, 6, 7], dtype=float)[:, None]
    groups = ranking.groups_of([f"p{k}g512r{r}" for k in range(3) for r in range(3)])
    assert groups.tolist() == [0, 0, 0, 1, 1, 1, 2, 2, 2]
    by = ranking.population_agreement(table, physics, groups)
    assert by["within_spearman"] == pytest.approx([-1.0, 1.0, 1.0])
    assert by["within_spearman_mean"] == pytest.approx(1 / 3)
    assert by["of_means_spearman"] == pytest.approx(1.0)
    assert by["physics_means"] == [2.0, 20.0, 6.0]
    assert ranking.groups_of(["p0g1best", "best_pop1"]).tolist() == [0, 1]  # not all: by index
    assert math.isnan(ranking.rho(np.array([1.0, 2.0]), np.array([2.0, 1.0])))  # too few


def test_sigterm_stops_the_measurement_and_its_workers(tmp_path: Path) -> None:
    """SIGTERM during the physics runs: exit 143 with what is kept and the command that
    resumes, and no pool worker left running (the process group empties)."""
    import os
    import signal
    import subprocess
    import sys
    import time

    run, _ = _run_folder(tmp_path / "run")
    out = tmp_path / "rank"
    argv = ["--run", str(run), "--per-population", "2", "--starts", "2", "--steps", "200",
            "--draws", "1", "--workers", "2", "--out", str(out)]  # fmt: skip
    proc = subprocess.Popen(
        [sys.executable, "-m", "servobot.robustness.measure", *argv],
        cwd=Path(__file__).resolve().parents[1], stdout=subprocess.DEVNULL,
        stderr=subprocess.PIPE, text=True, start_new_session=True,
    )  # fmt: skip
    t0 = time.monotonic()
    while not list(out.glob("matrix/runs/*/*/report.json")):  # the pool's workers are up
        assert proc.poll() is None, f"ended before its physics runs: {proc.stderr.read()}"
        assert time.monotonic() - t0 < 600  # a cold numba cache on a loaded machine: minutes
        time.sleep(0.05)
    proc.send_signal(signal.SIGTERM)
    _, err = proc.communicate(timeout=300)
    assert proc.returncode == 143, err
    assert "Traceback" not in err
    assert f"kept: the finished physics runs in {out / 'matrix'}" in err
    assert "resume with: python -m servobot.robustness.measure --run" in err
    t0 = time.monotonic()
    while True:  # the workers are in the command's process group
        try:
            os.killpg(proc.pid, 0)
        except ProcessLookupError:
            break
        assert time.monotonic() - t0 < 30, "a pool worker outlived the measurement"
        time.sleep(0.1)
