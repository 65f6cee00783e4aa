"""The physics test matrix: every controller × every physics world, from the same starts.

``run_matrix(chromosomes, out, settings)`` runs each controller from the same N seeded starts
in the table world (SPEC §3) and in each physics world of ``settings.worlds``
(``servobot.robustness.worlds``), unchanged. Each (controller, world) cell is one call of
``servobot.validation.lone`` validation plan — so the table world and physics run exactly as
``servobot validate`` runs them — into ``DIR/runs/{world}/{controller}/``; every cell's starts
go to the executor as one batch (``servobot.validation.lone.execute``)::

    DIR/settings.json              the run's ownership record (infra.rundir)
    DIR/models/{world}.xml         each built-in variant world's robot (servobot variant)
    DIR/runs/{world}/{name}/       one validation per cell: report.{json,md}, tracks.npz
    DIR/robustness.{json,md,png}   the matrix (servobot.robustness.report)

Starts: a 16-gene chromosome runs in coverage mode from N coverage starts (SPEC §5 region,
``evolve.starts.coverage_starts(default_rng(seed), N)``), ``settings.steps`` steps; an 8-gene
navigation section runs in navigation mode from N navigation starts clear of the station
block (``clear_navigation_starts(default_rng(seed), N)``), at most
``WorldSettings.navigation_steps`` steps. These are the starts ``servobot validate FILE
--starts N --seed S`` draws, so the ``shipped`` column equals that command's physics. Servo
noise: ``PhysicsSettings`` default, run k seeded by ``(seed, k)`` in every world
(``(noise_seed, k)`` when given: the same starts under another noise draw).

The table world does not depend on the physics world; every cell runs it again (it costs
milliseconds) and the matrix checks that each controller's table runs agree across the worlds
(start poses and records), reporting them once.

Resume: the folder is a run folder (lock, ``settings.json``; ``resume``/``force`` as every
command). With ``resume``, a cell whose ``report.json`` exists and matches the cell's inputs
(chromosome, table values, start poses, validation settings and model hash) is read back
instead of run again.
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from evolve.codec import ChromosomeError, format_chromosome, read_chromosome
from evolve.settings import WorldSettings
from evolve.starts import coverage_starts
from infra.bounds import Need, check_int, check_need
from infra.errors import InputError
from infra.executors import Executor, make_executor
from infra.io import ReadError, read_json
from infra.rundir import RECORD_FILE, run_folder
from servo_mj.robot.model import model_label
from servobot.robustness.report import ROBUSTNESS_OUTPUTS, summarise_matrix, write_outputs
from servobot.robustness.worlds import (
    BUILT_IN,
    PhysicsWorldSpec,
    materialise,
    model_path,
    resolve_worlds,
    world_sha256,
)
from servobot.validation.lone import (
    NAVIGATION_MODE,
    VALIDATION_FILES,
    ValidationError,
    check_chromosome,
    clear_navigation_starts,
    execute,
    jsonable,
    load_checked_table,
    mode_of,
    plan_validation,
    start_record,
    validation_need,
    validation_settings,
)

MODELS_DIR = "models"
"""Subfolder of the built-in variant worlds' model files."""
RUNS_DIR = "runs"
"""Subfolder of the cells' validations: ``runs/{world}/{controller}/``."""
ROBUSTNESS_FILES = (
    *ROBUSTNESS_OUTPUTS,
    f"{MODELS_DIR}/*.xml",
    *(f"{RUNS_DIR}/*/*/{f}" for f in (*VALIDATION_FILES, RECORD_FILE)),
)
"""Every file the matrix writes into its folder besides ``settings.json`` (``--force``)."""


class RobustnessError(InputError, ValueError):
    """Bad input to the matrix (a chromosome, a setting); the message names it."""


@dataclass(frozen=True)
class RobustnessSettings:
    """What a test matrix runs (saved in ``settings.json`` with the inputs' contents)."""

    worlds: tuple[str, ...] = tuple(BUILT_IN)
    """Physics worlds: built-in names (``servobot.robustness.worlds.BUILT_IN``) or paths of
    ``servobot variant`` files; default every built-in."""
    starts: int = 10
    """Start poses per controller, the same in every world."""
    steps: int = 600
    """Steps per coverage run (SPEC §5); a navigation section runs at most
    ``min(steps, WorldSettings.navigation_steps)``."""
    seed: int = 0
    """Seed of the start poses (``default_rng(seed)``) and of the servo noise."""
    noise_seed: int | None = None
    """Seed of the servo noise alone (None: ``seed``): the same starts under another noise
    draw, physics' own run-to-run spread (``servobot.robustness.floor``)."""
    table: str = "paper"
    """Gait table of the table world: ``paper`` or a calibration file of the shipped robot."""
    rrd: bool = False
    """Write a rerun recording of every run (``run{k}.rrd`` in each cell's folder)."""

    @property
    def servo_seed(self) -> int:
        """The seed of every run's servo noise."""
        return self.seed if self.noise_seed is None else self.noise_seed


@dataclass(frozen=True)
class Controller:
    """A chromosome of the matrix."""

    file: Path
    """The file it was read from."""
    name: str
    """Its file stem, made unique among the matrix's controllers (``-2``, ``-3``, ...)."""
    bits: np.ndarray
    """(16, 30) chromosome or (8, 30) navigation section."""

    @property
    def mode(self) -> str:
        """``coverage`` or ``navigation`` (an 8-gene section; ``servobot.validation.lone``)."""
        return mode_of(self.bits)


@dataclass(frozen=True)
class Cell:
    """One (controller, world) validation and what its inputs are."""

    controller: Controller
    world: PhysicsWorldSpec
    model: Path | None
    """The world's robot model file (None = shipped)."""
    starts: np.ndarray
    """(N, 3) start poses, x, y cm, heading deg."""
    steps: int
    folder: Path


def unique_names(paths: list[Path]) -> list[str]:
    """File stems, the second and later of a stem suffixed ``-2``, ``-3``, ..."""
    names: list[str] = []
    for p in paths:
        name, k = p.stem, 2
        while name in names:
            name, k = f"{p.stem}-{k}", k + 1
        names.append(name)
    return names


def read_controllers(paths: list[Path]) -> list[Controller]:
    """Each chromosome file read and checked (16 genes, or an 8-gene navigation section);
    ``RobustnessError`` naming the file otherwise."""
    if not paths:
        raise RobustnessError("no chromosome given")
    out = []
    for path, name in zip(paths, unique_names(paths), strict=True):
        try:
            bits = check_chromosome(read_chromosome(path), sections=True)
        except (ChromosomeError, ValidationError) as exc:
            msg = str(exc) if str(path) in str(exc) else f"{path}: {exc}"
            raise RobustnessError(f"chromosome {msg}") from exc
        out.append(Controller(Path(path), name, bits))
    return out


def check_settings(s: RobustnessSettings, cells: int, workers: int | None) -> None:
    """Sizes in range and a matrix the machine can run (``infra.bounds``), else
    ``BoundsError`` naming the option."""
    check_int(s.starts, "--starts", lo=1)
    check_int(s.steps, "--steps", lo=1)
    check_int(s.seed, "--seed", lo=0)
    if s.noise_seed is not None:
        check_int(s.noise_seed, "--noise-seed", lo=0)
    need, _ = validation_need(s.starts, s.steps, workers, s.rrd)
    check_need(Need(need.memory_bytes, need.wall_s * cells),
               f"{cells} cells × --starts {s.starts} × --steps {s.steps}")  # fmt: skip


def start_poses(mode: str, s: RobustnessSettings, world: WorldSettings) -> np.ndarray:
    """The (N, 3) starts of every controller of ``mode`` (module docstring)."""
    rng = np.random.default_rng(s.seed)
    if mode == NAVIGATION_MODE:
        return clear_navigation_starts(rng, s.starts, world)
    return coverage_starts(rng, s.starts, world)


def steps_of(mode: str, s: RobustnessSettings, world: WorldSettings) -> int:
    """Steps per run of a controller of ``mode``."""
    return min(s.steps, world.navigation_steps) if mode == NAVIGATION_MODE else s.steps


def table_info(table: Any) -> dict[str, str]:
    """The table world's gait table: its source and the SHA-256 of its (16, 3) values
    (float64, row-major), which is what the table world runs."""
    values = np.ascontiguousarray(table.values, dtype=np.float64)
    return {"source": str(table.source), "sha256": hashlib.sha256(values.tobytes()).hexdigest()}


def _expected(cell: Cell, table_values: np.ndarray, s: RobustnessSettings) -> dict[str, Any]:
    """What a cell's ``report.json`` must hold to count as done (JSON round-tripped)."""
    world = WorldSettings()
    settings = validation_settings(world, cell.world.arena, None, cell.steps, s.servo_seed,
                                   cell.model, cell.controller.mode)  # fmt: skip
    settings.pop("model")  # the label is a path; the hash says which model
    doc = {
        "chromosome": format_chromosome(cell.controller.bits),
        "table": table_values.tolist(),
        "starts": [start_record(tuple(float(v) for v in p)) for p in cell.starts],
        "settings": settings,
    }
    return json.loads(json.dumps(jsonable(doc)))


def finished_report(cell: Cell, expected: dict[str, Any]) -> dict[str, Any] | None:
    """The cell's validation report if it exists and matches ``expected``, else None."""
    path = cell.folder / "report.json"
    if not path.is_file():
        return None
    try:
        doc = read_json(path, what="validation report")
        settings = dict(doc["settings"])
        settings.pop("model", None)
        have = {
            "chromosome": doc["chromosome"],
            "table": doc["table"]["values"],
            "starts": [r["start"] for r in doc["runs"]],
            "settings": settings,
        }
    except (ReadError, KeyError, TypeError, ValueError):
        return None  # not a report of this cell: it is run again
    return doc if have == expected else None


def plan_cells(
    controllers: list[Controller], worlds: list[PhysicsWorldSpec], out: Path,
    s: RobustnessSettings,
) -> list[Cell]:  # fmt: skip
    """Every (controller, world) cell, world by world."""
    world = WorldSettings()
    starts = {m: start_poses(m, s, world) for m in {c.mode for c in controllers}}
    return [
        Cell(
            controller=c,
            world=w,
            model=model_path(w, out / MODELS_DIR),
            starts=starts[c.mode],
            steps=steps_of(c.mode, s, world),
            folder=out / RUNS_DIR / w.name / c.name,
        )
        for w in worlds
        for c in controllers
    ]


def world_rows(worlds: list[PhysicsWorldSpec], out: Path) -> list[dict[str, Any]]:
    """Each world's name, description, model file label and model SHA-256."""
    return [
        {"name": w.name, "description": w.description,
         "model": model_label(model_path(w, out / MODELS_DIR)), "model_sha256": world_sha256(w)}
        for w in worlds
    ]  # fmt: skip


def settings_record(
    s: RobustnessSettings, controllers: list[Controller], worlds: list[PhysicsWorldSpec],
    rows: list[dict[str, Any]], table: dict[str, str],
) -> dict[str, Any]:  # fmt: skip
    """The folder's ownership record: the settings and the contents of every input."""
    record = dataclasses.asdict(dataclasses.replace(s, worlds=tuple(w.name for w in worlds)))
    if s.noise_seed is None:  # absent, so folders written before it existed still resume
        del record["noise_seed"]
    return jsonable({
        "RobustnessSettings": record,
        "controllers": [{"name": c.name, "chromosome": format_chromosome(c.bits)}
                        for c in controllers],
        "worlds": [{"name": r["name"], "model_sha256": r["model_sha256"], "arena": w.arena}
                   for w, r in zip(worlds, rows, strict=True)],
        "table": table,
    })  # fmt: skip


def run_matrix(
    chromosomes: list[Path],
    out: Path,
    settings: RobustnessSettings,
    *,
    executor: Executor | None = None,
    workers: int | None = None,
    resume: bool = False,
    force: bool = False,
    on_run: Callable[[dict[str, Any]], None] | None = None,
    on_skip: Callable[[int], None] | None = None,
    log: Callable[[str], None] | None = None,
) -> dict[str, Any]:
    """Run the matrix into ``out`` and return ``robustness.json``'s document.

    ``executor`` (or a pool of ``workers``; ``infra.executors.make_executor``) runs every
    cell's starts as one batch (each cell's report is written when its last run ends);
    ``on_run(record)`` is called as each physics run finishes, ``on_skip(n)`` with a cell's run
    count when a finished cell is read back (``resume``), ``log(message)`` with warnings (a
    table file without a model hash). Every input is checked before the folder is
    taken (``InputError`` subclasses: ``RobustnessError``, ``WorldError``, ``BoundsError``,
    ``ValidationError``, ``RunDirError``).
    """
    controllers = read_controllers(list(chromosomes))
    check_settings(settings, len(controllers) * len(settings.worlds), None if executor else workers)
    table, warning = load_checked_table(settings.table, None)  # the table is the shipped robot's
    if warning and log is not None:
        log(warning)
    worlds = resolve_worlds(settings.worlds)
    out = Path(out)
    cells = plan_cells(controllers, worlds, out, settings)
    info = table_info(table)
    rows = world_rows(worlds, out)
    record = settings_record(settings, controllers, worlds, rows, info)
    ex = executor or make_executor(None, workers)
    reports: dict[tuple[str, str], dict[str, Any]] = {}
    with run_folder(out, record, owned=ROBUSTNESS_FILES, resume=resume, force=force,
                    command="robustness"):
        for w in worlds:
            materialise(w, out / MODELS_DIR)
        plans, todo = [], []
        for cell in cells:
            key = (cell.world.name, cell.controller.name)
            done = finished_report(cell, _expected(cell, table.values, settings))
            if done is not None:
                reports[key] = done
                if on_skip is not None:
                    on_skip(len(cell.starts))
                continue
            todo.append(key)
            plans.append(plan_validation(
                cell.controller.bits, cell.starts, table=table, arena=cell.world.arena,
                out_dir=cell.folder, rrd=settings.rrd, max_steps=cell.steps,
                seed=settings.servo_seed, model=cell.model, force=True,
                workers=None if executor else workers,
                meta={"world": cell.world.name, "chromosome_file": str(cell.controller.file),
                      "command": "servobot robustness"},
            ))  # fmt: skip
        reports.update(zip(todo, execute(plans, ex, on_run), strict=True))
        doc = summarise_matrix(rows, [_controller_row(c) for c in controllers], reports,
                               _head(settings, cells, info))  # fmt: skip
        write_outputs(out, doc)
    return doc


def _controller_row(c: Controller) -> dict[str, Any]:
    return {"file": str(c.file), "name": c.name, "mode": c.mode}


def _head(s: RobustnessSettings, cells: list[Cell], table: dict[str, str]) -> dict[str, Any]:
    """The settings part of ``robustness.json``."""
    poses = {c.controller.mode: c.starts.tolist() for c in cells}
    return {
        "starts": s.starts, "steps": s.steps,
        "navigation_steps": steps_of(NAVIGATION_MODE, s, WorldSettings()), "seed": s.seed,
        "table": table, "rrd": s.rrd, "start_poses": poses,
    } | ({} if s.noise_seed is None else {"noise_seed": s.noise_seed})  # fmt: skip


__all__ = [
    "ROBUSTNESS_FILES",
    "Cell",
    "Controller",
    "RobustnessError",
    "RobustnessSettings",
    "check_settings",
    "plan_cells",
    "read_controllers",
    "run_matrix",
    "start_poses",
    "steps_of",
    "table_info",
    "unique_names",
]
