"""Validation of an evolved controller: each start pose in the table world and in physics.

``validate(bits, starts, ...)`` runs the 16-gene chromosome with the reference interpreter
(``evolve.interpreter.run``, coverage mode, SPEC §5: 4.0 V, gene 0, 600 steps) from every
start pose twice — in the table world (``evolve.world.TableWorld``) and in the MuJoCo colony
(``servo_mj.world.physics_world.PhysicsWorld``) — and returns a report::

    {"runs": [{"index", "start": {"x", "y", "h"},
               "table":   {"squares", "inner_squares", "docks", "steps", "end": {"code", "name"},
                           "final_pose", "wall_s"},
               "physics": {... same ...} | None,
               "error":   None | "PhysicsError: ...",
               "physics_partial": {"steps", "squares", "pose"} (only with an error)}, ...],
     "summary": {...}, "settings": {...}, "chromosome": "...", "table": {...}}

The summary gives, per world, mean squares and inner squares, inner % of the 64 inner squares,
docks and docking success (share of runs with at least one dock), end reasons, and the
table-vs-physics gap in percentage points over the runs whose physics finished. Runs are
independent and go to an executor (``infra.executors``); a run whose physics blows up keeps
its table record and an ``error``, and the other runs are unaffected.

With ``out_dir``: ``report.json``, ``report.md`` and ``tracks.npz`` (per run ``table_{k}`` and
``physics_{k}``: (steps + 1, 3) poses x, y cm, heading deg) are written atomically; with
``rrd=True`` each run also writes ``run{k}.rrd`` (``servobot.recording``). Before any run,
the sizes are checked (``validation_need``) and ``out_dir`` is taken as a run folder
(``infra.rundir``: a lock; a folder holding a validation with other inputs is refused unless
``force``, which deletes only ``VALIDATION_FILES``). An interrupted run's recording is
discarded, never left truncated at its final path.

``validate`` is the one path of every validation: what runs at each start is its ``Kind``,
one robot (``LONE``) or a colony of R robots sharing the station (SPEC §7,
``servobot.validation.colony.colony_kind``); the checks, the run folder, the executor, the
report and its files are the same code for both.
"""

from __future__ import annotations

import contextlib
import dataclasses
import os
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from evolve import geometry
from evolve.codec import FULL_GENES, SECTION_GENES, check_bits, format_chromosome
from evolve.handoff import HandoffWatcher, handoff_record
from evolve.interpreter import END_NAMES, run
from evolve.settings import ColonySettings, WorldSettings
from evolve.starts import MAX_HEADING_DEG, navigation_starts_where
from evolve.table import GaitTable, GaitTableError, load_table, validate_table
from evolve.world import TableWorld
from infra.bounds import LIMITS, Need, check_int, check_need, check_workers
from infra.errors import InputError
from infra.executors import Executor, Failed, make_executor
from infra.io import check_free_space
from infra.rundir import run_folder
from servo_mj.robot.model import ModelFile, ModelFileError, model_label, model_sha256
from servo_mj.world.arena import ArenaSettings, default_robot, overlaps_station
from servobot.validation.report import summarise, write_report

MODE = "coverage"
"""A full 16-gene controller is validated in coverage mode (SPEC §5)."""
NAVIGATION_MODE = "navigation"
"""An 8-gene navigation section is validated in navigation mode (SPEC §6): from gene 0 until
it docks, ``WorldSettings.navigation_steps`` steps at most."""
VALIDATION_FILES = ("report.json", "report.md", "tracks.npz", "tracks*.png", "run*.rrd")
"""What a validation writes into its folder besides ``settings.json``."""
RRD_BYTES_PER_STEP = 25_000
"""Disk space a recording takes per robot step, bytes, rounded up [measured: a 600-step
validation recording 11.5 MB (0.8 MB + 17.5 kB per step), colony runs ≈ 25 kB per robot
step]."""
RUN_BYTES = 16384
"""Memory of one run's job and record, bytes [estimate; a 600-step coverage run's record with
its ≈ 12 hand-offs in both worlds measured 8.5 kB in Python objects, 2.9 kB without them];
tracks are counted apart."""


class ValidationError(InputError, ValueError):
    """Bad input to ``validate``: the message names the problem."""


@dataclass(frozen=True)
class Job:
    """Everything one worker needs for one start (picklable plain data): one robot's
    (``StartJob``) or a colony's (``servobot.validation.colony.ColonyJob``)."""

    index: int
    bits: np.ndarray
    start: Any
    """The start pose (x, y cm; heading deg); a colony's: one per robot."""
    table: np.ndarray
    world: WorldSettings
    arena: ArenaSettings
    physics: Any
    max_steps: int | None
    rrd_path: str | None
    seed: int = 0
    """Seed of the run's servo-noise generators: ``default_rng((seed, index))`` for one robot;
    a colony's: ``servo_mj.world.physics_colony.robot_rngs(seed, index, R)``."""
    model: str | None = None
    """The robot's model file (None = the shipped ServoBot)."""
    table_source: str = "array"
    """Where ``table`` came from (``GaitTable.source``), for the recording's properties."""
    command: str | None = None
    """The command line that asked for the run, for the recording (None: ``sys.argv``)."""


@dataclass(frozen=True)
class StartJob(Job):
    """One robot's start pose."""

    mode: str = MODE
    """``MODE`` (a 16-gene chromosome) or ``NAVIGATION_MODE`` (an 8-gene section)."""
    power: float | None = None
    """Power at the start, volts (None = ``WorldSettings.start_power_v``)."""


def check_start(
    start: Any,
    world: WorldSettings,
    arena: ArenaSettings | None = None,
    *,
    name: str = "start",
) -> tuple[float, ...]:
    """Return a start pose as (x, y, h) floats, or raise ``ValidationError`` naming the problem
    (outside the arena, in the kill zone, overlapping the station block)."""
    try:
        x, y, h = (float(v) for v in start)
    except (TypeError, ValueError) as exc:
        msg = f"{name}: a start pose is three numbers X Y H, got {start!r}"
        raise ValidationError(msg) from exc
    if not all(np.isfinite([x, y, h])):
        raise ValidationError(f"{name}: start pose ({x}, {y}, {h}) is not finite")
    if abs(h) > MAX_HEADING_DEG:
        raise ValidationError(
            f"{name}: heading {h:g} is beyond ±{MAX_HEADING_DEG:g}° (a heading is in degrees, 0 "
            "= north, clockwise)"
        )
    size = world.arena_size
    if not (0.0 <= x <= size and 0.0 <= y <= size):
        raise ValidationError(
            f"{name}: start ({x:g}, {y:g}) lies outside the {size:g} x {size:g} arena"
        )
    if geometry.in_kill_zone(x, y, world):
        raise ValidationError(
            f"{name}: start ({x:g}, {y:g}) lies in the kill zone "
            f"(within {world.kill_margin:g} units of a wall)"
        )
    arena = arena or ArenaSettings()
    if overlaps_station(x, y, world, arena):
        raise ValidationError(
            f"{name}: start ({x:g}, {y:g}) overlaps the power-station block (robot centre "
            f"within {arena.robot_clearance_cm:g} units of it)"
        )
    return x, y, h % 360.0


def clear_navigation_starts(
    rng: np.random.Generator, n: int, world: WorldSettings, arena: ArenaSettings | None = None
) -> np.ndarray:
    """(n, 3) navigation starts (SPEC §6 region, ``evolve.starts.navigation_starts``) that the
    physics arena can hold: poses overlapping the station block are drawn again."""
    return navigation_starts_where(rng, n, world, lambda p: _holdable(p, world, arena))


def _holdable(poses: np.ndarray, world: WorldSettings, arena: ArenaSettings | None) -> np.ndarray:
    """Which poses (N, 3) the physics arena can hold: not overlapping the station block."""
    arena = arena or ArenaSettings()
    return np.array([not overlaps_station(x, y, world, arena) for x, y, _ in poses], bool)


def sample_poses(
    poses: np.ndarray, powers: np.ndarray | None, n: int | None, rng: np.random.Generator,
    world: WorldSettings, arena: ArenaSettings | None = None,
) -> tuple[np.ndarray, np.ndarray | None]:  # fmt: skip
    """The poses (and their powers) that the physics arena can hold — those overlapping the
    station block are left out — all of them (``n`` None) or ``n`` drawn without replacement,
    in file order; ``ValidationError`` when fewer than ``n`` (or none) remain."""
    keep = _holdable(poses, world, arena)
    poses, powers = poses[keep], None if powers is None else powers[keep]
    if not len(poses) or (n is not None and n > len(poses)):
        raise ValidationError(
            f"{n or 'any'} poses asked, {len(poses)} clear of the station block available"
        )
    if n is not None:
        pick = np.sort(rng.choice(len(poses), n, replace=False))
        poses, powers = poses[pick], None if powers is None else powers[pick]
    return poses, powers


def check_chromosome(bits: Any, *, sections: bool = False, robots: int | None = None) -> np.ndarray:
    """A (16, 30) chromosome as uint8 — or, with ``sections``, an (8, 30) navigation section
    too, or with ``robots`` R a team (R, 16, 30), robot r carrying row r — else
    ``ValidationError``."""
    if robots is not None and np.ndim(bits) == 3:
        if len(bits) != robots:
            raise ValidationError(
                f"a team of {len(bits)} chromosomes for a colony of {robots}: give one "
                "chromosome, or one per robot"
            )
        return np.stack([check_chromosome(b) for b in bits])
    try:
        arr = check_bits(bits)
    except ValueError as exc:
        raise ValidationError(str(exc)) from exc
    if arr.shape[0] == SECTION_GENES and sections:
        return arr
    if arr.shape[0] != FULL_GENES:
        also = " or an 8-gene navigation section" if sections else ""
        raise ValidationError(
            f"validation needs a full 16-gene chromosome (coverage genes 0-7 + navigation "
            f"genes 8-15){also}, got {arr.shape[0]} genes"
        )
    return arr


def mode_of(bits: np.ndarray) -> str:
    """The mode a checked controller is validated in: ``NAVIGATION_MODE`` for an 8-gene
    section, else ``MODE``."""
    return NAVIGATION_MODE if np.ndim(bits) == 2 and len(bits) == SECTION_GENES else MODE


def _find_sha(meta: Any) -> str | None:
    """The model sha256 recorded anywhere in a calibration file's metadata, if any."""
    if isinstance(meta, dict):
        for k, v in meta.items():
            if "sha256" in str(k).lower() and isinstance(v, str):
                return v
        for v in meta.values():
            found = _find_sha(v)
            if found:
                return found
    return None


def load_checked_table(spec: str, model: ModelFile = None) -> tuple[GaitTable, str | None]:
    """Load ``paper`` or a calibration file; refuse a file made for another robot model.

    ``model``: the robot the physics runs (None = the shipped ServoBot, else a model file).
    Returns the table and a warning (or None). Raises ``ValidationError`` naming both models
    and their hashes when the file's model sha256 differs from ``model``'s.
    """
    try:
        table = load_table(spec)
        current = model_sha256(model)
    except (GaitTableError, ModelFileError) as exc:
        raise ValidationError(f"gait table: {exc}") from exc
    if spec == "paper":
        return table, None
    recorded = _find_sha(table.meta)
    if recorded is None:
        return table, f"warning: {spec} records no model sha256; cannot check it fits this robot"
    if recorded != current:
        was = table.meta.get("model", "an unnamed robot model")
        raise ValidationError(
            f"gait table {spec} was calibrated on another robot model: on {was} (sha256 "
            f"{recorded}), but the physics runs {model_label(model)} (sha256 {current}); "
            f"calibrate this model (servobot calibrate --model ...) or pass the model the "
            f"table was made for"
        )
    return table, None


def result_record(res: Any) -> dict[str, Any]:
    """One robot's run in one world (an ``evolve.interpreter.RunResult``): squares, inner
    squares, docks, steps, how it ended and where."""
    return {
        "squares": int(res.squares),
        "inner_squares": int(res.inner_squares),
        "docks": int(res.docks),
        "steps": int(res.steps),
        "end": {"code": int(res.end), "name": END_NAMES[int(res.end)]},
        "final_pose": [round(float(v), 4) for v in res.final_pose],
    }


def handoff_watcher(job: StartJob) -> HandoffWatcher | None:
    """A hand-off watcher for a coverage run of ``job`` (``evolve.handoff``), None for a
    navigation run (it has no hand-offs)."""
    if job.mode == NAVIGATION_MODE:
        return None
    power = job.world.start_power_v if job.power is None else job.power
    return HandoffWatcher(tuple(map(float, job.start)), power)


def fan_out(*handlers: Callable[[Any], None] | None) -> Callable[[Any], None] | None:
    """One ``on_event`` calling each given handler in order (None for a handler left out), or
    None when none is given."""
    given = [f for f in handlers if f is not None]
    if not given:
        return None

    def on_event(e: Any) -> None:
        for f in given:
            f(e)

    return on_event


def run_record(res: Any, watch: HandoffWatcher | None, t0: float) -> dict[str, Any]:
    """``result_record`` of a run begun at ``perf_counter()`` ``t0``, with its wall time and,
    for a coverage run, ``handoffs``: each switch to navigation (``handoff_record``)."""
    out = result_record(res) | {"wall_s": round(time.perf_counter() - t0, 4)}
    if watch is not None:
        out["handoffs"] = [handoff_record(h) for h in watch.finish(res.end)]
    return out


def physics_world(job: StartJob, on_frame: Callable[..., None] | None = None) -> Any:
    """The physics world of one run: the robot of ``job.model`` placed at ``job.start`` in the
    arena, its servo noise drawn from ``default_rng((job.seed, job.index))``."""
    from servo_mj.world.physics_world import PhysicsWorld

    x, y, h = job.start
    return PhysicsWorld(
        x, y, h, world=job.world, arena=job.arena, physics=job.physics,
        robot=None if job.model is None else default_robot(job.model),
        rng=np.random.default_rng((job.seed, job.index)), on_frame=on_frame,
    )  # fmt: skip


def run_start(job: StartJob, make_world: Callable[[], Any] | None = None) -> dict[str, Any]:
    """Run one start pose in both worlds (worker function; catches physics failures).
    ``make_world()``, when given, makes the physics world (a ``SharedView``; no recording)."""
    x, y, h = job.start
    rec = None
    if job.rrd_path is not None and make_world is None:
        from servobot.recording import RunRecorder

        rec = RunRecorder.for_validation(job)

    def table_run() -> tuple[dict[str, Any], np.ndarray]:
        t0 = time.perf_counter()
        table_world = TableWorld(job.table, x, y, h, job.world)
        watch = handoff_watcher(job)
        res = run(
            job.bits, table_world, mode=job.mode, settings=job.world, start_power=job.power,
            max_steps=job.max_steps,
            on_event=fan_out(watch, None if rec is None else rec.table_event),
        )  # fmt: skip
        return run_record(res, watch, t0), res.track

    def physics_run(last: dict[str, Any]) -> tuple[dict[str, Any], np.ndarray]:
        t0 = time.perf_counter()
        if make_world is not None:
            pw = make_world()
        else:
            pw = physics_world(job, on_frame=None if rec is None else rec.on_frame)
        if rec is not None:
            rec.attach_physics(pw)

        watch = handoff_watcher(job)

        def progress(e: Any) -> None:
            last.update(steps=e.step, squares=e.squares, pose=[float(v) for v in e.pose])

        res = run(
            job.bits, pw, mode=job.mode, settings=job.world, start_power=job.power,
            max_steps=job.max_steps,
            on_event=fan_out(progress, watch, None if rec is None else rec.physics_event),
        )  # fmt: skip
        return run_record(res, watch, t0), res.track

    out = {"index": job.index, "start": start_record(job.start)}
    if job.power is not None:
        out["power"] = job.power
    last = {"steps": 0, "squares": 0, "pose": [x, y, h]}
    return run_both_worlds(out, rec, table_run, physics_run, last)


def run_shared_starts(jobs: tuple[StartJob, ...]) -> list[dict[str, Any]]:
    """``run_start`` of each job, all from one start with one servo-noise seed in one physics
    world (``shares_physics``), their physics run through one ``PhysicsTree``: the cycles two
    runs share are simulated once; every record is the one ``run_start`` gives (worker
    function)."""
    from servo_mj.world.shared_physics import PhysicsTree

    tree = PhysicsTree(physics_world(jobs[0]))
    return [run_start(job, tree.view) for job in jobs]


def shares_physics(job: Any) -> tuple | None:
    """What a lone start job's physics depends on besides its gaits (start, noise seed and
    index, world, arena, physics settings, model, mode, power, steps): jobs with equal keys
    can share a ``PhysicsTree``. None for a job that cannot (a colony's, a recorded run)."""
    if not isinstance(job, StartJob) or job.rrd_path is not None:
        return None
    return (job.index, tuple(map(float, job.start)), job.seed, repr(job.world), repr(job.arena),
            repr(job.physics), job.model, job.mode, job.power, job.max_steps)  # fmt: skip


def run_both_worlds(
    out: dict[str, Any],
    rec: Any,
    table_run: Callable[[], tuple[dict[str, Any], np.ndarray]],
    physics_run: Callable[[dict[str, Any]], tuple[dict[str, Any], np.ndarray]],
    last: dict[str, Any],
) -> dict[str, Any]:
    """One run's record ``out`` completed by both worlds: ``table_run()`` and
    ``physics_run(last)`` each give (record, track); a physics failure becomes ``error`` and
    ``physics_partial`` (``last``, which ``physics_run`` keeps up to date). ``rec`` (a
    recorder or None) is closed with the record, or discarded when the run is interrupted."""
    out.update(table=None, physics=None, error=None)
    tracks: dict[str, np.ndarray] = {}
    try:
        out["table"], tracks["table"] = table_run()
        t0 = time.perf_counter()
        try:
            out["physics"], tracks["physics"] = physics_run(last)
        except Exception as exc:  # noqa: BLE001 - a physics failure is this run's record
            out["error"] = f"{type(exc).__name__}: {exc}"
            out["physics_partial"] = dict(last, wall_s=round(time.perf_counter() - t0, 4))
            if rec is not None:
                rec.error(out["error"])
    except BaseException:  # interrupted: no recording of a run that did not finish
        if rec is not None:
            rec.close(save=False)
        raise
    if rec is not None:
        rec.close(out)
    out["tracks"] = tracks
    return out


def jsonable(obj: Any) -> Any:
    if dataclasses.is_dataclass(obj) and not isinstance(obj, type):
        return jsonable(dataclasses.asdict(obj))
    if isinstance(obj, dict):
        return {str(k): jsonable(v) for k, v in obj.items()}
    if isinstance(obj, list | tuple):
        return [jsonable(v) for v in obj]
    if isinstance(obj, np.ndarray):
        return obj.tolist()
    if isinstance(obj, np.generic):
        return obj.item()
    if isinstance(obj, Path):
        return str(obj)
    return obj


def check_starts(
    starts: Any, world: WorldSettings, arena: ArenaSettings
) -> list[tuple[float, ...]]:
    """An (N, 3) array of start poses, each checked by ``check_start``."""
    arr = np.asarray(starts, dtype=float)
    if arr.ndim != 2 or arr.shape[1] != 3 or len(arr) == 0:
        raise ValidationError(f"starts must be an (N, 3) array of x, y, h, got {arr.shape}")
    return [check_start(s, world, arena, name=f"start {k}") for k, s in enumerate(arr)]


def validation_need(starts: int, steps: int, workers: int | None, rrd: bool) -> tuple[Need, int]:
    """(memory and optimistic wall time, disk bytes of the recordings) of ``starts`` runs of
    ``steps`` steps in both worlds with ``workers`` processes (None = one per core)."""
    procs = min(starts, workers or os.cpu_count() or 1)
    memory = starts * (RUN_BYTES + 2 * (steps + 1) * 24) + procs * LIMITS.physics_process_bytes
    wall = starts * steps / (LIMITS.physics_cycles_per_s * procs)
    return Need(memory, wall), (starts * (steps + 1) * RRD_BYTES_PER_STEP if rrd else 0)


def check_sizes(n: int, steps: int, workers: int | None, rrd: bool, seed: int) -> int:
    """Seed, worker count, memory and time, before any run; returns the recordings' bytes."""
    check_int(seed, "seed", lo=0)
    check_workers(workers, "workers")
    need, disk = validation_need(n, steps, workers, rrd)
    check_need(need, f"{n} starts × {steps} steps")
    return disk


def start_record(start: Any) -> Any:
    """A start pose (x, y, h) as ``{"x", "y", "h"}``; a colony's poses as a list of those."""
    if np.ndim(start) == 2:
        return [start_record(p) for p in start]
    x, y, h = start
    return {"x": x, "y": y, "h": h}


Record = dict[str, Any]
Summary = Callable[[list[Record], float], dict[str, Any]]
"""Summary of a validation's runs, given the runs and their wall time."""
Writer = Callable[[Path, dict[str, Any], dict[str, np.ndarray]], None]
"""Writes a finished validation's files: (folder, report, tracks by ``{world}_{index}``)."""


def _apply(work_and_job: tuple[Callable[[Any], Record], Any]) -> Record:
    """``work(job)``: one item of a batch that mixes validations (module level: picklable)."""
    work, job = work_and_job
    return work(job)


def _failed_record(job: Any, message: str) -> Record:
    """The record of a run whose worker failed: its start and the error, no results."""
    return {"index": job.index, "start": start_record(job.start), "table": None,
            "physics": None, "error": message, "tracks": {}}  # fmt: skip


def validation_settings(
    world: WorldSettings, arena: ArenaSettings, physics: Any, steps: int, seed: int,
    model: ModelFile, mode: str = MODE,
) -> dict[str, Any]:  # fmt: skip
    """The settings a validation's results depend on (``settings.json``, the report)."""
    return {
        "WorldSettings": jsonable(world),
        "ArenaSettings": jsonable(arena),
        "PhysicsSettings": jsonable(physics) if physics is not None else "default",
        "max_steps": steps,
        "seed": seed,
        "mode": mode,
        "model": model_label(model),
        "model_sha256": model_sha256(model),
    }


def report_head(
    arr: np.ndarray, table: Any, values: np.ndarray, settings: dict[str, Any],
    meta: dict[str, Any] | None,
) -> dict[str, Any]:  # fmt: skip
    """What a report holds besides its runs and summary."""
    return {
        "chromosome": format_chromosome(arr),
        "table": {
            "source": getattr(table, "source", "array"),
            "values": values.tolist(),
            "meta": jsonable(getattr(table, "meta", {})),
        },
        "settings": settings,
        "meta": jsonable(meta or {}),
    }


@dataclass(frozen=True)
class Plan:
    """A checked validation, ready to run: its jobs and how its report is made and written
    (``plan_validation``; ``execute`` runs one or several plans as one batch)."""

    jobs: list[Any]
    work: Callable[[Any], Record]
    """Runs one job in both worlds and gives its record (``Kind.work``)."""
    head: dict[str, Any]
    """The report's fields besides its runs and summary."""
    summary: Summary
    write: Writer
    out: Path | None
    """The run folder (None: nothing written)."""
    record: dict[str, Any]
    """The run folder's ownership record."""
    disk: int
    """Bytes of the recordings."""
    force: bool
    done: tuple[Record, ...] = ()
    """Records of runs taken from an earlier validation (tracks included): no job runs them,
    the report holds them beside the new ones, in start order."""


SHARE_GROUP_MAX = 12
"""[chosen] At most this many runs share one ``PhysicsTree`` (one executor item): a group's
records come back when its last run ends, so the cap bounds the work an interruption loses
and keeps items for many workers; consecutive plans (a sample's genomes, population by
population) fill a group, where most cycles are shared."""


def _batch(
    plans: list[Plan], share: bool
) -> tuple[list[tuple[Callable[[Any], Any], Any]], list[list[tuple[int, int]]]]:
    """The executor's items for ``plans`` and, for each item, the (plan, job) pairs it runs:
    one job per item, or with ``share`` each group of up to ``SHARE_GROUP_MAX`` lone jobs
    whose physics can share a ``PhysicsTree`` (``shares_physics``) as one
    ``run_shared_starts`` item, start by start (every plan's first starts finish first)."""
    owners: list[list[tuple[int, int]]] = []
    filling: dict[tuple, list[tuple[int, int]]] = {}  # the group each key is filling
    for i, plan in enumerate(plans):
        for k, job in enumerate(plan.jobs):
            key = shares_physics(job) if share and plan.work is run_start else None
            group = None if key is None else filling.get(key)
            if group is not None and len(group) < SHARE_GROUP_MAX:
                group.append((i, k))
                continue
            owners.append([(i, k)])
            if key is not None:
                filling[key] = owners[-1]
    if share:
        owners.sort(key=lambda o: plans[o[0][0]].jobs[o[0][1]].index)
    items = [
        (plans[o[0][0]].work, plans[o[0][0]].jobs[o[0][1]]) if len(o) == 1
        else (run_shared_starts, tuple(plans[i].jobs[k] for i, k in o))
        for o in owners
    ]  # fmt: skip
    return items, owners


def execute(
    plans: list[Plan],
    ex: Executor,
    on_run: Callable[[Record], None] | None = None,
    *,
    share: bool = False,
    on_record: Callable[[int, Record], None] | None = None,
) -> list[dict[str, Any]]:
    """Run every plan's jobs as one batch on ``ex`` and return each plan's report, in order.

    Every plan's run folder is taken (and its free disk space checked) before any run, so a
    refused folder costs no work; a plan's report is written as soon as its last run ends
    (an interrupted batch keeps the finished plans). One batch keeps every worker busy where
    one batch per plan would wait for each plan's slowest run and start a pool per plan.
    A plan's summary ``wall_s`` is the time from the batch's start to its last run's end.
    ``share``: lone runs of different plans from one start in one physics world go to one
    worker together and simulate the gait cycles they share once (``run_shared_starts``; the
    same records). ``on_record(plan index, record)`` is called with each run's record, tracks
    included, before its plan's report is made (e.g. to keep it on disk).
    """
    items, owners = _batch(plans, share)
    runs: list[list[Record]] = [[{} for _ in plan.jobs] for plan in plans]
    left = [len(plan.jobs) for plan in plans]
    reports: list[dict[str, Any]] = [{} for _ in plans]
    with contextlib.ExitStack() as folders:
        for plan in plans:
            if plan.out is not None:
                folders.enter_context(run_folder(plan.out, plan.record, owned=VALIDATION_FILES,
                                                 resumable=False, force=plan.force,
                                                 command="validate"))  # fmt: skip
                check_free_space(plan.out, plan.disk, what="the recordings")
        t0 = time.perf_counter()

        def finish(i: int) -> None:
            plan = plans[i]
            done = sorted([*plan.done, *runs[i]], key=lambda r: r["index"])
            tracks = {f"{w}_{r['index']}": t
                      for r in done for w, t in r.pop("tracks", {}).items()}  # fmt: skip
            reports[i] = plan.head | {
                "runs": done, "summary": plan.summary(done, time.perf_counter() - t0)
            }
            if plan.out is not None:
                plan.write(plan.out, reports[i], tracks)

        for i, plan in enumerate(plans):
            if not plan.jobs:
                finish(i)
        with contextlib.closing(ex.imap(_apply, items)) as outcomes:  # stops workers on Ctrl-C
            for n, outcome in outcomes:
                if isinstance(outcome, Failed):
                    recs = [_failed_record(plans[i].jobs[k], outcome.message)
                            for i, k in owners[n]]  # fmt: skip
                else:  # a group's records, or one run's
                    recs = outcome.value if isinstance(outcome.value, list) else [outcome.value]
                for (i, k), rec in zip(owners[n], recs, strict=True):
                    runs[i][k] = rec
                    if on_record is not None:
                        on_record(i, rec)
                    if on_run is not None:
                        on_run(rec)
                    left[i] -= 1
                    if left[i] == 0:
                        finish(i)
    return reports


@dataclass(frozen=True)
class Kind:
    """What runs at each start of a validation: one robot (``LONE``) or a colony of R robots
    sharing the station (``servobot.validation.colony.colony_kind``). Everything else is one
    path, ``validate``: the checks, the run folder, the executor, the report and its files."""

    job: Callable[..., Job]
    """One start's job: ``StartJob`` or ``ColonyJob``."""
    work: Callable[[Any], Record]
    """Runs one job in both worlds and gives its record: ``run_start``, ``run_colony_start``."""
    check_starts: Callable[[Any, WorldSettings, ArenaSettings], list[Any]]
    """The checked start poses: (N, 3) for one robot, (N, R, 3) for a colony."""
    summarise: Callable[[list[Record], WorldSettings, float], dict[str, Any]]
    """The report's summary of the runs, given their wall time."""
    write: Callable[[Path, dict[str, Any], dict[str, np.ndarray], WorldSettings], None]
    """Writes the report's files into the run folder."""
    colony: ColonySettings | None = None
    """The colony; None: one robot, which may be an 8-gene navigation section."""


LONE = Kind(
    StartJob, run_start, check_starts, summarise,
    lambda out, report, tracks, _world: write_report(out, report, tracks),
)  # fmt: skip
"""One robot at each start."""


def plan_validation(
    bits: np.ndarray,
    starts: np.ndarray,
    *,
    table: Any,
    world: WorldSettings | None = None,
    physics: Any = None,
    arena: ArenaSettings | None = None,
    out_dir: str | Path | None = None,
    rrd: bool = False,
    workers: int | None = None,
    max_steps: int | None = None,
    seed: int = 0,
    model: ModelFile = None,
    meta: dict[str, Any] | None = None,
    force: bool = False,
    powers: Any = None,
    kind: Kind = LONE,
    done: Sequence[Record] = (),
) -> Plan:
    """Check a validation of ``bits`` (16, 30) from every start (N, 3: x, y cm; h deg) in the
    table and physics, and make its jobs (``validate`` runs it; ``execute`` runs plans). A
    colony's ``bits`` may be a team (R, 16, 30): robot r carries row r.

    ``bits`` may also be an (8, 30) navigation section: it then runs in navigation mode
    (SPEC §6: from gene 0 until it docks, ``world.navigation_steps`` steps by default), and
    ``powers`` (N volts, default ``world.start_power_v``) sets each start's power, e.g. the
    power at a coverage run's hand-off (``evolve.handoff``).

    ``table`` is a (16, 3) array or a ``GaitTable``; ``physics`` a ``PhysicsSettings`` (None =
    default; with ``servo_noise_rad`` > 0, run k draws its noise from
    ``default_rng((seed, k))``). ``workers``: the pool size the memory check counts with
    (None: the plan goes to an executor). ``model``: the robot in physics (None = the shipped
    ServoBot, else a model file such as a ``servobot variant``; check the table against it
    with ``load_checked_table``). ``kind``: what runs at each start
    (``servobot.validation.colony.validate_colony`` passes a colony's; then ``starts`` is
    (N, R, 3), ``max_steps`` bounds each robot's own steps and ``powers`` is refused). The
    report is written into ``out_dir`` when given. ``done``: records of runs an earlier
    validation of the same chromosome, table and settings finished (``index``, ``start`` and
    ``tracks`` as ``execute`` gives them), e.g. the first N of a validation grown to more
    starts; their starts run no job and the report holds them as they are. Raises
    ``infra.errors.InputError`` subclasses (``ValidationError``, ``BoundsError``,
    ``RunDirError``, ...) on bad input, before any run (the run folder is taken by
    ``execute``).
    """
    world = world or WorldSettings()
    arena = arena or ArenaSettings()
    colony = kind.colony
    arr = check_chromosome(bits, sections=colony is None, robots=colony and colony.robots)
    mode = mode_of(arr)
    values = validate_table(getattr(table, "values", table))
    poses = kind.check_starts(starts, world, arena)
    if colony is not None and powers is not None:
        raise ValidationError(
            "powers: a colony's robots start on world.start_power_v (robot i on it + "
            "i × ColonySettings.start_power_spread, capped at world.charged_power_v)"
        )
    volts = check_powers(powers, len(poses), world)
    steps, out, rrd = check_run_options(max_steps, model, world, out_dir, rrd, mode)
    robots = 1 if colony is None else colony.robots
    disk = check_sizes(len(poses), steps * robots, workers, rrd, seed)
    settings = validation_settings(world, arena, physics, steps, seed, model, mode)
    if colony is not None:
        settings["ColonySettings"] = jsonable(colony.to_dict())  # blocking: only if not cancel
    common = {"bits": arr, "table": values, "world": world, "arena": arena, "physics": physics,
              "max_steps": max_steps, "seed": seed,
              "model": None if model is None else str(model),
              "table_source": getattr(table, "source", "array"),
              "command": (meta or {}).get("command")}  # fmt: skip

    def job(k: int, start: Any) -> Job:
        own = {"mode": mode, "power": volts[k]} if colony is None else {"colony": colony}
        rrd_path = str(out / f"run{k}.rrd") if rrd and out else None
        return kind.job(index=k, start=start, rrd_path=rrd_path, **common, **own)

    kept = _check_done(done, poses)
    jobs = [job(k, p) for k, p in enumerate(poses) if k not in kept]
    head = report_head(arr, table, values, settings, meta)
    record = {"chromosome": head["chromosome"], "table": head["table"]["values"],
              "starts": jsonable(poses), "settings": settings, "rrd": rrd}  # fmt: skip
    if powers is not None:
        record["powers"] = volts
    return Plan(
        jobs, kind.work, head=head,
        summary=lambda runs, wall: kind.summarise(runs, world, wall),
        write=lambda path, report, tracks: kind.write(path, report, tracks, world),
        out=out, record=record, disk=disk, force=force, done=tuple(done),
    )  # fmt: skip


def _check_done(done: Sequence[Record], poses: list[Any]) -> set[int]:
    """The start indices of ``done``, each a finished run of one of ``poses`` (its index in
    range, its start that pose's record), no index twice; else ``ValidationError``."""
    kept: set[int] = set()
    for r in done:
        k = r.get("index")
        if not isinstance(k, int) or not 0 <= k < len(poses) or k in kept:
            raise ValidationError(f"done: run index {k!r} is not one of {len(poses)} starts "
                                  "(or is given twice)")  # fmt: skip
        if r.get("start") != jsonable(start_record(poses[k])):
            raise ValidationError(f"done: run {k} started at {r.get('start')}, not at start "
                                  f"{k} of this validation")  # fmt: skip
        if r.get("physics") is None or r.get("error") is not None:
            raise ValidationError(f"done: run {k} has no physics result; it must run again")
        kept.add(k)
    return kept


def validate(
    bits: np.ndarray,
    starts: np.ndarray,
    *,
    table: Any,
    workers: int | None = None,
    executor: Executor | None = None,
    on_run: Callable[[dict[str, Any]], None] | None = None,
    **options: Any,
) -> dict[str, Any]:
    """Run ``bits`` (16, 30) from every start (N, 3: x, y cm; h deg) in the table and physics
    and return the report (``plan_validation`` says what the options are).

    ``executor`` (``infra.executors.make_executor``) runs the starts; without one, ``workers``
    1 runs them here and otherwise a pool of ``workers`` processes (None = one per core);
    records do not depend on where the runs ran. ``on_run(record)`` is called as each run
    finishes (progress).
    """
    plan = plan_validation(bits, starts, table=table, workers=None if executor else workers,
                           **options)  # fmt: skip
    return execute([plan], executor or make_executor(None, workers), on_run)[0]


def check_powers(powers: Any, n: int, world: WorldSettings) -> list[float | None]:
    """One start power per start (volts; None = ``world.start_power_v``), or
    ``ValidationError``: a power must be finite, at least ``world.empty_power_v`` (the run would
    end at once) and at most ``world.charged_power_v``."""
    if powers is None:
        return [None] * n
    arr = np.asarray(powers, dtype=float).reshape(-1)
    if len(arr) != n:
        raise ValidationError(f"powers: one per start, got {len(arr)} for {n} starts")
    lo, hi = world.empty_power_v, world.charged_power_v
    bad = [k for k, v in enumerate(arr) if not (np.isfinite(v) and lo <= v <= hi)]
    if bad:
        k = bad[0]
        raise ValidationError(f"power of start {k} is {arr[k]} V, not in [{lo}, {hi}] V")
    return [float(v) for v in arr]


def check_run_options(
    max_steps: int | None, model: ModelFile, world: WorldSettings, out_dir: Any, rrd: bool,
    mode: str = MODE,
) -> tuple[int, Path | None, bool]:  # fmt: skip
    """(steps per run, output folder or None, whether recordings are written), or
    ``ValidationError`` for a negative step count or a missing model file."""
    if max_steps is not None and max_steps < 0:
        raise ValidationError(f"max_steps must be >= 0, got {max_steps}")
    if model is not None and not Path(model).is_file():
        raise ValidationError(f"robot model {model}: no such file")
    out = None if out_dir is None else Path(out_dir)
    default = world.navigation_steps if mode == NAVIGATION_MODE else world.coverage_steps
    steps = max_steps if max_steps is not None else default
    return steps, out, rrd and out is not None


__all__ = [
    "MODE",
    "NAVIGATION_MODE",
    "VALIDATION_FILES",
    "StartJob",
    "Job",
    "Kind",
    "LONE",
    "ValidationError",
    "check_chromosome",
    "check_powers",
    "clear_navigation_starts",
    "sample_poses",
    "check_run_options",
    "check_sizes",
    "check_start",
    "Plan",
    "execute",
    "plan_validation",
    "jsonable",
    "load_checked_table",
    "mode_of",
    "physics_world",
    "report_head",
    "result_record",
    "run_both_worlds",
    "run_start",
    "start_record",
    "validate",
    "validation_need",
    "validation_settings",
]
