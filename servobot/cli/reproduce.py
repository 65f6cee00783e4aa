"""``servobot reproduce``: the end-to-end reproduction into one run folder (resumable).

Parses the options, shows progress and prints where the report is;
``servobot.reproduce.reproduce`` does the work.
"""

from __future__ import annotations

import argparse
import sys

from tqdm import tqdm

from evolve.population import StageError
from evolve.table import GaitTableError
from servobot.cli.options import add_executor_option, executor_from_args
from servobot.progress import GenerationBars
from servobot.reproduce import ReproduceError, reproduce, resolve_settings
from servobot.reproduce_report import format_seconds


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        prog="servobot reproduce",
        description="Calibrate, evolve navigation and coverage, validate the finalists in "
        "physics, and write REPORT.md with figures and .rrd recordings. Resumable: rerun the "
        "same command after an interruption.",
    )
    p.add_argument("--out", default="runs/reproduce", help="run folder (default runs/reproduce)")
    p.add_argument(
        "--quick", action="store_true", help="small budgets for a first look (a few minutes)"
    )
    p.add_argument("--seed", type=int, default=None, help="seed of every random draw (default 0)")
    p.add_argument(
        "--workers", type=int, default=None, help="processes for physics (default: all cores)"
    )
    add_executor_option(p, None, "process, serial with --workers 1 (validation runs)")
    p.add_argument(
        "--validate-starts",
        type=int,
        default=None,
        help="validation starts per finalist (default 20; --quick 3)",
    )
    p.add_argument(
        "--model",
        default=None,
        metavar="FILE",
        help="robot model file, e.g. from 'servobot variant' (default: the shipped ServoBot)",
    )
    p.add_argument("--no-progress", action="store_true", help="no progress bars")
    return p


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    if args.workers is not None and args.workers < 1:
        print("servobot reproduce: --workers must be ≥ 1", file=sys.stderr)
        return 2
    try:
        settings = resolve_settings(
            quick=args.quick, seed=args.seed, validate_starts=args.validate_starts,
            model=args.model,
        )  # fmt: skip
    except ReproduceError as exc:
        print(f"servobot reproduce: {exc}", file=sys.stderr)
        return 2
    bars = GenerationBars(enabled=not args.no_progress)
    runs = tqdm(
        total=settings.coverage_populations * settings.validate_starts,
        desc="validation runs", unit="run", disable=args.no_progress, file=sys.stderr,
    )  # fmt: skip
    try:
        res = reproduce(
            args.out,
            settings=settings,
            executor=executor_from_args(args, "servobot reproduce"),
            on_generation=bars,
            on_run=lambda _rec: runs.update(1),
        )
    except (ReproduceError, StageError, GaitTableError) as exc:
        print(f"servobot reproduce: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print(
            "\nservobot reproduce: interrupted; run the same command again to resume",
            file=sys.stderr,
        )
        return 130
    finally:
        bars.close()
        runs.close()
    print(f"report: {res['report']} (this invocation {format_seconds(res['wall_s'])})")
    return 0
