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
instead of run again, and the finished runs of a cell that was interrupted (kept in
``DIR/kept/`` as they end) are taken, so only its unfinished runs run again.

Shared cycles: with ``share``, the runs of every controller from one start in one world go
to one worker together and simulate the gait cycles they have in common once
(``servo_mj.world.shared_physics``): the same records, for controllers of one population
about half the physics.

Reuse: ``reuse`` names earlier matrix folders whose runs this one may take instead of
running them again, e.g. a matrix grown from 10 starts to 30 (start poses and servo noise of
run k depend on the seed and k alone, so its first 10 runs are the earlier ones), or one
gathered from matrices run controller by controller. A run is taken when its cell (same
world, controller name) holds the same chromosome, table values and validation settings
(model hash, steps, seeds) and the run started from the same pose at the same index with a
physics result, from the first folder (in the order given) that has it; the cell's report
lists how many it took and from where (``meta.reused_runs``, ``meta.reused_from``). Only the
inputs are compared, not the code that ran them.
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
import shutil
import zipfile
from collections.abc import Callable, Sequence
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
from infra.io import ReadError, atomic_write, read_json
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
KEPT_DIR = "kept"
"""Subfolder of the finished runs of unfinished cells: ``kept/{world}/{controller}/run{k}.npz``
(the record as JSON and both tracks), read back on resume, removed when the matrix is done."""
ROBUSTNESS_FILES = (
    *ROBUSTNESS_OUTPUTS,
    f"{MODELS_DIR}/*.xml",
    *(f"{RUNS_DIR}/*/*/{f}" for f in (*VALIDATION_FILES, RECORD_FILE)),
    f"{KEPT_DIR}/*/*/run*.npz",
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


def _inputs(doc: dict[str, Any]) -> dict[str, Any]:
    """A cell report's inputs, as ``_expected`` gives them (KeyError, TypeError or ValueError
    when ``doc`` is not a validation report)."""
    settings = dict(doc["settings"])
    settings.pop("model", None)
    return {
        "chromosome": doc["chromosome"],
        "table": doc["table"]["values"],
        "starts": [r["start"] for r in doc["runs"]],
        "settings": settings,
    }


def finished_report(cell: Cell, expected: dict[str, Any]) -> dict[str, Any] | None:
    """The cell's validation report if it exists and matches ``expected``, else None."""
    path = cell.folder / "report.json"
    if not path.is_file():
        return None
    try:
        doc = read_json(path, what="validation report")
        have = _inputs(doc)
    except (ReadError, KeyError, TypeError, ValueError):
        return None  # not a report of this cell: it is run again
    return doc if have == expected else None


def reusable_runs(cell: Cell, expected: dict[str, Any], reuse: Path) -> list[dict[str, Any]]:
    """The runs of ``cell``'s counterpart in the matrix folder ``reuse`` that this cell would
    repeat (module docstring, "Reuse"), tracks included; [] where it has none or cannot be
    read."""
    folder = reuse / RUNS_DIR / cell.world.name / cell.controller.name
    try:
        doc = read_json(folder / "report.json", what="validation report")
        if {**_inputs(doc), "starts": None} != {**expected, "starts": None}:  # any starts
            return []
        runs = _belonging(doc["runs"], expected)
        with np.load(folder / "tracks.npz") as npz:
            return [r | {"tracks": {w: npz[f"{w}_{r['index']}"] for w in ("table", "physics")}}
                    for r in runs]  # fmt: skip
    except (ReadError, KeyError, TypeError, ValueError, OSError, zipfile.BadZipFile):
        return []  # nothing to take: the cell runs in full


def keep_run(out: Path, cell: Cell, record: dict[str, Any]) -> None:
    """Write a finished run of ``cell`` (``execute``'s record, tracks included) into ``out``'s
    ``KEPT_DIR``, atomically."""
    rec = {k: v for k, v in record.items() if k != "tracks"}
    tracks = {f"track_{w}": t for w, t in record.get("tracks", {}).items()}
    path = out / KEPT_DIR / cell.world.name / cell.controller.name / f"run{rec['index']}.npz"
    text = np.array(json.dumps(jsonable(rec)))
    atomic_write(path, lambda tmp: np.savez(tmp, record=text, **tracks))


def kept_runs(out: Path, cell: Cell, expected: dict[str, Any]) -> list[dict[str, Any]]:
    """The runs of ``cell`` kept in ``out`` (``keep_run``) that belong to it (index, start,
    a physics result); the folder's ``settings.json`` vouches for the rest of its inputs."""
    found = []
    folder = out / KEPT_DIR / cell.world.name / cell.controller.name
    for f in sorted(folder.glob("run*.npz")):
        try:
            with np.load(f) as npz:
                rec = json.loads(str(npz["record"]))
                tracks = {w: npz[f"track_{w}"] for w in ("table", "physics")}
        except (OSError, KeyError, ValueError, zipfile.BadZipFile):
            continue  # an unreadable file: that run runs again
        found.append(rec | {"tracks": tracks})
    return _belonging(found, expected)


def _belonging(runs: list[dict[str, Any]], expected: dict[str, Any]) -> list[dict[str, Any]]:
    """The runs whose index is one of ``expected``'s starts, started from that start, with a
    physics result."""
    starts = expected["starts"]
    return [
        r for r in runs
        if isinstance(r.get("index"), int) and 0 <= r["index"] < len(starts)
        and r.get("start") == starts[r["index"]]
        and r.get("physics") is not None and r.get("error") is None
    ]  # fmt: skip


def check_reuse(reuse: Sequence[Path], out: Path, s: RobustnessSettings) -> None:
    """Each of ``reuse`` is an earlier matrix folder other than ``out`` and the runs write no
    recordings (a taken run has none here), else ``RobustnessError`` naming it."""
    for folder in reuse:
        if not (folder / RECORD_FILE).is_file() or not (folder / RUNS_DIR).is_dir():
            raise RobustnessError(f"--reuse {folder}: not a robustness matrix folder "
                                  f"(no {RECORD_FILE} and {RUNS_DIR}/)")  # fmt: skip
        if folder.resolve() == out.resolve():
            raise RobustnessError(f"--reuse {folder}: the output folder itself; use --resume")
    if reuse and s.rrd:
        raise RobustnessError("--reuse with --rrd: the reused runs have no recordings here")


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
    reuse: Path | Sequence[Path] = (),
    share: bool = False,
    on_run: Callable[[dict[str, Any]], None] | None = None,
    on_skip: Callable[[int], None] | None = None,
    log: Callable[[str], None] | None = None,
) -> dict[str, Any]:
    """Run the matrix into ``out`` and return ``robustness.json``'s document.

    ``executor`` (or a pool of ``workers``; ``infra.executors.make_executor``) runs every
    cell's starts as one batch (each cell's report is written when its last run ends);
    ``on_run(record)`` is called as each physics run finishes, ``on_skip(n)`` with a cell's run
    count when a finished cell is read back (``resume``) and with the runs taken from the
    matrix folders ``reuse`` (module docstring) or kept from an interrupted run of this one;
    ``share``: runs from one start in one world simulate the gait cycles they share once
    (``servobot.validation.lone.execute``; the same records); ``log(message)`` with warnings (a
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
    reuse = [Path(reuse)] if isinstance(reuse, str | Path) else [Path(f) for f in reuse]
    check_reuse(reuse, out, settings)
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
        plans, todo, todo_cells = [], [], []
        for cell in cells:
            key = (cell.world.name, cell.controller.name)
            expected = _expected(cell, table.values, settings)
            done = finished_report(cell, expected)
            if done is not None:
                reports[key] = done
                if on_skip is not None:
                    on_skip(len(cell.starts))
                continue
            kept = [] if settings.rrd else kept_runs(out, cell, expected)  # no recordings kept
            have = {r["index"] for r in kept}
            reused, sources = [], []
            for folder in reuse:
                new = [r for r in reusable_runs(cell, expected, folder) if r["index"] not in have]
                have |= {r["index"] for r in new}
                reused += new
                sources += [str(folder)] if new else []
            taken = kept + reused
            if taken and on_skip is not None:
                on_skip(len(taken))
            todo.append(key)
            todo_cells.append(cell)
            plans.append(plan_validation(
                cell.controller.bits, cell.starts, table=table, arena=cell.world.arena,
                out_dir=cell.folder, rrd=settings.rrd, max_steps=cell.steps,
                seed=settings.servo_seed, model=cell.model, force=True,
                workers=None if executor else workers,
                meta={"world": cell.world.name, "chromosome_file": str(cell.controller.file),
                      "command": "servobot robustness"}
                     | ({"reused_runs": len(reused), "reused_from": ", ".join(sources)}
                        if reused else {}),
                done=taken,
            ))  # fmt: skip
        keep = None if settings.rrd else lambda i, r: keep_run(out, todo_cells[i], r)
        reports.update(zip(todo, execute(plans, ex, on_run, share=share, on_record=keep),
                           strict=True))  # fmt: skip
        shutil.rmtree(out / KEPT_DIR, ignore_errors=True)  # every cell has its report now
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
