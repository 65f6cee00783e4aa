"""The reference interpreter: the one home of the controller semantics (SPEC §4), plain Python.

It runs a chromosome against any ``World`` (``evolve.world``): the table world, or the MuJoCo
physics world. Power, squares, the kill zone, docking, the low-power sensor, the mode switch
and the charging routine belong to the interpreter; the world only walks and senses. The
numba kernel (``evolve.kernel``) is a fast copy of this file for the table world, proven
equal by ``tests/test_kernel.py``.

Execution (SPEC §4): a gene runs its four instructions and repeats as its loop count says
(00 forever), then control moves to the next gene of the section, wrapping within it. A
positive branch restarts the destination gene at its first instruction with a fresh loop
count; a negative one falls through. Sensors are read when a branch executes.

Choices this file makes where the SPEC is silent (documented in ``docs/kernel.md``):
- the start pose is not a step, so its square is not marked (only poses after steps are);
- after each step: kill zone → power empty → mark square → docking → step limit; a dock on
  the last allowed step counts in ``docks`` and the run ends before the charge;
- the charging routine's backup steps are events of mode "charging" with gene = −1 and
  instruction = −1, and each may end the run (kill zone, power empty, step limit).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from evolve import geometry as geo
from evolve.codec import (
    FULL_GENES,
    LIGHT_LEFT,
    LIGHT_RIGHT,
    LOW_POWER,
    NAVIGATION_BASE,
    OBJECT_LEFT,
    OBJECT_RIGHT,
    OP_GAIT,
    SECTION_GENES,
    TEST_MASKS,
    TEST_NAMES,
    branch_destination,
    check_bits,
    decode,
    next_gene,
)
from evolve.settings import WorldSettings
from evolve.world import World

END_STEP_LIMIT, END_KILL_ZONE, END_POWER_EMPTY, END_BRANCH_LIMIT, END_DOCKED = 0, 1, 2, 3, 4
END_NAMES = ("step limit", "kill zone", "power empty", "branch limit", "docked")
"""Display name of each end code."""
MODES = ("coverage", "navigation")
"""Run modes: a 16-gene chromosome from gene 0, or an 8-gene navigation section alone."""
DEFAULT_SETTINGS = WorldSettings()

_OBJECT_BITS = OBJECT_LEFT | OBJECT_RIGHT
_LIGHT_BITS = LIGHT_LEFT | LIGHT_RIGHT


@dataclass(frozen=True)
class StepEvent:
    """One thing the controller did, for traces and recordings."""

    kind: str
    """"gait" | "branch" | "charge" | "end"."""
    step: int
    """Gait steps taken so far (after this event)."""
    gene: int
    """Absolute gene index (0–15, or 0–7 for an 8-gene section); −1 in the charging routine."""
    instruction: int
    """Instruction 0–3 in the gene; −1 for charge/end and the charging routine's steps."""
    text: str
    """e.g. "gait 8", "if light-left goto 5: taken", "end: kill zone"."""
    gait: int
    """Gait executed, −1 if none."""
    pose: tuple[float, float, float]
    """Pose after the event: x, y (arena units), heading (deg)."""
    power: float
    """Volts after the event."""
    mode: str
    """"coverage" | "navigation" | "charging"."""
    sensors: int
    """Active sensor bitmask at the pose after the event (incl. LOW_POWER)."""
    squares: int
    """Squares reached so far."""
    new_square: int
    """Square index first reached by this step, −1 if none."""


@dataclass
class RunResult:
    """Outcome of one run."""

    squares: int
    """Squares reached."""
    inner_squares: int
    """Inner squares reached (1 ≤ i, j ≤ grid_n − 2)."""
    steps: int
    """Gait steps taken (charging-routine steps included)."""
    docks: int
    """Times the robot docked (coverage mode; 1 for a docked navigation run)."""
    end: int
    """End code: END_STEP_LIMIT, END_KILL_ZONE, END_POWER_EMPTY, END_BRANCH_LIMIT, END_DOCKED."""
    final_pose: tuple[float, float, float]
    """Pose at the end: x, y (arena units), heading (deg)."""
    reached: frozenset[int]
    """Indices i + grid_n·j of the squares reached."""
    track: np.ndarray
    """(steps + 1, 3) poses: the start, then the pose after each step."""


class _Run:
    """State of one run; ``execute`` is the controller loop."""

    def __init__(self, bits, world, mode, settings, start_power, max_steps, on_event) -> None:
        self.n_genes = bits.shape[0]
        self.loops, self.ops, self.arg, self.target = (a.tolist() for a in decode(bits))
        self.world = world
        self.nav_run = mode == "navigation"
        self.p = geo.packed_tuple(settings)
        self.s = settings
        self.power = float(start_power)
        self.max_steps = int(max_steps)
        self.on_event = on_event
        self.steps = 0
        self.docks = 0
        self.branches = 0
        self.reached: set[int] = set()
        self.inner = 0
        self.track = [world.pose()]

    # -- sensors -------------------------------------------------------------------------
    def active(self, mask: int) -> int:
        """Active sensors among those in ``mask`` (reads only the sensors a test needs)."""
        bits = 0
        if mask & LOW_POWER and self.power < self.s.low_power_v:
            bits |= LOW_POWER
        if mask & _OBJECT_BITS:
            left, right = self.world.object_sensors()
            bits |= (OBJECT_LEFT if left else 0) | (OBJECT_RIGHT if right else 0)
        if mask & _LIGHT_BITS:
            left, right = self.world.light_sensors()
            bits |= (LIGHT_LEFT if left else 0) | (LIGHT_RIGHT if right else 0)
        return bits

    def emit(self, kind, gene, instr, text, gait=-1, mode="coverage", new_square=-1) -> None:
        if self.on_event is None:
            return
        all_bits = LOW_POWER | _OBJECT_BITS | _LIGHT_BITS
        self.on_event(
            StepEvent(
                kind=kind,
                step=self.steps,
                gene=gene,
                instruction=instr,
                text=text,
                gait=gait,
                pose=self.world.pose(),
                power=self.power,
                mode=mode,
                sensors=self.active(all_bits),
                squares=len(self.reached),
                new_square=new_square,
            )
        )

    # -- one gait cycle and the post-step checks ------------------------------------------
    def step(self, gait: int, gene: int, instr: int, mode: str) -> int | None:
        """Walk one cycle; kill zone → power empty → mark square. Returns an end code or None."""
        self.world.step(gait)
        x, y, h = self.world.pose()
        self.power = self.power - self.p[geo.P_GAIT_COST + gait]
        self.steps += 1
        self.branches = 0
        self.track.append((x, y, h))
        text = f"gait {gait}"
        if geo.killed(x, y, self.p):
            self.emit("gait", gene, instr, text, gait, mode)
            return END_KILL_ZONE
        if self.power < self.s.empty_power_v:
            self.emit("gait", gene, instr, text, gait, mode)
            return END_POWER_EMPTY
        sq = geo.square_at(x, y, self.p)
        new = -1
        if sq >= 0 and sq not in self.reached:
            self.reached.add(sq)
            self.inner += 1 if geo.square_is_inner(sq, self.p) else 0
            new = sq
        self.emit("gait", gene, instr, text, gait, mode, new)
        return None

    def charge(self) -> int | None:
        """The charging routine: power to full, then the backup cycles (no docking check)."""
        s = self.s
        self.power = float(s.charged_power_v)
        text = f"charging: {s.charged_power_v:.1f} V, {s.backup_cycles}× gait {s.backup_gait}"
        self.emit("charge", -1, -1, text, -1, "charging")
        for _ in range(s.backup_cycles):
            end = self.step(s.backup_gait, -1, -1, "charging")
            if end is not None:
                return end
            if self.steps >= self.max_steps:
                return END_STEP_LIMIT
        return None

    # -- the controller loop --------------------------------------------------------------
    def execute(self) -> tuple[int, int, str]:
        """Run to the end; returns (end code, gene, mode) at the end."""
        n = self.n_genes
        g, k = 0, 0
        rem = self.loops[0]
        mode = "navigation" if self.nav_run else "coverage"
        if self.max_steps <= 0:
            return END_STEP_LIMIT, g, mode
        while True:
            in_nav = self.nav_run or g >= NAVIGATION_BASE
            mode = "navigation" if in_nav else "coverage"
            if self.ops[g][k] == OP_GAIT:
                gait = self.arg[g][k]
                end = self.step(gait, g, k, mode)
                if end is not None:
                    return end, g, mode
                x, y, h = self.world.pose()
                if in_nav and geo.docked(x, y, h, self.p):
                    if self.nav_run:
                        self.docks += 1
                        return END_DOCKED, g, mode
                    self.docks += 1
                    if self.steps >= self.max_steps:
                        return END_STEP_LIMIT, g, mode
                    end = self.charge()
                    if end is not None:
                        return end, -1, "charging"
                    g, k = 0, 0
                    rem = self.loops[0]
                    continue
                if self.steps >= self.max_steps:
                    return END_STEP_LIMIT, g, mode
            else:
                test = self.arg[g][k]
                mask = TEST_MASKS[test]
                positive = (self.active(mask) & mask) == mask
                dest = branch_destination(g, test, self.target[g][k], n)
                self.branches += 1
                verdict = "taken" if positive else "not taken"
                text = f"if {TEST_NAMES[test]} goto {dest}: {verdict}"
                self.emit("branch", g, k, text, -1, mode)
                if self.branches >= self.s.max_consecutive_branches:
                    return END_BRANCH_LIMIT, g, mode
                if positive:
                    g, k = dest, 0
                    rem = self.loops[g]
                    continue
            k += 1
            if k == 4:
                k = 0
                if rem != 0:
                    rem -= 1
                    if rem == 0:
                        g = next_gene(g)
                        rem = self.loops[g]


def run(
    bits: np.ndarray,
    world: World,
    *,
    mode: str,
    settings: WorldSettings = DEFAULT_SETTINGS,
    start_power: float | None = None,
    max_steps: int | None = None,
    on_event: Callable[[StepEvent], None] | None = None,
) -> RunResult:
    """Run chromosome ``bits`` in ``world`` from its current pose until the run ends.

    ``mode`` "coverage": a 16-gene chromosome from gene 0 (default 600 steps); "navigation":
    an 8-gene section from gene 0, docking ends the run (default 100 steps). ``start_power``
    defaults to ``settings.start_power_v``. ``on_event`` receives every ``StepEvent``.
    """
    if mode not in MODES:
        raise ValueError(f"mode must be 'coverage' or 'navigation', got {mode!r}")
    arr = check_bits(bits)
    want = FULL_GENES if mode == "coverage" else SECTION_GENES
    if arr.shape[0] != want:
        raise ValueError(f"mode {mode!r} needs a {want}-gene chromosome, got {arr.shape[0]} genes")
    if max_steps is None:
        max_steps = settings.coverage_steps if mode == "coverage" else settings.navigation_steps
    if max_steps < 0:
        raise ValueError(f"max_steps must be ≥ 0, got {max_steps}")
    power = settings.start_power_v if start_power is None else float(start_power)
    r = _Run(arr, world, mode, settings, power, max_steps, on_event)
    end, gene, end_mode = r.execute()
    r.emit("end", gene, -1, f"end: {END_NAMES[end]}", -1, end_mode)
    return RunResult(
        squares=len(r.reached),
        inner_squares=r.inner,
        steps=r.steps,
        docks=r.docks,
        end=end,
        final_pose=tuple(float(v) for v in world.pose()),
        reached=frozenset(r.reached),
        track=np.array(r.track, dtype=np.float64).reshape(-1, 3),
    )


__all__ = [
    "END_BRANCH_LIMIT",
    "END_DOCKED",
    "END_KILL_ZONE",
    "END_NAMES",
    "END_POWER_EMPTY",
    "END_STEP_LIMIT",
    "MODES",
    "RunResult",
    "StepEvent",
    "run",
]
