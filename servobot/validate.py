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
``rrd=True`` each run also writes ``run{k}.rrd`` (``servobot.recording``).
"""

from __future__ import annotations

import dataclasses
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from evolve import geometry
from evolve.codec import FULL_GENES, check_bits, format_chromosome
from evolve.interpreter import END_NAMES, run
from evolve.settings import WorldSettings
from evolve.table import GaitTable, GaitTableError, load_table, validate_table
from evolve.world import TableWorld
from infra.executors import Executor, Failed, make_executor
from servo_mj.robot.model import ModelFile, model_label, model_sha256
from servo_mj.world.arena import ArenaSettings, default_robot, overlaps_station
from servobot.validation_report import summarise, write_report

MODE = "coverage"
"""Validation runs the full controller in coverage mode (SPEC §5)."""


class ValidationError(ValueError):
    """Bad input to ``validate``: the message names the problem."""


@dataclass(frozen=True)
class StartJob:
    """Everything one worker needs for one start pose (picklable plain data)."""

    index: int
    bits: np.ndarray
    start: tuple[float, float, float]
    table: np.ndarray
    world: WorldSettings
    arena: ArenaSettings
    physics: Any
    max_steps: int | None
    rrd_path: str | None
    seed: int = 0
    """Seed of this run's servo-noise generator: ``default_rng((seed, index))``."""
    model: str | None = None
    """The robot's model file (None = the shipped ServoBot)."""


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


def check_chromosome(bits: Any) -> np.ndarray:
    """A (16, 30) chromosome as uint8, or ``ValidationError`` (an 8-gene section is refused)."""
    try:
        arr = check_bits(bits)
    except ValueError as exc:
        raise ValidationError(str(exc)) from exc
    if arr.shape[0] != FULL_GENES:
        raise ValidationError(
            f"validation needs a full 16-gene chromosome (coverage genes 0-7 + navigation "
            f"genes 8-15), got {arr.shape[0]} genes"
        )
    return arr


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
    except (GaitTableError, FileNotFoundError) as exc:
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


def _record(res: Any, wall_s: float) -> dict[str, Any]:
    return {
        "squares": int(res.squares),
        "inner_squares": int(res.inner_squares),
        "docks": int(res.docks),
        "steps": int(res.steps),
        "end": {"code": int(res.end), "name": END_NAMES[int(res.end)]},
        "final_pose": [round(float(v), 4) for v in res.final_pose],
        "wall_s": round(wall_s, 4),
    }


def run_start(job: StartJob) -> dict[str, Any]:
    """Run one start pose in both worlds (worker function; catches physics failures)."""
    from servo_mj.world.physics_world import PhysicsWorld

    x, y, h = job.start
    out: dict[str, Any] = {
        "index": job.index,
        "start": {"x": x, "y": y, "h": h},
        "table": None,
        "physics": None,
        "error": None,
    }
    rec = None
    if job.rrd_path is not None:
        from servobot.recording import Recording

        rec = Recording(job.rrd_path, app_id="servobot-validate")
        rec.log_arena(job.world)
    tracks: dict[str, np.ndarray] = {}
    try:
        t0 = time.perf_counter()
        table_world = TableWorld(job.table, x, y, h, job.world)
        on_table = None if rec is None else (lambda e: rec.log_event(e, world_name="table"))
        res = run(
            job.bits, table_world, mode=MODE, settings=job.world,
            max_steps=job.max_steps, on_event=on_table,
        )  # fmt: skip
        out["table"] = _record(res, time.perf_counter() - t0)
        tracks["table"] = res.track

        last: dict[str, Any] = {"steps": 0, "squares": 0, "pose": [x, y, h]}
        t0 = time.perf_counter()
        try:
            pw = PhysicsWorld(
                x, y, h, world=job.world, arena=job.arena, physics=job.physics,
                robot=None if job.model is None else default_robot(job.model),
                rng=np.random.default_rng((job.seed, job.index)),
                on_frame=None if rec is None else _state_logger(rec),
            )  # fmt: skip
            if rec is not None:
                rec.log_robot_model(pw.model, prefix=pw.prefix)

            def on_physics(e: Any) -> None:
                last.update(steps=e.step, squares=e.squares, pose=[float(v) for v in e.pose])
                if rec is not None:
                    rec.log_event(e, world_name="physics", t_s=pw.t_s)

            res = run(
                job.bits, pw, mode=MODE, settings=job.world,
                max_steps=job.max_steps, on_event=on_physics,
            )  # fmt: skip
            out["physics"] = _record(res, time.perf_counter() - t0)
            tracks["physics"] = res.track
        except Exception as exc:  # noqa: BLE001 - a physics failure is this run's record
            out["error"] = f"{type(exc).__name__}: {exc}"
            out["physics_partial"] = dict(last, wall_s=round(time.perf_counter() - t0, 4))
    finally:
        if rec is not None:
            rec.close()
    out["tracks"] = tracks
    return out


def _state_logger(rec: Any) -> Callable[[Any], None]:
    def log(frame: Any) -> None:
        rec.log_robot_state(frame.data, t_s=frame.t_s, prefix=frame.prefix)

    return log


def _jsonable(obj: Any) -> Any:
    if dataclasses.is_dataclass(obj) and not isinstance(obj, type):
        return _jsonable(dataclasses.asdict(obj))
    if isinstance(obj, dict):
        return {str(k): _jsonable(v) for k, v in obj.items()}
    if isinstance(obj, list | tuple):
        return [_jsonable(v) for v in obj]
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


def _run_jobs(
    ex: Executor, jobs: list[StartJob], on_run: Callable[[dict[str, Any]], None] | None
) -> list[dict[str, Any]]:
    """Every job's record in start order; a worker that failed gives a record with its error."""
    runs: list[dict[str, Any]] = [{} for _ in jobs]
    for k, outcome in ex.imap(run_start, jobs):
        if isinstance(outcome, Failed):
            x, y, h = jobs[k].start
            rec: dict[str, Any] = {
                "index": k, "start": {"x": x, "y": y, "h": h}, "table": None,
                "physics": None, "error": outcome.message, "tracks": {},
            }  # fmt: skip
        else:
            rec = outcome.value
        runs[k] = rec
        if on_run is not None:
            on_run(rec)
    return runs


def validate(
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
    executor: Executor | None = None,
    max_steps: int | None = None,
    seed: int = 0,
    model: ModelFile = None,
    on_run: Callable[[dict[str, Any]], None] | None = None,
    meta: dict[str, Any] | None = None,
) -> dict[str, Any]:
    """Run ``bits`` (16, 30) from every start (N, 3: x, y cm; h deg) in the table and physics.

    ``table`` is a (16, 3) array or a ``GaitTable``; ``physics`` a ``PhysicsSettings`` (None =
    default; with ``servo_noise_rad`` > 0, run k draws its noise from
    ``default_rng((seed, k))``). ``executor`` (``infra.executors.make_executor``) runs the
    starts; without one, ``workers`` 1 runs them here and otherwise a pool of ``workers``
    processes (None = one per core); records do not depend on where the runs ran. ``model``:
    the robot in physics (None = the shipped ServoBot, else a model file such as a
    ``servobot variant``; check the table against it with ``load_checked_table``).
    ``on_run(record)`` is called as each run finishes (progress). Returns the report (and
    writes it into ``out_dir`` when given). Raises ``ValidationError`` on bad input.
    """
    world = world or WorldSettings()
    arena = arena or ArenaSettings()
    arr = check_chromosome(bits)
    values = validate_table(getattr(table, "values", table))
    poses = check_starts(starts, world, arena)
    if max_steps is not None and max_steps < 0:
        raise ValidationError(f"max_steps must be >= 0, got {max_steps}")
    if model is not None and not Path(model).is_file():
        raise ValidationError(f"robot model {model}: no such file")
    out = None if out_dir is None else Path(out_dir)
    jobs = [
        StartJob(
            index=k,
            bits=arr,
            start=p,
            table=values,
            world=world,
            arena=arena,
            physics=physics,
            max_steps=max_steps,
            seed=seed,
            model=None if model is None else str(model),
            rrd_path=str(out / f"run{k}.rrd") if (rrd and out is not None) else None,
        )  # fmt: skip
        for k, p in enumerate(poses)
    ]
    t0 = time.perf_counter()
    runs = _run_jobs(executor or make_executor(None, workers), jobs, on_run)
    wall = time.perf_counter() - t0
    tracks = {f"{w}_{r['index']}": t for r in runs for w, t in r.pop("tracks", {}).items()}
    report = {
        "chromosome": format_chromosome(arr),
        "table": {
            "source": getattr(table, "source", "array"),
            "values": values.tolist(),
            "meta": _jsonable(getattr(table, "meta", {})),
        },
        "settings": {
            "WorldSettings": _jsonable(world),
            "ArenaSettings": _jsonable(arena),
            "PhysicsSettings": _jsonable(physics) if physics is not None else "default",
            "max_steps": max_steps if max_steps is not None else world.coverage_steps,
            "seed": seed,
            "mode": MODE,
            "model": model_label(model),
            "model_sha256": model_sha256(model),
        },
        "meta": _jsonable(meta or {}),
        "runs": runs,
        "summary": summarise(runs, world, wall),
    }
    if out is not None:
        write_report(out, report, tracks)
    return report


__all__ = [
    "MODE",
    "StartJob",
    "ValidationError",
    "check_chromosome",
    "check_start",
    "load_checked_table",
    "run_start",
    "validate",
]
