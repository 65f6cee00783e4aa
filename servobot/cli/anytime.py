"""``servobot anytime``: coverage learning with physics punctuations (anytime learning).

A thin layer over ``servobot.anytime.run.run_anytime``::

    servobot anytime --navigation FILE [--table paper|PATH] [--method none|bias|model|transfer]
                     [--every K] [--top T] [--physics-starts M] [--physics-steps N]
                     [--final-starts N] [--neighbours K] [--descriptor-starts D]
                     [--populations P] [--generations G]
                     [--population-size N] [--seed S] [--model FILE] [--baseline DIR]
                     [--executor process|ray|ray:ADDRESS|serial] [--workers W]
                     [--out DIR] [--resume] [--force]

Defaults are the paper's scale for the GA (5 × 256 × 512, SPEC §5) and ``AnytimeSettings``
for the punctuations. ``--navigation`` takes an 8-gene section or a 16-gene chromosome (its
genes 8–15). Bad input prints one message and exits with code 2 before any work
(``servobot.cli.runner``); Ctrl-C keeps the checkpoints and punctuation records and says how
to resume (exit 130). See docs/anytime.md.
"""

from __future__ import annotations

import argparse
import dataclasses
import sys
from pathlib import Path
from typing import Any

from evolve.anytime import METHODS, AnytimeSettings
from evolve.settings import WorldSettings
from infra.bounds import check_int, check_workers
from infra.io import check_output_dir
from servobot.cli.evolve import ga_settings, load_navigation, run_evolution
from servobot.cli.options import (
    add_envelope_option,
    add_executor_option,
    add_ga_options,
    add_model_option,
    envelope_from_args,
    executor_from_args,
)
from servobot.progress import GenerationBars, RunBar

PROG = "servobot anytime"
DEFAULT_OUT = Path("runs/anytime")
"""Default run folder of ``--out``."""
DEFAULTS = AnytimeSettings()


def build_parser() -> argparse.ArgumentParser:
    """The argument parser of ``servobot anytime``."""
    p = argparse.ArgumentParser(
        prog=PROG,
        description="Coverage learning on the table simulation with physics punctuations: "
        "every K generations the T best of each population walk in MuJoCo from M starts, and "
        "their results bias the fitness (bias) or correct the gait table (model); none "
        "measures without feeding back (the table-only control).",
    )
    p.add_argument("--navigation", type=Path, required=True, help="navigation section file")
    p.add_argument("--table", default="paper", help="gait table: 'paper' or a calibration JSON")
    p.add_argument("--method", choices=METHODS, default=DEFAULTS.method,
                   help=f"what physics corrects (default {DEFAULTS.method})")  # fmt: skip
    for flag, field, what in (
        ("--every", "every", "generations between punctuations, K"),
        ("--top", "top", "genomes tested per population, T"),
        ("--physics-starts", "physics_starts", "start poses per punctuation, M"),
        ("--physics-steps", "physics_steps", "steps of every physics run"),
        ("--final-starts", "final_starts", "fresh starts of the final test"),
        ("--neighbours", "neighbours", "transfer: tested behaviours an individual's disparity "
         "is predicted from, k"),
        ("--descriptor-starts", "descriptor_starts", "transfer: fixed starts a behaviour is "
         "described from"),
    ):  # fmt: skip
        default = getattr(DEFAULTS, field)
        p.add_argument(flag, type=int, default=default, help=f"{what} (default {default})")
    add_ga_options(p, "512")
    add_model_option(p, "robot model file in physics (default: the shipped ServoBot); a --table "
                     "PATH must have been calibrated on it")  # fmt: skip
    p.add_argument("--baseline", type=Path, default=None, metavar="DIR",
                   help="a --method none run of the same seed (its --out), drawn beside this "
                   "one in figure_anytime.png")  # fmt: skip
    add_envelope_option(p)
    add_executor_option(p, "process", "process (a pool of --workers)")
    p.add_argument("--workers", type=int, default=None, help="processes or Ray CPUs (one per core)")
    p.add_argument("--out", type=Path, default=DEFAULT_OUT, help=f"run folder ({DEFAULT_OUT})")
    p.add_argument("--resume", action="store_true", help="continue the run in --out")
    p.add_argument(
        "--force", action="store_true",
        help="--out holds another run: delete its anytime files (only those), start afresh",
    )  # fmt: skip
    p.add_argument("--no-progress", action="store_true", help="no progress bars")
    return p


def anytime_settings(args: argparse.Namespace) -> AnytimeSettings:
    """The punctuations of the command line (each option range-checked by name)."""
    over: dict[str, Any] = {"method": args.method}
    for flag in ("every", "top", "physics_starts", "physics_steps", "final_starts", "neighbours",
                 "descriptor_starts"):  # fmt: skip
        over[flag] = check_int(getattr(args, flag), "--" + flag.replace("_", "-"), lo=1)
    return dataclasses.replace(DEFAULTS, **over)


def _print(summary: dict[str, Any], out: Path) -> None:
    from servobot.anytime.report import percent as pct

    f = summary["final"]
    print(
        f"anytime ({summary['method']}): final bests on {f['starts']} fresh starts: table "
        f"{pct(f['table_inner_percent'])}, physics {pct(f['physics_inner_percent'])} of the 64 "
        f"inner squares"
    )
    for p in f["populations"]:
        print(f"  population {p['population']}: table {pct(p['table_inner_percent'])}, "
              f"physics {pct(p['physics_inner_percent'])}")  # fmt: skip
    print(
        f"{len(summary['punctuations'])} punctuations, {summary['physics_runs']} physics runs "
        f"({summary['physics_wall_s']:.1f} s); final test {summary['final_wall_s']:.1f} s; "
        f"wall {summary['wall_s']:.1f} s"
    )
    print(f"wrote {out / 'anytime'}")


def _run(args: argparse.Namespace, bars: GenerationBars) -> int:
    from servobot.anytime.run import run_anytime
    from servobot.validation.lone import load_checked_table

    args.stage = "coverage"  # ga_settings: coverage's defaults
    ga = ga_settings(args)
    settings = anytime_settings(args)
    check_workers(args.workers)
    navigation = load_navigation(args.navigation)
    table, warning = load_checked_table(args.table, args.model)
    if warning:
        print(warning, file=sys.stderr)
    check_output_dir(args.out, option="--out")
    physics_bar = RunBar("physics", enabled=not args.no_progress)
    try:
        summary = run_anytime(
            args.out, navigation=navigation, table=table, ga=ga, world=WorldSettings(),
            settings=settings, model=args.model, executor=executor_from_args(args),
            baseline=args.baseline, resume=args.resume, force=args.force, on_generation=bars,
            on_physics_run=physics_bar, envelope=envelope_from_args(args),
        )  # fmt: skip
    finally:
        physics_bar.close()
    _print(summary, args.out)
    return 0


def main(argv: list[str] | None = None) -> int:
    """Run ``servobot anytime``; returns the exit code (0 ok, 2 bad input, 130 interrupted)."""

    def kept(args: argparse.Namespace) -> str:
        folder = args.out / "anytime"
        if (folder / "checkpoints").is_dir():
            return f"the checkpoints and punctuation records in {folder}"
        return "nothing yet"

    return run_evolution(PROG, build_parser(), argv, _run, kept)


if __name__ == "__main__":
    sys.exit(main())
