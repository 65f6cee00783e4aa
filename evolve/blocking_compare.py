"""The colony's two blocking rules side by side in the table world (issue 17, docs/colony.md
"Blocking rule: cancel or slide"): each chromosome runs as a colony from the same colony
starts under ``ColonySettings.blocking = "cancel"`` and ``"slide"`` (the kernel), and with
``slide`` once more in the reference interpreter to count the blocked moves that slid and
those still cancelled.

Run: ``python -m evolve.blocking_compare FILE [FILE ...] [--starts 200] [--robots 3]
[--seed 0] [--table paper|PATH] [--power paper|table]``. Prints one line per chromosome and
rule: colony inner % (of 64, mean over the starts), per robot inner %, blocked moves per run
(slid or cancelled) and, for slide, how many of them were cancelled. Table world only; the
physics side is ``servobot validate FILE --robots R [--blocking slide]``.
"""

from __future__ import annotations

import argparse
import dataclasses
from pathlib import Path

import numpy as np

from evolve.codec import read_chromosome
from evolve.evaluation import evaluate_colony
from evolve.interpreter import run_colony
from evolve.settings import BLOCKING_RULES, ColonySettings, WorldSettings
from evolve.starts import colony_starts
from evolve.table import load_table, with_power_model
from evolve.world import TableColony

INNER_SQUARES = 64
"""Inner squares of the test (SPEC §5): coverage percentages are of these."""


class _CountingColony(TableColony):
    """A ``TableColony`` that counts blocked moves that left the robot where it was."""

    cancelled = 0

    def step(self, i: int, gait: int) -> bool:
        before = self.pose(i)
        blocked = super().step(i, gait)
        self.cancelled += blocked and self.pose(i) == before
        return blocked


def compare(
    bits: np.ndarray, starts: np.ndarray, table: np.ndarray, world: WorldSettings,
    colony: ColonySettings,
) -> dict[str, dict[str, float]]:  # fmt: skip
    """Per rule (``BLOCKING_RULES``): mean colony and per-robot inner % and blocked moves per
    run of chromosome ``bits`` (16, 30) from colony ``starts`` (S, R, 3); for ``slide`` also
    the cancelled moves per run (the interpreter's count)."""
    out: dict[str, dict[str, float]] = {}
    for rule in BLOCKING_RULES:
        c = dataclasses.replace(colony, blocking=rule)
        ev = evaluate_colony(bits[None], starts, table=table, mode="coverage", settings=world,
                             colony=c)  # fmt: skip
        out[rule] = {
            "colony_inner_percent": 100.0 * ev.inner_squares.mean() / INNER_SQUARES,
            "robot_inner_percent": 100.0 * ev.robot_inner_squares.mean() / INNER_SQUARES,
            "blocked_per_run": float(ev.collisions.sum(axis=2).mean()),
        }
        if rule == "slide":
            cancelled = 0
            for s in range(starts.shape[0]):
                w = _CountingColony(table, starts[s], world, c)
                run_colony(bits, w, mode="coverage", settings=world, colony=c)
                cancelled += w.cancelled
            out[rule]["cancelled_per_run"] = cancelled / starts.shape[0]
    return out


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("files", type=Path, nargs="+", help="16-gene chromosome files")
    ap.add_argument("--starts", type=int, default=200, help="colony starts (200)")
    ap.add_argument("--robots", type=int, default=ColonySettings().robots)
    ap.add_argument("--seed", type=int, default=0, help="seed of the colony starts (0)")
    ap.add_argument("--table", default="paper", help="'paper' or a calibration JSON")
    ap.add_argument("--power", choices=("paper", "table"), default="paper")
    args = ap.parse_args(argv)
    table = load_table(args.table)
    world = with_power_model(WorldSettings(), args.power, table)
    colony = ColonySettings(robots=args.robots)
    starts = colony_starts(np.random.default_rng(args.seed), args.starts, world, colony)
    print(f"{args.starts} colony starts of {args.robots} (seed {args.seed}), table {args.table}")
    for path in args.files:
        res = compare(read_chromosome(path), starts, table.values, world, colony)
        for rule, r in res.items():
            extra = f", of them cancelled {r['cancelled_per_run']:.1f}" if rule == "slide" else ""
            print(
                f"{path} {rule:6s}: colony inner {r['colony_inner_percent']:5.1f}%, per robot "
                f"{r['robot_inner_percent']:5.1f}%, blocked moves per run "
                f"{r['blocked_per_run']:5.1f}{extra}"
            )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
