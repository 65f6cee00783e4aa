"""``servobot validate CHROMOSOME``: run a controller in the table simulation and in physics.

Runs the 16-gene chromosome from N start poses (SPEC §5 coverage region, seeded) or from the
given ``--start X Y H`` poses, in both worlds, and writes ``report.json``, ``report.md``,
``tracks.npz`` (and ``run{k}.rrd`` with ``--rrd``) into ``--out``. Prints the per-start table
and the summary. Exit status: 0 = all runs finished, 1 = some physics runs failed (their
errors are in the report), 2 = bad input (message names the problem).
"""

from __future__ import annotations

import argparse
import dataclasses
import sys
from pathlib import Path
from typing import Any

import numpy as np
from tqdm import tqdm

from evolve.codec import ChromosomeError, read_chromosome
from evolve.settings import WorldSettings
from evolve.starts import coverage_starts
from servo_mj.robot.settings import PhysicsSettings
from servo_mj.world.arena import ArenaSettings
from servobot.cli.options import add_executor_option, executor_from_args
from servobot.validate import (
    ValidationError,
    check_chromosome,
    check_start,
    load_checked_table,
    validate,
)
from servobot.validation_report import run_rows, summary_lines

DEFAULT_STARTS = 20
"""Start poses drawn when no ``--start`` is given."""
DEFAULT_OUT = Path("runs/validate")
"""Default output folder."""


class InputError(ValueError):
    """Bad command-line input; the message names the problem (exit status 2)."""


def parse_args(argv: list[str] | None) -> argparse.Namespace:
    p = argparse.ArgumentParser(
        prog="servobot validate",
        description="Run a 16-gene chromosome from start poses in the table simulation and "
        "in MuJoCo physics; report squares, inner squares, docks, steps, end reasons and the "
        "table-vs-physics gap.",
    )
    p.add_argument("chromosome", type=Path, help="chromosome text file (16 genes)")
    p.add_argument(
        "--starts",
        type=int,
        default=DEFAULT_STARTS,
        metavar="N",
        help=f"seeded start poses from the coverage region (default {DEFAULT_STARTS})",
    )
    p.add_argument(
        "--start",
        type=float,
        nargs=3,
        action="append",
        metavar=("X", "Y", "H"),
        help="a start pose (cm, cm, deg); repeatable; replaces --starts",
    )
    p.add_argument(
        "--seed", type=int, default=0, help="seed of the start poses and servo noise (default 0)"
    )
    p.add_argument(
        "--table",
        default="paper",
        metavar="paper|PATH",
        help="gait table of the table simulation (default: paper's Figure 4)",
    )
    p.add_argument(
        "--out",
        type=Path,
        default=DEFAULT_OUT,
        metavar="DIR",
        help=f"output folder (default {DEFAULT_OUT})",
    )
    p.add_argument("--rrd", action="store_true", help="write run{k}.rrd rerun recordings")
    p.add_argument(
        "--workers",
        type=int,
        default=None,
        metavar="K",
        help="processes or Ray CPUs (default: one per core)",
    )
    add_executor_option(p, None, "process, serial with --workers 1")
    p.add_argument(
        "--steps", type=int, default=None, metavar="N", help="steps per run (default 600, SPEC §5)"
    )
    p.add_argument(
        "--noise",
        type=float,
        default=None,
        metavar="RAD",
        help="servo-target noise std in physics, rad (default: PhysicsSettings, 0 = off)",
    )
    p.add_argument(
        "--model",
        type=Path,
        default=None,
        metavar="FILE",
        help="robot model file in physics, e.g. from 'servobot variant' (default: shipped); "
        "a --table PATH must have been calibrated on it",
    )
    p.add_argument(
        "--station-height",
        type=float,
        default=None,
        metavar="M",
        help="height of the physics station block, m (default ArenaSettings: 0.10, below the "
        "rangefinder rays; 0.30 lets the object sensors see the block)",
    )
    p.add_argument("--no-progress", action="store_true", help="no progress bar")
    return p.parse_args(argv)


def prepare(args: argparse.Namespace, world: WorldSettings) -> tuple[np.ndarray, np.ndarray]:
    """Read the chromosome and build the start poses; ``InputError`` on bad input."""
    try:
        bits = check_chromosome(read_chromosome(args.chromosome))
    except (ChromosomeError, ValidationError) as exc:
        raise InputError(f"chromosome: {exc}") from exc
    if args.start:
        starts = np.array(args.start, dtype=float)
    else:
        if args.starts < 1:
            raise InputError(f"--starts must be at least 1, got {args.starts}")
        starts = coverage_starts(np.random.default_rng(args.seed), args.starts, world)
    for k, s in enumerate(starts):
        try:
            check_start(s, world, name=f"start {k} ({s[0]:g} {s[1]:g} {s[2]:g})")
        except ValidationError as exc:
            raise InputError(str(exc)) from exc
    if args.workers is not None and args.workers < 1:
        raise InputError(f"--workers must be at least 1, got {args.workers}")
    if args.noise is not None and not (args.noise >= 0.0 and np.isfinite(args.noise)):
        raise InputError(f"--noise must be a finite number >= 0, got {args.noise}")
    if args.steps is not None and args.steps < 0:
        raise InputError(f"--steps must be at least 0, got {args.steps}")
    if args.station_height is not None and not (0.0 < args.station_height < np.inf):
        raise InputError(f"--station-height must be a height > 0 m, got {args.station_height}")
    return bits, starts


def main(argv: list[str] | None = None) -> int:
    args = parse_args(argv)
    world = WorldSettings()
    try:
        bits, starts = prepare(args, world)
        table, warning = load_checked_table(args.table, args.model)
    except (InputError, ValidationError) as exc:
        print(f"servobot validate: {exc}", file=sys.stderr)
        return 2
    if warning:
        print(warning, file=sys.stderr)

    physics = None if args.noise is None else PhysicsSettings(servo_noise_rad=args.noise)
    arena = ArenaSettings()
    if args.station_height is not None:
        arena = dataclasses.replace(arena, station_height_m=args.station_height)
    bar = tqdm(total=len(starts), desc="validate", unit="start", disable=args.no_progress)

    def on_run(rec: dict[str, Any]) -> None:
        bar.update(1)
        if rec.get("error"):
            bar.write(f"run {rec['index']}: {rec['error']}")

    try:
        report = validate(
            bits,
            starts,
            table=table,
            world=world,
            physics=physics,
            arena=arena,
            out_dir=args.out,
            rrd=args.rrd,
            executor=executor_from_args(args, "servobot validate"),
            max_steps=args.steps,
            seed=args.seed,
            model=args.model,
            on_run=on_run,
            meta={
                "chromosome_file": str(args.chromosome),
                "seed": args.seed,
                "command": "servobot validate " + " ".join(argv or sys.argv[1:]),
            },
        )
    finally:
        bar.close()
    print("\n".join(run_rows(report)))
    print()
    print("\n".join(summary_lines(report)))
    print(f"\nwrote {args.out / 'report.json'}, {args.out / 'report.md'}")
    return 1 if report["summary"]["physics_errors"] else 0


if __name__ == "__main__":
    sys.exit(main())
