"""``reproduce(out)``: the whole reproduction into one run folder, resumable.

Stages, in order (each writes ``DIR/<stage>/done.json`` when complete and is skipped on a
rerun with the same settings; the evolution stages also resume from their checkpoints, and
validation resumes finalist by finalist)::

    1 calibration  DIR/calibration/gait_table.json, figure4.png     (MuJoCo, shipped gaits)
    2 navigation   DIR/navigation/best.txt, summary.json             (CGA, calibrated table)
    3 coverage     DIR/coverage/best_pop{k}.txt, figure9.*, figure10_pop{k}.png, DIR/figure8.png
    4 validation   DIR/validation/pop{k}/report.{json,md}, run{j}.rrd  (table vs physics)
    5 report       DIR/REPORT.md                                      (always rewritten)

Budgets live in ``ReproduceSettings`` (paper scale by default, ``quick_settings()`` for a
first look). A folder made with other settings is refused with a message naming the stage
and the differing fields, so results of different budgets never mix. Progress reaches the
outside through ``log(message)`` and ``on_generation`` / ``on_run`` callbacks.
"""

from __future__ import annotations

import dataclasses
import datetime as dt
import json
import os
import sys
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from calibration.calibrate import FIGURE_FILE, TABLE_FILE, calibrate
from evolve.codec import read_chromosome
from evolve.population import OnGeneration
from evolve.settings import WorldSettings, settings_json
from evolve.stages import run_coverage, run_navigation
from evolve.starts import coverage_starts
from evolve.table import GaitTable, load_table
from infra.executors import Executor, make_executor
from infra.io import atomic_write_json, atomic_write_text
from servobot.recording import Recording, calibration_recorder
from servobot.reproduce_report import write_report
from servobot.reproduce_settings import (
    STAGES,
    ReproduceError,
    ReproduceSettings,
    check_settings,
    quick_settings,
    stage_key,
)
from servobot.validate import ValidationError, validate

VALIDATION_SEED_WORD = 2
"""Second entropy word of the validation starts' SeedSequence (stages use 0 and 1)."""
RECORDING_FILE = "calibration.rrd"
"""The calibration stage's recording of the 16 walks."""
DONE = "done.json"
"""A stage's completion marker: its settings key, wall time and a summary."""


# --------------------------------------------------------------------------- markers


def read_done(folder: Path, key: dict[str, Any]) -> dict[str, Any] | None:
    """The stage's done record if it finished with these settings; None if not finished;
    ``ReproduceError`` if it finished with other settings."""
    path = folder / DONE
    if not path.exists():
        return None
    try:
        doc = json.loads(path.read_text())
    except (OSError, ValueError) as exc:
        raise ReproduceError(f"{path}: unreadable stage marker ({exc}); delete it to redo") from exc
    stored = doc.get("settings", {})
    if stored != key:
        diff = sorted(k for k in set(stored) | set(key) if stored.get(k) != key.get(k))
        detail = ", ".join(f"{k}: {stored.get(k)!r} here, {key.get(k)!r} asked" for k in diff)
        raise ReproduceError(
            f"{folder} was made with other settings ({detail}); use a fresh --out DIR"
        )
    return doc


def write_done(folder: Path, key: dict[str, Any], wall_s: float, **extra: Any) -> None:
    """Mark a stage complete (atomically)."""
    atomic_write_json(
        folder / DONE,
        {
            "settings": key,
            "wall_s": round(wall_s, 3),
            "finished_utc": dt.datetime.now(dt.timezone.utc).isoformat(timespec="seconds"),
            **extra,
        },
    )


def check_folder(out: Path, s: ReproduceSettings) -> None:
    """Raise ``ReproduceError`` if any stage in ``out`` finished with other settings."""
    for name in STAGES:
        read_done(out / name, stage_key(s, name))
    for sub in sorted((out / "validation").glob("pop*")):
        read_done(sub, stage_key(s, "validation"))


# --------------------------------------------------------------------------- the pipeline


@dataclass
class _Pipeline:
    """One invocation of the stages over a run folder: runs or skips each, records how."""

    out: Path
    s: ReproduceSettings
    world: WorldSettings
    executor: Executor
    log: Callable[[str], None]
    on_generation: OnGeneration | None
    on_run: Callable[[dict[str, Any]], None] | None
    stages: dict[str, dict[str, Any]] = dataclasses.field(default_factory=dict)

    def stage(self, name: str, body: Callable[[], dict[str, Any]], outputs: list[Path]) -> None:
        """Run ``body`` unless the stage finished earlier with these settings."""
        folder = self.out / name
        key = stage_key(self.s, name)
        done = read_done(folder, key)
        if done is not None and all(p.exists() for p in outputs):
            self.log(f"[{name}] already done ({done['wall_s']:.1f} s earlier) — skipped")
            self.stages[name] = {"skipped": True, "wall_s": done["wall_s"], **done.get("info", {})}
            return
        self.log(f"[{name}] running")
        folder.mkdir(parents=True, exist_ok=True)
        t0 = time.perf_counter()
        try:
            info = body()
        except BaseException as exc:
            what = "interrupted" if isinstance(exc, KeyboardInterrupt) else f"failed: {exc}"
            wall = round(time.perf_counter() - t0, 3)
            self.stages[name] = {"skipped": False, "wall_s": wall, "failed": what}
            raise
        wall = time.perf_counter() - t0
        write_done(folder, key, wall, info=info)
        self.stages[name] = {"skipped": False, "wall_s": round(wall, 3), **info}
        self.log(f"[{name}] done in {wall:.1f} s")

    def calibration(self) -> GaitTable:
        folder = self.out / "calibration"

        def body() -> dict[str, Any]:
            settings = self.s.calibration()
            with Recording(folder / RECORDING_FILE, app_id="servobot-calibration") as rec:
                calibrate(
                    folder, settings, command="servobot reproduce (stage 1)",
                    **calibration_recorder(rec, settings),
                )  # fmt: skip
            return {}

        self.stage("calibration", body, [folder / TABLE_FILE, folder / FIGURE_FILE])
        return load_table(str(folder / TABLE_FILE))

    def navigation(self, table: GaitTable) -> np.ndarray:
        folder = self.out / "navigation"

        def body() -> dict[str, Any]:
            summ = run_navigation(
                self.out, table=table, ga=self.s.navigation_ga(), world=self.world,
                resume=True, on_generation=self.on_generation,
            )  # fmt: skip
            return {"dock_success": summ["dock_success"], "chosen": summ["chosen_population"]}

        self.stage("navigation", body, [folder / "best.txt", folder / "summary.json"])
        return read_chromosome(folder / "best.txt")

    def coverage(self, table: GaitTable, navigation: np.ndarray) -> None:
        folder = self.out / "coverage"

        def body() -> dict[str, Any]:
            summ = run_coverage(
                self.out, navigation=navigation, table=table, ga=self.s.coverage_ga(),
                world=self.world, resume=True, on_generation=self.on_generation,
            )  # fmt: skip
            return {"final_mean_inner_percent": summ["final_mean_inner_percent"]}

        finalists = [folder / f"best_pop{k}.txt" for k in range(self.s.coverage_populations)]
        self.stage("coverage", body, [folder / "summary.json", *finalists])

    def validation(self, table: GaitTable) -> None:
        folder = self.out / "validation"
        reports = [folder / f"pop{k}" / "report.json" for k in range(self.s.coverage_populations)]

        def body() -> dict[str, Any]:
            res = self._validate_finalists(table)
            failed = [k for k, r in res.items() if "error" in r]
            if failed:
                raise ReproduceError(
                    f"validation failed for finalist(s) {', '.join(failed)}; see the log above"
                )
            return {"finalists": res}

        self.stage("validation", body, reports)

    def _validate_finalists(self, table: GaitTable) -> dict[str, Any]:
        """Physics validation of each coverage finalist; resumable finalist by finalist."""
        s, folder = self.s, self.out / "validation"
        key = stage_key(s, "validation")
        starts = validation_starts(s, self.world)
        atomic_write_json(folder / "starts.json", {"starts": starts.tolist(), "seed": s.seed})
        results: dict[str, Any] = {}
        for k in range(s.coverage_populations):
            sub = folder / f"pop{k}"
            done = read_done(sub, key)
            if done is not None and (sub / "report.json").exists():
                results[str(k)] = {"skipped": True, "wall_s": done["wall_s"]}
                continue
            t0 = time.perf_counter()
            try:
                validate(
                    read_chromosome(self.out / "coverage" / f"best_pop{k}.txt"), starts,
                    table=table, world=self.world, out_dir=sub, rrd=True, executor=self.executor,
                    max_steps=s.validate_max_steps, model=s.model, on_run=self.on_run,
                    meta={"finalist": k, "source": f"coverage/best_pop{k}.txt"},
                )  # fmt: skip
            except ValidationError as exc:  # a bad finalist must not stop the others
                self.log(f"validation of finalist {k} failed: {exc}")
                results[str(k)] = {"error": str(exc)}
                continue
            wall = time.perf_counter() - t0
            write_done(sub, key, wall)
            results[str(k)] = {"skipped": False, "wall_s": round(wall, 3)}
        return results


def validation_starts(s: ReproduceSettings, world: WorldSettings) -> np.ndarray:
    """The seeded coverage starts every finalist is validated from."""
    seq = np.random.SeedSequence([int(s.seed), VALIDATION_SEED_WORD])
    return coverage_starts(np.random.Generator(np.random.PCG64(seq)), s.validate_starts, world)


def resolve_settings(
    settings: ReproduceSettings | None = None,
    *,
    quick: bool = False,
    seed: int | None = None,
    validate_starts: int | None = None,
    model: str | Path | None = None,
) -> ReproduceSettings:
    """``settings`` (else paper scale, or ``quick_settings()``) with the overrides applied."""
    s = settings or (quick_settings() if quick else ReproduceSettings())
    if model is not None:
        s = dataclasses.replace(s, model=str(model))
    if seed is not None:
        s = dataclasses.replace(s, seed=int(seed))
    if validate_starts is not None:
        s = dataclasses.replace(s, validate_starts=int(validate_starts))
    check_settings(s)
    return s


def reproduce(
    out: str | Path,
    *,
    quick: bool = False,
    seed: int | None = None,
    workers: int | None = None,
    executor: Executor | None = None,
    validate_starts: int | None = None,
    settings: ReproduceSettings | None = None,
    world: WorldSettings | None = None,
    log: Callable[[str], None] | None = None,
    on_generation: OnGeneration | None = None,
    on_run: Callable[[dict[str, Any]], None] | None = None,
) -> dict[str, Any]:
    """Run (or resume) every stage into ``out``; return ``{"stages", "report", "wall_s"}``.

    ``settings`` wins over ``quick``; ``seed`` and ``validate_starts`` override its fields.
    ``executor`` runs the validation starts (default ``make_executor(None, workers)``: 1 =
    here, else a pool of ``workers`` processes, None = every core); calibration records its
    walks, so it runs in this process, and evolution runs here (the kernel uses every core).
    Each stage
    record says whether it ran now or was skipped as already done, and its wall time.
    ``on_generation`` (GA progress) and ``on_run`` (each finished validation run) are the
    progress callbacks; ``log`` gets one line per stage event (default: stderr).
    """
    out = Path(out)
    log = log or (lambda msg: print(msg, file=sys.stderr, flush=True))
    s = resolve_settings(settings, quick=quick, seed=seed, validate_starts=validate_starts)
    world = world or WorldSettings()
    t_all = time.perf_counter()
    check_folder(out, s)  # refuse a folder of other settings before writing anything
    out.mkdir(parents=True, exist_ok=True)
    doc = {"ReproduceSettings": s.to_dict(), **json.loads(settings_json(world))}
    atomic_write_text(out / "settings.json", json.dumps(doc, indent=2) + "\n")
    ex = executor or make_executor(None, workers)
    run = _Pipeline(out, s, world, ex, log, on_generation, on_run)
    try:
        table = run.calibration()
        navigation = run.navigation(table)
        run.coverage(table, navigation)
        run.validation(table)
    finally:  # the report says how far the run got, also when a stage failed
        total = time.perf_counter() - t_all
        try:
            ncpu = os.cpu_count() or 1
            report = write_report(out, s, world, run.stages, total_wall_s=total, ncpu=ncpu)
            log(f"[report] {report}")
        except Exception as exc:  # noqa: BLE001 - never mask the stage's own error
            log(f"[report] could not be written: {exc}")
    return {"stages": run.stages, "report": str(out / "REPORT.md"), "wall_s": round(total, 3)}


__all__ = [
    "ReproduceError",
    "ReproduceSettings",
    "check_settings",
    "quick_settings",
    "reproduce",
    "resolve_settings",
    "stage_key",
    "validation_starts",
]
