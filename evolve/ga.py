"""Operators of the multi-loop cyclic GA with conditional branching (SPEC §5; paper §IV).

Source: Parker & Zbeda, "Learning Area Coverage for a Self-Sufficient Colony Robot", the
training procedure of the area-coverage section (the navigation section is evolved with
the same operators, SPEC §6). One generation, as ``next_generation`` runs it::

    weights  = fitness ** 1.5                      # roulette weights
    child 0  = best individual, unchanged           # elitism
    for every other child (vectorised over the population):
        p1, p2 = roulette(weights), roulette(weights)
        with prob ½: one-point crossover (genes 0..c from p1, c+1..7 from p2)
                     then each of the 32 instructions redrawn with prob 1/600
        else:        gene-by-gene crossover (per gene bits [0, c) from p1, [c, 30) from p2,
                     c uniform in 1–29), then every bit flipped with prob 1/200

Sections are uint8 bit arrays (N, G, 30), most significant bit first (``evolve.codec``):
bits 0–1 loop count, then four 7-bit instructions at bits 2, 9, 16, 23. All operators are
pure functions of their arrays and an explicit ``np.random.Generator``; the same generator
state gives the same children bit for bit.
"""

from __future__ import annotations

import numpy as np

from evolve.codec import GENE_BITS, INSTRUCTION_BITS, INSTRUCTIONS_PER_GENE, LOOP_BITS
from evolve.settings import GASettings

MIN_CUT, MAX_CUT = 1, GENE_BITS - 1
"""Gene-by-gene crossover cut range, inclusive: head = bits [0, cut) of parent 1 (SPEC §5)."""


class GAError(ValueError):
    """Bad input to a GA operator (shape, dtype or fitness values)."""


def _check_sections(bits: np.ndarray, name: str) -> np.ndarray:
    arr = np.asarray(bits)
    if arr.ndim != 3 or arr.shape[2] != GENE_BITS:
        raise GAError(f"{name}: expected a bit array (N, G, 30), got shape {arr.shape}")
    if arr.dtype != np.uint8:
        raise GAError(f"{name}: expected dtype uint8, got {arr.dtype}")
    return arr


def _check_pair(p1: np.ndarray, p2: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    a, b = _check_sections(p1, "first parents"), _check_sections(p2, "second parents")
    if a.shape != b.shape:
        raise GAError(f"parents differ in shape: {a.shape} vs {b.shape}")
    return a, b


def roulette(weights: np.ndarray, n: int, rng: np.random.Generator) -> np.ndarray:
    """Draw ``n`` indices with probability proportional to ``weights`` (fitness-proportional).

    ``weights`` must be finite and ≥ 0. If they are all 0 (a population where nobody scores,
    common in generation 0 of navigation), every index is equally likely. Returns int64 (n,).
    """
    w = np.asarray(weights, dtype=np.float64)
    if w.ndim != 1 or w.size == 0:
        raise GAError(f"roulette weights must be a non-empty 1-D array, got shape {w.shape}")
    if not np.all(np.isfinite(w)) or np.any(w < 0):
        raise GAError("roulette weights must be finite and non-negative")
    if n < 0:
        raise GAError(f"roulette: cannot draw {n} indices")
    cum = np.cumsum(w)
    total = cum[-1]
    if total <= 0.0:
        return rng.integers(0, w.size, size=n)
    # u in [0, total): the first index whose cumulative weight exceeds u; zero-weight
    # entries have cum equal to their predecessor and are never chosen.
    u = rng.random(n) * total
    idx = np.searchsorted(cum, u, side="right")
    return np.minimum(idx, w.size - 1)


def one_point_crossover(p1: np.ndarray, p2: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """Gene-level one-point crossover: cut c uniform in 0..G−1, genes 0..c from ``p1``,
    genes c+1..G−1 from ``p2`` (SPEC §5; c = G−1 copies ``p1``). Shapes (N, G, 30)."""
    a, b = _check_pair(p1, p2)
    n, g, _ = a.shape
    cut = rng.integers(0, g, size=n)
    from_first = np.arange(g)[None, :] <= cut[:, None]  # (N, G)
    return np.where(from_first[:, :, None], a, b).astype(np.uint8)


def gene_by_gene_crossover(p1: np.ndarray, p2: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """Per gene one-point crossover: cut c uniform in 1–29 per (child, gene); the child's
    bits [0, c) come from ``p1`` (the head), bits [c, 30) from ``p2`` (the tail) (SPEC §5).
    So every child gene takes at least its first bit from ``p1`` and its last from ``p2``."""
    a, b = _check_pair(p1, p2)
    n, g, _ = a.shape
    cut = rng.integers(MIN_CUT, MAX_CUT + 1, size=(n, g))
    head = np.arange(GENE_BITS)[None, None, :] < cut[:, :, None]
    return np.where(head, a, b).astype(np.uint8)


def instruction_mutation(bits: np.ndarray, rng: np.random.Generator, rate: float) -> np.ndarray:
    """Redraw each 7-bit instruction uniformly (7 fair random bits) with probability ``rate``;
    loop-count bits 0–1 are never touched (SPEC §5). Returns a new array."""
    arr = _check_sections(bits, "instruction_mutation input")
    n, g, _ = arr.shape
    hit = rng.random((n, g, INSTRUCTIONS_PER_GENE)) < rate
    fresh = rng.integers(0, 2, size=(n, g, INSTRUCTIONS_PER_GENE, INSTRUCTION_BITS), dtype=np.uint8)
    out = arr.copy()
    instr = out[:, :, LOOP_BITS:].reshape(n, g, INSTRUCTIONS_PER_GENE, INSTRUCTION_BITS)
    instr[...] = np.where(hit[..., None], fresh, instr)
    out[:, :, LOOP_BITS:] = instr.reshape(n, g, GENE_BITS - LOOP_BITS)
    return out


def bit_flip_mutation(bits: np.ndarray, rng: np.random.Generator, rate: float) -> np.ndarray:
    """Flip every bit independently with probability ``rate`` (SPEC §5). Returns a new array."""
    arr = _check_sections(bits, "bit_flip_mutation input")
    flip = (rng.random(arr.shape) < rate).astype(np.uint8)
    return arr ^ flip


def next_generation(
    pop: np.ndarray, fitness: np.ndarray, rng: np.random.Generator, ga: GASettings
) -> np.ndarray:
    """The next population of sections (P, G, 30) from ``pop`` and its fitness (P,) ≥ 0.

    Index 0 is the best individual (first maximum of ``fitness``), bit-identical. Each of the
    other P−1 children has two parents drawn independently by roulette on
    ``fitness ** ga.selection_exponent`` (they may be the same individual); with probability
    ``ga.one_point_probability`` it is one-point crossover + instruction mutation, else
    gene-by-gene crossover + bit-flip mutation. Random draws, in order: first parents, second
    parents, operator choice, then the one-point children's draws, then the gene-by-gene ones.
    """
    arr = _check_sections(pop, "population")
    fit = np.asarray(fitness, dtype=np.float64)
    if fit.shape != (arr.shape[0],):
        raise GAError(f"fitness shape {fit.shape} does not match population of {arr.shape[0]}")
    if not np.all(np.isfinite(fit)) or np.any(fit < 0):
        raise GAError("fitness must be finite and non-negative")
    p = arr.shape[0]
    children = np.empty_like(arr)
    best = int(np.argmax(fit))
    children[0] = arr[best]
    n = p - 1
    if n == 0:
        return children
    weights = fit**ga.selection_exponent
    first = roulette(weights, n, rng)
    second = roulette(weights, n, rng)
    one_point = rng.random(n) < ga.one_point_probability
    a = np.flatnonzero(one_point)
    b = np.flatnonzero(~one_point)
    if a.size:
        kids = one_point_crossover(arr[first[a]], arr[second[a]], rng)
        children[1 + a] = instruction_mutation(kids, rng, ga.instruction_mutation_rate)
    if b.size:
        kids = gene_by_gene_crossover(arr[first[b]], arr[second[b]], rng)
        children[1 + b] = bit_flip_mutation(kids, rng, ga.bit_flip_rate)
    return children


def random_sections(rng: np.random.Generator, n: int, genes: int = 8) -> np.ndarray:
    """``n`` uniformly random sections (n, genes, 30) uint8 — generation 0 (SPEC §5)."""
    return rng.integers(0, 2, size=(n, genes, GENE_BITS), dtype=np.uint8)


__all__ = [
    "GAError",
    "roulette",
    "one_point_crossover",
    "gene_by_gene_crossover",
    "instruction_mutation",
    "bit_flip_mutation",
    "next_generation",
    "random_sections",
]
