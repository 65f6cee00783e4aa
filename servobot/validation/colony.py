"""Validation of a colony (SPEC §7): each colony start in the table world and in physics.

``validate_colony(bits, starts, ...)`` runs the 16-gene chromosome on R robots from every
colony start ((N, R, 3) poses) twice — in the table world (``evolve.world.TableColony``) and
in the MuJoCo arena with R ServoBots (``servo_mj.world.physics_colony.PhysicsColony``), both
by ``evolve.interpreter.run_colony`` — and returns a report::

    {"runs": [{"index", "start": [{"x", "y", "h"}, ...],        # one per robot
               "table":   {"colony": {"squares", "inner_squares", "colony_steps",
                                      "collisions", "station_waits"},
                           "robots": [{"squares", "inner_squares", "docks", "steps",
                                       "end": {"code", "name"}, "final_pose",
                                       "collisions", "station_waits"}, ...],
                           "wall_s"},
               "physics": {... same, and "min_distance_cm"} | None,
               "error":   None | "PhysicsError: ...",
               "physics_partial": {"colony_steps", "squares", "poses"} (only with an error)},
              ...],
     "summary": {...}, "settings": {... "ColonySettings"}, "chromosome": "...", "table": {...}}

One colony start is one run of the executor. ``collisions`` are blocked moves (table: the
move was cancelled; physics: a bumper contact, ``PhysicsColony.step``). With ``out_dir``:
``report.json``, ``report.md``, ``tracks.npz`` (per run ``table_{k}`` and ``physics_{k}``:
(colony steps + 1, R, 3) poses), ``tracks{k}.png`` (every robot's track in both worlds) and,
with ``rrd=True``, one ``run{k}.rrd`` per colony run (``servobot.recording.colony``). Robot i
of run k draws its servo noise from ``servo_mj.world.physics_colony.robot_rngs``: robot 0 as
the lone validation's run k, so R = 1 gives the lone validation's records.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from evolve.interpreter import END_NAMES, ColonyResult, RunResult, run_colony
from evolve.settings import ColonySettings, WorldSettings
from evolve.table import validate_table
from evolve.world import TableColony
from infra.executors import Executor, make_executor
from servo_mj.robot.model import ModelFile
from servo_mj.world.arena import ArenaSettings, default_robot
from servobot.validation.colony_report import summarise_colony, write_colony_report
from servobot.validation.lone import (
    MODE,
    ValidationError,
    check_chromosome,
    check_run_options,
    check_sizes,
    check_start,
    execute,
    jsonable,
    report_head,
    run_both_worlds,
    start_record,
    validation_settings,
)


@dataclass(frozen=True)
class ColonyJob:
    """Everything one worker needs for one colony start (picklable plain data)."""

    index: int
    bits: np.ndarray
    start: tuple[tuple[float, float, float], ...]
    """The R robots' start poses (x, y cm; heading deg)."""
    table: np.ndarray
    world: WorldSettings
    arena: ArenaSettings
    colony: ColonySettings
    physics: Any
    max_steps: int | None
    rrd_path: str | None
    seed: int = 0
    """Seed of the robots' servo-noise generators (``robot_rngs(seed, index, R)``)."""
    model: str | None = None
    """The robots' model file (None = the shipped ServoBot)."""
    table_source: str = "array"
    """Where ``table`` came from (``GaitTable.source``), for the recording's properties."""
    command: str | None = None
    """The command line that asked for the run, for the recording (None: ``sys.argv``)."""


def check_colony_starts(
    starts: Any, world: WorldSettings, arena: ArenaSettings, colony: ColonySettings
) -> list[tuple[tuple[float, ...], ...]]:
    """An (N, R, 3) array of colony starts, R = ``colony.robots``: each pose checked by
    ``check_start``, and no two robots of a start closer than two disc radii (their discs
    and bumpers would overlap). Raises ``ValidationError`` naming the start and robots."""
    arr = np.asarray(starts, dtype=float)
    r = colony.robots
    if arr.ndim != 3 or arr.shape[1:] != (r, 3) or len(arr) == 0:
        raise ValidationError(
            f"colony starts must be an (N, {r}, 3) array of x, y, h per robot, got {arr.shape}"
        )
    out = []
    for k, poses in enumerate(arr):
        run = tuple(
            check_start(p, world, arena, name=f"start {k}, robot {i}") for i, p in enumerate(poses)
        )
        for i in range(r):
            for j in range(i):
                d = float(np.hypot(run[i][0] - run[j][0], run[i][1] - run[j][1]))
                if d < colony.min_distance:
                    raise ValidationError(
                        f"start {k}: robots {j} and {i} are {d:g} units apart, closer than two "
                        f"disc radii ({colony.min_distance:g}): they would overlap"
                    )
        out.append(run)
    return out


def robot_record(res: RunResult) -> dict[str, Any]:
    """One robot's part of a colony run."""
    return {
        "squares": int(res.squares),
        "inner_squares": int(res.inner_squares),
        "docks": int(res.docks),
        "steps": int(res.steps),
        "end": {"code": int(res.end), "name": END_NAMES[int(res.end)]},
        "final_pose": [round(float(v), 4) for v in res.final_pose],
        "collisions": int(res.collisions),
        "station_waits": int(res.station_waits),
    }


def colony_record(res: ColonyResult, wall_s: float) -> dict[str, Any]:
    """One world's record of a colony run: the colony's numbers and each robot's."""
    return {
        "colony": {
            "squares": int(res.squares),
            "inner_squares": int(res.inner_squares),
            "colony_steps": int(res.colony_steps),
            "collisions": int(res.collisions),
            "station_waits": int(res.station_waits),
        },
        "robots": [robot_record(r) for r in res.robots],
        "wall_s": round(wall_s, 4),
    }


def run_colony_start(job: ColonyJob) -> dict[str, Any]:
    """Run one colony start in both worlds (worker function; catches physics failures)."""
    from servo_mj.world.physics_colony import PhysicsColony, robot_rngs

    rec = None
    if job.rrd_path is not None:
        from servobot.recording.colony import ColonyRecorder

        rec = ColonyRecorder.for_validation(job)
    kwargs = {"mode": MODE, "settings": job.world, "colony": job.colony,
              "max_steps": job.max_steps}  # fmt: skip

    def table_run() -> tuple[dict[str, Any], np.ndarray]:
        t0 = time.perf_counter()
        world = TableColony(job.table, job.start, job.world, job.colony)
        on_event = None if rec is None else rec.table_event
        res = run_colony(job.bits, world, on_event=on_event, **kwargs)
        return colony_record(res, time.perf_counter() - t0), res.track

    def physics_run(last: dict[str, Any]) -> tuple[dict[str, Any], np.ndarray]:
        t0 = time.perf_counter()
        world = PhysicsColony(
            job.start, world=job.world, arena=job.arena, colony_settings=job.colony,
            physics=job.physics, robot=None if job.model is None else default_robot(job.model),
            rngs=robot_rngs(job.seed, job.index, job.colony.robots),
            on_frame=None if rec is None else rec.on_frame,
        )  # fmt: skip
        if rec is not None:
            rec.attach_physics(world)

        def on_physics(e: Any) -> None:
            last["colony_steps"] = e.colony_step
            last["squares"][e.robot] = e.event.squares
            last["poses"][e.robot] = [float(v) for v in e.event.pose]
            if rec is not None:
                rec.physics_event(e)

        res = run_colony(job.bits, world, on_event=on_physics, **kwargs)
        record = colony_record(res, time.perf_counter() - t0)
        low = world.min_distance_cm
        record["min_distance_cm"] = round(low, 4) if np.isfinite(low) else None
        return record, res.track

    out = {"index": job.index, "start": start_record(job.start)}
    last = {
        "colony_steps": 0,
        "squares": [0] * len(job.start),
        "poses": [list(p) for p in job.start],
    }
    return run_both_worlds(out, rec, table_run, physics_run, last)


def validate_colony(
    bits: np.ndarray,
    starts: np.ndarray,
    *,
    table: Any,
    colony: ColonySettings | None = None,
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
    force: bool = False,
) -> dict[str, Any]:
    """Run ``bits`` (16, 30) on a colony from every colony start ((N, R, 3): x, y cm; h deg)
    in the table world and in physics. ``colony`` defaults to ``ColonySettings(robots=R)``;
    ``max_steps`` bounds each robot's own gait steps (default 600). Everything else as
    ``servobot.validation.lone.validate``, whose run folder, executors and errors it shares."""
    world = world or WorldSettings()
    arena = arena or ArenaSettings()
    arr = check_chromosome(bits)
    values = validate_table(getattr(table, "values", table))
    shape = np.shape(starts)
    colony = colony or ColonySettings(robots=shape[1] if len(shape) == 3 else 1)
    poses = check_colony_starts(starts, world, arena, colony)
    steps, out, rrd = check_run_options(max_steps, model, world, out_dir, rrd)
    robot_steps = steps * colony.robots
    disk = check_sizes(len(poses), robot_steps, None if executor else workers, rrd, seed)
    settings = validation_settings(world, arena, physics, steps, seed, model)
    settings["ColonySettings"] = jsonable(colony)
    jobs = [
        ColonyJob(
            index=k,
            bits=arr,
            start=p,
            table=values,
            world=world,
            arena=arena,
            colony=colony,
            physics=physics,
            max_steps=max_steps,
            seed=seed,
            model=None if model is None else str(model),
            rrd_path=str(out / f"run{k}.rrd") if rrd and out else None,
            table_source=getattr(table, "source", "array"),
            command=(meta or {}).get("command"),
        )  # fmt: skip
        for k, p in enumerate(poses)
    ]
    head = report_head(arr, table, values, settings, meta)
    record = {"chromosome": head["chromosome"], "table": head["table"]["values"],
              "starts": [[list(q) for q in p] for p in poses], "settings": settings,
              "rrd": rrd}  # fmt: skip
    return execute(
        jobs, run_colony_start, ex=executor or make_executor(None, workers), head=head,
        summary=lambda runs, wall: summarise_colony(runs, world, wall),
        write=lambda path, report, tracks: write_colony_report(path, report, tracks, world),
        out=out, record=record, disk=disk, force=force, on_run=on_run,
    )  # fmt: skip


__all__ = [
    "ColonyJob",
    "check_colony_starts",
    "colony_record",
    "robot_record",
    "run_colony_start",
    "validate_colony",
]
