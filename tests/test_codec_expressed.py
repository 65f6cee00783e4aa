"""``evolve.codec.expressed``: the bits of a chromosome that can change what it does (SPEC §4),
by hand and against the table kernel (chromosomes equal in their expressed bits score the
same, bit for bit, in every mode and world)."""

from __future__ import annotations

import numpy as np
import pytest
from chromosome_text import LIGHT_FOLLOWER, STILL, B, G, gene

from evolve import evaluate
from evolve.codec import expressed, expressed_mask, parse_chromosome
from evolve.envelope import DEFAULT, NONE
from evolve.ga import random_sections
from evolve.settings import WorldSettings
from evolve.starts import coverage_starts, navigation_starts
from evolve.table import PAPER_TABLE

GAIT_BITS = [True] * 5 + [False] * 2
"""A gait instruction: its kind bit and 4 gait bits count, the 2 unused bits do not."""
BRANCH_BITS = [True] * 7
NONE_BITS = [False] * 7
LOOP = [True, True]
NO_LOOP = [False, False]


def row(loop: list[bool], *instrs: list[bool]) -> list[bool]:
    return loop + [b for i in instrs for b in i]


def test_a_hand_worked_chromosome() -> None:
    """Coverage: gene 0 (×2) falls through to gene 1 and branches to 3; gene 1 always leaves
    for gene 0 (its last two instructions and loop count do nothing); gene 3 loops forever
    (gene 4 is never next) and its low-power test goes to gene 8 whatever its target. Genes 2,
    4–7 are never reached. Navigation (the light follower): gene 8 branches to 9–11 and loops
    forever; 9–11 always leave after one gait; 12–15 are never reached."""
    cov = [
        gene("10", G(1), B(5, 3), G(5), G(6)),
        gene("00", G(2), B(0, 0), G(9), G(9)),
        STILL,
        gene("00", B(4, 5), G(4), G(4), G(4)),
        *[STILL] * 4,
    ]
    bits = parse_chromosome("\n".join(cov) + "\n" + LIGHT_FOLLOWER)
    low_power = [True] * 4 + [False] * 3
    want = np.zeros((16, 30), dtype=bool)
    want[0] = row(LOOP, GAIT_BITS, BRANCH_BITS, GAIT_BITS, GAIT_BITS)
    want[1] = row(NO_LOOP, GAIT_BITS, BRANCH_BITS, NONE_BITS, NONE_BITS)
    want[3] = row(LOOP, low_power, GAIT_BITS, GAIT_BITS, GAIT_BITS)
    want[8] = row(LOOP, BRANCH_BITS, BRANCH_BITS, BRANCH_BITS, GAIT_BITS)
    for g in (9, 10, 11):
        want[g] = row(NO_LOOP, GAIT_BITS, BRANCH_BITS, NONE_BITS, NONE_BITS)
    assert np.array_equal(expressed_mask(bits), want)
    assert np.array_equal(expressed(bits), np.where(want, bits, 0))
    # The same coverage section alone: its low-power test is a branch to gene 5, as written.
    alone = expressed_mask(bits[:8])
    assert alone[3, 2:9].all() and alone[5].any() and not alone[2].any()


def _twins(bits: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """Each chromosome with every unexpressed bit redrawn at random."""
    out = bits.copy()
    for i, b in enumerate(bits):
        mask = expressed_mask(b)
        out[i] = np.where(mask, b, rng.integers(0, 2, size=b.shape, dtype=np.uint8))
    return out


@pytest.mark.parametrize("envelope", [NONE, DEFAULT], ids=["none", "default"])
def test_equal_expressed_bits_score_the_same_bit_for_bit(envelope) -> None:
    """1500 random full chromosomes (random coverage sections; half with the light follower
    as navigation section, half random) and 1500 random navigation sections, each beside a
    twin whose unexpressed bits are redrawn: the twins' expressed bits are the chromosome's,
    and the table kernel scores them the same in every output, run by run."""
    rng = np.random.default_rng(5)
    world = WorldSettings()
    nav = parse_chromosome(LIGHT_FOLLOWER)
    full = np.concatenate([random_sections(rng, 1500), random_sections(rng, 1500)], axis=1)
    full[::2, 8:] = nav
    sections = random_sections(rng, 1500)
    for bits, mode, starts in (
        (full, "coverage", coverage_starts(rng, 6, world)),
        (sections, "navigation", navigation_starts(rng, 6, world)),
    ):
        twins = _twins(bits, rng)
        pairs = list(zip(bits, twins, strict=True))
        assert all(np.array_equal(expressed(a), expressed(b)) for a, b in pairs)
        changed = np.mean([not np.array_equal(a, b) for a, b in pairs])
        assert changed > 0.9  # the twins do differ
        a = evaluate(bits, starts, table=PAPER_TABLE, mode=mode, envelope=envelope)
        b = evaluate(twins, starts, table=PAPER_TABLE, mode=mode, envelope=envelope)
        for field in ("squares", "inner_squares", "steps", "docks", "end", "final_pose"):
            assert np.array_equal(getattr(a, field), getattr(b, field)), (mode, field)
        assert len(np.unique(a.steps)) > 10  # the runs are not all alike


def test_the_mask_depends_on_the_expressed_bits_alone() -> None:
    rng = np.random.default_rng(11)
    for b in random_sections(rng, 200):
        twin = _twins(b[None], rng)[0]
        assert np.array_equal(expressed_mask(b), expressed_mask(twin))
