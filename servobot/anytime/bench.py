"""Does anytime learning pay in physics? Table-only and each method on the same seeds.

``python -m servobot.anytime.bench --navigation FILE --out runs/anytime_bench --seeds 0 1
[--table paper|PATH] [--populations 3] [--generations 128] [--population-size 128]
[--every 32] [--top 2] [--physics-starts 2] [--physics-steps 600] [--final-starts 20]
[--methods none bias model transfer] [--neighbours 3] [--descriptor-starts 4]
[--envelope none|default|FILE.json] [--executor process] [--workers N] [--resume]``

For each seed it runs ``servobot.anytime.run.run_anytime`` once per method into
``OUT/seed{s}/{method}`` (``none`` first: it is the others' baseline; the control measures
the same punctuations without feeding them back, so its ``table_wall_s`` is the table-only
run's wall time; every method evolves in ``--envelope``, SPEC §9). Then, per method over all
seeds: the finalists' inner coverage in physics and in the table world (20 fresh starts each)
and their gap, the difference in physics from the control, the rank correlation (Spearman)
between table and physics fitness over the tested genomes (pooled, and within each
punctuation), the physics runs and their wall time, and the wall time against the table-only
run. Writes ``OUT/bench.json``, ``OUT/bench.md`` and ``OUT/figure_anytime_bench.png``; prints
the Markdown table. ``--resume`` continues interrupted runs and reuses finished ones. See
docs/anytime.md.
"""

from __future__ import annotations

import argparse
import dataclasses
import sys
from pathlib import Path
from typing import Any

from scipy.stats import spearmanr

from evolve import figures
from evolve.anytime import METHODS, AnytimeSettings
from evolve.codec import read_chromosome
from evolve.envelope import NONE, load_envelope
from evolve.settings import coverage_ga_settings
from evolve.stages import navigation_section
from infra.executors import EXECUTOR_SPECS, check_spec, make_executor
from infra.io import atomic_write_json, atomic_write_text, read_json
from servobot.anytime.report import label, mean_of
from servobot.anytime.run import run_anytime
from servobot.validation.lone import load_checked_table

GOAL_PP = 3.0
"""The issue's goal: anytime finalists ≥ this many pp more inner coverage in physics…"""
GOAL_WALL = 1.30
"""…with at most this factor of the table-only run's wall time."""


def parse_args(argv: list[str] | None) -> argparse.Namespace:
    p = argparse.ArgumentParser(prog="python -m servobot.anytime.bench", description=__doc__,
                                formatter_class=argparse.RawDescriptionHelpFormatter)  # fmt: skip
    p.add_argument("--navigation", type=Path, required=True, help="navigation section file")
    p.add_argument("--out", type=Path, default=Path("runs/anytime_bench"))
    p.add_argument("--seeds", type=int, nargs="+", default=[0])
    p.add_argument("--table", default="paper")
    p.add_argument("--methods", nargs="+", choices=METHODS, default=list(METHODS))
    p.add_argument("--populations", type=int, default=3)
    p.add_argument("--generations", type=int, default=128)
    p.add_argument("--population-size", type=int, default=128)
    p.add_argument("--every", type=int, default=32)
    p.add_argument("--top", type=int, default=2)
    p.add_argument("--physics-starts", type=int, default=2)
    p.add_argument("--physics-steps", type=int, default=600)
    p.add_argument("--final-starts", type=int, default=20)
    p.add_argument("--neighbours", type=int, default=AnytimeSettings.neighbours,
                   help="transfer: k nearest tested behaviours")  # fmt: skip
    p.add_argument("--descriptor-starts", type=int, default=AnytimeSettings.descriptor_starts,
                   help="transfer: fixed starts of a behaviour")  # fmt: skip
    p.add_argument("--envelope", default="none", metavar="none|default|FILE.json",
                   help="envelope of variation every arm evolves in (SPEC §9; default none)")
    p.add_argument("--resume", action="store_true")
    p.add_argument(
        "--executor", type=check_spec, default="process", metavar="|".join(EXECUTOR_SPECS)
    )
    p.add_argument("--workers", type=int, default=None)
    return p.parse_args(argv)


def run_arms(args: argparse.Namespace) -> dict[int, dict[str, dict[str, Any]]]:
    """Every (seed, method) run; their summaries."""
    table, warning = load_checked_table(args.table, None)
    if warning:
        print(warning, file=sys.stderr)
    nav = navigation_section(read_chromosome(args.navigation))
    envelope = load_envelope(args.envelope)
    ex = make_executor(args.executor, args.workers)
    base = AnytimeSettings(
        every=args.every, top=args.top, physics_starts=args.physics_starts,
        physics_steps=args.physics_steps, final_starts=args.final_starts,
        neighbours=args.neighbours, descriptor_starts=args.descriptor_starts,
    )  # fmt: skip
    methods = ["none"] + [m for m in args.methods if m != "none"]
    out: dict[int, dict[str, dict[str, Any]]] = {}
    for seed in args.seeds:
        ga = coverage_ga_settings(
            in_envelope=envelope != NONE, populations=args.populations,
            generations=args.generations, population_size=args.population_size, seed=seed,
        )  # fmt: skip
        for method in methods:
            folder = args.out / f"seed{seed}" / method
            done = folder / "anytime" / "summary.json"
            if args.resume and done.exists():
                out.setdefault(seed, {})[method] = read_json(done, what="anytime summary")
                continue
            print(f"seed {seed}, method {method} ...", file=sys.stderr)
            out.setdefault(seed, {})[method] = run_anytime(
                folder, navigation=nav, table=table, ga=ga, executor=ex,
                settings=dataclasses.replace(base, method=method),
                baseline=None if method == "none" else args.out / f"seed{seed}" / "none",
                resume=args.resume, envelope=envelope,
            )  # fmt: skip
    return out


def _spearman(a: list[float], b: list[float]) -> float | None:
    if len(a) < 3 or len(set(a)) < 2 or len(set(b)) < 2:
        return None
    return float(spearmanr(a, b).statistic)


def arm_numbers(runs: list[dict[str, Any]], control: list[dict[str, Any]]) -> dict[str, Any]:
    """The measured numbers of one method over its seeds (``control``: the none runs)."""
    pairs: list[tuple[float, float]] = []
    within = []
    for s in runs:
        for p in s["punctuations"]:
            tp = [(t["table_fitness"], t["physics_fitness"]) for t in p["tested"]
                  if t["physics_fitness"] is not None]  # fmt: skip
            pairs += tp
            within.append(_spearman([a for a, _ in tp], [b for _, b in tp]))
    phys = [s["final"]["physics_inner_percent"] for s in runs]
    base = [c["final"]["physics_inner_percent"] for c in control]
    table_only = sum(c["table_wall_s"] for c in control)
    training = sum(s["table_wall_s"] + s["physics_wall_s"] for s in runs)
    with_final = sum(s["table_wall_s"] + s["physics_wall_s"] + s["final_wall_s"] for s in runs)
    only_final = sum(c["table_wall_s"] + c["final_wall_s"] for c in control)
    delta = [None if a is None or b is None else a - b for a, b in zip(phys, base, strict=True)]
    return {
        "seeds": len(runs),
        "physics_inner_percent": mean_of(phys),
        "table_inner_percent": mean_of([s["final"]["table_inner_percent"] for s in runs]),
        "gap_pp": mean_of([s["final"]["gap_pp"] for s in runs]),
        "physics_vs_control_pp": mean_of(delta),
        "physics_vs_control_pp_per_seed": delta,
        "spearman_pooled": _spearman([a for a, _ in pairs], [b for _, b in pairs]),
        "spearman_within_punctuation": mean_of(within),
        "tested": len(pairs),
        "physics_runs": sum(s["physics_runs"] for s in runs),
        "physics_wall_s": sum(s["physics_wall_s"] for s in runs),
        "table_wall_s": sum(s["table_wall_s"] for s in runs),
        "final_wall_s": sum(s["final_wall_s"] for s in runs),
        "wall_vs_table_only": training / table_only if table_only > 0 else None,
        "wall_vs_table_only_with_final": with_final / only_final if only_final > 0 else None,
    }


def numbers(summaries: dict[int, dict[str, dict[str, Any]]]) -> dict[str, Any]:
    """Per method, its ``arm_numbers``; and whether each anytime method met the goal."""
    methods = next(iter(summaries.values())).keys()
    control = [summaries[s]["none"] for s in summaries]
    arms = {m: arm_numbers([summaries[s][m] for s in summaries], control) for m in methods}
    for m, a in arms.items():
        d, w = a["physics_vs_control_pp"], a["wall_vs_table_only"]
        a["goal_met"] = None if m == "none" or d is None or w is None else (
            d >= GOAL_PP and w <= GOAL_WALL
        )  # fmt: skip
    return arms


def markdown(arms: dict[str, Any], settings: dict[str, Any]) -> str:
    """The table of the numbers (bench.md)."""

    def f(v: Any, fmt: str = ".1f") -> str:
        return "—" if v is None else format(v, fmt)

    rows = [
        f"Settings: {settings}",
        "",
        "| method | physics inner % | table inner % | gap pp | Δ physics vs none pp | "
        "Spearman pooled | within punct. | tested | physics runs | physics s | table s | "
        "final s | wall / table-only | with final | goal |",
        "|---|" + "---|" * 14,
    ]
    for m, a in arms.items():
        rows.append(
            f"| {m} | {f(a['physics_inner_percent'])} | {f(a['table_inner_percent'])} | "
            f"{f(a['gap_pp'], '+.1f')} | {f(a['physics_vs_control_pp'], '+.1f')} | "
            f"{f(a['spearman_pooled'], '.2f')} | {f(a['spearman_within_punctuation'], '.2f')} | "
            f"{a['tested']} | {a['physics_runs']} | {f(a['physics_wall_s'], '.0f')} | "
            f"{f(a['table_wall_s'], '.0f')} | {f(a['final_wall_s'], '.0f')} | "
            f"{f(a['wall_vs_table_only'], '.2f')} | {f(a['wall_vs_table_only_with_final'], '.2f')}"
            f" | {'—' if a['goal_met'] is None else ('met' if a['goal_met'] else 'not met')} |"
        )
    return "\n".join(rows) + "\n"


def mean_curve(runs: list[dict[str, Any]]) -> dict[str, list[Any]]:
    """``best_curve`` averaged over seeds (same punctuation generations)."""
    curves = [s["best_by_generation"] for s in runs]
    out: dict[str, list[Any]] = {"generations": curves[0]["generations"]}
    for key in ("physics_fitness", "table_fitness"):
        out[key] = [mean_of(list(vals)) for vals in zip(*(c[key] for c in curves), strict=True)]
    return out


def main(argv: list[str] | None = None) -> int:
    args = parse_args(argv)
    summaries = run_arms(args)
    arms = numbers(summaries)
    settings = {k: v for k, v in vars(args).items() if k not in ("out", "resume")}
    settings = {k: str(v) if isinstance(v, Path) else v for k, v in settings.items()}
    args.out.mkdir(parents=True, exist_ok=True)
    atomic_write_json(args.out / "bench.json", {"settings": settings, "methods": arms})
    text = markdown(arms, settings)
    atomic_write_text(args.out / "bench.md", text)
    curves = []
    for m in arms:
        runs = [summaries[s][m] for s in summaries]
        text_label = label(m, arms[m]["physics_inner_percent"])
        curves.append((text_label, mean_curve(runs), figures.ANYTIME_COLOURS[m]))
    title = (f"anytime learning: the best of each population in physics (mean of "
             f"{args.populations} populations × {len(args.seeds)} seeds)")  # fmt: skip
    figures.figure_anytime(args.out / "figure_anytime_bench.png", curves, title)
    print(text)
    print(f"wrote {args.out / 'bench.md'}, bench.json, figure_anytime_bench.png")
    return 0


if __name__ == "__main__":
    sys.exit(main())


__all__ = ["arm_numbers", "main", "markdown", "mean_curve", "numbers"]
