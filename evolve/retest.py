"""Re-test a run's coverage finalists on another gait table or power model.

"Does my controller still work?" — a finalist evolved on one table world (the paper's costs,
the shipped robot) runs, unchanged, from fresh coverage starts in another (the ``table`` power
model, a variant's gait table)::

    python -m evolve.retest RUN_DIR --table PATH|paper [--power paper|table]
                            [--starts 100] [--seed 0]

prints, per finalist (``RUN_DIR/coverage/best_pop{k}.txt``), the mean inner coverage (% of
the 64 inner squares, Figure 9's measure), squares, docks and the share of runs that ended
with the bank empty, then the mean over the finalists.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Any

import numpy as np

from evolve.codec import read_chromosome
from evolve.evaluation import evaluate
from evolve.interpreter import END_POWER_EMPTY
from evolve.settings import WorldSettings
from evolve.starts import coverage_starts
from evolve.table import POWER_MODELS, GaitTable, load_table, with_power_model


def finalists(run_dir: str | Path) -> list[Path]:
    """The coverage finalists of a run folder, in population order (``FileNotFoundError`` if
    there are none)."""
    paths = sorted(Path(run_dir, "coverage").glob("best_pop*.txt"))
    if not paths:
        raise FileNotFoundError(f"{run_dir}: no coverage/best_pop*.txt finalists")
    return sorted(paths, key=lambda p: int(p.stem.removeprefix("best_pop")))


def retest(
    run_dir: str | Path,
    table: GaitTable,
    world: WorldSettings,
    *,
    starts: int = 100,
    seed: int = 0,
) -> list[dict[str, Any]]:
    """Each finalist from ``starts`` coverage starts drawn from ``default_rng(seed)``: one
    record per finalist (``finalist``, ``inner_percent``, ``squares``, ``docks``,
    ``power_empty``: share of runs)."""
    if starts < 1:
        raise ValueError(f"starts must be >= 1, got {starts}")
    poses = coverage_starts(np.random.default_rng(seed), starts, world)
    paths = finalists(run_dir)
    genomes = np.stack([read_chromosome(p) for p in paths])
    ev = evaluate(genomes, poses, table=table, mode="coverage", settings=world)
    return [
        {
            "finalist": p.stem,
            "inner_percent": float(100.0 * ev.inner_squares[k].mean() / world.inner_square_count),
            "squares": float(ev.squares[k].mean()),
            "docks": float(ev.docks[k].mean()),
            "power_empty": float((ev.end[k] == END_POWER_EMPTY).mean()),
        }
        for k, p in enumerate(paths)
    ]


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="python -m evolve.retest", description=__doc__.split("\n")[0])
    p.add_argument("run_dir", type=Path)
    p.add_argument("--table", default="paper", help="gait table: 'paper' or a calibration JSON")
    p.add_argument("--power", choices=POWER_MODELS, default="paper", help="power model")
    p.add_argument("--starts", type=int, default=100, help="fresh coverage starts (100)")
    p.add_argument("--seed", type=int, default=0, help="seed of the starts (0)")
    args = p.parse_args(argv)
    try:
        table = load_table(args.table)
        world = with_power_model(WorldSettings(), args.power, table)
        rows = retest(args.run_dir, table, world, starts=args.starts, seed=args.seed)
    except (ValueError, FileNotFoundError) as exc:
        print(f"evolve.retest: {exc}", file=sys.stderr)
        return 2
    print(f"{args.run_dir} on {args.table}, power model {args.power}, {args.starts} starts:")
    for r in rows:
        print(f"  {r['finalist']}: inner {r['inner_percent']:5.1f} %, squares {r['squares']:5.1f},"
              f" docks {r['docks']:4.2f}, power empty {r['power_empty']:.0%}")  # fmt: skip
    mean = np.mean([r["inner_percent"] for r in rows])
    print(f"  mean inner coverage {mean:.1f} % of {WorldSettings().inner_square_count}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
