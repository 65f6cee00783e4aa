"""Throughput benchmark of ``evolve.evaluate`` in robot steps per second.

Populations:
- random: uniformly random 16-gene chromosomes from the coverage start region (most die fast);
- long: constructed chromosomes that walk in circles with gaits 9/10 from the arena centre,
  testing object and light sensors on the way (never the low-power test), started with
  enough power that every run lasts the full 600 steps — the load of an evolved population.

Run: ``python -m evolve.bench [--threads 1 2] [--population 256] [--starts 10] [--repeats 5]``.
"""

from __future__ import annotations

import argparse
import time

import numba
import numpy as np

from evolve.evaluation import evaluate
from evolve.ga import random_sections
from evolve.table import PAPER_TABLE

LONG_START_POWER_V = 20.0
"""Start power of the long population: 600 cycles cost 12.54 V, so no run empties."""
CIRCLE_GAITS = (9, 10)
"""Gaits of the circling chromosomes (right turns of radius about 94 and 44 units)."""
NON_POWER_TESTS = (1, 2, 3, 5, 6, 7)
"""Sensor tests the circling chromosomes use (not 0 = always, not 4 = low power)."""


def _gait_instr(gait: int) -> list[int]:
    return [0] + [int(b) for b in f"{gait:04b}"] + [0, 0]


def _branch_instr(test: int, target: int) -> list[int]:
    return [1] + [int(b) for b in f"{test:03b}"] + [int(b) for b in f"{target:03b}"]


def circling_population(rng: np.random.Generator, n: int) -> np.ndarray:
    """``n`` 16-gene chromosomes whose every gene loops forever: gait a, a sensor branch back to
    the same gene, gait a, gait a — a from ``CIRCLE_GAITS`` (uint8 (n, 16, 30)). A taken branch
    restarts the same sequence, so the robot walks a steady circle whatever it senses."""
    out = np.empty((n, 16, 30), dtype=np.uint8)
    out[:, 8:] = random_sections(rng, n)
    for i in range(n):
        for g in range(8):
            a = int(rng.choice(CIRCLE_GAITS))
            test = int(rng.choice(NON_POWER_TESTS))
            gene = [0, 0] + _gait_instr(a) + _branch_instr(test, g) + _gait_instr(a)
            out[i, g] = gene + _gait_instr(a)
    return out


def _measure(genomes, starts, *, start_power: float, repeats: int) -> tuple[float, float]:
    """Best-of-``repeats`` (steps/s, mean steps per run)."""
    best = 0.0
    steps = 0.0
    for _ in range(repeats):
        t0 = time.perf_counter()
        ev = evaluate(genomes, starts, table=PAPER_TABLE, mode="coverage", start_power=start_power)
        dt = time.perf_counter() - t0
        best = max(best, float(ev.steps.sum()) / dt)
        steps = float(ev.steps.mean())
    return best, steps


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--threads", type=int, nargs="+", default=[1, 2])
    ap.add_argument("--population", type=int, default=256)
    ap.add_argument("--starts", type=int, default=10)
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--seed", type=int, default=0)
    args = ap.parse_args(argv)
    rng = np.random.default_rng(args.seed)
    n, s = args.population, args.starts
    rand = rng.integers(0, 2, size=(n, 16, 30), dtype=np.uint8)
    rand_starts = np.column_stack(
        [rng.uniform(350, 450, s), rng.uniform(175, 325, s), rng.uniform(0, 360, s)]
    )
    circ = circling_population(rng, n)
    circ_starts = np.column_stack(
        [rng.uniform(220, 280, s), rng.uniform(220, 280, s), rng.uniform(0, 360, s)]
    )
    evaluate(rand[:2], rand_starts[:1], table=PAPER_TABLE, mode="coverage")  # compile / load
    print(f"numba {numba.__version__}, threading layer after first call: {numba.threading_layer()}")
    print(f"population {n} x {s} starts, best of {args.repeats}")
    for threads in args.threads:
        numba.set_num_threads(threads)
        r_rate, r_steps = _measure(rand, rand_starts, start_power=4.0, repeats=args.repeats)
        c_rate, c_steps = _measure(
            circ, circ_starts, start_power=LONG_START_POWER_V, repeats=args.repeats
        )
        print(
            f"threads {threads}: random {r_rate / 1e6:6.2f} M steps/s ({r_steps:5.1f} steps/run)"
            f" | long {c_rate / 1e6:6.2f} M steps/s ({c_steps:5.1f} steps/run)"
        )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
