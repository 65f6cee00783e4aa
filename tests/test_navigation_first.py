"""The navigation stage started from a given section (``run_navigation(first=...)``,
``servobot evolve navigation --first FILE``; issue 16: a lineage found in one world carried
into an envelope): generation 0 is that section throughout, it is recorded, a resume with
another is refused, and the command line takes 8- and 16-gene files and refuses bad ones."""

from __future__ import annotations

import dataclasses
import json

import numpy as np
import pytest
from chromosome_text import LIGHT_FOLLOWER
from test_stages import TABLE, TINY

from evolve import stages
from evolve.codec import read_chromosome, write_chromosome
from infra.rundir import RunDirError


def _first(tmp_path):
    path = tmp_path / "light_follower.txt"
    path.write_text(LIGHT_FOLLOWER)
    return stages.navigation_section(read_chromosome(path))


def assert_generation_0_is(folder, first, populations):
    """Every population's saved generation 0 in stage ``folder`` is ``first`` throughout, and
    the stage's record names it."""
    for k in range(populations):
        gen0 = np.load(folder / f"populations/pop{k}_gen0000.npz")
        assert (gen0["population"] == first).all()
        assert np.ptp(gen0["fitness"]) == 0  # one section: one fitness
        np.testing.assert_array_equal(gen0["best"], first)
    settings = json.loads((folder / "settings.json").read_text())
    assert settings["initial_section"] == ["".join(map(str, g)) for g in first.tolist()]


def test_generation_0_is_the_given_section_and_it_is_recorded(tmp_path):
    first = _first(tmp_path)
    ga = dataclasses.replace(TINY, populations=2, generations=2, save_generations=(0,))
    stages.run_navigation(tmp_path / "run", table=TABLE, ga=ga, first=first)
    assert_generation_0_is(tmp_path / "run/navigation", first, 2)
    # Without it generation 0 is random: the same seed gives another population.
    stages.run_navigation(tmp_path / "random", table=TABLE, ga=ga)
    gen0 = np.load(tmp_path / "random/navigation/populations/pop0_gen0000.npz")
    assert not (gen0["population"] == first).all()
    assert "initial_section" not in json.loads(
        (tmp_path / "random/navigation/settings.json").read_text()
    )
    # A resume with another first section is another run.
    other = first.copy()
    other[0, 0] ^= 1
    with pytest.raises(RunDirError, match="initial_section"):
        stages.run_navigation(tmp_path / "run", table=TABLE, ga=ga, first=other, resume=True)
    with pytest.raises(stages.StageError, match=r"the first section must be an \(8, 30\)"):
        stages.run_navigation(tmp_path / "bad", table=TABLE, ga=ga, first=first[:7])


def test_the_command_line(tmp_path, capsys):
    from servobot.cli import main

    first = _first(tmp_path)
    full = tmp_path / "full.txt"  # a 16-gene chromosome: its genes 8–15 are the section
    write_chromosome(full, np.concatenate([np.zeros_like(first), first]))
    common = ["--populations", "1", "--generations", "2", "--population-size", "4",
              "--starts-per-generation", "2", "--table", "paper", "--no-progress"]  # fmt: skip
    out = tmp_path / "nav"
    assert main(["evolve", "navigation", "--first", str(full), *common, "--out", str(out)]) == 0
    gen0 = np.load(out / "navigation/populations/pop0_gen0000.npz")
    assert (gen0["population"] == first).all()
    capsys.readouterr()
    assert main(["evolve", "navigation", "--first", str(tmp_path / "missing.txt"), *common,
                 "--out", str(tmp_path / "m")]) == 2  # fmt: skip
    assert "--first" in (err := capsys.readouterr().err) and "missing.txt: no such file" in err
