"""``servobot validate CHROMOSOME``: run a controller in the table simulation and in physics.

Runs the 16-gene chromosome from N start poses (SPEC §5 coverage region, seeded) or from the
given ``--start X Y H`` poses, in both worlds, and writes ``report.json``, ``report.md``,
``tracks.npz`` (and ``run{k}.rrd`` with ``--rrd``) into ``--out``. Prints the per-start table
and the summary. Exit status: 0 = all runs finished, 1 = some physics runs failed (their
errors are in the report), 2 = bad input (message names the problem).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Any

import numpy as np

from evolve.settings import WorldSettings
from evolve.table import GaitTable, GaitTableError, load_table

DEFAULT_STARTS = 20
"""Start poses drawn when no ``--start`` is given."""
DEFAULT_OUT = Path("runs/validate")
"""Default output folder."""


class InputError(ValueError):
    """Bad command-line input; the message names the problem (exit status 2)."""


def draw_starts(n: int, rng: np.random.Generator, world: WorldSettings) -> np.ndarray:
    """(n, 3) coverage start poses (SPEC §5): x, y uniform in the coverage region, heading
    uniform in [0, 360); one ``rng.random((n, 3))`` draw, as ``evolve.stages.coverage_starts``."""
    (x0, x1), (y0, y1) = world.coverage_start_x, world.coverage_start_y
    u = rng.random((n, 3))
    return np.column_stack([x0 + (x1 - x0) * u[:, 0], y0 + (y1 - y0) * u[:, 1], 360.0 * u[:, 2]])


def _find_sha(meta: Any) -> str | None:
    """The model sha256 recorded anywhere in a calibration file's metadata, if any."""
    if isinstance(meta, dict):
        for k, v in meta.items():
            if "sha256" in str(k).lower() and isinstance(v, str):
                return v
        for v in meta.values():
            found = _find_sha(v)
            if found:
                return found
    return None


def load_checked_table(spec: str) -> tuple[GaitTable, str | None]:
    """Load ``paper`` or a calibration file; refuse a file made for another robot model.

    Returns the table and a warning (or None). Raises ``InputError`` naming both model hashes
    when the file's model sha256 differs from the current ServoBot model's.
    """
    try:
        table = load_table(spec)
    except GaitTableError as exc:
        raise InputError(f"gait table: {exc}") from exc
    if spec == "paper":
        return table, None
    from servo_mj.model import model_sha256

    current = model_sha256()
    recorded = _find_sha(table.meta)
    if recorded is None:
        return table, f"warning: {spec} records no model sha256; cannot check it fits this robot"
    if recorded != current:
        raise InputError(
            f"gait table {spec} was calibrated on another robot model: its model sha256 is "
            f"{recorded}, the current model's (models/servobot) is {current}"
        )
    return table, None


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
        help="processes (default: one per core; 1 = serial)",
    )
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
    p.add_argument("--no-progress", action="store_true", help="no progress bar")
    return p.parse_args(argv)


def prepare(args: argparse.Namespace, world: WorldSettings) -> tuple[np.ndarray, np.ndarray]:
    """Read the chromosome and build the start poses; ``InputError`` on bad input."""
    from evolve.codec import ChromosomeError, read_chromosome
    from servo_mj.validate import ValidationError, check_chromosome, check_start

    try:
        bits = check_chromosome(read_chromosome(args.chromosome))
    except (ChromosomeError, ValidationError) as exc:
        raise InputError(f"chromosome: {exc}") from exc
    if args.start:
        starts = np.array(args.start, dtype=float)
    else:
        if args.starts < 1:
            raise InputError(f"--starts must be at least 1, got {args.starts}")
        starts = draw_starts(args.starts, np.random.default_rng(args.seed), world)
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
    return bits, starts


def main(argv: list[str] | None = None) -> int:
    args = parse_args(argv)
    world = WorldSettings()
    try:
        bits, starts = prepare(args, world)
        table, warning = load_checked_table(args.table)
    except InputError as exc:
        print(f"servobot validate: {exc}", file=sys.stderr)
        return 2
    if warning:
        print(warning, file=sys.stderr)

    from tqdm import tqdm

    from servo_mj.validate import run_rows, summary_lines, validate

    physics = None
    if args.noise is not None:
        from servo_mj.settings import PhysicsSettings

        physics = PhysicsSettings(servo_noise_rad=args.noise)
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
            out_dir=args.out,
            rrd=args.rrd,
            workers=args.workers,
            max_steps=args.steps,
            seed=args.seed,
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
