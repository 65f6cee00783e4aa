"""``servobot calibrate``: re-measure Figure 4 in MuJoCo (and optionally fit the gaits first).

Parses the options and prints; ``calibration.calibrate.calibrate`` does the work and writes
``DIR/gait_table.json``, ``DIR/figure4.png`` and, with ``--fit``, the fitted gait parameters to
``DIR/gait_params.json`` and to ``--params-out`` (default: the shipped
``servo_mj/robot/data/gait_params.json``, where the gait library loads them from; with
``--model``, only ``DIR``: a variant's fit never replaces the shipped parameters unasked).
Bad input exits 2 before any physics; ``--force`` replaces a calibration made with other
settings in ``--out``; Ctrl-C exits 130 leaving earlier files untouched
(``servobot.cli.runner``).
"""

from __future__ import annotations

import argparse
import os
import sys
from pathlib import Path

from calibration.calibrate import calibrate
from calibration.fit import FitSettings
from calibration.measure import DEFAULTS, CalibrationSettings
from calibration.report import format_energy, format_table
from infra.bounds import check_int, check_number, check_workers
from infra.command import EXIT_FAILED
from infra.executors import BatchError
from infra.io import check_output_file
from servo_mj.robot.bot import PhysicsError
from servo_mj.robot.gaits import MAX_TARGET_RAD, PARAMS_JSON, GaitLibrary
from servobot.cli.options import add_executor_option, add_model_option, executor_from_args
from servobot.cli.runner import run_main

PROG = "servobot calibrate"
MEASURE_OPTIONS = (
    ("--cycles", "cycles", int, "measured cycles per gait"),
    ("--settle-cycles", "settle_cycles", int, "unmeasured cycles first"),
    ("--seed", "seed", int, "seed of the servo-target noise"),
    ("--noise", "noise_rad", float, "servo-target noise std, rad"),
)
"""(option, field of ``calibration.measure.WalkSettings``, type, help) of how the gaits
are walked."""


def _parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        prog="servobot calibrate",
        description="Measure F, T, dH of the 16 gaits in MuJoCo and compare with Figure 4.",
    )
    for flag, field, kind, what in MEASURE_OPTIONS:
        default = getattr(DEFAULTS, field)
        p.add_argument(flag, type=kind, default=default, help=f"{what} ({default})")
    p.add_argument("--out", type=Path, default=Path("runs/calibration"), help="output folder")
    p.add_argument("--fit", action="store_true", help="fit the gait parameters to Figure 4 first")
    p.add_argument(
        "--fit-evals",
        type=int,
        default=FitSettings.max_evals,
        help=f"max evaluations per gait in --fit ({FitSettings.max_evals})",
    )
    p.add_argument(
        "--params",
        type=Path,
        default=None,
        help="gait-parameter JSON to start from (default: the shipped one)",
    )
    p.add_argument(
        "--params-out",
        type=Path,
        default=None,
        help="where --fit also saves the fitted parameters (default: the shipped file; with "
        "--model: none, only DIR/gait_params.json)",
    )
    p.add_argument("--rrd", type=Path, default=None, help="record the walks for rerun (.rrd)")
    add_model_option(p)
    p.add_argument(
        "--force",
        action="store_true",
        help="--out holds a calibration made otherwise: delete its files (only those) and redo",
    )
    p.add_argument(
        "--workers",
        type=int,
        default=min(2, os.cpu_count() or 1),
        help="processes (or Ray CPUs) for measuring/fitting gaits in parallel",
    )
    add_executor_option(p, None, "process, serial with --workers 1")
    return p


def _check(args: argparse.Namespace) -> None:
    """Range checks of the options (``BoundsError`` naming the option)."""
    check_int(args.cycles, "--cycles", lo=1)
    check_int(args.settle_cycles, "--settle-cycles", lo=0)
    check_int(args.seed, "--seed", lo=0)
    check_number(args.noise, "--noise", lo=0.0, hi=MAX_TARGET_RAD, unit=" rad")
    check_workers(args.workers)
    check_int(args.fit_evals, "--fit-evals", lo=1)
    if args.rrd is not None:
        check_output_file(args.rrd, option="--rrd")


def _run(args: argparse.Namespace, command: str) -> int:
    _check(args)
    library = GaitLibrary.load(args.params)
    dest = {flag: flag[2:].replace("-", "_") for flag, *_ in MEASURE_OPTIONS}  # argparse's
    walk = {field: getattr(args, dest[flag]) for flag, field, _, _ in MEASURE_OPTIONS}
    settings = CalibrationSettings(**walk, model=None if args.model is None else str(args.model))
    fit = None
    if args.fit:
        fit = FitSettings(**walk, max_evals=args.fit_evals)
        print(f"fitting 15 gaits ({args.workers} workers, <= {fit.max_evals} evaluations each)")
    params_out = args.params_out or (PARAMS_JSON if args.model is None else None)
    kwargs = dict(
        library=library,
        fit=fit,
        params_out=params_out,
        workers=args.workers,
        executor=executor_from_args(args),
        log=lambda s: print("  " + s, flush=True),
        command=command,
        force=args.force,
    )
    try:
        if args.rrd is None:
            res = calibrate(args.out, settings, **kwargs)
        else:
            from servobot.recording import Recording, calibration_recorder, log_calibration_result

            with Recording.for_calibration(args.rrd) as rec:
                rec_kw = calibration_recorder(rec, settings, command)
                res = calibrate(args.out, settings, **rec_kw, **kwargs)
                log_calibration_result(rec, res)
    except (PhysicsError, BatchError) as exc:
        print(f"{PROG}: physics failed: {exc}", file=sys.stderr)
        return EXIT_FAILED
    if res.params_path is not None:
        also = f"{params_out} and " if params_out is not None else ""
        print(f"fitted gait parameters written to {also}{res.params_path}")
    print(format_table(res.values, res.std))
    print(format_energy(res.energy))
    print(f"wrote {res.table_path} and {res.figure_path} ({res.wall_s:.1f} s wall)")
    if args.rrd is not None:
        print(f"recording saved to {args.rrd}")
    return 0


def main(argv: list[str] | None = None) -> int:
    """Run ``servobot calibrate``; returns the exit code (0 ok, 1 physics failed, 2 bad
    input, 130 interrupted)."""

    def kept(args: argparse.Namespace) -> str:
        return (
            f"every earlier file in {args.out} as it was (a calibration writes its files only "
            "when all gaits are measured)"
        )

    return run_main(PROG, _parser(), argv, _run, kept, again="the calibration starts again")
