"""GA operators (SPEC §5): elitism, roulette, both crossover/mutation pairs, determinism."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from evolve import ga
from evolve.settings import GASettings


def _rng(seed: int = 0) -> np.random.Generator:
    return np.random.default_rng(seed)


def _pop(n: int, genes: int = 8, seed: int = 1) -> np.ndarray:
    return _rng(seed).integers(0, 2, size=(n, genes, 30), dtype=np.uint8)


def test_roulette_frequencies_follow_weights() -> None:
    w = np.array([0.0, 1.0, 2.0, 5.0, 0.0, 2.0])
    draws = ga.roulette(w, 200_000, _rng(3))
    freq = np.bincount(draws, minlength=w.size) / draws.size
    expected = w / w.sum()
    assert freq[0] == 0.0 and freq[4] == 0.0  # zero weight never chosen
    np.testing.assert_allclose(freq, expected, atol=0.01)


def test_roulette_all_zero_is_uniform() -> None:
    draws = ga.roulette(np.zeros(4), 40_000, _rng(4))
    freq = np.bincount(draws, minlength=4) / draws.size
    np.testing.assert_allclose(freq, 0.25, atol=0.02)


@pytest.mark.parametrize("bad", [np.array([1.0, -0.1]), np.array([np.nan, 1.0]), np.array([])])
def test_roulette_rejects_bad_weights(bad: np.ndarray) -> None:
    with pytest.raises(ga.GAError):
        ga.roulette(bad, 3, _rng())


def test_one_point_crossover_takes_head_genes_from_first_parent() -> None:
    n = 2000
    p1 = np.zeros((n, 8, 30), np.uint8)
    p2 = np.ones((n, 8, 30), np.uint8)
    child = ga.one_point_crossover(p1, p2, _rng(5))
    per_gene = child.all(axis=2) | (~child.astype(bool)).all(axis=2)
    assert per_gene.all()  # whole genes are copied, never split
    from_first = child[:, :, 0] == 0  # (n, 8)
    # genes 0..c from parent 1, then c+1..7 from parent 2: a prefix of Trues
    c = from_first.sum(axis=1) - 1
    assert np.array_equal(from_first, np.arange(8)[None, :] <= c[:, None])
    assert from_first[:, 0].all()  # gene 0 always from the first parent
    counts = np.bincount(c, minlength=8)
    assert counts.min() > n / 8 * 0.7  # c uniform in 0..7


def test_gene_by_gene_cut_inside_1_to_29() -> None:
    n = 3000
    p1 = np.zeros((n, 8, 30), np.uint8)
    p2 = np.ones((n, 8, 30), np.uint8)
    child = ga.gene_by_gene_crossover(p1, p2, _rng(6))
    cut = (child == 0).sum(axis=2)  # head length in bits
    # head is bits [0, cut) of parent 1, tail [cut, 30) of parent 2
    assert np.array_equal(child, (np.arange(30)[None, None, :] >= cut[..., None]).astype(np.uint8))
    assert cut.min() == 1 and cut.max() == 29
    counts = np.bincount(cut.ravel(), minlength=30)[1:30]
    assert counts.min() > cut.size / 29 * 0.7


def test_instruction_mutation_never_touches_loop_bits_and_redraws_whole_instructions() -> None:
    pop = _pop(4000)
    out = ga.instruction_mutation(pop, _rng(7), rate=0.5)
    assert np.array_equal(out[:, :, :2], pop[:, :, :2])
    changed = (out[:, :, 2:] != pop[:, :, 2:]).reshape(4000, 8, 4, 7).any(axis=3)
    # A redrawn instruction equals the old one with chance 1/128: changed ≈ 0.5·127/128.
    assert abs(changed.mean() - 0.5 * 127 / 128) < 0.01
    # and with rate 1/600 about 32/600 instructions per section change
    low = ga.instruction_mutation(pop, _rng(8), rate=1 / 600)
    n_changed = (low[:, :, 2:] != pop[:, :, 2:]).reshape(4000, 32, 7).any(axis=2).sum()
    expected = 4000 * 32 / 600 * 127 / 128
    assert 0.8 * expected < n_changed < 1.2 * expected


def test_bit_flip_rate() -> None:
    pop = _pop(5000)
    out = ga.bit_flip_mutation(pop, _rng(9), rate=1 / 200)
    rate = (out != pop).mean()
    assert abs(rate - 1 / 200) < 0.0005  # 1.2 M bits: sd ≈ 6e-5
    assert out.dtype == np.uint8 and set(np.unique(out)) <= {0, 1}


def test_next_generation_elitism_and_shape() -> None:
    pop = _pop(64)
    fit = _rng(10).random(64)
    fit[37] = 5.0
    nxt = ga.next_generation(pop, fit, _rng(11), GASettings())
    assert nxt.shape == pop.shape and nxt.dtype == np.uint8
    assert np.array_equal(nxt[0], pop[37])
    assert np.array_equal(pop, _pop(64))  # input untouched


def test_next_generation_is_deterministic() -> None:
    pop, fit = _pop(32), _rng(12).random(32)
    a = ga.next_generation(pop, fit, _rng(13), GASettings())
    b = ga.next_generation(pop, fit, _rng(13), GASettings())
    c = ga.next_generation(pop, fit, _rng(14), GASettings())
    assert np.array_equal(a, b)
    assert not np.array_equal(a, c)


def test_next_generation_selection_pressure() -> None:
    """Only individuals with weight > 0 can be parents: with mutation off, every child is
    built from the two all-ones parents and so is all ones."""
    pop = np.zeros((100, 8, 30), np.uint8)
    pop[[3, 50]] = 1
    fit = np.zeros(100)
    fit[[3, 50]] = 1.0
    quiet = dataclasses.replace(GASettings(), instruction_mutation_rate=0.0, bit_flip_rate=0.0)
    nxt = ga.next_generation(pop, fit, _rng(15), quiet)
    assert (nxt == 1).all()


def test_next_generation_operator_mix() -> None:
    """One-point children never split genes; gene-by-gene ones do (parents 0s and 1s)."""
    pop = np.zeros((2001, 8, 30), np.uint8)
    pop[1::2] = 1
    quiet = dataclasses.replace(GASettings(), instruction_mutation_rate=0.0, bit_flip_rate=0.0)
    nxt = ga.next_generation(pop, np.ones(2001), _rng(16), quiet)[1:]
    mixed_gene = (nxt.min(axis=2) != nxt.max(axis=2)).any(axis=1)
    # gene-by-gene children with different parents split every gene; half the children
    # use gene-by-gene and about half of those have parents of different kind
    assert 0.2 < mixed_gene.mean() < 0.3


def test_operators_reject_bad_shapes() -> None:
    with pytest.raises(ga.GAError, match="shape"):
        ga.bit_flip_mutation(np.zeros((3, 8, 29), np.uint8), _rng(), 0.1)
    with pytest.raises(ga.GAError, match="fitness"):
        ga.next_generation(_pop(4), np.ones(3), _rng(), GASettings())
    with pytest.raises(ga.GAError, match="fitness"):
        ga.next_generation(_pop(4), np.array([1.0, -1.0, 0, 0]), _rng(), GASettings())
