"""``servobot reproduce``: the end-to-end reproduction into one run folder (resumable).

Parses the options, shows progress and prints where the report is;
``servobot.reproduce.run.reproduce`` does the work. Bad input exits 2 before any stage runs;
Ctrl-C exits 130 keeping the finished stages and checkpoints (``servobot.cli.runner``).
"""

from __future__ import annotations

import argparse
from pathlib import Path

from evolve.settings import BLOCKING_RULES, COLONY_FITNESSES
from infra.bounds import check_int, check_nonnegative, check_workers
from infra.errors import InputError
from servobot.cli.options import (
    add_envelope_option,
    add_executor_option,
    add_model_option,
    executor_from_args,
)
from servobot.cli.runner import run_main
from servobot.progress import GenerationBars, RunBar
from servobot.reproduce.report import format_seconds
from servobot.reproduce.run import reproduce, resolve_settings
from servobot.reproduce.settings import ROBUSTNESS_WORLDS

PROG = "servobot reproduce"
COLONY_OPTIONS = ("--blocking", "--colony-fitness", "--start-power-spread", "--robots-unseen",
                  "--contact-yaw")
"""Options of the colony stages only (with ``--robots R``, R ≥ 2)."""


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        prog="servobot reproduce",
        description="Calibrate, evolve navigation and coverage, validate the finalists in "
        "physics, run them through the physics test matrix (with --robots R: evolve coverage "
        "for a colony of R and validate it in physics), and write REPORT.md with figures "
        "and .rrd recordings. Resumable: rerun the same command after an interruption.",
    )
    p.add_argument(
        "--out", type=Path, default=Path("runs/reproduce"), help="run folder (runs/reproduce)"
    )
    p.add_argument(
        "--quick", action="store_true", help="small budgets for a first look (a few minutes)"
    )
    p.add_argument("--seed", type=int, default=None, help="seed of every random draw (default 0)")
    p.add_argument(
        "--workers", type=int, default=None, help="processes for physics (default: all cores)"
    )
    p.add_argument(
        "--validate-starts",
        type=int,
        default=None,
        help="validation starts per finalist (default 20; --quick 3)",
    )
    p.add_argument(
        "--robots",
        type=int,
        default=None,
        metavar="R",
        help="R ≥ 2: add the colony stages, coverage learned by a colony of R robots sharing "
        "the station and its physics validation with R robots (SPEC §7; default 1: none)",
    )
    p.add_argument(
        "--blocking",
        choices=BLOCKING_RULES,
        default=None,
        help="with --robots R: the table world's rule for a move another robot blocks, "
        "cancel (SPEC §7, default) or slide (docs/colony.md)",
    )
    p.add_argument(
        "--colony-fitness",
        choices=COLONY_FITNESSES,
        default=None,
        help="with --robots R: what a colony run scores, as servobot evolve colony's "
        "(squares, default; alive; per_step; docks; alive_docks)",
    )
    p.add_argument(
        "--start-power-spread",
        type=float,
        default=None,
        metavar="V",
        help="with --robots R: robot i starts with 4.0 + i × V volts, capped at 5.0 V "
        "(default 0), in the colony stage and both worlds of its validation",
    )
    p.add_argument(
        "--contact-yaw",
        type=float,
        default=None,
        metavar="DEG",
        help="with --robots R: a blocked move also turns the robot away from each robot that "
        "blocks it, DEG degrees for one abeam, in the table world (default 0; 9.3 measured in "
        "MuJoCo: python -m calibration.contact_yaw)",
    )
    p.add_argument(
        "--robots-unseen",
        action="store_true",
        default=None,
        help="with --robots R: the object sensors do not see the other robots (default: seen, "
        "SPEC §7), in the colony stage and both worlds of its validation",
    )
    add_executor_option(
        p, None, "process, serial with --workers 1 (validation and robustness runs)"
    )
    add_model_option(p, type=str)
    add_envelope_option(p)
    p.add_argument(
        "--force",
        action="store_true",
        help="--out holds a run made with other settings: delete its files (only those) and "
        "start afresh",
    )
    p.add_argument("--no-progress", action="store_true", help="no progress bars")
    return p


def _run(args: argparse.Namespace) -> int:
    check_workers(args.workers)
    if args.seed is not None:
        check_int(args.seed, "--seed", lo=0)
    if args.robots is not None:
        check_int(args.robots, "--robots", lo=1)
    for flag in COLONY_OPTIONS:
        if getattr(args, flag[2:].replace("-", "_")) is not None and (args.robots or 1) < 2:
            raise InputError(f"{flag} is an option of the colony stages (--robots R, R ≥ 2)")
    if args.start_power_spread is not None:
        check_nonnegative(args.start_power_spread, "--start-power-spread", "volts")
    if args.contact_yaw is not None:
        check_nonnegative(args.contact_yaw, "--contact-yaw", "degrees")
    colony = {
        "colony_blocking": args.blocking, "colony_fitness": args.colony_fitness,
        "colony_start_power_spread": args.start_power_spread,
        "colony_robots_seen": False if args.robots_unseen else None,
        "colony_contact_yaw_deg": args.contact_yaw,
    }  # fmt: skip
    settings = resolve_settings(
        quick=args.quick, seed=args.seed, validate_starts=args.validate_starts,
        model=args.model, envelope=args.envelope, robots=args.robots, **colony,
    )  # fmt: skip
    bars = GenerationBars(enabled=not args.no_progress)
    per_world = 0 if settings.model is not None else settings.robustness_starts
    matrix = len(ROBUSTNESS_WORLDS) * per_world
    runs = RunBar(  # shown at its first run, not before the checks
        "physics runs", not args.no_progress,
        total=settings.coverage_populations * settings.validate_starts
        + settings.matrix_finalists() * matrix + 2 * settings.validate_navigation_starts
        + (settings.coverage_populations * settings.colony_validate_starts
           if settings.colony() is not None else 0),
    )  # fmt: skip
    try:
        res = reproduce(
            args.out,
            settings=settings,
            workers=args.workers,
            executor=executor_from_args(args),
            on_generation=bars,
            on_run=runs,
            force=args.force,
        )
    finally:
        bars.close()
        runs.close()
    print(f"report: {res['report']} (this invocation {format_seconds(res['wall_s'])})")
    return 0


def main(argv: list[str] | None = None) -> int:
    """Run ``servobot reproduce``; returns the exit code (0 ok, 2 bad input, 130 interrupted)."""
    return run_main(
        PROG, build_parser(), argv, lambda args, _command: _run(args),
        lambda args: f"the finished stages and the evolution checkpoints in {args.out}",
        drop=["--force"],
    )  # fmt: skip
