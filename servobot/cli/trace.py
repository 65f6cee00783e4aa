"""``servobot trace``: run one chromosome on the table world and print every step.

::

    servobot trace FILE --start X Y H [--mode coverage|navigation] [--power V]
                   [--table paper|PATH] [--steps N] [--json] [--rrd FILE]

One line per interpreter event (``evolve.trace.event_line``); text mode ends with a ``#``
summary line. ``--json`` prints one JSON object per event and nothing else. ``--rrd FILE``
also records the run with ``servobot.recording``; open it with ``rerun FILE``.
``--mode`` defaults to the chromosome's length: 16 genes → coverage, 8 genes → navigation.
Bad input exits 2 with a message; ``--rrd`` is checked writable before the run; Ctrl-C
exits 130 and discards the unfinished recording (``servobot.cli.runner``).
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from pathlib import Path
from typing import TextIO

from evolve.codec import read_chromosome
from evolve.interpreter import MODES, StepEvent
from evolve.settings import WorldSettings
from evolve.starts import MAX_HEADING_DEG
from evolve.table import load_table
from evolve.trace import TEXT_HEADER, event_dict, event_line, summary_line, trace
from infra.bounds import LIMITS, Need, check_need
from infra.errors import InputError
from infra.io import check_output_file
from servobot.cli.runner import run_main

PROG = "servobot trace"
DEFAULT_WORLD = WorldSettings()
STEP_BYTES = 400
"""Memory one traced step keeps (track entry, event, recording buffers), bytes [estimate]."""


class TraceError(InputError, ValueError):
    """Bad input to ``servobot trace``; the message is printed as is."""


def build_parser() -> argparse.ArgumentParser:
    """The argument parser of ``servobot trace``."""
    p = argparse.ArgumentParser(
        prog="servobot trace",
        description="Run a chromosome on the table world and print one line per step.",
    )
    p.add_argument("chromosome", type=Path, help="chromosome text file (8 or 16 genes)")
    p.add_argument(
        "--start",
        nargs=3,
        type=float,
        required=True,
        metavar=("X", "Y", "H"),
        help="start pose: x, y (cm, east/north), heading (deg, 0 = north, clockwise)",
    )
    p.add_argument(
        "--mode", choices=MODES, default=None, help="default: 16 genes coverage, 8 navigation"
    )
    p.add_argument("--power", type=float, default=None, help="start power in volts (4.0)")
    p.add_argument("--table", default="paper", help="'paper' (Figure 4) or a calibration JSON")
    p.add_argument(
        "--steps", type=int, default=None, help="step limit (default 600 coverage, 100 nav)"
    )
    p.add_argument("--json", action="store_true", help="one JSON object per event")
    p.add_argument("--rrd", type=Path, default=None, help="also write a rerun recording")
    return p


def _check(args: argparse.Namespace, world: WorldSettings, genes: int) -> str:
    x, y, h = args.start
    if not all(math.isfinite(v) for v in args.start):
        raise TraceError(f"--start must be finite numbers, got {args.start}")
    if not (0.0 <= x <= world.arena_size and 0.0 <= y <= world.arena_size):
        raise TraceError(f"--start ({x:g}, {y:g}) lies outside the arena [0, {world.arena_size:g}]")
    if abs(h) > MAX_HEADING_DEG:
        raise TraceError(
            f"--start heading {h:g} is beyond ±{MAX_HEADING_DEG:g}° (a heading is in degrees, 0 "
            "= north, clockwise)"
        )
    if args.steps is not None and args.steps < 1:
        raise TraceError(f"--steps must be ≥ 1 (a trace of no step shows nothing), got "
                         f"{args.steps}")  # fmt: skip
    if args.steps is not None:
        need = Need(args.steps * STEP_BYTES, args.steps / LIMITS.interpreter_steps_per_s)
        check_need(need, f"--steps {args.steps}")
    if args.power is not None and not math.isfinite(args.power):
        raise TraceError(f"--power must be a finite number, got {args.power}")
    mode = args.mode or ("coverage" if genes == 16 else "navigation")
    want = 16 if mode == "coverage" else 8
    if genes != want:
        raise TraceError(
            f"{args.chromosome}: mode {mode} needs a {want}-gene chromosome, it has {genes}"
        )
    return mode


def _run(args: argparse.Namespace, out: TextIO, command: str) -> int:
    world = DEFAULT_WORLD
    bits = read_chromosome(args.chromosome)
    mode = _check(args, world, bits.shape[0])
    table = load_table(args.table)
    if args.rrd is not None:
        check_output_file(args.rrd, option="--rrd")

    def emit(e: StepEvent) -> None:
        if args.json:
            out.write(json.dumps(event_dict(e)) + "\n")
        else:
            out.write(event_line(e) + "\n")

    start = tuple(args.start)
    if not args.json:
        out.write(
            f"# {args.chromosome} ({bits.shape[0]} genes), mode {mode}, table {table.source}, "
            f"start ({start[0]:g}, {start[1]:g}, {start[2]:g})\n{TEXT_HEADER}\n"
        )
    kw = dict(mode=mode, table=table, world=world, power=args.power, max_steps=args.steps)
    if args.rrd is None:
        res = trace(bits, start, on_event=emit, **kw)
    else:
        from servobot.recording import RunRecorder  # lazy: rerun only when asked for

        with RunRecorder.for_trace(args.rrd, bits, start, mode=mode, table=table, world=world,
                                   source=args.chromosome, command=command) as rec:  # fmt: skip

            def emit_and_record(e: StepEvent) -> None:
                emit(e)
                rec.table_event(e)

            res = trace(bits, start, on_event=emit_and_record, **kw)
            rec.close({"table": res})
    if not args.json:
        out.write(summary_line(res) + "\n")
        if args.rrd is not None:
            out.write(f"# recording: {args.rrd}\n")
    out.flush()
    return 0


def main(argv: list[str] | None = None, *, stdout: TextIO | None = None) -> int:
    """Run ``servobot trace``; returns the exit code (0 ok, 2 bad input, 130 interrupted)."""

    def kept(args: argparse.Namespace) -> str:
        rrd = "" if args.rrd is None else "; the unfinished recording was not written"
        return f"the lines printed above{rrd}"

    return run_main(PROG, build_parser(), argv,
                    lambda args, command: _run(args, stdout or sys.stdout, command),
                    kept)  # fmt: skip


if __name__ == "__main__":
    sys.exit(main())
