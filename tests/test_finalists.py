"""The chromosomes kept in ``docs/finalists`` (the ones the docs' measurements rest on): each
parses as a navigation section or a whole chromosome, the folder's README lists exactly them,
each coverage finalist carries the navigation section its name says it evolved on (a composed
one, the section it was put together with), and a composed one its source's coverage section."""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest

from evolve.codec import SECTION_GENES, read_chromosome

FOLDER = Path(__file__).resolve().parents[1] / "docs" / "finalists"
FILES = sorted(FOLDER.glob("*.txt"))


def test_the_readme_lists_every_kept_chromosome():
    listed = set(re.findall(r"^\| `([^`]+\.txt)` \|", (FOLDER / "README.md").read_text(), re.M))
    assert listed == {f.name for f in FILES}


@pytest.mark.parametrize("path", FILES, ids=lambda p: p.name)
def test_each_file_is_a_section_or_a_whole_chromosome(path):
    bits = read_chromosome(path)
    assert bits.shape in ((SECTION_GENES, 30), (2 * SECTION_GENES, 30))
    assert path.name.startswith("nav_") == (bits.shape[0] == SECTION_GENES)


@pytest.mark.parametrize(
    ("coverage", "navigation"),
    [("cov_s0_sliphalf_pop4.txt", "nav_s0_default.txt"),
     ("cov_s1_sliphalf_p13g0896_pop4.txt", "nav_s1_p13g0896.txt"),
     ("cov_s1_sliphalf_worst_handoffs_pop3.txt", "nav_s1_worst_handoffs.txt"),
     ("cov_s1_sliphalf_min_p13g0896_pop1.txt", "nav_s1_p13g0896.txt"),
     ("cov_s1_all4mean_refined_p0i222.txt", "nav_s1_p13g0896.txt"),
     ("cov_s1_worst4_refined_p0i160.txt", "nav_s1_p13g0896.txt"),
     ("cov_s1_navmix_p1i245.txt", "nav_s1_mix.txt"),
     ("cov_s1_sliphalf_navmix.txt", "nav_s1_mix.txt"),
     ("cov_s1_sh15_p7_refined_p0i189.txt", "nav_s1_mix.txt"),
     ("cov_s1_p0i189_navp7.txt", "nav_s1_p7_p0g0512.txt"),
     ("cov_s1_p0i189_navC_p1.txt", "nav_s1_C_p1.txt"),
     ("cov_s1_sliphalf_navC_p2.txt", "nav_s1_C_p1.txt"),
     ("colony_s1_liver.txt", "nav_s1_station_colony.txt"),
     ("colony_s1_coverer.txt", "nav_s1_station_colony.txt"),
     ("colony_s1_liver_beside.txt", "nav_s1_station_colony.txt"),
     ("colony_s1_parker.txt", "nav_s1_station_colony.txt"),
     ("colony_s1_liver_alive_docks.txt", "nav_s1_station_colony.txt")],
)  # fmt: skip
def test_coverage_finalists_carry_their_navigation_section(coverage, navigation):
    full = read_chromosome(FOLDER / coverage)
    np.testing.assert_array_equal(full[SECTION_GENES:], read_chromosome(FOLDER / navigation))


@pytest.mark.parametrize(
    ("chromosome", "coverage"),
    [("cov_s1_sliphalf_navmix.txt", "cov_s1_sliphalf_p13g0896_pop4.txt"),
     ("cov_s1_p0i189_navp7.txt", "cov_s1_sh15_p7_refined_p0i189.txt"),
     ("cov_s1_p0i189_navcovA_p1.txt", "cov_s1_sh15_p7_refined_p0i189.txt"),
     ("cov_s1_p0i189_navcovA_p4.txt", "cov_s1_sh15_p7_refined_p0i189.txt"),
     ("cov_s1_p0i189_navC_p1.txt", "cov_s1_sh15_p7_refined_p0i189.txt")],  # fmt: skip
)
def test_composed_finalists_carry_their_coverage_section(chromosome, coverage):
    np.testing.assert_array_equal(read_chromosome(FOLDER / chromosome)[:SECTION_GENES],
                                  read_chromosome(FOLDER / coverage)[:SECTION_GENES])
