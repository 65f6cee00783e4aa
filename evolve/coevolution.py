"""Cooperative coevolution of a colony's coverage sections (issue 17; ``ColonySettings.sections
= "team"``): each robot of the colony carries its own section, evolved in its own population.

A *team* is R populations, one per robot (Potter & De Jong's cooperative coevolution). In
generation g every population draws nothing of its own: the team draws the generation's
colony starts once (so every robot's population meets the same starts), then each individual
of population r runs as robot r of the colony whose other robots carry the *partners*, the
team of generation g − 1 (at g = 0, each population's individual 0, a random section). Its
fitness is the colony stage's run fitness (``ColonySettings.fitness``) averaged over the
starts, in the stage's envelope as any population's (``training_generation``). All
populations are scored before any partner changes, so the order of the robots does not
matter. The *team* of generation g is the best colony evaluated in it: the partners with
robot r* carrying population r*'s best, r* the population whose best scored highest (ties:
the lowest r). Taking every population's best instead makes a team of sections that never
ran together, each best only beside the old partners: in a probe (3 teams × 64 × 128) such
teams lost ground between generations (Figure 9 45.7 → 42.7 % from generation 64 to 128).
Then each population breeds its next generation with the GA of SPEC §5 (elitist: its best
survives). The stage's result is the final generation's team.

``ga.populations`` independent teams evolve (team t from the stage's population seed t), so
a team stage costs R × the shared stage's runs. Files in the stage's folder (the names the
shared stage's ``STAGE_FILES`` already own)::

    checkpoints/pop{t}_team.npz        (resume state, every CHECKPOINT_EVERY generations)
    checkpoints/pop{t}_team_final.npz  (populations, fitness, team, history when done)
    populations/pop{t}_gen{g:04d}.npz  (team (R, 8, 30), populations, fitness, starts)
    history_pop{t}_robot{r}.csv        best_pop{t}_robot{r}.txt (written by the stage)

A resumed team is bit-identical to an uninterrupted one (its checkpoint holds the
populations, the partners, every generator's state and the history).
"""

from __future__ import annotations

import dataclasses
import functools
import hashlib
import json
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from evolve import ga as gaops
from evolve.checkpoint import check_array, check_settings, read_npz, write_npz
from evolve.codec import GENE_BITS, SECTION_GENES
from evolve.envelope import NONE, key_of_test
from evolve.population import (
    CHECKPOINT_EVERY,
    HISTORY_COLUMNS,
    OnGeneration,
    PopulationJob,
    SpawnedSeeds,
    Stage,
    StageError,
    generation_record,
    save_generations,
    training_generation,
    write_history,
)
from evolve.settings import GASettings, WorldSettings
from evolve.stages import populations_on
from evolve.table import GaitTable
from infra.executors import Executor


@dataclass
class TeamResult:
    """A finished team: its final bests and per-robot history."""

    index: int
    team: np.ndarray
    """(R, 8, 30) sections: robot r's is population r's final best."""
    history: np.ndarray
    """(G + 1, R, len(HISTORY_COLUMNS)): each population's ``HISTORY_COLUMNS`` rows."""


def role_stage(stage: Stage, partners: np.ndarray, role: int) -> Stage:
    """``stage`` whose evaluation runs each individual as robot ``role`` of a colony whose
    other robots carry ``partners`` (R, 8, 30) sections (+ the stage's navigation)."""
    team = stage.genomes(partners)
    return dataclasses.replace(
        stage, evaluate=functools.partial(stage.evaluate, partners=team, role=role)
    )


def evaluate_team(
    team: np.ndarray, starts: np.ndarray, stage: Stage, table: GaitTable, world: WorldSettings,
    key: tuple[int, ...] = (0, 0),
) -> Any:  # fmt: skip
    """Run the team's sections (R, 8, 30) as one colony from every colony start (S, R, 3) in
    ``stage``'s envelope with the draws of ``key``; the ``ColonyEvaluation`` of one
    individual (row 0)."""
    genomes = stage.genomes(team)
    varied = {} if stage.envelope == NONE else {"envelope": stage.envelope, "envelope_key": key}
    assert stage.evaluate is not None
    return stage.evaluate(
        genomes[:1], np.ascontiguousarray(starts, dtype=np.float64), table=table,
        mode=stage.mode, start_power=world.start_power_v, max_steps=stage.max_steps,
        settings=world, partners=genomes, role=0, **varied,
    )  # fmt: skip


class TeamRun:
    """Team ``t`` of ``robots`` populations of ``stage`` in ``folder``: resumes from its
    checkpoint, then ``step()`` one generation at a time until ``finished``. A fresh team
    starts from random populations, or with ``initial`` (P, 8, 30) every population a copy of
    it and its index 0 every robot's partner."""

    def __init__(
        self,
        t: int,
        stage: Stage,
        folder: Path,
        *,
        robots: int,
        seed_seq: np.random.SeedSequence,
        table: GaitTable,
        ga: GASettings,
        world: WorldSettings,
        settings_text: str,
        resume: bool,
        initial: np.ndarray | None = None,
    ) -> None:
        self.t, self.stage, self.folder, self.robots = t, stage, Path(folder), robots
        self.table, self.ga, self.world, self.settings_text = table, ga, world, settings_text
        self.ckpt = self.folder / "checkpoints" / f"pop{t}_team.npz"
        self.final = self.folder / "checkpoints" / f"pop{t}_team_final.npz"
        self.saves = set(save_generations(ga))
        seeds = SpawnedSeeds(seed_seq, 0, robots + 1)
        self.starts_rng = np.random.Generator(np.random.PCG64(seeds[0]))
        self.rngs = [np.random.Generator(np.random.PCG64(seeds[1 + r])) for r in range(robots)]
        self.generation = 0
        self.history: list[list[tuple]] = []
        self.result: TeamResult | None = None
        if resume and self.final.exists():
            self._load_final()
        elif resume and self.ckpt.exists():
            self._load_checkpoint()
        elif initial is not None:  # every population a copy of it, its index 0 the partner
            self.pops = [np.array(initial, dtype=np.uint8) for _ in self.rngs]
            self.partners = np.stack([pop[0] for pop in self.pops])
        else:
            size = ga.population_size
            self.pops = [gaops.random_sections(rng, size, SECTION_GENES) for rng in self.rngs]
            self.partners = np.stack([pop[0] for pop in self.pops])

    @property
    def finished(self) -> bool:
        return self.result is not None

    def _shape(self, *lead: int) -> tuple[int, ...]:
        return (*lead, SECTION_GENES, GENE_BITS)

    def _load_final(self) -> None:
        data = read_npz(self.final, "final team file", ("team", "history", "settings"),
                        error=StageError)  # fmt: skip
        check_settings(data["settings"], self.settings_text, self.final, error=StageError)
        team = check_array(data, "team", self._shape(self.robots), self.final, bits=True,
                           error=StageError)  # fmt: skip
        shape = (self.ga.generations + 1, self.robots, len(HISTORY_COLUMNS))
        history = check_array(data, "history", shape, self.final, error=StageError)
        self.result = TeamResult(self.t, team.astype(np.uint8), history)

    def _load_checkpoint(self) -> None:
        keys = ("populations", "partners", "generation", "rng_state", "history", "settings")
        data = read_npz(self.ckpt, "team checkpoint", keys, error=StageError)
        check_settings(data["settings"], self.settings_text, self.ckpt, error=StageError)
        r, size = self.robots, self.ga.population_size
        pops = check_array(data, "populations", self._shape(r, size), self.ckpt, bits=True,
                           error=StageError)  # fmt: skip
        partners = check_array(data, "partners", self._shape(r), self.ckpt, bits=True,
                               error=StageError)  # fmt: skip
        history = check_array(data, "history", (-1, r, len(HISTORY_COLUMNS)), self.ckpt,
                              error=StageError)  # fmt: skip
        gen = data["generation"]
        g = int(gen) if gen.shape == () and gen.dtype.kind in "iu" else -1
        try:
            states = json.loads(str(data["rng_state"]))
            for rng, state in zip([self.starts_rng, *self.rngs], states, strict=True):
                rng.bit_generator.state = state
        except (ValueError, TypeError, KeyError, OverflowError, RecursionError) as exc:
            raise StageError(f"{self.ckpt}: corrupt team checkpoint (rng states: {exc})") from exc
        if not 0 <= g <= self.ga.generations or len(history) != g:
            raise StageError(
                f"{self.ckpt}: corrupt team checkpoint (generation {gen}, {len(history)} "
                "history rows); delete it to start over"
            )
        self.pops = [p.astype(np.uint8) for p in pops]
        self.partners = partners.astype(np.uint8)
        self.generation = g
        self.history = [[tuple(row) for row in rows] for rows in history.tolist()]

    def _checkpoint(self) -> None:
        states = [rng.bit_generator.state for rng in (self.starts_rng, *self.rngs)]
        write_npz(
            self.ckpt,
            populations=np.stack(self.pops),
            partners=self.partners,
            generation=np.int64(self.generation),
            rng_state=np.str_(json.dumps(states)),
            history=self._history_array(),
            settings=np.str_(self.settings_text),
        )

    def _history_array(self) -> np.ndarray:
        rows = np.asarray(self.history, dtype=np.float64)
        return rows.reshape(-1, self.robots, len(HISTORY_COLUMNS))

    def step(self) -> dict[str, Any]:
        """Evaluate and breed one generation of every population; returns the team's
        ``on_generation`` record (best and mean: the populations' means; docked: theirs)."""
        if self.finished:
            raise StageError(f"team {self.t} has already finished")
        g = self.generation
        if g % CHECKPOINT_EVERY == 0:
            self._checkpoint()
        starts = self.stage.starts(self.starts_rng, self.ga.starts_per_generation, self.world)
        gens = [
            training_generation(self.pops[r], starts, role_stage(self.stage, self.partners, r),
                                self.table, self.world, self.ga, g)  # fmt: skip
            for r in range(self.robots)
        ]
        best = [int(np.argmax(gen.fitness)) for gen in gens]
        top = int(np.argmax([gen.fitness[b] for gen, b in zip(gens, best, strict=True)]))
        team = self.partners.copy()
        team[top] = self.pops[top][best[top]]
        rows = [
            (g, float(gen.fitness[b]), float(gen.fitness.mean()), gen.docked_fraction,
             gen.unique)  # fmt: skip
            for gen, b in zip(gens, best, strict=True)
        ]
        self.history.append(rows)
        fitness = np.stack([gen.fitness for gen in gens])
        if g in self.saves:
            write_npz(
                self.folder / "populations" / f"pop{self.t}_gen{g:04d}.npz",
                team=team, populations=np.stack(self.pops), fitness=fitness, starts=starts,
            )  # fmt: skip
        self.partners = team
        if g == self.ga.generations:
            self._finish(fitness)
        else:
            self.pops = [
                gaops.next_generation(pop, fit, rng, self.ga)
                for pop, fit, rng in zip(self.pops, fitness, self.rngs, strict=True)
            ]
            self.generation += 1
        mean_row = tuple(np.mean(rows, axis=0))
        return generation_record(self.stage.name, self.t, self.ga.generations, mean_row)

    def _finish(self, fitness: np.ndarray) -> None:
        hist = self._history_array()
        write_npz(
            self.final, team=self.partners, populations=np.stack(self.pops), fitness=fitness,
            history=hist, settings=np.str_(self.settings_text),
        )  # fmt: skip
        self.ckpt.unlink(missing_ok=True)
        for r in range(self.robots):
            write_history(self.folder / f"history_pop{self.t}_robot{r}.csv", hist[:, r])
        self.result = TeamResult(self.t, self.partners.copy(), hist)


def evolve_team(
    t: int, stage: Stage, folder: Path, *, on_generation: OnGeneration | None = None,
    **kwargs: Any,
) -> TeamResult:  # fmt: skip
    """Evolve team ``t`` to its final generation (``TeamRun`` keyword arguments)."""
    run = TeamRun(t, stage, folder, **kwargs)
    while not run.finished:
        record = run.step()
        if on_generation is not None:
            on_generation(record)
    assert run.result is not None
    return run.result


def run_teams(
    stage: Stage, folder: Path, seeds: Any, *, robots: int, table: GaitTable, ga: GASettings,
    world: WorldSettings, settings_text: str, resume: bool,
    executor: Executor | None = None, threads: int | None = None,
    on_generation: OnGeneration | None = None, initial: np.ndarray | None = None,
) -> list[TeamResult]:  # fmt: skip
    """Evolve ``ga.populations`` teams (team t from ``seeds[t]``, and from ``initial[t]`` if
    given), in this process one after another or as runs of ``executor``; their results in
    order."""
    kwargs = [
        dict(robots=robots, seed_seq=seeds[t], table=table, ga=ga, world=world,
             settings_text=settings_text, resume=resume,
             initial=None if initial is None else initial[t])
        for t in range(ga.populations)
    ]  # fmt: skip
    if executor is None:
        return [
            evolve_team(t, stage, folder, on_generation=on_generation, **kwargs[t])
            for t in range(ga.populations)
        ]
    jobs = [PopulationJob(t, stage, folder, kwargs[t], threads, evolve_team)
            for t in range(ga.populations)]  # fmt: skip
    return populations_on(executor, jobs, on_generation, "team",
                           lambda res: res.history.mean(axis=1))  # fmt: skip


def shared_populations(run: Path, ga: GASettings) -> np.ndarray:
    """The final populations (T, P, 8, 30) of a finished shared colony run folder ``run``
    (``run/colony/checkpoints/pop{t}_final.npz``, t < ``ga.populations``), each with its best
    (by final fitness) at index 0: where ``--team-from`` starts a team stage. ``StageError``
    naming what is missing or of the wrong size."""
    out = []
    for t in range(ga.populations):
        path = Path(run) / "colony" / "checkpoints" / f"pop{t}_final.npz"
        if not path.exists():
            raise StageError(
                f"{path}: no such file; --team-from needs a finished shared colony run "
                f"('servobot evolve colony', --sections shared) of {ga.populations} populations"
            )
        data = read_npz(path, "final population file", ("population", "fitness"),
                        error=StageError)  # fmt: skip
        size = ga.population_size
        if len(data["population"]) != size:
            raise StageError(f"{path}: a population of {len(data['population'])}, but this team "
                             f"stage's populations hold {size} (--population-size)")  # fmt: skip
        pop = check_array(data, "population", (size, SECTION_GENES, GENE_BITS), path, bits=True,
                          error=StageError)  # fmt: skip
        fit = check_array(data, "fitness", (size,), path, error=StageError)
        pop = pop.astype(np.uint8)
        best = int(np.argmax(fit))
        pop[[0, best]] = pop[[best, 0]]
        out.append(pop)
    return np.stack(out)


def check_team_from(
    team_from: np.ndarray, colony: Any, ga: GASettings
) -> tuple[np.ndarray, dict[str, Any]]:
    """``team_from`` checked (team sections, (T, P, 8, 30) bits) and its ``settings.json``
    entry: ``{"team_from_sha256": ...}``; ``StageError`` naming the problem."""
    if colony.sections != "team":
        raise StageError("team_from: only for a team of sections (ColonySettings.sections 'team')")
    arr = np.asarray(team_from)
    want = (ga.populations, ga.population_size, SECTION_GENES, GENE_BITS)
    if arr.shape != want or not np.isin(arr, (0, 1)).all():
        raise StageError(f"team_from must be {want} bits (teams × population × genes × bits), "
                         f"got {arr.shape}")  # fmt: skip
    arr = np.ascontiguousarray(arr, dtype=np.uint8)
    return arr, {"team_from_sha256": hashlib.sha256(arr.tobytes()).hexdigest()}


def team_figure9(
    folder: Path, stage: Stage, table: GaitTable, world: WorldSettings,
    generations: tuple[int, ...], teams: int, test_starts: np.ndarray, seed: int,
) -> tuple[np.ndarray, np.ndarray]:  # fmt: skip
    """Figure 9 of a team stage: the team of every saved generation (each population's best
    of it) as one colony from the shared colony ``test_starts``, in ``stage``'s envelope
    (draws ``key_of_test(seed, "figure9")``). Returns (inner %, mean squares), each (teams,
    generations)."""
    key = key_of_test(seed, "figure9")
    inner = np.zeros((teams, len(generations)))
    squares = np.zeros_like(inner)
    for t in range(teams):
        for j, g in enumerate(generations):
            path = folder / "populations" / f"pop{t}_gen{g:04d}.npz"
            team = read_npz(path, "saved team generation", ("team",), error=StageError)["team"]
            ev = evaluate_team(team.astype(np.uint8), test_starts, stage, table, world, key)
            inner[t, j] = 100.0 * ev.inner_squares[0].mean() / world.inner_square_count
            squares[t, j] = ev.squares[0].mean()
    return inner, squares


__all__ = [
    "TeamResult",
    "TeamRun",
    "evaluate_team",
    "evolve_team",
    "check_team_from",
    "role_stage",
    "run_teams",
    "shared_populations",
    "team_figure9",
]
