"""The numba kernels: fast copies of the reference interpreter (``evolve.interpreter``) for the
table world, running whole populations × start poses in parallel — one robot per run
(``run_one``) or a colony of R robots per run (``run_colony_one``, SPEC §7).

Geometry (motion, sensors, squares, kill zone, docking, other robots' discs) is not copied:
the kernels compile the very functions of ``evolve.geometry`` (``register_jitable``), so every
float formula is the interpreter's, operation for operation, and ``fastmath`` stays off. Only
the control flow is copied here. Both kernels take a gait cycle with its checks in ``_walk``;
object sensors (walls, other robots' discs, an envelope's station block) are
``_object_sense``, and a branch's test ``_branch_test``; the colony moves its program counter
with ``_next_pc`` (``evolve.codec.next_pc`` compiled; ``run_one`` spells that rule out,
measured 3 % faster).
``tests/test_kernel.py`` and ``tests/test_colony_kernel.py`` prove the kernels equal to the
interpreter on random, hand-worked and evolved chromosomes.

Speed: sensors are evaluated only when a branch reads them, only the ones its test needs, and
once per pose: the branches between two steps (a colony robot's turn) share the pose's bits,
pure functions of the pose and of the robots that do not move meanwhile (one robot's coverage
1.34×, navigation 1.5× the rate of reading them anew);
reached squares live in two uint64 masks; nothing allocates inside the loop. The P × S runs
are flattened into one ``prange`` with dynamic chunks, for load balance. A lone robot passes
the empty ``_NO_ROBOTS`` as the other robots. A colony keeps each robot's state in rows of
preallocated arrays (``S_*`` columns) and runs its turns in one loop: numba's inlining
re-references every array argument of an inlined helper (an atomic increment and decrement
each), so helpers that take the state arrays sit only on the rare paths (charging,
docking). Per robot step the colony runs at about 0.9 of the lone kernel's rate.

An envelope of variation (SPEC §9) reaches the kernels as arrays made once per batch in
Python (``evolve.variation.KernelDraws``: each run's gait table with its bias, its reach, its
station block, its scatter key) and as one jitable function, ``scattered_row``, that draws a
cycle's scatter from the robot's key and its cycle count (its ``steps``); the interpreter's
table worlds call the same. The envelope ``none`` costs a branch per cycle (scatter scale 0,
no block) and reads the table's own rows: its results are the pre-envelope ones, bit for bit
(``tests/test_envelope.py`` against stored results).

Constants and the branch, next-gene and program-counter rules come from ``evolve.codec`` and
the end codes from ``evolve.interpreter``: the kernel types none of them again.

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
    LIGHT_BITS,
    LOW_POWER,
    NAVIGATION_BASE,
    OBJECT_BITS,
    OP_GAIT,
    TEST_MASKS,
    branch_destination,
    next_gene,
    next_pc,
    sensor_test_positive,
)
from evolve.geometry import (
    P_BACKUP_GAIT,
    P_BACKUP_N,
    P_CHARGED,
    P_EMPTY,
    P_GAIT_COST,
    P_GRID_N,
    P_LOW,
    P_MAX_BRANCH,
    block_bits,
    block_slide_end,
    block_stops,
    contact_yaw,
    disc_bits_within,
    docked,
    killed,
    light_bits,
    move,
    slide_end,
    square_at,
    square_is_inner,
    too_close,
    wall_bits,
    wrap360,
)
from evolve.interpreter import (
    END_BRANCH_LIMIT,
    END_DOCKED,
    END_KILL_ZONE,
    END_POWER_EMPTY,
    END_STEP_LIMIT,
)
from evolve.settings import BLOCKING_RULES
from evolve.variation import (
    E_BACK,
    E_FRICTION,
    E_FRONT,
    E_RADIUS,
    E_SCATTER,
    E_SIDE,
    E_SLIDE,
    E_X0,
    E_X1,
    E_Y0,
    E_Y1,
    STATION_SEEN,
    STATION_STOPS,
    scattered_row,
)  # fmt: skip

_branch_destination = register_jitable(branch_destination)
_next_gene = register_jitable(next_gene)
_sensor_test_positive = register_jitable(sensor_test_positive)
_next_pc = njit(cache=True, inline="always")(next_pc)
"""``evolve.codec.next_pc`` compiled, inlined where the colony's turn loop calls it."""
_NO_ROBOTS = np.zeros((0, 3))
"""The other robots of a lone robot: none."""

OUT_SQUARES, OUT_INNER, OUT_STEPS, OUT_DOCKS, OUT_END = 0, 1, 2, 3, 4
"""Columns of the integer output of ``evaluate_flat``."""
CHUNK = 8
"""Runs per dynamically scheduled chunk of the parallel loop."""

# Per-robot integer state of a colony run, one row per robot; the first columns are outputs.
S_SQUARES, S_INNER, S_STEPS, S_DOCKS, S_END, S_COLLISIONS, S_WAITS = 0, 1, 2, 3, 4, 5, 6
S_G, S_K, S_REM, S_BRANCHES, S_PHASE, S_COUNT = 7, 8, 9, 10, 11, 12
S_COLUMNS = 13
"""S_END is −1 while the robot is live. S_COUNT: charging or backup steps left."""
PHASE_PROGRAM, PHASE_CHARGE, PHASE_BACKUP = 0, 1, 2
"""What a colony robot does on its turn: run its program, charge, or back up."""
BLOCK_SLIDE = BLOCKING_RULES.index("slide")
"""The kernel's code of ``ColonySettings.blocking = "slide"`` (``blocking_code``)."""
RUN_SQUARES, RUN_INNER, RUN_COLONY_STEPS = 0, 1, 2
"""Columns of the per-run integer output of ``evaluate_colony_flat``."""


# --------------------------------------------------------------------------- shared pieces


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
def _blocked(x, y, others, me, min_dist):
    """Whether (x, y) is too close to a robot of ``others`` (rows (x, y, h)) but row ``me``."""
    for j in range(others.shape[0]):
        if j != me and too_close(x, y, others[j, 0], others[j, 1], min_dist):
            return True
    return False


@njit(cache=True)
def _slid(x, y, nx, ny, others, me, min_dist):
    """A blocked move from (x, y) to (nx, ny) under ``ColonySettings.blocking = "slide"``:
    (end x, end y, cancelled). Slid along the one robot of ``others`` (but row ``me``) that
    blocks it (``geometry.slide_end``), cancelled when two or more block it or the slid end
    is still too close to any. Called on blocked moves only (not inlined: a rare path)."""
    first = -1
    for j in range(others.shape[0]):
        if j != me and too_close(nx, ny, others[j, 0], others[j, 1], min_dist):
            if first >= 0:
                return x, y, True
            first = j
    sx, sy = slide_end(x, y, nx, ny, others[first, 0], others[first, 1])
    if _blocked(sx, sy, others, me, min_dist):
        return x, y, True
    return sx, sy, False


@njit(cache=True)
def _yaw(x, y, h, nx, ny, others, me, min_dist, yaw):
    """Heading change, degrees, of a move from (x, y), heading h, to (nx, ny) that robots
    block: ``geometry.contact_yaw`` summed over the robots of ``others`` (but row ``me``)
    closer than ``min_dist`` to (nx, ny), in row order (``ColonySettings.contact_yaw_deg``).
    Called on blocked moves only."""
    turn = 0.0
    for j in range(others.shape[0]):
        if j != me and too_close(nx, ny, others[j, 0], others[j, 1], min_dist):
            turn += contact_yaw(x, y, h, others[j, 0], others[j, 1], yaw)
    return turn


@njit(cache=True, inline="always")
def _walk(
    gait, table, sigma, p, x, y, h, power, lo, hi, squares, inner, others, me, min_dist,
    slide, yaw, run_env, key, cycle,
):  # fmt: skip
    """One gait cycle and the post-step checks, kill zone → power empty → mark square.

    ``table`` is the robot's gait table for the run (``evolve.variation``: rows plus bias);
    cycle number ``cycle`` of the robot (from 0) adds its scatter (σ ``sigma``, the robot's
    scatter ``key``). A move that would bring the centre closer than ``min_dist`` to another
    robot (rows of ``others`` but ``me``) is cancelled, or with ``slide`` slid along it
    (``_slid``, ``ColonySettings.blocking``); one into a station block that stops is
    cancelled, or slid along it keeping the heading (``Envelope.station_blocking``) unless
    another robot blocks the slid end. A cancelled move keeps the pose; the step still costs
    and is checked. With ``yaw`` ≠ 0 a move that robots block (at its unslid end) then turns
    by ``_yaw`` (``ColonySettings.contact_yaw_deg``), slid or cancelled.
    ``run_env`` = ``_run_env``'s tuple. Returns (x, y, h, power, lo, hi, squares, inner,
    end, blocked), end = −1 if the run goes on, blocked when another robot or the station
    block blocked the move (cancelled or slid).
    """
    scale, stops, x0, y0, x1, y1, radius, slide_block, friction, body = run_env
    f, t, dh = table[gait, 0], table[gait, 1], table[gait, 2]
    if scale > 0.0:
        f, t, dh = scattered_row(
            f, t, dh, sigma[gait, 0], sigma[gait, 1], sigma[gait, 2], scale, key, cycle
        )
    nx, ny, nh = move(x, y, h, f, t, dh)
    blocked = _blocked(nx, ny, others, me, min_dist)
    turn = 0.0
    if blocked and yaw != 0.0:
        turn = _yaw(x, y, h, nx, ny, others, me, min_dist, yaw)
    cancel = blocked
    if slide and blocked:
        nx, ny, cancel = _slid(x, y, nx, ny, others, me, min_dist)
    if (
        stops
        and not cancel
        and block_stops(x, y, h, nx, ny, nh, x0, y0, x1, y1, radius, body[0], body[1], body[2])
    ):
        blocked = True
        cancel = True
        if slide_block:
            nx, ny = block_slide_end(x, y, nx, ny, x0, y0, x1, y1, friction)
            nh = h
            cancel = _blocked(nx, ny, others, me, min_dist)
    if not cancel:
        x, y, h = nx, ny, nh
    if turn != 0.0:
        h = wrap360(h + turn)
    power = power - p[P_GAIT_COST + gait]
    if killed(x, y, p):
        return x, y, h, power, lo, hi, squares, inner, END_KILL_ZONE, blocked
    if power < p[P_EMPTY]:
        return x, y, h, power, lo, hi, squares, inner, END_POWER_EMPTY, blocked
    sq = square_at(x, y, p)
    if sq >= 0:
        lo, hi, new = _mark(sq, lo, hi)
        if new:
            squares += 1
            if square_is_inner(sq, p):
                inner += 1
    return x, y, h, power, lo, hi, squares, inner, -1, blocked


@njit(cache=True, inline="always")
def _run_env(env, station):
    """(scatter scale, whether the block stops, x0, y0, x1, y1, radius, whether it slides,
    friction, the oval body's (front, back, side)) of a run from the packed envelope ``env``
    (``evolve.variation.E_*``) and its ``station`` bits: scalars that ``_walk`` reads."""
    stops = (station & STATION_STOPS) != 0
    x0, y0, x1, y1 = env[E_X0], env[E_Y0], env[E_X1], env[E_Y1]
    slides = env[E_SLIDE] != 0.0
    body = (env[E_FRONT], env[E_BACK], env[E_SIDE])
    return env[E_SCATTER], stops, x0, y0, x1, y1, env[E_RADIUS], slides, env[E_FRICTION], body


@njit(cache=True, inline="always")
def _seen_block(env, station):
    """(seen, x0, y0, x1, y1): the station block as the object sensors meet it
    (``_object_sense``)."""
    seen = (station & STATION_SEEN) != 0
    return seen, env[E_X0], env[E_Y0], env[E_X1], env[E_Y1]


@njit(cache=True, inline="always")
def _object_sense(x, y, h, p, others, me, radius, reach, block):
    """Active object-sensor bits within ``reach``: the walls, the discs of ``others`` (but row
    ``me``) and, when ``block`` = (seen, x0, y0, x1, y1) is seen, the station block."""
    active = wall_bits(x, y, h, reach, p)
    for j in range(others.shape[0]):
        if j != me:
            active |= disc_bits_within(x, y, h, others[j, 0], others[j, 1], radius, reach, p)
    seen, x0, y0, x1, y1 = block
    if seen:
        active |= block_bits(x, y, h, x0, y0, x1, y1, reach, p)
    return active


@njit(cache=True, inline="always")
def _branch_test(test, objects, lights, x, y, h, power, p, others, me, radius, reach, block):
    """Whether sensor test ``test`` (0–7) is positive at pose (x, y, h) with ``power`` volts:
    (positive, objects, lights). ``objects``/``lights``: the pose's object and light bits, −1
    until a branch reads them; read here only when the test needs them, so the branches
    between two steps share them (``_object_sense`` takes ``others`` … ``block``)."""
    mask = TEST_MASKS[test]
    active = LOW_POWER if (mask & LOW_POWER) and power < p[P_LOW] else 0
    if mask & OBJECT_BITS:
        if objects < 0:
            objects = _object_sense(x, y, h, p, others, me, radius, reach, block)
        active |= objects
    if mask & LIGHT_BITS:
        if lights < 0:
            lights = light_bits(x, y, h, p)
        active |= lights
    return _sensor_test_positive(test, active), objects, lights


@njit(cache=True, inline="always")
def _individual_start(idx, n_starts):
    """(individual, start) of row ``idx`` of a flat batch: row i·S + s is individual i from
    start s."""
    i = idx // n_starts
    return i, idx - i * n_starts


# --------------------------------------------------------------------------- one robot


@njit(cache=True)
def run_one(
    loops, ops, arg, target, nav_run, table, p, x, y, h, power, max_steps, draws
):  # fmt: skip
    """Run one chromosome (decoded, (G,) and (G, 4) arrays) from pose (x, y, h).

    ``table``: the robot's gait table for the run; ``draws`` = (packed envelope, σ (16, 3),
    scatter key, reach, station bits), its envelope draws (``evolve.variation``).
    Returns (squares, inner, steps, docks, end, x, y, h) — the interpreter's ``RunResult``.
    """
    env, sigma, key, reach, station = draws
    run_env = _run_env(env, station)
    block = _seen_block(env, station)
    n_genes = loops.shape[0]
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
    seen_objects = -1  # the pose's object and light bits once a branch has read them
    seen_lights = -1
    while True:
        in_nav = nav_run or g >= NAVIGATION_BASE
        if ops[g, k] == OP_GAIT:
            gait = arg[g, k]
            x, y, h, power, lo, hi, squares, inner, end, _ = _walk(
                gait, table, sigma, p, x, y, h, power, lo, hi, squares, inner, _NO_ROBOTS, -1,
                0.0, False, 0.0, run_env, key, steps,
            )  # fmt: skip
            steps += 1
            branches = 0
            seen_objects = -1
            seen_lights = -1
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
                    x, y, h, power, lo, hi, squares, inner, end, _ = _walk(
                        backup, table, sigma, p, x, y, h, power, lo, hi, squares, inner,
                        _NO_ROBOTS, -1, 0.0, False, 0.0, run_env, key, steps,
                    )  # fmt: skip
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
                seen_objects = -1  # (already: no branch since the docking step)
                seen_lights = -1
                g = 0
                k = 0
                rem = loops[0]
                continue
            if steps >= max_steps:
                end = END_STEP_LIMIT
                break
        else:
            test = arg[g, k]
            positive, seen_objects, seen_lights = _branch_test(
                test, seen_objects, seen_lights, x, y, h, power, p, _NO_ROBOTS, -1, 0.0, reach,
                block)  # fmt: skip
            branches += 1
            if branches >= max_branches:
                end = END_BRANCH_LIMIT
                break
            if positive:
                g = _branch_destination(g, test, target[g, k], n_genes)
                k = 0
                rem = loops[g]
                continue
        k += 1  # the rule of _next_pc, spelled out: measured 3 % faster here
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
    loops, ops, arg, target, starts, draws, p, start_power, max_steps, nav_run, out_int, out_pose
):
    """Run every (individual, start) pair; writes ``out_int`` (P·S, 5) and ``out_pose`` (P·S, 3).

    ``loops`` (P, G), ``ops``/``arg``/``target`` (P, G, 4) int64 from ``codec.decode``;
    ``starts`` (S, 3) float64; ``draws`` the arrays of ``evolve.variation.KernelDraws`` for
    S starts × 1 robot (each run's gait table, reach, station, scatter key; σ; the packed
    envelope); ``p`` from ``geometry.pack_world``. Row i·S + s holds individual i from
    start s.
    """
    rows, reach, station, keys, sigma, env = draws
    n_starts = starts.shape[0]
    total = loops.shape[0] * n_starts
    for idx in prange(total):
        i, s = _individual_start(idx, n_starts)
        r = run_one(
            loops[i],
            ops[i],
            arg[i],
            target[i],
            nav_run,
            rows[s, 0],
            p,
            starts[s, 0],
            starts[s, 1],
            starts[s, 2],
            start_power,
            max_steps,
            (env, sigma, keys[s, 0], reach[s, 0], station[s]),
        )
        out_int[idx, OUT_SQUARES] = r[0]
        out_int[idx, OUT_INNER] = r[1]
        out_int[idx, OUT_STEPS] = r[2]
        out_int[idx, OUT_DOCKS] = r[3]
        out_int[idx, OUT_END] = r[4]
        out_pose[idx, 0] = r[5]
        out_pose[idx, 1] = r[6]
        out_pose[idx, 2] = r[7]


def run_flat(loops, ops, arg, target, starts, draws, p, start_power, max_steps, nav_run):
    """Allocate outputs and run ``evaluate_flat`` with dynamic chunks; returns (ints, poses).
    ``draws``: ``evolve.variation.KernelDraws`` of S starts × 1 robot."""
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
            tuple(draws),
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


# --------------------------------------------------------------------------- a colony


@njit(cache=True, inline="always")
def _charge_step(i, loops, p, power, st):
    """Robot ``i`` charges for one colony step; returns the station's holder afterwards. Its
    power is set when full (nothing reads it while it charges). ``loops`` (R, G): every
    robot's loop counts."""
    st[i, S_COUNT] -= 1
    if st[i, S_COUNT] > 0:
        return i
    power[i] = p[P_CHARGED]
    _after_charge(i, loops, p, st)
    return -1


@njit(cache=True, inline="always")
def _after_charge(i, loops, p, st):
    """Robot ``i`` is full: its backup cycles next, or its program from gene 0."""
    st[i, S_PHASE] = PHASE_BACKUP
    st[i, S_COUNT] = int(p[P_BACKUP_N])
    st[i, S_G] = 0
    st[i, S_K] = 0
    st[i, S_REM] = loops[i, 0]
    if st[i, S_COUNT] == 0:
        st[i, S_PHASE] = PHASE_PROGRAM


@njit(cache=True, inline="always")
def _dock(i, loops, p, charge_steps, power, st):
    """Robot ``i`` docks with the station free: it holds the station for ``charge_steps``
    colony steps, or charges at once. Returns the station's holder."""
    if charge_steps > 0:
        st[i, S_PHASE] = PHASE_CHARGE
        st[i, S_COUNT] = charge_steps
        return i
    power[i] = p[P_CHARGED]
    _after_charge(i, loops, p, st)
    return -1


@njit(cache=True)
def _union(masks, p):
    """(squares, inner squares) reached by any robot."""
    lo = np.uint64(0)
    hi = np.uint64(0)
    for i in range(masks.shape[0]):
        lo |= masks[i, 0]
        hi |= masks[i, 1]
    squares = inner = 0
    n = int(p[P_GRID_N])
    for sq in range(n * n):
        word = lo if sq < 64 else hi
        if (word >> np.uint64(sq % 64)) & np.uint64(1):
            squares += 1
            if square_is_inner(sq, p):
                inner += 1
    return squares, inner


@njit(cache=True)
def _start(loops, power0, max_steps, pose, power, st, masks):
    """Every robot live at gene 0, robot i with ``power0[i]`` (ended at once if ``max_steps``
    ≤ 0)."""
    for i in range(pose.shape[0]):
        pose[i, 2] = wrap360(pose[i, 2])
        power[i] = power0[i]
        st[i, :] = 0
        st[i, S_REM] = loops[i, 0]
        st[i, S_END] = -1 if max_steps > 0 else END_STEP_LIMIT
        masks[i, 0] = 0
        masks[i, 1] = 0


@njit(cache=True)
def run_colony_one(code, nav_run, draws, p, power0, max_steps, colony, pose, power, st, masks, out):
    """Run a colony (SPEC §7) in place, robot i carrying the chromosome of row i of ``code``.

    One colony step: each live robot in index order takes a charging step, or a backup
    cycle, or runs its program to its next gait and takes it, each with its checks.
    ``code`` = decoded (loops (R, G), ops, arg, target (R, G, 4)), one row per robot (the
    same row R times for a colony of one chromosome); ``colony`` = (disc radius, minimum centre
    distance, charge steps, colony-step limit or −1, blocking code: ``BLOCK_SLIDE`` slides
    blocked moves, 0 cancels them; 1 or 0: whether the object sensors see the other robots;
    the contact yaw, degrees: ``ColonySettings.contact_yaw_deg``).
    ``power0`` (R,): each robot's start power (``ColonySettings.start_powers``). ``pose``
    (R, 3) holds the start poses and receives the final ones; ``power`` (R,), ``st`` (R,
    S_COLUMNS), ``masks`` (R, 2) uint64 are the robots' state; ``out`` receives (colony
    squares, inner, colony steps).
    ``draws`` = (gait tables (R, 16, 3), reaches (R,), station bits, scatter keys (R,), σ
    (16, 3), packed envelope): the run's envelope draws (``evolve.variation``).
    The turn is written out here, not in a helper: an inlined helper taking these arrays
    would increment and decrement each one's reference count on every turn (see the module
    docstring).
    """
    loops, ops, arg, target = code
    rows, reach, station, keys, sigma, env = draws
    run_env = _run_env(env, station)
    block = _seen_block(env, station)
    radius, min_dist = colony[0], colony[1]
    charge_steps, step_limit = int(colony[2]), int(colony[3])
    slide = int(colony[4]) == BLOCK_SLIDE
    seen = pose if int(colony[5]) != 0 else pose[:0]  # the discs the object sensors see
    yaw = colony[6]
    max_branches = int(p[P_MAX_BRANCH])
    backup = int(p[P_BACKUP_GAIT])
    _start(loops, power0, max_steps, pose, power, st, masks)
    live = pose.shape[0] if max_steps > 0 else 0
    holder = -1
    rounds = 0
    while live > 0 and rounds != step_limit:
        rounds += 1
        for i in range(pose.shape[0]):
            if st[i, S_END] >= 0:
                continue
            phase = st[i, S_PHASE]
            if phase == PHASE_CHARGE:
                holder = _charge_step(i, loops, p, power, st)
                continue
            g, k, rem, branches = st[i, S_G], st[i, S_K], st[i, S_REM], st[i, S_BRANCHES]
            x, y, h, pw = pose[i, 0], pose[i, 1], pose[i, 2], power[i]
            gait = backup
            end = -1
            if phase == PHASE_PROGRAM:
                seen_objects = -1  # as in run_one: nothing moves during the turn's branches
                seen_lights = -1
                while ops[i, g, k] != OP_GAIT:
                    test = arg[i, g, k]
                    positive, seen_objects, seen_lights = _branch_test(
                        test, seen_objects, seen_lights, x, y, h, pw, p, seen, i, radius,
                        reach[i], block)  # fmt: skip
                    branches += 1
                    if branches >= max_branches:
                        end = END_BRANCH_LIMIT
                        break
                    if positive:
                        g = _branch_destination(g, test, target[i, g, k], loops.shape[1])
                        k = 0
                        rem = loops[i, g]
                    else:
                        g, k, rem, fresh = _next_pc(g, k, rem)
                        if fresh:
                            rem = loops[i, g]
                gait = arg[i, g, k]
            if end < 0:
                lo, hi, sq, inner = masks[i, 0], masks[i, 1], st[i, S_SQUARES], st[i, S_INNER]
                x, y, h, pw, lo, hi, sq, inner, end, blocked = _walk(
                    gait, rows[i], sigma, p, x, y, h, pw, lo, hi, sq, inner, pose, i, min_dist,
                    slide, yaw, run_env, keys[i], st[i, S_STEPS],
                )  # fmt: skip
                pose[i, 0], pose[i, 1], pose[i, 2], power[i] = x, y, h, pw
                masks[i, 0], masks[i, 1], st[i, S_SQUARES], st[i, S_INNER] = lo, hi, sq, inner
                st[i, S_STEPS] += 1
                st[i, S_COLLISIONS] += blocked
                branches = 0
            st[i, S_BRANCHES] = branches
            steps = st[i, S_STEPS]
            if phase == PHASE_BACKUP:
                st[i, S_COUNT] -= 1
                if st[i, S_COUNT] == 0:
                    st[i, S_PHASE] = PHASE_PROGRAM  # g, k, rem were reset when it docked
            elif end < 0 and (nav_run or g >= NAVIGATION_BASE) and docked(x, y, h, p):
                if holder >= 0:
                    st[i, S_WAITS] += 1
                else:
                    st[i, S_DOCKS] += 1
                    if nav_run:
                        end = END_DOCKED
                    elif steps < max_steps:
                        holder = _dock(i, loops, p, charge_steps, power, st)
                        continue
            if end < 0 and steps >= max_steps:
                end = END_STEP_LIMIT
            if end >= 0:
                st[i, S_END] = end
                live -= 1
            elif phase == PHASE_PROGRAM:
                g, k, rem, fresh = _next_pc(g, k, rem)
                st[i, S_G], st[i, S_K], st[i, S_REM] = g, k, loops[i, g] if fresh else rem
    for i in range(pose.shape[0]):
        if st[i, S_END] < 0:
            st[i, S_END] = END_STEP_LIMIT
    out[RUN_SQUARES], out[RUN_INNER] = _union(masks, p)
    out[RUN_COLONY_STEPS] = rounds


@njit(parallel=True, cache=True)
def evaluate_colony_flat(
    loops, ops, arg, target, starts, draws, p, start_power, max_steps, nav_run, colony,
    st, pose, power, masks, out_run,
):  # fmt: skip
    """Run every (individual, colony start) pair: ``loops`` (P, R, G), ``ops``, ``arg``,
    ``target`` (P, R, G, 4): individual i's colony code, a row per robot (``robot_code``);
    ``starts`` (S, R, 3); ``start_power`` (R,) each robot's start power; ``draws`` the arrays
    of ``evolve.variation.KernelDraws`` for S starts × R robots; state and outputs (P·S, R, …)
    and ``out_run`` (P·S, 3), row i·S + s for individual i from start s."""
    rows, reach, station, keys, sigma, env = draws
    n_starts = starts.shape[0]
    total = loops.shape[0] * n_starts
    for idx in prange(total):
        i, s = _individual_start(idx, n_starts)
        pose[idx] = starts[s]
        run_colony_one(
            (loops[i], ops[i], arg[i], target[i]), nav_run,
            (rows[s], reach[s], station[s], keys[s], sigma, env), p, start_power, max_steps,
            colony, pose[idx], power[idx], st[idx], masks[idx], out_run[idx],
        )  # fmt: skip


def robot_code(code, robots, team=None, role=-1):
    """Each individual's colony code, a row per robot: the decoded (loops (P, G), ops, arg,
    target (P, G, 4)) of P individuals as (P, R, …) arrays, every robot carrying its
    individual, or with ``team`` (the decoded code of R partners) robot ``role`` carrying it
    and robot j ≠ ``role`` row j of ``team``."""
    out = []
    for k, own in enumerate(code):
        if team is None:
            rows = np.repeat(own[:, None], robots, axis=1)
        else:
            rows = np.repeat(np.asarray(team[k])[None], own.shape[0], axis=0)
            rows[:, role] = own
        out.append(np.ascontiguousarray(rows))
    return tuple(out)


def run_colony_flat(
    loops, ops, arg, target, starts, draws, p, start_power, max_steps, nav_run, colony,
    team=None, role=-1,
):  # fmt: skip
    """Allocate state and outputs, run ``evaluate_colony_flat`` with dynamic chunks
    (``start_power``: (R,) each robot's start power; ``team``, ``role``: partners as in
    ``robot_code``, None = every robot carries the individual); returns
    (robot state (P·S, R, S_COLUMNS), final poses (P·S, R, 3), run outputs (P·S, 3))."""
    total = loops.shape[0] * starts.shape[0]
    n_robots = starts.shape[1]
    code = robot_code((loops, ops, arg, target), n_robots, team, role)
    st = np.zeros((total, n_robots, S_COLUMNS), dtype=np.int64)
    pose = np.zeros((total, n_robots, 3), dtype=np.float64)
    power = np.zeros((total, n_robots), dtype=np.float64)
    masks = np.zeros((total, n_robots, 2), dtype=np.uint64)
    out_run = np.zeros((total, 3), dtype=np.int64)
    power0 = np.ascontiguousarray(start_power, dtype=np.float64)
    old = numba.set_parallel_chunksize(CHUNK)
    try:
        evaluate_colony_flat(
            *code, starts, tuple(draws), p, power0, int(max_steps), bool(nav_run),
            np.asarray(colony, dtype=np.float64), st, pose, power, masks, out_run,
        )  # fmt: skip
    finally:
        numba.set_parallel_chunksize(old)
    return st, pose, out_run


__all__ = [
    "CHUNK",
    "evaluate_colony_flat",
    "evaluate_flat",
    "run_colony_flat",
    "run_colony_one",
    "robot_code",
    "run_flat",
    "run_one",
]
