"""Anytime learning with MuJoCo as the real robot: ``run_anytime(out, ...)`` (``servobot
anytime``).

Coverage learning (SPEC §5, the navigation section fixed) runs on the table world
(``evolve.anytime.evolve_anytime``); every K generations the T best genomes of each population
walk in physics from M seeded coverage starts (``measure_run``: the validation's physics world
and servo noise, every gait cycle logged, ``calibration.residuals``), and the results bias
the fitness or correct the gait table. At the end each population's best runs in both worlds
from ``final_starts`` fresh starts (``servobot.validation.lone.validate``). Every batch of physics
runs goes to one executor (``infra.executors``); the results do not depend on which.

Layout of ``out/anytime`` (a run folder: lock, ``settings.json``, ``--resume``, ``--force``)::

    summary.json              method, punctuations, final, physics_wall_s, wall_s, ...
    best_pop{k}.txt           each population's final best (16 genes)
    figure_anytime.png        physics fitness of the best by generation (and the baseline's)
    punctuations/gen{g:04d}.json   every punctuation: tested genomes, both fitnesses, residuals
    tables/gen{g:04d}.json    method model: the corrected gait table after each punctuation
    final/pop{k}.json         the final test of population k (both worlds, per start)
    checkpoints/, populations/, history_pop{k}.csv   as ``servobot evolve`` writes them
"""

from __future__ import annotations

import contextlib
import dataclasses
import json
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from calibration.residuals import LoggingWorld, residuals
from evolve.anytime import (
    AnytimeError,
    AnytimeResult,
    AnytimeSettings,
    OnPunctuation,
    PhysicsRun,
    PhysicsTester,
    evolve_anytime,
    final_starts,
    punctuation_generations,
)
from evolve.codec import format_chromosome, write_chromosome
from evolve.envelope import NONE, Envelope
from evolve.interpreter import END_NAMES, run
from evolve.population import OnGeneration
from evolve.settings import GASettings, WorldSettings
from evolve.stages import (
    DEFAULT_GA,
    DEFAULT_WORLD,
    STAGE_FILES,
    check_ga,
    coverage_stage,
    stage_settings_doc,
)
from evolve.table import GaitTable
from infra.bounds import check_need, is_finite_number
from infra.executors import Executor, Failed, make_executor
from infra.io import atomic_write_json, read_json
from infra.rundir import run_folder, settings_diff
from servo_mj.robot.model import ModelFile, model_label, model_sha256
from servo_mj.robot.settings import PhysicsSettings
from servo_mj.world.arena import ArenaSettings, station_distance_cm
from servobot.anytime import report
from servobot.validation.lone import (
    MODE,
    SHARE_GROUP_MAX,
    StartJob,
    jsonable,
    physics_world,
    validate,
    validation_need,
)

ANYTIME_FILES = (
    *STAGE_FILES, "punctuations/gen*.json", "tables/gen*.json", "final/pop*.json",
    "figure_anytime.png",
)  # fmt: skip
"""Every file ``run_anytime`` writes in ``out/anytime`` besides ``settings.json``."""
DEFAULT_ANYTIME = AnytimeSettings()
"""The default punctuations (frozen, shared)."""


@dataclass(frozen=True)
class PunctuationJob:
    """One tested genome from one start in physics (picklable plain data)."""

    run: StartJob
    """The run: chromosome, start, base table (the residuals' reference), physics, seeds."""
    station_margin_cm: float
    """Cycles beginning closer than this to the station block are not counted."""


def measure_run(job: PunctuationJob, make_world: Callable[[], Any] | None = None) -> PhysicsRun:
    """Run one start in physics (worker function): squares reached and the residuals of the
    cycles that count; a physics failure becomes the run's ``error``. ``make_world()``, when
    given, makes the physics world (a ``SharedView``)."""
    sj = job.run
    world = LoggingWorld(physics_world(sj) if make_world is None else make_world())
    try:
        res = run(sj.bits, world, mode=MODE, settings=sj.world, max_steps=sj.max_steps)
    except Exception as exc:  # noqa: BLE001 - a physics failure is this run's record
        return PhysicsRun(None, None, f"{type(exc).__name__}: {exc}")
    counted = [
        (gait, r)
        for (gait, _, r), (_, before, _) in zip(residuals(world.log, sj.table), world.log,
                                                strict=True)
        if station_distance_cm(before[0], before[1], sj.world, sj.arena) >= job.station_margin_cm
    ]  # fmt: skip
    return PhysicsRun(
        int(res.squares),
        int(res.inner_squares),
        None,
        np.array([g for g, _ in counted], dtype=np.int64),
        np.array([r for _, r in counted], dtype=np.float64).reshape(-1, 3),
        len(world.log),
        END_NAMES[int(res.end)],
    )


def measure_shared_runs(jobs: tuple[PunctuationJob, ...]) -> list[PhysicsRun]:
    """``measure_run`` of each job, all from one start with one noise seed, through one
    ``PhysicsTree``: the gait cycles the genomes share are simulated once, the results are
    those of separate runs (worker function)."""
    from servo_mj.world.shared_physics import PhysicsTree

    tree = PhysicsTree(physics_world(jobs[0].run))
    return [measure_run(job, tree.view) for job in jobs]


def physics_tester(
    ex: Executor, *, world: WorldSettings, arena: ArenaSettings, physics: PhysicsSettings,
    model: ModelFile, settings: AnytimeSettings, on_run: Callable[[], None] | None = None,
) -> PhysicsTester:  # fmt: skip
    """The ``PhysicsTester`` of ``evolve_anytime``: each (genome, start) one ``measure_run``
    on ``ex``, the genomes from one start in groups of up to ``SHARE_GROUP_MAX`` that share
    their common gait cycles (``measure_shared_runs``; the same results); ``on_run()`` after
    each run (progress)."""

    def test(genomes: np.ndarray, starts: np.ndarray, seed: int, base: np.ndarray) -> list:
        jobs = [
            PunctuationJob(
                StartJob(index=m, bits=genome, start=tuple(float(v) for v in s), table=base,
                         world=world, arena=arena, physics=physics,
                         max_steps=settings.physics_steps, rrd_path=None, seed=seed,
                         model=None if model is None else str(model)),
                settings.station_margin_cm,
            )
            for genome in genomes
            for m, s in enumerate(starts)
        ]  # fmt: skip
        n = len(starts)  # job g·n + m: genome g from start m
        groups = [list(range(m + n * g0, min(len(jobs), m + n * (g0 + SHARE_GROUP_MAX)), n))
                  for m in range(n) for g0 in range(0, len(genomes), SHARE_GROUP_MAX)]  # fmt: skip
        items = [tuple(jobs[i] for i in g) for g in groups]
        out: list[PhysicsRun] = [PhysicsRun(None, None, "not run")] * len(jobs)
        with contextlib.closing(ex.imap(measure_shared_runs, items)) as done:  # Ctrl-C stops
            for k, outcome in done:
                if isinstance(outcome, Failed):
                    runs = [PhysicsRun(None, None, outcome.message)] * len(groups[k])
                else:
                    runs = outcome.value
                for i, r in zip(groups[k], runs, strict=True):
                    out[i] = r
                    if on_run is not None:
                        on_run()
        return out

    return test


def check_anytime(ga: GASettings, settings: AnytimeSettings, workers: int | None) -> None:
    """Refuse settings that contradict each other (a run with no punctuation, more genomes
    tested than a population holds) and sizes whose table evolution or physics runs the
    machine cannot give."""
    check_ga(ga, WorldSettings().coverage_steps)
    if settings.every > ga.generations:
        raise AnytimeError(
            f"--every {settings.every} is larger than --generations {ga.generations}: the run "
            f"would have no punctuation (physics tests at generations K, 2K, … ≤ G); give "
            f"--every {ga.generations} or less"
        )
    if settings.top > ga.population_size:
        raise AnytimeError(
            f"--top {settings.top} is larger than --population-size {ga.population_size}: a "
            f"punctuation cannot test more genomes than a population holds; give --top "
            f"{ga.population_size} or less"
        )
    punct = len(punctuation_generations(ga.generations, settings.every))
    runs = punct * ga.populations * settings.top * settings.physics_starts
    runs += ga.populations * settings.final_starts
    need, _ = validation_need(runs, settings.physics_steps, workers, False)
    check_need(need, f"{runs} physics runs (punctuations and final) × {settings.physics_steps} "
                     "steps")  # fmt: skip


BASELINE_FIELDS = ("GASettings", "AnytimeSettings", "table", "WorldSettings", "PhysicsSettings",
                   "ArenaSettings", "model_sha256")  # fmt: skip
"""The settings a ``--baseline`` run must share with this run to be drawn beside it (its
method aside): the GA's sizes and seed, the punctuations, the base table, the worlds and
the robot model. The envelope may differ (a run in an envelope against the plain control)."""


METHOD_FIELDS = ("method", "neighbours", "descriptor_starts")
"""``AnytimeSettings`` fields that belong to one method (a baseline may differ in them)."""


def _comparable(doc: dict[str, Any]) -> dict[str, Any]:
    out = {k: doc.get(k) for k in BASELINE_FIELDS}
    if isinstance(out["AnytimeSettings"], dict):
        out["AnytimeSettings"] = {k: v for k, v in out["AnytimeSettings"].items()
                                  if k not in METHOD_FIELDS}  # fmt: skip
    return out


def _is_num(v: Any, *, none: bool = True) -> bool:
    if v is None:
        return none
    return is_finite_number(v)


def check_summary(doc: Any, file: Path, method: str | None = None) -> dict[str, Any]:
    """``doc`` if it is an anytime ``summary.json`` (of ``method``, when given) that the
    figure can draw, else ``AnytimeError`` naming ``file`` and the field."""
    if not isinstance(doc, dict) or not {"method", "best_by_generation", "final"} <= set(doc):
        raise AnytimeError(f"{file}: not the summary of a servobot anytime run")

    def bad(field: str, why: str) -> AnytimeError:
        return AnytimeError(f"{file}: field {field}: {why}; not a summary of a finished run")

    if not isinstance(doc["method"], str):
        raise bad("method", f"a method name, got {doc['method']!r}")
    if method is not None and doc["method"] != method:
        raise AnytimeError(f"{file}: the baseline must be a --method {method} run, not "
                           f"{doc['method']}")  # fmt: skip
    curve = doc["best_by_generation"]
    keys = ("generations", "physics_fitness", "table_fitness")
    if not isinstance(curve, dict) or not all(isinstance(curve.get(k), list) for k in keys):
        raise bad("best_by_generation", f"an object of the lists {', '.join(keys)}")
    if len({len(curve[k]) for k in keys}) != 1:
        raise bad("best_by_generation", "its lists differ in length")
    if not all(isinstance(g, int) and not isinstance(g, bool) and g >= 0
               for g in curve["generations"]):  # fmt: skip
        raise bad("best_by_generation.generations", "generations are integers ≥ 0")
    for k in keys[1:]:
        if not all(_is_num(v) for v in curve[k]):
            raise bad(f"best_by_generation.{k}", "fitnesses are finite numbers or null")
    final = doc["final"]
    if (not isinstance(final, dict) or "physics_inner_percent" not in final
            or not _is_num(final["physics_inner_percent"])):  # fmt: skip
        raise bad("final.physics_inner_percent", "a finite number or null")
    if not isinstance(doc.get("settings"), dict):
        raise bad("settings", "the run's settings object")
    return doc


def read_baseline(path: Path, doc: dict[str, Any]) -> dict[str, Any]:
    """The summary of the control run in ``path`` (a ``--method none`` run's DIR, or its
    ``anytime`` folder); ``AnytimeError`` unless it is a well-formed one whose settings
    (``BASELINE_FIELDS``) are this run's (``doc``, its settings document), naming the file
    and the first differing fields."""
    path = Path(path)
    file = next((p for p in (path / "anytime/summary.json", path / "summary.json") if p.exists()),
                path / "anytime/summary.json")  # fmt: skip
    doc_read = read_json(file, what="anytime summary", error=AnytimeError)
    base = check_summary(doc_read, file, method="none")
    diff = settings_diff(_comparable(base["settings"]), _comparable(doc))
    if diff:
        more = f" and {len(diff) - 3} more" if len(diff) > 3 else ""
        raise AnytimeError(
            f"--baseline {path}: {file} is a run with other settings than this one "
            f"({'; '.join(diff[:3])}{more}); a baseline must share the GA sizes and seed, the "
            "punctuations, the table, the worlds and the model"
        )
    return base


def run_anytime(
    out: Path,
    *,
    navigation: np.ndarray,
    table: GaitTable,
    ga: GASettings = DEFAULT_GA,
    world: WorldSettings = DEFAULT_WORLD,
    settings: AnytimeSettings = DEFAULT_ANYTIME,
    physics: PhysicsSettings | None = None,
    arena: ArenaSettings | None = None,
    model: ModelFile = None,
    executor: Executor | None = None,
    baseline: Path | None = None,
    resume: bool = False,
    force: bool = False,
    on_generation: OnGeneration | None = None,
    on_punctuation: OnPunctuation | None = None,
    on_physics_run: Callable[[], None] | None = None,
    envelope: Envelope = NONE,
) -> dict[str, Any]:
    """Anytime learning into ``out/anytime`` (module docstring); returns the summary.

    ``table``: the GA's base model (check it against ``model`` first:
    ``servobot.validation.lone.load_checked_table``); ``physics`` (default ``PhysicsSettings()``,
    servo noise as in validation), ``arena``, ``model``: the physics robot. ``executor``
    (default a process pool of one worker per core) runs every batch of physics runs.
    ``baseline``: a ``method none`` run of the same seed, drawn beside this one in the figure.
    ``envelope`` (SPEC §9): the table world the populations evolve in (default the exact one).
    Summary keys: ``method``, ``punctuations`` (per punctuation: ``generation``, ``tested``
    (``population``, ``index``, ``rank``, ``table_fitness``, ``physics_fitness``, ``ratio``),
    ``bias`` (method bias: per population the mean ratio the untested get) and
    ``table_error``), ``final`` (``table_inner_percent``, ``physics_inner_percent``, their
    ``gap_pp``, per population), ``physics_runs``, ``physics_wall_s`` (the punctuations'
    physics, over the whole run), ``final_wall_s``, ``table_wall_s`` (the evolution without its
    physics, this invocation), ``wall_s`` (this invocation), ``settings``."""
    t0 = time.perf_counter()
    physics = physics or PhysicsSettings()
    arena = arena or ArenaSettings()
    check_anytime(ga, settings, None)
    stage = dataclasses.replace(coverage_stage(world, navigation, envelope),
                                extra_settings=(settings,))  # fmt: skip
    doc = stage_settings_doc(stage, ga, world, table) | {
        "command": "anytime",
        "PhysicsSettings": jsonable(physics),
        "ArenaSettings": jsonable(arena),
        "model": model_label(model),
        "model_sha256": model_sha256(model),
    }
    control = None if baseline is None else read_baseline(baseline, doc)
    folder = Path(out) / "anytime"
    ex = executor or make_executor(None, None)
    kw = dict(world=world, arena=arena, physics=physics, model=model, settings=settings)
    with run_folder(folder, doc, owned=ANYTIME_FILES, resume=resume, force=force,
                    command="anytime"):
        t1 = time.perf_counter()
        result = evolve_anytime(
            folder, stage=stage, table=table, ga=ga, world=world, settings=settings,
            test_in_physics=physics_tester(ex, on_run=on_physics_run, **kw),
            settings_text=json.dumps(doc, sort_keys=True), resume=resume,
            on_generation=on_generation, on_punctuation=on_punctuation,
            table_meta={"model": doc["model"], "model_sha256": doc["model_sha256"]},
        )  # fmt: skip
        evolution_s = time.perf_counter() - t1
        finals = _finals(folder, result, stage, ga, ex, on_physics_run, **kw)
        summary = report.summary(result, finals, settings, doc)
        summary |= {
            "table_wall_s": evolution_s - result.physics_wall_s,
            "wall_s": time.perf_counter() - t0,
            "resumed": bool(resume),
            "baseline": None if baseline is None else str(baseline),
        }
        for k, res in enumerate(result.results):
            full = stage.genomes(res.best[None])[0]
            head = report.provenance(k, ga, table, settings, summary["final"]["populations"][k])
            write_chromosome(folder / f"best_pop{k}.txt", full, head)
        report.figure(folder / "figure_anytime.png", summary, control)
        atomic_write_json(folder / "summary.json", summary)
    return summary


def check_final(doc: dict[str, Any], path: Path) -> dict[str, Any]:
    """A kept final test (``final/pop{k}.json``) whose summary the report can use, else
    ``AnytimeError`` naming the file and field (a record of other genomes, tables or starts is
    not checked: it is measured again)."""
    s = doc.get("summary")

    def bad(field: str, why: str) -> AnytimeError:
        return AnytimeError(f"{path}: field {field}: {why}; delete the file to measure the "
                            "final test again, or rerun with --force")  # fmt: skip

    if not isinstance(s, dict):
        raise bad("summary", "an object")
    for world in ("table", "physics"):
        w = s.get(world)
        if not isinstance(w, dict) or not _is_num(w.get("inner_pct")):
            raise bad(f"summary.{world}.inner_pct", "a finite number or null")
    if not isinstance(s.get("gap"), dict) or not _is_num(s["gap"].get("inner_pct_pp")):
        raise bad("summary.gap.inner_pct_pp", "a finite number or null")
    for field in ("physics_errors", "starts"):
        v = s.get(field)
        if not (isinstance(v, int) and not isinstance(v, bool) and v >= 0):
            raise bad(f"summary.{field}", f"an integer ≥ 0, got {v!r}")
    if not _is_num(s.get("wall_s"), none=False) or s["wall_s"] < 0:
        raise bad("summary.wall_s", f"a finite number of seconds ≥ 0, got {s.get('wall_s')!r}")
    return doc


def _finals(
    folder: Path, result: AnytimeResult, stage: Any, ga: GASettings, ex: Executor,
    on_run: Callable[[], None] | None, *, world: WorldSettings, arena: ArenaSettings,
    physics: PhysicsSettings, model: ModelFile, settings: AnytimeSettings,
) -> list[dict[str, Any]]:  # fmt: skip
    """Each population's final best from the same fresh starts, in both worlds (the table
    world on the table the GA used last); a finished population's test is kept in
    ``final/pop{k}.json`` and reused on resume."""
    starts, seed = final_starts(ga.seed, settings.final_starts, world)
    out = []
    for res in result.results:
        full = stage.genomes(res.best[None])[0]
        key = {
            "population": res.index, "chromosome": format_chromosome(full),
            "table": result.table.values.tolist(), "starts": starts.tolist(), "seed": seed,
        }  # fmt: skip
        path = folder / "final" / f"pop{res.index}.json"
        done = read_json(path, what="final test", error=AnytimeError) if path.exists() else {}
        if not isinstance(done, dict) or {k: done.get(k) for k in key} != key:
            rep = validate(
                full, starts, table=result.table, world=world, physics=physics, arena=arena,
                executor=ex, max_steps=settings.physics_steps, seed=seed, model=model,
                on_run=None if on_run is None else lambda _rec: on_run(),
            )  # fmt: skip
            done = key | {"summary": rep["summary"], "runs": rep["runs"]}
            atomic_write_json(path, done)
        out.append(check_final(done, path))
    return out


__all__ = [
    "ANYTIME_FILES",
    "BASELINE_FIELDS",
    "PunctuationJob",
    "check_anytime",
    "check_final",
    "check_summary",
    "measure_run",
    "physics_tester",
    "read_baseline",
    "run_anytime",
]
