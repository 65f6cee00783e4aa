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
from evolve.table import GaitTableError


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        prog="servobot compare",
        description="Compare two or more gait tables (Figure 4 side by side, PNG + CSV of the "
        "differences from the first).",
    )
    p.add_argument("tables", nargs="+", metavar="TABLE", help="gait_table.json files or 'paper'")
    p.add_argument("--out", type=Path, default=Path("runs/compare"), help="output folder")
    p.add_argument("--labels", nargs="+", default=None, help="a name per table (default: folder)")
    return p


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    try:
        cmp = compare_tables(args.tables, args.out, args.labels)
    except (GaitTableError, ValueError) as exc:
        print(f"servobot compare: {exc}", file=sys.stderr)
        return 2
    print(cmp.summary())
    print(f"wrote {cmp.figure_path} and {cmp.csv_path}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
