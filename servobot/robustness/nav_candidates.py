"""A navigation stage's candidate sections as chromosome files, for the test matrix (issue 16):
``python -m servobot.robustness.nav_candidates STAGE [--top N] [--out DIR]``.

STAGE is a finished ``servobot evolve navigation`` folder (``RUN/navigation``). The stage
compared candidates in the table world (``summary.json``'s ``candidates``: each population's
best of every saved generation, ``populations/pop{k}_gen{g:04d}.npz``, and its final best,
``best_pop{k}.txt``) and kept the one that docked most. This writes, as ``DIR/p{k}g{g:04d}.txt``,
the ``--top`` distinct sections that docked most there (ties: the higher selection fitness),
then each population's final best not among them, so that every lineage is in the choice.
The files go through ``servobot robustness DIR/*.txt`` and ``python -m
servobot.robustness.matrix_choice MATRIX --sections navigation`` (docs/robustness.md, "The
navigation section chosen by physics"). Exit 0, or 2 naming what is missing or malformed.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Any

import numpy as np

from evolve.checkpoint import read_npz
from evolve.codec import read_chromosome, write_chromosome
from infra.command import Interrupted, run_command
from infra.errors import InputError
from infra.io import check_output_dir, read_json

PROG = "python -m servobot.robustness.nav_candidates"
TOP = 12
"""Distinct sections kept by their table-world docking before the final bests are added."""


def section(stage: Path, population: int, generation: int, final: int) -> np.ndarray:
    """The best section of ``population`` at ``generation`` (the final best at ``final``)."""
    if generation == final:
        return read_chromosome(stage / f"best_pop{population}.txt")
    path = stage / "populations" / f"pop{population}_gen{generation:04d}.npz"
    return read_npz(path, "saved population", ("best",), error=InputError)["best"]


def candidates(stage: Path, top: int = TOP) -> list[dict[str, Any]]:
    """The sections to write, in order: ``top`` distinct ones by table docking, then each
    population's final best not among them; each ``{population, generation,
    selection_dock_rate, bits}``."""
    summary = read_json(stage / "summary.json", what="navigation summary", error=InputError)
    keys = {"population", "generation", "selection_dock_rate", "selection_fitness"}
    ok = isinstance(summary, dict) and summary.get("stage") == "navigation"
    rows = summary.get("candidates") if ok else None
    if (
        not isinstance(rows, list)
        or not rows
        or not all(isinstance(r, dict) and keys <= r.keys() for r in rows)
    ):
        raise InputError(
            f"{stage}/summary.json: not a finished navigation stage's summary "
            f"with its candidates ({', '.join(sorted(keys))})"
        )
    final = max(r["generation"] for r in rows)
    ranked = sorted(rows, key=lambda r: (-r["selection_dock_rate"], -r["selection_fitness"]))
    finals = sorted((r for r in rows if r["generation"] == final), key=lambda r: r["population"])
    kept: dict[bytes, dict[str, Any]] = {}

    def keep(r: dict[str, Any]) -> None:
        bits = np.asarray(section(stage, r["population"], r["generation"], final), np.uint8)
        kept.setdefault(bits.tobytes(), {**r, "bits": bits})

    for r in ranked:
        if len(kept) == top:
            break
        keep(r)
    for r in finals:
        keep(r)
    return list(kept.values())


def write(stage: Path, out: Path, top: int = TOP) -> list[Path]:
    """Write ``candidates(stage, top)`` to ``out``; the files written."""
    paths = []
    for c in candidates(stage, top):
        k, g = c["population"], c["generation"]
        header = (f"{stage} population {k} generation {g}: docked from "
                  f"{c['selection_dock_rate']:.1%} of the stage's selection starts")  # fmt: skip
        paths.append(write_chromosome(out / f"p{k}g{g:04d}.txt", c["bits"], header))
    return paths


def main(argv: list[str] | None = None) -> int:
    """Write the candidates and print their files; exit 0 or 2 (module docstring)."""
    ap = argparse.ArgumentParser(prog=PROG, description=__doc__.splitlines()[0])
    ap.add_argument("stage", type=Path, metavar="STAGE", help="a servobot evolve navigation folder")
    ap.add_argument("--top", type=int, default=TOP, metavar="N",
                    help=f"distinct sections by table docking (default {TOP})")  # fmt: skip
    ap.add_argument("--out", type=Path, default=None, metavar="DIR",
                    help="output folder (default STAGE/candidates)")  # fmt: skip
    a = ap.parse_args(argv)

    def body() -> int:
        if a.top < 1:
            raise InputError(f"--top must be ≥ 1, got {a.top}")
        out = check_output_dir(a.out or a.stage / "candidates")
        for p in write(a.stage, out, a.top):
            print(p)
        return 0

    return run_command(PROG, body, lambda: Interrupted("the files written so far", PROG))


if __name__ == "__main__":
    sys.exit(main())
