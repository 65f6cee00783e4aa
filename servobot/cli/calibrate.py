"""``servobot calibrate``: re-measure Figure 4 in MuJoCo (and optionally fit the gaits first).

Parses the options and prints; ``calibration.calibrate.calibrate`` does the work and writes
``DIR/gait_table.json``, ``DIR/figure4.png`` and, with ``--fit``, the fitted gait parameters to
``DIR/gait_params.json`` and to ``--params-out`` (default: the shipped
``servo_mj/robot/data/gait_params.json``, where the gait library loads them from).
"""

from __future__ import annotations

import argparse
import os
import sys
from pathlib import Path

from calibration.calibrate import calibrate
from calibration.fit import FitSettings
from calibration.measure import DEFAULTS, CalibrationSettings
from calibration.report import format_table
from servo_mj.robot.bot import PhysicsError
from servo_mj.robot.gaits import PARAMS_JSON, GaitLibrary


def _parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        prog="servobot calibrate",
        description="Measure F, T, dH of the 16 gaits in MuJoCo and compare with Figure 4.",
    )
    p.add_argument(
        "--cycles",
        type=int,
        default=DEFAULTS.cycles,
        help=f"measured cycles per gait ({DEFAULTS.cycles})",
    )
    p.add_argument(
        "--settle-cycles",
        type=int,
        default=DEFAULTS.settle_cycles,
        help=f"unmeasured cycles first ({DEFAULTS.settle_cycles})",
    )
    p.add_argument(
        "--seed",
        type=int,
        default=DEFAULTS.seed,
        help=f"seed of the servo-target noise ({DEFAULTS.seed})",
    )
    p.add_argument(
        "--noise",
        type=float,
        default=DEFAULTS.noise_rad,
        help=f"servo-target noise std, rad ({DEFAULTS.noise_rad})",
    )
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
        default=PARAMS_JSON,
        help="where --fit saves the fitted parameters (default: the shipped file)",
    )
    p.add_argument("--rrd", type=Path, default=None, help="record the walks for rerun (.rrd)")
    p.add_argument(
        "--workers",
        type=int,
        default=min(2, os.cpu_count() or 1),
        help="processes for measuring/fitting gaits in parallel",
    )
    return p


def _check(args: argparse.Namespace) -> str | None:
    if args.cycles < 1:
        return f"--cycles must be >= 1, got {args.cycles}"
    if args.settle_cycles < 0:
        return f"--settle-cycles must be >= 0, got {args.settle_cycles}"
    if not (args.noise >= 0.0) or args.noise == float("inf"):
        return f"--noise must be a finite angle >= 0 rad, got {args.noise}"
    if args.workers < 1:
        return f"--workers must be >= 1, got {args.workers}"
    if args.fit_evals < 1:
        return f"--fit-evals must be >= 1, got {args.fit_evals}"
    return None


def main(argv: list[str] | None = None) -> int:
    args = _parser().parse_args(argv)
    problem = _check(args)
    if problem:
        print(f"servobot calibrate: {problem}", file=sys.stderr)
        return 2
    try:
        library = GaitLibrary.load(args.params)
    except ValueError as exc:
        print(f"servobot calibrate: {exc}", file=sys.stderr)
        return 2
    settings = CalibrationSettings(
        cycles=args.cycles, settle_cycles=args.settle_cycles, seed=args.seed, noise_rad=args.noise
    )
    fit = None
    if args.fit:
        fit = FitSettings(
            cycles=args.cycles,
            settle_cycles=args.settle_cycles,
            seed=args.seed,
            noise_rad=args.noise,
            max_evals=args.fit_evals,
        )
        print(f"fitting 15 gaits ({args.workers} workers, <= {fit.max_evals} evaluations each)")
    command = "servobot calibrate " + " ".join(sys.argv[1:] if argv is None else argv)
    kwargs = dict(
        library=library,
        fit=fit,
        params_out=args.params_out,
        workers=args.workers,
        log=lambda s: print("  " + s, flush=True),
        command=command,
    )
    try:
        if args.rrd is None:
            res = calibrate(args.out, settings, **kwargs)
        else:
            from servobot.recording import Recording, calibration_recorder, log_calibration_result

            with Recording.for_calibration(args.rrd) as rec:
                res = calibrate(args.out, settings, **calibration_recorder(rec, settings), **kwargs)
                log_calibration_result(rec, res)
    except PhysicsError as exc:
        print(f"servobot calibrate: physics failed: {exc}", file=sys.stderr)
        return 1
    if res.params_path is not None:
        print(f"fitted gait parameters written to {args.params_out} and {res.params_path}")
    print(format_table(res.values, res.std))
    print(f"wrote {res.table_path} and {res.figure_path} ({res.wall_s:.1f} s wall)")
    if args.rrd is not None:
        print(f"recording saved to {args.rrd}")
    return 0
