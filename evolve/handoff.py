"""Where coverage hands control to navigation, and whether navigation then docks.

In a coverage run (SPEC §4–5) a positive low-power test switches control to gene 8, the
navigation section; docking switches it back. A *hand-off* is one such switch: the pose and
power at that moment and what followed — the robot docked (the charging routine began), the
run ended first (kill zone, power empty, branch limit), or the coverage run's step limit cut
the approach short. Hand-offs come from the reference interpreter's events
(``evolve.interpreter.run``), so they are exactly what the table world does.

The docking rate from hand-offs counts docked / (docked + ended); a cut approach says
nothing either way (a dock on the run's very last step, which ends the run before the
charge, counts as cut). Run in navigation mode from the hand-off's pose and power (SPEC §6,
gene 8 = the section's gene 0, a fresh loop count), the section does the same steps, so
these poses also serve to test the section alone, in physics
(``servobot validate SECTION --poses handoffs.csv``).
"""

from __future__ import annotations

import csv
import io
from collections.abc import Iterable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from evolve.interpreter import END_NAMES, END_STEP_LIMIT, StepEvent, run
from evolve.settings import WorldSettings
from evolve.table import GaitTable
from evolve.world import TableWorld
from infra.errors import InputError
from infra.io import atomic_write_text, read_text

DOCKED = "docked"
"""Outcome of a hand-off after which the robot docked."""
CUT = "cut"
"""Outcome of a hand-off whose approach the run's step limit cut short."""
COLUMNS = ("x", "y", "h", "power", "outcome", "population", "start", "step")
"""Columns of ``handoffs.csv``: pose (cm, cm, deg) and power (V) at the switch, what
followed, which finalist and start, and the gait steps taken before it."""


@dataclass(frozen=True)
class Handoff:
    """One switch from coverage to navigation."""

    pose: tuple[float, float, float]
    """(x, y, heading) at the switch: arena units (cm), degrees."""
    power: float
    """Volts at the switch."""
    step: int
    """Gait steps taken before the switch."""
    outcome: str
    """``DOCKED``, ``CUT``, or the name of the end that came first (``END_NAMES``)."""


class HandoffWatcher:
    """Follows one coverage run's events (an ``on_event`` of ``evolve.interpreter.run``, in
    either world) and gathers its hand-offs: ``finish(end)`` after the run gives them all."""

    def __init__(self, pose: tuple[float, float, float], power: float) -> None:
        """``pose`` (cm, cm, deg) and ``power`` (V): the run's start."""
        self.last: tuple[tuple[float, float, float], float, int] = (pose, power, 0)
        self.mode = "coverage"
        self.open: tuple[tuple[float, float, float], float, int] | None = None
        self.found: list[Handoff] = []

    def __call__(self, e: StepEvent) -> None:
        if e.kind == "gait":
            if e.mode == "navigation" and self.mode != "navigation":
                self.open = self.last
            self.mode = e.mode
        elif e.kind == "charge" and self.open is not None:
            self.found.append(Handoff(*self.open, DOCKED))
            self.open = None
        self.last = (e.pose, e.power, e.step)

    def finish(self, end: int) -> list[Handoff]:
        """Every hand-off of the run that ended with code ``end``, in order: the one still
        open (the run ended before its approach docked) closed by ``open_outcome(end)``."""
        if self.open is not None:
            self.found.append(Handoff(*self.open, open_outcome(end)))
            self.open = None
        return self.found


def open_outcome(end: int) -> str:
    """The outcome of a hand-off still open when its robot's run ended with code ``end``:
    ``CUT`` by the step limit, else the end's name (``END_NAMES``)."""
    return CUT if end == END_STEP_LIMIT else END_NAMES[end]


def collect_handoffs(
    chromosome: np.ndarray,
    starts: np.ndarray,
    *,
    table: GaitTable | np.ndarray,
    world: WorldSettings,
    max_steps: int | None = None,
) -> list[list[Handoff]]:
    """Every hand-off of a 16-gene ``chromosome``'s coverage runs from ``starts`` (S, 3) in the
    table world: one list per start, in order."""
    values = getattr(table, "values", table)
    out = []
    for x, y, h in np.asarray(starts, dtype=float):
        watch = HandoffWatcher((float(x), float(y), float(h)), world.start_power_v)
        tw = TableWorld(values, x, y, h, world)
        res = run(chromosome, tw, mode="coverage", settings=world, max_steps=max_steps,
                  on_event=watch)  # fmt: skip
        out.append(watch.finish(res.end))
    return out


def handoff_record(h: Handoff) -> dict[str, Any]:
    """One hand-off as JSON: ``pose`` [x, y, h] (cm, cm, deg), ``power`` (V), ``step``,
    ``outcome``."""
    return {"pose": [round(float(v), 4) for v in h.pose], "power": round(float(h.power), 6),
            "step": int(h.step), "outcome": h.outcome}  # fmt: skip


def handoff_rate(handoffs: Iterable[Handoff]) -> dict[str, Any]:
    """``{"handoffs", "docked", "failed", "cut", "dock_rate"}``: dock_rate = docked /
    (docked + failed), None when no approach finished."""
    outcomes = [h.outcome for h in handoffs]
    docked, cut = outcomes.count(DOCKED), outcomes.count(CUT)
    failed = len(outcomes) - docked - cut
    done = docked + failed
    return {
        "handoffs": len(outcomes),
        "docked": docked,
        "failed": failed,
        "cut": cut,
        "dock_rate": docked / done if done else None,
    }


def write_handoffs(path: Path, by_population: dict[int, list[list[Handoff]]]) -> Path:
    """``handoffs.csv`` (``COLUMNS``), atomically: every hand-off of every finalist."""
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(COLUMNS)
    for k, per_start in sorted(by_population.items()):
        for j, found in enumerate(per_start):
            for h in found:
                x, y, hd = h.pose
                w.writerow((f"{x:.4f}", f"{y:.4f}", f"{hd:.4f}", f"{h.power:.6f}", h.outcome,
                            k, j, h.step))  # fmt: skip
    return atomic_write_text(path, buf.getvalue())


class PosesError(InputError, ValueError):
    """A poses file that cannot be used; the message names the file, the line and the
    problem."""


def parse_poses(text: str, *, name: str = "<poses>") -> tuple[np.ndarray, np.ndarray | None]:
    """(poses (N, 3), powers (N,) or None) from CSV text with a header naming ``x``, ``y``,
    ``h`` and optionally ``power`` (other columns ignored, e.g. ``handoffs.csv``). Every value
    must be a finite number; ``PosesError`` names the line otherwise."""
    try:  # one row a line, whatever the line ends (\n, \r\n, \r)
        rows = list(csv.reader(text.splitlines()))
    except csv.Error as exc:
        raise PosesError(f"{name}: not CSV ({exc})") from exc
    if not rows or not any(rows[0]):
        raise PosesError(f"{name}: empty; expected a CSV header with columns x, y, h [, power]")
    head = [c.strip() for c in rows[0]]
    missing = [c for c in ("x", "y", "h") if c not in head]
    if missing:
        raise PosesError(f"{name}: line 1: the header lacks column(s) {', '.join(missing)}")
    cols = [head.index(c) for c in ("x", "y", "h", "power") if c in head]
    values = []
    for line, row in enumerate(rows[1:], start=2):
        if not any(v.strip() for v in row):
            continue
        if len(row) != len(head):
            raise PosesError(f"{name}: line {line}: {len(row)} fields, the header has {len(head)}")
        try:
            nums = [float(row[c]) for c in cols]
        except ValueError as exc:
            raise PosesError(f"{name}: line {line}: not a number ({exc})") from exc
        if not all(np.isfinite(nums)):
            raise PosesError(f"{name}: line {line}: values must be finite, got {nums}")
        values.append(nums)
    if not values:
        raise PosesError(f"{name}: no poses after the header")
    arr = np.array(values, dtype=np.float64)
    return arr[:, :3], (arr[:, 3] if arr.shape[1] == 4 else None)


def read_poses(path: str | Path) -> tuple[np.ndarray, np.ndarray | None]:
    """``parse_poses`` of a file, read with named errors (``infra.io.read_text``)."""
    return parse_poses(read_text(path, what="poses file"), name=str(path))


__all__ = [
    "COLUMNS",
    "CUT",
    "DOCKED",
    "Handoff",
    "HandoffWatcher",
    "PosesError",
    "collect_handoffs",
    "handoff_rate",
    "handoff_record",
    "open_outcome",
    "parse_poses",
    "read_poses",
    "write_handoffs",
]
