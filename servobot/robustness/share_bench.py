"""Benchmark: physics runs of many controllers from one start, shared against separate.

    python -m servobot.robustness.share_bench runs/rank60_slidehalf_s0/genomes \\
        [--start 3] [--steps 600] [--limit 12] [--table runs/cal/gait_table.json]

Runs the chromosomes in a folder (``*.txt``, e.g. a ranking measurement's ``genomes/``) from
one seeded coverage start (``--seed``'s ``coverage_starts``, index ``--start``) in the
shipped physics world, each on its own (``run_start``) and all through one ``PhysicsTree`` (as
``run_shared_starts`` does), checks that the records agree, and prints the gait cycles walked and
simulated and the CPU seconds of each way, with their ratios.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

from evolve.codec import read_chromosome
from evolve.settings import WorldSettings
from evolve.starts import coverage_starts
from evolve.table import load_table
from servo_mj.world.shared_physics import PhysicsTree
from servobot.validation.lone import physics_world, plan_validation, run_start


def _same(a: dict, b: dict) -> bool:
    """Records equal but for wall times."""

    def plain(r: dict) -> dict:
        out = {k: v for k, v in r.items() if k != "tracks"}
        for side in ("table", "physics"):
            if r[side] is not None:
                out[side] = {f: v for f, v in r[side].items() if f != "wall_s"}
        return out

    return plain(a) == plain(b) and all(
        np.array_equal(a["tracks"][w], b["tracks"][w]) for w in a["tracks"]
    )


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="python -m servobot.robustness.share_bench",
                                description=__doc__,
                                formatter_class=argparse.RawDescriptionHelpFormatter)  # fmt: skip
    p.add_argument("folder", type=Path, help="a folder of chromosome files (*.txt)")
    p.add_argument("--start", type=int, default=3, help="index of the seeded coverage start")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--steps", type=int, default=600)
    p.add_argument("--limit", type=int, default=12, help="at most this many chromosomes")
    p.add_argument("--table", default="paper")
    a = p.parse_args(argv)
    files = sorted(a.folder.glob("*.txt"))[: a.limit]
    if not files or a.start < 0 or a.steps < 1:
        p.error(f"{a.folder}: needs chromosome files (*.txt), --start ≥ 0 and --steps ≥ 1")
    starts = coverage_starts(np.random.default_rng(a.seed), a.start + 1, WorldSettings())
    table = load_table(a.table)
    jobs = [plan_validation(read_chromosome(f), starts, table=table, max_steps=a.steps,
                            seed=a.seed).jobs[a.start] for f in files]  # fmt: skip
    t0 = time.process_time()
    alone = [run_start(j) for j in jobs]
    t_alone = time.process_time() - t0
    t0 = time.process_time()
    tree = PhysicsTree(physics_world(jobs[0]))  # as run_shared_starts, keeping the tree
    shared = [run_start(j, tree.view) for j in jobs]
    t_shared = time.process_time() - t0
    if not all(_same(x, y) for x, y in zip(alone, shared, strict=True)):
        print("shared runs differ from separate runs", file=sys.stderr)
        return 1
    walked = sum(r["physics"]["steps"] for r in alone if r["physics"])
    simulated = tree.cycles_run
    print(f"{len(jobs)} chromosomes from start {a.start}, {a.steps} steps: records identical")
    print(f"gait cycles walked {walked}, simulated shared {simulated} ({simulated / walked:.2f})")
    print(f"CPU s: separate {t_alone:.1f}, shared {t_shared:.1f}; "
          f"speed-up {t_alone / t_shared:.2f}×")  # fmt: skip
    return 0


if __name__ == "__main__":
    sys.exit(main())
