"""Settings of the table world, the colony and the GA (SPEC §3, §5–7) as frozen dataclasses.

Every value the SPEC marks [chosen] is a named field here; [paper] values are fields too so
that a run folder's saved settings say exactly how it was made. Units: lengths in arena units
(1 unit = 1 cm), angles in degrees (0 = north/+y, clockwise positive), power in volts.
Override with ``dataclasses.replace``.
"""

from __future__ import annotations

import dataclasses
import json
import math
import numbers
from dataclasses import dataclass
from typing import Any

from infra.bounds import is_finite_number
from infra.errors import InputError


class SettingsError(InputError, ValueError):
    """Settings that cannot describe a run (a bad power model, an impossible colony); the
    message names the field."""


BLOCKING_RULES = ("cancel", "slide")
"""``ColonySettings.blocking`` values; a rule's index is its code in the numba kernel
(``ColonySettings.blocking_code``)."""

COLONY_FITNESSES = ("squares", "alive", "per_step", "docks", "alive_docks")
"""``ColonySettings.fitness`` values: what one colony run scores in the colony stage."""

ALIVE_FITNESSES = ("alive", "alive_docks")
"""The ``ColonySettings.fitness`` values that add the live robots' term (``alive_weight``)."""

DOCK_FITNESSES = ("docks", "alive_docks")
"""The ``ColonySettings.fitness`` values that add the capped docks' term (``dock_weight``,
``dock_cap``)."""

COLONY_SECTIONS = ("shared", "team", "navigation", "beside")
"""``ColonySettings.sections`` values: one coverage section for every robot, one per robot
evolved by cooperative coevolution, the navigation section under fixed coverage sections, or
the last robot's coverage section beside fixed partners."""


@dataclass(frozen=True)
class WorldSettings:
    """The colony arena, sensors and power model (SPEC §3)."""

    arena_size: float = 500.0
    """Side of the square arena, units [paper]."""
    grid_n: int = 10
    """Squares per side of the coverage grid [paper]."""
    square_size: float = 50.0
    """Side of one coverage square, units [paper]."""
    contact_half_width: float = 19.0
    """A square is reached inside its central 38 × 38: |dx|, |dy| ≤ this [paper]."""
    kill_margin: float = 25.0
    """A centre closer than this to a wall ends the run [paper]."""

    station_y: float = 250.0
    """Power-station plate centre on the east wall, y [chosen]."""
    station_width: float = 60.0
    """Power-station plate width along the wall [chosen]."""
    dock_x_min: float = 455.0
    """Docking needs x ≥ this after a gait cycle [chosen]."""
    dock_y_half_width: float = 30.0
    """Docking needs |y − station_y| ≤ this [chosen]."""
    dock_heading_deg: float = 90.0
    """Docking heading (east, facing the plate) [chosen]."""
    dock_heading_tol_deg: float = 30.0
    """Docking needs the heading within ± this of ``dock_heading_deg`` [chosen]."""
    dock_point: tuple[float, float] = (465.0, 250.0)
    """Point whose distance scores navigation runs that do not dock (SPEC §6) [chosen]."""
    dock_fitness: float = 2.0
    """Navigation run that docks scores this − steps/navigation_steps (SPEC §6) [chosen]."""
    approach_fitness: float = 0.5
    """Navigation run that does not dock scores this · max(0, 1 − d_end/d_start) [chosen]."""

    lights: tuple[tuple[float, float], ...] = ((500.0, 235.0), (500.0, 265.0))
    """Point light sources, (x, y) units [paper: two points; positions chosen]."""
    light_axis_deg: float = 270.0
    """Each source lights a cone around this heading (west) [chosen]."""
    light_half_angle_deg: float = 60.0
    """Half-angle of each source's lit cone [chosen]."""
    light_left_span_deg: tuple[float, float] = (-60.0, 20.0)
    """Left light sensor, relative bearings (80° span, 40° overlap) [paper spans; chosen]."""
    light_right_span_deg: tuple[float, float] = (-20.0, 60.0)
    """Right light sensor, relative bearings [paper spans; chosen]."""
    object_left_span_deg: tuple[float, float] = (-40.0, 5.0)
    """Left object sensor, relative bearings (45° span, 10° overlap) [paper spans; chosen]."""
    object_right_span_deg: tuple[float, float] = (-5.0, 40.0)
    """Right object sensor, relative bearings [paper spans; chosen]."""
    object_range: float = 50.0
    """Object sensors fire when a wall lies within this distance in their span [chosen]."""

    gait_cost_v: float = 0.0209
    """Power used by every gait cycle except gait 7, volts (power model ``paper``) [paper]."""
    still_gait: int = 7
    """The gait that costs no power in the ``paper`` power model (stand still) [paper]."""
    power_model: str = "paper"
    """What a gait cycle costs: ``"paper"`` = ``gait_cost_v`` for every gait but
    ``still_gait`` (SPEC §3) [paper]; ``"table"`` = gait g costs ``gait_dv[g]`` volts, its
    voltage drop measured from physics by the calibration (``calibration.energy``; gait 7
    costs its measured standing drop too) [chosen]."""
    gait_dv: tuple[float, ...] | None = None
    """Voltage drop per cycle of each of the 16 gaits, volts, for ``power_model = "table"``
    (``with_table_power`` fills it from a calibration file's ``dV`` column)."""
    capacitance_f: float = 150.0
    """Capacitor bank, farads (6 pairs of 50 F in series, paper §II): converts a gait's
    measured energy per cycle into its voltage drop (``calibration.energy``) [paper]."""
    low_power_v: float = 4.0
    """Low-power sensor active below this, volts [paper]."""
    empty_power_v: float = 2.7
    """A run ends when power falls below this, volts [paper]."""
    charged_power_v: float = 5.0
    """Power after the charging routine, volts [paper]."""
    backup_gait: int = 15
    """Gait the charging routine walks after charging (backwards) [paper]."""
    backup_cycles: int = 4
    """How many backup gait cycles the charging routine walks [paper]."""
    start_power_v: float = 4.0
    """Power at the start of a run, volts [paper]."""
    max_consecutive_branches: int = 32
    """Branch instructions without a gait that end a run [paper]."""

    coverage_steps: int = 600
    """Steps of a coverage run [paper]."""
    navigation_steps: int = 100
    """Step limit of a navigation run [chosen]."""
    coverage_start_x: tuple[float, float] = (350.0, 450.0)
    """Coverage start poses: x range, units [chosen]."""
    coverage_start_y: tuple[float, float] = (175.0, 325.0)
    """Coverage start poses: y range, units [chosen]."""
    navigation_start_xy: tuple[float, float] = (25.0, 475.0)
    """Navigation start poses: x and y range, units [chosen]."""

    @property
    def inner_square_count(self) -> int:
        """Inner squares (1 ≤ i, j ≤ grid_n − 2): 64 on the 10 × 10 grid, Figure 9's
        denominator."""
        return (self.grid_n - 2) ** 2

    def gait_costs_v(self) -> tuple[float, ...]:
        """Power used by one cycle of each of the 16 gaits, volts, under ``power_model``;
        ``SettingsError`` naming the problem for an unknown model or a bad ``gait_dv``."""
        if self.power_model == "paper":
            return tuple(0.0 if g == self.still_gait else self.gait_cost_v for g in range(16))
        if self.power_model != "table":
            raise SettingsError(f"power_model must be 'paper' or 'table', got {self.power_model!r}")
        dv = self.gait_dv
        if dv is None or len(dv) != 16:
            n = "none" if dv is None else len(dv)
            raise SettingsError(f"power_model 'table' needs gait_dv: 16 voltage drops, got {n}")
        bad = [g for g, v in enumerate(dv) if not (math.isfinite(v) and v >= 0.0)]
        if bad:
            raise SettingsError(f"gait_dv must be finite volts >= 0; gaits {bad} are not")
        return tuple(float(v) for v in dv)

    def to_dict(self) -> dict[str, Any]:
        return dataclasses.asdict(self)


def with_table_power(world: WorldSettings, dv: Any) -> WorldSettings:
    """``world`` with the ``table`` power model: gait g costs ``dv[g]`` volts per cycle."""
    return dataclasses.replace(world, power_model="table", gait_dv=tuple(float(v) for v in dv))


@dataclass(frozen=True)
class ColonySettings:
    """A colony of robots sharing the arena and its one station (SPEC §7).

    Every robot runs the same chromosome under ``WorldSettings``; these fields add what the
    colony needs. Lengths in arena units (cm); times in colony steps (one step of every live
    robot, in index order).
    """

    robots: int = 3
    """Robots in the colony, R [chosen]."""
    disc_radius: float = 15.0
    """Table-world footprint: a disc of this radius around each robot's centre, units [chosen].
    A move that would bring two centres closer than two radii is cancelled; object sensors
    see every point of another robot's disc within ``WorldSettings.object_range``."""
    charge_steps: int = 10
    """Colony steps a docked robot occupies the station while charging (power rising linearly
    to ``charged_power_v``, the robot standing still) before its backup cycles [chosen].
    0 charges at once, as one robot does in SPEC §3."""
    start_separation: float = 40.0
    """Colony start poses: every centre at least this far from every other, units [chosen]."""
    colony_step_limit: int | None = None
    """If set, the run also ends after this many colony steps (SPEC §7 read literally: a
    robot's charging steps then come out of its 600). None (default): each robot takes up
    to ``coverage_steps`` (``navigation_steps``) gait steps of its own, charging steps not
    counted, and the run ends when no robot is live — so R = 1 is exactly one robot [chosen;
    see docs/colony.md]."""
    start_attempts: int = 10_000
    """Rejection draws allowed per robot's start pose before the sampler gives up (a bound,
    not a SPEC value)."""
    blocking: str = "cancel"
    """What the table world does with a gait move that another robot blocks [chosen; issue 17].
    Robot at centre c = (x, y) (arena units, x east, y north) with its move's end c + d (d: the
    gait row's (F, T) turned into the arena frame by the heading at the cycle's start, as
    ``geometry.move``; d = end − c) and heading h + ΔH. The move is blocked when c + d lies
    closer than ``min_distance`` (two radii) to another robot's centre o (live or ended).

    - ``"cancel"`` (default, SPEC §7): a blocked move is cancelled, the robot keeps its whole
      pose (heading too).
    - ``"slide"``: a move blocked by exactly one robot keeps its component along the contact
      tangent: with n = (c − o) / |c − o|, the unit normal from the other centre to this one
      at the move's start, d' = d − (d·n) n, and the robot ends at c + d' with heading
      h + ΔH (``geometry.slide_end``). The move is cancelled as under ``"cancel"`` when two
      or more robots block it, when d·n ≥ 0 (d does not point into the other disc: only
      rounding can then block it), or when c + d' is still closer than two radii to any
      robot. An envelope's station block that stops motion (``Envelope.station_stops``)
      then cancels the slid move as it cancels any move.

    Either way a blocked move (slid or cancelled) counts as a collision, costs power and is
    checked (squares, kill zone, docking) on the pose it leaves. Only the table world reads
    this; physics blocks by contacts (frictionless bumpers, which slide)."""
    fitness: str = "squares"
    """What one colony run scores in the colony stage (its run fitness; an individual's
    fitness is the mean over its runs, SPEC §5) [chosen; issue 17, docs/colony.md "Learning to
    share"]. Units: squares (of 100 in training, as the lone coverage fitness).

    - ``"squares"`` (default, SPEC §7): the colony's squares, reached by any robot.
    - ``"alive"``: the colony's squares + ``alive_weight`` × L / R, L the robots live at the
      end of the run (``evolve.interpreter.LIVE_ENDS``: ended by their step limit, or by the
      colony-step limit — walking, charging, backing up or waiting — or docked in navigation
      mode; not live: kill zone, power empty, branch limit).
    - ``"per_step"``: the colony's squares × (R × N) / T, T the gait steps all robots took
      (backup cycles included, charging steps not), N the run's gait-step limit per robot
      (``coverage_steps``, 600): squares per robot step, scaled so that a colony whose robots
      all take their N steps scores exactly its squares; fewer steps for the same squares
      score more. 0 when no robot took a step (no square is reached then).
    - ``"docks"``: the colony's squares + ``dock_weight`` × Σ_r min(D_r, ``dock_cap``) / R,
      D_r the times robot r docked in the run: each dock up to the cap pays ``dock_weight``
      / R squares, so a colony whose every robot docks ``dock_cap`` times gains
      ``dock_weight`` × ``dock_cap``.
    - ``"alive_docks"``: both terms, ``"alive"``'s then ``"docks"``'s: every robot is paid for
      being live at the end and for each of its first ``dock_cap`` docks, so a colony cannot
      score its lives by a robot that parks and never docks, nor its docks by a robot that
      docks and dies (docs/colony.md "Every robot paid for its life and its docks")."""
    alive_weight: float = 8.0
    """``fitness = "alive"`` or ``"alive_docks"``: what keeping every robot live to the end
    adds to a run's fitness, in squares (the units of the ``"squares"`` fitness, of 100): 8 =
    as much as 8 more squares; each live robot adds ``alive_weight`` / R [chosen]."""
    dock_weight: float = 4.0
    """``fitness = "docks"`` or ``"alive_docks"``: what one dock of one robot is worth, in
    squares, times R (each dock adds ``dock_weight`` / R to a run's fitness); 4 with
    ``dock_cap`` 2: a colony whose every robot docks twice gains 8 squares, as
    ``alive_weight`` 8 pays for every robot live [chosen; docs/colony.md "Learning to
    dock"]."""
    dock_cap: int = 2
    """``fitness = "docks"`` or ``"alive_docks"``: the docks per robot and run that count;
    more earn nothing, so a colony is not paid for robots that shuttle to the station instead
    of covering. 2 = issue 17's goal of ≥ 2 docks per robot [chosen]."""
    start_power_spread: float = 0.0
    """The colony's start layout for power, volts [chosen; issue 17, docs/colony.md "Start
    layout: staggered start power"]: robot i of R starts with its store at
    min(P0 + i × spread, ``WorldSettings.charged_power_v``), P0 the run's start power (robot
    0's: ``WorldSettings.start_power_v``, 4.0 V), never below P0 (``start_powers``). 0
    (default): every robot starts on P0, as SPEC §7 reads; 0.5 → 4.0, 4.5, 5.0 V, so the
    robots do not all reach the low-power threshold at once. Only the start differs: a
    charge still ends at ``charged_power_v``."""
    robots_seen: bool = True
    """Whether the object sensors see the other robots [chosen; issue 17, docs/colony.md
    "Robots the rangefinders do not see"]. True (default, SPEC §7): a span is active if some
    point of another robot's disc lies within the activation distance along it. False: the
    object sensors see the walls (and a seen station block) only; the other robots still
    block moves. In MuJoCo, False is a robot whose rangefinder rays pass above the other
    robots (no shell, the bumper invisible to rays: ``servo_mj.world.arena``)."""
    contact_yaw_deg: float = 0.0
    """How far a robot turns away from a robot that blocks its move, degrees, for one abeam
    [chosen; issue 17, docs/colony.md "Where the colony's robots die"]. A move that robots
    block (their discs within two radii of its unslid end) also turns the robot by
    −``contact_yaw_deg`` · sin b per blocking robot, b the bearing of the other's centre from
    the robot's heading at the move's start (clockwise; ``geometry.contact_yaw``): away from
    the contact, most for a robot abeam, not at all for one dead ahead. The turn is added to
    the heading the move leaves (slid or cancelled, ``blocking``). 0 (default, SPEC §7): no
    turn. Measured in MuJoCo: a robot walking into a standing one 45° off its heading turns
    6.6° a cycle further away from it than the gait's row says (mean over 4 gaits × 3
    headings × both sides; ``tests/test_colony_contact_yaw.py``), i.e. 9.3° abeam. Only the
    table world reads this: physics turns by contact."""
    sections: str = "shared"
    """What the colony stage evolves [chosen; issue 17, docs/colony.md "A team of sections:
    cooperative coevolution"]: ``"shared"`` (default, SPEC §7), one coverage section that
    every robot carries; ``"team"``, one section per robot, robot r's from its own population
    (``evolve.coevolution``: each individual is scored as robot r of a colony whose other
    robots carry the other populations' current bests). A team costs R populations' runs.
    ``"navigation"``: the navigation section every robot carries, learned as a colony (from
    the hand-off poses the colony makes, among the other robots), population k's robots
    carrying the fixed coverage section of a finished shared run's finalist k and its
    individuals starting as the navigation section that run carried
    (``evolve.colony_stage.run_colony_stage(coverage=...)``; docs/colony.md "Navigation learned
    in the colony"). ``"beside"``: one robot's coverage section (the last, R−1, unless
    ``--beside-robot`` names another), learned beside fixed partners: the other robots carry
    given coverage sections (``--partners FILE[,FILE...]``), every robot the stage's
    navigation section, and each individual is scored as the learned robot of that colony
    (``evolve.colony_stage.run_colony_stage(partners=..., robot=...)``; docs/colony.md "A
    coverer learned for its team", "Any robot learned beside its team")."""

    def __post_init__(self) -> None:
        if self.fitness not in COLONY_FITNESSES:
            allowed = ", ".join(repr(f) for f in COLONY_FITNESSES)
            raise SettingsError(f"fitness must be one of {allowed}, got {self.fitness!r}")
        for name, unit in (("alive_weight", "squares"), ("dock_weight", "squares"),
                           ("start_power_spread", "volts")):  # fmt: skip
            w = getattr(self, name)
            if not (is_finite_number(w) and w >= 0):
                raise SettingsError(f"{name} must be a finite number ≥ 0 ({unit}), got {w!r}")
        cap = self.dock_cap
        if not (isinstance(cap, numbers.Integral) and not isinstance(cap, bool) and cap >= 1):
            raise SettingsError(f"dock_cap must be an integer ≥ 1 (docks per robot), got {cap!r}")
        if self.sections not in COLONY_SECTIONS:
            allowed = ", ".join(repr(v) for v in COLONY_SECTIONS)
            raise SettingsError(f"sections must be one of {allowed}, got {self.sections!r}")
        if not (is_finite_number(self.contact_yaw_deg) and self.contact_yaw_deg >= 0):
            raise SettingsError(f"contact_yaw_deg must be a finite number ≥ 0 (degrees), got "
                                f"{self.contact_yaw_deg!r}")  # fmt: skip
        if not isinstance(self.robots_seen, bool):
            raise SettingsError(f"robots_seen must be true or false, got {self.robots_seen!r}")
        if self.blocking not in BLOCKING_RULES:
            allowed = ", ".join(repr(b) for b in BLOCKING_RULES)
            raise SettingsError(f"blocking must be one of {allowed}, got {self.blocking!r}")
        if self.robots < 1:
            raise SettingsError(f"robots must be ≥ 1, got {self.robots}")
        if not self.disc_radius >= 0.0:
            raise SettingsError(f"disc_radius must be ≥ 0, got {self.disc_radius}")
        if self.charge_steps < 0:
            raise SettingsError(f"charge_steps must be ≥ 0, got {self.charge_steps}")
        if not self.start_separation >= 2.0 * self.disc_radius:
            raise SettingsError(
                f"start_separation {self.start_separation} must be at least two disc radii "
                f"({2.0 * self.disc_radius}): robots would start overlapping"
            )
        if self.colony_step_limit is not None and self.colony_step_limit < 0:
            limit = self.colony_step_limit
            raise SettingsError(f"colony_step_limit must be ≥ 0 or None, got {limit}")
        if self.start_attempts < 1:
            raise SettingsError(f"start_attempts must be ≥ 1, got {self.start_attempts}")

    @property
    def min_distance(self) -> float:
        """Closest allowed distance between two robots' centres: two disc radii, units."""
        return 2.0 * self.disc_radius

    @property
    def blocking_code(self) -> int:
        """``blocking`` as the numba kernel's code: its index in ``BLOCKING_RULES``."""
        return BLOCKING_RULES.index(self.blocking)

    def start_powers(self, start_power: float, charged_power: float) -> tuple[float, ...]:
        """Each robot's start power, volts (``start_power_spread``): robot i of ``robots``
        starts on max(P0, min(P0 + i × spread, ``charged_power``)), P0 = ``start_power``.
        With spread 0 every robot starts on P0 exactly. The one rule of the interpreter
        (``run_colony``) and the kernel (``evaluate_colony`` passes these values)."""
        p0 = float(start_power)
        spread = float(self.start_power_spread)
        if spread == 0.0:
            return (p0,) * self.robots
        cap = float(charged_power)
        return tuple(max(p0, min(p0 + i * spread, cap)) for i in range(self.robots))

    def to_dict(self) -> dict[str, Any]:
        """Every field, but ``blocking`` only when it is not ``"cancel"``, ``fitness`` only when
        it is not ``"squares"``, ``sections`` only when it is not ``"shared"``, ``alive_weight``
        only with ``fitness = "alive"`` or ``"alive_docks"``, ``dock_weight``, ``dock_cap`` only
        with ``fitness = "docks"`` or ``"alive_docks"`` (the fitnesses that read them),
        ``start_power_spread`` only when it is not 0, ``robots_seen`` only when False and
        ``contact_yaw_deg`` only when not 0: the record of a colony made before these fields
        existed (``settings.json``, checked on resume) is unchanged, so such a run folder still
        resumes."""
        d = dataclasses.asdict(self)
        if self.blocking == "cancel":
            del d["blocking"]
        if self.fitness == "squares":
            del d["fitness"]
        if self.fitness not in ALIVE_FITNESSES:
            del d["alive_weight"]
        if self.fitness not in DOCK_FITNESSES:
            del d["dock_weight"], d["dock_cap"]
        if self.start_power_spread == 0.0:
            del d["start_power_spread"]
        if self.sections == "shared":
            del d["sections"]
        if self.robots_seen:
            del d["robots_seen"]
        if self.contact_yaw_deg == 0.0:
            del d["contact_yaw_deg"]
        return d


@dataclass(frozen=True)
class GASettings:
    """The multi-loop CGA with conditional branching (SPEC §5, §6)."""

    populations: int = 5
    """Independent populations [paper]."""
    population_size: int = 256
    """Individuals per population [paper]."""
    generations: int = 512
    """Generations per population (coverage 512 [paper], navigation 1024 [chosen])."""
    starts_per_generation: int = 10
    """Start poses drawn anew each generation, shared by the population [paper]."""
    selection_exponent: float = 1.5
    """Roulette weight = fitness ** this [paper]."""
    one_point_probability: float = 0.5
    """Chance of gene-level one-point crossover (else gene-by-gene) [paper]."""
    instruction_mutation_rate: float = 1.0 / 600.0
    """After one-point crossover: chance each instruction is redrawn [paper]."""
    bit_flip_rate: float = 1.0 / 200.0
    """After gene-by-gene crossover: chance each bit flips [paper]."""
    test_starts: int = 100
    """Fresh start poses for the generational test (Figure 9, navigation report) [paper]."""
    save_generations: tuple[int, ...] = (0, 1, 32, 64, 128, 256, 384, 512)
    """Generations whose population and best individual are saved [paper]."""
    seed: int = 0
    """Seed of every random draw of the run [chosen]."""

    def to_dict(self) -> dict[str, Any]:
        return dataclasses.asdict(self)


NAVIGATION_WORLD_FIELDS = ("start_power_v", "dock_heading_tol_deg")
"""``NavigationSettings`` fields that, when set, replace the ``WorldSettings`` field of the same
name in every run of the stage (``NavigationSettings.world``); None keeps the world's."""


@dataclass(frozen=True)
class NavigationSettings:
    """How the navigation stage picks its final section (SPEC §6: how the section is chosen
    among populations and saved generations is [chosen]).

    SPEC §6 as first written compares each population's final best on the 100 test starts
    by mean run fitness. Here the candidates are compared on their own, larger set of fresh
    starts (never the test starts, so the reported docking rate stays an unbiased estimate),
    and by docking rate first: a section that docks from every start beats one that docks
    from half, whatever their fitness. docs/evolution.md has the measurements behind the
    defaults.
    """

    candidates: str = "saved"
    """``"saved"``: the best individual of every saved generation of every population;
    ``"final"``: each population's final best only [chosen]."""
    criterion: str = "dock_rate"
    """``"dock_rate"``: highest docking rate on the selection starts, ties broken by mean run
    fitness; ``"fitness"``: highest mean run fitness (SPEC §6 as first written) [chosen]."""
    selection_starts: int = 1000
    """Fresh navigation start poses (drawn from their own seed) on which the candidates are
    compared [chosen]."""
    first_start_radius: float = 100.0
    """Start region of the training runs, a curriculum: at generation 0 they start within
    this distance of ``WorldSettings.dock_point`` (units), inside the SPEC §6 region [chosen]."""
    start_ramp_fraction: float = 0.25
    """The training start region grows linearly from ``first_start_radius`` to the whole
    SPEC §6 region over this fraction of the stage's generations (256 of 1024), then stays
    whole; 0 = the whole region from generation 0 (SPEC §6 as first written). The test and
    selection starts always cover the whole region [chosen]."""
    start_power_v: float | None = None
    """Store (V) at the start of every run of the stage (training, selection, test); None:
    ``WorldSettings.start_power_v``, 4.0 V as SPEC §6 writes [chosen]. The coverage section hands
    off only once the low-power sensor is on (store < ``low_power_v``), so every run of the
    section in use starts with it on, while a SPEC §6 run starts at exactly 4.0 V with it off
    until the first paid cycle: a section whose first low-power test branches on that bit can
    dock from 4.0 V and fail from every hand-off. A value below ``low_power_v`` (3.99) trains
    and chooses the section as it will run (docs/envelope.md)."""
    dock_heading_tol_deg: float | None = None
    """Docking tolerance of every run of the stage (training, selection, test): the heading
    within ± this of ``WorldSettings.dock_heading_deg``, degrees; None:
    ``WorldSettings.dock_heading_tol_deg``, 30° as SPEC §3 writes [chosen]. Physics' robot loses
    5–20° of a rotation in place against the station's face, so a section that reaches the
    docking box a few degrees inside the band in the table world can turn short of it in
    MuJoCo and push there until its store is empty. A stricter band (20°) trains sections that
    end their approach squarer to the station; the section then runs in the world of SPEC §3,
    where the summary reports it too (``spec_dock_success``; docs/envelope.md)."""

    start_poses: tuple[tuple[float, float, float], ...] | None = None
    """Start poses (x, y arena units, heading degrees) every run of the stage starts from
    (training, selection, test), drawn with replacement; None: SPEC §6's region, the training
    runs in the growing region above [chosen]. A coverage run's hand-offs (``handoffs.csv``,
    ``servobot evolve navigation --nav-starts``) train and choose the section where the
    coverage section will hand it control: a SPEC §6 start is a uniform pose at full store,
    while hand-offs gather where coverage excursions turn home, and what decides a coverage
    run is the rate over them (seed 1's p13g0896 docks 97.8 % of one coverage section's
    hand-offs on the shipped robot's table, 93.2 % on the heavy robot's; docs/robustness.md).
    The test starts come from the same poses, so the stage's docking rate is a rate over them."""

    def __post_init__(self) -> None:
        if self.candidates not in ("saved", "final"):
            raise SettingsError(f"candidates must be 'saved' or 'final', got {self.candidates!r}")
        if self.criterion not in ("dock_rate", "fitness"):
            raise SettingsError(
                f"criterion must be 'dock_rate' or 'fitness', got {self.criterion!r}"
            )
        if not isinstance(self.selection_starts, int) or self.selection_starts < 1:
            raise SettingsError(f"selection_starts must be ≥ 1, got {self.selection_starts!r}")
        if not (math.isfinite(self.first_start_radius) and self.first_start_radius > 0.0):
            raise SettingsError(
                f"first_start_radius must be a distance > 0, got {self.first_start_radius!r}"
            )
        ramp = self.start_ramp_fraction
        if not (isinstance(ramp, int | float) and 0.0 <= ramp <= 1.0):
            raise SettingsError(f"start_ramp_fraction must be in [0, 1], got {ramp!r}")
        v = self.start_power_v
        if v is not None and not (is_finite_number(v) and v > 0.0):
            raise SettingsError(f"start_power_v must be a voltage > 0 or None, got {v!r}")
        tol = self.dock_heading_tol_deg
        if tol is not None and not (is_finite_number(tol) and 0.0 < tol <= 180.0):
            raise SettingsError(f"dock_heading_tol_deg must be an angle in (0, 180] degrees or "
                                f"None, got {tol!r}")  # fmt: skip

        poses = self.start_poses
        if poses is not None and not (
            len(poses) > 0
            and all(len(p) == 3 and all(is_finite_number(v) for v in p) for p in poses)
        ):
            raise SettingsError("start_poses must be one or more (x, y, h) poses of finite "
                                "numbers, or None")  # fmt: skip

    def ramp_generations(self, generations: int) -> int:
        """Generations over which the training start region grows in a stage of
        ``generations`` (0: no growth, the whole region throughout)."""
        return round(self.start_ramp_fraction * generations)

    def to_dict(self) -> dict[str, Any]:
        """The fields; ``start_power_v``, ``dock_heading_tol_deg`` and ``start_poses`` only when
        set (folders made before them resume)."""
        doc = dataclasses.asdict(self)
        for name in (*NAVIGATION_WORLD_FIELDS, "start_poses"):
            if doc[name] is None:
                del doc[name]
        return doc

    def world(self, world: WorldSettings) -> WorldSettings:
        """``world`` as the stage's runs see it: its start power and docking tolerance replaced
        by ``start_power_v`` and ``dock_heading_tol_deg`` where set."""
        changes = {name: float(v) for name in NAVIGATION_WORLD_FIELDS
                   if (v := getattr(self, name)) is not None}  # fmt: skip
        return dataclasses.replace(world, **changes) if changes else world


NAVIGATION_STARTS_PER_GENERATION = 40
"""Training starts per navigation generation [chosen: SPEC §6 lets this move from the paper's
10; 40 halves the selection noise of a section's mean fitness, docs/evolution.md]."""


def navigation_ga_settings(**overrides: Any) -> GASettings:
    """GA settings of the navigation stage (SPEC §6): 1024 generations, saves every 128,
    ``NAVIGATION_STARTS_PER_GENERATION`` training starts per generation."""
    base = GASettings(
        generations=1024,
        save_generations=(0, 1, 32, 64) + tuple(range(128, 1025, 128)),
        starts_per_generation=NAVIGATION_STARTS_PER_GENERATION,
    )
    return dataclasses.replace(base, **overrides)


ENVELOPE_COVERAGE_STARTS_PER_GENERATION = 30
"""Training starts per coverage generation in an envelope of variation other than ``none``
[chosen: each start's score is then a draw of a varied world, so 10 starts select on noise;
30 raised Figure 9 from 43.7 to 52.5 % (seed 0) and 38.7 to 40.7 % (seed 1) and the held-out
physics world by 12.2 and 2.9 pp, docs/envelope.md]."""


def coverage_ga_settings(*, in_envelope: bool = False, **overrides: Any) -> GASettings:
    """GA settings of the coverage stage (SPEC §5): the paper's, with
    ``ENVELOPE_COVERAGE_STARTS_PER_GENERATION`` training starts per generation when the stage
    evolves ``in_envelope`` (an envelope other than ``none``)."""
    base = GASettings()
    if in_envelope:
        base = dataclasses.replace(
            base, starts_per_generation=ENVELOPE_COVERAGE_STARTS_PER_GENERATION
        )
    return dataclasses.replace(base, **overrides)


def settings_json(*objs: Any) -> str:
    """Serialise settings dataclasses as one JSON object keyed by class name: each one's
    ``to_dict()`` where it has one (``ColonySettings`` leaves a default field out), else
    every field."""
    return json.dumps(
        {type(o).__name__: o.to_dict() if hasattr(o, "to_dict") else dataclasses.asdict(o)
         for o in objs},
        indent=2,
    )  # fmt: skip


def settings_from_record(
    cls: type, doc: Any, name: str, error: type[Exception] = SettingsError
) -> Any:
    """The ``cls`` settings dataclass of a recorded object (``settings_json``'s, JSON lists
    back into tuples); ``error`` naming ``name`` when ``doc`` is not such an object or has a
    field ``cls`` lacks or refuses."""
    if not isinstance(doc, dict):
        raise error(f"{name}: no {cls.__name__} object")
    known = {f.name for f in dataclasses.fields(cls)}
    unknown = sorted(set(doc) - known)
    if unknown:
        raise error(f"{name}: {cls.__name__} has unknown fields {unknown}")

    def tuples(v: Any) -> Any:
        return tuple(tuples(x) for x in v) if isinstance(v, list) else v

    try:
        return cls(**{k: tuples(v) for k, v in doc.items()})
    except (TypeError, ValueError) as exc:
        raise error(f"{name}: {cls.__name__}: {exc}") from exc


__all__ = [
    "ALIVE_FITNESSES",
    "BLOCKING_RULES",
    "COLONY_FITNESSES",
    "COLONY_SECTIONS",
    "DOCK_FITNESSES",
    "SettingsError",
    "ColonySettings",
    "GASettings",
    "NAVIGATION_STARTS_PER_GENERATION",
    "NavigationSettings",
    "WorldSettings",
    "navigation_ga_settings",
    "settings_from_record",
    "settings_json",
    "with_table_power",
]
