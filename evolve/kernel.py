"""The numba kernel: a fast copy of the reference interpreter (``evolve.interpreter``) for the
table world, running whole populations × start poses in parallel.

Geometry (motion, sensors, squares, kill zone, docking) is not copied: the kernel compiles the
very functions of ``evolve.geometry`` (``register_jitable``), so every float formula is the
interpreter's, operation for operation, and ``fastmath`` stays off. Only the control flow is
copied here; ``tests/test_kernel.py`` proves it equal on random and hand-worked chromosomes.

Speed: sensors are evaluated only when a branch reads them and only the ones its test needs;
reached squares live in two uint64 masks; nothing allocates inside the loop. The P × S runs
are flattened into one ``prange`` with dynamic chunks, for load balance.

Constants and the branch and next-gene rules come from ``evolve.codec`` and the end codes
from ``evolve.interpreter``: the kernel types none of them again.

Note on numba's cache: a cached kernel is invalidated by edits to this file only, not to
``geometry.py`` or ``codec.py``; after editing those, delete
``evolve/__pycache__/kernel*.nbi/.nbc``.
"""

from __future__ import annotations

import numba
import numpy as np
from numba import njit, prange
from numba.extending import register_jitable

from evolve.codec import (
    LIGHT_LEFT,
    LIGHT_RIGHT,
    LOW_POWER,
    NAVIGATION_BASE,
    OBJECT_LEFT,
    OBJECT_RIGHT,
    OP_GAIT,
    TEST_MASKS,
    branch_destination,
    next_gene,
)
from evolve.geometry import (
    P_BACKUP_GAIT,
    P_BACKUP_N,
    P_CHARGED,
    P_EMPTY,
    P_GAIT_COST,
    P_LOW,
    P_MAX_BRANCH,
    docked,
    killed,
    light_bits,
    move,
    object_bits,
    square_at,
    square_is_inner,
    wrap360,
)
from evolve.interpreter import (
    END_BRANCH_LIMIT,
    END_DOCKED,
    END_KILL_ZONE,
    END_POWER_EMPTY,
    END_STEP_LIMIT,
)

_OBJECT_MASK = OBJECT_LEFT | OBJECT_RIGHT
_LIGHT_MASK = LIGHT_LEFT | LIGHT_RIGHT
_branch_destination = register_jitable(branch_destination)
_next_gene = register_jitable(next_gene)

OUT_SQUARES, OUT_INNER, OUT_STEPS, OUT_DOCKS, OUT_END = 0, 1, 2, 3, 4
"""Columns of the integer output of ``evaluate_flat``."""
CHUNK = 8
"""Runs per dynamically scheduled chunk of the parallel loop."""


@njit(cache=True)
def _mark(sq, lo, hi):
    """Set square ``sq`` in the (lo, hi) masks; returns (lo, hi, newly reached)."""
    if sq < 64:
        bit = np.uint64(1) << np.uint64(sq)
        if lo & bit:
            return lo, hi, False
        return lo | bit, hi, True
    bit = np.uint64(1) << np.uint64(sq - 64)
    if hi & bit:
        return lo, hi, False
    return lo, hi | bit, True


@njit(cache=True, inline="always")
def _walk(gait, table, p, x, y, h, power, lo, hi, squares, inner):
    """One gait cycle and the post-step checks, kill zone → power empty → mark square.

    Returns (x, y, h, power, lo, hi, squares, inner, end) with end = −1 when the run goes on.
    """
    x, y, h = move(x, y, h, table[gait, 0], table[gait, 1], table[gait, 2])
    power = power - p[P_GAIT_COST + gait]
    if killed(x, y, p):
        return x, y, h, power, lo, hi, squares, inner, END_KILL_ZONE
    if power < p[P_EMPTY]:
        return x, y, h, power, lo, hi, squares, inner, END_POWER_EMPTY
    sq = square_at(x, y, p)
    if sq >= 0:
        lo, hi, new = _mark(sq, lo, hi)
        if new:
            squares += 1
            if square_is_inner(sq, p):
                inner += 1
    return x, y, h, power, lo, hi, squares, inner, -1


@njit(cache=True)
def run_one(loops, ops, arg, target, nav_run, table, p, x, y, h, power, max_steps):
    """Run one chromosome (decoded, (G,) and (G, 4) arrays) from pose (x, y, h).

    Returns (squares, inner, steps, docks, end, x, y, h) — the interpreter's ``RunResult``.
    """
    n_genes = loops.shape[0]
    low = p[P_LOW]
    max_branches = int(p[P_MAX_BRANCH])
    backup = int(p[P_BACKUP_GAIT])
    n_backup = int(p[P_BACKUP_N])
    charged = p[P_CHARGED]
    h = wrap360(h)
    lo = np.uint64(0)
    hi = np.uint64(0)
    squares = 0
    inner = 0
    steps = 0
    docks = 0
    branches = 0
    end = END_STEP_LIMIT
    if max_steps <= 0:
        return squares, inner, steps, docks, end, x, y, h
    g = 0
    k = 0
    rem = loops[0]
    while True:
        in_nav = nav_run or g >= NAVIGATION_BASE
        if ops[g, k] == OP_GAIT:
            gait = arg[g, k]
            x, y, h, power, lo, hi, squares, inner, end = _walk(
                gait, table, p, x, y, h, power, lo, hi, squares, inner
            )
            steps += 1
            branches = 0
            if end >= 0:
                break
            if in_nav and docked(x, y, h, p):
                docks += 1
                if nav_run:
                    end = END_DOCKED
                    break
                if steps >= max_steps:
                    end = END_STEP_LIMIT
                    break
                # Charging routine: full power, backup cycles, no docking check.
                power = charged
                stop = False
                for _ in range(n_backup):
                    x, y, h, power, lo, hi, squares, inner, end = _walk(
                        backup, table, p, x, y, h, power, lo, hi, squares, inner
                    )
                    steps += 1
                    if end >= 0:
                        stop = True
                        break
                    if steps >= max_steps:
                        end = END_STEP_LIMIT
                        stop = True
                        break
                if stop:
                    break
                g = 0
                k = 0
                rem = loops[0]
                continue
            if steps >= max_steps:
                end = END_STEP_LIMIT
                break
        else:
            test = arg[g, k]
            mask = TEST_MASKS[test]
            active = 0
            if (mask & LOW_POWER) and power < low:
                active |= LOW_POWER
            if mask & _OBJECT_MASK:
                active |= object_bits(x, y, h, p)
            if mask & _LIGHT_MASK:
                active |= light_bits(x, y, h, p)
            branches += 1
            if branches >= max_branches:
                end = END_BRANCH_LIMIT
                break
            if (active & mask) == mask:
                g = _branch_destination(g, test, target[g, k], n_genes)
                k = 0
                rem = loops[g]
                continue
        k += 1
        if k == 4:
            k = 0
            if rem != 0:
                rem -= 1
                if rem == 0:
                    g = _next_gene(g)
                    rem = loops[g]
    return squares, inner, steps, docks, end, x, y, h


@njit(parallel=True, cache=True)
def evaluate_flat(
    loops, ops, arg, target, starts, table, p, start_power, max_steps, nav_run, out_int, out_pose
):
    """Run every (individual, start) pair; writes ``out_int`` (P·S, 5) and ``out_pose`` (P·S, 3).

    ``loops`` (P, G), ``ops``/``arg``/``target`` (P, G, 4) int64 from ``codec.decode``;
    ``starts`` (S, 3) float64; ``table`` (16, 3); ``p`` from ``geometry.pack_world``.
    Row i·S + s holds individual i from start s.
    """
    n_starts = starts.shape[0]
    total = loops.shape[0] * n_starts
    for idx in prange(total):
        i = idx // n_starts
        s = idx - i * n_starts
        r = run_one(
            loops[i],
            ops[i],
            arg[i],
            target[i],
            nav_run,
            table,
            p,
            starts[s, 0],
            starts[s, 1],
            starts[s, 2],
            start_power,
            max_steps,
        )
        out_int[idx, OUT_SQUARES] = r[0]
        out_int[idx, OUT_INNER] = r[1]
        out_int[idx, OUT_STEPS] = r[2]
        out_int[idx, OUT_DOCKS] = r[3]
        out_int[idx, OUT_END] = r[4]
        out_pose[idx, 0] = r[5]
        out_pose[idx, 1] = r[6]
        out_pose[idx, 2] = r[7]


def run_flat(loops, ops, arg, target, starts, table, p, start_power, max_steps, nav_run):
    """Allocate outputs and run ``evaluate_flat`` with dynamic chunks; returns (ints, poses)."""
    total = loops.shape[0] * starts.shape[0]
    out_int = np.zeros((total, 5), dtype=np.int64)
    out_pose = np.zeros((total, 3), dtype=np.float64)
    old = numba.set_parallel_chunksize(CHUNK)
    try:
        evaluate_flat(
            loops,
            ops,
            arg,
            target,
            starts,
            table,
            p,
            float(start_power),
            int(max_steps),
            bool(nav_run),
            out_int,
            out_pose,
        )
    finally:
        numba.set_parallel_chunksize(old)
    return out_int, out_pose


__all__ = ["CHUNK", "evaluate_flat", "run_flat", "run_one"]
