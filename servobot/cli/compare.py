"""``servobot compare TABLE_A TABLE_B [...] --out DIR``: gait tables side by side.

Parses and prints; ``calibration.compare.compare_tables`` writes ``DIR/compare.png`` (Figure 4
of every table, with the voltage drop per gait where measured) and ``DIR/compare.csv`` (each
table's values and its differences from the first). A table is a calibration file or
``paper`` (Figure 4).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from calibration.compare import compare_tables
from infra.io import check_output_dir
from servobot.cli.runner import run_main

PROG = "servobot compare"


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        prog="servobot compare",
        description="Compare two or more gait tables (Figure 4 side by side, PNG + CSV of the "
        "differences from the first).",
    )
    p.add_argument("tables", nargs="+", metavar="TABLE", help="gait_table.json files or 'paper'")
    p.add_argument("--out", type=Path, default=Path("runs/compare"), help="output folder")
    p.add_argument("--labels", nargs="+", default=None, help="a name per table (default: folder)")
    p.add_argument(
        "--force",
        action="store_true",
        help="--out holds another comparison: delete its files (only those) first",
    )
    return p


def _run(args: argparse.Namespace) -> int:
    check_output_dir(args.out, option="--out")
    cmp = compare_tables(args.tables, args.out, args.labels, force=args.force)
    print(cmp.summary())
    print(f"wrote {cmp.figure_path} and {cmp.csv_path}")
    return 0


def main(argv: list[str] | None = None) -> int:
    """Run ``servobot compare``; 0 ok, 2 bad input, 130 interrupted."""
    return run_main(PROG, build_parser(), argv, lambda args, _command: _run(args),
                    lambda args: f"every earlier file in {args.out} as it was")  # fmt: skip


if __name__ == "__main__":
    sys.exit(main())
