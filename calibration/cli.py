"""``servobot calibrate``: re-measure Figure 4 in MuJoCo (and optionally fit the gaits first).

Writes ``DIR/gait_table.json`` (the layout of ``evolve.table.table_to_json`` plus provenance),
``DIR/figure4.png`` and, with ``--fit``, the fitted gait parameters both to
``servo_mj/data/gait_params.json`` (where the gait library loads them by default; override
with ``--params-out``) and to ``DIR/gait_params.json``. Every file is written atomically at the
end, so a failed run loses nothing already written.
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path

import mujoco

from calibration.fit import FitSettings, fit_library
from calibration.measure import DEFAULTS, CalibrationSettings, measure_all, summarise
from calibration.report import format_table, save_figure, within_tolerance
from evolve.io import atomic_write_json
from evolve.table import table_to_json
from servo_mj import constants as C
from servo_mj.executor import PhysicsError
from servo_mj.gaits import N_GAITS, PARAMS_JSON, GaitLibrary
from servo_mj.model import load_robot, model_sha256
from servo_mj.settings import PhysicsSettings


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


def _record(args, library, kwargs):
    """Measure sequentially while logging the walks to a rerun recording."""
    from servo_mj.recording import Recording  # lazy: rerun only when asked for

    model, _ = load_robot(scene=True)
    feet = [mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_SITE, n) for n in C.foot_sites()]
    cycle_s = len(library.frames(0)) * PhysicsSettings().frame_s
    per_gait_s = PhysicsSettings().settle_s + (args.settle_cycles + args.cycles) * cycle_s + 1.0
    with Recording(args.rrd, app_id="servobot-calibration") as rec:
        rec.log_robot_model(model, prefix="")

        def on_frame(g: int, d: mujoco.MjData) -> None:
            t = g * per_gait_s + d.time
            rec.log_robot_state(d, prefix="", t_s=t)
            rec.log_feet(t, d.site_xpos[feet])

        def on_cycle(g, res, bot) -> None:
            f, t, dh = res.ftdh
            k = res.cycle - args.settle_cycles
            rec.log_calibration_cycle(g, k, f, t, dh, g * per_gait_s + res.t_end_s)

        return measure_all(
            range(N_GAITS),
            workers=1,
            model=model,
            on_frame=on_frame,
            on_cycle=on_cycle,
            **kwargs,
        )


def main(argv: list[str] | None = None) -> int:
    args = _parser().parse_args(argv)
    problem = _check(args)
    if problem:
        print(f"servobot calibrate: {problem}", file=sys.stderr)
        return 2
    t0 = time.perf_counter()
    try:
        library = GaitLibrary.load(args.params)
    except ValueError as exc:
        print(f"servobot calibrate: {exc}", file=sys.stderr)
        return 2
    fit_report = None
    try:
        if args.fit:
            fs = FitSettings(
                cycles=args.cycles,
                settle_cycles=args.settle_cycles,
                seed=args.seed,
                noise_rad=args.noise,
                max_evals=args.fit_evals,
            )
            print(f"fitting 15 gaits ({args.workers} workers, <= {fs.max_evals} evaluations each)")
            library, fit_report = fit_library(
                library, fs, workers=args.workers, log=lambda s: print("  " + s, flush=True)
            )
            library = GaitLibrary(
                library.rows,
                library.stride_rad,
                library.lift_rad,
                {
                    "fitted": True,
                    "fit_settings": fs.__dict__ | {"step": list(fs.step)},
                    "fit_report": {str(g): r for g, r in fit_report.items()},
                    "model_sha256": model_sha256(),
                    "mujoco_version": mujoco.__version__,
                },
            )
        kwargs = dict(
            cycles=args.cycles,
            settle_cycles=args.settle_cycles,
            seed=args.seed,
            noise_rad=args.noise,
            library=library,
        )
        if args.rrd is not None:
            per_cycle = _record(args, library, kwargs)
        else:
            per_cycle = measure_all(range(N_GAITS), workers=args.workers, **kwargs)
    except PhysicsError as exc:
        print(f"servobot calibrate: physics failed: {exc}", file=sys.stderr)
        return 1
    values, std = summarise(per_cycle)
    wall_s = time.perf_counter() - t0
    doc = table_to_json(
        values,
        std,
        cycles=args.cycles,
        source="MuJoCo calibration (servobot calibrate)",
        model_sha256=model_sha256(),
        mujoco_version=mujoco.__version__,
        calibration=CalibrationSettings(
            cycles=args.cycles,
            settle_cycles=args.settle_cycles,
            seed=args.seed,
            noise_rad=args.noise,
        ).to_dict(),
        seed=args.seed,
        noise_rad=args.noise,
        settle_cycles=args.settle_cycles,
        physics=PhysicsSettings().to_dict(),
        gait_params=library.to_dict(),
        within_tolerance=int(within_tolerance(values).sum()),
        wall_time_s=round(wall_s, 3),
        command="servobot calibrate " + " ".join(sys.argv[1:] if argv is None else argv),
    )
    args.out.mkdir(parents=True, exist_ok=True)
    if fit_report is not None:
        atomic_write_json(args.params_out, library.to_dict())
        atomic_write_json(args.out / "gait_params.json", library.to_dict())
        print(f"fitted gait parameters written to {args.params_out}")
    atomic_write_json(args.out / "gait_table.json", doc)
    save_figure(args.out / "figure4.png", values, std)
    print(format_table(values, std))
    print(
        f"wrote {args.out / 'gait_table.json'} and {args.out / 'figure4.png'} ({wall_s:.1f} s wall)"
    )
    if args.rrd is not None:
        print(f"recording saved to {args.rrd}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
