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

A colony (SPEC §7, ``run_colony``) runs one such per-robot run for each of R robots against a
``ColonyWorld``. Each run is a generator that stops at the end of each of its colony steps
(one gait step, one charging step, or one backup step); the colony resumes the live robots in
index order, one colony step each, and keeps the one station: a robot docks only while no
other robot is charging, then occupies it for ``ColonySettings.charge_steps`` colony steps.
The lone ``run`` drives the same generator to its end with charging at once, so R = 1 is
one robot. Choices for the colony (documented in ``docs/colony.md``):
- each robot takes up to ``max_steps`` gait steps of its own; its charging steps are not gait
  steps; the run ends when no robot is live (or after ``colony_step_limit`` colony steps);
- the station is occupied from the dock until the end of the robot's last charging step;
  power rises linearly, ``charged_power_v`` exactly at the last one;
- a robot that meets the docking rule while another charges does not dock (a "wait" event)
  and runs on; the step counts as a station wait.
"""

from __future__ import annotations

from collections.abc import Callable, Generator
from dataclasses import dataclass

import numpy as np

from evolve import geometry as geo
from evolve.codec import (
    FULL_GENES,
    LIGHT_BITS,
    LIGHT_LEFT,
    LIGHT_RIGHT,
    LOW_POWER,
    NAVIGATION_BASE,
    OBJECT_BITS,
    OBJECT_LEFT,
    OBJECT_RIGHT,
    OP_GAIT,
    SECTION_GENES,
    TEST_MASKS,
    TEST_NAMES,
    branch_destination,
    check_bits,
    decode,
    next_pc,
    sensor_test_positive,
)
from evolve.settings import ALIVE_FITNESSES, DOCK_FITNESSES, ColonySettings, WorldSettings
from evolve.world import ColonyWorld, RobotView, World

END_STEP_LIMIT, END_KILL_ZONE, END_POWER_EMPTY, END_BRANCH_LIMIT, END_DOCKED = 0, 1, 2, 3, 4
END_NAMES = ("step limit", "kill zone", "power empty", "branch limit", "docked")
"""Display name of each end code."""
BLOCKED_MARK = " (blocked)"
"""Ends the text of a ``"gait"`` event whose move was cancelled (``RunResult.collisions``)."""
LIVE_ENDS = (END_STEP_LIMIT, END_DOCKED)
"""End codes of a robot *live at the end* of a colony run (``ColonySettings.fitness``
``"alive"``, the colony's reports): it ran until its own gait-step limit, or the colony-step
limit stopped it (walking, charging, backing up or waiting for the station: all end
``END_STEP_LIMIT``), or it docked in a navigation run. Kill zone, power empty and branch limit
end a robot that is no longer live (SPEC §7)."""
MODES = ("coverage", "navigation")
"""Run modes: a 16-gene chromosome from gene 0, or an 8-gene navigation section alone."""
DEFAULT_SETTINGS = WorldSettings()
DEFAULT_COLONY = ColonySettings()


@dataclass(frozen=True)
class StepEvent:
    """One thing the controller did, for traces and recordings."""

    kind: str
    """"gait" | "branch" | "charge" | "wait" (colony: docking refused, station busy) | "end"."""
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
    collisions: int = 0
    """Steps whose move was cancelled: another robot blocked it (colony runs), or an
    envelope's station block that stops motion (SPEC §9); else 0."""
    station_waits: int = 0
    """Steps after which the docking rule held while another robot was charging (colony)."""


Where = tuple[int, str]
"""(gene, mode) where a run stands: what ``_Run.execute`` yields after each colony step."""


class _Station:
    """The one power station: which robot, if any, is charging."""

    def __init__(self) -> None:
        self.holder: int | None = None


class _Run:
    """State of one run; ``execute`` is the controller loop."""

    def __init__(
        self, bits, world, mode, settings, start_power, max_steps, on_event,
        *, index=0, station=None, charge_steps=0,
    ) -> None:  # fmt: skip
        self.index = index
        self.station = _Station() if station is None else station
        self.charge_steps = int(charge_steps)
        self.collisions = 0
        self.waits = 0
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
        if mask & OBJECT_BITS:
            left, right = self.world.object_sensors()
            bits |= (OBJECT_LEFT if left else 0) | (OBJECT_RIGHT if right else 0)
        if mask & LIGHT_BITS:
            left, right = self.world.light_sensors()
            bits |= (LIGHT_LEFT if left else 0) | (LIGHT_RIGHT if right else 0)
        return bits

    def emit(self, kind, gene, instr, text, gait=-1, mode="coverage", new_square=-1) -> None:
        if self.on_event is None:
            return
        all_bits = LOW_POWER | OBJECT_BITS | LIGHT_BITS
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
        """Walk one cycle; kill zone → power empty → mark square. Returns an end code or None.
        A move that the world cancelled (another robot, a station block) keeps the pose and
        still counts and costs."""
        blocked = bool(self.world.step(gait))
        x, y, h = self.world.pose()
        self.power = self.power - self.p[geo.P_GAIT_COST + gait]
        self.steps += 1
        self.branches = 0
        self.collisions += blocked
        self.track.append((x, y, h))
        text = f"gait {gait}{BLOCKED_MARK}" if blocked else f"gait {gait}"
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

    def may_dock(self, gene: int, instr: int, mode: str) -> bool:
        """Docking check after a step: the rule holds and no other robot is charging. When
        only the station is missing, the step is a station wait."""
        x, y, h = self.world.pose()
        if not geo.docked(x, y, h, self.p):
            return False
        holder = self.station.holder
        if holder is None:
            return True
        self.waits += 1
        self.emit("wait", gene, instr, f"docking refused: robot {holder} is charging", -1, mode)
        return False

    def charge(self) -> Generator[Where, None, int | None]:
        """The charging routine: the station held for ``charge_steps`` colony steps while power
        rises linearly to full (at once if 0), then the backup cycles (no docking check).
        Yields at the end of each colony step; returns an end code or None."""
        s, n = self.s, self.charge_steps
        self.station.holder = self.index
        start = self.power
        for j in range(1, n):
            yield -1, "charging"
            self.power = start + (s.charged_power_v - start) * j / n
            self.emit("charge", -1, -1, f"charging {j}/{n}: {self.power:.3f} V", -1, "charging")
        if n > 0:
            yield -1, "charging"
        self.power = float(s.charged_power_v)
        text = f"charging: {s.charged_power_v:.1f} V, {s.backup_cycles}× gait {s.backup_gait}"
        self.emit("charge", -1, -1, text, -1, "charging")
        self.station.holder = None
        for _ in range(s.backup_cycles):
            yield -1, "charging"
            end = self.step(s.backup_gait, -1, -1, "charging")
            if end is not None:
                return end
            if self.steps >= self.max_steps:
                return END_STEP_LIMIT
        yield -1, "charging"
        return None

    # -- the controller loop --------------------------------------------------------------
    def execute(self) -> Generator[Where, None, tuple[int, int, str]]:
        """Run to the end, yielding (gene, mode) at the end of each colony step; returns
        (end code, gene, mode) at the end."""
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
                if in_nav and self.may_dock(g, k, mode):
                    self.docks += 1
                    if self.nav_run:
                        return END_DOCKED, g, mode
                    if self.steps >= self.max_steps:
                        return END_STEP_LIMIT, g, mode
                    end = yield from self.charge()
                    if end is not None:
                        return end, -1, "charging"
                    g, k = 0, 0
                    rem = self.loops[0]
                    continue
                if self.steps >= self.max_steps:
                    return END_STEP_LIMIT, g, mode
                yield g, mode
            else:
                test = self.arg[g][k]
                positive = sensor_test_positive(test, self.active(TEST_MASKS[test]))
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
            g, k, rem, fresh = next_pc(g, k, rem)
            if fresh:
                rem = self.loops[g]

    def finish(self, end: int, gene: int, mode: str) -> RunResult:
        """Emit the end event and return the run's result."""
        self.emit("end", gene, -1, f"end: {END_NAMES[end]}", -1, mode)
        return RunResult(
            squares=len(self.reached),
            inner_squares=self.inner,
            steps=self.steps,
            docks=self.docks,
            end=end,
            final_pose=tuple(float(v) for v in self.world.pose()),
            reached=frozenset(self.reached),
            track=np.array(self.track, dtype=np.float64).reshape(-1, 3),
            collisions=self.collisions,
            station_waits=self.waits,
        )


def _check_run(
    bits: np.ndarray, mode: str, settings: WorldSettings, max_steps: int | None
) -> tuple[np.ndarray, int]:
    """The checked chromosome and step limit of a run (lone or colony)."""
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
    return arr, int(max_steps)


def _last(gen: Generator[Where, None, tuple[int, int, str]]) -> tuple[int, int, str]:
    """Drive a run's generator to its end; its return value."""
    while True:
        try:
            next(gen)
        except StopIteration as stop:
            return stop.value


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
    arr, max_steps = _check_run(bits, mode, settings, max_steps)
    power = settings.start_power_v if start_power is None else float(start_power)
    r = _Run(arr, world, mode, settings, power, max_steps, on_event)
    return r.finish(*_last(r.execute()))


@dataclass(frozen=True)
class ColonyEvent:
    """One robot's ``StepEvent`` in a colony run."""

    robot: int
    """Index of the robot, 0 … R − 1."""
    colony_step: int
    """Colony step (1-based) during which it happened; 0 before the first."""
    event: StepEvent


@dataclass
class ColonyResult:
    """Outcome of one colony run."""

    squares: int
    """Colony squares: reached by any robot."""
    inner_squares: int
    """Inner squares reached by any robot."""
    reached: frozenset[int]
    """Union of the robots' reached squares (indices i + grid_n·j)."""
    colony_steps: int
    """Colony steps run (rounds of every live robot)."""
    robots: tuple[RunResult, ...]
    """Per robot: its own squares, steps, docks, end, final pose, track, collisions, waits."""
    track: np.ndarray
    """(colony_steps + 1, R, 3): every robot's pose at the start and after each colony step."""

    @property
    def collisions(self) -> int:
        """Blocked moves, all robots."""
        return sum(r.collisions for r in self.robots)

    @property
    def station_waits(self) -> int:
        """Station waits, all robots."""
        return sum(r.station_waits for r in self.robots)

    @property
    def live(self) -> int:
        """Robots live at the end of the run (their end code in ``LIVE_ENDS``)."""
        return sum(1 for r in self.robots if r.end in LIVE_ENDS)

    @property
    def steps(self) -> int:
        """Gait steps, all robots (backup cycles included, charging steps not)."""
        return sum(r.steps for r in self.robots)


def colony_fitness(result: ColonyResult, colony: ColonySettings, max_steps: int) -> float:
    """One colony run's fitness under ``colony.fitness`` (``ColonySettings.fitness``), in
    squares; ``max_steps``: each robot's gait-step limit N of the run (``"per_step"``'s scale
    R × N). The reference for ``evolve.evaluation.colony_run_fitness``, bit for bit."""
    fitness = float(result.squares)
    n = len(result.robots)
    if colony.fitness == "per_step":
        steps = result.steps
        return 0.0 if steps == 0 else fitness * float(n * max_steps) / steps
    if colony.fitness in ALIVE_FITNESSES:
        fitness = fitness + float(colony.alive_weight) * result.live / n
    if colony.fitness in DOCK_FITNESSES:
        docks = sum(min(r.docks, colony.dock_cap) for r in result.robots)
        fitness = fitness + float(colony.dock_weight) * docks / n
    return fitness


def run_colony(
    bits: np.ndarray,
    world: ColonyWorld,
    *,
    mode: str = "coverage",
    settings: WorldSettings = DEFAULT_SETTINGS,
    colony: ColonySettings = DEFAULT_COLONY,
    start_power: float | None = None,
    max_steps: int | None = None,
    on_event: Callable[[ColonyEvent], None] | None = None,
) -> ColonyResult:
    """Run chromosome ``bits`` on every robot of ``world`` (SPEC §7) until no robot is live;
    ``bits`` (R, genes, 30): robot i carries ``bits[i]`` (a team, ``evolve.coevolution``).

    One colony step: each live robot in index order runs its program to its next gait
    instruction and executes it with its checks (or takes one charging or backup step).
    ``max_steps`` (default as ``run``) bounds each robot's own gait steps; robot i starts
    with ``colony.start_powers(start_power, settings.charged_power_v)[i]`` (``start_power``
    defaults to ``settings.start_power_v``; ``ColonySettings.start_power_spread``); ``colony``
    gives the charging time and the optional colony-step limit, and must have
    ``colony.robots == world.robots``. ``on_event`` receives every ``ColonyEvent``.
    """
    n = world.robots
    if colony.robots != n:
        raise ValueError(f"the world holds {n} robots but colony.robots = {colony.robots}")
    team = np.asarray(bits)
    if team.ndim == 3 and team.shape[0] != n:
        raise ValueError(f"a team of {team.shape[0]} chromosomes for a colony of {n} robots")
    each = team if team.ndim == 3 else [team]
    checked = [_check_run(b, mode, settings, max_steps) for b in each]
    max_steps = checked[0][1]
    chromosomes = [c[0] for c in checked] * (n if len(checked) == 1 else 1)
    power = settings.start_power_v if start_power is None else float(start_power)
    powers = colony.start_powers(power, settings.charged_power_v)
    station = _Station()
    clock = [0]

    def emitter(i: int) -> Callable[[StepEvent], None] | None:
        if on_event is None:
            return None
        return lambda e: on_event(ColonyEvent(i, clock[0], e))

    runs = [
        _Run(chromosomes[i], RobotView(world, i), mode, settings, powers[i], max_steps, emitter(i),
             index=i, station=station, charge_steps=colony.charge_steps)
        for i in range(n)
    ]  # fmt: skip
    gens = [r.execute() for r in runs]
    where: list[Where] = [(0, "navigation" if mode == "navigation" else "coverage")] * n
    results: list[RunResult | None] = [None] * n
    track = [[world.pose(i) for i in range(n)]]
    limit = 0 if max_steps <= 0 else colony.colony_step_limit
    while any(r is None for r in results) and (limit is None or clock[0] < limit):
        clock[0] += 1
        for i in range(n):
            if results[i] is None:
                try:
                    where[i] = next(gens[i])
                except StopIteration as stop:
                    results[i] = runs[i].finish(*stop.value)
        track.append([world.pose(i) for i in range(n)])
    for i in range(n):
        if results[i] is None:  # the colony-step limit, or no step allowed
            gens[i].close()
            results[i] = runs[i].finish(END_STEP_LIMIT, *where[i])
    done = tuple(r for r in results if r is not None)
    reached = frozenset().union(*(r.reached for r in done))
    p = geo.packed_tuple(settings)
    return ColonyResult(
        squares=len(reached),
        inner_squares=sum(1 for sq in reached if geo.square_is_inner(sq, p)),
        reached=reached,
        colony_steps=clock[0],
        robots=done,
        track=np.array(track, dtype=np.float64).reshape(-1, n, 3),
    )


__all__ = [
    "BLOCKED_MARK",
    "END_BRANCH_LIMIT",
    "END_DOCKED",
    "END_KILL_ZONE",
    "END_NAMES",
    "END_POWER_EMPTY",
    "END_STEP_LIMIT",
    "LIVE_ENDS",
    "MODES",
    "ColonyEvent",
    "ColonyResult",
    "RunResult",
    "StepEvent",
    "colony_fitness",
    "run",
    "run_colony",
]
