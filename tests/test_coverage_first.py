"""The coverage stage started from a given section (``run_coverage(first=...)``,
``servobot evolve coverage --first FILE``; issue 16: a finalist evolved in one envelope refined
in another): generation 0 is that section throughout, it is recorded, a resume with another is
refused, and the command line takes a 16-gene file's genes 0–7 and refuses bad ones."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from chromosome_text import LIGHT_FOLLOWER, B, G, chrom, gene
from test_navigation_first import assert_generation_0_is
from test_stages import TABLE, TINY

from evolve import stages
from evolve.codec import parse_chromosome, write_chromosome
from infra.rundir import RunDirError

NAV = parse_chromosome(LIGHT_FOLLOWER)
WALKER = chrom(gene("00", B(4, 1), G(0), G(0), G(0)), gene("00", G(11), G(11), B(0, 0), G(7)),
               n=8)  # fmt: skip
"""Ahead until something is in front, then turn right twice: a coverage section."""


def test_generation_0_is_the_given_section_and_it_is_recorded(tmp_path):
    ga = dataclasses.replace(TINY, populations=2, generations=2, save_generations=(0,))
    stages.run_coverage(tmp_path / "run", navigation=NAV, table=TABLE, ga=ga, first=WALKER)
    assert_generation_0_is(tmp_path / "run/coverage", WALKER, 2)
    stages.run_coverage(tmp_path / "random", navigation=NAV, table=TABLE, ga=ga)
    gen0 = np.load(tmp_path / "random/coverage/populations/pop0_gen0000.npz")
    assert not (gen0["population"] == WALKER).all()
    other = WALKER.copy()
    other[0, 0] ^= 1
    with pytest.raises(RunDirError, match="initial_section"):
        stages.run_coverage(tmp_path / "run", navigation=NAV, table=TABLE, ga=ga, first=other,
                            resume=True)  # fmt: skip
    with pytest.raises(stages.StageError, match=r"the first section must be an \(8, 30\)"):
        stages.run_coverage(tmp_path / "bad", navigation=NAV, table=TABLE, ga=ga,
                            first=WALKER[:7])  # fmt: skip


def test_the_command_line(tmp_path, capsys):
    from servobot.cli import main

    nav, full = tmp_path / "nav.txt", tmp_path / "full.txt"
    write_chromosome(nav, NAV)
    write_chromosome(full, np.concatenate([WALKER, NAV]))
    common = ["--populations", "1", "--generations", "2", "--population-size", "4",
              "--starts-per-generation", "2", "--table", "paper",
              "--navigation", str(nav), "--no-progress"]  # fmt: skip
    out = tmp_path / "cov"
    assert main(["evolve", "coverage", "--first", str(full), *common, "--out", str(out)]) == 0
    gen0 = np.load(out / "coverage/populations/pop0_gen0000.npz")
    assert (gen0["population"] == WALKER).all()
    capsys.readouterr()
    assert main(["evolve", "coverage", "--first", str(nav), *common,
                 "--out", str(tmp_path / "short")]) == 2  # fmt: skip
    assert "8 genes, but --first takes the coverage section" in capsys.readouterr().err
    assert main(["evolve", "colony", "--first", str(full), *common,
                 "--out", str(tmp_path / "c")]) == 2  # fmt: skip
    assert "--first is an option of the navigation and coverage stages" in capsys.readouterr().err
