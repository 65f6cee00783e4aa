"""``servobot validate CHROMOSOME``: run a controller in the table simulation and in physics.

Runs the 16-gene chromosome from N start poses (SPEC §5 coverage region, seeded) or from the
given ``--start X Y H`` poses, in both worlds; an 8-gene navigation section runs in navigation
mode (SPEC §6) from N navigation starts clear of the station block, the ``--start`` poses, or
the ``--poses FILE`` poses and powers (e.g. a coverage stage's ``handoffs.csv``). It writes
``report.json``, ``report.md``,
``tracks.npz`` (and ``run{k}.rrd`` with ``--rrd``) into ``--out``. With ``--robots R`` each
start is a colony of R robots sharing the station (SPEC §7): N colony starts drawn by
``evolve.starts.colony_starts``, or the ``--start`` poses taken R at a time (``--blocking``:
the table world's blocking rule, ``ColonySettings.blocking``; ``--start-power-spread``: robot
i starts i × V volts above the start power, ``ColonySettings.start_power_spread``;
``--robots-unseen``: object sensors blind to the other robots, ``ColonySettings.robots_seen``;
``--contact-yaw``: the table world's turn away from a blocking robot,
``ColonySettings.contact_yaw_deg``);
it also writes ``tracks{k}.png`` (``servobot.validation.colony``). Prints the per-start table
and the summary. Exit status: 0 = all runs finished, 1 = some physics runs failed (their
errors are in the report), 2 = bad input (message names the problem; checked before any
run), 130 = interrupted (``servobot.cli.runner``). ``--force`` replaces a validation made
with other inputs in ``--out``.
"""

from __future__ import annotations

import argparse
import dataclasses
import sys
from pathlib import Path
from typing import Any

import numpy as np

from evolve.codec import SECTION_GENES, ChromosomeError, read_chromosome
from evolve.handoff import read_poses
from evolve.settings import BLOCKING_RULES, ColonySettings, WorldSettings
from evolve.starts import colony_starts, coverage_starts
from infra.bounds import check_int, check_need, check_nonnegative, check_number, check_workers
from infra.command import EXIT_FAILED
from infra.errors import InputError
from servo_mj.robot.gaits import MAX_TARGET_RAD
from servo_mj.robot.settings import PhysicsSettings
from servo_mj.world.arena import ArenaSettings
from servobot.cli.options import add_executor_option, add_model_option, executor_from_args
from servobot.cli.runner import run_main
from servobot.progress import RunBar
from servobot.validation.colony import check_colony_starts, validate_colony
from servobot.validation.colony_report import colony_run_rows, colony_summary_lines
from servobot.validation.lone import (
    ValidationError,
    check_chromosome,
    check_start,
    clear_navigation_starts,
    load_checked_table,
    sample_poses,
    validate,
    validation_need,
)
from servobot.validation.report import run_rows, summary_lines

PROG = "servobot validate"

DEFAULT_STARTS = 20
"""Start poses drawn when no ``--start`` is given."""
DEFAULT_OUT = Path("runs/validate")
"""Default output folder."""


def build_parser() -> argparse.ArgumentParser:
    """The argument parser of ``servobot validate``."""
    p = argparse.ArgumentParser(
        prog="servobot validate",
        description="Run a 16-gene chromosome (or an 8-gene navigation section, in navigation "
        "mode) from start poses in the table simulation and in MuJoCo physics; report squares, "
        "inner squares, docks, steps, end reasons and the table-vs-physics gap.",
    )
    p.add_argument(
        "chromosome",
        type=Path,
        nargs="+",
        help="chromosome text file: 16 genes, or an 8-gene navigation section (navigation "
        "mode); with --robots R, R files make a team, robot r carrying file r (e.g. "
        "colony/best_pop0_robot{0,1,2}.txt of 'servobot evolve colony --sections team')",
    )
    p.add_argument(
        "--starts",
        type=int,
        default=None,
        metavar="N",
        help=f"seeded start poses from the coverage region (a navigation section: from the "
        f"whole arena; with --poses: drawn from the file's) (default {DEFAULT_STARTS}; with "
        "--poses: all of the file's)",
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
        "--poses",
        type=Path,
        default=None,
        metavar="FILE",
        help="navigation section only: start poses (and powers) from a CSV with columns x, y, "
        "h [, power], e.g. coverage/handoffs.csv; --starts N then draws N of them (seeded)",
    )
    p.add_argument(
        "--robots",
        type=int,
        default=None,
        metavar="R",
        help="a colony of R robots sharing the station at each start (SPEC §7); --start poses "
        "are then taken R at a time (default: one robot, no colony)",
    )
    p.add_argument(
        "--blocking",
        choices=BLOCKING_RULES,
        default=None,
        help="with --robots: the table world's rule for a move another robot blocks, cancel "
        "(SPEC §7, default) or slide along the contact tangent (docs/colony.md); physics "
        "blocks by contacts either way",
    )
    p.add_argument(
        "--start-power-spread",
        type=float,
        default=None,
        metavar="V",
        help="with --robots: robot i starts with the start power + i × V volts, capped at the "
        "charged 5.0 V (ColonySettings.start_power_spread; 0, default: all on 4.0 V), in both "
        "worlds",
    )
    p.add_argument(
        "--contact-yaw",
        type=float,
        default=None,
        metavar="DEG",
        help="with --robots, table world: a blocked move also turns the robot away from each "
        "robot that blocks it, DEG degrees for one abeam (ColonySettings.contact_yaw_deg; 0, "
        "default; 9.3 measured in MuJoCo: python -m calibration.contact_yaw)",
    )
    p.add_argument(
        "--robots-unseen",
        action="store_true",
        help="with --robots: the object sensors do not see the other robots, in both worlds "
        "(ColonySettings.robots_seen False: no shell in MuJoCo, the rays pass above the "
        "robots); they still block",
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
    add_model_option(
        p,
        "robot model file in physics, e.g. from 'servobot variant' (default: shipped); "
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
    p.add_argument(
        "--force",
        action="store_true",
        help="--out holds a validation with other inputs: delete its files (only those) first",
    )
    p.add_argument("--no-progress", action="store_true", help="no progress bar")
    return p


def _check_options(args: argparse.Namespace, n_starts: int) -> None:
    """Range checks of the numeric options and the run's size, before anything is built."""
    check_int(args.seed, "--seed", lo=0)
    check_workers(args.workers)
    if args.noise is not None:
        check_number(args.noise, "--noise", lo=0.0, hi=MAX_TARGET_RAD, unit=" rad")
    if args.steps is not None:
        check_int(args.steps, "--steps", lo=1)
    if args.station_height is not None:
        check_number(args.station_height, "--station-height", lo=0.01, hi=10.0, unit=" m")
    robots = args.robots or 1
    steps = WorldSettings().coverage_steps if args.steps is None else args.steps
    check_need(validation_need(n_starts, steps * robots, args.workers, args.rrd)[0],
               f"--starts {n_starts} × --steps {steps} × --robots {robots}")  # fmt: skip


def _colony(args: argparse.Namespace) -> ColonySettings | None:
    """The colony of ``--robots``, ``--blocking``, ``--start-power-spread``,
    ``--robots-unseen`` and ``--contact-yaw`` (None without ``--robots``)."""
    if args.robots is None:
        given = {"--blocking": args.blocking is not None, "--robots-unseen": args.robots_unseen,
                 "--start-power-spread": args.start_power_spread is not None,
                 "--contact-yaw": args.contact_yaw is not None}  # fmt: skip
        flag = next((f for f, on in given.items() if on), None)
        if flag is not None:
            raise InputError(f"{flag} is an option of a colony (--robots R)")
        return None
    check_int(args.robots, "--robots", lo=1)
    kw: dict[str, Any] = {} if args.blocking is None else {"blocking": args.blocking}
    if args.start_power_spread is not None:
        kw["start_power_spread"] = check_nonnegative(args.start_power_spread,
                                                     "--start-power-spread", "volts")  # fmt: skip
    if args.robots_unseen:
        kw["robots_seen"] = False
    if args.contact_yaw is not None:
        kw["contact_yaw_deg"] = check_nonnegative(args.contact_yaw, "--contact-yaw", "degrees")
    return ColonySettings(robots=args.robots, **kw)


def _given_starts(args: argparse.Namespace, colony: ColonySettings | None) -> np.ndarray:
    """The ``--start`` poses: (N, 3), or (N, R, 3) taken R at a time for a colony."""
    starts = np.array(args.start, dtype=float)
    if colony is None:
        return starts
    if len(starts) % colony.robots:
        raise InputError(
            f"--robots {colony.robots}: give the --start poses {colony.robots} at a time (one "
            f"pose per robot of each colony start), got {len(starts)}"
        )
    return starts.reshape(-1, colony.robots, 3)


def prepare(
    args: argparse.Namespace, world: WorldSettings
) -> tuple[np.ndarray, np.ndarray, ColonySettings | None, np.ndarray | None]:
    """Read the controller and build the start poses ((N, 3), or (N, R, 3) with ``--robots``),
    the colony and the start powers (``--poses`` only, else None); ``InputError`` on bad
    input."""
    colony = _colony(args)
    if not args.start and args.starts is not None:
        check_int(args.starts, "--starts", lo=1)
    count = DEFAULT_STARTS if args.starts is None else args.starts
    n = len(args.start) // (colony.robots if colony else 1) if args.start else count
    _check_options(args, max(n, 1))
    files = args.chromosome
    robots = colony.robots if colony else 1
    if len(files) not in (1, robots):
        also = f" or {robots}, one per robot (a team)" if colony else " (a team needs --robots)"
        raise InputError(f"chromosome: give 1 file{also}, got {len(files)}")
    try:
        read = [read_chromosome(f) for f in files]
        bits = check_chromosome(read[0] if len(read) == 1 else np.stack(read),
                                sections=colony is None, robots=robots)  # fmt: skip
    except (ChromosomeError, ValidationError) as exc:
        raise InputError(f"chromosome: {exc}") from exc
    except ValueError as exc:  # np.stack: files of different lengths
        raise InputError(f"chromosome: a team needs 16-gene files ({exc})") from exc
    section = bits.ndim == 2 and len(bits) == SECTION_GENES
    if args.poses is not None and (not section or args.start):
        raise InputError("--poses: only for an 8-gene navigation section, and not with --start")
    rng = np.random.default_rng(args.seed)
    powers = None
    if args.start:
        starts = _given_starts(args, colony)
    elif args.poses is not None:
        starts, powers = _drawn_poses(args, world, rng)
    elif section:
        starts = clear_navigation_starts(rng, count, world)
    elif colony is None:
        starts = coverage_starts(rng, count, world)
    else:
        try:
            starts = colony_starts(rng, count, world, colony)
        except ValueError as exc:
            raise InputError(f"--robots {colony.robots}: {exc}") from exc
    try:
        if colony is None:
            for k, s in enumerate(starts):
                check_start(s, world, name=f"start {k} ({s[0]:g} {s[1]:g} {s[2]:g})")
        else:
            check_colony_starts(starts, world, ArenaSettings(), colony)
    except ValidationError as exc:  # name where the poses came from
        if args.poses is None and not args.start:
            raise
        source = f"--poses {args.poses}" if args.poses is not None else "--start"
        raise ValidationError(f"{source}: {exc}") from None
    return bits, starts, colony, powers


def _drawn_poses(
    args: argparse.Namespace, world: WorldSettings, rng: np.random.Generator
) -> tuple[np.ndarray, np.ndarray | None]:
    """The ``--poses`` file's poses the physics arena can hold, all of them or ``--starts N``
    drawn without replacement (``servobot.validation.lone.sample_poses``)."""
    poses, powers = read_poses(args.poses)
    try:
        return sample_poses(poses, powers, args.starts, rng, world)
    except ValidationError as exc:
        raise InputError(f"--poses {args.poses}: {exc}") from exc


def _run(args: argparse.Namespace, command: str) -> int:
    world = WorldSettings()
    bits, starts, colony, powers = prepare(args, world)
    table, warning = load_checked_table(args.table, args.model)
    if warning:
        print(warning, file=sys.stderr)

    physics = None if args.noise is None else PhysicsSettings(servo_noise_rad=args.noise)
    arena = ArenaSettings()
    if args.station_height is not None:
        arena = dataclasses.replace(arena, station_height_m=args.station_height)
    bar = RunBar("validate", not args.no_progress, total=len(starts), unit="start")

    def on_run(rec: dict[str, Any]) -> None:
        bar()
        if rec.get("error"):
            bar.write(f"run {rec['index']}: {rec['error']}")

    kwargs: dict[str, Any] = {"powers": powers} if colony is None else {"colony": colony}
    try:
        report = (validate if colony is None else validate_colony)(
            bits,
            starts,
            table=table,
            world=world,
            physics=physics,
            arena=arena,
            out_dir=args.out,
            rrd=args.rrd,
            workers=args.workers,
            executor=executor_from_args(args),
            model=args.model,
            max_steps=args.steps,
            seed=args.seed,
            on_run=on_run,
            meta={"chromosome_file": ", ".join(map(str, args.chromosome)), "seed": args.seed,
                  "command": command},
            force=args.force,
            **kwargs,
        )
    finally:
        bar.close()
    rows, lines = (run_rows, summary_lines)
    if colony is not None:
        rows, lines = colony_run_rows, colony_summary_lines
    print("\n".join(rows(report)))
    print()
    print("\n".join(lines(report)))
    print(f"\nwrote {args.out / 'report.json'}, {args.out / 'report.md'}")
    return EXIT_FAILED if report["summary"]["physics_errors"] else 0


def main(argv: list[str] | None = None) -> int:
    """Run ``servobot validate``; returns the exit code (0 ok, 1 physics errors, 2 bad input,
    130 interrupted)."""

    def kept(args: argparse.Namespace) -> str:
        done = sorted(p.name for p in args.out.glob("run*.rrd")) if args.rrd else []
        kept = (
            f"the recordings of finished runs in {args.out} ({', '.join(done) or 'none'})"
            if args.rrd
            else f"every earlier file in {args.out} as it was"
        )
        return kept + "; the report is written only when every run has finished"

    return run_main(PROG, build_parser(), argv, _run, kept, again="validation starts again")


if __name__ == "__main__":
    sys.exit(main())
