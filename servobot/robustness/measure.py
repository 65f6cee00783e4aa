"""Issue 16's ranking measurement: does the table world (in an arm's own envelope) rank a
run's controllers as physics does, and which envelope scales would rank them best?

    python -m servobot.robustness.measure --run runs/none_s0 --envelope none \\
        --table runs/cal/gait_table.json --per-population 5 --starts 4 --out runs/rank_none_s0 \\
        [--bests] [--tune] [--workers 2] [--executor ray:ADDRESS] [--reuse EARLIER_OUT]

Genomes: ``--per-population`` distinct genomes from each final population's top 20 %
(``ranking.top_genomes``), and with ``--bests`` the best of every saved generation. Each runs
from the same ``--starts`` seeded coverage starts in the table world and in the physics
worlds ``shipped`` and ``station-seen`` (``run_matrix`` into ``OUT/matrix``, resumable;
``--reuse EARLIER_OUT`` takes an earlier measurement's runs of the same genomes and starts; one
physics cell per behaviour: genomes equal in their expressed bits, ``evolve.codec.expressed``,
run alike, and ``ranking.json``'s ``runs_as`` names the genome each clone's runs are). The
table side is the arm's own world: the exact table for ``none``, else the mean over draws of
the envelope; beside it the exact table and the *matched* world (the arm's envelope with the
station block never seen for ``shipped``, always for ``station-seen``: a table world told
which station physics has). ``--tune`` scores a grid of envelopes on the same physics runs,
each world against the envelope with the station block never (``shipped``) or always
(``station-seen``) seen. Beside the agreement, its ceiling: the best any model reaches
against one run of a world that varies as the envelope says (``ranking.noise_ceiling``: the
arm's envelope, ``default`` for ``none``, against one draw of itself, the same genomes and
starts), where the agreement comes from (``ranking.population_agreement``: Spearman
within each population and over the population means, the own world), and how the runs end
in the own world and in physics (``ranking.end_agreement``: each end's share, per population,
and how the genomes' shares correlate). Writes
``OUT/ranking.json`` and ``OUT/ranking.md``.
"""

from __future__ import annotations

import argparse
import dataclasses
import itertools
import sys
from pathlib import Path
from typing import Any

import numpy as np

from evolve.codec import expressed, format_chromosome
from evolve.envelope import DEFAULT, NONE, TRAINING_DEFAULTS, Envelope, load_envelope
from evolve.interpreter import END_NAMES
from evolve.table import load_table
from infra.bounds import check_workers
from infra.command import Interrupted, command_line, run_command
from infra.errors import InputError
from infra.executors import RayExecutor, make_executor
from infra.io import read_json, write_report
from servobot.progress import RunBar, progress_bar
from servobot.robustness.matrix import RUNS_DIR, RobustnessSettings, check_reuse, run_matrix
from servobot.robustness.ranking import (
    RankingError,
    agreement,
    end_agreement,
    generation_bests,
    groups_of,
    mean_inner_squares,
    noise_ceiling,
    population_agreement,
    seen,
    table_end_shares,
    table_evaluations,
    table_runs,
    top_genomes,
)

WORLDS = ("shipped", "station-seen")
"""The physics worlds the ranking is measured in (issue 16)."""
TUNE_GRID = {
    "scatter_scale": (0.0, 0.5, 1.0, 1.5, 2.0),
    "bias_scale": (0.0, 0.5, 1.0),
    "reach_units": (0.0, 5.0, 10.0),
    "station_stops": (False, True),
}
"""The envelope scales ``--tune`` tries (every combination)."""


def cell_report(matrix: Path, world: str, name: str) -> dict[str, Any]:
    """The ``report.json`` of chromosome ``name``'s cell in ``world`` of a finished matrix
    (``InputError`` naming the file when it cannot be read)."""
    path = matrix / RUNS_DIR / world / name / "report.json"
    return read_json(path, what="matrix cell report", error=InputError)


def cell_runs(matrix: Path, world: str, names: list[str]) -> list[list[dict[str, Any]]]:
    """The runs (``report.json``'s ``runs``) of each named genome's cell in ``world``."""
    return [cell_report(matrix, world, n)["runs"] for n in names]


def inner_squares(cells: list[list[dict[str, Any]]], starts: int, side: str) -> np.ndarray:
    """(G, S) inner squares of each cell's runs on ``side`` ("physics" or "table"; NaN where
    that side has no result, a physics error)."""
    out = np.full((len(cells), starts), np.nan)
    for g, runs in enumerate(cells):
        for r in runs:
            if r[side] is not None:
                out[g, r["index"]] = r[side]["inner_squares"]
    return out


def physics_runs(matrix: Path, world: str, names: list[str], starts: int) -> np.ndarray:
    """(G, S) physics inner squares of each genome's cell in ``world`` (NaN: a physics error)."""
    return inner_squares(cell_runs(matrix, world, names), starts, "physics")


def end_shares(cells: list[list[dict[str, Any]]], side: str) -> np.ndarray:
    """(G, len(END_NAMES)) share of each cell's runs on ``side`` that end each way
    (``evolve.interpreter.END_NAMES`` order; runs without a result there, physics errors,
    left out)."""
    out = np.zeros((len(cells), len(END_NAMES)))
    for g, runs in enumerate(cells):
        for r in runs:
            if r[side] is not None:
                out[g, r[side]["end"]["code"]] += 1
    return out / np.maximum(out.sum(axis=1, keepdims=True), 1)


def _score(tab: dict[str, np.ndarray], phys: dict[str, np.ndarray]) -> dict[str, Any]:
    per = {w: agreement(tab[w], phys[w]) for w in phys}
    return per | {
        "spearman_mean": float(np.mean([v["spearman"] for v in per.values()])),
        "abs_delta_mean": float(np.mean([v["mean_abs_delta"] for v in per.values()])),
    }


def tune(genomes, starts, table, phys, seed: int, draws: int, steps: int) -> list[dict[str, Any]]:
    """Every envelope of ``TUNE_GRID``, scored on the physics runs ``phys`` by world."""
    rows = []
    combos = list(itertools.product(*TUNE_GRID.values()))
    bar = progress_bar(desc="tune", unit="envelope", total=len(combos))
    for values in combos:
        bar.update(1)
        scales = dict(zip(TUNE_GRID, values, strict=True))
        env = Envelope(**scales, station_seen_p=DEFAULT.station_seen_p)
        tab = {w: table_runs(genomes, starts, table=table, envelope=seen(env, w != "shipped"),
                             seed=seed, draws=draws, steps=steps) for w in phys}  # fmt: skip
        rows.append({"envelope": env.to_dict()} | _score(tab, phys))
    bar.close()
    return sorted(rows, key=lambda r: (-r["spearman_mean"], r["abs_delta_mean"]))


def _markdown(doc: dict[str, Any]) -> str:
    lines = [f"# Ranking: {doc['run']} (envelope {doc['envelope_name']})", "",
             f"{doc['genomes']} genomes ({doc['behaviours']} behaviours: genomes equal in their "
             f"expressed bits run in physics once) × {doc['starts']} starts, worlds "
             f"{', '.join(WORLDS)}", "",
             "| sample | table world | physics world | Spearman | mean abs Δ | table | physics |",
             "|---|---|---|---|---|---|---|"]  # fmt: skip
    for sample, by in doc["agreement"].items():
        for side, worlds in by.items():
            for w, a in worlds.items():
                lines.append(f"| {sample} | {side} | {w} | {a['spearman']:.2f} | "
                             f"{a['mean_abs_delta']:.1f} | {a['table_mean']:.1f} | "
                             f"{a['physics_mean']:.1f} |")  # fmt: skip
    for sample, by in doc.get("by_population", {}).items():
        lines += ["", f"## {sample}: by population (own world)", "",
                  "| physics world | Spearman within each population | mean | of the populations' "
                  "means | physics mean per population |", "|---|---|---|---|---|"]  # fmt: skip
        for w, a in by.items():
            within = ", ".join(f"{v:.2f}" for v in a["within_spearman"])
            means = ", ".join(f"{v:.1f}" for v in a["physics_means"])
            lines.append(f"| {w} | {within} | {a['within_spearman_mean']:.2f} | "
                         f"{a['of_means_spearman']:.2f} | {means} |")  # fmt: skip
    for sample, by in doc.get("ends", {}).items():
        lines += ["", f"## {sample}: how runs end (own world against physics)", "",
                  "Share of the runs ending each way; r: Pearson over the genomes' shares.", "",
                  "| physics world | end | table | physics | r | table per population | "
                  "physics per population |", "|---|---|---|---|---|---|---|"]  # fmt: skip
        for w, ends in by.items():
            for name, e in ends.items():
                t, p = (", ".join(f"{100 * v:.0f}" for v in e[k])
                        for k in ("table_by_population", "physics_by_population"))  # fmt: skip
                lines.append(
                    f"| {w} | {name} | {100 * e['table']:.1f} % | "
                    f"{100 * e['physics']:.1f} % | {e['r']:.2f} | {t} | {p} |"
                )
    if doc.get("tune"):
        lines += ["", "## Envelope scales scored on these physics runs (best 10)", "",
                  "| scatter | bias | reach | stops | Spearman (mean of worlds) | mean abs Δ |",
                  "|---|---|---|---|---|---|"]  # fmt: skip
        for r in doc["tune"][:10]:
            e = r["envelope"]
            lines.append(f"| {e['scatter_scale']} | {e['bias_scale']} | {e['reach_units']} | "
                         f"{e['station_stops']} | {r['spearman_mean']:.2f} | "
                         f"{r['abs_delta_mean']:.1f} |")  # fmt: skip
    return "\n".join(lines) + "\n"


PROG = "python -m servobot.robustness.measure"


def main(argv: list[str] | None = None) -> int:
    """Run the measurement; returns the exit code (0 done, 2 bad input, 130 Ctrl-C, 143
    SIGTERM: the physics runs finished so far are kept, the same command resumes)."""
    argv = list(sys.argv[1:] if argv is None else argv)
    p = argparse.ArgumentParser(
        prog=PROG,
        description=__doc__,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.add_argument("--run", type=Path, required=True, help="an evolve run folder")
    p.add_argument("--envelope", default="none", help="the arm's envelope (its own world)")
    p.add_argument("--table", default="paper")
    p.add_argument("--per-population", type=int, default=5,
                   help="genomes per final population's top 20 %% (0: only --bests)")  # fmt: skip
    p.add_argument("--bests", action="store_true", help="also every saved generation's best")
    p.add_argument("--starts", type=int, default=4)
    p.add_argument("--steps", type=int, default=600, help="steps per run (SPEC §5: 600)")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--draws", type=int, default=16, help="envelope draws per table start")
    p.add_argument("--tune", action="store_true")
    p.add_argument("--workers", type=int, default=None)
    p.add_argument("--executor", default=None, metavar="serial|process|ray|ray:ADDRESS",
                   help="where the physics runs go (docs/executors.md); default: a process "
                   "pool of --workers, serial with --workers 1")  # fmt: skip
    p.add_argument("--reuse", type=Path, default=None, metavar="DIR",
                   help="an earlier measurement's --out: its physics runs of the same genomes "
                   "and starts are taken, not run again (e.g. going from 10 starts to 30)")
    p.add_argument("--no-share", action="store_true",
                   help="run every physics run on its own (default: the runs from one start "
                   "in one world simulate the gait cycles they share once; same numbers)")
    p.add_argument("--out", type=Path, required=True)
    a = p.parse_args(argv)

    def interrupted() -> Interrupted:
        return Interrupted(
            f"the finished physics runs in {a.out / 'matrix'}", command_line(PROG, argv)
        )

    return run_command(PROG, lambda: _measure(p, a), interrupted)


def _measure(p: argparse.ArgumentParser, a: argparse.Namespace) -> int:
    envelope, table = load_envelope(a.envelope), load_table(a.table)
    if a.per_population < 0 or (a.per_population == 0 and not a.bests):
        p.error("--per-population must be ≥ 1, or 0 with --bests (the bests alone)")
    if a.tune and a.per_population == 0:
        p.error("--tune scores the top-20 % sample: give --per-population ≥ 1")
    check_workers(a.workers)
    reuse = [] if a.reuse is None else [a.reuse / "matrix"]
    check_reuse(reuse, a.out / "matrix", RobustnessSettings())  # before anything is written
    executor = None if a.executor is None else make_executor(a.executor, a.workers)
    if isinstance(executor, RayExecutor):
        executor.connect()  # a cluster that cannot be joined stops here, exit 2
    samples = {"top20": top_genomes(a.run, a.per_population)} if a.per_population else {}
    if a.bests:
        samples["generation_bests"] = generation_bests(a.run)
    genomes = [g for s in samples.values() for g in s]
    for g in genomes:
        f = a.out / "genomes" / f"{g.label}.txt"
        f.parent.mkdir(parents=True, exist_ok=True)
        f.write_text(format_chromosome(g.bits) + "\n")
    # Physics runs once per behaviour: genomes equal in their expressed bits run alike.
    first: dict[bytes, str] = {}
    runs_as = [first.setdefault(expressed(g.bits).tobytes(), g.label) for g in genomes]
    reps = list(first.values())
    settings = RobustnessSettings(
        worlds=WORLDS, starts=a.starts, steps=a.steps, seed=a.seed, table=a.table
    )
    matrix = a.out / "matrix"
    bar = RunBar("physics", total=len(reps) * len(WORLDS) * a.starts)
    doc = run_matrix([a.out / "genomes" / f"{r}.txt" for r in reps], matrix, settings,
                     executor=executor, workers=a.workers,
                     resume=(matrix / "settings.json").exists(),
                     reuse=reuse, share=not a.no_share,
                     on_run=bar, on_skip=bar.advance)  # fmt: skip
    bar.close()
    starts = np.asarray(doc["start_poses"]["coverage"], dtype=float)
    names = [Path(c["file"]).stem for c in doc["table_per_chromosome"]]
    if names != reps:
        raise RankingError(f"{matrix}: holds other genomes than this sample; use another --out")
    cells = {w: cell_runs(matrix, w, runs_as) for w in WORLDS}
    phys_all = {w: inner_squares(c, a.starts, "physics") for w, c in cells.items()}
    ends_all = {w: end_shares(c, "physics") for w, c in cells.items()}
    out: dict[str, Any] = {"run": str(a.run), "envelope_name": a.envelope,
                           "envelope": envelope.to_dict(), "genomes": len(genomes),
                           "behaviours": len(reps), "starts": a.starts,
                           "runs_as": {g.label: r for g, r in zip(genomes, runs_as, strict=True)
                                       if g.label != r},
                           "agreement": {}}  # fmt: skip
    offset = 0
    for sample, gs in samples.items():
        rows = slice(offset, offset + len(gs))
        offset += len(gs)
        phys = {w: v[rows] for w, v in phys_all.items()}
        own_runs = table_evaluations(gs, starts, table=table, envelope=envelope, seed=a.seed,
                                     draws=a.draws, steps=a.steps)  # fmt: skip
        own = mean_inner_squares(own_runs)
        exact = own if envelope == NONE else table_runs(gs, starts, table=table, steps=a.steps)
        varied = DEFAULT if envelope == NONE else envelope
        matched = {w: table_runs(gs, starts, table=table, envelope=seen(envelope, w != WORLDS[0]),
                                 seed=a.seed, draws=a.draws, steps=a.steps)
                   for w in WORLDS}  # fmt: skip
        groups = groups_of([g.label for g in gs])
        out.setdefault("by_population", {})[sample] = {
            w: population_agreement(own, phys[w], groups) for w in WORLDS
        }
        own_ends = table_end_shares(own_runs)
        out.setdefault("ends", {})[sample] = {
            w: end_agreement(own_ends, ends_all[w][rows], groups) for w in WORLDS
        }
        out["agreement"][sample] = {
            "own world": {w: agreement(own, phys[w]) for w in WORLDS},
            "exact world": {w: agreement(exact, phys[w]) for w in WORLDS},
            "matched world": {w: agreement(matched[w], phys[w]) for w in WORLDS},
            "ceiling": {w: noise_ceiling(gs, starts, table=table, seed=a.seed, draws=a.draws,
                                         envelope=seen(varied, w != WORLDS[0]), steps=a.steps)
                        for w in WORLDS},
        }  # fmt: skip
    if a.tune:
        top = samples["top20"]
        phys = {w: v[: len(top)] for w, v in phys_all.items()}
        out["tune"] = tune(top, starts, table, phys, a.seed, a.draws, a.steps)
        aspects = dataclasses.replace(DEFAULT, **TRAINING_DEFAULTS).to_dict()
        out["default_rank"] = next(  # None: `default` is not on the grid
            (i for i, r in enumerate(out["tune"]) if r["envelope"] == aspects), None
        )
    write_report(a.out, "ranking", out, _markdown(out))
    return 0


if __name__ == "__main__":
    sys.exit(main())
