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


LIGHT_FOLLOWER = "\n".join(
    [
        gene("00", B(7, 1), B(6, 2), B(5, 3), G(14)),  # both lights: 1, left: 2, right: 3
        gene("00", G(0), B(0, 0), G(7), G(7)),  # ahead, look again
        gene("00", G(3), B(0, 0), G(7), G(7)),  # left, look again
        gene("00", G(11), B(0, 0), G(7), G(7)),  # right, look again
    ]
    + [STILL] * 4
)
"""A hand-written navigation section that walks towards the lights and turns on the spot in
the dark: with the paper's table it docks from 60 % of coverage start poses."""
