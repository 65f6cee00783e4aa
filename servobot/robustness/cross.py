"""Finalists of several runs in several table worlds: how much of a Figure 9 difference is the
world and how much the controllers (issue 16).

    python -m servobot.robustness.cross runs/none_s0 runs/default_s0 \\
        --table runs/cal/gait_table.json [--starts 100 --draws 8 --seed 7]

Each run's five coverage finalists (``coverage/best_pop{k}.txt``) from the same ``--starts``
coverage starts in the exact world and in variants of ``evolve.envelope.DEFAULT`` (the block
always / never seen, scatter and reach only); an envelope world is the mean of ``--draws``
draws per start. Prints % of the 64 inner squares, per finalist and mean.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

from evolve.codec import SECTION_GENES, read_chromosome
from evolve.envelope import DEFAULT, NONE, Envelope, key_of_test
from evolve.evaluation import evaluate
from evolve.interpreter import END_NAMES
from evolve.settings import WorldSettings
from evolve.starts import coverage_starts, navigation_starts
from evolve.table import load_table
from servobot.robustness.ranking import Genome, seen, table_runs

SEEN = seen(NONE, True)
"""The exact world with the station block always seen."""
WORLDS: dict[str, Envelope] = {
    "exact": NONE,
    "default": DEFAULT,
    "default, block always seen": seen(DEFAULT, True),
    "default, block never seen": seen(DEFAULT, False),
    "block always seen, exact moves": SEEN,
}
"""The table worlds each finalist runs in."""
NAVIGATION_STARTS = 1000
"""Uniform navigation starts (SPEC §6 region) of the navigation section's docking rate."""
KILL, DOCKED = END_NAMES.index("kill zone"), END_NAMES.index("docked")


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="python -m servobot.robustness.cross", description=__doc__,
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("runs", type=Path, nargs="+", help="evolve run folders")
    p.add_argument("--table", default="paper")
    p.add_argument("--starts", type=int, default=100)
    p.add_argument("--draws", type=int, default=8)
    p.add_argument("--seed", type=int, default=7)
    a = p.parse_args(argv)
    table = load_table(a.table)
    n_inner = WorldSettings().inner_square_count
    starts = coverage_starts(np.random.default_rng(a.seed), a.starts, WorldSettings())
    print("| table world | " + " | ".join(str(r) for r in a.runs) + " |")
    print("|---|" + "---|" * len(a.runs))
    finalists = {r: [Genome(f.stem, read_chromosome(f))
                     for f in sorted((r / "coverage").glob("best_pop*.txt"))] for r in a.runs}
    for name, env in WORLDS.items():
        cells = []
        for r in a.runs:
            inner = table_runs(finalists[r], starts, table=table, envelope=env, seed=a.seed,
                               draws=a.draws).mean(axis=1) / n_inner * 100  # fmt: skip
            cells.append(f"{inner.mean():.1f} ({', '.join(f'{v:.1f}' for v in inner)})")
        print(f"| {name} | " + " | ".join(cells) + " |")
    print("\nEnds (exact world and block always seen, one draw per start): kill-zone ends of the "
          "finalists' runs, docks per run; the navigation section's docking from "
          f"{NAVIGATION_STARTS} uniform navigation starts")
    rng = np.random.default_rng(a.seed)
    nav_starts = navigation_starts(rng, NAVIGATION_STARTS, WorldSettings())
    for r in a.runs:
        bits = np.stack([g.bits for g in finalists[r]])
        for name, env in (("exact", NONE), ("block seen", SEEN)):
            key = key_of_test(a.seed, "ranking", 0)
            ev = evaluate(bits, starts, table=table, mode="coverage", envelope=env,
                          envelope_key=key)  # fmt: skip
            nav = evaluate(bits[:1, SECTION_GENES:], nav_starts, table=table, mode="navigation",
                           envelope=env, envelope_key=key)  # fmt: skip
            print(f"{r} {name}: kill zone {(ev.end == KILL).sum()} of {ev.end.size} runs, "
                  f"{ev.docks.mean():.2f} docks per run; navigation docks "
                  f"{(nav.end == DOCKED).mean():.1%}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
