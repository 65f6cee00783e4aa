"""The colony stage (SPEC §7): area coverage learned by a colony of R robots sharing one
station, all carrying the evolved chromosome (or, with ``ColonySettings.sections = "team"``,
each its own, ``evolve.coevolution``; with ``"navigation"``, the navigation section learned
behind a finished run's fixed coverage sections).

It is the coverage stage of SPEC §5 with the colony's fitness: every individual runs as a
colony of ``ColonySettings.robots`` from colony start poses (``evolve.starts.colony_starts``,
10 per generation, shared by the population) and a run scores the colony's squares, the union
of its robots' (``evolve.evaluate_colony``). The generation loop, checkpoints, seeds and the
Figure 9 test are the other stages' (``evolve.population``, ``evolve.stages``): only the
``Stage`` differs.

Layout under the run folder ``out``::

    colony/settings.json  colony/history_pop{k}.csv  colony/populations/  colony/checkpoints/
    colony/figure9.{csv,json,png}  colony/best_pop{k}.txt  colony/figure10_pop{k}.png
    colony/summary.json
    (a team stage: best_pop{t}_robot{r}.txt, history_pop{t}_robot{r}.csv, team checkpoints)
"""

from __future__ import annotations

import dataclasses
import functools
import json
import numbers
import time
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from evolve.codec import SECTION_GENES, read_chromosome, write_chromosome
from evolve.envelope import NONE, Envelope
from evolve.interpreter import END_NAMES
from evolve.population import Stage, StageError, save_generations, stage_seeds
from evolve.settings import ColonySettings, GASettings, WorldSettings
from evolve.stages import (
    StageOptions,
    StageRun,
    _check_section,
    _gene_text,
    _kernel_threads,
    _provenance,
    _run_populations,
    _stage_folder,
    _write_figure9,
    both_worlds,
    envelope_figure9,
    figure9_both,
    figure9_summary,
    started_from,
    write_summary,
)
from evolve.starts import CAPACITY_REHEARSALS, colony_capacity, colony_starts
from evolve.table import GaitTable

if TYPE_CHECKING:  # typing.Unpack from Python 3.11 on
    from typing_extensions import Unpack

FIGURE10_SEED = 10
"""Seed of the one colony start (R poses from ``colony_starts``) of every population's
Figure 10 tracks."""
DEFAULT_WORLD = WorldSettings()
DEFAULT_GA = GASettings()
DEFAULT_COLONY = ColonySettings()


def _evaluate_colony(genomes: np.ndarray, starts: np.ndarray, **kw: Any) -> Any:
    from evolve.evaluation import evaluate_colony  # numba: loaded on first use

    return evaluate_colony(genomes, starts, **kw)


def check_capacity(world: WorldSettings, colony: ColonySettings) -> None:
    """Refuse (``StageError`` naming ``--robots``) more robots than the coverage start region
    holds reliably at the start separation (``evolve.starts.colony_capacity``)."""
    fit = colony_capacity(world, colony)
    if fit < colony.robots:
        raise StageError(
            f"--robots {colony.robots}: cannot place robot {fit + 1} of {colony.robots} reliably "
            f"at least {colony.start_separation:g} units from the others in the start region x "
            f"{world.coverage_start_x}, y {world.coverage_start_y}: robots placed one at a time "
            f"at random jam there; at most {fit} robots fit every one of "
            f"{CAPACITY_REHEARSALS} rehearsed colony starts, so give --robots {fit} or fewer"
        )


def colony_stage_fitness(
    ev: Any, starts: np.ndarray, world: WorldSettings, *, colony: ColonySettings
) -> np.ndarray:
    """Run fitness (P, S) of the colony stage: ``colony.fitness`` of each colony run
    (``evolve.evaluation.colony_run_fitness``, robots' step limit ``world.coverage_steps``);
    ``"squares"`` is the colony squares as float64, as ``coverage_run_fitness``."""
    from evolve.evaluation import colony_run_fitness  # numba: loaded on first use

    return colony_run_fitness(ev, colony, world.coverage_steps)


def colony_stage(
    world: WorldSettings, colony: ColonySettings, navigation: np.ndarray, envelope: Envelope = NONE,
    coverage: np.ndarray | None = None, partners: np.ndarray | None = None,
    first: np.ndarray | None = None, robot: int | None = None,
) -> Stage:  # fmt: skip
    """The colony's ``Stage``: coverage mode, colony starts, ``colony.fitness`` as run fitness
    (default the colony squares), in ``envelope``. It evolves coverage sections under the
    fixed ``navigation`` section, or (``colony.sections = "navigation"``) navigation sections
    starting as ``navigation``, population k's under the fixed coverage section
    ``coverage[k]`` ((K, 8, 30) bits), or (``"beside"``) the coverage section of robot
    ``robot`` (None: the last, R − 1) of a colony whose other robots carry fixed coverage
    sections ``partners`` ((8, 30) bits, every other robot's; or (R − 1, 8, 30), theirs in
    robot order), every individual of generation 0 carrying ``first`` ((8, 30) bits; None:
    random)."""
    nav = _check_section(navigation)
    check_capacity(world, colony)
    learn_navigation = colony.sections == "navigation"
    if learn_navigation != (coverage is not None):
        raise StageError(
            "coverage sections are given exactly when the colony stage learns navigation "
            "(ColonySettings.sections 'navigation', --coverage-from)"
        )
    if (colony.sections == "beside") != (partners is not None):
        raise StageError(
            "a partner's coverage section is given exactly when the colony stage learns one "
            "robot's section beside partners (ColonySettings.sections 'beside', --partners)"
        )
    if coverage is not None:
        coverage = np.asarray(coverage)
        bits = np.isin(coverage, (0, 1)).all()
        if coverage.ndim != 3 or coverage.shape[1:] != nav.shape or not bits:
            raise StageError(
                f"coverage sections must be (populations, 8, 30) bits, got {coverage.shape}"
            )
        coverage = np.ascontiguousarray(coverage, dtype=np.uint8)
    stage = Stage(
        "colony",
        "coverage",
        world.coverage_steps,
        functools.partial(colony_starts, colony=colony),
        functools.partial(colony_stage_fitness, colony=colony),
        None if learn_navigation else nav,
        evaluate=functools.partial(_evaluate_colony, colony=colony),
        extra_settings=(colony,),
        envelope=envelope,
        coverage=coverage,
        initial=nav if learn_navigation else None,
    )
    if first is not None and partners is None:
        raise StageError(
            "a first section is given only to the colony stage that learns "
            "one robot's beside partners (ColonySettings.sections 'beside', --first)"
        )
    if robot is not None and partners is None:
        raise StageError("a learned robot is named only for the colony stage that learns one "
                         "robot's section beside partners (ColonySettings.sections 'beside', "
                         "--beside-robot)")  # fmt: skip
    if partners is None:
        return stage
    from evolve.coevolution import role_stage

    team, role = beside_team(partners, colony.robots, robot)
    return role_stage(started_from(stage, first), team, role)


def beside_team(
    partners: np.ndarray, robots: int, robot: int | None = None
) -> tuple[np.ndarray, int]:
    """((R, 8, 30) sections, the learned robot's index) of a ``"beside"`` colony stage:
    ``partners`` is the (8, 30) section every robot but the learned one carries, or (R − 1,
    8, 30) theirs in robot order; ``robot`` (None: R − 1) the learned robot, whose row holds
    a placeholder (the individual replaces it). ``StageError`` naming what does not fit."""
    role = robots - 1 if robot is None else robot
    if not (isinstance(role, numbers.Integral) and not isinstance(role, bool)
            and 0 <= role < robots):  # fmt: skip
        raise StageError(f"the learned robot must be one of 0 … {robots - 1} (a colony of "
                         f"{robots}), got {robot!r}")  # fmt: skip
    arr = np.asarray(partners)
    if arr.ndim != 3:
        one = _check_section(arr, "partners'")
        return np.broadcast_to(one, (robots, *one.shape)), int(role)
    if len(arr) != robots - 1:
        raise StageError(f"{len(arr)} partners' sections for a colony of {robots}: give one "
                         f"for each of the other {robots - 1} robots, or one for all")  # fmt: skip
    others = np.stack([_check_section(a, f"partner {i}'s") for i, a in enumerate(arr)])
    return np.insert(others, role, others[0], axis=0), int(role)


def coverage_section(
    path: Path, navigation: np.ndarray | None = None, option: str = "--partners"
) -> np.ndarray:
    """(8, 30): the coverage section (genes 0–7) of the 16-gene chromosome at ``path``: the
    partners' of a ``"beside"`` colony stage, or (``option`` ``--first``) its first
    generation's. ``StageError`` naming the file when it is not a whole chromosome or, with
    ``navigation`` (the partners': every robot runs the stage's), carries another."""
    bits = read_chromosome(path)
    if bits.shape[0] != 2 * SECTION_GENES:
        raise StageError(f"{path}: {bits.shape[0]} genes, but {option} takes the coverage "
                         "section of a 16-gene chromosome")  # fmt: skip
    if navigation is not None and not np.array_equal(bits[SECTION_GENES:], navigation):
        raise StageError(f"{path}: its navigation section (genes 8–15) differs from the "
                         "stage's --navigation; every robot carries the stage's, so give "
                         "that one")  # fmt: skip
    return bits[:SECTION_GENES].astype(np.uint8)


def finalists_coverage(run: Path, populations: int) -> np.ndarray:
    """(K, 8, 30): the coverage sections (genes 0–7) of a finished colony run's finalists
    ``run/colony/best_pop{k}.txt``, k < ``populations``: where ``--coverage-from`` takes the
    fixed sections of a colony stage that learns navigation. ``StageError`` naming a missing
    file or one that is not a whole chromosome."""
    out = []
    for k in range(populations):
        path = Path(run) / "colony" / f"best_pop{k}.txt"
        if not path.exists():
            raise StageError(
                f"{path}: no such file; --coverage-from needs a finished shared colony run "
                f"('servobot evolve colony') of {populations} populations"
            )
        bits = read_chromosome(path)
        if bits.shape[0] != 2 * SECTION_GENES:
            raise StageError(f"{path}: {bits.shape[0]} genes, but --coverage-from takes the "
                             "coverage section of a 16-gene colony finalist")  # fmt: skip
        out.append(bits[:SECTION_GENES])
    return np.stack(out).astype(np.uint8)


def figure10_starts(world: WorldSettings, colony: ColonySettings) -> np.ndarray:
    """(R, 3): the colony start of the Figure 10 tracks, drawn with ``FIGURE10_SEED``."""
    return colony_starts(np.random.default_rng(FIGURE10_SEED), 1, world, colony)[0]


def run_colony_stage(
    out: Path,
    *,
    navigation: np.ndarray,
    table: GaitTable,
    ga: GASettings = DEFAULT_GA,
    world: WorldSettings = DEFAULT_WORLD,
    colony: ColonySettings = DEFAULT_COLONY,
    team_from: np.ndarray | None = None,
    coverage: np.ndarray | None = None,
    partners: np.ndarray | None = None,
    first: np.ndarray | None = None,
    robot: int | None = None,
    **options: Unpack[StageOptions],
) -> dict[str, Any]:
    """Colony stage (SPEC §7) into ``out/colony``; returns the summary (also
    ``summary.json``). ``executor``: where the populations evolve, and ``resume``/``force``
    (the run folder's lock and ownership), as in ``evolve.stages.run_navigation``.

    Figure 9: the best section of each saved generation of each population, as a colony
    with the fixed ``navigation`` section, from the same ``ga.test_starts`` fresh colony
    starts; colony inner squares / 64 as a percentage. Summary keys as the coverage stage's
    (``figure9_*``, ``final_mean_inner_percent``, ``final_inner_percent``, ``figure10``) plus
    ``robots``, ``final_test`` (per population: colony and per-robot coverage, docks, station
    waits, blocked moves, ends, and the same best measured alone) and
    ``one_robot_final_mean_inner_percent``.

    ``envelope`` (SPEC §9): the populations evolve in it; Figure 9 is also measured in it on
    the same colony test starts, as the coverage stage's (``envelope_figure9_*``,
    ``envelope_final_*``, ``envelope``); ``final_test`` and Figure 10 stay in the world of §3.

    ``team_from`` (``colony.sections = "team"`` only): (T, P, 8, 30) populations, team t's
    every population starting as a copy of row t (index 0 its partners; e.g. a shared run's
    final populations, ``evolve.coevolution.shared_populations``), recorded in
    ``settings.json`` by its SHA-256; None: random populations.

    ``coverage`` (``colony.sections = "navigation"`` only): (``ga.populations``, 8, 30) fixed
    coverage sections, population k's robots carrying row k (e.g. a shared run's finalists,
    ``finalists_coverage``); every individual of generation 0 is the ``navigation`` section,
    and the stage evolves it in the colony. Its saved bests and finalists are navigation
    sections behind those coverage sections; Figure 9's generation 0 is the colony the
    coverage sections came from (the same colony test starts at the same seed).

    ``partners`` (``colony.sections = "beside"`` only): the (8, 30) coverage section robots
    0 … R − 2 carry (e.g. ``coverage_section`` of a colony finalist), recorded in
    ``settings.json`` (``partner_section``); the stage evolves robot R − 1's. Or, with
    ``robot`` the robot it evolves (None: R − 1), the other robots' (R − 1, 8, 30) sections in
    robot order (recorded as ``partner_sections`` and ``beside_robot``). Figure 9, the final
    test and Figure 10 run the whole colony; ``best_pop{k}.txt`` is the learned robot's
    chromosome, and the final test's lone robot is it. ``first``: the (8, 30) section every
    individual of generation 0 carries (e.g. the team's current section of that robot;
    recorded as ``initial_section``); None: random.
    """
    folder = Path(out) / "colony"
    run = StageRun(**options)
    if coverage is not None and len(coverage) != ga.populations:
        raise StageError(f"{len(coverage)} coverage sections for {ga.populations} populations")
    stage = colony_stage(world, colony, navigation, run.envelope, coverage, partners, first, robot)
    extra = None
    if partners is not None:
        team, role = stage.evaluate.keywords["partners"], stage.evaluate.keywords["role"]
        if np.ndim(partners) == 2 and role == colony.robots - 1:
            extra = {"partner_section": _gene_text(partners)}
        else:
            others = [_gene_text(s[:SECTION_GENES]) for r, s in enumerate(team) if r != role]
            extra = {"partner_sections": others, "beside_robot": role}
    if team_from is not None:
        from evolve.coevolution import check_team_from

        team_from, extra = check_team_from(team_from, colony, ga)
    with _stage_folder(stage, folder, table, ga, world, run.resume, run.force, extra) as doc:
        return _colony(stage, folder, doc, table, ga, world, colony, run, team_from)


def _colony(
    stage: Stage, folder: Path, doc: dict[str, Any], table: GaitTable, ga: GASettings,
    world: WorldSettings, colony: ColonySettings, run: StageRun,
    team_from: np.ndarray | None = None,
) -> dict[str, Any]:  # fmt: skip
    from evolve import figures

    t0 = time.perf_counter()
    gens = save_generations(ga)
    beside = colony.sections == "beside"  # finals are teams; the learned robot's is the finalist
    role = stage.evaluate.keywords["role"] if beside else 0
    if colony.sections == "team":
        finals, fig9, test_starts = _evolve_teams(stage, folder, doc, table, ga, world, colony,
                                                  run, team_from)  # fmt: skip
    else:
        results, test_starts = _run_populations(
            stage, folder, doc, table=table, ga=ga, world=world, run=run
        )
        fig9 = figure9_both(folder, stage, table, world, gens, ga.populations, test_starts,
                            ga.seed)  # fmt: skip
        finals = np.stack([stage.for_population(k).genomes(res.best[None])[0]
                           for k, res in enumerate(results)])  # fmt: skip
        if beside:
            finals = beside_teams(stage, finals)
    inner = fig9[""][0]
    _write_figure9(folder, gens, fig9, stage.envelope)
    r = colony.robots
    figures.figure9(
        folder / "figure9.png", gens, inner,
        title=f"Figure 9, a colony of {r}: colony inner squares of each population's best",
    )  # fmt: skip
    final = final_test(finals, test_starts, table, world, colony, lone_robot=role)
    fig10 = []
    start = figure10_starts(world, colony)
    for k, full in enumerate(finals):
        _write_finalist(folder, k, full[role] if beside else full, ga, table, world, inner[k, -1],
                        colony.sections, role)  # fmt: skip
        fig = figures.colony_figure10(
            folder / f"figure10_pop{k}.png", full, table=table, world=world, colony=colony,
            starts=start, title=f"population {k}",
        )  # fmt: skip
        fig10.append({"population": k, **fig})
    summary = {
        "stage": "colony",
        "robots": r,
        "generations": list(gens),
        **figure9_summary(fig9[""]),
        "one_robot_final_mean_inner_percent": float(
            np.mean([p["one_robot_inner_percent"] for p in final])
        ),
        "final_test": final,
        "figure10_starts": start.tolist(),
        "figure10": fig10,
        "test_starts": len(test_starts),
    }
    return write_summary(folder, summary, t0, run, doc, envelope_figure9(stage, fig9))


def _evolve_teams(
    stage: Stage, folder: Path, doc: dict[str, Any], table: GaitTable, ga: GASettings,
    world: WorldSettings, colony: ColonySettings, run: StageRun, team_from: np.ndarray | None,
) -> tuple[np.ndarray, dict[str, tuple[np.ndarray, np.ndarray]], np.ndarray]:  # fmt: skip
    """``ga.populations`` teams of ``colony.robots`` coevolved populations
    (``evolve.coevolution``; from ``team_from`` if given); returns (final teams (T, R, 16,
    30), Figure 9 in both worlds, test starts)."""
    from evolve.coevolution import run_teams, team_figure9

    test_seq, seeds = stage_seeds(ga.seed, stage.name, ga.populations)
    threads = None if run.executor is None else _kernel_threads(run.executor)
    results = run_teams(
        stage, folder, seeds, robots=colony.robots, table=table, ga=ga, world=world,
        settings_text=json.dumps(doc, sort_keys=True), resume=run.resume,
        executor=run.executor, threads=threads, on_generation=run.on_generation,
        initial=team_from,
    )  # fmt: skip
    test_starts = stage.starts(np.random.Generator(np.random.PCG64(test_seq)), ga.test_starts,
                               world)  # fmt: skip
    gens = save_generations(ga)
    fig9 = {
        prefix: team_figure9(folder, st, table, world, gens, ga.populations, test_starts, ga.seed)
        for prefix, st in both_worlds(stage)
    }
    return np.stack([stage.genomes(res.team) for res in results]), fig9, test_starts


def beside_teams(stage: Stage, finals: np.ndarray) -> np.ndarray:
    """(K, R, 16, 30): each finalist (K, 16, 30) as the learned robot of the ``"beside"``
    stage's colony, the other robots carrying the partners' chromosomes."""
    team, role = stage.evaluate.keywords["partners"], stage.evaluate.keywords["role"]
    out = np.repeat(team[None], len(finals), axis=0)  # team: (R, 16, 30), set by role_stage
    out[:, role] = finals
    return out


def _write_finalist(
    folder: Path, k: int, full: np.ndarray, ga: GASettings, table: GaitTable,
    world: WorldSettings, inner: float, colony_sections: str, role: int = 0,
) -> None:  # fmt: skip
    """``best_pop{k}.txt``, or a team's ``best_pop{k}_robot{r}.txt`` (``full``: (16, 30) or
    (R, 16, 30)); ``colony_sections``: what the stage learned (``ColonySettings.sections``),
    ``role`` the robot a ``"beside"`` stage learned."""
    test = f"Figure 9 test {inner:.1f}% of the {world.inner_square_count} inner squares"
    if full.ndim == 2:
        learned = {
            "navigation": "coverage section (fixed) + navigation (learned as a colony)",
            "beside": f"robot {role}'s coverage section (learned beside the partners of "
            "settings.json) + navigation (fixed)",
        }.get(colony_sections, "coverage section (learned as a colony) + navigation (fixed)")
        extra = f"16 genes: {learned}; {test}"
        write_chromosome(
            folder / f"best_pop{k}.txt", full, _provenance("colony", k, ga, table, extra)
        )
        return
    for r, bits in enumerate(full):
        extra = (
            f"16 genes: robot {r}'s coverage section of a team of {len(full)} (coevolved) + "
            f"navigation (fixed); the team's {test}"
        )
        write_chromosome(folder / f"best_pop{k}_robot{r}.txt", bits,
                         _provenance("colony", k, ga, table, extra))  # fmt: skip


def final_test(
    genomes: np.ndarray,
    test_starts: np.ndarray,
    table: GaitTable,
    world: WorldSettings,
    colony: ColonySettings,
    lone_robot: int = 0,
) -> list[dict[str, Any]]:
    """Each population's final best (rows of ``genomes``, 16 genes; or teams (K, R, 16, 30),
    robot r carrying row r) as a colony from the colony ``test_starts`` (T, R, 3), and alone
    (a team's robot ``lone_robot``) from each start's robot-0 pose (T, 3).

    Per population: colony and per-robot inner coverage (% of the inner squares), squares,
    docks per robot, station waits and blocked moves per run, colony steps, how the robots
    ended (fractions), the robots live at the end per run (of R; ``LIVE_ENDS``) and the mean
    run fitness under ``colony.fitness``, and the lone robot's inner coverage and squares.
    """
    from evolve.evaluation import colony_run_fitness, evaluate, evaluate_colony

    kw = dict(table=table.values, mode="coverage", start_power=world.start_power_v,
              settings=world)  # fmt: skip
    if genomes.ndim == 4:
        evs = [evaluate_colony(team[:1], test_starts, colony=colony, partners=team, role=0, **kw)
               for team in genomes]  # fmt: skip
        ev = type(evs[0])(**{f.name: np.concatenate([getattr(e, f.name) for e in evs])
                             for f in dataclasses.fields(evs[0])})  # fmt: skip
        genomes = genomes[:, lone_robot]
    else:
        ev = evaluate_colony(genomes, test_starts, colony=colony, **kw)
    lone = evaluate(genomes, np.ascontiguousarray(test_starts[:, 0]), **kw)
    pct = 100.0 / world.inner_square_count
    live = ev.live.sum(axis=2)
    fitness = colony_run_fitness(ev, colony, world.coverage_steps)
    out = []
    for k in range(genomes.shape[0]):
        ends = np.bincount(ev.end[k].ravel(), minlength=len(END_NAMES)) / ev.end[k].size
        out.append(
            {
                "population": k,
                "colony_inner_percent": float(pct * ev.inner_squares[k].mean()),
                "robot_inner_percent": float(pct * ev.robot_inner_squares[k].mean()),
                "colony_squares": float(ev.squares[k].mean()),
                "robot_squares": float(ev.robot_squares[k].mean()),
                "docks_per_robot": float(ev.docks[k].mean()),
                "station_waits_per_run": float(ev.station_waits[k].sum(axis=1).mean()),
                "collisions_per_run": float(ev.collisions[k].sum(axis=1).mean()),
                "colony_steps": float(ev.colony_steps[k].mean()),
                "ends": {name: float(f) for name, f in zip(END_NAMES, ends, strict=True)},
                "live_at_end_per_run": float(live[k].mean()),
                "run_fitness": float(fitness[k].mean()),
                "one_robot_inner_percent": float(pct * lone.inner_squares[k].mean()),
                "one_robot_squares": float(lone.squares[k].mean()),
                "one_robot_docks": float(lone.docks[k].mean()),
            }
        )
    return out


__all__ = [
    "FIGURE10_SEED",
    "check_capacity",
    "colony_stage",
    "colony_stage_fitness",
    "figure10_starts",
    "final_test",
    "finalists_coverage",
    "coverage_section",
    "run_colony_stage",
]
