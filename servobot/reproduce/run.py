"""``reproduce(out)``: the whole reproduction into one run folder, resumable.

Stages, in order (each writes ``DIR/<stage>/done.json`` when complete and is skipped on a
rerun with the same settings; the evolution stages also resume from their checkpoints, and
validation resumes finalist by finalist)::

    1 calibration  DIR/calibration/gait_table.json, figure4.png     (MuJoCo, shipped gaits)
    2 navigation   DIR/navigation/best.txt, summary.json             (CGA, calibrated table)
    3 coverage     DIR/coverage/best_pop{k}.txt, figure9.*, figure10_pop{k}.png, DIR/figure8.png
    4 validation   DIR/validation/pop{k}/report.{json,md}, run{j}.rrd  (table vs physics)
                   DIR/validation/navigation_{fresh,handoffs}/report.{json,md}  (the section)
    5 robustness   DIR/robustness/robustness.{json,md,png}, runs/{world}/best_pop{k}/
                   (the finalists × every built-in physics world: the test matrix)
    6 colony       DIR/colony/best_pop{k}.txt, figure9.*, figure10_pop{k}.png, summary.json
                   (only with robots R ≥ 2: coverage learned by a colony of R, SPEC §7)
    7 colony_validation  DIR/colony_validation/pop{k}/report.{json,md}, tracks{j}.png,
                   run{j}.rrd (each colony finalist as a colony of R: table vs physics)
    8 report       DIR/REPORT.md                                      (always rewritten)

An envelope (``ReproduceSettings.envelope``, SPEC §9) makes navigation and coverage evolve in a
varied table world; their summaries then carry the envelope's figures (``envelope_*``) beside
the exact world's, and the envelope is part of every later stage's key. The robustness stage
runs ``servobot.robustness.matrix.run_matrix`` on the calibrated table, resumable cell by cell.

Budgets live in ``ReproduceSettings`` (paper scale by default, ``quick_settings()`` for a
first look). Before anything runs, the budgets are checked against the machine
(``reproduce_need``) and the folder is taken (``infra.rundir``: an OS lock, ``settings.json``
as the ownership record): a folder made with other settings is refused with a message naming
the differing fields, so results of different budgets never mix; ``force`` deletes only the
run's own files (``REPRODUCE_FILES``) and starts afresh. Progress reaches the outside through
``log(message)`` and ``on_generation`` / ``on_run`` callbacks.
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

from calibration.calibrate import (
    CALIBRATION_FILES,
    FIGURE_FILE,
    TABLE_FILE,
    calibrate,
    calibration_need,
)
from evolve.codec import read_chromosome
from evolve.colony_stage import check_capacity, run_colony_stage
from evolve.envelope import NONE, Envelope
from evolve.handoff import PosesError, read_poses
from evolve.population import OnGeneration
from evolve.settings import WorldSettings, settings_json
from evolve.stages import STAGE_FILES, run_coverage, run_navigation, stage_need
from evolve.starts import colony_starts, coverage_starts
from evolve.table import GaitTable, load_table
from infra.bounds import Need, check_need, is_finite_number
from infra.executors import Executor, make_executor
from infra.io import atomic_write_json, check_free_space, read_json
from infra.rundir import RECORD_FILE, run_folder
from servobot.recording import Recording, calibration_recorder, log_calibration_result
from servobot.reproduce.report import write_report
from servobot.reproduce.settings import (
    COLONY_FIELDS,
    ROBUSTNESS_WORLDS,
    STAGES,
    ReproduceError,
    ReproduceSettings,
    check_settings,
    quick_settings,
    stage_key,
)
from servobot.robustness.matrix import ROBUSTNESS_FILES, run_matrix
from servobot.validation.colony import colony_kind
from servobot.validation.colony_report import per_robot
from servobot.validation.lone import (
    VALIDATION_FILES,
    ValidationError,
    clear_navigation_starts,
    execute,
    plan_validation,
    sample_poses,
    validation_need,
)

VALIDATION_SEED_WORD = 2
"""Second entropy word of the validation starts' SeedSequence (stages use 0 and 1)."""
COLONY_STARTS_WORD = 2
"""Third entropy word of the colony validation's starts (the navigation section's: 1)."""
NAVIGATION_VALIDATIONS = ("navigation_fresh", "navigation_handoffs")
"""Folders of the navigation section's physics validations: from fresh navigation starts, and
from the coverage finalists' hand-off poses."""
RECORDING_FILE = "calibration.rrd"
"""The calibration stage's recording of the 16 walks."""
DONE = "done.json"
"""A stage's completion marker: its settings key, wall time and a summary."""
REPRODUCE_FILES = (
    "REPORT.md", "figure8.png", f"calibration/{RECORDING_FILE}",
    *(f"{stage}/{f}" for stage in STAGES for f in (DONE, RECORD_FILE)),
    *(f"calibration/{f}" for f in CALIBRATION_FILES),
    *(f"{stage}/{f}" for stage in ("navigation", "coverage", "colony") for f in STAGE_FILES),
    "validation/starts.json", "colony_validation/starts.json",
    *(f"validation/{sub}/{f}" for sub in ("pop*", *NAVIGATION_VALIDATIONS)
      for f in (DONE, RECORD_FILE, *VALIDATION_FILES)),
    *(f"colony_validation/pop*/{f}" for f in (DONE, RECORD_FILE, *VALIDATION_FILES)),
    *(f"robustness/{f}" for f in ROBUSTNESS_FILES),
)  # fmt: skip
"""Every file a reproduction writes under its folder besides ``settings.json``."""


# --------------------------------------------------------------------------- markers


def read_done(folder: Path, key: dict[str, Any]) -> dict[str, Any] | None:
    """The stage's done record if it finished with these settings; None if not finished;
    ``ReproduceError`` if it finished with other settings or the marker is unreadable."""
    path = folder / DONE
    if not path.exists() and not path.is_symlink():
        return None
    doc = read_json(path, what="stage marker", error=ReproduceError)
    ok = isinstance(doc, dict) and isinstance(doc.get("settings"), dict)
    ok = ok and isinstance(doc.get("info", {}), dict) and _is_number(doc.get("wall_s"))
    if not ok:
        raise ReproduceError(f"{path}: not a stage marker; delete it to redo the stage")
    stored = doc["settings"]
    if stored != key:
        diff = sorted(k for k in set(stored) | set(key) if stored.get(k) != key.get(k))
        detail = ", ".join(f"{k}: {stored.get(k)!r} here, {key.get(k)!r} asked" for k in diff)
        raise ReproduceError(
            f"{folder} was made with other settings ({detail}); use a fresh --out DIR"
        )
    return doc


def _is_number(v: Any) -> bool:
    return isinstance(v, int | float) and not isinstance(v, bool)


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


def reproduce_need(s: ReproduceSettings, world: WorldSettings, workers: int | None) -> Need:
    """Peak memory and optimistic wall time of a whole reproduction (``infra.bounds.Need``)."""
    need = calibration_need(s.calibration(), None)
    need += stage_need(s.navigation_ga(), world.navigation_steps)
    need += stage_need(s.coverage_ga(), world.coverage_steps)
    for _ in range(s.coverage_populations):
        need += validation_need(s.validate_starts, s.validate_max_steps, workers, True)[0]
    for _ in NAVIGATION_VALIDATIONS:
        n = s.validate_navigation_starts
        need += validation_need(n, world.navigation_steps, workers, False)[0]
    if s.model is None:
        for _ in range(s.matrix_finalists() * len(ROBUSTNESS_WORLDS)):
            need += validation_need(s.robustness_starts, s.robustness_steps, workers, False)[0]
    if s.colony() is not None:
        need += stage_need(s.coverage_ga(), world.coverage_steps * s.robots)
        for _ in range(s.coverage_populations):
            need += colony_validation_need(s, workers)[0]
    return need


def colony_validation_need(s: ReproduceSettings, workers: int | None) -> tuple[Need, int]:
    """(Need, recording bytes) of one colony finalist's physics validation: its colony starts of
    R robots × ``validate_max_steps`` steps each, recorded (as ``servobot validate --robots``)."""
    return validation_need(s.colony_validate_starts, s.validate_max_steps * s.robots, workers,
                           True)  # fmt: skip


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

    @property
    def envelope(self) -> Envelope:
        """The envelope navigation and coverage evolve in."""
        return self.s.envelope_value()

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
            with Recording.for_calibration(folder / RECORDING_FILE) as rec:
                res = calibrate(
                    folder, settings, command="servobot reproduce (stage 1)",
                    **calibration_recorder(rec, settings, "servobot reproduce (stage 1)"),
                )  # fmt: skip
                log_calibration_result(rec, res)
            return {}

        self.stage("calibration", body, [folder / TABLE_FILE, folder / FIGURE_FILE])
        return load_table(str(folder / TABLE_FILE))

    def navigation(self, table: GaitTable) -> np.ndarray:
        folder = self.out / "navigation"

        def body() -> dict[str, Any]:
            summ = run_navigation(
                self.out, table=table, ga=self.s.navigation_ga(), world=self.world,
                resume=True, on_generation=self.on_generation, envelope=self.envelope,
            )  # fmt: skip
            info = {"dock_success": summ["dock_success"], "chosen": summ["chosen_population"]}
            return info | _envelope_info(summ, "envelope_dock_success")

        self.stage("navigation", body, [folder / "best.txt", folder / "summary.json"])
        return read_chromosome(folder / "best.txt")

    def coverage(self, table: GaitTable, navigation: np.ndarray) -> None:
        folder = self.out / "coverage"

        def body() -> dict[str, Any]:
            summ = run_coverage(
                self.out, navigation=navigation, table=table, ga=self.s.coverage_ga(),
                world=self.world, resume=True, on_generation=self.on_generation,
                envelope=self.envelope,
            )  # fmt: skip
            info = {"final_mean_inner_percent": summ["final_mean_inner_percent"]}
            return info | _envelope_info(summ, "envelope_final_mean_inner_percent")

        finalists = [folder / f"best_pop{k}.txt" for k in range(self.s.coverage_populations)]
        self.stage("coverage", body, [folder / "summary.json", *finalists])

    def validation(self, table: GaitTable) -> None:
        folder = self.out / "validation"
        reports = [folder / f"pop{k}" / "report.json" for k in range(self.s.coverage_populations)]

        def body() -> dict[str, Any]:
            finalists, sections = self._finalist_validations(), self._navigation_validations()
            done = self._validate_all(table, finalists | sections)
            res = {name: done[name] for name in finalists}
            nav = {name: done[name] for name in sections}
            failed = [f"finalist {k}" for k, r in res.items() if "error" in r]
            failed += [f"the navigation section ({k})" for k, r in nav.items() if "error" in r]
            if failed:
                raise ReproduceError(
                    f"validation failed for {', '.join(failed)}; see the log above"
                )
            return {"finalists": res, "navigation": nav}

        self.stage("validation", body, reports)

    def robustness(self) -> None:
        """The coverage finalists through the physics test matrix (every built-in world) into
        ``DIR/robustness``; the matrix resumes cell by cell. Not run for another robot
        (``model``): the matrix's worlds are variants of the shipped one."""
        folder = self.out / "robustness"
        n = self.s.matrix_finalists()

        def body() -> dict[str, Any]:
            if self.s.model is not None:
                self.log("[robustness] the matrix's worlds vary the shipped robot; not run for "
                         f"{self.s.model}")  # fmt: skip
                return {"note": "not run: the matrix's worlds are variants of the shipped robot"}
            path = self.out / "coverage" / "summary.json"
            coverage = read_json(path, what="coverage summary", error=ReproduceError)
            inner = coverage.get("final_inner_percent") if isinstance(coverage, dict) else None
            if not (isinstance(inner, list) and inner and all(map(is_finite_number, inner))):
                raise ReproduceError(
                    f"{path}: field final_inner_percent: a list of finite numbers (one per "
                    "population) expected; the coverage stage's summary was edited or damaged: "
                    "rerun with --force"
                )
            finalists = [self.out / "coverage" / f"best_pop{k}.txt"
                         for k in best_finalists(inner, n)]  # fmt: skip
            doc = run_matrix(
                finalists, folder, self.s.robustness(self.out), executor=self.executor,
                resume=True, on_run=self.on_run, log=self.log,
            )  # fmt: skip
            return robustness_info(doc)

        outputs = [] if self.s.model is not None else [folder / "robustness.json"]
        self.stage("robustness", body, outputs)

    def colony(self, table: GaitTable, navigation: np.ndarray) -> None:
        """Coverage learned by a colony of R (SPEC §7, ``evolve.colony_stage``) into
        ``DIR/colony``, as ``servobot evolve colony``: the coverage stage's GA budget, the
        navigation section fixed, the envelope; resumes from its checkpoints."""
        folder = self.out / "colony"

        def body() -> dict[str, Any]:
            summ = run_colony_stage(
                self.out, navigation=navigation, table=table, ga=self.s.coverage_ga(),
                world=self.world, colony=self.s.colony(), resume=True,
                on_generation=self.on_generation, envelope=self.envelope,
            )  # fmt: skip
            return colony_info(summ) | _envelope_info(summ, "envelope_final_mean_inner_percent")

        finalists = [folder / f"best_pop{k}.txt" for k in range(self.s.coverage_populations)]
        self.stage("colony", body, [folder / "summary.json", *finalists])

    def colony_validation(self, table: GaitTable) -> None:
        """Each colony finalist as a colony of R in the table world and in physics (as
        ``servobot validate --robots R --rrd``) into ``DIR/colony_validation/pop{k}``, from the
        same seeded colony starts; resumes finalist by finalist."""
        folder = self.out / "colony_validation"
        n = self.s.coverage_populations

        def body() -> dict[str, Any]:
            todo = self._finalist_validations("colony_validation", "colony", self.s.colony())
            res = self._validate_all(table, todo, "colony_validation")
            failed = [k for k, r in res.items() if "error" in r]
            if failed:
                raise ReproduceError(f"colony validation failed for colony finalist "
                                     f"{', '.join(failed)}; see the log above")  # fmt: skip
            return {"finalists": res, **colony_validation_info(folder, n)}

        self.stage("colony_validation", body, [folder / f"pop{k}" / "report.json"
                                               for k in range(n)])  # fmt: skip

    def _finalist_validations(
        self, stage: str = "validation", source: str = "coverage", colony: Any = None
    ) -> dict[str, Any]:
        """The physics validation of each finalist ``DIR/{source}/best_pop{k}.txt`` into
        ``DIR/{stage}/pop{k}``, every one from the stage's seeded starts
        (``validation_starts``, saved as ``DIR/{stage}/starts.json``), for ``_validate_all``;
        with a ``colony`` (``ColonySettings``), as colonies of its robots."""
        s, folder = self.s, self.out / stage
        starts = validation_starts(s, self.world, colony)
        atomic_write_json(folder / "starts.json", {"starts": starts.tolist(), "seed": s.seed})
        what = "finalist" if colony is None else f"{source} finalist"
        kind = {} if colony is None else {"kind": colony_kind(colony)}
        return {
            str(k): (
                folder / f"pop{k}",
                f"{what} {k}",
                read_chromosome(self.out / source / f"best_pop{k}.txt"),
                starts,
                {"rrd": True, "max_steps": s.validate_max_steps, **kind,
                 "meta": {"finalist": k, "source": f"{source}/best_pop{k}.txt"}},
            )  # fmt: skip
            for k in range(s.coverage_populations)
        }

    def _navigation_validations(self) -> dict[str, Any]:
        """Physics validation of the navigation section alone (navigation mode): from fresh
        navigation starts and from hand-off poses of the coverage finalists
        (``_validate_all``)."""
        section = read_chromosome(self.out / "navigation" / "best.txt")
        fresh, handoffs, powers = navigation_validation_starts(self.s, self.world, self.out)
        return {
            name: (
                self.out / "validation" / name, f"the navigation section ({name})", section,
                starts, {"powers": volts, "meta": {"source": "navigation/best.txt",
                                                   "starts": name}},
            )  # fmt: skip
            for name, starts, volts in zip(NAVIGATION_VALIDATIONS, (fresh, handoffs),
                                           (None, powers), strict=True)  # fmt: skip
        }

    def _validate_all(
        self, table: GaitTable, todo: dict[str, Any], stage: str = "validation"
    ) -> dict[str, Any]:
        """Each validation ``name: (folder, what, bits, starts, options)`` of ``stage``, every
        one's runs as one batch on the executor. A validation that finished with these
        settings is skipped; one without starts is noted; a bad input is that validation's
        ``error`` and does not stop the others."""
        key = stage_key(self.s, stage)
        results: dict[str, Any] = {}
        plans: dict[str, tuple[Path, Any]] = {}
        for name, (sub, what, bits, starts, options) in todo.items():
            done = read_done(sub, key)
            if done is not None and (sub / "report.json").exists():
                results[name] = {"skipped": True, "wall_s": done["wall_s"]}
            elif not len(starts):
                results[name] = {"skipped": True, "wall_s": 0.0, "note": "no poses"}
            else:
                try:
                    plans[name] = (sub, plan_validation(
                        bits, starts, table=table, world=self.world, out_dir=sub,
                        model=self.s.model, **options,
                    ))  # fmt: skip
                except ValidationError as exc:
                    self.log(f"validation of {what} failed: {exc}")
                    results[name] = {"error": str(exc)}
        reports = execute([plan for _, plan in plans.values()], self.executor, self.on_run)
        for (name, (sub, _)), report in zip(plans.items(), reports, strict=True):
            wall = report["summary"]["wall_s"]
            write_done(sub, key, wall)
            results[name] = {"skipped": False, "wall_s": round(wall, 3)}
        return {name: results[name] for name in todo}


def _envelope_info(summary: dict[str, Any], figure: str) -> dict[str, Any]:
    """A stage summary's envelope and its headline figure in it (none in the exact world)."""
    if "envelope" not in summary:
        return {}
    return {"envelope": summary["envelope"], figure: summary[figure]}


def colony_info(summary: dict[str, Any]) -> dict[str, Any]:
    """The colony stage's done record: R, Figure 9's final colony inner % (mean and per
    population), the same bests alone, and per population the table world's docks per robot
    and station waits per run on the test starts (``evolve.colony_stage.final_test``)."""
    keys = ("docks_per_robot", "station_waits_per_run", "robot_inner_percent")
    return {
        "robots": summary["robots"],
        "final_mean_inner_percent": summary["final_mean_inner_percent"],
        "final_inner_percent": summary["final_inner_percent"],
        "one_robot_final_mean_inner_percent": summary["one_robot_final_mean_inner_percent"],
        "final_test": [{k: t[k] for k in ("population", *keys)} for t in summary["final_test"]],
    }


def colony_validation_info(folder: Path, n: int) -> dict[str, Any]:
    """The colony validation's numbers (its done record; REPORT.md shows them): per colony
    finalist ``k`` (``folder/pop{k}/report.json``) the colony inner % in each world and the gap
    table − physics (pp), both over the runs whose physics finished (None when none did), each
    robot's docks and station waits per run in each world (``per_robot``), physics errors, the
    robots live at the end per run in each world (``live_at_end``); ``gap_inner_pp``: the mean
    gap over the finalists that have one."""
    finalists: dict[str, Any] = {}
    for k in range(n):
        rep = read_json(folder / f"pop{k}" / "report.json", what="colony validation report",
                        error=ReproduceError)  # fmt: skip
        sm = rep["summary"]
        gap = sm.get("gap", {})
        finalists[str(k)] = {
            "runs_ok": sm["physics_ok"],
            "starts": sm["starts"],
            "table_inner_percent": sm["table_paired"].get("inner_pct"),
            "physics_inner_percent": sm["physics"].get("inner_pct"),
            "gap_inner_pp": gap["inner_pct_pp"] if gap.get("runs") else None,
            "docks": per_robot(rep, "docks"),
            "station_waits": per_robot(rep, "station_waits"),
            "physics_errors": sm["physics_errors"],
            "live_at_end": {w: sm[key].get("live_at_end_per_run")
                            for w, key in (("table", "table_paired"), ("physics", "physics"))},
        }  # fmt: skip
    gaps = [f["gap_inner_pp"] for f in finalists.values() if f["gap_inner_pp"] is not None]
    return {"colony_finalists": finalists,
            "gap_inner_pp": float(np.mean(gaps)) if gaps else None}  # fmt: skip


def best_finalists(inner_percent: list[float], n: int) -> list[int]:
    """Indices of the ``n`` best populations by their final Figure 9 test (inner %), best
    first; ties by index."""
    return sorted(range(len(inner_percent)), key=lambda k: (-inner_percent[k], k))[:n]


def robustness_info(doc: dict[str, Any]) -> dict[str, Any]:
    """The robustness stage's done record: the table world's and each physics world's mean
    inner %, each world's drop vs ``shipped`` (pp) and physics errors."""
    return {
        "table_inner_percent": doc["table_inner_percent"],
        "worlds": {
            w["name"]: {k: w[k] for k in ("physics_inner_percent", "drop_vs_shipped_pp",
                                          "physics_errors")}
            for w in doc["worlds"]
        },
    }  # fmt: skip


def navigation_validation_starts(
    s: ReproduceSettings, world: WorldSettings, out: Path
) -> tuple[np.ndarray, np.ndarray, np.ndarray | None]:
    """(fresh navigation starts, hand-off poses, their powers) of the navigation section's
    validation: ``s.validate_navigation_starts`` of each, seeded; the hand-off poses drawn
    without replacement from ``coverage/handoffs.csv`` (those the arena cannot hold left
    out; none when the finalists never handed over)."""
    seq = np.random.SeedSequence([int(s.seed), VALIDATION_SEED_WORD, 1])
    rng = np.random.Generator(np.random.PCG64(seq))
    n = s.validate_navigation_starts
    fresh = clear_navigation_starts(rng, n, world)
    try:
        poses, powers = sample_poses(*read_poses(out / "coverage" / "handoffs.csv"), None,
                                     rng, world)  # fmt: skip
    except (PosesError, ValidationError):  # no hand-off (or none the arena can hold)
        return fresh, np.empty((0, 3)), None
    return (fresh, *sample_poses(poses, powers, min(n, len(poses)), rng, world))


def validation_starts(
    s: ReproduceSettings, world: WorldSettings, colony: Any = None
) -> np.ndarray:
    """The seeded coverage starts every finalist is validated from ((N, 3)); with a
    ``colony`` (``ColonySettings``), the ``colony_validate_starts`` colony starts every colony
    finalist is validated from ((N, R, 3), ``evolve.starts.colony_starts``)."""
    if colony is None:
        seq = np.random.SeedSequence([int(s.seed), VALIDATION_SEED_WORD])
        return coverage_starts(np.random.Generator(np.random.PCG64(seq)), s.validate_starts,
                               world)  # fmt: skip
    seq = np.random.SeedSequence([int(s.seed), VALIDATION_SEED_WORD, COLONY_STARTS_WORD])
    rng = np.random.Generator(np.random.PCG64(seq))
    return colony_starts(rng, s.colony_validate_starts, world, colony)


def resolve_settings(
    settings: ReproduceSettings | None = None,
    *,
    quick: bool = False,
    seed: int | None = None,
    validate_starts: int | None = None,
    model: str | Path | None = None,
    envelope: str | Path | None = None,
    robots: int | None = None,
    **colony: Any,
) -> ReproduceSettings:
    """``settings`` (else paper scale, or ``quick_settings()``) with the overrides applied
    and checked (``check_settings``: a bad envelope file raises ``EnvelopeError``);
    ``robots``: the colony stages' R; ``colony``: their ``COLONY_FIELDS`` by name (e.g.
    ``colony_blocking``, ``colony_fitness``). None leaves a setting as it is."""
    unknown = set(colony) - set(COLONY_FIELDS)
    if unknown:
        raise TypeError(f"resolve_settings: not a colony setting: {', '.join(sorted(unknown))}")
    s = settings or (quick_settings() if quick else ReproduceSettings())
    overrides = {"robots": robots, **colony, "seed": seed, "validate_starts": validate_starts,
                 "model": None if model is None else str(model),
                 "envelope": None if envelope is None else str(envelope)}  # fmt: skip
    s = dataclasses.replace(s, **{k: v for k, v in overrides.items() if v is not None})
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
    envelope: str | Path | None = None,
    settings: ReproduceSettings | None = None,
    world: WorldSettings | None = None,
    log: Callable[[str], None] | None = None,
    on_generation: OnGeneration | None = None,
    on_run: Callable[[dict[str, Any]], None] | None = None,
    force: bool = False,
) -> dict[str, Any]:
    """Run (or resume) every stage into ``out``; return ``{"stages", "report", "wall_s"}``.

    ``settings`` wins over ``quick``; ``seed``, ``validate_starts`` and ``envelope`` (``none``,
    ``default`` or an envelope file, SPEC §9) override its fields. With ``settings.robots``
    R ≥ 2 the colony stages run after the others (more robots than the start region holds
    are refused first, ``StageError``).
    ``executor`` runs the validation starts (default ``make_executor(None, workers)``: 1 =
    here, else a pool of ``workers`` processes, None = every core); calibration records its
    walks, so it runs in this process, and evolution runs here (the kernel uses every core).
    Each stage
    record says whether it ran now or was skipped as already done, and its wall time.
    ``on_generation`` (GA progress) and ``on_run`` (each finished physics run of the
    validation, the robustness matrix and the colony validation) are the
    progress callbacks; ``log`` gets one line per stage event (default: stderr). ``force``
    deletes the files of a run made with other settings in ``out`` and starts afresh.
    """
    out = Path(out)
    log = log or (lambda msg: print(msg, file=sys.stderr, flush=True))
    s = resolve_settings(settings, quick=quick, seed=seed, validate_starts=validate_starts,
                         envelope=envelope)  # fmt: skip
    world = world or WorldSettings()
    if s.colony() is not None:  # before any stage: more robots than the start region holds
        check_capacity(world, s.colony())
    check_need(reproduce_need(s, world, workers), "the reproduction's budgets")
    t_all = time.perf_counter()
    doc = {"ReproduceSettings": s.to_dict(), **json.loads(settings_json(world))}
    if s.envelope_value() != NONE:  # the envelope's fields, also when named by a file
        doc["Envelope"] = s.envelope_value().to_dict()
    with run_folder(out, doc, owned=REPRODUCE_FILES, resume=True, force=force,
                    command="reproduce"):
        disk = (
            s.coverage_populations
            * validation_need(s.validate_starts, s.validate_max_steps, workers, True)[1]
        )
        if s.colony() is not None:
            disk += s.coverage_populations * colony_validation_need(s, workers)[1]
        check_free_space(out, disk, what="the validation recordings")
        ex = executor or make_executor(None, workers)
        run = _Pipeline(out, s, world, ex, log, on_generation, on_run)
        try:
            table = run.calibration()
            navigation = run.navigation(table)
            run.coverage(table, navigation)
            run.validation(table)
            run.robustness()
            if s.colony() is not None:
                run.colony(table, navigation)
                run.colony_validation(table)
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
    "REPRODUCE_FILES",
    "ReproduceError",
    "ReproduceSettings",
    "check_settings",
    "quick_settings",
    "reproduce",
    "reproduce_need",
    "resolve_settings",
    "best_finalists",
    "colony_info",
    "colony_validation_info",
    "robustness_info",
    "stage_key",
    "validation_starts",
]
