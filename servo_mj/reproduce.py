"""``servobot reproduce``: the whole reproduction into one run folder, resumable.

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
and the differing fields, so results of different budgets never mix.
"""

from __future__ import annotations

import argparse
import dataclasses
import datetime as dt
import json
import os
import platform
import sys
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from evolve.io import atomic_write_json, atomic_write_text
from evolve.settings import GASettings, WorldSettings, navigation_ga_settings, settings_json
from evolve.table import PAPER_TABLE, GaitTable, GaitTableError, load_table

STAGES = ("calibration", "navigation", "coverage", "validation")
"""The stages with a ``done.json`` marker, in order; the report is always rewritten."""
VALIDATION_SEED_WORD = 2
"""Second entropy word of the validation starts' SeedSequence (stages use 0 and 1)."""
DONE = "done.json"
CALIBRATION_TOLERANCE = np.array([1.0, 1.0, 1.5])
"""Target accuracy of (F cm, T cm, dH deg) against Figure 4 (issue 2), for the report."""


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
    "coverage": (
        "coverage_populations",
        "coverage_population_size",
        "coverage_generations",
    ),
    "validation": ("validate_starts", "validate_max_steps"),
}


def stage_key(settings: ReproduceSettings, stage: str) -> dict[str, Any]:
    """The settings a stage's result depends on: its own fields and those of earlier stages."""
    d = settings.to_dict()
    key: dict[str, Any] = {}
    for s in STAGES[: STAGES.index(stage) + 1]:
        key.update({f: d[f] for f in _STAGE_FIELDS[s]})
    return key


# --------------------------------------------------------------------------- markers


def _read_done(folder: Path, key: dict[str, Any]) -> dict[str, Any] | None:
    """The stage's done record if it finished with these settings; None if not finished."""
    path = folder / DONE
    if not path.exists():
        return None
    try:
        doc = json.loads(path.read_text())
    except (OSError, json.JSONDecodeError) as exc:
        raise ReproduceError(f"{path}: unreadable stage marker ({exc}); delete it to redo") from exc
    stored = doc.get("settings", {})
    if stored != key:
        diff = sorted(k for k in set(stored) | set(key) if stored.get(k) != key.get(k))
        detail = ", ".join(f"{k}: {stored.get(k)!r} here, {key.get(k)!r} asked" for k in diff)
        raise ReproduceError(
            f"{folder} was made with other settings ({detail}); use a fresh --out DIR"
        )
    return doc


def _write_done(folder: Path, key: dict[str, Any], wall_s: float, **extra: Any) -> None:
    atomic_write_json(
        folder / DONE,
        {
            "settings": key,
            "wall_s": round(wall_s, 3),
            "finished_utc": dt.datetime.now(dt.timezone.utc).isoformat(timespec="seconds"),
            **extra,
        },
    )


# --------------------------------------------------------------------------- stages


def _calibrate(folder: Path, s: ReproduceSettings, workers: int, record: bool) -> dict:
    """``servobot calibrate`` with the shipped gait library into ``folder``: gait_table.json,
    figure4.png, and (``record``) calibration.rrd of the walks."""
    from calibration import cli as calibrate_cli

    argv = [
        "--out", str(folder),
        "--cycles", str(s.calibration_cycles),
        "--settle-cycles", str(s.calibration_settle_cycles),
        "--seed", str(s.seed),
        "--workers", str(max(1, workers)),
    ]  # fmt: skip
    if record:
        argv += ["--rrd", str(folder / "calibration.rrd")]
    rc = calibrate_cli.main(argv)
    if rc != 0:
        raise ReproduceError(f"calibration failed (servobot calibrate exit status {rc})")
    return {}


def _validation_starts(s: ReproduceSettings, world: WorldSettings) -> np.ndarray:
    from evolve.stages import coverage_starts

    seq = np.random.SeedSequence([int(s.seed), VALIDATION_SEED_WORD])
    return coverage_starts(np.random.Generator(np.random.PCG64(seq)), s.validate_starts, world)


def _validate_finalists(
    out: Path,
    s: ReproduceSettings,
    table: GaitTable,
    world: WorldSettings,
    workers: int | None,
    progress: bool,
    key: dict[str, Any],
    log: Callable[[str], None],
) -> dict[str, Any]:
    """Physics validation of each coverage finalist; resumable finalist by finalist."""
    from tqdm import tqdm

    from evolve.codec import read_chromosome
    from servo_mj.validate import ValidationError, validate

    starts = _validation_starts(s, world)
    folder = out / "validation"
    folder.mkdir(parents=True, exist_ok=True)
    atomic_write_json(folder / "starts.json", {"starts": starts.tolist(), "seed": s.seed})
    results: dict[str, Any] = {}
    todo = []
    for k in range(s.coverage_populations):
        sub = folder / f"pop{k}"
        done = _read_done(sub, key)
        if done is not None and (sub / "report.json").exists():
            results[str(k)] = {"skipped": True, "wall_s": done["wall_s"]}
        else:
            todo.append(k)
    bar = tqdm(
        total=len(todo) * len(starts),
        desc="validation runs",
        unit="run",
        disable=not progress,
        file=sys.stderr,
    )
    try:
        for k in todo:
            sub = folder / f"pop{k}"
            bits = read_chromosome(out / "coverage" / f"best_pop{k}.txt")
            t0 = time.perf_counter()
            try:
                validate(
                    bits,
                    starts,
                    table=table,
                    world=world,
                    out_dir=sub,
                    rrd=True,
                    workers=workers,
                    max_steps=s.validate_max_steps,
                    on_run=lambda _rec: bar.update(1),
                    meta={"finalist": k, "source": f"coverage/best_pop{k}.txt"},
                )
            except ValidationError as exc:  # a bad finalist must not stop the others
                log(f"validation of finalist {k} failed: {exc}")
                results[str(k)] = {"error": str(exc)}
                continue
            wall = time.perf_counter() - t0
            _write_done(sub, key, wall)
            results[str(k)] = {"skipped": False, "wall_s": round(wall, 3)}
    finally:
        bar.close()
    return results


def reproduce(
    out: str | Path,
    *,
    quick: bool = False,
    seed: int | None = None,
    workers: int | None = None,
    validate_starts: int | None = None,
    settings: ReproduceSettings | None = None,
    world: WorldSettings | None = None,
    progress: bool = True,
    log: Callable[[str], None] | None = None,
) -> dict[str, Any]:
    """Run (or resume) every stage into ``out``; return ``{"stages": {...}, "report": path}``.

    ``settings`` wins over ``quick``; ``seed`` and ``validate_starts`` override its fields.
    ``workers``: processes for calibration and validation (None = every core). Each stage
    record says whether it ran now or was skipped as already done, and its wall time.
    """
    out = Path(out)
    log = log or (lambda msg: print(msg, file=sys.stderr, flush=True))
    s = settings or (quick_settings() if quick else ReproduceSettings())
    if seed is not None:
        s = dataclasses.replace(s, seed=int(seed))
    if validate_starts is not None:
        s = dataclasses.replace(s, validate_starts=int(validate_starts))
    _check_settings(s)
    world = world or WorldSettings()
    ncpu = os.cpu_count() or 1
    t_all = time.perf_counter()
    _check_folder(out, s)  # refuse a folder of other settings before writing anything
    out.mkdir(parents=True, exist_ok=True)
    atomic_write_text(
        out / "settings.json",
        json.dumps({"ReproduceSettings": s.to_dict(), **json.loads(settings_json(world))}, indent=2)
        + "\n",
    )
    stages: dict[str, dict[str, Any]] = {}

    def run_stage(name: str, body: Callable[[], dict[str, Any]], outputs: list[Path]) -> None:
        folder = out / name
        key = stage_key(s, name)
        done = _read_done(folder, key)
        if done is not None and all(p.exists() for p in outputs):
            log(f"[{name}] already done ({done['wall_s']:.1f} s earlier) — skipped")
            stages[name] = {"skipped": True, "wall_s": done["wall_s"], **done.get("info", {})}
            return
        log(f"[{name}] running")
        folder.mkdir(parents=True, exist_ok=True)
        t0 = time.perf_counter()
        try:
            info = body()
        except BaseException as exc:
            wall = round(time.perf_counter() - t0, 3)
            what = "interrupted" if isinstance(exc, KeyboardInterrupt) else f"failed: {exc}"
            stages[name] = {"skipped": False, "wall_s": wall, "failed": what}
            raise
        wall = time.perf_counter() - t0
        _write_done(folder, key, wall, info=info)
        stages[name] = {"skipped": False, "wall_s": round(wall, 3), **info}
        log(f"[{name}] done in {wall:.1f} s")

    def run_all() -> None:
        # 1. calibration
        cal = out / "calibration"
        run_stage(
            "calibration",
            lambda: _calibrate(cal, s, workers or ncpu, record=True),
            [cal / "gait_table.json", cal / "figure4.png"],
        )
        table = load_table(str(cal / "gait_table.json"))

        # 2. navigation
        from evolve.stages import run_coverage, run_navigation

        nav = out / "navigation"

        def navigation() -> dict[str, Any]:
            summ = run_navigation(
                out, table=table, ga=s.navigation_ga(), world=world, resume=True, progress=progress
            )
            return {"dock_success": summ["dock_success"], "chosen": summ["chosen_population"]}

        run_stage("navigation", navigation, [nav / "best.txt", nav / "summary.json"])

        # 3. coverage
        from evolve.codec import read_chromosome

        cov = out / "coverage"

        def coverage() -> dict[str, Any]:
            bits8 = read_chromosome(nav / "best.txt")
            summ = run_coverage(
                out,
                navigation=bits8,
                table=table,
                ga=s.coverage_ga(),
                world=world,
                resume=True,
                progress=progress,
            )
            return {"final_mean_inner_percent": summ["final_mean_inner_percent"]}

        finalists = [cov / f"best_pop{k}.txt" for k in range(s.coverage_populations)]
        run_stage("coverage", coverage, [cov / "summary.json", *finalists])

        # 4. validation (finalist by finalist)
        val = out / "validation"
        val_key = stage_key(s, "validation")

        def validation() -> dict[str, Any]:
            res = _validate_finalists(out, s, table, world, workers, progress, val_key, log)
            failed = [k for k, r in res.items() if "error" in r]
            if failed:
                raise ReproduceError(
                    f"validation failed for finalist(s) {', '.join(failed)}; see the log above"
                )
            return {"finalists": res}

        run_stage(
            "validation",
            validation,
            [val / f"pop{k}" / "report.json" for k in range(s.coverage_populations)],
        )

    try:
        run_all()
    finally:  # the report says how far the run got, also when a stage failed
        total = time.perf_counter() - t_all
        try:
            report = write_report(out, s, world, stages, total_wall_s=total, ncpu=ncpu)
            log(f"[report] {report}")
        except Exception as exc:  # noqa: BLE001 - never mask the stage's own error
            log(f"[report] could not be written: {exc}")
    return {"stages": stages, "report": str(out / "REPORT.md"), "wall_s": round(total, 3)}


def _check_folder(out: Path, s: ReproduceSettings) -> None:
    """Raise ``ReproduceError`` if any stage in ``out`` finished with other settings."""
    for name in STAGES:
        _read_done(out / name, stage_key(s, name))
    for sub in sorted((out / "validation").glob("pop*")):
        _read_done(sub, stage_key(s, "validation"))


def _check_settings(s: ReproduceSettings) -> None:
    for f in dataclasses.fields(s):
        v = getattr(s, f.name)
        low = 0 if f.name in ("calibration_settle_cycles", "seed") else 1
        if not isinstance(v, int) or v < low:
            raise ReproduceError(f"setting {f.name} must be an integer ≥ {low}, got {v!r}")


# --------------------------------------------------------------------------- report


def _load_json(path: Path) -> dict[str, Any] | None:
    try:
        return json.loads(path.read_text())
    except (OSError, json.JSONDecodeError):
        return None


def _img(out: Path, path: Path, alt: str) -> list[str]:
    if not path.exists():
        return [f"*({alt}: {path.relative_to(out)} not written)*", ""]
    return [f"![{alt}]({path.relative_to(out).as_posix()})", ""]


def _fmt_s(seconds: float) -> str:
    return f"{seconds:.1f} s" if seconds < 120 else f"{seconds / 60:.1f} min"


def _calibration_section(out: Path) -> list[str]:
    lines = ["## 1. Calibration (Figure 4 rebuilt in MuJoCo)", ""]
    lines += _img(out, out / "calibration" / "figure4.png", "Figure 4: measured vs paper")
    try:
        table = load_table(str(out / "calibration" / "gait_table.json"))
    except Exception as exc:  # noqa: BLE001 - the report names what is missing
        return [*lines, f"*(gait table unreadable: {exc})*", ""]
    v, std = table.values, table.std
    err = v - PAPER_TABLE
    lines += [
        "| gait | F | T | dH | paper F | paper T | paper dH | err F | err T | err dH |"
        + (" std F | std T | std dH |" if std is not None else ""),
        "|" + "---|" * (13 if std is not None else 10),
    ]
    for g in range(16):
        row = (
            f"| {g} | {v[g, 0]:.2f} | {v[g, 1]:.2f} | {v[g, 2]:.2f} | {PAPER_TABLE[g, 0]:g} | "
            f"{PAPER_TABLE[g, 1]:g} | {PAPER_TABLE[g, 2]:g} | {err[g, 0]:+.2f} | "
            f"{err[g, 1]:+.2f} | {err[g, 2]:+.2f} |"
        )
        if std is not None:
            row += f" {std[g, 0]:.2f} | {std[g, 1]:.2f} | {std[g, 2]:.2f} |"
        lines.append(row)
    mx = np.abs(err).max(axis=0)
    ok = np.abs(err) <= CALIBRATION_TOLERANCE
    lines += [
        "",
        f"Largest error: F {mx[0]:.2f} cm, T {mx[1]:.2f} cm, dH {mx[2]:.2f}°. Entries within "
        f"1.0 cm (F, T) / 1.5° (dH) of the paper: {int(ok.sum())} of 48; gaits with all three "
        f"within: {int(ok.all(axis=1).sum())} of 16. Std = per-cycle standard deviation.",
        "",
    ]
    return lines


def _navigation_section(out: Path) -> list[str]:
    summ = _load_json(out / "navigation" / "summary.json")
    lines = ["## 2. Navigation (evolved on the calibrated table)", ""]
    if summ is None:
        return [*lines, "*(navigation/summary.json not written)*", ""]
    steps = summ.get("mean_steps_to_dock")
    lines += [
        f"Chosen section: population {summ['chosen_population']} "
        f"(`navigation/best.txt`); docking success on {summ['test_starts']} fresh starts: "
        f"**{100 * summ['dock_success']:.0f}%**"
        + (f", mean {steps:.1f} steps to dock." if steps is not None else "."),
        "",
        "| population | test fitness | dock rate | final training fitness |",
        "|---|---|---|---|",
    ]
    for p in summ.get("populations", []):
        lines.append(
            f"| {p['population']} | {p['test_fitness']:.3f} | {100 * p['dock_rate']:.0f}% | "
            f"{p['final_training_fitness']:.3f} |"
        )
    return [*lines, ""]


def _coverage_section(out: Path) -> list[str]:
    summ = _load_json(out / "coverage" / "summary.json")
    lines = ["## 3. Area coverage (Figures 8, 9, 10)", ""]
    lines += _img(out, out / "figure8.png", "Figure 8: arena, lit cones and dark area")
    lines += _img(out, out / "coverage" / "figure9.png", "Figure 9: inner coverage by generation")
    if summ is None:
        return [*lines, "*(coverage/summary.json not written)*", ""]
    gens = summ["generations"]
    inner = np.asarray(summ["figure9_inner_percent"])
    lines += [
        f"Figure 9 at generation {gens[-1]} (best individual on {summ['test_starts']} fresh "
        f"starts, % of the 64 inner squares): mean **{summ['final_mean_inner_percent']:.1f}%**"
        "; per population " + ", ".join(f"{k}: {v:.1f}%" for k, v in enumerate(inner[:, -1])) + ".",
        "",
        "| generation | " + " | ".join(f"pop {k}" for k in range(len(inner))) + " | mean |",
        "|---|" + "---|" * (len(inner) + 1),
    ]
    for j, g in enumerate(gens):
        lines.append(
            f"| {g} | "
            + " | ".join(f"{inner[k, j]:.1f}" for k in range(len(inner)))
            + f" | {inner[:, j].mean():.1f} |"
        )
    lines += ["", "Figure 10: each population's final best from (415, 252, 98°).", ""]
    for f in summ.get("figure10", []):
        k = f["population"]
        desc = ", ".join(f"{a} {f[a]}" for a in ("squares", "docks", "end") if a in f)
        lines += [f"Population {k}: {desc}", ""]
        lines += _img(out, out / "coverage" / f"figure10_pop{k}.png", f"Figure 10 pop {k}")
    return lines


def _validation_section(out: Path, s: ReproduceSettings) -> tuple[list[str], list[Path]]:
    lines = [
        "## 4. Reality gap: table simulation vs MuJoCo physics",
        "",
        f"Each finalist (`coverage/best_pop{{k}}.txt`) from the same {s.validate_starts} "
        f"seeded coverage starts, {s.validate_max_steps} steps, in the table world and in "
        "physics. Inner % = mean inner squares / 64; dock = share of runs with ≥ 1 dock; gap = "
        "table − physics over the runs whose physics finished.",
        "",
        "| finalist | runs ok | table inner % | physics inner % | gap (pp) | table dock | "
        "physics dock | dock gap (pp) | physics errors | wall |",
        "|---|---|---|---|---|---|---|---|---|---|",
    ]
    rrds: list[Path] = []
    gaps, t_in, p_in, t_dk, p_dk = [], [], [], [], []
    for k in range(s.coverage_populations):
        sub = out / "validation" / f"pop{k}"
        rep = _load_json(sub / "report.json")
        rrds += sorted(sub.glob("run*.rrd"), key=lambda p: int(p.stem[3:] or 0))
        if rep is None:
            lines.append(f"| {k} | — | — | — | — | — | — | — | not run | — |")
            continue
        sm = rep["summary"]
        tp, ph, gap = sm.get("table_paired", {}), sm.get("physics", {}), sm.get("gap", {})
        if gap.get("runs", 0):
            gaps.append(gap["inner_pct_pp"])
            t_in.append(tp["inner_pct"])
            p_in.append(ph["inner_pct"])
            t_dk.append(tp["dock_success"])
            p_dk.append(ph["dock_success"])
            lines.append(
                f"| {k} | {gap['runs']}/{sm['starts']} | {tp['inner_pct']:.1f} | "
                f"{ph['inner_pct']:.1f} | {gap['inner_pct_pp']:+.1f} | "
                f"{100 * tp['dock_success']:.0f}% | {100 * ph['dock_success']:.0f}% | "
                f"{gap['dock_success_pp']:+.0f} | {sm['physics_errors']} | "
                f"{_fmt_s(sm['wall_s'])} |"
            )
        else:
            lines.append(
                f"| {k} | 0/{sm['starts']} | — | — | — | — | — | — | {sm['physics_errors']} | "
                f"{_fmt_s(sm['wall_s'])} |"
            )
    if gaps:
        lines.append(
            f"| **all** | | **{np.mean(t_in):.1f}** | **{np.mean(p_in):.1f}** | "
            f"**{np.mean(gaps):+.1f}** | {100 * np.mean(t_dk):.0f}% | {100 * np.mean(p_dk):.0f}% "
            f"| {100 * (np.mean(t_dk) - np.mean(p_dk)):+.0f} | | |"
        )
    lines += ["", "Per-run details: `validation/pop{k}/report.md`.", ""]
    return lines, rrds


def write_report(
    out: Path,
    s: ReproduceSettings,
    world: WorldSettings,
    stages: dict[str, dict[str, Any]],
    *,
    total_wall_s: float,
    ncpu: int,
) -> Path:
    """Write ``out/REPORT.md`` from the files the stages left in ``out``."""
    now = dt.datetime.now(dt.timezone.utc).isoformat(timespec="seconds")
    lines = [
        "# ServoBot colony reproduction — report",
        "",
        f"Written {now} on {platform.node() or 'this machine'} ({ncpu} CPU cores, "
        f"Python {platform.python_version()}). Settings: `settings.json`; seed {s.seed}.",
        "",
        "| stage | wall time | this invocation |",
        "|---|---|---|",
    ]
    for name in STAGES:
        st = stages.get(name)
        if st is None:
            lines.append(f"| {name} | — | not reached |")
        else:
            how = st.get("failed") or ("skipped (done earlier)" if st.get("skipped") else "ran")
            lines.append(f"| {name} | {_fmt_s(float(st['wall_s']))} | {how} |")
    ran = sum(float(st["wall_s"]) for st in stages.values())
    lines += [
        f"| **all stages** | **{_fmt_s(ran)}** | this invocation took {_fmt_s(total_wall_s)} |",
        "",
    ]
    lines += _calibration_section(out)
    lines += _navigation_section(out)
    lines += _coverage_section(out)
    vlines, rrds = _validation_section(out, s)
    lines += vlines
    if (out / "calibration" / "calibration.rrd").exists():
        rrds.insert(0, out / "calibration" / "calibration.rrd")
    lines += ["## 5. Recordings", "", "Open any run in the rerun viewer:", ""]
    by_folder: dict[str, list[str]] = {}
    for p in rrds:
        by_folder.setdefault(p.parent.relative_to(out).as_posix(), []).append(p.name)
    for folder, names in by_folder.items():
        more = f" ({len(names)} recordings in `{folder}/`)" if len(names) > 1 else ""
        lines.append(f"- `rerun {folder}/{names[0]}`{more}")
    if not by_folder:
        lines.append("*(none)*")
    lines += [
        "",
        "Each holds the arena, the robot's bodies, the physics (orange) and table (blue) tracks,",
        "squares as reached, power, sensors, mode and squares over time, and the instructions.",
        "",
        "## 6. Settings",
        "",
        "```json",
        json.dumps({"ReproduceSettings": s.to_dict()}, indent=2),
        "```",
        "",
        "World, GA and physics settings of each stage: `*/settings.json` and",
        "`validation/pop*/report.json`; calibration provenance: `calibration/gait_table.json`.",
        "",
    ]
    return atomic_write_text(out / "REPORT.md", "\n".join(lines))


# --------------------------------------------------------------------------- CLI


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        prog="servobot reproduce",
        description="Calibrate, evolve navigation and coverage, validate the finalists in "
        "physics, and write REPORT.md with figures and .rrd recordings. Resumable: rerun the "
        "same command after an interruption.",
    )
    p.add_argument("--out", default="runs/reproduce", help="run folder (default runs/reproduce)")
    p.add_argument(
        "--quick", action="store_true", help="small budgets for a first look (a few minutes)"
    )
    p.add_argument("--seed", type=int, default=None, help="seed of every random draw (default 0)")
    p.add_argument(
        "--workers", type=int, default=None, help="processes for physics (default: all cores)"
    )
    p.add_argument(
        "--validate-starts",
        type=int,
        default=None,
        help="validation starts per finalist (default 20; --quick 3)",
    )
    p.add_argument("--no-progress", action="store_true", help="no progress bars")
    return p


def main(argv: list[str] | None = None) -> int:
    from evolve.stages import StageError

    args = build_parser().parse_args(argv)
    if args.workers is not None and args.workers < 1:
        print("servobot reproduce: --workers must be ≥ 1", file=sys.stderr)
        return 2
    try:
        res = reproduce(
            args.out,
            quick=args.quick,
            seed=args.seed,
            workers=args.workers,
            validate_starts=args.validate_starts,
            progress=not args.no_progress,
        )
    except (ReproduceError, StageError, GaitTableError) as exc:
        print(f"servobot reproduce: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print(
            "\nservobot reproduce: interrupted; run the same command again to resume",
            file=sys.stderr,
        )
        return 130
    print(f"report: {res['report']} (this invocation {_fmt_s(res['wall_s'])})")
    return 0


if __name__ == "__main__":
    sys.exit(main())


__all__ = [
    "ReproduceError",
    "ReproduceSettings",
    "build_parser",
    "main",
    "quick_settings",
    "reproduce",
    "stage_key",
    "write_report",
]
