"""Does the table world rank controllers as physics does? Genome samples, the table's
prediction in an envelope, and the agreement measures of issue 16 (pure functions over
arrays and run folders; the physics runs come from ``servobot.robustness.matrix``).

Units: fitness is inner squares reached of the 64 (SPEC §5 test), per run or averaged over a
genome's starts. A genome's table fitness in an envelope is its mean over ``draws``
independent draws of the envelope per start (keys ``key_of_test(seed, "ranking", d)``), so
that it estimates the envelope's expectation, not one sample of it.
"""

from __future__ import annotations

import dataclasses
import re
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from scipy.stats import spearmanr

from evolve.codec import SECTION_GENES, read_chromosome
from evolve.envelope import NONE, Envelope, key_of_test
from evolve.evaluation import Evaluation, evaluate
from evolve.interpreter import END_NAMES
from infra.errors import InputError

TOP_FRACTION = 0.2
"""Where selection acts: the top 20 % of a final population by its last training fitness."""
_GEN_FILE = re.compile(r"pop(\d+)_gen(\d+)\.npz$")


class RankingError(InputError, ValueError):
    """A run folder without what a ranking needs; the message names the file."""


@dataclass(frozen=True)
class Genome:
    """A sampled controller: a label saying where it came from and its (16, 30) bits."""

    label: str
    bits: np.ndarray


def _saved(run: Path) -> dict[int, dict[int, Path]]:
    """{population: {generation: file}} of a coverage run's saved populations."""
    found: dict[int, dict[int, Path]] = {}
    for f in sorted((run / "coverage" / "populations").glob("pop*_gen*.npz")):
        m = _GEN_FILE.search(f.name)
        if m:
            found.setdefault(int(m[1]), {})[int(m[2])] = f
    if not found:
        raise RankingError(f"{run / 'coverage' / 'populations'}: no saved populations")
    return found


def navigation_of(run: Path) -> np.ndarray:
    """The fixed navigation section (8, 30) the run's coverage stage used."""
    best = run / "coverage" / "best_pop0.txt"
    if not best.is_file():
        raise RankingError(f"{best}: missing (a finished coverage stage writes it)")
    return read_chromosome(best)[SECTION_GENES:]


def _full(section: np.ndarray, navigation: np.ndarray) -> np.ndarray:
    return np.concatenate([section, navigation]).astype(np.uint8)


def final_populations(run: Path) -> list[tuple[int, int, np.ndarray, np.ndarray]]:
    """(population, generation, coverage sections (N, 8, 30), training fitness (N,)) of each
    population's last saved generation."""
    out = []
    for pop, gens in sorted(_saved(run).items()):
        last = max(gens)
        with np.load(gens[last]) as d:
            out.append((pop, last, d["population"], d["fitness"]))
    return out


def top_genomes(run: Path, per_population: int, fraction: float = TOP_FRACTION) -> list[Genome]:
    """``per_population`` distinct genomes of each final population's top ``fraction`` (by the
    last generation's training fitness), evenly spaced over those ranks, best first."""
    navigation = navigation_of(run)
    out: list[Genome] = []
    for pop, last, population, fitness in final_populations(run):
        order = np.argsort(-fitness, kind="stable")[: max(1, round(fraction * len(fitness)))]
        seen: set[bytes] = set()
        distinct = []
        for i in order:
            key = population[i].tobytes()
            if key not in seen:
                seen.add(key)
                distinct.append(int(i))
        picks = np.unique(np.linspace(0, len(distinct) - 1, per_population).round().astype(int))
        for rank in picks:
            i = distinct[rank]
            out.append(Genome(f"p{pop}g{last}r{rank}", _full(population[i], navigation)))
    return out


def generation_bests(run: Path) -> list[Genome]:
    """The best of every saved generation of every population."""
    navigation = navigation_of(run)
    out = []
    for pop, gens in sorted(_saved(run).items()):
        for gen, f in sorted(gens.items()):
            with np.load(f) as d:
                out.append(Genome(f"p{pop}g{gen}best", _full(d["best"], navigation)))
    return out


def table_evaluations(
    genomes: list[Genome],
    starts: np.ndarray,
    *,
    table,
    envelope: Envelope = NONE,
    seed: int = 0,
    draws: int = 16,
    steps: int | None = None,
) -> list[Evaluation]:
    """The table world's coverage runs of ``genomes`` from ``starts`` under ``envelope``: one
    ``Evaluation`` for ``NONE``, else one per draw (keys ``key_of_test(seed, "ranking", d)``)."""
    bits = np.stack([g.bits for g in genomes])
    return [evaluate(bits, starts, table=table, mode="coverage", max_steps=steps,
                     envelope=envelope, envelope_key=key_of_test(seed, "ranking", d))
            for d in range(1 if envelope == NONE else draws)]  # fmt: skip


def mean_inner_squares(evaluations: list[Evaluation]) -> np.ndarray:
    """(G, S) inner squares per genome and start, the mean over ``evaluations`` (draws)."""
    total = np.zeros(evaluations[0].inner_squares.shape)
    for ev in evaluations:
        total += ev.inner_squares
    return total / len(evaluations)


def table_end_shares(evaluations: list[Evaluation]) -> np.ndarray:
    """(G, len(END_NAMES)) share of each genome's runs in ``evaluations`` (every start and
    draw) that end each way (``evolve.interpreter.END_NAMES`` order)."""
    counts = np.zeros((evaluations[0].end.shape[0], len(END_NAMES)))
    for ev in evaluations:
        counts += (ev.end[:, :, None] == np.arange(len(END_NAMES))).sum(axis=1)
    return counts / counts.sum(axis=1, keepdims=True)


def table_runs(
    genomes: list[Genome],
    starts: np.ndarray,
    *,
    table,
    envelope: Envelope = NONE,
    seed: int = 0,
    draws: int = 16,
    steps: int | None = None,
) -> np.ndarray:
    """(G, S) inner squares per genome and start in the table world under ``envelope``: one
    run for ``NONE``, else the mean of ``draws`` draws of the envelope
    (``table_evaluations``)."""
    return mean_inner_squares(table_evaluations(genomes, starts, table=table, envelope=envelope,
                                                seed=seed, draws=draws, steps=steps))  # fmt: skip


def noise_ceiling(
    genomes: list[Genome],
    starts: np.ndarray,
    *,
    table,
    envelope: Envelope,
    seed: int = 0,
    draws: int = 16,
    realisations: int = 4,
    steps: int | None = None,
) -> dict[str, float]:
    """The best ``agreement`` any model can reach against one run of a world that varies as
    ``envelope`` says: the envelope's prediction (``table_runs``, ``draws`` draws per start)
    against one draw of it per start (keys of ``seed + 1``, never the prediction's), averaged
    over ``realisations`` such draws. With ``NONE`` a run is its own prediction (Spearman 1,
    |Δ| 0)."""
    if realisations < 1:
        raise ValueError(f"realisations must be ≥ 1, got {realisations}")
    pred = table_runs(genomes, starts, table=table, envelope=envelope, seed=seed, draws=draws,
                      steps=steps)  # fmt: skip
    bits = np.stack([g.bits for g in genomes])
    scores = []
    for r in range(realisations):
        one = evaluate(bits, starts, table=table, mode="coverage", max_steps=steps,
                       envelope=envelope, envelope_key=key_of_test(seed + 1, "ranking", r))
        scores.append(agreement(pred, one.inner_squares.astype(np.float64)))
    return {k: float(np.mean([sc[k] for sc in scores])) for k in scores[0]}


def seen(envelope: Envelope, station_seen: bool) -> Envelope:
    """``envelope`` with the station block always (or never) seen: its prediction for one
    physics world (``station-seen`` or ``shipped``)."""
    return dataclasses.replace(envelope, station_seen_p=1.0 if station_seen else 0.0)


def rho(a: np.ndarray, b: np.ndarray) -> float:
    """Spearman of the finite pairs of ``a`` and ``b``; NaN with fewer than 3 or no spread."""
    ok = np.isfinite(a) & np.isfinite(b)
    if ok.sum() < 3 or np.ptp(a[ok]) == 0 or np.ptp(b[ok]) == 0:
        return float("nan")
    return float(spearmanr(a[ok], b[ok]).statistic)


POPULATION = re.compile(r"^p(\d+)g")
"""A sampled genome's label: population k's genomes start ``p{k}g`` (``top_genomes``,
``generation_bests``)."""


def groups_of(names: list[str]) -> np.ndarray:
    """(G,) group of each name: its population when every name is ``p{k}g…``, else its index."""
    found = [POPULATION.match(n) for n in names]
    if all(found):
        return np.array([int(m.group(1)) for m in found])  # type: ignore[union-attr]
    return np.arange(len(names))


def population_agreement(
    table: np.ndarray, physics: np.ndarray, groups: np.ndarray
) -> dict[str, Any]:
    """Where a ranking's agreement comes from: Spearman within each population (its genomes'
    mean fitness, table against physics) and over the populations' means."""
    t, p = table.mean(axis=1), physics.mean(axis=1)
    keys = np.unique(groups)
    within = [rho(t[groups == k], p[groups == k]) for k in keys]
    return {
        "populations": keys.tolist(),
        "within_spearman": within,
        "within_spearman_mean": float(np.nanmean(within)) if np.isfinite(within).any()
        else float("nan"),
        "of_means_spearman": rho(np.array([t[groups == k].mean() for k in keys]),
                                 np.array([p[groups == k].mean() for k in keys])),
        "physics_means": [float(p[groups == k].mean()) for k in keys],
    }  # fmt: skip


def end_agreement(
    table: np.ndarray, physics: np.ndarray, groups: np.ndarray
) -> dict[str, dict[str, Any]]:
    """How the table world predicts the way physics' runs end, from (G, len(END_NAMES)) end
    shares of the same genomes (``table_end_shares`` and the physics runs'): per end that
    either side has, each side's mean share, Pearson's r of the genomes' shares (NaN without
    spread on either side) and each population's mean share of each side (``groups``)."""
    keys = np.unique(groups)
    out = {}
    for code, name in enumerate(END_NAMES):
        t, p = table[:, code], physics[:, code]
        if not (t.any() or p.any()):
            continue
        spread = np.ptp(t) > 0 and np.ptp(p) > 0
        out[name] = {
            "table": float(t.mean()),
            "physics": float(p.mean()),
            "r": float(np.corrcoef(t, p)[0, 1]) if spread else float("nan"),
            "table_by_population": [float(t[groups == k].mean()) for k in keys],
            "physics_by_population": [float(p[groups == k].mean()) for k in keys],
        }
    return out


def agreement(table: np.ndarray, physics: np.ndarray) -> dict[str, float]:
    """How table runs (G, S) predict physics runs (G, S) of the same genomes and starts:
    Spearman of the genomes' mean fitness, mean per-run |Δ inner squares|, and the mean
    fitness of each side (inner squares)."""
    t, p = table.mean(axis=1), physics.mean(axis=1)
    return {
        "spearman": rho(t, p),
        "mean_abs_delta": float(np.abs(table - physics).mean()),
        "table_mean": float(t.mean()),
        "physics_mean": float(p.mean()),
    }
