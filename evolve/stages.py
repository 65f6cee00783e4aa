"""The two learning stages (SPEC §5, §6): navigation, then area coverage, with checkpoints.

Each stage evolves ``ga.populations`` independent populations of 8-gene sections. A
population's generation loop (``evolve.ga`` does the operators)::

    rng = Generator(PCG64(population's own SeedSequence))
    pop = random sections                                  # generation 0
    for g in 0..G:
        [checkpoint (g, pop, rng state) every CHECKPOINT_EVERY generations]
        starts = 10 start poses drawn from rng             # shared by the population
        fitness = mean over starts of the run fitness      # unique genomes evaluated once
        [save population + best if g is a save generation]
        if g < G: pop = next_generation(pop, fitness, rng)

Seeds: ``SeedSequence([seed, stage id]).spawn(populations + 1)``; child 0 draws the shared
100 test starts, child 1 + k drives population k. Population k's numbers therefore do not
depend on how many populations run, and a run resumed from a checkpoint is bit-identical to
an uninterrupted one.

Layout under the run folder ``out`` (the CLI's ``--out DIR``)::

    navigation/settings.json   navigation/best.txt   navigation/summary.json
    navigation/best_pop{k}.txt navigation/history_pop{k}.csv
    navigation/populations/pop{k}_gen{g:04d}.npz  (population, fitness, best, starts)
    navigation/checkpoints/pop{k}.npz             (resume state; pop{k}_final.npz when done)
    coverage/...  the same, plus figure9.{csv,json,png}, best_pop{k}.txt,
                  figure10_pop{k}.png, summary.json;  figure8.png in ``out`` itself.
"""

from __future__ import annotations

import csv
import io
import json
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from evolve import ga as gaops
from evolve.codec import write_chromosome
from evolve.interpreter import END_DOCKED
from evolve.io import atomic_write, atomic_write_json, atomic_write_text
from evolve.settings import GASettings, WorldSettings, navigation_ga_settings, settings_json
from evolve.table import GaitTable

CHECKPOINT_EVERY = 16
"""Generations between checkpoints of a population (operational, not a SPEC value)."""
STAGE_IDS = {"navigation": 0, "coverage": 1}
"""Second entropy word of each stage's SeedSequence, so the stages draw different numbers."""
SECTION_GENES = 8
"""Genes of the learned section (SPEC §4)."""
INNER_SQUARES = 64
"""Inner squares of the coverage grid, the denominator of Figure 9 (SPEC §5)."""
FIGURE10_START = (415.0, 252.0, 98.0)
"""Start pose (x, y, heading) of the Figure 10 tracks [paper]."""
HISTORY_COLUMNS = ("generation", "best_fitness", "mean_fitness", "docked_fraction", "unique")
"""Columns of ``history_pop{k}.csv``: per generation, on that generation's 10 starts;
``docked_fraction`` = fraction of all runs that docked at least once; ``unique`` = distinct
genomes evaluated."""

DEFAULT_WORLD = WorldSettings()
"""The SPEC's world (frozen, shared default)."""
DEFAULT_GA = GASettings()
"""The SPEC's coverage GA settings (frozen, shared default)."""

OnGeneration = Callable[[dict[str, Any]], None]


class StageError(RuntimeError):
    """A stage cannot run or resume (bad settings, corrupt or mismatched checkpoint)."""


# --------------------------------------------------------------------------- start poses


def navigation_starts(rng: np.random.Generator, n: int, world: WorldSettings) -> np.ndarray:
    """(n, 3) navigation start poses: x, y uniform in ``world.navigation_start_xy``, heading
    uniform in [0, 360) degrees (SPEC §6). Draw order: x, y, heading per pose, vectorised."""
    lo, hi = world.navigation_start_xy
    u = rng.random((n, 3))
    return np.column_stack([lo + (hi - lo) * u[:, 0], lo + (hi - lo) * u[:, 1], 360.0 * u[:, 2]])


def coverage_starts(rng: np.random.Generator, n: int, world: WorldSettings) -> np.ndarray:
    """(n, 3) coverage start poses: x in ``world.coverage_start_x``, y in
    ``world.coverage_start_y``, heading uniform in [0, 360) degrees (SPEC §5)."""
    (x0, x1), (y0, y1) = world.coverage_start_x, world.coverage_start_y
    u = rng.random((n, 3))
    return np.column_stack([x0 + (x1 - x0) * u[:, 0], y0 + (y1 - y0) * u[:, 1], 360.0 * u[:, 2]])


# --------------------------------------------------------------------------- fitness


def navigation_run_fitness(ev: Any, starts: np.ndarray, world: WorldSettings) -> np.ndarray:
    """Run fitness (P, S) of navigation (SPEC §6): 2 − steps/100 when the run docked, else
    0.5·max(0, 1 − d_end/d_start) with d the distance to ``world.dock_point`` (0 if
    d_start = 0). 2, 100 and 0.5 are ``world.dock_fitness``, ``world.navigation_steps`` and
    ``world.approach_fitness``."""
    dx, dy = world.dock_point
    d_start = np.hypot(starts[:, 0] - dx, starts[:, 1] - dy)[None, :]
    d_end = np.hypot(ev.final_pose[..., 0] - dx, ev.final_pose[..., 1] - dy)
    ratio = np.divide(d_end, d_start, out=np.ones_like(d_end), where=d_start > 0)
    near = world.approach_fitness * np.maximum(0.0, 1.0 - ratio)
    docked = np.asarray(ev.end) == END_DOCKED
    dock_score = world.dock_fitness - np.asarray(ev.steps) / world.navigation_steps
    return np.where(docked, dock_score, near)


def coverage_run_fitness(ev: Any, starts: np.ndarray, world: WorldSettings) -> np.ndarray:
    """Run fitness (P, S) of coverage (SPEC §5): squares reached, of 100."""
    return np.asarray(ev.squares, dtype=np.float64)


@dataclass(frozen=True)
class Stage:
    """What differs between the navigation and coverage stages."""

    name: str
    mode: str
    max_steps: int
    starts: Callable[[np.random.Generator, int, WorldSettings], np.ndarray]
    run_fitness: Callable[[Any, np.ndarray, WorldSettings], np.ndarray]
    navigation: np.ndarray | None = None
    """Fixed navigation section (8, 30) appended to every coverage section."""

    def genomes(self, sections: np.ndarray) -> np.ndarray:
        """Chromosomes the kernel runs: the sections, or sections + navigation (P, 16, 30)."""
        if self.navigation is None:
            return np.ascontiguousarray(sections)
        nav = np.broadcast_to(self.navigation, (sections.shape[0],) + self.navigation.shape)
        return np.ascontiguousarray(np.concatenate([sections, nav], axis=1))


def navigation_stage(world: WorldSettings) -> Stage:
    return Stage(
        "navigation",
        "navigation",
        world.navigation_steps,
        navigation_starts,
        navigation_run_fitness,
    )


def coverage_stage(world: WorldSettings, navigation: np.ndarray) -> Stage:
    nav = _check_navigation(navigation)
    return Stage(
        "coverage", "coverage", world.coverage_steps, coverage_starts, coverage_run_fitness, nav
    )


def _check_navigation(navigation: np.ndarray) -> np.ndarray:
    nav = np.asarray(navigation)
    if nav.shape != (SECTION_GENES, gaops.GENE_BITS) or not np.isin(nav, (0, 1)).all():
        raise StageError(f"navigation section must be an (8, 30) array of bits, got {nav.shape}")
    return nav.astype(np.uint8)


def _evaluate(*args: Any, **kwargs: Any) -> Any:
    """The numba kernel (``evolve.evaluate``), imported on first use."""
    from evolve import evaluate

    return evaluate(*args, **kwargs)


def evaluate_sections(
    sections: np.ndarray,
    starts: np.ndarray,
    stage: Stage,
    table: GaitTable,
    world: WorldSettings,
) -> tuple[np.ndarray, Any, np.ndarray, np.ndarray]:
    """Run every distinct section once from every start.

    Returns ``(run_fitness (P, S), evaluation of the unique genomes, unique index (U,),
    inverse (P,))`` where row p of the population's results is row ``inverse[p]`` of the
    unique ones. Converged populations repeat individuals; the results are identical to
    evaluating all P, with less work.
    """
    p = sections.shape[0]
    packed = np.packbits(sections.reshape(p, -1), axis=1)
    _, first, inverse = np.unique(packed, axis=0, return_index=True, return_inverse=True)
    inverse = inverse.reshape(-1)
    ev = _evaluate(
        stage.genomes(sections[first]),
        np.ascontiguousarray(starts, dtype=np.float64),
        table=table.values,
        mode=stage.mode,
        start_power=world.start_power_v,
        max_steps=stage.max_steps,
        settings=world,
    )
    run_fit = stage.run_fitness(ev, starts, world)
    return run_fit[inverse], ev, first, inverse


# --------------------------------------------------------------------------- seeds & files


def stage_seeds(seed: int, stage: str, populations: int) -> tuple[np.random.SeedSequence, list]:
    """(test-start seed, [population seeds]) of a stage; see the module docstring."""
    children = np.random.SeedSequence([int(seed), STAGE_IDS[stage]]).spawn(populations + 1)
    return children[0], children[1:]


def _save_generations(ga: GASettings) -> tuple[int, ...]:
    """The save generations that exist in this run, plus the final one."""
    return tuple(sorted({g for g in ga.save_generations if g <= ga.generations} | {ga.generations}))


def _npz_write(path: Path, **arrays: Any) -> None:
    def write(tmp: Path) -> None:
        with open(tmp, "wb") as fh:
            np.savez_compressed(fh, **arrays)

    atomic_write(path, write)


def _npz_read(path: Path, what: str) -> dict[str, np.ndarray]:
    try:
        with np.load(path, allow_pickle=False) as z:
            return {k: z[k] for k in z.files}
    except Exception as exc:  # zipfile.BadZipFile, OSError, ValueError, EOFError, ...
        raise StageError(
            f"{path}: corrupt {what} ({type(exc).__name__}: {exc}); delete it to start over"
        ) from exc


def _require(data: dict[str, np.ndarray], keys: tuple[str, ...], path: Path, what: str) -> None:
    missing = [k for k in keys if k not in data]
    if missing:
        raise StageError(f"{path}: corrupt {what}: missing {missing}; delete it to start over")


def _settings_doc(
    stage: Stage, ga: GASettings, world: WorldSettings, table: GaitTable
) -> dict[str, Any]:
    doc = json.loads(settings_json(ga, world))
    doc["stage"] = stage.name
    doc["table"] = {"source": table.source, "values": table.values.tolist()}
    if stage.navigation is not None:
        doc["navigation_section"] = ["".join(map(str, g)) for g in stage.navigation.tolist()]
    doc["checkpoint_every"] = CHECKPOINT_EVERY
    return doc


def _check_settings(stored: np.ndarray, expected: str, path: Path) -> None:
    if str(stored) != expected:
        raise StageError(
            f"{path}: checkpoint was written with different settings (seed, sizes, table, "
            "world or navigation section); use the same options, or run without --resume"
        )


# --------------------------------------------------------------------------- one population


@dataclass
class PopulationResult:
    """A finished population: its final best section and per-generation history."""

    index: int
    best: np.ndarray
    history: np.ndarray  # (G+1, len(HISTORY_COLUMNS))


def evolve_population(
    k: int,
    stage: Stage,
    folder: Path,
    *,
    seed_seq: np.random.SeedSequence,
    table: GaitTable,
    ga: GASettings,
    world: WorldSettings,
    settings_text: str,
    resume: bool,
    progress: bool,
    on_generation: OnGeneration | None,
) -> PopulationResult:
    """Evolve population ``k`` of ``stage`` in ``folder``, resuming from its checkpoint."""
    from tqdm import tqdm

    ckpt = folder / "checkpoints" / f"pop{k}.npz"
    final = folder / "checkpoints" / f"pop{k}_final.npz"
    pops_dir = folder / "populations"
    saves = set(_save_generations(ga))
    rng = np.random.Generator(np.random.PCG64(seed_seq))
    gen, history = 0, []

    if resume and final.exists():
        data = _npz_read(final, "final population file")
        _require(data, ("best", "history", "settings"), final, "final population file")
        _check_settings(data["settings"], settings_text, final)
        return PopulationResult(k, data["best"].astype(np.uint8), data["history"])
    if resume and ckpt.exists():
        data = _npz_read(ckpt, "checkpoint")
        _require(
            data,
            ("population", "generation", "rng_state", "history", "settings"),
            ckpt,
            "checkpoint",
        )
        _check_settings(data["settings"], settings_text, ckpt)
        try:
            rng.bit_generator.state = json.loads(str(data["rng_state"]))
        except (ValueError, TypeError, KeyError) as exc:
            raise StageError(f"{ckpt}: corrupt checkpoint (rng state: {exc})") from exc
        pop = data["population"].astype(np.uint8)
        gen = int(data["generation"])
        history = [tuple(row) for row in data["history"].tolist()]
        if pop.shape != (ga.population_size, SECTION_GENES, gaops.GENE_BITS) or len(history) != gen:
            raise StageError(f"{ckpt}: corrupt checkpoint (population {pop.shape}, gen {gen})")
    else:
        pop = gaops.random_sections(rng, ga.population_size, SECTION_GENES)

    bar = tqdm(
        total=ga.generations + 1,
        initial=gen,
        desc=f"{stage.name} pop {k}",
        disable=not progress,
        unit="gen",
        leave=True,
    )
    try:
        while True:
            if gen % CHECKPOINT_EVERY == 0:
                _npz_write(
                    ckpt,
                    population=pop,
                    generation=np.int64(gen),
                    rng_state=np.str_(json.dumps(rng.bit_generator.state)),
                    history=np.asarray(history, dtype=np.float64).reshape(-1, len(HISTORY_COLUMNS)),
                    settings=np.str_(settings_text),
                )
            starts = stage.starts(rng, ga.starts_per_generation, world)
            run_fit, ev, first, inverse = evaluate_sections(pop, starts, stage, table, world)
            fitness = run_fit.mean(axis=1)
            docked = (np.asarray(ev.docks) > 0) | (np.asarray(ev.end) == END_DOCKED)
            docked_frac = float(docked[inverse].mean())
            best_i = int(np.argmax(fitness))
            row = (gen, float(fitness[best_i]), float(fitness.mean()), docked_frac, len(first))
            history.append(row)
            if gen in saves:
                _npz_write(
                    pops_dir / f"pop{k}_gen{gen:04d}.npz",
                    population=pop,
                    fitness=fitness,
                    best=pop[best_i],
                    starts=starts,
                )
            bar.update(1)
            if progress:
                bar.set_postfix(best=f"{row[1]:.3f}", mean=f"{row[2]:.3f}", uniq=len(first))
            if on_generation is not None:
                on_generation(
                    dict(
                        zip(
                            ("stage", "population") + HISTORY_COLUMNS,
                            (stage.name, k) + row,
                            strict=True,
                        )
                    )
                )
            if gen == ga.generations:
                break
            pop = gaops.next_generation(pop, fitness, rng, ga)
            gen += 1
    finally:
        bar.close()
    hist = np.asarray(history, dtype=np.float64)
    _npz_write(
        final,
        best=pop[best_i],
        population=pop,
        fitness=fitness,
        history=hist,
        settings=np.str_(settings_text),
    )
    ckpt.unlink(missing_ok=True)
    _write_history(folder / f"history_pop{k}.csv", hist)
    return PopulationResult(k, pop[best_i].copy(), hist)


def _write_history(path: Path, hist: np.ndarray) -> None:
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(HISTORY_COLUMNS)
    for row in hist:
        w.writerow([int(row[0]), f"{row[1]:.6g}", f"{row[2]:.6g}", f"{row[3]:.6g}", int(row[4])])
    atomic_write_text(path, buf.getvalue())


def _check_ga(ga: GASettings) -> None:
    if ga.populations < 1:
        raise StageError(f"populations must be ≥ 1, got {ga.populations}")
    if ga.population_size < 2:
        raise StageError(f"population size must be ≥ 2, got {ga.population_size}")
    if ga.generations < 1:
        raise StageError(f"generations must be ≥ 1, got {ga.generations}")
    if ga.starts_per_generation < 1 or ga.test_starts < 1:
        raise StageError("starts per generation and test starts must be ≥ 1")


def _run_populations(
    stage: Stage,
    folder: Path,
    *,
    table: GaitTable,
    ga: GASettings,
    world: WorldSettings,
    resume: bool,
    progress: bool,
    on_generation: OnGeneration | None,
) -> tuple[list[PopulationResult], np.ndarray, dict[str, Any]]:
    """Evolve all populations of a stage; returns (results, test starts, settings doc)."""
    _check_ga(ga)
    folder.mkdir(parents=True, exist_ok=True)
    doc = _settings_doc(stage, ga, world, table)
    settings_text = json.dumps(doc, sort_keys=True)
    atomic_write_json(folder / "settings.json", doc)
    test_seq, pop_seqs = stage_seeds(ga.seed, stage.name, ga.populations)
    results = [
        evolve_population(
            k,
            stage,
            folder,
            seed_seq=pop_seqs[k],
            table=table,
            ga=ga,
            world=world,
            settings_text=settings_text,
            resume=resume,
            progress=progress,
            on_generation=on_generation,
        )
        for k in range(ga.populations)
    ]
    test_rng = np.random.Generator(np.random.PCG64(test_seq))
    test_starts = stage.starts(test_rng, ga.test_starts, world)
    return results, test_starts, doc


# --------------------------------------------------------------------------- navigation


def run_navigation(
    out: Path,
    *,
    table: GaitTable,
    ga: GASettings | None = None,
    world: WorldSettings = DEFAULT_WORLD,
    resume: bool = False,
    progress: bool = True,
    on_generation: OnGeneration | None = None,
) -> dict[str, Any]:
    """Navigation stage (SPEC §6) into ``out/navigation``; returns the summary dict.

    Each population's final best runs from the same ``ga.test_starts`` fresh start poses;
    the one with the highest mean run fitness becomes ``navigation/best.txt``. Summary keys:
    ``dock_success`` (fraction of those starts the chosen section docks from),
    ``mean_steps_to_dock``, ``chosen_population``, ``populations`` (per-population test
    fitness, dock rate, final training fitness), ``wall_s``, ``settings``.
    """
    ga = navigation_ga_settings() if ga is None else ga
    t0 = time.perf_counter()
    folder = Path(out) / "navigation"
    stage = navigation_stage(world)
    results, test_starts, doc = _run_populations(
        stage,
        folder,
        table=table,
        ga=ga,
        world=world,
        resume=resume,
        progress=progress,
        on_generation=on_generation,
    )
    bests = np.stack([r.best for r in results])
    run_fit, ev, _, inverse = evaluate_sections(bests, test_starts, stage, table, world)
    docked = (np.asarray(ev.end) == END_DOCKED)[inverse]
    steps = np.asarray(ev.steps)[inverse]
    test_fit = run_fit.mean(axis=1)
    chosen = int(np.argmax(test_fit))
    per_pop = []
    for r in results:
        k = r.index
        per_pop.append(
            {
                "population": k,
                "test_fitness": float(test_fit[k]),
                "dock_rate": float(docked[k].mean()),
                "mean_steps_to_dock": float(steps[k][docked[k]].mean())
                if docked[k].any()
                else None,
                "final_training_fitness": float(r.history[-1, 1]),
            }
        )
        write_chromosome(
            folder / f"best_pop{k}.txt",
            r.best,
            _provenance(
                "navigation",
                k,
                ga,
                table,
                f"test fitness {test_fit[k]:.4f}, "
                f"docked {docked[k].mean():.0%} of {len(test_starts)} test starts",
            ),
        )
    summary = {
        "stage": "navigation",
        "dock_success": float(docked[chosen].mean()),
        "mean_steps_to_dock": per_pop[chosen]["mean_steps_to_dock"],
        "chosen_population": chosen,
        "test_fitness": float(test_fit[chosen]),
        "test_starts": len(test_starts),
        "populations": per_pop,
        "wall_s": time.perf_counter() - t0,
        "resumed": bool(resume),
        "settings": doc,
    }
    header = _provenance(
        "navigation",
        chosen,
        ga,
        table,
        f"chosen: best test fitness {test_fit[chosen]:.4f} of "
        f"{ga.populations} populations; docked {summary['dock_success']:.0%} "
        f"of {len(test_starts)} fresh starts",
    )
    write_chromosome(folder / "best.txt", results[chosen].best, header)
    atomic_write_json(folder / "summary.json", summary)
    return summary


def _provenance(stage: str, k: int, ga: GASettings, table: GaitTable, extra: str) -> str:
    return (
        f"servobot {stage} stage, population {k} of {ga.populations}, final generation "
        f"{ga.generations}, population size {ga.population_size}, seed {ga.seed}\n"
        f"gait table: {table.source}\n{extra}"
    )


# --------------------------------------------------------------------------- coverage


def run_coverage(
    out: Path,
    *,
    navigation: np.ndarray,
    table: GaitTable,
    ga: GASettings = DEFAULT_GA,
    world: WorldSettings = DEFAULT_WORLD,
    resume: bool = False,
    progress: bool = True,
    on_generation: OnGeneration | None = None,
) -> dict[str, Any]:
    """Coverage stage (SPEC §5) into ``out/coverage`` with Figures 8–10; returns the summary.

    Figure 9: the best section of each saved generation of each population runs (with the
    fixed ``navigation`` section) from the same ``ga.test_starts`` fresh coverage starts;
    inner squares / 64 as a percentage. Summary keys: ``figure9`` (per population and mean,
    per generation), ``final_mean_inner_percent``, ``final_inner_percent`` (per population),
    ``figure10`` (squares, docks, end per population), ``wall_s``, ``settings``.
    """
    from evolve import figures

    t0 = time.perf_counter()
    out = Path(out)
    folder = out / "coverage"
    stage = coverage_stage(world, navigation)
    results, test_starts, doc = _run_populations(
        stage,
        folder,
        table=table,
        ga=ga,
        world=world,
        resume=resume,
        progress=progress,
        on_generation=on_generation,
    )
    gens = _save_generations(ga)
    inner = np.zeros((ga.populations, len(gens)))
    squares = np.zeros_like(inner)
    for k in range(ga.populations):
        bests = []
        for g in gens:
            path = folder / "populations" / f"pop{k}_gen{g:04d}.npz"
            data = _npz_read(path, "saved population")
            _require(data, ("best",), path, "saved population")
            bests.append(data["best"].astype(np.uint8))
        _, ev, _, inverse = evaluate_sections(np.stack(bests), test_starts, stage, table, world)
        inner[k] = 100.0 * np.asarray(ev.inner_squares)[inverse].mean(axis=1) / INNER_SQUARES
        squares[k] = np.asarray(ev.squares)[inverse].mean(axis=1)
    mean = inner.mean(axis=0)
    _write_figure9(folder, gens, inner, squares)
    figures.figure9(folder / "figure9.png", gens, inner)
    figures.figure8(out / "figure8.png", world)
    fig10 = []
    for r in results:
        k = r.index
        full = stage.genomes(r.best[None])[0]
        header = _provenance(
            "coverage",
            k,
            ga,
            table,
            "16 genes: coverage section (learned) + navigation (fixed); "
            f"Figure 9 test {inner[k, -1]:.1f}% of the 64 inner squares",
        )
        write_chromosome(folder / f"best_pop{k}.txt", full, header)
        fig10.append(
            {
                "population": k,
                **figures.figure10(
                    folder / f"figure10_pop{k}.png",
                    full,
                    table=table,
                    world=world,
                    start=FIGURE10_START,
                    title=f"population {k}",
                ),
            }
        )
    summary = {
        "stage": "coverage",
        "generations": list(gens),
        "figure9_mean_inner_percent": mean.tolist(),
        "figure9_inner_percent": inner.tolist(),
        "final_mean_inner_percent": float(mean[-1]),
        "final_inner_percent": inner[:, -1].tolist(),
        "final_mean_squares": squares[:, -1].tolist(),
        "figure10": fig10,
        "test_starts": len(test_starts),
        "wall_s": time.perf_counter() - t0,
        "resumed": bool(resume),
        "settings": doc,
    }
    atomic_write_json(folder / "summary.json", summary)
    return summary


def _write_figure9(folder: Path, gens: tuple[int, ...], inner: np.ndarray, sq: np.ndarray) -> None:
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(("population", "generation", "inner_percent"))
    for k in range(inner.shape[0]):
        for j, g in enumerate(gens):
            w.writerow((k, g, f"{inner[k, j]:.4f}"))
    atomic_write_text(folder / "figure9.csv", buf.getvalue())
    atomic_write_json(
        folder / "figure9.json",
        {
            "generations": list(gens),
            "inner_percent": {str(k): inner[k].tolist() for k in range(inner.shape[0])},
            "mean_inner_percent": inner.mean(axis=0).tolist(),
            "mean_squares_of_100": {str(k): sq[k].tolist() for k in range(sq.shape[0])},
            "note": "best individual of each saved generation on the shared fresh test starts; "
            "inner squares reached / 64 × 100",
        },
    )


__all__ = [
    "StageError",
    "run_navigation",
    "run_coverage",
    "navigation_starts",
    "coverage_starts",
    "navigation_run_fitness",
    "coverage_run_fitness",
    "evaluate_sections",
    "stage_seeds",
    "CHECKPOINT_EVERY",
]
