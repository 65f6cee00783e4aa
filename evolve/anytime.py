"""Punctuated anytime learning: coverage learning on the table world, corrected by physics.

Anytime learning (Parker) keeps a fast model of the robot for the genetic algorithm and, every
so often, tests the best controllers on the real robot, whose results correct the learning.
Two published variants, both here, with MuJoCo physics as the real robot:

- ``bias``: fitness biasing (G. Parker & J. Mills, "Adaptive hexapod gait control using
  anytime learning with fitness biasing"). The physics/table fitness ratios of
  the tested individuals bias the model's fitness until the next punctuation (``bias_rule``,
  ``Bias``).
- ``model``: co-evolution of model parameters (G. Parker, punctuated anytime learning),
  here fitted rather than evolved. The gait table is corrected by the per-cycle residuals
  physics measured along the tested runs (``corrected_table``).
- ``transfer``: the transferability approach (S. Koos, J.-B. Mouret & S. Doncieux, "The
  transferability approach: crossing the reality gap in evolutionary robotics", 2013). Each
  tested genome's disparity, table minus physics fitness, is kept with its behaviour in the
  table world (``behaviour``: how its runs end from a fixed set of starts); every individual's
  disparity is predicted from its nearest tested behaviours (``predict_disparity``) and the GA
  selects on table fitness minus that prediction: a predicted physics fitness.
- ``none``: the control arm. The same punctuations are measured and recorded but not fed
  back; its populations are exactly ``servobot evolve coverage``'s with the same seed.

The loop, populations in lockstep (each a ``PopulationRun`` seeded as coverage's)::

    for g in 0..G:
        table_g = base table (model: base + pooled residuals of the punctuations before g)
        each population: f = evaluate on table_g                  # SPEC §5, 10 starts
        f' = f · bias (bias: from the last punctuation, else 1)
        f' = max(0, f − d̂) (transfer: d̂ the mean d of the k nearest archived behaviours)
        if g is a punctuation (K, 2K, … ≤ G):
            the T best distinct genomes of each population by f' run in physics from M starts
            drawn for g, and in the table world on table_g from the same starts
            bias:  b = physics / table per tested genome; the population's mean b for the rest
            transfer: d = table − physics and the behaviour of each tested genome archived
            model: residuals pooled, table corrected, generation g re-evaluated on it
        each population: commit(f')                                # elite and roulette on f'

Physics stays outside this module (``evolve`` imports no MuJoCo): the caller passes a
``PhysicsTester`` (``servobot.anytime.run``). Each punctuation is a file written once,
``punctuations/gen{g:04d}.json``; what a generation needs (biases, the corrected table) is a
function of these records, so a resumed run, its populations back at their checkpoints,
replays to the same numbers bit for bit without running physics again.

A stage evolved in an envelope of variation (SPEC §9, ``Stage.envelope``) evaluates its
generations in it (key (seed, g)), a ``model`` re-evaluation of generation g too, and a
punctuation's table-world runs with the key ``key_of_test(seed, "punctuation", g)``: the
bias compares physics with the fitness the GA sees.
"""

from __future__ import annotations

import dataclasses
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from evolve.codec import format_chromosome, parse_chromosome
from evolve.envelope import NONE, key_of_test
from evolve.interpreter import END_KILL_ZONE, END_POWER_EMPTY
from evolve.population import (
    Generation,
    OnGeneration,
    PopulationResult,
    PopulationRun,
    Stage,
    StageError,
    evaluate_sections,
    stage_rng,
    stage_seeds,
)
from evolve.settings import GASettings, WorldSettings
from evolve.starts import coverage_starts
from evolve.table import COLUMNS, N_GAITS, GaitTable, table_to_json, validate_table
from infra.bounds import is_finite_number
from infra.io import atomic_write_json, read_json

METHODS = ("none", "bias", "model", "transfer")
"""What a punctuation feeds back: nothing (control), a fitness bias, a corrected table, a
disparity predicted from behaviour."""
RECORDS = "punctuations"
"""Folder of the punctuation records, ``gen{g:04d}.json``."""
TABLES = "tables"
"""Folder of the corrected gait tables of method ``model``, ``gen{g:04d}.json``."""


class AnytimeError(StageError):
    """Anytime learning cannot run or resume (bad settings, an inconsistent record)."""


@dataclass(frozen=True)
class AnytimeSettings:
    """Punctuations of anytime learning: when, whom and how physics tests, what it corrects."""

    method: str = "bias"
    """``none`` (measure, feed nothing back: the table-only control), ``bias`` (fitness
    biasing), ``model`` (corrected gait table) or ``transfer`` (predicted disparity)
    [chosen]."""
    every: int = 32
    """K: a punctuation at generations K, 2K, … up to G (none at generation 0, whose random
    controllers would spend physics on nothing) [chosen]."""
    top: int = 2
    """T: distinct genomes tested per population, the best by the fitness in force. ``bias``
    needs T ≥ 2: with one tested genome its ratio is also the population's mean, every
    individual is scaled alike, and roulette on fitness^1.5 is scale-invariant [chosen]."""
    physics_starts: int = 2
    """M: coverage start poses of a punctuation, drawn for that generation and shared by every
    tested genome (both worlds) [chosen]."""
    physics_steps: int = 600
    """Steps of a punctuation's runs and of the final test, both worlds (SPEC §5: 600; tests
    use a few)."""
    final_starts: int = 20
    """Fresh coverage starts on which each population's final best runs in both worlds."""
    min_samples: int = 20
    """``model``: a gait's row is corrected once this many physics cycles of it were counted
    (pooled over punctuations); until then it keeps its base row [chosen]."""
    station_margin_cm: float = 30.0
    """``model``: a cycle that begins with the robot's centre closer than this to the station
    block is not counted: it measures the block (the table world has none), not the gait
    (probe reach 23.7 cm) [chosen]."""
    neighbours: int = 3
    """``transfer``: k, the archived behaviours whose mean disparity an individual is
    predicted to have [chosen]."""
    descriptor_starts: int = 4
    """``transfer``: the fixed coverage starts (drawn once per run) from which a behaviour is
    described, ``physics_steps`` steps each in the exact table world [chosen]."""

    def __post_init__(self) -> None:
        if self.method not in METHODS:
            raise AnytimeError(f"method must be one of {', '.join(METHODS)}, got {self.method!r}")
        for name in ("every", "top", "physics_starts", "physics_steps", "final_starts",
                     "neighbours", "descriptor_starts"):  # fmt: skip
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, int) or value < 1:
                raise AnytimeError(f"{name} must be an integer ≥ 1, got {value!r}")
        if isinstance(self.min_samples, bool) or not isinstance(self.min_samples, int):
            raise AnytimeError(f"min_samples must be an integer ≥ 1, got {self.min_samples!r}")
        if self.min_samples < 1:
            raise AnytimeError(f"min_samples must be an integer ≥ 1, got {self.min_samples!r}")
        if not self.station_margin_cm >= 0.0:
            raise AnytimeError(f"station_margin_cm must be ≥ 0, got {self.station_margin_cm}")


@dataclass(frozen=True)
class PhysicsRun:
    """What physics measured along one run of a tested genome."""

    squares: int | None
    """Squares reached (of 100; the run fitness, SPEC §5); None when physics failed."""
    inner_squares: int | None
    """Inner squares reached (of 64); None when physics failed."""
    error: str | None = None
    """Why physics failed (``PhysicsError: ...``), else None."""
    gaits: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=np.int64))
    """(n,) gait of each cycle that counts for the model."""
    residuals: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))
    """(n, 3) that cycle's move (F, T cm, dH deg) minus the base table row of its gait."""
    cycles: int = 0
    """Gait cycles the run walked, counted for the model or not."""
    end: str | None = None
    """Why the run ended (``evolve.interpreter.END_NAMES``); None when physics failed."""


PhysicsTester = Callable[[np.ndarray, np.ndarray, int, np.ndarray], list[PhysicsRun]]
"""``test_in_physics(genomes (C, 16, 30), starts (M, 3), seed, base table (16, 3))`` → C·M
runs, genome-major (run c·M + m: genome c from start m, servo noise seeded by (seed, m)), of
``AnytimeSettings.physics_steps`` steps each; residuals against the base table."""
OnPunctuation = Callable[[dict[str, Any]], None]
"""``on_punctuation(record)`` after each punctuation (measured now or replayed from its file)."""


# --------------------------------------------------------------------------- the rules


def punctuation_generations(generations: int, every: int) -> tuple[int, ...]:
    """The generations physics tests: K, 2K, … ≤ G."""
    return tuple(range(every, generations + 1, every))


def bias_rule(table_fitness: Any, physics_fitness: Any) -> tuple[np.ndarray, float]:
    """Fitness biasing: (b per tested genome, the population's mean b).

    b = physics fitness / table fitness, both the mean squares over the same M starts. A
    genome without a ratio (table fitness 0, or no physics run that finished: NaN) gets no b
    of its own (NaN here) and is biased by the mean. The mean is over the defined b; 1 when
    none is defined."""
    t = np.asarray(table_fitness, dtype=np.float64)
    p = np.asarray(physics_fitness, dtype=np.float64)
    ok = (t > 0.0) & np.isfinite(p)
    b = np.full(t.shape, np.nan)
    b[ok] = p[ok] / t[ok]
    return b, float(b[ok].mean()) if ok.any() else 1.0


def section_keys(sections: np.ndarray) -> list[bytes]:
    """One key per section (its packed bits): equal keys, equal genomes."""
    n = sections.shape[0]
    return [row.tobytes() for row in np.packbits(sections.reshape(n, -1), axis=1)]


@dataclass(frozen=True)
class Bias:
    """A population's fitness bias from its last punctuation: each tested genome keeps its own
    b (matched by its bits, wherever and however often it appears) while it survives; every
    other individual gets the mean."""

    own: dict[bytes, float] = field(default_factory=dict)
    mean: float = 1.0

    def factors(self, sections: np.ndarray) -> np.ndarray:
        """(P,) bias of each section."""
        return np.array([self.own.get(k, self.mean) for k in section_keys(sections)])


def corrected_table(
    base: np.ndarray, residual_sum: np.ndarray, count: np.ndarray, min_samples: int
) -> np.ndarray:
    """The model's correction: each gait's row = base row + its mean residual (physics move −
    base row, pooled over every counted cycle so far) once ``count`` ≥ ``min_samples``; a gait
    observed less keeps its base row. Checked against the table bounds."""
    base = validate_table(base)
    n = np.asarray(count, dtype=np.float64)
    mean = np.asarray(residual_sum, dtype=np.float64) / np.maximum(n, 1.0)[:, None]
    use = n >= max(int(min_samples), 1)
    return validate_table(np.where(use[:, None], base + mean, base), name="corrected gait table")


def table_error(
    gaits: np.ndarray, residuals: np.ndarray, base: np.ndarray, in_use: np.ndarray
) -> dict[str, float]:
    """Mean |physics move − row of the table in use| per column over the counted cycles (the
    residuals are against ``base``), and the number of cycles."""
    r = np.asarray(residuals, dtype=np.float64).reshape(-1, 3)
    gaits = np.asarray(gaits, dtype=np.int64)
    err = np.abs(r - (in_use - base)[gaits]).mean(axis=0) if len(r) else np.full(3, np.nan)
    return {c: _num(v) for c, v in zip(COLUMNS, err, strict=True)} | {"cycles": len(r)}


def residual_sums(gaits: np.ndarray, residuals: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(sum of residuals (16, 3), count (16,)) per gait."""
    total = np.zeros((N_GAITS, 3))
    np.add.at(total, np.asarray(gaits, dtype=np.int64), np.asarray(residuals).reshape(-1, 3))
    return total, np.bincount(np.asarray(gaits, dtype=np.int64), minlength=N_GAITS)


def top_distinct(fitness: np.ndarray, sections: np.ndarray, n: int) -> list[int]:
    """Indices of the ``n`` best distinct genomes by ``fitness`` (ties: lower index first)."""
    keys = section_keys(sections)
    seen: set[bytes] = set()
    out: list[int] = []
    for i in np.argsort(-np.asarray(fitness), kind="stable"):
        if keys[i] not in seen:
            seen.add(keys[i])
            out.append(int(i))
            if len(out) == n:
                break
    return out


def _num(v: Any) -> float | None:
    """A float for JSON, None for NaN."""
    v = float(v)
    return v if np.isfinite(v) else None


# --------------------------------------------------------------------------- seeds, state


def final_starts(seed: int, n: int, world: WorldSettings) -> tuple[np.ndarray, int]:
    """(start poses (n, 3), servo-noise seed) of the final test, shared by every population."""
    rng = stage_rng(seed, "anytime", 0)
    return coverage_starts(rng, n, world), int(rng.integers(2**62))


def pooled_residuals(
    records: dict[int, dict[str, Any]], upto: int
) -> tuple[np.ndarray, np.ndarray]:
    """(sum (16, 3), count (16,)) of the residuals of every punctuation at generation ≤ upto,
    added in generation order."""
    total, count = np.zeros((N_GAITS, 3)), np.zeros(N_GAITS, dtype=np.int64)
    for g in sorted(records):
        if g <= upto:
            total += np.asarray(records[g]["residual_sum"], dtype=np.float64)
            count += np.asarray(records[g]["residual_count"], dtype=np.int64)
    return total, count


def model_table(
    base: GaitTable, records: dict[int, dict[str, Any]], upto: int, settings: AnytimeSettings
) -> GaitTable:
    """The table the GA uses after the punctuations at generation ≤ ``upto``: ``base`` unless
    the method is ``model``."""
    if settings.method != "model" or not any(g <= upto for g in records):
        return base
    values = corrected_table(base.values, *pooled_residuals(records, upto), settings.min_samples)
    source = f"{base.source}, corrected to gen {upto}"
    return GaitTable(values, base.std, meta=base.meta, source=source)  # σ: the base table's


def population_bias(records: dict[int, dict[str, Any]], k: int, upto: int) -> Bias:
    """Population ``k``'s bias after the punctuations at generation ≤ ``upto`` (method bias)."""
    last = [g for g in records if g <= upto]
    if not last:
        return Bias()
    rec = records[max(last)]
    own = {
        _key(t["section"]): float(t["ratio"])
        for t in rec["tested"]
        if t["population"] == k and t["ratio"] is not None
    }
    return Bias(own, float(rec["bias"][str(k)]))


BEHAVIOUR_FEATURES = ("squares", "inner", "x", "y", "kill_zone", "power_empty", "docks")
"""Per descriptor start, what ``behaviour`` describes of a run (each scaled to about 0–1)."""
DOCKS_SCALE = 10.0
"""Docks of a run that count as 1 in a behaviour (a 600-step run docks ≈ 2–7 times)."""


def behaviour(ev: Any, world: WorldSettings) -> np.ndarray:
    """(P, S · 7) behaviour descriptors of an evaluation (P individuals × S starts): per start
    the squares (of 100) and inner squares (of 64) reached, the end point (x, y / arena size),
    whether the run ended in the kill zone or with an empty store, and the docks / 10."""
    feats = np.stack(
        [
            ev.squares / MAX_SQUARES, ev.inner_squares / world.inner_square_count,
            ev.final_pose[..., 0] / world.arena_size, ev.final_pose[..., 1] / world.arena_size,
            ev.end == END_KILL_ZONE, ev.end == END_POWER_EMPTY, ev.docks / DOCKS_SCALE,
        ],
        axis=-1,
    ).astype(np.float64)  # fmt: skip
    return feats.reshape(feats.shape[0], -1)


def predict_disparity(
    archive: np.ndarray, disparity: np.ndarray, queries: np.ndarray, k: int
) -> np.ndarray:
    """(Q,) the mean disparity of each query's ``k`` nearest archived behaviours (Euclidean;
    ties to the earlier archive entry); zeros when the archive is empty."""
    if len(archive) == 0:
        return np.zeros(len(queries))
    dist = np.sqrt(((queries[:, None, :] - archive[None, :, :]) ** 2).sum(axis=-1))
    nearest = np.argsort(dist, axis=1, kind="stable")[:, :k]
    return disparity[nearest].mean(axis=1)


def transfer_archive(
    records: dict[int, dict[str, Any]], upto: int
) -> tuple[np.ndarray, np.ndarray]:
    """(behaviours (N, F), disparities (N,)) of every genome tested at a punctuation at or
    before ``upto`` whose physics finished, in generation then record order."""
    tested = [t for g in sorted(records) if g <= upto for t in records[g]["tested"]
              if t.get("disparity") is not None]  # fmt: skip
    if not tested:
        return np.zeros((0, 0)), np.zeros(0)
    return (np.array([t["descriptor"] for t in tested], dtype=np.float64),
            np.array([t["disparity"] for t in tested], dtype=np.float64))  # fmt: skip


Describe = Callable[[np.ndarray], np.ndarray]
"""``describe(sections (P, 8, 30))`` → (P, F) behaviours (method transfer)."""


def describer(stage: Stage, table: GaitTable, world: WorldSettings, settings: AnytimeSettings,
              seed: int) -> Describe:  # fmt: skip
    """The behaviour of sections in ``stage``'s exact table world (no envelope: a behaviour
    must not depend on a generation's draws) from ``settings.descriptor_starts`` fixed starts
    (key (2,) of the run's anytime draws), ``physics_steps`` steps each."""
    starts = stage.starts(stage_rng(seed, "anytime", 2), settings.descriptor_starts, world)
    exact = dataclasses.replace(stage, envelope=NONE, max_steps=settings.physics_steps)

    def describe(sections: np.ndarray) -> np.ndarray:
        _, ev, _, inverse = evaluate_sections(sections, starts, exact, table, world)
        return behaviour(ev, world)[inverse]

    return describe


def _key(text_genes: list[str]) -> bytes:
    """The key of a section recorded as text, one gene a line."""
    return section_keys(parse_chromosome("\n".join(text_genes))[None])[0]


def _genes(section: np.ndarray) -> list[str]:
    return format_chromosome(section).splitlines()


# --------------------------------------------------------------------------- punctuations


def _tested(
    runs: list[PopulationRun], fitness: dict[int, np.ndarray], top: int
) -> list[tuple[int, int, int]]:
    """(population, rank, index) of every genome a punctuation tests."""
    return [
        (r.k, rank, i)
        for r in runs
        for rank, i in enumerate(top_distinct(fitness[r.k], r.pop, top))
    ]


def _measure(
    g: int, runs: list[PopulationRun], chosen: list[tuple[int, int, int]], *, stage: Stage,
    in_use: GaitTable, base: GaitTable, ga: GASettings, world: WorldSettings,
    settings: AnytimeSettings, test_in_physics: PhysicsTester, describe: Describe,
) -> dict[str, Any]:  # fmt: skip
    """Run the chosen genomes in physics and in the table world; the punctuation's record."""
    rng = stage_rng(ga.seed, "anytime", 1, g)
    starts = stage.starts(rng, settings.physics_starts, world)
    seed = int(rng.integers(2**62))
    by_k = {r.k: r for r in runs}
    sections = np.stack([by_k[k].pop[i] for k, _, i in chosen])
    short = dataclasses.replace(stage, max_steps=settings.physics_steps)
    key = key_of_test(ga.seed, "punctuation", g)
    table_squares = evaluate_sections(sections, starts, short, in_use, world, key)[0]
    t0 = time.perf_counter()
    measured = test_in_physics(stage.genomes(sections), starts, seed, base.values)
    wall = time.perf_counter() - t0
    m = settings.physics_starts
    if len(measured) != len(chosen) * m:
        raise AnytimeError(f"physics returned {len(measured)} runs for {len(chosen) * m} jobs")
    tested = []
    for c, (k, rank, i) in enumerate(chosen):
        mine = measured[c * m : (c + 1) * m]
        ok = [run.squares for run in mine if run.squares is not None]
        tested.append({
            "population": k, "rank": rank, "index": i, "section": _genes(sections[c]),
            "table_fitness": float(table_squares[c].mean()),
            "physics_fitness": float(np.mean(ok)) if ok else None,
            "table_squares": table_squares[c].tolist(),
            "physics_squares": [run.squares for run in mine],
            "physics_inner_squares": [run.inner_squares for run in mine],
            "physics_ends": [run.end for run in mine],
            "errors": [run.error for run in mine if run.error],
        })  # fmt: skip
    means = _apply_bias_rule(tested, runs)
    if settings.method == "transfer":
        for t, d in zip(tested, describe(sections), strict=True):
            t["descriptor"] = d.tolist()
            phys = t["physics_fitness"]
            t["disparity"] = None if phys is None else t["table_fitness"] - phys
    gaits = np.concatenate([run.gaits for run in measured]).astype(np.int64)
    res = np.concatenate([run.residuals.reshape(-1, 3) for run in measured])
    total, count = residual_sums(gaits, res)
    return {
        "generation": g,
        "method": settings.method,
        "starts": starts.tolist(),
        "noise_seed": seed,
        "tested": tested,
        "bias": means if settings.method == "bias" else None,
        "table_error": table_error(gaits, res, base.values, in_use.values),
        "table_in_use": in_use.values.tolist(),
        "residual_sum": total.tolist(),
        "residual_count": count.tolist(),
        "physics_cycles": sum(run.cycles for run in measured),
        "physics_runs": len(measured),
        "physics_errors": sum(run.error is not None for run in measured),
        "physics_wall_s": wall,
    }


def _apply_bias_rule(tested: list[dict[str, Any]], runs: list[PopulationRun]) -> dict[str, float]:
    """Set each tested genome's ``ratio`` b (``bias_rule``; None where undefined); returns per
    population the mean b that its other individuals get."""
    means = {}
    for r in runs:
        mine = [t for t in tested if t["population"] == r.k]
        phys = [np.nan if t["physics_fitness"] is None else t["physics_fitness"] for t in mine]
        b, means[str(r.k)] = bias_rule([t["table_fitness"] for t in mine], phys)
        for t, v in zip(mine, b, strict=True):
            t["ratio"] = _num(v)
    return means


MAX_SQUARES = 100
"""Squares of the arena a run can reach (SPEC §5): the largest fitness of a run."""


def _is_int(v: Any, lo: int = 0, hi: int | None = None) -> bool:
    return (isinstance(v, int) and not isinstance(v, bool) and v >= lo
            and (hi is None or v < hi))  # fmt: skip


def _is_real(v: Any, lo: float = 0.0, hi: float = float("inf")) -> bool:
    return is_finite_number(v) and lo <= v <= hi


def _numbers(v: Any, shape: tuple[int, ...], ok: Callable[[Any], bool]) -> bool:
    """``v`` a nested list of ``shape`` whose every element passes ``ok``."""
    if not shape:
        return ok(v)
    return (isinstance(v, list) and len(v) == shape[0]
            and all(_numbers(x, shape[1:], ok) for x in v))  # fmt: skip


def check_record(
    rec: Any, path: Path, *, generations: tuple[int, ...], ga: GASettings,
    settings: AnytimeSettings,
) -> dict[str, Any]:  # fmt: skip
    """``rec`` if it is a punctuation record this run could have written at ``path``, else
    ``AnytimeError`` naming the file and the first field that is not: every field a resumed
    run replays (generation, method, the tested genomes and their ratios, the biases, the
    residuals) is of its type and in its range, so that a replay computes nothing absurd."""

    def bad(name: str, why: str) -> AnytimeError:
        return AnytimeError(
            f"{path}: not a punctuation record of this run (edited or damaged?): field {name}: "
            f"{why}; delete it and the later records to measure them again, or rerun with --force"
        )

    if not isinstance(rec, dict):
        raise bad("(the record)", f"a JSON object, got a {type(rec).__name__}")
    missing = [k for k in RECORD_KEYS if k not in rec]
    if missing:
        raise bad(missing[0], "missing")
    g = rec["generation"]
    if not _is_int(g, 1) or g not in generations:
        raise bad("generation", f"one of this run's punctuations {list(generations)}, got {g!r}")
    if path.name != f"gen{g:04d}.json":
        raise bad("generation", f"{g} belongs in gen{g:04d}.json")
    if rec["method"] != settings.method:
        raise bad("method", f"this run's method {settings.method!r}, got {rec['method']!r}")
    m, p, top = settings.physics_starts, ga.populations, settings.top
    if not _numbers(rec["starts"], (m, 3), lambda v: _is_real(v, -1e6, 1e6)):
        raise bad("starts", f"{m} start poses of three finite numbers")
    if not _is_int(rec["noise_seed"]):
        raise bad("noise_seed", "an integer ≥ 0")
    tested = rec["tested"]
    if not isinstance(tested, list) or not 0 < len(tested) <= p * top:
        raise bad("tested", f"a list of 1 to {p * top} tested genomes ({p} populations × top "
                  f"{top})")  # fmt: skip
    seen = set()
    for j, t in enumerate(tested):
        name = f"tested[{j}]"
        if not isinstance(t, dict):
            raise bad(name, "an object")
        for key in ("population", "rank", "index", "section", "table_fitness",
                    "physics_fitness", "ratio"):  # fmt: skip
            if key not in t:
                raise bad(f"{name}.{key}", "missing")
        checks = (
            ("population", _is_int(t["population"], 0, p), f"a population 0–{p - 1} of this run"),
            ("rank", _is_int(t["rank"], 0, top), f"a rank 0–{top - 1} (top {top})"),
            ("index", _is_int(t["index"], 0, ga.population_size),
             f"an individual 0–{ga.population_size - 1} of a population"),
            ("table_fitness", _is_real(t["table_fitness"], 0.0, MAX_SQUARES),
             f"a finite number of squares 0–{MAX_SQUARES}"),
            ("physics_fitness", t["physics_fitness"] is None
             or _is_real(t["physics_fitness"], 0.0, MAX_SQUARES),
             f"null or a finite number of squares 0–{MAX_SQUARES}"),
            ("ratio", t["ratio"] is None or _is_real(t["ratio"], 0.0, MAX_SQUARES * m),
             f"null or a finite ratio 0–{MAX_SQUARES * m}"),
        )  # fmt: skip
        for key, ok, want in checks:
            if not ok:
                raise bad(f"{name}.{key}", f"{want}, got {t[key]!r}")
        if (t["population"], t["rank"]) in seen:
            raise bad(f"{name}", f"population {t['population']} rank {t['rank']} twice")
        seen.add((t["population"], t["rank"]))
        section = t["section"]
        try:
            if not (isinstance(section, list) and all(isinstance(x, str) for x in section)):
                raise ValueError("a list of gene texts")
            if parse_chromosome("\n".join(section)).shape[0] != len(section) or len(section) != 8:
                raise ValueError("8 genes")
        except ValueError as exc:
            raise bad(f"{name}.section", f"a coverage section of 8 genes ({exc})") from None
    if settings.method == "transfer":
        width = len(BEHAVIOUR_FEATURES) * settings.descriptor_starts
        for j, t in enumerate(tested):
            if not _numbers(t.get("descriptor"), (width,), lambda v: _is_real(v, 0.0, 1e6)):
                raise bad(f"tested[{j}].descriptor", f"{width} finite numbers ≥ 0 (a behaviour)")
            d = t.get("disparity", "missing")
            if not (d is None or _is_real(d, -MAX_SQUARES, MAX_SQUARES)):
                raise bad(f"tested[{j}].disparity", f"null or a finite number of squares "
                          f"−{MAX_SQUARES}–{MAX_SQUARES}, got {d!r}")  # fmt: skip
    bias = rec["bias"]
    if settings.method == "bias":
        want = [str(k) for k in range(p)]
        if not isinstance(bias, dict) or sorted(bias) != sorted(want):
            raise bad("bias", f"an object with a bias for each population {', '.join(want)}")
        for k in want:
            if not _is_real(bias[k], 0.0, MAX_SQUARES * m):
                raise bad(f"bias.{k}", f"a finite bias 0–{MAX_SQUARES * m}, got {bias[k]!r}")
    elif bias is not None:
        raise bad("bias", f"null for method {settings.method}, got {bias!r}")
    if not isinstance(rec["table_error"], dict):
        raise bad("table_error", "an object")
    if not _numbers(rec["residual_sum"], (N_GAITS, 3), lambda v: _is_real(v, -1e12, 1e12)):
        raise bad("residual_sum", f"{N_GAITS} rows of three finite numbers")
    if not _numbers(rec["residual_count"], (N_GAITS,), lambda v: _is_int(v, 0, 10**12)):
        raise bad("residual_count", f"{N_GAITS} integers ≥ 0")
    for key in ("physics_cycles", "physics_runs", "physics_errors"):
        if not _is_int(rec[key], 0, 10**12):
            raise bad(key, f"an integer ≥ 0, got {rec[key]!r}")
    if not _is_real(rec["physics_wall_s"]):
        wall = rec["physics_wall_s"]
        raise bad("physics_wall_s", f"a finite number of seconds ≥ 0, got {wall!r}")
    return rec


RECORD_KEYS = (
    "generation", "method", "starts", "noise_seed", "tested", "bias", "table_error",
    "residual_sum", "residual_count", "physics_cycles", "physics_runs", "physics_errors",
    "physics_wall_s",
)  # fmt: skip
"""The fields of a punctuation record that a resumed run replays or reports."""


def load_records(
    folder: Path, generations: tuple[int, ...], ga: GASettings, settings: AnytimeSettings,
    base: GaitTable | None = None,
) -> dict[int, dict[str, Any]]:  # fmt: skip
    """The punctuation records in ``folder/punctuations`` (a resumed run reuses them), each
    checked (``check_record``); method model: the table each one corrects to (from ``base``)
    must be within the table bounds. ``AnytimeError`` names the file and field that fail."""
    records = {}
    for path in sorted((folder / RECORDS).glob("gen*.json")):
        rec = read_json(path, what="punctuation record", error=AnytimeError)
        check_record(rec, path, generations=generations, ga=ga, settings=settings)
        g = rec["generation"]
        records[g] = rec
        if base is not None and settings.method == "model":
            try:
                model_table(base, records, g, settings)
            except ValueError as exc:
                raise AnytimeError(
                    f"{path}: field residual_sum: the table it corrects to is not physical "
                    f"({exc}); delete it and the later records, or rerun with --force"
                ) from None
    return records


def _check_replay(
    rec: dict[str, Any], chosen: list[tuple[int, int, int]], runs: list[PopulationRun], path: Path
) -> None:
    """A resumed population must choose the genomes its record tested."""
    by_k = {r.k: r for r in runs}
    want = {(t["population"], t["rank"]): (t["index"], t["section"]) for t in rec["tested"]}
    for k, rank, i in chosen:
        if want.get((k, rank)) != (i, _genes(by_k[k].pop[i])):
            raise AnytimeError(
                f"{path}: population {k} does not replay to the genomes this record tested; "
                "the run folder is inconsistent: rerun with --force"
            )


# --------------------------------------------------------------------------- the loop


@dataclass
class AnytimeResult:
    """Evolved populations, the punctuation records and the table in use at the end."""

    results: list[PopulationResult]
    records: list[dict[str, Any]]
    """In generation order."""
    table: GaitTable
    """The table the GA used last (``model``: corrected; else the base table)."""
    physics_wall_s: float = 0.0
    """Wall time of the punctuations measured in this call (a resumed run's replayed ones
    cost nothing)."""


def evolve_anytime(
    folder: Path,
    *,
    stage: Stage,
    table: GaitTable,
    ga: GASettings,
    world: WorldSettings,
    settings: AnytimeSettings,
    test_in_physics: PhysicsTester,
    settings_text: str,
    resume: bool,
    on_generation: OnGeneration | None = None,
    on_punctuation: OnPunctuation | None = None,
    table_meta: dict[str, Any] | None = None,
) -> AnytimeResult:
    """Evolve ``ga.populations`` populations of ``stage`` (coverage) in lockstep in ``folder``
    (already claimed: ``infra.rundir``) with physics punctuations (module docstring).

    ``settings_text`` is stored in the checkpoints and checked on resume; ``table_meta`` goes
    into each corrected table's file (method ``model``: ``tables/gen{g:04d}.json``)."""
    folder = Path(folder)
    gens = punctuation_generations(ga.generations, settings.every)
    records = load_records(folder, gens, ga, settings, table) if resume else {}
    _, seqs = stage_seeds(ga.seed, "coverage", ga.populations)
    runs = [
        PopulationRun(k, stage, folder, seed_seq=seqs[k], table=table, ga=ga, world=world,
                      settings_text=settings_text, resume=resume)
        for k in range(ga.populations)
    ]  # fmt: skip
    describe = describer(stage, table, world, settings, ga.seed)
    physics_s = 0.0
    while live := [r for r in runs if not r.finished]:
        g = min(r.generation for r in live)
        active = [r for r in live if r.generation == g]
        in_use = model_table(table, records, g - 1, settings)
        evaluated: dict[int, Generation] = {}
        for r in active:
            r.table = in_use
            evaluated[r.k] = r.evaluate()
        fitness = _in_force(active, evaluated, records, g - 1, settings, describe)
        if g in gens:
            chosen = _tested(active, fitness, settings.top)
            path = folder / RECORDS / f"gen{g:04d}.json"
            if g in records:
                _check_replay(records[g], chosen, active, path)
            elif len(active) < len(runs):
                raise AnytimeError(f"{path}: missing while other populations are past it")
            else:
                rec = _measure(
                    g, active, chosen, stage=stage, in_use=in_use, base=table, ga=ga,
                    world=world, settings=settings, test_in_physics=test_in_physics,
                    describe=describe,
                )  # fmt: skip
                records[g] = _save(folder, rec, table, records | {g: rec}, settings, table_meta)
                physics_s += rec["physics_wall_s"]
            fitness = _after(active, evaluated, records, g, stage, table, world, settings, ga.seed,
                             describe)  # fmt: skip
            if on_punctuation is not None:
                on_punctuation(records[g])
        for r in active:
            record = r.commit(fitness[r.k])
            if on_generation is not None:
                on_generation(record)
    results = [r.result for r in runs]
    assert all(res is not None for res in results)
    return AnytimeResult(
        results,  # type: ignore[arg-type]
        [records[g] for g in sorted(records)],
        model_table(table, records, ga.generations, settings),
        physics_s,
    )


def _in_force(
    active: list[PopulationRun], evaluated: dict[int, Generation],
    records: dict[int, dict[str, Any]], upto: int, settings: AnytimeSettings,
    describe: Describe,
) -> dict[int, np.ndarray]:  # fmt: skip
    """Each population's fitness in force: the table fitness, times its bias (method bias),
    or less its predicted disparity, not below 0 (method transfer, once a punctuation
    archived a behaviour)."""
    if settings.method == "transfer":
        archive, disparity = transfer_archive(records, upto)
    out = {}
    for r in active:
        f = evaluated[r.k].fitness
        if settings.method == "bias":
            f = f * population_bias(records, r.k, upto).factors(r.pop)
        elif settings.method == "transfer" and len(disparity):
            d = predict_disparity(archive, disparity, describe(r.pop), settings.neighbours)
            f = np.maximum(f - d, 0.0)
        out[r.k] = f
    return out


def _after(
    active: list[PopulationRun], evaluated: dict[int, Generation],
    records: dict[int, dict[str, Any]], g: int, stage: Stage, base: GaitTable,
    world: WorldSettings, settings: AnytimeSettings, seed: int, describe: Describe,
) -> dict[int, np.ndarray]:  # fmt: skip
    """The fitness in force once punctuation ``g`` applies: the new bias, or the generation
    re-evaluated on the corrected table (from the same starts, with the same envelope draws:
    key (seed, g))."""
    if settings.method != "model":
        return _in_force(active, evaluated, records, g, settings, describe)
    table = model_table(base, records, g, settings)
    out = {}
    for r in active:
        fit = evaluate_sections(r.pop, evaluated[r.k].starts, stage, table, world, (seed, g))[0]
        out[r.k] = fit.mean(axis=1)
    return out


def _save(
    folder: Path, rec: dict[str, Any], base: GaitTable, records: dict[int, dict[str, Any]],
    settings: AnytimeSettings, table_meta: dict[str, Any] | None,
) -> dict[str, Any]:  # fmt: skip
    """Write a new punctuation (its corrected table first, for method model); returns the
    record as read back from JSON, so a resumed run computes with exactly these numbers."""
    g = rec["generation"]
    if settings.method == "model":
        total, count = pooled_residuals(records, g)
        values = corrected_table(base.values, total, count, settings.min_samples)
        doc = table_to_json(
            values, source=f"{base.source}, corrected by physics to generation {g}",
            generation=g, min_samples=settings.min_samples, samples=count.tolist(),
            **(table_meta or {}),
        )  # fmt: skip
        atomic_write_json(folder / TABLES / f"gen{g:04d}.json", doc)
    path = atomic_write_json(folder / RECORDS / f"gen{g:04d}.json", rec)
    return read_json(path, what="punctuation record", error=AnytimeError)


__all__ = [
    "METHODS",
    "RECORDS",
    "TABLES",
    "AnytimeError",
    "AnytimeResult",
    "AnytimeSettings",
    "Bias",
    "OnPunctuation",
    "PhysicsRun",
    "PhysicsTester",
    "behaviour",
    "bias_rule",
    "describer",
    "corrected_table",
    "evolve_anytime",
    "final_starts",
    "check_record",
    "load_records",
    "model_table",
    "population_bias",
    "predict_disparity",
    "pooled_residuals",
    "punctuation_generations",
    "residual_sums",
    "section_keys",
    "table_error",
    "top_distinct",
    "transfer_archive",
]
