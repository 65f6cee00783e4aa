"""One coverage section put together with several navigation sections:
``python -m evolve.splice COVERAGE NAVIGATION... [--out DIR]``.

A 16-gene chromosome is a coverage section (genes 0–7) that hands control to a navigation
section (genes 8–15) when its store reads low (SPEC §4). The two sections are evolved in
different stages, and the one that docks a coverage section's hand-offs best in physics is
not the one the table world picked (docs/robustness.md), so a user tries one coverage
section on several navigation sections. COVERAGE is a 16-gene chromosome file (its genes
0–7 are kept); each NAVIGATION is an 8-gene section or a 16-gene chromosome (its genes
8–15 are taken). This writes one 16-gene chromosome per distinct navigation section as
``DIR/NAME.txt``, NAME the navigation file's stem, prefixed by as many of its parent
folders as tell it from the other inputs (``a/navigation/best.txt`` and
``b/navigation/best.txt`` give ``a_navigation_best`` and ``b_navigation_best``); a
section equal to an earlier one is written once and reported. Each file's header names
both sources. The files go through ``servobot robustness DIR/*.txt`` and ``python -m
servobot.robustness.matrix_choice``. Prints the files written; exit 0, or 2 naming a
malformed input.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

from evolve.codec import (
    FULL_GENES,
    SECTION_GENES,
    ChromosomeError,
    read_chromosome,
    write_chromosome,
)
from evolve.stages import navigation_section
from infra.command import Interrupted, run_command
from infra.errors import InputError
from infra.io import check_output_dir

PROG = "python -m evolve.splice"


def coverage_section(path: Path) -> np.ndarray:
    """Genes 0–7 of a 16-gene chromosome file; an 8-gene file is refused (a section file
    holds a navigation section)."""
    bits = read_chromosome(path)
    if len(bits) != FULL_GENES:
        raise ChromosomeError(
            f"a coverage section comes from a {FULL_GENES}-gene chromosome, "
            f"this file has {len(bits)} genes",
            name=str(path),
        )
    return bits[:SECTION_GENES]


def names(paths: list[Path]) -> list[str]:
    """Each path's stem, prefixed by the fewest parent folders that tell it from every other
    file given (joined by ``_``); the same file given twice keeps one name."""
    parts = [p.resolve().with_suffix("").parts for p in paths]

    def tail(p: tuple[str, ...], depth: int) -> str:
        return "_".join(p[-depth:])

    out = []
    for p in parts:
        depth = 1
        while depth < len(p) and any(q != p and tail(q, depth) == tail(p, depth) for q in parts):
            depth += 1
        out.append(tail(p, depth))
    owner: dict[str, tuple[str, ...]] = {}
    for name, p in zip(out, parts, strict=True):
        if owner.setdefault(name, p) != p:
            raise InputError(f"two navigation files would be written as {name}.txt")
    return out


def splice(
    coverage: Path, navigation: list[Path]
) -> tuple[list[tuple[str, np.ndarray, str]], list[tuple[str, str]]]:
    """``(name, bits, header)`` per distinct navigation section, in input order, and
    ``(name, earlier name)`` for each section equal to an earlier one (not written)."""
    cov = coverage_section(coverage)
    first: dict[bytes, str] = {}
    written, same = [], []
    for name, path in zip(names(navigation), navigation, strict=True):
        nav = navigation_section(read_chromosome(path))
        key = nav.tobytes()
        if key in first:
            same.append((name, first[key]))
            continue
        first[key] = name
        header = f"{coverage}: coverage (genes 0-7)\n{path}: navigation (genes 8-15)"
        written.append((name, np.concatenate([cov, nav]), header))
    return written, same


def main(argv: list[str] | None = None) -> int:
    """Write the spliced chromosomes and print their files; exit 0 or 2 (module docstring)."""
    ap = argparse.ArgumentParser(prog=PROG, description=__doc__.splitlines()[0])
    ap.add_argument("coverage", type=Path, metavar="COVERAGE",
                    help="16-gene chromosome: its coverage section (genes 0-7)")  # fmt: skip
    ap.add_argument("navigation", type=Path, nargs="+", metavar="NAVIGATION",
                    help="8-gene sections or 16-gene chromosomes (genes 8-15)")  # fmt: skip
    ap.add_argument("--out", type=Path, default=Path("runs/splice"), metavar="DIR",
                    help="output folder (default runs/splice)")  # fmt: skip
    a = ap.parse_args(argv)

    def body() -> int:
        written, same = splice(a.coverage, a.navigation)
        out = check_output_dir(a.out)
        for name, earlier in same:
            print(f"{name}: the same section as {earlier}, not written")
        for name, bits, header in written:
            print(write_chromosome(out / f"{name}.txt", bits, header))
        return 0

    return run_command(PROG, body, lambda: Interrupted("the files written so far", PROG))


if __name__ == "__main__":
    sys.exit(main())
