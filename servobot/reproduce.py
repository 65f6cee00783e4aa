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
from calibration.measure import CalibrationSettings
from evolve.codec import read_chromosome
from evolve.population import OnGeneration
from evolve.settings import GASettings, WorldSettings, navigation_ga_settings, settings_json
from evolve.stages import run_coverage, run_navigation
from evolve.starts import coverage_starts
from evolve.table import GaitTable, load_table
from infra.io import atomic_write_json, atomic_write_text
from servobot.recording import Recording, calibration_recorder
from servobot.reproduce_report import STAGES, write_report
from servobot.validate import ValidationError, validate

VALIDATION_SEED_WORD = 2
"""Second entropy word of the validation starts' SeedSequence (stages use 0 and 1)."""
RECORDING_FILE = "calibration.rrd"
"""The calibration stage's recording of the 16 walks."""
DONE = "done.json"
"""A stage's completion marker: its settings key, wall time and a summary."""


class ReproduceError(RuntimeError):
    """The run folder cannot be used (other settings, missing inputs); the message says why."""


@dataclass(frozen=True)
class ReproduceSettings:
    """Budgets of one reproduction. Defaults = the paper's scale (SPEC §5, §6)."""

    calibration_cycles: int = 20
    """Measured gait cycles per gait (after ``calibration_settle_cycles``)."""
    calibration_settle_cycles: int = 1
    """Unmeasured cycles each gait walks first."""
    navigation_populations: int = 5
    """Independent navigation populations (SPEC §6)."""
    navigation_population_size: int = 256
    """Individuals per navigation population (SPEC §6)."""
    navigation_generations: int = 1024
    """Navigation generations (SPEC §6)."""
    coverage_populations: int = 5
    """Independent coverage populations; each final best is a finalist (SPEC §5)."""
    coverage_population_size: int = 256
    """Individuals per coverage population (SPEC §5)."""
    coverage_generations: int = 512
    """Coverage generations (SPEC §5)."""
    test_starts: int = 100
    """Fresh start poses of the navigation report and of Figure 9 (SPEC §5, §6)."""
    validate_starts: int = 20
    """Coverage start poses per finalist in the physics validation (issue 4: ≥ 20)."""
    validate_max_steps: int = 600
    """Steps of a validation run (SPEC §5: 600)."""
    seed: int = 0
    """Seed of every random draw (calibration noise, GA, test and validation starts)."""

    def calibration(self) -> CalibrationSettings:
        """Settings of the calibration stage (the shipped gait parameters, no fit)."""
        return CalibrationSettings(
            cycles=self.calibration_cycles,
            settle_cycles=self.calibration_settle_cycles,
            seed=self.seed,
        )

    def navigation_ga(self) -> GASettings:
        """GA settings of the navigation stage."""
        return navigation_ga_settings(
            populations=self.navigation_populations,
            population_size=self.navigation_population_size,
            generations=self.navigation_generations,
            test_starts=self.test_starts,
            seed=self.seed,
        )

    def coverage_ga(self) -> GASettings:
        """GA settings of the coverage stage."""
        return dataclasses.replace(
            GASettings(),
            populations=self.coverage_populations,
            population_size=self.coverage_population_size,
            generations=self.coverage_generations,
            test_starts=self.test_starts,
            seed=self.seed,
        )

    def to_dict(self) -> dict[str, Any]:
        return dataclasses.asdict(self)


def quick_settings(**overrides: Any) -> ReproduceSettings:
    """A first look in a few minutes on 2 cores: the paper's 5 populations but of 64
    individuals, 256 navigation and 128 coverage generations, 5 calibration cycles, and 3
    full-length (600-step) validation starts per finalist, so that docking and recharging
    show in physics."""
    base = ReproduceSettings(
        calibration_cycles=5,
        navigation_population_size=64,
        navigation_generations=256,
        coverage_population_size=64,
        coverage_generations=128,
        validate_starts=3,
    )
    return dataclasses.replace(base, **overrides)


_STAGE_FIELDS: dict[str, tuple[str, ...]] = {
    "calibration": ("calibration_cycles", "calibration_settle_cycles", "seed"),
    "navigation": (
        "navigation_populations",
        "navigation_population_size",
        "navigation_generations",
        "test_starts",
    ),
    "coverage": ("coverage_populations", "coverage_population_size", "coverage_generations"),
    "validation": ("validate_starts", "validate_max_steps"),
}


def stage_key(settings: ReproduceSettings, stage: str) -> dict[str, Any]:
    """The settings a stage's result depends on: its own fields and those of earlier stages."""
    d = settings.to_dict()
    key: dict[str, Any] = {}
    for s in STAGES[: STAGES.index(stage) + 1]:
        key.update({f: d[f] for f in _STAGE_FIELDS[s]})
    return key


def check_settings(s: ReproduceSettings) -> None:
    """Every budget is an integer ≥ 1 (settle cycles and seed ≥ 0), else ``ReproduceError``."""
    for f in dataclasses.fields(s):
        v = getattr(s, f.name)
        low = 0 if f.name in ("calibration_settle_cycles", "seed") else 1
        if not isinstance(v, int) or v < low:
            raise ReproduceError(f"setting {f.name} must be an integer ≥ {low}, got {v!r}")


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
    workers: int | None
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
                    table=table, world=self.world, out_dir=sub, rrd=True, workers=self.workers,
                    max_steps=s.validate_max_steps, on_run=self.on_run,
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
) -> ReproduceSettings:
    """``settings`` (else paper scale, or ``quick_settings()``) with the overrides applied."""
    s = settings or (quick_settings() if quick else ReproduceSettings())
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
    validate_starts: int | None = None,
    settings: ReproduceSettings | None = None,
    world: WorldSettings | None = None,
    log: Callable[[str], None] | None = None,
    on_generation: OnGeneration | None = None,
    on_run: Callable[[dict[str, Any]], None] | None = None,
) -> dict[str, Any]:
    """Run (or resume) every stage into ``out``; return ``{"stages", "report", "wall_s"}``.

    ``settings`` wins over ``quick``; ``seed`` and ``validate_starts`` override its fields.
    ``workers``: processes for validation (None = every core; calibration records its walks,
    so it runs in this process). Each stage
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
    run = _Pipeline(out, s, world, workers, log, on_generation, on_run)
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
