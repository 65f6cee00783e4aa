"""``python -m evolve.splice``: one coverage section put together with several navigation
sections, each distinct section once, named by its file; bad inputs refused before anything
is written."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from evolve.codec import read_chromosome, write_chromosome
from evolve.splice import main, names
from infra.errors import InputError


def bits(seed: int, genes: int) -> np.ndarray:
    return np.random.default_rng(seed).integers(0, 2, (genes, 30)).astype(np.uint8)


def test_each_distinct_section_after_the_coverage_section(tmp_path, capsys):
    cov, other = bits(1, 16), bits(2, 16)
    write_chromosome(tmp_path / "cov.txt", cov)
    write_chromosome(tmp_path / "a" / "navigation" / "best.txt", bits(3, 8))
    write_chromosome(tmp_path / "b" / "navigation" / "best.txt", other)  # genes 8-15 taken
    write_chromosome(tmp_path / "again.txt", bits(3, 8))  # a's section once more
    nav = [tmp_path / "a/navigation/best.txt", tmp_path / "b/navigation/best.txt",
           tmp_path / "again.txt"]  # fmt: skip
    out = tmp_path / "out"
    assert main([str(tmp_path / "cov.txt"), *map(str, nav), "--out", str(out)]) == 0
    printed = capsys.readouterr().out.splitlines()
    assert printed == [
        "again: the same section as a_navigation_best, not written",
        str(out / "a_navigation_best.txt"),
        str(out / "b_navigation_best.txt"),
    ]
    assert sorted(p.name for p in out.iterdir()) == [Path(n).name for n in printed[1:]]
    a = read_chromosome(out / "a_navigation_best.txt")
    np.testing.assert_array_equal(a[:8], cov[:8])
    np.testing.assert_array_equal(a[8:], bits(3, 8))
    np.testing.assert_array_equal(read_chromosome(out / "b_navigation_best.txt")[8:], other[8:])
    header = (out / "b_navigation_best.txt").read_text().splitlines()[:2]
    assert header == [f"# {tmp_path / 'cov.txt'}: coverage (genes 0-7)",
                      f"# {nav[1]}: navigation (genes 8-15)"]  # fmt: skip


def test_names_take_the_fewest_folders_that_tell_files_apart(tmp_path):
    paths = [tmp_path / "x/run/best.txt", tmp_path / "y/run/best.txt", tmp_path / "mix.txt"]
    assert names(paths) == ["x_run_best", "y_run_best", "mix"]
    assert names([paths[2], paths[2]]) == ["mix", "mix"]  # one file twice: one name
    # c/a/b must take a parent to be told from d/b, and then reads as the file a_b
    with pytest.raises(InputError, match="a_b.txt"):
        names([tmp_path / "a_b.txt", tmp_path / "c/a/b.txt", tmp_path / "d/b.txt"])


def test_bad_inputs_exit_2_naming_them_and_write_nothing(tmp_path, capsys):
    write_chromosome(tmp_path / "cov.txt", bits(1, 16))
    write_chromosome(tmp_path / "section.txt", bits(2, 8))
    (tmp_path / "broken.txt").write_text("01 0000000 1111111 0000000 111111\n")
    out = tmp_path / "out"
    cases = [
        (["section.txt", "section.txt"], "section.txt: a coverage section comes from a 16-gene"),
        (["cov.txt", "section.txt", "broken.txt"], "broken.txt:1: a gene needs 30 binary digits"),
        (["cov.txt", "missing.txt"], "missing.txt"),
    ]
    for args, message in cases:
        argv = [str(tmp_path / a) for a in args] + ["--out", str(out)]
        assert main(argv) == 2
        assert message in capsys.readouterr().err
        assert not out.exists()
