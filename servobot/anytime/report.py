"""The summary, provenance and figure of an anytime run (pure functions over its records).

``summary(result, finals, settings, doc)`` is ``summary.json`` without its wall times;
``best_curve(summary)`` the physics (and table) fitness of each population's best at each
punctuation, averaged over the populations; ``figure`` draws it beside a baseline's.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from evolve import figures
from evolve.anytime import AnytimeResult, AnytimeSettings
from evolve.settings import GASettings
from evolve.table import GaitTable

TESTED_KEYS = ("population", "index", "rank", "table_fitness", "physics_fitness", "ratio")
"""What ``summary.json`` keeps of each tested genome (its record has every run)."""


def punctuation_entry(rec: dict[str, Any]) -> dict[str, Any]:
    """A punctuation as ``summary.json`` lists it."""
    entry = {
        "generation": rec["generation"],
        "tested": [{k: t[k] for k in TESTED_KEYS} for t in rec["tested"]],
    }
    if rec["bias"] is not None:
        entry["bias"] = rec["bias"]
    return entry | {
        "table_error": rec["table_error"],
        "physics_cycles": rec["physics_cycles"],
        "physics_runs": rec["physics_runs"],
        "physics_errors": rec["physics_errors"],
        "physics_wall_s": rec["physics_wall_s"],
    }


def mean_of(values: list[Any]) -> float | None:
    """The mean of the values that are not None; None if there are none."""
    vals = [v for v in values if v is not None]
    return float(np.mean(vals)) if vals else None


def percent(v: float | None) -> str:
    """A percentage for people: ``41.3%``, ``—`` when not measured."""
    return "—" if v is None else f"{v:.1f}%"


def final_entry(finals: list[dict[str, Any]]) -> dict[str, Any]:
    """The final test: per population and mean, inner % in both worlds and their gap."""
    pops = []
    for d in finals:
        s = d["summary"]
        pops.append({
            "population": d["population"],
            "table_inner_percent": s["table"].get("inner_pct"),
            "physics_inner_percent": s["physics"].get("inner_pct"),
            "gap_pp": s["gap"].get("inner_pct_pp"),
            "physics_errors": s["physics_errors"],
        })  # fmt: skip
    return {
        "starts": finals[0]["summary"]["starts"] if finals else 0,
        "table_inner_percent": mean_of([p["table_inner_percent"] for p in pops]),
        "physics_inner_percent": mean_of([p["physics_inner_percent"] for p in pops]),
        "gap_pp": mean_of([p["gap_pp"] for p in pops]),
        "physics_errors": sum(p["physics_errors"] for p in pops),
        "populations": pops,
    }


def best_curve(records: list[dict[str, Any]]) -> dict[str, list[Any]]:
    """Per punctuation, the mean over populations of the fitness of each population's best
    (rank 0 of its tested genomes: the best by the fitness in force) in physics and in the
    table world, on that punctuation's starts."""
    out: dict[str, list[Any]] = {"generations": [], "physics_fitness": [], "table_fitness": []}
    for rec in records:
        best = [t for t in rec["tested"] if t["rank"] == 0]
        out["generations"].append(rec["generation"])
        out["physics_fitness"].append(mean_of([t["physics_fitness"] for t in best]))
        out["table_fitness"].append(mean_of([t["table_fitness"] for t in best]))
    return out


def summary(
    result: AnytimeResult, finals: list[dict[str, Any]], settings: AnytimeSettings,
    doc: dict[str, Any],
) -> dict[str, Any]:  # fmt: skip
    """``summary.json`` of a finished run, wall times of this invocation aside."""
    return {
        "method": settings.method,
        "punctuations": [punctuation_entry(r) for r in result.records],
        "best_by_generation": best_curve(result.records),
        "final": final_entry(finals),
        "physics_runs": sum(r["physics_runs"] for r in result.records),
        "physics_wall_s": sum(r["physics_wall_s"] for r in result.records),
        "final_wall_s": sum(d["summary"]["wall_s"] for d in finals),
        "final_table": result.table.source,
        "settings": doc,
    }


def provenance(
    k: int, ga: GASettings, table: GaitTable, settings: AnytimeSettings, final: dict[str, Any]
) -> str:
    """The header of ``best_pop{k}.txt``."""
    return (
        f"servobot anytime, method {settings.method} (every {settings.every}, top "
        f"{settings.top}, {settings.physics_starts} physics starts), population {k} of "
        f"{ga.populations}, final generation {ga.generations}, population size "
        f"{ga.population_size}, seed {ga.seed}\ngait table: {table.source}\n"
        "16 genes: coverage section (learned) + navigation (fixed); final test on "
        f"{settings.final_starts} fresh starts: table {percent(final['table_inner_percent'])}, "
        f"physics {percent(final['physics_inner_percent'])} of the inner squares"
    )


def label(method: str, physics_inner_percent: float | None) -> str:
    """A method's legend label, with its finalists' physics inner coverage."""
    return f"{method} (final: physics {percent(physics_inner_percent)} inner)"


def _label(s: dict[str, Any]) -> str:
    return label(s["method"], s["final"]["physics_inner_percent"])


def figure(path: Path, run: dict[str, Any], baseline: dict[str, Any] | None) -> Path:
    """``figure_anytime.png``: physics (solid) and table (dotted) fitness of the best by
    generation, this run beside the ``baseline`` (a ``method none`` run of the same seed)."""
    colours = figures.ANYTIME_COLOURS
    arms = [(_label(run), run["best_by_generation"], colours[run["method"]])]
    if baseline is not None:  # drawn first: this run's curves lie on top
        label = f"baseline: {_label(baseline)}"
        arms.insert(0, (label, baseline["best_by_generation"], colours["none"]))
    ga = run["settings"]["GASettings"]
    title = (
        f"anytime learning, method {run['method']}: the best of each population in physics "
        f"(mean of {ga['populations']}, seed {ga['seed']})"
    )
    return figures.figure_anytime(path, arms, title)


__all__ = [
    "best_curve",
    "figure",
    "final_entry",
    "label",
    "mean_of",
    "percent",
    "provenance",
    "punctuation_entry",
    "summary",
]
