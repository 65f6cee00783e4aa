"""Throughput benchmark of ``evolve.evaluate`` and ``evolve.evaluate_colony`` in robot steps
per second.

Populations:
- random: uniformly random 16-gene chromosomes from the coverage start region (most die fast);
- long: constructed chromosomes that walk in circles with gaits 9/10 from the arena centre,
  testing object and light sensors on the way (never the low-power test), started with
  enough power that every run lasts the full 600 steps — the load of an evolved population.

Each population runs alone (one robot per run) and as colonies of ``--robots`` robots from
colony starts in the same regions (``evolve.starts.colony_starts``); the colony lines give
robot steps per second and their ratio to the lone robot's, measured in alternation. Each
load runs in the world of §3 (envelope ``none``) and, on an ``envelope default`` line, in the
envelope ``DEFAULT`` (SPEC §9), with its rates' ratio to ``none``'s.

Run: ``python -m evolve.bench [--threads 1 2] [--population 256] [--starts 10] [--repeats 5]
[--robots 3] [--blocking cancel|slide] [--clock wall|cpu]``; ``--clock cpu`` divides by the
process's CPU time, which a shared machine's other load disturbs less than wall time (it hides
poor thread scaling). ``--blocking``: the colonies' ``ColonySettings.blocking``.
"""

from __future__ import annotations

import argparse
import dataclasses
import time

import numba
import numpy as np

from evolve.envelope import DEFAULT, NONE, Envelope
from evolve.evaluation import evaluate, evaluate_colony
from evolve.ga import random_sections
from evolve.settings import BLOCKING_RULES, ColonySettings, WorldSettings
from evolve.starts import colony_starts, coverage_starts
from evolve.table import PAPER_TABLE

LONG_START_POWER_V = 20.0
"""Start power of the long population: 600 cycles cost 12.54 V, so no run empties."""
CIRCLE_GAITS = (9, 10)
"""Gaits of the circling chromosomes (right turns of radius about 94 and 44 units)."""
NON_POWER_TESTS = (1, 2, 3, 5, 6, 7)
"""Sensor tests the circling chromosomes use (not 0 = always, not 4 = low power)."""
CENTRE_REGION = (220.0, 280.0)
"""x and y range of the long population's start poses, units."""


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


CLOCKS = {"wall": time.perf_counter, "cpu": time.process_time}
"""``--clock``: wall time, or the process's CPU time (all threads; steadier under load)."""


def _measure(
    genomes, starts, *, start_power: float, repeats: int, colony=None, clock=time.perf_counter,
    envelope: Envelope = NONE,
) -> float:  # fmt: skip
    """Best-of-``repeats`` robot steps per second, alone (``colony`` None) or as colonies, in
    ``envelope``."""
    best = 0.0
    kw = dict(table=PAPER_TABLE, mode="coverage", start_power=start_power, envelope=envelope)
    for _ in range(repeats):
        t0 = clock()
        if colony is None:
            ev = evaluate(genomes, starts, **kw)
        else:
            ev = evaluate_colony(genomes, starts, colony=colony, **kw)
        dt = clock() - t0
        best = max(best, float(ev.steps.sum()) / dt)
    return best


def _loads(rng: np.random.Generator, n: int, s: int, colony: ColonySettings) -> list[tuple]:
    """(name, genomes, lone starts (S, 3), colony starts (S, R, 3), start power) per load."""
    world = WorldSettings()
    centre = dataclasses.replace(
        world, coverage_start_x=CENTRE_REGION, coverage_start_y=CENTRE_REGION
    )
    rand = rng.integers(0, 2, size=(n, 16, 30), dtype=np.uint8)
    circ = circling_population(rng, n)
    return [
        ("random", rand, coverage_starts(rng, s, world), colony_starts(rng, s, world, colony), 4.0),
        ("long", circ, coverage_starts(rng, s, centre), colony_starts(rng, s, centre, colony),
         LONG_START_POWER_V),
    ]  # fmt: skip


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--threads", type=int, nargs="+", default=[1, 2])
    ap.add_argument("--population", type=int, default=256)
    ap.add_argument("--starts", type=int, default=10)
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--robots", type=int, default=ColonySettings().robots)
    ap.add_argument("--blocking", choices=BLOCKING_RULES, default=ColonySettings().blocking)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--clock", choices=tuple(CLOCKS), default="wall")
    args = ap.parse_args(argv)
    clock = CLOCKS[args.clock]
    rng = np.random.default_rng(args.seed)
    colony = ColonySettings(robots=args.robots, blocking=args.blocking)
    loads = _loads(rng, args.population, args.starts, colony)
    _, g, lone, col, _ = loads[0]
    for env in (NONE, DEFAULT):  # compile / load
        evaluate(g[:2], lone[:1], table=PAPER_TABLE, mode="coverage", envelope=env)
        evaluate_colony(g[:2], col[:1], table=PAPER_TABLE, mode="coverage", colony=colony,
                        envelope=env)  # fmt: skip
    print(f"numba {numba.__version__}, threading layer after first call: {numba.threading_layer()}")
    print(
        f"population {args.population} x {args.starts} starts, colonies of {args.robots} "
        f"({args.blocking}), best of {args.repeats} (lone and colony calls alternate), "
        f"{args.clock} clock"
    )
    for threads in args.threads:
        numba.set_num_threads(threads)
        for name, genomes, lone, col, power in loads:
            rates = {}
            for _ in range(args.repeats):  # alternate, so that all see the same load
                for env in (NONE, DEFAULT):
                    for kind, starts, c in (("lone", lone, None), ("colony", col, colony)):
                        r = _measure(genomes, starts, start_power=power, repeats=1, colony=c,
                                     clock=clock, envelope=env)  # fmt: skip
                        rates[env, kind] = max(rates.get((env, kind), 0.0), r)
            a, b = rates[NONE, "lone"], rates[NONE, "colony"]
            print(
                f"threads {threads}: {name:6s} lone {a / 1e6:6.2f} M steps/s | colony of "
                f"{args.robots} {b / 1e6:6.2f} M robot steps/s | ratio {b / a:.2f}"
            )
            da, db = rates[DEFAULT, "lone"], rates[DEFAULT, "colony"]
            print(
                f"  envelope default: lone {da / 1e6:6.2f} M steps/s ({da / a:.2f} of none) | "
                f"colony {db / 1e6:6.2f} M robot steps/s ({db / b:.2f} of none)"
            )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
