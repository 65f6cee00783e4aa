"""The two learning stages (SPEC §5, §6): navigation, then area coverage.

Each stage evolves ``ga.populations`` independent populations of 8-gene sections
(``evolve.population``: the generation loop, checkpoints, seeds), then tests the finalists:
navigation picks its section among the saved bests (``NavigationSettings``), coverage
measures Figure 9, where its finalists hand control to navigation (``evolve.handoff``) and
draws Figures 8 and 10.

A stage may evolve in an envelope of variation (SPEC §9, ``evolve.envelope``; ``none`` by
default): its training runs vary with the key (seed, generation), its tests are run in the
envelope (key ``key_of_test(seed, test)``) and in the world of §3 on the same starts. The
existing summary keys keep the world of §3; the envelope's figures sit beside them, prefixed
``envelope_`` (absent for ``none``, whose files are as before); ``settings.json`` records the
envelope (no ``Envelope`` entry: ``none``).

Before anything is allocated or written, a stage checks that its sizes fit the machine
(``stage_need``, ``infra.bounds``) and takes its folder (``infra.rundir.run_folder``: an OS
lock, ``settings.json`` as the ownership record; ``resume`` continues a run with the same
settings, ``force`` deletes only the stage's own files, ``STAGE_FILES``, and starts afresh).

Layout under the run folder ``out`` (the CLI's ``--out DIR``)::

    navigation/settings.json   navigation/best.txt   navigation/summary.json
    navigation/best_pop{k}.txt navigation/history_pop{k}.csv  navigation/docking.png
    navigation/populations/pop{k}_gen{g:04d}.npz  (population, fitness, best, starts)
    navigation/checkpoints/pop{k}.npz             (resume state; pop{k}_final.npz when done)
    coverage/...  the same, plus figure9.{csv,json,png}, best_pop{k}.txt, handoffs.csv,
                  figure10_pop{k}.png, summary.json;  figure8.png in ``out`` itself.
"""

from __future__ import annotations

import contextlib
import csv
import dataclasses
import functools
import io
import json
import os
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import TYPE_CHECKING, Any, TypedDict

import numpy as np

from evolve.checkpoint import read_npz
from evolve.codec import GENE_BITS, SECTION_GENES, write_chromosome
from evolve.envelope import NONE, ROBOT_RADIUS, Envelope, key_of_test
from evolve.handoff import collect_handoffs, handoff_rate, write_handoffs
from evolve.interpreter import END_DOCKED
from evolve.population import (
    CHECKPOINT_EVERY,
    HISTORY_COLUMNS,
    OnGeneration,
    PopulationJob,
    PopulationResult,
    Stage,
    StageError,
    evaluate_sections,
    evolve_population,
    generation_record,
    run_population_job,
    save_generations,
    stage_rng,
    stage_seeds,
)
from evolve.settings import (
    GASettings,
    NavigationSettings,
    WorldSettings,
    navigation_ga_settings,
    settings_json,
)
from evolve.starts import (
    coverage_starts,
    navigation_starts,
    navigation_training_starts,
    pose_starts,
)
from evolve.table import GaitTable
from evolve.variation import Variation
from infra.bounds import LIMITS, Limits, Need, check_int, check_need
from infra.executors import BatchError, Executor, Failed, RayExecutor, values_or_raise
from infra.io import atomic_write_json, atomic_write_text
from infra.rundir import run_folder

if TYPE_CHECKING:  # typing.Unpack from Python 3.11 on
    from typing_extensions import Unpack

FIGURE10_START = (415.0, 252.0, 98.0)
"""Start pose (x, y, heading) of the Figure 10 tracks [paper]."""
DEFAULT_WORLD = WorldSettings()
"""The SPEC's world (frozen, shared default)."""
DEFAULT_GA = GASettings()
"""The SPEC's coverage GA settings (frozen, shared default)."""
DEFAULT_NAVIGATION = NavigationSettings()
"""How the navigation stage chooses its section by default (frozen, shared)."""
NAVIGATION_GENERATIONS = navigation_ga_settings().generations
"""Generations of a navigation stage by default (SPEC §6: 1024)."""
STAGE_FILES = (
    "summary.json", "best.txt", "best_pop*.txt", "history_pop*.csv", "figure9.*",
    "figure10_pop*.png", "docking.png", "handoffs.csv", "populations/pop*_gen*.npz",
    "checkpoints/pop*.npz",
)  # fmt: skip
"""Every file a stage writes in its folder besides ``settings.json``: what ``force`` deletes."""
RUN_RESULT_BYTES = 64
"""Memory of one run's results in an evaluation (5 int64 + 3 float64), bytes."""


class StageOptions(TypedDict, total=False):
    """The keywords every stage runner takes beside what it evolves (``run_navigation``,
    ``run_coverage``, ``evolve.colony_stage.run_colony_stage``); ``StageRun`` holds them
    with their defaults and meanings."""

    resume: bool
    force: bool
    on_generation: OnGeneration | None
    executor: Executor | None
    envelope: Envelope


@dataclasses.dataclass(frozen=True)
class StageRun:
    """How a stage runs (``StageOptions``, with their defaults)."""

    resume: bool = False
    """Continue the run in the stage's folder from its checkpoints (same settings only)."""
    force: bool = False
    """The folder holds another run: delete that run's files (``STAGE_FILES``), start afresh."""
    on_generation: OnGeneration | None = None
    """Hears each generation's record (progress)."""
    executor: Executor | None = None
    """Where the populations evolve: None = one after another in this process."""
    envelope: Envelope = NONE
    """The envelope of variation the populations evolve in (SPEC §9)."""


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


def navigation_stage(
    world: WorldSettings,
    navigation: NavigationSettings = DEFAULT_NAVIGATION,
    generations: int = NAVIGATION_GENERATIONS,
    envelope: Envelope = NONE,
) -> Stage:
    """The navigation stage (SPEC §6) of ``generations`` generations in ``envelope``;
    ``navigation`` (the growing training start region, or the start poses of every run; how
    the final section is chosen) is saved with its settings."""
    ramp = navigation.ramp_generations(generations)
    starts, training = navigation_starts, None
    if navigation.start_poses is not None:
        starts = functools.partial(pose_starts, poses=np.asarray(navigation.start_poses))
    elif ramp > 0:
        training = functools.partial(
            navigation_training_starts,
            first_radius=navigation.first_start_radius,
            ramp_generations=ramp,
        )
    return Stage(
        "navigation",
        "navigation",
        world.navigation_steps,
        starts,
        navigation_run_fitness,
        extra_settings=(navigation,),
        envelope=envelope,
        training_starts=training,
    )


def coverage_stage(
    world: WorldSettings, navigation: np.ndarray, envelope: Envelope = NONE
) -> Stage:
    """The coverage stage (SPEC §5) with the fixed ``navigation`` section, in ``envelope``."""
    nav = _check_section(navigation)
    return Stage(
        "coverage", "coverage", world.coverage_steps, coverage_starts, coverage_run_fitness, nav,
        envelope=envelope,
    )  # fmt: skip


def navigation_section(bits: np.ndarray) -> np.ndarray:
    """The (8, 30) navigation section of a chromosome: an 8-gene section as is, or genes
    8–15 of a full 16-gene chromosome (SPEC §4)."""
    return bits if bits.shape[0] == SECTION_GENES else bits[SECTION_GENES:]


def _check_section(section: np.ndarray, name: str = "navigation") -> np.ndarray:
    """``section`` as (8, 30) uint8 bits; ``StageError`` naming it (``the {name} section``)."""
    bits = np.asarray(section)
    if bits.shape != (SECTION_GENES, GENE_BITS) or not np.isin(bits, (0, 1)).all():
        raise StageError(f"the {name} section must be an (8, 30) array of bits, got {bits.shape}")
    return bits.astype(np.uint8)


def started_from(stage: Stage, first: np.ndarray | None) -> Stage:
    """``stage`` with every individual of generation 0 carrying the (8, 30) section ``first``
    (``Stage.initial``, recorded as ``initial_section``); ``stage`` itself when None."""
    if first is None:
        return stage
    return dataclasses.replace(stage, initial=_check_section(first, "first"))


def _gene_text(section: np.ndarray) -> list[str]:
    """A section's genes as strings of bits (a settings document's record of it)."""
    return ["".join(map(str, g)) for g in section.tolist()]


def stage_settings_doc(
    stage: Stage, ga: GASettings, world: WorldSettings, table: GaitTable
) -> dict[str, Any]:
    """Everything a stage's results depend on (its ``settings.json`` and checkpoints' record):
    the settings dataclasses, the stage, the table, the fixed sections (navigation, or the
    colony's navigation stage's coverage sections and its initial section), the envelope
    (when not ``none``: a folder made before envelopes existed resumes as it was)."""
    doc = json.loads(settings_json(ga, world, *stage.extra_settings))
    if stage.envelope != NONE:
        doc["Envelope"] = stage.envelope.to_dict()
    doc["stage"] = stage.name
    doc["table"] = {"source": table.source, "values": table.values.tolist()}
    if stage.navigation is not None:
        doc["navigation_section"] = _gene_text(stage.navigation)
    if stage.coverage is not None:
        doc["coverage_sections"] = [_gene_text(c) for c in stage.coverage]
    if stage.initial is not None:
        doc["initial_section"] = _gene_text(stage.initial)
    doc["checkpoint_every"] = CHECKPOINT_EVERY
    return doc


def stage_need(ga: GASettings, max_steps: int, limits: Limits = LIMITS) -> Need:
    """Peak memory and (optimistic) wall time of a stage: populations run one after another;
    each evaluates population × starts runs of at most ``max_steps`` steps per generation,
    then the finalists (and, for Figure 9, every save generation's best) on the test starts."""
    p, s = ga.population_size, ga.starts_per_generation
    saves = len(save_generations(ga))
    genome = 2 * SECTION_GENES * GENE_BITS  # a section and its full chromosome
    histories = ga.populations * (ga.generations + 1) * len(HISTORY_COLUMNS) * 8
    tests = max(ga.populations, saves) * ga.test_starts * RUN_RESULT_BYTES
    memory = p * (4 * genome + 2 * s * RUN_RESULT_BYTES) + histories + tests
    runs = ga.populations * ((ga.generations + 1) * p * s + (1 + saves) * ga.test_starts)
    return Need(memory, runs * max_steps / limits.table_steps_per_s)


def check_ga(ga: GASettings, max_steps: int) -> None:
    """Refuse GA settings out of range or whose memory or time the machine cannot give."""
    try:
        check_int(ga.populations, "populations", lo=1)
        check_int(ga.population_size, "population size", lo=2)
        check_int(ga.generations, "generations", lo=1)
        check_int(ga.starts_per_generation, "starts per generation", lo=1)
        check_int(ga.test_starts, "test starts", lo=1)
        check_int(ga.seed, "seed", lo=0)
        what = (
            f"{ga.populations} populations × {ga.population_size} individuals × "
            f"{ga.generations} generations"
        )
        check_need(stage_need(ga, max_steps), what)
    except ValueError as exc:
        raise StageError(str(exc)) from exc


def check_envelope(stage: Stage, table: GaitTable, world: WorldSettings) -> None:
    """Refuse a stage whose envelope cannot vary ``table`` in ``world`` (a table without σ, a
    reach beyond the activation distance): ``EnvelopeError`` before any work."""
    Variation.of(stage.envelope, table, world, (0, 0), ROBOT_RADIUS)


def both_worlds(stage: Stage) -> list[tuple[str, Stage]]:
    """(prefix, stage) of each world a stage's tests report: the world of §3 (prefix ``""``,
    the existing keys) and, for a stage evolved in an envelope, the envelope (``"envelope_"``)."""
    plain = [("", dataclasses.replace(stage, envelope=NONE))]
    return plain if stage.envelope == NONE else plain + [("envelope_", stage)]


@contextmanager
def _stage_folder(
    stage: Stage, folder: Path, table: GaitTable, ga: GASettings, world: WorldSettings,
    resume: bool, force: bool, extra: dict[str, Any] | None = None,
) -> Iterator[dict[str, Any]]:  # fmt: skip
    """Check the sizes, then hold the stage's folder (lock, ownership record) for the block;
    yields the settings document (with ``extra``'s entries)."""
    check_ga(ga, stage.max_steps)
    check_envelope(stage, table, world)
    doc = stage_settings_doc(stage, ga, world, table) | (extra or {})
    with run_folder(folder, doc, owned=STAGE_FILES, resume=resume, force=force,
                    command=f"evolve {stage.name}"):
        yield doc


def _run_populations(
    stage: Stage,
    folder: Path,
    doc: dict[str, Any],
    *,
    table: GaitTable,
    ga: GASettings,
    world: WorldSettings,
    run: StageRun,
) -> tuple[list[PopulationResult], np.ndarray]:
    """Evolve all populations of a stage in its (claimed) folder as ``run`` says; returns
    (results, test starts)."""
    settings_text = json.dumps(doc, sort_keys=True)
    test_seq, pop_seqs = stage_seeds(ga.seed, stage.name, ga.populations)
    kwargs = [
        dict(seed_seq=pop_seqs[k], table=table, ga=ga, world=world,
             settings_text=settings_text, resume=run.resume)
        for k in range(ga.populations)
    ]  # fmt: skip
    if run.executor is None:
        results = [
            evolve_population(k, stage, folder, on_generation=run.on_generation, **kwargs[k])
            for k in range(ga.populations)
        ]
    else:
        threads = _kernel_threads(run.executor)
        jobs = [PopulationJob(k, stage, folder, kwargs[k], threads) for k in range(ga.populations)]
        results = populations_on(run.executor, jobs, run.on_generation)
    test_rng = np.random.Generator(np.random.PCG64(test_seq))
    test_starts = stage.starts(test_rng, ga.test_starts, world)
    return results, test_starts


def _kernel_threads(executor: Executor) -> int:
    """numba threads per population when an executor runs populations side by side: this
    machine's cores shared out among its workers (one each on Ray, whose tasks take one CPU)."""
    if isinstance(executor, RayExecutor):
        return 1
    cores = os.cpu_count() or 1
    return max(1, cores // (getattr(executor, "workers", None) or cores))


def populations_on(
    executor: Executor, jobs: list[PopulationJob], on_generation: OnGeneration | None,
    what: str = "population", rows: Callable[[Any], Any] = lambda res: res.history,
) -> list[Any]:
    """Each population (or team: ``what``) as one run of ``executor``; ``on_generation``
    hears its generations when it finishes, one record per ``HISTORY_COLUMNS`` row of
    ``rows(result)``."""
    outcomes: list[Any] = [None] * len(jobs)
    with contextlib.closing(executor.imap(run_population_job, jobs)) as finished:
        for k, outcome in finished:
            outcomes[k] = outcome
            if on_generation is not None and not isinstance(outcome, Failed):
                res, job = outcome.value, jobs[k]
                for row in rows(res):
                    on_generation(
                        generation_record(job.stage.name, k, job.kwargs["ga"].generations, row)
                    )
    try:
        return values_or_raise(outcomes, [f"{what} {k}" for k in range(len(jobs))])
    except BatchError as exc:
        raise StageError(f"{exc}; the checkpoints are kept, rerun with --resume") from exc


# --------------------------------------------------------------------------- navigation


def run_navigation(
    out: Path,
    *,
    table: GaitTable,
    ga: GASettings | None = None,
    world: WorldSettings = DEFAULT_WORLD,
    navigation: NavigationSettings = DEFAULT_NAVIGATION,
    first: np.ndarray | None = None,
    **options: Unpack[StageOptions],
) -> dict[str, Any]:
    """Navigation stage (SPEC §6) into ``out/navigation``; returns the summary dict.
    ``options``: how it runs (``StageRun``: ``resume``, ``force``, ``on_generation``,
    ``executor``, ``envelope``), as for every stage.

    The populations evolve one after another in this process (the numba kernel uses every
    core), or each as one run of ``executor`` (``infra.executors``; progress then arrives
    per finished population): the same seeds give the same results either way.

    The final section is picked as ``navigation`` says (``NavigationSettings``): by default
    the best individual of every saved generation of every population runs from
    ``navigation.selection_starts`` fresh starts of their own seed, and the one that docks
    most often there becomes ``navigation/best.txt``. It is then reported on the
    ``ga.test_starts`` test starts, which the choice never saw. Summary keys:
    ``dock_success`` (fraction of the test starts the chosen section docks from),
    ``mean_steps_to_dock``, ``test_fitness``, ``chosen_population``, ``chosen_generation``,
    ``selection`` (how it was chosen and its rates on the selection starts), ``candidates``
    (every candidate's selection dock rate and fitness), ``populations`` (each population's
    final best on the test starts: fitness, dock rate, final training fitness), ``wall_s``,
    ``settings``.

    With ``navigation.dock_heading_tol_deg`` set, every run of the stage docks within that
    band; ``spec_dock_success`` is then the chosen section's rate on the same test starts
    (world of §3) docking within ``world``'s band (SPEC §3's 30°), the band it will run in.

    ``envelope`` (SPEC §9): the populations evolve in it and the candidates are compared in
    it (key ``key_of_test(seed, "selection")``); the test keys above stay the world of §3,
    and ``envelope_dock_success``, ``envelope_mean_steps_to_dock``, ``envelope_test_fitness``
    (and ``envelope_dock_rate``, ``envelope_test_fitness`` per population) give the same
    test starts in the envelope (key ``key_of_test(seed, "docking")``).

    ``first``: an (8, 30) section every individual of generation 0 carries (recorded as
    ``initial_section``; a resume with another is refused), e.g. a lineage found in another
    world carried into an envelope; None: a random generation 0.
    """
    run = StageRun(**options)
    ga = navigation_ga_settings() if ga is None else ga
    given, world = world, navigation.world(world)
    stage = started_from(navigation_stage(world, navigation, ga.generations, run.envelope), first)
    folder = Path(out) / "navigation"
    with _stage_folder(stage, folder, table, ga, world, run.resume, run.force) as doc:
        t0 = time.perf_counter()
        results, test_starts = _run_populations(
            stage, folder, doc, table=table, ga=ga, world=world, run=run
        )
        summary = _navigation_summary(stage, folder, results, test_starts, table, ga, world,
                                      navigation, given.dock_heading_tol_deg)  # fmt: skip
        return write_summary(folder, summary, t0, run, doc)


def write_summary(
    folder: Path, summary: dict[str, Any], t0: float, run: StageRun, doc: dict[str, Any],
    after: dict[str, Any] | None = None,
) -> dict[str, Any]:  # fmt: skip
    """``summary`` with the keys that end every stage's summary — ``wall_s`` (seconds since
    ``perf_counter`` read ``t0``), ``resumed``, ``settings`` (``doc``) — and then ``after``,
    written as ``folder/summary.json``; returns it."""
    summary = summary | {
        "wall_s": time.perf_counter() - t0, "resumed": bool(run.resume), "settings": doc,
    }  # fmt: skip
    summary |= after or {}
    atomic_write_json(folder / "summary.json", summary)
    return summary


def choose_section(dock_rate: np.ndarray, fitness: np.ndarray, criterion: str) -> int:
    """Index of the candidate a navigation stage keeps: the highest ``dock_rate`` (ties: the
    highest mean run ``fitness``) for criterion ``"dock_rate"``, the highest ``fitness`` for
    ``"fitness"``; remaining ties go to the lowest index."""
    dock_rate, fitness = np.asarray(dock_rate, float), np.asarray(fitness, float)
    if criterion == "fitness":
        return int(np.argmax(fitness))
    if criterion != "dock_rate":
        raise StageError(f"criterion must be 'dock_rate' or 'fitness', got {criterion!r}")
    return int(np.lexsort((-fitness, -dock_rate))[0])


def navigation_candidates(
    folder: Path, results: list[PopulationResult], ga: GASettings, nav: NavigationSettings
) -> list[tuple[int, int, np.ndarray]]:
    """(population, generation, section) of every section the choice compares: each
    population's final best, and with ``nav.candidates == "saved"`` the best of every saved
    generation before it too (read from ``populations/pop{k}_gen{g:04d}.npz``)."""
    gens = save_generations(ga) if nav.candidates == "saved" else (ga.generations,)
    out = []
    for r in results:
        for g in gens:
            if g == ga.generations:
                best = r.best
            else:
                path = folder / "populations" / f"pop{r.index}_gen{g:04d}.npz"
                best = read_npz(path, "saved population", ("best",), error=StageError)["best"]
            out.append((r.index, g, np.asarray(best, dtype=np.uint8)))
    return out


def _dock_stats(
    sections: np.ndarray, starts: np.ndarray, stage: Stage, table: GaitTable,
    world: WorldSettings, key: tuple[int, ...] = (0, 0),
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:  # fmt: skip
    """Per section: (mean run fitness, dock rate, mean steps to dock (NaN if none), end codes
    (C, S)) on ``starts``, in ``stage``'s envelope with the draws of ``key``."""
    run_fit, ev, _, inverse = evaluate_sections(sections, starts, stage, table, world, key)
    ends = np.asarray(ev.end)[inverse]
    docked = ends == END_DOCKED
    steps = np.asarray(ev.steps, dtype=float)[inverse]
    with np.errstate(invalid="ignore"):
        mean_steps = np.where(docked, steps, 0.0).sum(axis=1) / docked.sum(axis=1)
    return run_fit.mean(axis=1), docked.mean(axis=1), mean_steps, ends


def _navigation_summary(
    stage: Stage, folder: Path, results: list[PopulationResult], test_starts: np.ndarray,
    table: GaitTable, ga: GASettings, world: WorldSettings, nav: NavigationSettings,
    spec_tol_deg: float,
) -> dict[str, Any]:  # fmt: skip
    """Choose the section, write ``best.txt``, ``best_pop{k}.txt`` and ``docking.png``; the
    summary (with ``spec_dock_success`` when the stage's docking band is not
    ``spec_tol_deg``)."""
    from evolve import figures

    cands = navigation_candidates(folder, results, ga, nav)
    sel_starts = stage.starts(stage_rng(ga.seed, stage.name, 1), nav.selection_starts, world)
    sections = np.stack([c[2] for c in cands])
    sel_key = key_of_test(ga.seed, "selection")
    sel_fit, sel_dock, _, sel_ends = _dock_stats(sections, sel_starts, stage, table, world,
                                                 sel_key)  # fmt: skip
    c = choose_section(sel_dock, sel_fit, nav.criterion)
    chosen_k, chosen_g, chosen = cands[c]
    finals = np.stack([r.best for r in results])
    tested = np.concatenate([chosen[None], finals])
    worlds, dock_key = both_worlds(stage), key_of_test(ga.seed, "docking")
    stats = {
        prefix: _dock_stats(tested, test_starts, st, table, world, dock_key)
        for prefix, st in worlds
    }  # fmt: skip
    fit, dock, steps, _ = stats[""]
    spec = {}
    if world.dock_heading_tol_deg != spec_tol_deg:
        band = dataclasses.replace(world, dock_heading_tol_deg=spec_tol_deg)
        _, spec_dock, _, _ = _dock_stats(chosen[None], test_starts, worlds[0][1], table, band,
                                         dock_key)  # fmt: skip
        spec = {"spec_dock_success": float(spec_dock[0])}
    per_pop = []
    for j, r in enumerate(results, start=1):
        k = r.index
        per_pop.append({
            "population": k, "test_fitness": float(fit[j]), "dock_rate": float(dock[j]),
            "mean_steps_to_dock": _maybe(steps[j]),
            "final_training_fitness": float(r.history[-1, 1]),
        })  # fmt: skip
        if "envelope_" in stats:
            e_fit, e_dock, _, _ = stats["envelope_"]
            per_pop[-1] |= {"envelope_test_fitness": float(e_fit[j]),
                            "envelope_dock_rate": float(e_dock[j])}  # fmt: skip
        extra = (f"test fitness {fit[j]:.4f}, docked {dock[j]:.0%} of {len(test_starts)} test "
                 "starts")  # fmt: skip
        write_chromosome(folder / f"best_pop{k}.txt", r.best,
                         _provenance("navigation", k, ga, table, extra))  # fmt: skip
    header = _provenance(
        "navigation", chosen_k, ga, table,
        f"chosen: the best of {len(cands)} candidates by {nav.criterion} on "
        f"{len(sel_starts)} selection starts{_in(stage)} (docked {sel_dock[c]:.0%}); docked "
        f"{dock[0]:.0%} of {len(test_starts)} fresh test starts",
        generation=chosen_g,
    )  # fmt: skip
    write_chromosome(folder / "best.txt", chosen, header)
    figures.docking_map(
        folder / "docking.png", sel_starts, sel_ends[c], world,
        f"navigation/best.txt (generation {chosen_g} of population {chosen_k}) from "
        f"{len(sel_starts)} selection starts{_in(stage)}: docked {sel_dock[c]:.1%}",
    )  # fmt: skip
    return {
        "stage": "navigation",
        "dock_success": float(dock[0]),
        "mean_steps_to_dock": _maybe(steps[0]),
        "test_fitness": float(fit[0]),
        "test_starts": len(test_starts),
        "chosen_population": chosen_k,
        "chosen_generation": chosen_g,
        "selection": {
            **nav.to_dict(),
            "dock_rate": float(sel_dock[c]),
            "fitness": float(sel_fit[c]),
        },
        "candidates": [
            {
                "population": k,
                "generation": g,
                "selection_dock_rate": float(d),
                "selection_fitness": float(f),
            }
            for (k, g, _), d, f in zip(cands, sel_dock, sel_fit, strict=True)
        ],  # fmt: skip
        "populations": per_pop,
    } | _envelope_docking(stage, stats) | spec


def _envelope_docking(stage: Stage, stats: dict[str, tuple]) -> dict[str, Any]:
    """The chosen section's test figures in the envelope (``envelope_*`` keys; none without
    one)."""
    if "envelope_" not in stats:
        return {}
    fit, dock, steps, _ = stats["envelope_"]
    return {
        "envelope": stage.envelope.to_dict(),
        "envelope_dock_success": float(dock[0]),
        "envelope_mean_steps_to_dock": _maybe(steps[0]),
        "envelope_test_fitness": float(fit[0]),
    }


def _in(stage: Stage) -> str:
    """Where a stage's own runs (selection) happen, for titles: "" or " in the envelope"."""
    return "" if stage.envelope == NONE else " in the envelope"


def _maybe(v: float) -> float | None:
    return None if not np.isfinite(v) else float(v)


def _provenance(
    stage: str, k: int, ga: GASettings, table: GaitTable, extra: str, generation: int | None = None
) -> str:
    gen = "final generation" if generation in (None, ga.generations) else "generation"
    return (
        f"servobot {stage} stage, population {k} of {ga.populations}, {gen} "
        f"{ga.generations if generation is None else generation} of {ga.generations}, "
        f"population size {ga.population_size}, seed {ga.seed}\n"
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
    first: np.ndarray | None = None,
    **options: Unpack[StageOptions],
) -> dict[str, Any]:
    """Coverage stage (SPEC §5) into ``out/coverage`` with Figures 8–10; returns the summary.
    ``executor``: where the populations evolve, as in ``run_navigation``.

    Figure 9: the best section of each saved generation of each population runs (with the
    fixed ``navigation`` section) from the same ``ga.test_starts`` fresh coverage starts;
    inner squares / 64 as a percentage. Summary keys: ``figure9`` (per population and mean,
    per generation), ``final_mean_inner_percent``, ``final_inner_percent`` (per population),
    ``figure10`` (squares, docks, end per population), ``handoffs`` (``evolve.handoff``: how
    often navigation docked after each finalist's switches to it on the Figure 9 test
    starts, all finalists and per population; every hand-off in ``handoffs.csv``),
    ``wall_s``, ``settings``.

    ``envelope`` (SPEC §9): the populations evolve in it; Figure 9 is also measured in it on
    the same test starts (key ``key_of_test(seed, "figure9")``): ``envelope_figure9_*``,
    ``envelope_final_*`` beside the keys above (the world of §3), and ``envelope`` (its
    fields); hand-offs and Figure 10 stay in the world of §3.

    ``first``: an (8, 30) coverage section every individual of generation 0 carries, as in
    ``run_navigation`` (e.g. a finalist evolved in one envelope refined in another); None: a
    random generation 0.
    """
    out = Path(out)
    run = StageRun(**options)
    stage = started_from(coverage_stage(world, navigation, run.envelope), first)
    with _stage_folder(stage, out / "coverage", table, ga, world, run.resume, run.force) as doc:
        return _coverage(stage, out, doc, table, ga, world, run)


def _coverage(
    stage: Stage, out: Path, doc: dict[str, Any], table: GaitTable, ga: GASettings,
    world: WorldSettings, run: StageRun,
) -> dict[str, Any]:  # fmt: skip
    from evolve import figures

    t0 = time.perf_counter()
    folder = out / "coverage"
    results, test_starts = _run_populations(
        stage, folder, doc, table=table, ga=ga, world=world, run=run
    )
    gens = save_generations(ga)
    fig9 = figure9_both(folder, stage, table, world, gens, ga.populations, test_starts, ga.seed)
    inner = fig9[""][0]
    _write_figure9(folder, gens, fig9, stage.envelope)
    figures.figure9(folder / "figure9.png", gens, inner)
    figures.figure8(out / "figure8.png", world)
    handoffs = {
        r.index: collect_handoffs(stage.genomes(r.best[None])[0], test_starts, table=table,
                                  world=world)
        for r in results
    }  # fmt: skip
    write_handoffs(folder / "handoffs.csv", handoffs)
    fig10 = []
    for r in results:
        k = r.index
        full = stage.genomes(r.best[None])[0]
        extra = (
            "16 genes: coverage section (learned) + navigation (fixed); "
            f"Figure 9 test {inner[k, -1]:.1f}% of the {world.inner_square_count} inner squares"
        )
        write_chromosome(
            folder / f"best_pop{k}.txt", full, _provenance("coverage", k, ga, table, extra)
        )
        fig = figures.figure10(
            folder / f"figure10_pop{k}.png", full, table=table, world=world,
            start=FIGURE10_START, title=f"population {k}",
        )  # fmt: skip
        fig10.append({"population": k, **fig})
    summary = {
        "stage": "coverage",
        "generations": list(gens),
        **figure9_summary(fig9[""]),
        "figure10": fig10,
        "handoffs": {
            "all": handoff_rate(h for runs in handoffs.values() for found in runs for h in found),
            "populations": [
                handoff_rate(h for found in handoffs[k] for h in found) for k in sorted(handoffs)
            ],
        },
        "test_starts": len(test_starts),
    }
    return write_summary(folder, summary, t0, run, doc, envelope_figure9(stage, fig9))


def figure9_summary(fig9: tuple[np.ndarray, np.ndarray], prefix: str = "") -> dict[str, Any]:
    """Summary keys of one world's Figure 9 (inner %, squares; (populations, generations)):
    per generation the mean and each population's inner %, the final ones, the final mean
    squares; keys prefixed by ``prefix``."""
    inner, squares = fig9
    mean = inner.mean(axis=0)
    return {
        f"{prefix}figure9_mean_inner_percent": mean.tolist(),
        f"{prefix}figure9_inner_percent": inner.tolist(),
        f"{prefix}final_mean_inner_percent": float(mean[-1]),
        f"{prefix}final_inner_percent": inner[:, -1].tolist(),
        f"{prefix}final_mean_squares": squares[:, -1].tolist(),
    }


def envelope_figure9(
    stage: Stage, fig9: dict[str, tuple[np.ndarray, np.ndarray]]
) -> dict[str, Any]:
    """The envelope's Figure 9 summary keys (``envelope_*``) and fields; none without one."""
    if "envelope_" not in fig9:
        return {}
    return {"envelope": stage.envelope.to_dict(), **figure9_summary(fig9["envelope_"], "envelope_")}


def figure9_both(
    folder: Path, stage: Stage, table: GaitTable, world: WorldSettings,
    generations: tuple[int, ...], populations: int, test_starts: np.ndarray, seed: int,
) -> dict[str, tuple[np.ndarray, np.ndarray]]:  # fmt: skip
    """``figure9_test`` in each world of ``both_worlds``, keyed by its prefix (the envelope's
    draws: ``key_of_test(seed, "figure9")``, the same for every saved best)."""
    key = key_of_test(seed, "figure9")
    return {
        prefix: figure9_test(folder, st, table, world, generations, populations, test_starts, key)
        for prefix, st in both_worlds(stage)
    }


def figure9_test(
    folder: Path,
    stage: Stage,
    table: GaitTable,
    world: WorldSettings,
    generations: tuple[int, ...],
    populations: int,
    test_starts: np.ndarray,
    key: tuple[int, ...] = (0, 0),
) -> tuple[np.ndarray, np.ndarray]:
    """Figure 9 (SPEC §5): the saved best of every generation in ``generations`` of every
    population, run from the shared ``test_starts`` (in ``stage``'s envelope, with the draws
    of ``key``). Returns (inner %, of the inner squares; mean squares, of 100), each
    (populations, generations)."""
    inner = np.zeros((populations, len(generations)))
    squares = np.zeros_like(inner)
    for k in range(populations):
        bests = []
        for g in generations:
            path = folder / "populations" / f"pop{k}_gen{g:04d}.npz"
            bests.append(read_npz(path, "saved population", ("best",), error=StageError)["best"])
        sections = np.stack(bests).astype(np.uint8)
        _, ev, _, inverse = evaluate_sections(sections, test_starts, stage.for_population(k),
                                              table, world, key)  # fmt: skip
        inner[k] = 100.0 * ev.inner_squares[inverse].mean(axis=1) / world.inner_square_count
        squares[k] = ev.squares[inverse].mean(axis=1)
    return inner, squares


def _write_figure9(
    folder: Path, gens: tuple[int, ...], fig9: dict[str, tuple[np.ndarray, np.ndarray]],
    envelope: Envelope = NONE,
) -> None:  # fmt: skip
    """``figure9.csv`` and ``figure9.json`` of each world of ``fig9`` (prefix → (inner %,
    squares)): the world of §3's columns and keys, then the envelope's, prefixed."""
    prefixes = list(fig9)
    inner = fig9[""][0]
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(("population", "generation", *(f"{p}inner_percent" for p in prefixes)))
    for k in range(inner.shape[0]):
        for j, g in enumerate(gens):
            w.writerow((k, g, *(f"{fig9[p][0][k, j]:.4f}" for p in prefixes)))
    atomic_write_text(folder / "figure9.csv", buf.getvalue())
    doc: dict[str, Any] = {"generations": list(gens)}
    for p in prefixes:
        inner, sq = fig9[p]
        doc |= {
            f"{p}inner_percent": {str(k): inner[k].tolist() for k in range(inner.shape[0])},
            f"{p}mean_inner_percent": inner.mean(axis=0).tolist(),
            f"{p}mean_squares_of_100": {str(k): sq[k].tolist() for k in range(sq.shape[0])},
        }
    if envelope != NONE:
        doc["envelope"] = envelope.to_dict()
    doc["note"] = (
        "best individual of each saved generation on the shared fresh test starts; "
        "inner squares reached / 64 × 100"
        + ("; envelope_*: the same runs in the envelope of variation" if envelope != NONE else "")
    )
    atomic_write_json(folder / "figure9.json", doc)


__all__ = [
    "navigation_section",
    "STAGE_FILES",
    "StageError",
    "check_ga",
    "run_navigation",
    "both_worlds",
    "check_envelope",
    "choose_section",
    "envelope_figure9",
    "figure9_both",
    "figure9_summary",
    "navigation_candidates",
    "run_coverage",
    "navigation_run_fitness",
    "coverage_run_fitness",
    "evaluate_sections",
    "stage_need",
    "stage_seeds",
    "stage_settings_doc",
    "populations_on",
    "CHECKPOINT_EVERY",
]
