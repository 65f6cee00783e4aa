"""Counter-based random draws (SPEC §9): a pure integer hash of a key, the same bits in plain
Python and in the numba kernels.

A draw is a function of its key, not of a generator's state: nothing is consumed, so every
individual of a generation meets the same draws at the same start, a run can be repeated alone,
and the interpreter and the kernel agree bit for bit. The hash is splitmix64's finaliser
(Steele, Lea & Flood 2014, "Fast splittable pseudorandom number generators"), a bijection of
64-bit words; a key of several words is folded in one word at a time (``absorb``).

Like ``evolve.geometry``, the functions are ``register_jitable``: plain Python when Python
calls them, compiled by numba inside the kernels. Python's integers are unbounded, numba's
``uint64`` wraps: ``u64`` and ``wrap64`` make both compute modulo 2⁶⁴ (Python masks with
``MASK64``; numba's overloads convert to ``uint64`` and leave its wraparound alone), so each
function is one source for both.

Floats: ``unit`` takes the top 53 bits of a word, ``normal3`` three standard normals by
Box–Muller (``math.log``, ``sqrt``, ``cos``, ``sin``: the same C library calls in both).
"""

from __future__ import annotations

import math

import numpy as np
from numba.extending import overload, register_jitable

MASK64 = 0xFFFF_FFFF_FFFF_FFFF
"""2⁶⁴ − 1: Python integers masked with it behave as ``uint64``."""
GOLDEN64 = 0x9E37_79B9_7F4A_7C15
"""2⁶⁴/φ, splitmix64's increment: added at each folded word."""
MIX_A = 0xBF58_476D_1CE4_E5B9
MIX_B = 0x94D0_49BB_1331_11EB
"""splitmix64's two multipliers."""
UNIT53 = 1.0 / 9007199254740992.0
"""2⁻⁵³: a 53-bit integer times this is a double in [0, 1), exactly."""
TWO_PI = 2.0 * math.pi
ROOT_KEY = 0x5345_5256_4F42_4F54
"""The hash state before the first word of a key ("SERVOBOT" in ASCII)."""


def u64(v):
    """``v`` as a uint64 (two's complement for a negative integer)."""
    return int(v) & MASK64


def wrap64(v):
    """``v`` modulo 2⁶⁴ (after a ``+`` or ``*`` of two uint64)."""
    return v & MASK64


@overload(u64)
def _u64_numba(v):
    return lambda v: np.uint64(v)


@overload(wrap64)
def _wrap64_numba(v):
    return lambda v: v  # uint64 arithmetic already wraps


@register_jitable
def mix64(z):
    """splitmix64's finaliser: a bijection of 64-bit words that mixes every bit into every
    other."""
    z = wrap64((z ^ (z >> u64(30))) * u64(MIX_A))
    z = wrap64((z ^ (z >> u64(27))) * u64(MIX_B))
    return z ^ (z >> u64(31))


@register_jitable
def absorb(h, word):
    """The hash state ``h`` after folding in the integer ``word`` (for a fixed ``h``, distinct
    words give distinct states)."""
    return mix64(wrap64((h ^ u64(word)) + u64(GOLDEN64)))


@register_jitable
def unit(z):
    """A double in [0, 1) from the top 53 bits of the word ``z``."""
    return (z >> u64(11)) * UNIT53


@register_jitable
def normal3(h, j):
    """Three standard normals, the ``j``-th triple of state ``h``: two Box–Muller pairs of
    uniforms from words 4j … 4j + 3 (the second pair's sine unused)."""
    base = 4 * j
    r1 = math.sqrt(-2.0 * math.log(1.0 - unit(absorb(h, base))))
    a1 = TWO_PI * unit(absorb(h, base + 1))
    r2 = math.sqrt(-2.0 * math.log(1.0 - unit(absorb(h, base + 2))))
    a2 = TWO_PI * unit(absorb(h, base + 3))
    return r1 * math.cos(a1), r1 * math.sin(a1), r2 * math.cos(a2)


def fold(words: tuple[int, ...]) -> int:
    """The hash state of a key of several integers (``ROOT_KEY`` absorbing each in order), as
    a Python int in [0, 2⁶⁴)."""
    h = ROOT_KEY
    for w in words:
        h = absorb(h, int(w))
    return h


__all__ = ["MASK64", "absorb", "fold", "mix64", "normal3", "u64", "unit", "wrap64"]
