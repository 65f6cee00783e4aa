"""Chromosome codec: bits ↔ the SPEC's text form, disassembly, and the decoded form kernels use.

The controller language of SPEC §4. A gene is 30 bits, most significant bit first: a 2-bit
loop count (01 once, 10 twice, 11 three times, 00 forever) and four 7-bit instructions.
An instruction whose first bit is 0 runs the gait in its next 4 bits (last 2 bits unused);
one whose first bit is 1 is a branch: 3 bits of sensor test, then 3 bits of target gene.

Genomes are ``uint8`` arrays of 0/1: shape (G, 30) for one chromosome, (P, G, 30) for a
population, with G = 8 (one section) or 16 (coverage genes 0–7 + navigation genes 8–15).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from infra.errors import InputError
from infra.io import ReadError, atomic_write_text, read_text

GENE_BITS = 30
"""Bits per gene: 2 loop bits + 4 instructions of 7 bits."""
LOOP_BITS = 2
INSTRUCTION_BITS = 7
INSTRUCTIONS_PER_GENE = 4
SECTION_GENES = 8
"""Genes in one section (coverage or navigation)."""
FULL_GENES = 16
"""Genes in a full chromosome: coverage section then navigation section."""
NAVIGATION_BASE = 8
"""Absolute index of the navigation section's first gene in a full chromosome."""

OP_GAIT = 0
"""Decoded instruction kind: run a gait cycle."""
OP_BRANCH = 1
"""Decoded instruction kind: conditional branch."""
LOOP_FOREVER = 0
"""Decoded loop count of ``00``: repeat the gene until a branch leaves it."""

# Sensor bits of the active-sensor mask (SPEC §4, Figure 7 of the paper).
OBJECT_RIGHT = 1
OBJECT_LEFT = 2
LOW_POWER = 4
LIGHT_RIGHT = 8
LIGHT_LEFT = 16
OBJECT_BITS = OBJECT_LEFT | OBJECT_RIGHT
"""Both object sensors' bits."""
LIGHT_BITS = LIGHT_LEFT | LIGHT_RIGHT
"""Both light sensors' bits."""
TEST_MASKS = (0, 1, 2, 3, 4, 8, 16, 24)
"""Sensor set of tests 0–7: test t is positive iff ``TEST_MASKS[t] & active == TEST_MASKS[t]``."""
TEST_NAMES = (
    "always",
    "object-right",
    "object-left",
    "both-object",
    "low-power",
    "light-right",
    "light-left",
    "both-light",
)
"""Display names of tests 0–7."""
LOW_POWER_TEST = 4
"""In the coverage section a positive test 4 switches control to gene 8 (SPEC §4)."""
SENSOR_NAMES = (
    (OBJECT_LEFT, "object-left"),
    (OBJECT_RIGHT, "object-right"),
    (LIGHT_LEFT, "light-left"),
    (LIGHT_RIGHT, "light-right"),
    (LOW_POWER, "low-power"),
)


class ChromosomeError(InputError, ValueError):
    """Malformed chromosome text or bits; ``line`` is the 1-based line (0 if none)."""

    def __init__(self, reason: str, *, line: int = 0, name: str = "<string>") -> None:
        self.reason = reason
        self.line = line
        self.name = name
        where = f"{name}:{line}" if line else name
        super().__init__(f"{where}: {reason}")


def sensor_test_positive(test: int, active: int) -> bool:
    """Whether sensor test 0–7 is positive for the active-sensor bitmask."""
    mask = TEST_MASKS[test]
    return (mask & active) == mask


def sensor_names(active: int) -> str:
    """Active sensors as a comma-separated list, ``-`` when none."""
    names = [n for bit, n in SENSOR_NAMES if active & bit]
    return ",".join(names) if names else "-"


def check_bits(
    bits: np.ndarray, *, name: str = "chromosome", population: bool = False
) -> np.ndarray:
    """Return ``bits`` as contiguous uint8 (G, 30) (or (P, G, 30)) of 0/1, else raise."""
    arr = np.asarray(bits)
    ndim = 3 if population else 2
    want = "(P, G, 30)" if population else "(G, 30)"
    if arr.ndim != ndim or arr.shape[-1] != GENE_BITS:
        raise ChromosomeError(f"expected a bit array of shape {want}, got {arr.shape}", name=name)
    if arr.shape[-2] not in (SECTION_GENES, FULL_GENES):
        raise ChromosomeError(f"expected 8 or 16 genes, got {arr.shape[-2]}", name=name)
    if arr.dtype.kind not in "biu":
        raise ChromosomeError(f"bits must be integers 0/1, got dtype {arr.dtype}", name=name)
    if arr.size and (arr.min() < 0 or arr.max() > 1):
        raise ChromosomeError("bits must be 0 or 1", name=name)
    return np.ascontiguousarray(arr, dtype=np.uint8)


def parse_chromosome(text: str, *, name: str = "<string>") -> np.ndarray:
    """Parse the SPEC text form into a uint8 (G, 30) array, G = 8 or 16.

    One gene per line, 30 binary digits optionally grouped by spaces; blank lines and ``#``
    comments (whole-line or trailing) are ignored. Raises ``ChromosomeError`` naming the line.
    """
    genes: list[list[int]] = []
    last_line = 0
    for lineno, raw in enumerate(text.splitlines(), start=1):
        body = raw.split("#", 1)[0].strip()
        if not body:
            continue
        last_line = lineno
        digits = "".join(body.split())
        for col, ch in enumerate(digits):
            if ch not in "01":
                raise ChromosomeError(
                    f"non-binary character {ch!r} in gene (digit {col + 1})", line=lineno, name=name
                )
        if len(digits) != GENE_BITS:
            raise ChromosomeError(
                f"a gene needs 30 binary digits, this line has {len(digits)}",
                line=lineno,
                name=name,
            )
        genes.append([int(c) for c in digits])
        if len(genes) > FULL_GENES:
            raise ChromosomeError(
                "too many genes: a chromosome has 8 or 16", line=lineno, name=name
            )
    if len(genes) not in (SECTION_GENES, FULL_GENES):
        raise ChromosomeError(
            f"expected 8 or 16 genes, found {len(genes)}", line=last_line, name=name
        )
    return np.array(genes, dtype=np.uint8)


def format_gene(gene: np.ndarray) -> str:
    """One gene as SPEC text, grouped ``ll iiiiiii iiiiiii iiiiiii iiiiiii``."""
    s = "".join("1" if b else "0" for b in gene)
    groups = [s[:LOOP_BITS]] + [
        s[LOOP_BITS + k * INSTRUCTION_BITS : LOOP_BITS + (k + 1) * INSTRUCTION_BITS]
        for k in range(INSTRUCTIONS_PER_GENE)
    ]
    return " ".join(groups)


def format_chromosome(bits: np.ndarray) -> str:
    """A (G, 30) chromosome as SPEC text: one grouped gene a line, newline-terminated. A
    team (R, G, 30), one chromosome per robot of a colony, is each chromosome after a
    ``# robot r`` line (for reports; a chromosome file holds one)."""
    if np.ndim(bits) == 3:
        return "".join(f"# robot {r}\n" + format_chromosome(b) for r, b in enumerate(bits))
    arr = check_bits(bits)
    return "".join(format_gene(g) + "\n" for g in arr)


def read_chromosome(path: str | Path) -> np.ndarray:
    """Read a chromosome text file (``#`` header comments allowed) as uint8 (G, 30); any
    problem with the file (``infra.io.read_text``) or its text is a ``ChromosomeError``."""
    try:
        text = read_text(path, what="chromosome file")
    except ReadError as exc:
        raise ChromosomeError(exc.reason, name=str(path)) from exc
    return parse_chromosome(text, name=str(path))


def write_chromosome(path: str | Path, bits: np.ndarray, header: str = "") -> Path:
    """Write a chromosome atomically in SPEC text form, ``header`` lines as ``#`` comments."""
    body = format_chromosome(bits)
    head = "".join(f"# {line}".rstrip() + "\n" for line in header.splitlines())
    return atomic_write_text(path, head + body)


def _field(bits: np.ndarray, start: int, width: int) -> np.ndarray:
    """Unsigned integer of bits[..., start:start+width], MSB first."""
    out = np.zeros(bits.shape[:-1], dtype=np.int64)
    for k in range(width):
        out = (out << 1) | bits[..., start + k].astype(np.int64)
    return out


def decode(bits: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Decode (..., G, 30) bits into arrays for kernels.

    Returns ``loops`` (..., G) int64 with 1, 2, 3 or 0 = forever (``LOOP_FOREVER``);
    ``ops`` (..., G, 4) int64, 0 gait / 1 branch; ``arg`` (..., G, 4) gait 0–15 or test 0–7;
    ``target`` (..., G, 4) target gene 0–7 within the section (0 for gait instructions).
    """
    b = np.asarray(bits, dtype=np.uint8)
    if b.ndim < 2 or b.shape[-1] != GENE_BITS:
        raise ChromosomeError(f"expected (..., G, 30) bits, got shape {b.shape}")
    loops = _field(b, 0, LOOP_BITS)
    shape = b.shape[:-1] + (INSTRUCTIONS_PER_GENE,)
    ops = np.zeros(shape, dtype=np.int64)
    arg = np.zeros(shape, dtype=np.int64)
    target = np.zeros(shape, dtype=np.int64)
    for k in range(INSTRUCTIONS_PER_GENE):
        s = LOOP_BITS + k * INSTRUCTION_BITS
        is_branch = b[..., s].astype(np.int64)
        ops[..., k] = is_branch
        gait = _field(b, s + 1, 4)
        test = _field(b, s + 1, 3)
        tgt = _field(b, s + 4, 3)
        arg[..., k] = np.where(is_branch == 1, test, gait)
        target[..., k] = np.where(is_branch == 1, tgt, 0)
    return loops, ops, arg, target


def branch_destination(gene: int, test: int, target: int, n_genes: int) -> int:
    """Absolute gene a positive branch in ``gene`` goes to (SPEC §4).

    In a 16-gene chromosome the coverage section's low-power test goes to gene 8 whatever its
    target, and branches in the navigation section go to 8 + target. In an 8-gene section
    run alone the target is used as is. Plain Python on ints, so the numba kernel compiles
    this very function (``register_jitable``): the rule has one home.
    """
    if n_genes == FULL_GENES:
        if gene >= NAVIGATION_BASE:
            return NAVIGATION_BASE + target
        if test == LOW_POWER_TEST:
            return NAVIGATION_BASE
    return target


def next_gene(gene: int) -> int:
    """The gene after ``gene`` once its loop count is spent: the next of its section, wrapping
    from the section's last gene to its first (SPEC §4). Plain Python on ints, compiled by
    the numba kernel too."""
    base = NAVIGATION_BASE if gene >= NAVIGATION_BASE else 0
    return base + (gene - base + 1) % SECTION_GENES


def next_pc(gene: int, k: int, rem: int) -> tuple[int, int, int, bool]:
    """The program counter after instruction ``k`` (0–3) of ``gene`` ran without a taken
    branch, ``rem`` runs of the gene left (0: forever) (SPEC §4): (gene, k, rem, fresh); when
    ``fresh`` the gene is new and the caller sets ``rem`` to its loop count. Plain Python on
    ints, compiled by the numba kernel too (scalars only: an array argument here costs the
    kernel's loops measurably)."""
    k += 1
    if k < 4:
        return gene, k, rem, False
    if rem != 0:
        rem -= 1
        if rem == 0:
            return next_gene(gene), 0, rem, True
    return gene, 0, rem, False


def instruction_text(op: int, arg: int, dest: int) -> str:
    """``gait 8`` or ``if light-left goto 5`` (``dest`` the absolute destination gene)."""
    if op == OP_GAIT:
        return f"gait {arg}"
    return f"if {TEST_NAMES[arg]} goto {dest}"


def disassemble(bits: np.ndarray, *, navigation_offset: bool = False) -> str:
    """Readable listing, one gene a line: ``gene 3 ×2: gait 8 | if light-left goto 5 | ...``.

    For a 16-gene chromosome gene numbers and branch targets are absolute (navigation targets
    8 + t, the coverage low-power test goes to 8). For an 8-gene section ``navigation_offset``
    shows it as the navigation section of a full chromosome (genes and targets + 8).
    """
    arr = check_bits(bits)
    n = arr.shape[0]
    loops, ops, arg, target = decode(arr)
    offset = NAVIGATION_BASE if (n == SECTION_GENES and navigation_offset) else 0
    lines = []
    for g in range(n):
        count = "∞" if loops[g] == LOOP_FOREVER else str(int(loops[g]))
        parts = []
        for k in range(INSTRUCTIONS_PER_GENE):
            dest = branch_destination(g, int(arg[g, k]), int(target[g, k]), n) + offset
            parts.append(instruction_text(int(ops[g, k]), int(arg[g, k]), dest))
        lines.append(f"gene {g + offset} ×{count}: " + " | ".join(parts))
    return "\n".join(lines) + "\n"


def expressed_mask(bits: np.ndarray) -> np.ndarray:
    """(G, 30) bool: the bits of one chromosome (8 or 16 genes) that can change what it does
    (SPEC §4). Not expressed: the genes no path reaches, the instructions after a branch whose test
    always holds (test 0, ``{}``) and that gene's loop count, the two unused bits of a gait
    instruction, and the target of the coverage section's low-power test in a full
    chromosome (it goes to gene 8). A section's entry (gene 0; gene 8 too in a full
    chromosome: low power and navigation runs start there) is reached; a branch with any
    other test may go either way. The mask depends on the expressed bits alone."""
    arr = check_bits(bits)
    n = arr.shape[0]
    loops, ops, arg, target = decode(arr)
    keep = np.zeros(arr.shape, dtype=bool)
    todo = [0] if n == SECTION_GENES else [0, NAVIGATION_BASE]
    reached: set[int] = set()
    while todo:
        g = todo.pop()
        if g in reached:
            continue
        reached.add(g)
        leaves = False  # an always-true branch: the gene never ends by its loop count
        for k in range(INSTRUCTIONS_PER_GENE):
            s = LOOP_BITS + k * INSTRUCTION_BITS
            if ops[g, k] == OP_GAIT:
                keep[g, s : s + 5] = True
                continue
            keep[g, s : s + 4] = True
            test = int(arg[g, k])
            if not (n == FULL_GENES and g < NAVIGATION_BASE and test == LOW_POWER_TEST):
                keep[g, s + 4 : s + INSTRUCTION_BITS] = True
            todo.append(branch_destination(g, test, int(target[g, k]), n))
            if TEST_MASKS[test] == 0:
                leaves = True
                break
        if not leaves:
            keep[g, :LOOP_BITS] = True
            if loops[g] != LOOP_FOREVER:
                todo.append(next_gene(g))
    return keep


def expressed(bits: np.ndarray) -> np.ndarray:
    """One chromosome with its unexpressed bits (``expressed_mask``) cleared: two chromosomes
    with equal expressed bits run the same instructions from every start in every world, so
    they score the same, bit for bit (a *behaviour*; ``tests/test_codec_expressed.py``)."""
    arr = check_bits(bits)
    return np.where(expressed_mask(arr), arr, 0).astype(np.uint8)


__all__ = [
    "ChromosomeError",
    "FULL_GENES",
    "GENE_BITS",
    "LIGHT_BITS",
    "LIGHT_LEFT",
    "LIGHT_RIGHT",
    "LOOP_FOREVER",
    "LOW_POWER",
    "LOW_POWER_TEST",
    "NAVIGATION_BASE",
    "OBJECT_BITS",
    "OBJECT_LEFT",
    "OBJECT_RIGHT",
    "OP_BRANCH",
    "OP_GAIT",
    "SECTION_GENES",
    "TEST_MASKS",
    "TEST_NAMES",
    "branch_destination",
    "check_bits",
    "decode",
    "disassemble",
    "expressed",
    "expressed_mask",
    "format_chromosome",
    "next_gene",
    "next_pc",
    "parse_chromosome",
    "read_chromosome",
    "sensor_names",
    "sensor_test_positive",
    "write_chromosome",
]
