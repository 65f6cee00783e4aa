"""Building chromosomes in the SPEC's text form for hand-worked test cases (SPEC §4)."""

from __future__ import annotations

import numpy as np

from evolve.codec import parse_chromosome


def G(gait: int) -> str:
    """Gait instruction text: 0, 4 gait bits, 2 unused bits."""
    return f"0{gait:04b}00"


def B(test: int, target: int) -> str:
    """Branch instruction text: 1, 3 test bits, 3 target bits."""
    return f"1{test:03b}{target:03b}"


def gene(loop: str, *instrs: str) -> str:
    """One gene line: the 2 loop bits, then the instructions."""
    return " ".join((loop,) + instrs)


STILL = gene("00", G(7), G(7), G(7), G(7))
"""A gene that stands still forever."""


def chrom(*genes: str, n: int = 16) -> np.ndarray:
    """Chromosome from the given genes, the rest filled with ``STILL``."""
    return parse_chromosome("\n".join(list(genes) + [STILL] * (n - len(genes))))
