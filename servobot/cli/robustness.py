"""``servobot robustness CHROMOSOME...``: controllers in named physics worlds (a test matrix).

Runs each chromosome (16 genes; an 8-gene navigation section in navigation mode) from the
same N seeded starts in the table world and in every physics world of ``--worlds`` (built-in
names, or ``servobot variant`` files), unchanged, through ``servobot validate``'s library
(``servobot.robustness.run_matrix``). Writes ``robustness.{json,md,png}``, the worlds' models
and one validation folder per cell into ``--out``; prints the Markdown grid. Exit status: 0
done, 1 some physics runs failed (recorded in their cells), 2 bad input (named; checked before
any run), 130 interrupted (finished runs are kept; ``--resume`` skips them).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from infra.bounds import check_workers
from infra.command import EXIT_FAILED, Interrupted, command_line, run_command
from servobot.cli.options import add_executor_option, comma_list, executor_from_args
from servobot.progress import RunBar
from servobot.robustness.matrix import RobustnessSettings, run_matrix
from servobot.robustness.report import markdown
from servobot.robustness.worlds import BUILT_IN

PROG = "servobot robustness"
DEFAULT_OUT = Path("runs/robustness")
"""Default output folder."""
_DEFAULTS = RobustnessSettings()


def build_parser() -> argparse.ArgumentParser:
    worlds = "\n".join(f"  {w.name:<13} {w.description}" for w in BUILT_IN.values())
    p = argparse.ArgumentParser(
        prog=PROG,
        formatter_class=argparse.RawDescriptionHelpFormatter,
        description="Run chromosomes from the same seeded starts in the table world and in "
        "each physics world of a test matrix, unchanged; report inner coverage (navigation "
        "sections: docking) per chromosome and world.",
        epilog=f"built-in worlds:\n{worlds}\nsee docs/robustness.md",
    )
    p.add_argument(
        "chromosome",
        type=Path,
        nargs="+",
        help="chromosome text files: 16 genes, or 8-gene navigation sections",
    )
    p.add_argument(
        "--worlds",
        type=comma_list,
        default=_DEFAULTS.worlds,
        metavar="LIST",
        help="comma-separated physics worlds: built-in names or servobot variant "
        "files (named by their stem) (default: every built-in)",
    )
    d = _DEFAULTS
    # fmt: off
    p.add_argument("--starts", type=int, default=d.starts, metavar="N",
                   help=f"seeded start poses per chromosome (default {d.starts})")
    p.add_argument("--steps", type=int, default=d.steps, metavar="N",
                   help=f"steps per coverage run (default {d.steps}; navigation runs at most 100)")
    p.add_argument("--seed", type=int, default=d.seed,
                   help="seed of the start poses and the servo noise (default 0)")
    p.add_argument("--noise-seed", type=int, default=None, metavar="N",
                   help="seed of the servo noise alone (default: --seed): the same starts "
                   "under another noise draw (python -m servobot.robustness.floor)")
    p.add_argument("--table", default=d.table, metavar="paper|PATH",
                   help="gait table of the table world (default: paper's Figure 4)")
    p.add_argument("--out", type=Path, default=DEFAULT_OUT, metavar="DIR",
                   help=f"output folder (default {DEFAULT_OUT})")
    p.add_argument("--rrd", action="store_true", help="write run{k}.rrd recordings per cell")
    p.add_argument("--workers", type=int, default=None, metavar="K",
                   help="processes or Ray CPUs (default: one per core)")
    # fmt: on
    add_executor_option(p, None, "process, serial with --workers 1")
    p.add_argument(
        "--resume",
        action="store_true",
        help="continue the run in --out: finished cells are read back",
    )
    p.add_argument(
        "--force",
        action="store_true",
        help="--out holds another run: delete its files (only those) first",
    )
    p.add_argument(
        "--reuse",
        type=Path,
        action="append",
        default=[],
        metavar="DIR",
        help="an earlier matrix folder: take its runs this matrix would repeat (same "
        "chromosome, table, settings and start at the same index, e.g. the first N when "
        "--starts grows, or matrices run controller by controller) instead of running them "
        "again; repeat it to take runs from several (the first that has a run gives it)",
    )
    p.add_argument(
        "--share",
        action="store_true",
        help="the runs from one start in one world go to one worker and simulate the gait "
        "cycles they share once (same results; pays off for many similar chromosomes)",
    )
    p.add_argument("--no-progress", action="store_true", help="no progress bar")
    return p  # fmt: skip


def _run(args: argparse.Namespace) -> int:
    check_workers(args.workers)
    settings = RobustnessSettings(worlds=args.worlds, starts=args.starts, steps=args.steps,
                                  seed=args.seed, noise_seed=args.noise_seed, table=args.table,
                                  rrd=args.rrd)  # fmt: skip
    cells = len(args.chromosome) * len(args.worlds)
    bar = RunBar("robustness", enabled=not args.no_progress, total=cells * args.starts)
    try:
        doc = run_matrix(
            args.chromosome, args.out, settings, executor=executor_from_args(args),
            workers=args.workers, resume=args.resume, force=args.force, reuse=args.reuse,
            share=args.share, on_run=bar,
            on_skip=bar.advance, log=lambda m: print(m, file=sys.stderr),
        )  # fmt: skip
    finally:
        bar.close()
    print(markdown(doc))
    print(f"wrote {args.out / 'robustness.json'}, {args.out / 'robustness.md'}, "
          f"{args.out / 'robustness.png'}")  # fmt: skip
    errors = sum(w["physics_errors"] for w in doc["worlds"])
    if errors:
        print(f"{errors} physics runs failed; see the cells' report.md", file=sys.stderr)
    return EXIT_FAILED if errors else 0


def main(argv: list[str] | None = None) -> int:
    """Run ``servobot robustness``; returns the exit code (0 ok, 1 physics errors, 2 bad
    input, 130 interrupted)."""
    argv = list(sys.argv[1:] if argv is None else argv)
    args = build_parser().parse_args(argv)

    def interrupted() -> Interrupted:
        return Interrupted(
            f"the finished runs in {args.out} (cells in runs/, runs of unfinished cells in "
            "kept/)",
            command_line(PROG, argv, "--resume", drop=["--force"]),
        )

    return run_command(PROG, lambda: _run(args), interrupted)


if __name__ == "__main__":
    sys.exit(main())
