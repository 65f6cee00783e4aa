"""Cost of a gait cycle in a colony arena of R robots, against the lone robot's arena.

Robot 0 walks the same gait sequence from the arena centre while the other R − 1 robots stand
far from it (no contact): one ``PhysicsColony.step(0, gait)`` per cycle, against
``PhysicsWorld.step(gait)`` in the lone arena. Every robot of the model is simulated while one
walks (the standing robots hold their servos and stand on their feet): measured, each
standing robot adds ≈ 0.6 of a lone cycle (docs/colony.md "Cost").

Interleaved ``--repeats`` times in this process, CPU seconds (``time.process_time``); prints
ms per cycle and the ratio to the lone arena; asserts nothing.

Run: ``python -m servo_mj.world.colony_bench [--robots 1 2 3 5] [--cycles 20] [--repeats 3]``.
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from evolve.settings import ColonySettings
from servo_mj.world.physics_colony import PhysicsColony
from servo_mj.world.physics_world import PhysicsWorld

STANDING = ((100.0, 100.0, 0.0), (400.0, 100.0, 0.0), (100.0, 400.0, 0.0), (400.0, 400.0, 0.0),
            (100.0, 250.0, 0.0), (250.0, 100.0, 0.0), (250.0, 400.0, 0.0))  # fmt: skip
"""Where robots 1, 2, … stand: ≥ 1 m from the walker's circle around the centre."""
WALK = (8, 14, 8, 6, 0, 11, 15, 3)
"""Robot 0's gait sequence (repeated): walks, turns and backs up near the centre."""


def time_cycles(robots: int | None, cycles: int) -> float:
    """CPU seconds per gait cycle of robot 0; ``robots`` None = the lone arena."""
    gaits = [WALK[k % len(WALK)] for k in range(cycles)]
    start = (250.0, 250.0, 0.0)
    if robots is None:
        world = PhysicsWorld(*start)
        t0 = time.process_time()
        for g in gaits:
            world.step(g)
    else:
        if robots - 1 > len(STANDING):
            raise ValueError(f"at most {len(STANDING) + 1} robots")
        starts = [start, *STANDING[: robots - 1]]
        colony = PhysicsColony(starts, colony_settings=ColonySettings(robots=robots))
        t0 = time.process_time()
        for g in gaits:
            colony.step(0, g)
    return (time.process_time() - t0) / cycles


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="python -m servo_mj.world.colony_bench", description=__doc__)
    p.add_argument("--robots", type=int, nargs="+", default=[1, 2, 3, 5])
    p.add_argument("--cycles", type=int, default=20)
    p.add_argument("--repeats", type=int, default=3)
    args = p.parse_args(argv)
    kinds: list[int | None] = [None, *args.robots]
    for k in kinds:  # compile every arena before timing
        time_cycles(k, 1)
    times: dict[int | None, list[float]] = {k: [] for k in kinds}
    for _ in range(args.repeats):
        for k in kinds:
            times[k].append(time_cycles(k, args.cycles))
    lone = float(np.median(times[None]))
    print(f"{'arena':>12} | ms per cycle (median of {args.repeats}) | × lone")
    for k in kinds:
        med = float(np.median(times[k]))
        name = "lone" if k is None else f"colony of {k}"
        spread = ", ".join(f"{1000 * t:.1f}" for t in times[k])
        print(f"{name:>12} | {1000 * med:.1f} ({spread}) | {med / lone:.2f}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
