"""Codec: SPEC §4 text form round trips and rejects, decoding and disassembly by hand."""

from __future__ import annotations

import numpy as np
import pytest
from chromosome_text import B, G, gene

from evolve.codec import (
    ChromosomeError,
    check_bits,
    decode,
    disassemble,
    format_chromosome,
    parse_chromosome,
    read_chromosome,
    write_chromosome,
)
from evolve.ga import random_sections

FILLER = gene("01", G(7), G(7), G(7), G(7))


@pytest.mark.parametrize("n_genes", [8, 16])
def test_round_trip_text(n_genes: int) -> None:
    rng = np.random.default_rng(n_genes)
    bits = rng.integers(0, 2, size=(n_genes, 30), dtype=np.uint8)
    text = format_chromosome(bits)
    assert len(text.splitlines()) == n_genes
    assert np.array_equal(parse_chromosome(text), bits)


def test_format_groups_loop_and_instructions() -> None:
    line = gene("10", G(8), B(6, 5), G(15), B(0, 0))
    bits = parse_chromosome("\n".join([line] + [FILLER] * 7))
    first = format_chromosome(bits).splitlines()[0]
    assert first == "10 0100000 1110101 0111100 1000000"
    assert [len(g) for g in first.split()] == [2, 7, 7, 7, 7]


def test_file_round_trip_with_header(tmp_path) -> None:
    bits = random_sections(np.random.default_rng(3), 1)[0]
    path = write_chromosome(tmp_path / "best.txt", bits, header="best of population 2\nfit 0.5")
    text = path.read_text()
    assert text.startswith("# best of population 2\n# fit 0.5\n")
    assert np.array_equal(read_chromosome(path), bits)
    assert [p.name for p in tmp_path.iterdir()] == ["best.txt"]  # no temp file left behind


def test_parse_ignores_comments_blank_lines_and_spacing() -> None:
    lines = ["# header", "", gene("00", G(1), G(2), G(3), G(4)).replace(" ", "") + "  # gene 0"]
    lines += ["   " + FILLER] * 7
    bits = parse_chromosome("\n".join(lines))
    assert bits.shape == (8, 30) and bits.dtype == np.uint8
    loops, ops, arg, _ = decode(bits)
    assert loops[0] == 0 and arg[0].tolist() == [1, 2, 3, 4] and ops[0].tolist() == [0, 0, 0, 0]


def test_reject_short_gene_names_line() -> None:
    lines = ["# c", FILLER, FILLER[:-1]] + [FILLER] * 6
    with pytest.raises(ChromosomeError, match=r"<string>:3: .*30 binary digits.*29") as info:
        parse_chromosome("\n".join(lines))
    assert info.value.line == 3


def test_reject_non_binary_character_names_line() -> None:
    lines = [FILLER] * 4 + [FILLER.replace("1", "2", 1)] + [FILLER] * 3
    with pytest.raises(ChromosomeError, match=r"f\.txt:5: non-binary character '2'"):
        parse_chromosome("\n".join(lines), name="f.txt")


@pytest.mark.parametrize("count", [0, 1, 7, 9, 15])
def test_reject_wrong_gene_count(count: int) -> None:
    with pytest.raises(ChromosomeError, match=f"expected 8 or 16 genes, found {count}"):
        parse_chromosome("\n".join([FILLER] * count))


def test_reject_too_many_genes_names_line() -> None:
    with pytest.raises(ChromosomeError, match=r":17: too many genes") as info:
        parse_chromosome("\n".join([FILLER] * 17))
    assert info.value.line == 17


def test_missing_file_is_a_chromosome_error(tmp_path) -> None:
    with pytest.raises(ChromosomeError, match="no such chromosome file"):
        read_chromosome(tmp_path / "absent.txt")


def test_decode_every_loop_count_and_instruction_kind() -> None:
    genes = [
        gene("01", G(0), G(15), B(0, 7), B(7, 0)),
        gene("10", G(8), B(6, 5), G(15), B(4, 3)),
        gene("11", G(7), G(7), G(7), G(7)),
        gene("00", B(1, 1), B(2, 2), B(3, 3), B(5, 6)),
    ] + [FILLER] * 4
    loops, ops, arg, target = decode(parse_chromosome("\n".join(genes)))
    assert loops[:4].tolist() == [1, 2, 3, 0]
    assert ops[0].tolist() == [0, 0, 1, 1] and arg[0].tolist() == [0, 15, 0, 7]
    assert target[0].tolist() == [0, 0, 7, 0]
    assert arg[1].tolist() == [8, 6, 15, 4] and target[1].tolist() == [0, 5, 0, 3]
    assert arg[3].tolist() == [1, 2, 3, 5] and target[3].tolist() == [1, 2, 3, 6]


def test_gait_unused_bits_are_ignored() -> None:
    a = parse_chromosome("\n".join([gene("01", "0100011", G(0), G(0), G(0))] + [FILLER] * 7))
    _, ops, arg, _ = decode(a)
    assert ops[0, 0] == 0 and arg[0, 0] == 8


def test_decode_population_shape() -> None:
    bits = np.random.default_rng(0).integers(0, 2, size=(5, 16, 30), dtype=np.uint8)
    loops, ops, arg, target = decode(bits)
    assert loops.shape == (5, 16) and ops.shape == arg.shape == target.shape == (5, 16, 4)
    single = decode(bits[3])
    assert np.array_equal(single[2], arg[3]) and np.array_equal(single[0], loops[3])


def test_disassemble_matches_spec_example() -> None:
    genes = [FILLER] * 3 + [gene("10", G(8), B(6, 5), G(15), B(0, 0))] + [FILLER] * 3
    genes.append(gene("00", B(4, 3), G(7), G(7), G(7)))
    lines = disassemble(parse_chromosome("\n".join(genes))).splitlines()
    assert lines[3] == "gene 3 ×2: gait 8 | if light-left goto 5 | gait 15 | if always goto 0"
    assert lines[7] == "gene 7 ×∞: if low-power goto 3 | gait 7 | gait 7 | gait 7"
    nav = disassemble(parse_chromosome("\n".join(genes)), navigation_offset=True).splitlines()
    assert nav[3].startswith("gene 11 ×2: gait 8 | if light-left goto 13 |")
    assert nav[3].endswith("if always goto 8")


def test_disassemble_full_chromosome_targets() -> None:
    cov = [gene("00", B(4, 3), B(5, 2), G(0), G(0))] + [FILLER] * 7
    nav = [gene("11", B(4, 3), B(0, 1), G(9), G(9))] + [FILLER] * 7
    lines = disassemble(parse_chromosome("\n".join(cov + nav))).splitlines()
    # Coverage low-power test goes to gene 8 whatever its target; navigation targets are 8 + t.
    assert lines[0] == "gene 0 ×∞: if low-power goto 8 | if light-right goto 2 | gait 0 | gait 0"
    assert lines[8] == "gene 8 ×3: if low-power goto 11 | if always goto 9 | gait 9 | gait 9"


def test_random_sections_are_seeded() -> None:
    a = random_sections(np.random.default_rng(7), 4)
    b = random_sections(np.random.default_rng(7), 4)
    assert a.shape == (4, 8, 30) and a.dtype == np.uint8 and np.array_equal(a, b)
    assert set(np.unique(a)) == {0, 1}


def test_check_bits_rejects_bad_arrays() -> None:
    with pytest.raises(ChromosomeError, match="0 or 1"):
        check_bits(np.full((8, 30), 2, dtype=np.uint8))
    with pytest.raises(ChromosomeError, match="8 or 16 genes"):
        check_bits(np.zeros((9, 30), dtype=np.uint8))
    with pytest.raises(ChromosomeError, match=r"\(G, 30\)"):
        check_bits(np.zeros((8, 29), dtype=np.uint8))
    with pytest.raises(ChromosomeError, match="integers"):
        check_bits(np.zeros((8, 30), dtype=np.float64))
