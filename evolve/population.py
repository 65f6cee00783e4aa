"""One population of the CGA, generation by generation, checkpointed and resumable.

A ``Stage`` says what is evolved (mode, steps, start poses, run fitness, a fixed navigation
section to append); a ``PopulationRun`` is one population's loop, exposed step by step so
that a caller can look at (or bias) the fitness between evaluating a generation and
breeding the next one — anytime learning drives several populations in lockstep this way.
``evolve_population`` is the plain loop::

    rng = Generator(PCG64(population's own SeedSequence))
    pop = random sections                                  # generation 0
    for g in 0..G:
        [checkpoint (g, pop, rng state) every CHECKPOINT_EVERY generations]
        starts = 10 start poses drawn from rng             # shared by the population
        fitness = mean over starts of the run fitness      # unique genomes evaluated once,
                                                           # in the stage's envelope, key (seed, g)
        [save population + best if g is a save generation]
        if g < G: pop = next_generation(pop, fitness, rng)

Progress reaches the outside through ``on_generation(record)``, never prints.
"""

from __future__ import annotations

import csv
import dataclasses
import io
import json
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from evolve import ga as gaops
from evolve.checkpoint import check_array, check_settings, read_npz, write_npz
from evolve.codec import GENE_BITS, SECTION_GENES
from evolve.envelope import NONE, Envelope
from evolve.interpreter import END_DOCKED
from evolve.settings import GASettings, WorldSettings
from evolve.table import GaitTable
from infra.errors import InputError
from infra.io import atomic_write_text

CHECKPOINT_EVERY = 16
"""Generations between checkpoints of a population (operational, not a SPEC value)."""
STAGE_IDS = {"navigation": 0, "coverage": 1, "colony": 2, "anytime": 3}
"""Second entropy word of each stage's SeedSequence, so the stages draw different numbers.
``anytime`` seeds only the physics punctuations' own draws (their start poses and servo
noise, the final test); its populations evolve from coverage's seeds (``evolve.anytime``)."""
HISTORY_COLUMNS = ("generation", "best_fitness", "mean_fitness", "docked_fraction", "unique")
"""Columns of ``history_pop{k}.csv``: per generation, on that generation's 10 starts;
``docked_fraction`` = fraction of all runs that docked at least once; ``unique`` = distinct
genomes evaluated."""

OnGeneration = Callable[[dict[str, Any]], None]
"""``on_generation(record)``: ``stage``, ``population``, ``generations`` (the final one), then
the ``HISTORY_COLUMNS`` of the generation just evaluated."""


class StageError(InputError, RuntimeError):
    """A stage cannot run or resume (bad settings, corrupt or mismatched checkpoint)."""


@dataclass(frozen=True)
class Stage:
    """What differs between the learning stages."""

    name: str
    mode: str
    max_steps: int
    starts: Callable[[np.random.Generator, int, WorldSettings], np.ndarray]
    run_fitness: Callable[[Any, np.ndarray, WorldSettings], np.ndarray]
    navigation: np.ndarray | None = None
    """Fixed navigation section (8, 30) appended to every coverage section."""
    evaluate: Callable[..., Any] | None = None
    """Batch evaluation with ``evolve.evaluate``'s signature; None: ``evolve.evaluate``, one
    robot per run (the colony stage passes ``evaluate_colony`` bound to its settings)."""
    extra_settings: tuple[Any, ...] = ()
    """Further settings dataclasses saved with the stage and checked on resume."""
    training_starts: Callable[[np.random.Generator, int, WorldSettings, int], np.ndarray] | None = (
        None
    )
    """``training_starts(rng, n, world, generation)``: the start poses of a generation's runs
    when they are not ``starts``' (the navigation stage's growing start region); None:
    ``starts``. The test starts always come from ``starts``."""
    envelope: Envelope = NONE
    """The envelope of variation (SPEC §9) every evaluation of the stage runs in: training
    with the keys ``Envelope.training_keys(seed, generation)`` (one per draw per start) once
    past its warm-up (``Envelope.warmup_fraction``; the warm-up trains in the world of §3),
    tests with ``evolve.envelope.key_of_test``; ``NONE``: the world of §3. A stage evolved in
    an envelope reports its tests in both worlds."""

    coverage: np.ndarray | None = None
    """(K, 8, 30): population k's fixed coverage section, put before every navigation section
    it evolves (the colony's navigation stage, ``ColonySettings.sections = "navigation"``);
    ``for_population(k)`` keeps row k. None: the sections are whole chromosomes' first half."""
    initial: np.ndarray | None = None
    """(8, 30): the section every individual of generation 0 carries; None: uniformly random
    bits (SPEC §5)."""

    def for_population(self, k: int) -> Stage:
        """The stage population ``k`` evolves in: with ``coverage``, its own row of it."""
        if self.coverage is None:
            return self
        return dataclasses.replace(self, coverage=self.coverage[k : k + 1])

    def genomes(self, sections: np.ndarray) -> np.ndarray:
        """Chromosomes the kernel runs (P, 16, 30) or (P, 8, 30): the sections, sections +
        navigation, or (``coverage``, one population's) coverage + sections."""
        n = sections.shape[0]
        if self.coverage is not None:
            if len(self.coverage) != 1:
                raise StageError("a stage with a coverage section per population runs one "
                                 "population at a time: Stage.for_population(k)")  # fmt: skip
            parts = [np.broadcast_to(self.coverage[0], (n, *self.coverage.shape[1:])), sections]
        elif self.navigation is not None:
            parts = [sections, np.broadcast_to(self.navigation, (n, *self.navigation.shape))]
        else:
            return np.ascontiguousarray(sections)
        return np.ascontiguousarray(np.concatenate(parts, axis=1))


def evaluate_sections(
    sections: np.ndarray,
    starts: np.ndarray,
    stage: Stage,
    table: GaitTable,
    world: WorldSettings,
    key: tuple[int, ...] = (0, 0),
) -> tuple[np.ndarray, Any, np.ndarray, np.ndarray]:
    """Run every distinct section once from every start, in ``stage.envelope`` with the draws
    of ``key`` (the stage's seed and the generation, or a test's key).

    Returns ``(run_fitness (P, S), evaluation of the unique genomes, unique index (U,),
    inverse (P,))`` where row p of the population's results is row ``inverse[p]`` of the
    unique ones. Converged populations repeat individuals; the results are identical to
    evaluating all P, with less work.
    """
    from evolve.evaluation import evaluate  # numba: loaded on first use

    p = sections.shape[0]
    packed = np.packbits(sections.reshape(p, -1), axis=1)
    _, first, inverse = np.unique(packed, axis=0, return_index=True, return_inverse=True)
    inverse = inverse.reshape(-1)
    varied = {} if stage.envelope == NONE else {"envelope": stage.envelope, "envelope_key": key}
    ev = (stage.evaluate or evaluate)(
        stage.genomes(sections[first]),
        np.ascontiguousarray(starts, dtype=np.float64),
        table=table,
        mode=stage.mode,
        start_power=world.start_power_v,
        max_steps=stage.max_steps,
        settings=world,
        **varied,
    )
    run_fit = stage.run_fitness(ev, starts, world)
    return run_fit[inverse], ev, first, inverse


def training_generation(
    sections: np.ndarray, starts: np.ndarray, stage: Stage, table: GaitTable,
    world: WorldSettings, ga: GASettings, generation: int,
) -> Generation:  # fmt: skip
    """Evaluate generation ``generation`` of a population from its training ``starts``: in
    the world of §3 during the envelope's warm-up, else once per training draw of
    ``stage.envelope`` (``Envelope.training_keys``), a run's fitness the mean (or ``min``,
    ``draw_fitness``) over its draws."""
    if generation < stage.envelope.warmup_generations(ga.generations):
        stage = dataclasses.replace(stage, envelope=NONE)
    fits, docked = [], []
    for key in stage.envelope.training_keys(ga.seed, generation):
        run_fit, ev, first, inverse = evaluate_sections(sections, starts, stage, table, world, key)
        fits.append(run_fit)
        docks = (np.asarray(ev.docks) > 0) | (np.asarray(ev.end) == END_DOCKED)
        docked.append(docks[inverse])
    combine = np.min if stage.envelope.draw_fitness == "min" else np.mean
    run_fit = fits[0] if len(fits) == 1 else combine(fits, axis=0)
    return Generation(starts, run_fit.mean(axis=1), float(np.mean(docked)), len(first))


class SpawnedSeeds(Sequence):
    """Children ``first``, ``first + 1``, ... of a SeedSequence, made when asked for: equal to
    ``root.spawn(...)``'s but costing nothing up front (a billion populations do not hang)."""

    def __init__(self, root: np.random.SeedSequence, first: int, count: int) -> None:
        self.root, self.first, self.count = root, first, count

    def __len__(self) -> int:
        return self.count

    def __getitem__(self, k: Any) -> Any:
        if isinstance(k, slice):
            return [self[i] for i in range(*k.indices(self.count))]
        if not -self.count <= k < self.count:
            raise IndexError(k)
        r = self.root
        child = self.first + k % self.count
        return np.random.SeedSequence(
            r.entropy, spawn_key=(*r.spawn_key, child), pool_size=r.pool_size
        )


def stage_seeds(
    seed: int, stage: str, populations: int
) -> tuple[np.random.SeedSequence, SpawnedSeeds]:
    """(test-start seed, population seeds) of a stage: the children of
    ``SeedSequence([seed, stage id])``, as ``.spawn(populations + 1)`` gives them; child 0 draws
    the shared test starts, child 1 + k drives population k, so a population's numbers do not
    depend on how many populations run."""
    root = np.random.SeedSequence([int(seed), STAGE_IDS[stage]])
    return SpawnedSeeds(root, 0, 1)[0], SpawnedSeeds(root, 1, populations)


def stage_rng(seed: int, stage: str, *key: int) -> np.random.Generator:
    """A generator of one of a stage's own draws beside its populations and test starts:
    ``SeedSequence([seed, stage id, *key])`` (navigation (1,): the selection starts on which
    the candidate sections are compared; anytime (0,): the final test, (1, g): the
    punctuation at generation g), independent of ``stage_seeds``' children."""
    seq = np.random.SeedSequence([int(seed), STAGE_IDS[stage], *key])
    return np.random.Generator(np.random.PCG64(seq))


def save_generations(ga: GASettings) -> tuple[int, ...]:
    """The save generations that exist in this run, plus the final one."""
    return tuple(sorted({g for g in ga.save_generations if g <= ga.generations} | {ga.generations}))


@dataclass
class PopulationResult:
    """A finished population: its final best section and per-generation history."""

    index: int
    best: np.ndarray
    history: np.ndarray
    """(G + 1, len(HISTORY_COLUMNS))."""


@dataclass(frozen=True)
class Generation:
    """One evaluated generation: its starts and the (unbiased) fitness of every individual."""

    starts: np.ndarray
    """(S, 3) start poses drawn for this generation."""
    fitness: np.ndarray
    """(P,) mean run fitness over the starts."""
    docked_fraction: float
    """Fraction of all runs that docked at least once."""
    unique: int
    """Distinct genomes evaluated."""


class PopulationRun:
    """Population ``k`` of ``stage`` in ``folder``: resumes from its checkpoint, then
    ``evaluate()`` / ``commit(fitness)`` one generation at a time until ``finished``.

    Files: ``checkpoints/pop{k}.npz`` every ``CHECKPOINT_EVERY`` generations (population,
    generation, rng state, history, settings), ``populations/pop{k}_gen{g:04d}.npz`` at the
    save generations, and on completion ``checkpoints/pop{k}_final.npz`` and
    ``history_pop{k}.csv``. A resumed run is bit-identical to an uninterrupted one.
    """

    def __init__(
        self,
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
    ) -> None:
        stage = stage.for_population(k)
        self.k, self.stage, self.folder = k, stage, Path(folder)
        self.table, self.ga, self.world, self.settings_text = table, ga, world, settings_text
        self.ckpt = self.folder / "checkpoints" / f"pop{k}.npz"
        self.final = self.folder / "checkpoints" / f"pop{k}_final.npz"
        self.saves = set(save_generations(ga))
        self.rng = np.random.Generator(np.random.PCG64(seed_seq))
        self.generation = 0
        self.history: list[tuple] = []
        self.result: PopulationResult | None = None
        self._pending: Generation | None = None
        if resume and self.final.exists():
            self._load_final()
        elif resume and self.ckpt.exists():
            self._load_checkpoint()
        elif stage.initial is not None:
            self.pop = np.repeat(stage.initial[None].astype(np.uint8), ga.population_size, axis=0)
        else:
            self.pop = gaops.random_sections(self.rng, ga.population_size, SECTION_GENES)

    @property
    def finished(self) -> bool:
        """Whether the final generation has been committed (now or in an earlier run)."""
        return self.result is not None

    def _load_final(self) -> None:
        data = read_npz(self.final, "final population file", ("best", "history", "settings"),
                        error=StageError)  # fmt: skip
        check_settings(data["settings"], self.settings_text, self.final, error=StageError)
        best = self._array(data, "best", (SECTION_GENES, GENE_BITS), self.final, bits=True)
        history = self._array(data, "history", (self.ga.generations + 1, len(HISTORY_COLUMNS)),
                              self.final)  # fmt: skip
        self.result = PopulationResult(self.k, best.astype(np.uint8), history)

    @staticmethod
    def _array(data: dict, key: str, shape: tuple, path: Path, bits: bool = False) -> np.ndarray:
        return check_array(data, key, shape, path, bits=bits, error=StageError)

    def _load_checkpoint(self) -> None:
        keys = ("population", "generation", "rng_state", "history", "settings")
        data = read_npz(self.ckpt, "checkpoint", keys, error=StageError)
        check_settings(data["settings"], self.settings_text, self.ckpt, error=StageError)
        try:
            self.rng.bit_generator.state = json.loads(str(data["rng_state"]))
        except (ValueError, TypeError, KeyError, OverflowError, RecursionError) as exc:
            raise StageError(f"{self.ckpt}: corrupt checkpoint (rng state: {exc})") from exc
        shape = (self.ga.population_size, SECTION_GENES, GENE_BITS)
        self.pop = self._array(data, "population", shape, self.ckpt, bits=True).astype(np.uint8)
        gen = self._array(data, "generation", (), self.ckpt)
        history = self._array(data, "history", (-1, len(HISTORY_COLUMNS)), self.ckpt)
        g = int(gen) if gen.dtype.kind in "iu" else -1
        if not 0 <= g <= self.ga.generations or len(history) != g:
            raise StageError(
                f"{self.ckpt}: corrupt checkpoint (generation {gen}, {len(history)} history "
                "rows); delete it to start over"
            )
        self.generation = g
        self.history = [tuple(row) for row in history.tolist()]

    def _checkpoint(self) -> None:
        write_npz(
            self.ckpt,
            population=self.pop,
            generation=np.int64(self.generation),
            rng_state=np.str_(json.dumps(self.rng.bit_generator.state)),
            history=np.asarray(self.history, dtype=np.float64).reshape(-1, len(HISTORY_COLUMNS)),
            settings=np.str_(self.settings_text),
        )

    def evaluate(self) -> Generation:
        """Checkpoint if due, draw this generation's starts and evaluate the population."""
        if self.finished:
            raise StageError(f"population {self.k} has already finished")
        if self.generation % CHECKPOINT_EVERY == 0:
            self._checkpoint()
        n, draw = self.ga.starts_per_generation, self.stage.training_starts
        if draw is None:
            starts = self.stage.starts(self.rng, n, self.world)
        else:
            starts = draw(self.rng, n, self.world, self.generation)
        self._pending = training_generation(
            self.pop, starts, self.stage, self.table, self.world, self.ga, self.generation
        )
        return self._pending

    def commit(self, fitness: np.ndarray | None = None) -> dict[str, Any]:
        """Record the evaluated generation and breed the next one from ``fitness`` (default:
        the evaluated fitness; anytime learning passes a biased one). Returns the
        ``on_generation`` record. After the final generation the population is finished."""
        gen_eval = self._pending
        if gen_eval is None:
            raise StageError("commit() needs an evaluate() first")
        self._pending = None
        fit = gen_eval.fitness if fitness is None else np.asarray(fitness, dtype=np.float64)
        best = int(np.argmax(fit))
        g = self.generation
        row = (g, float(fit[best]), float(fit.mean()), gen_eval.docked_fraction, gen_eval.unique)
        self.history.append(row)
        if g in self.saves:
            write_npz(
                self.folder / "populations" / f"pop{self.k}_gen{g:04d}.npz",
                population=self.pop,
                fitness=fit,
                best=self.pop[best],
                starts=gen_eval.starts,
            )
        if g == self.ga.generations:
            self._finish(best, fit)
        else:
            self.pop = gaops.next_generation(self.pop, fit, self.rng, self.ga)
            self.generation += 1
        return generation_record(self.stage.name, self.k, self.ga.generations, row)

    def _finish(self, best: int, fitness: np.ndarray) -> None:
        hist = np.asarray(self.history, dtype=np.float64)
        write_npz(
            self.final,
            best=self.pop[best],
            population=self.pop,
            fitness=fitness,
            history=hist,
            settings=np.str_(self.settings_text),
        )
        self.ckpt.unlink(missing_ok=True)
        write_history(self.folder / f"history_pop{self.k}.csv", hist)
        self.result = PopulationResult(self.k, self.pop[best].copy(), hist)


def evolve_population(
    k: int,
    stage: Stage,
    folder: Path,
    *,
    on_generation: OnGeneration | None = None,
    **kwargs: Any,
) -> PopulationResult:
    """Evolve population ``k`` to its final generation (``PopulationRun`` keyword arguments);
    ``on_generation(record)`` after every generation."""
    run = PopulationRun(k, stage, folder, **kwargs)
    while not run.finished:
        run.evaluate()
        record = run.commit()
        if on_generation is not None:
            on_generation(record)
    assert run.result is not None
    return run.result


def generation_record(stage: str, k: int, generations: int, row: Any) -> dict[str, Any]:
    """The ``on_generation`` record of population ``k`` for one ``HISTORY_COLUMNS`` row."""
    g, best, mean, docked, unique = row
    return {"stage": stage, "population": k, "generations": generations} | dict(
        zip(HISTORY_COLUMNS, (int(g), float(best), float(mean), float(docked), int(unique)),
            strict=True)
    )  # fmt: skip


@dataclass(frozen=True)
class PopulationJob:
    """One population's whole evolution as a run of an executor (picklable plain data):
    ``evolve_population(k, stage, folder, **kwargs)``."""

    k: int
    stage: Stage
    folder: Path
    kwargs: dict[str, Any]
    """``PopulationRun`` keyword arguments (seed sequence, table, settings, resume)."""
    threads: int | None = None
    """Threads of the numba kernel while this population evolves (None = as they are)."""
    evolve: Callable[..., Any] = evolve_population
    """What evolves it: ``evolve_population``, or ``evolve.coevolution.evolve_team`` for a
    team of populations (then ``k`` is the team)."""


def run_population_job(job: PopulationJob) -> Any:
    """Evolve one population (or team) where an executor runs it (no progress callback
    crosses)."""
    if job.threads is None:
        return job.evolve(job.k, job.stage, job.folder, **job.kwargs)
    import numba

    before = numba.get_num_threads()
    numba.set_num_threads(min(job.threads, numba.config.NUMBA_NUM_THREADS))
    try:
        return job.evolve(job.k, job.stage, job.folder, **job.kwargs)
    finally:
        numba.set_num_threads(before)


def write_history(path: Path, hist: np.ndarray) -> None:
    """``history_pop{k}.csv`` of a finished population (``HISTORY_COLUMNS``)."""
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(HISTORY_COLUMNS)
    for row in hist:
        w.writerow([int(row[0]), f"{row[1]:.6g}", f"{row[2]:.6g}", f"{row[3]:.6g}", int(row[4])])
    atomic_write_text(path, buf.getvalue())


__all__ = [
    "CHECKPOINT_EVERY",
    "HISTORY_COLUMNS",
    "Generation",
    "OnGeneration",
    "PopulationJob",
    "PopulationResult",
    "PopulationRun",
    "Stage",
    "StageError",
    "evaluate_sections",
    "evolve_population",
    "generation_record",
    "run_population_job",
    "save_generations",
    "stage_rng",
    "stage_seeds",
    "training_generation",
    "write_history",
]
