"""Cost of recording a validation run: the same run with and without its ``.rrd``, interleaved.

::

    python -m servobot.recording.bench CHROMOSOME [--start X Y H] [--steps N] [--repeats K]
                                       [--out DIR]

Runs ``servobot.validation.lone.run_start`` (table world + physics world, the default settings and
servo noise) ``K`` times without and ``K`` times with a recording, alternating, and prints the
CPU time of each, the CPU spent inside the recording hooks (``RunRecorder``'s methods,
``close`` included), the ratio with/without, and the file's size; then the same for a
recording without servo detail (``RecordingSettings(servo_detail=False)``). Same seed, so
every repeat runs the same physics.
"""

from __future__ import annotations

import argparse
import dataclasses
import os
import statistics
import sys
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import numpy as np

from evolve.codec import read_chromosome
from evolve.settings import WorldSettings
from evolve.table import PAPER_TABLE
from servo_mj.world.arena import ArenaSettings
from servobot.recording import runs
from servobot.recording.style import RecordingSettings
from servobot.validation.lone import StartJob, run_start

HOOKS = ("table_event", "attach_physics", "on_frame", "physics_event", "error", "close")
"""The ``RunRecorder`` methods a run calls; their CPU time is the cost of recording."""


@contextmanager
def timed_hooks(spent: dict[str, float]) -> Iterator[None]:
    """Add the CPU seconds spent inside ``RunRecorder``'s hooks to ``spent["s"]``."""
    originals = {n: getattr(runs.RunRecorder, n) for n in HOOKS}

    def wrap(f: Callable[..., Any]) -> Callable[..., Any]:
        def timed(*a: Any, **k: Any) -> Any:
            t0 = time.process_time()
            try:
                return f(*a, **k)
            finally:
                spent["s"] += time.process_time() - t0

        return timed

    for n, f in originals.items():
        setattr(runs.RunRecorder, n, wrap(f))
    try:
        yield
    finally:
        for n, f in originals.items():
            setattr(runs.RunRecorder, n, f)


def one_run(job: StartJob) -> tuple[float, float, int]:
    """(CPU s, CPU s in the recording hooks, file bytes) of one run."""
    spent = {"s": 0.0}
    with timed_hooks(spent):
        c0 = time.process_time()
        rec = run_start(job)
        cpu = time.process_time() - c0
    if rec["error"]:
        raise RuntimeError(f"the run failed: {rec['error']}")
    size = os.path.getsize(job.rrd_path) if job.rrd_path else 0
    return cpu, spent["s"], size


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="python -m servobot.recording.bench", description=__doc__)
    p.add_argument("chromosome", type=Path, help="a 16-gene chromosome text file")
    p.add_argument("--start", nargs=3, type=float, default=(415.0, 252.0, 98.0))
    p.add_argument("--steps", type=int, default=600)
    p.add_argument("--repeats", type=int, default=2)
    p.add_argument("--out", type=Path, default=Path("runs/bench_recording"))
    args = p.parse_args(argv)
    job = StartJob(
        index=0, bits=read_chromosome(args.chromosome), start=tuple(args.start),
        table=np.asarray(PAPER_TABLE), world=WorldSettings(), arena=ArenaSettings(),
        physics=None, max_steps=args.steps, rrd_path=None,
    )  # fmt: skip
    variants = {"without .rrd": (None, None), "with .rrd": (args.out / "run.rrd", None)}
    lean = RecordingSettings(servo_detail=False)
    variants["with .rrd, no servo detail"] = (args.out / "lean.rrd", lean)
    results: dict[str, list[tuple[float, float, int]]] = {k: [] for k in variants}
    for _ in range(args.repeats):
        for name, (path, settings) in variants.items():
            j = dataclasses.replace(job, rrd_path=None if path is None else str(path))
            with _settings(settings):
                results[name].append(one_run(j))
    base = statistics.median(r[0] for r in results["without .rrd"])
    for name, rows in results.items():
        cpu = statistics.median(r[0] for r in rows)
        hooks = statistics.median(r[1] for r in rows)
        size = f"  file {rows[-1][2] / 1e6:.1f} MB" if rows[-1][2] else ""
        print(f"{name:28s} CPU {cpu:6.2f} s (× {cpu / base:.3f})  in recording {hooks:5.2f} s "
              f"({100 * hooks / cpu:4.1f} %){size}")  # fmt: skip
    return 0


@contextmanager
def _settings(settings: RecordingSettings | None) -> Iterator[None]:
    """Make ``RunRecorder`` use ``settings`` (None: its default)."""
    if settings is None:
        yield
        return
    init = runs.RunRecorder.__init__

    def patched(self: Any, *a: Any, **k: Any) -> None:
        init(self, *a, **dict(k, settings=settings))

    runs.RunRecorder.__init__ = patched  # type: ignore[method-assign]
    try:
        yield
    finally:
        runs.RunRecorder.__init__ = init  # type: ignore[method-assign]


if __name__ == "__main__":
    sys.exit(main())
