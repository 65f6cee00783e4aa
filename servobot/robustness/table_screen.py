"""A coverage run's final populations screened in the table world across robot tables, the
candidates for the test matrix (issue 16):
``python -m servobot.robustness.table_screen RUN --variants T1,T2,... [--table PATH]
[--envelope E] [--starts N] [--draws D] [--seed S] [--per-population K] [--top N]
[--out DIR]``.

RUN is a finished ``servobot evolve coverage`` folder. Its candidates are every distinct
individual of each population's last saved generation (``RUN/coverage/populations``), with
the run's navigation section. Each is run in the table world under ``--envelope`` from
``--starts`` coverage starts (``default_rng([seed, SCREEN_STREAM])``: not the matrix's), once
with ``--table`` (the robot the run was evolved for) and once with each ``--variants`` table:
a robot variant's calibration (``servobot calibrate --model VARIANT.xml``), never the
held-out world's. A candidate scores its worst table's inner coverage (ties: the mean over
the tables), and each population's ``--per-population`` best are kept (candidates with equal
scores on every table are one behaviour, kept once): one lineage cannot fill the list with
near-copies of one behaviour, and the kept ones stand beside the populations' rank 0, the
GA's finalists; ``--top N`` keeps the N best of those by the same score, for a matrix that
must run fewer.

The table world walks a variant's calibrated table as physics walks the variant
(docs/robustness.md, "The final populations screened across robot tables"), and a GA's final
population holds behaviours that its rank 0 does not: the screen finds them without physics,
and ``servobot robustness DIR/*.txt`` then ``python -m servobot.robustness.matrix_choice``
decide among them in physics. Writes ``DIR/p{k}i{i:03d}.txt`` (population k's
individual i) and ``DIR/screen.json`` (the rule, the tables and each written candidate's and
each population's rank 0's scores) and prints them. Exit 0, or 2 naming what is missing or
malformed.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Any

import numpy as np

from evolve.codec import write_chromosome
from evolve.envelope import key_of_test, load_envelope
from evolve.evaluation import evaluate
from evolve.settings import WorldSettings
from evolve.starts import coverage_starts
from evolve.table import load_table
from infra.command import Interrupted, run_command
from infra.errors import InputError
from infra.io import atomic_write_json, check_output_dir
from servobot.robustness.ranking import _full, final_populations, navigation_of

PROG = "python -m servobot.robustness.table_screen"
PER_POPULATION = 1
"""Distinct behaviours written per population."""
STARTS = 100
"""Table-world coverage starts per candidate and table (the Figure 9 test's number)."""
DRAWS = 2
"""Draws of the envelope per start (keys ``key_of_test(seed, "screen", d)``)."""
SCREEN_STREAM = 16
"""Second word of the screen's start seed, so its starts are not the matrix's
(``default_rng(seed)``)."""


def candidates(run: Path) -> list[dict[str, Any]]:
    """Every distinct coverage section of the final populations, as ``{population,
    generation, index, rank0, bits}`` (bits: the full (16, 30) chromosome); rank 0 is the
    population's best by training fitness."""
    navigation = navigation_of(run)
    seen: dict[bytes, dict[str, Any]] = {}
    for pop, gen, bits, fitness in final_populations(run):
        best = int(np.argmax(fitness))
        for i in np.argsort(-fitness, kind="stable"):
            row = {"population": pop, "generation": gen, "index": int(i),
                   "rank0": int(i) == best, "bits": _full(bits[i], navigation)}  # fmt: skip
            seen.setdefault(bits[i].tobytes(), row)
    return list(seen.values())


def scores(
    bits: np.ndarray, tables: list, envelope, *, starts: int = STARTS, draws: int = DRAWS,
    seed: int = 0,
) -> np.ndarray:  # fmt: skip
    """(G, T) inner coverage, % of the 64, of each chromosome of ``bits`` (G, 16, 30) with each
    table: the mean over ``starts`` coverage starts and ``draws`` draws of ``envelope``."""
    world = WorldSettings()
    poses = coverage_starts(np.random.default_rng([seed, SCREEN_STREAM]), starts, world)
    out = np.zeros((bits.shape[0], len(tables)))
    for t, table in enumerate(tables):
        for d in range(draws):
            ev = evaluate(bits, poses, table=table, mode="coverage", envelope=envelope,
                          envelope_key=key_of_test(seed, "screen", d))  # fmt: skip
            out[:, t] += ev.inner_squares.mean(axis=1)
    return 100.0 * out / (draws * world.inner_square_count)


def ranked(score: np.ndarray) -> list[int]:
    """Row indices of ``score`` (G, T), one per distinct row, by worst table then mean."""
    order = sorted(range(len(score)), key=lambda g: (-score[g].min(), -score[g].mean(), g))
    kept: dict[bytes, int] = {}
    for g in order:
        kept.setdefault(score[g].tobytes(), g)
    return list(kept.values())


def kept(
    rows: list[dict[str, Any]], score: np.ndarray, per_population: int, top: int = 0
) -> list[int]:
    """Each population's ``per_population`` best rows (``ranked``), population by population;
    with ``top`` > 0 only the ``top`` best of them, in that order."""
    order = ranked(score)
    out: list[int] = []
    for pop in sorted({r["population"] for r in rows}):
        out += [g for g in order if rows[g]["population"] == pop][:per_population]
    return [g for g in order if g in out][:top] if top > 0 else out


def screen(run: Path, table: str, variants: list[str], envelope: str, *,
           per_population: int = PER_POPULATION, top: int = 0,
           starts: int = STARTS, draws: int = DRAWS, seed: int = 0) -> dict[str, Any]:  # fmt: skip
    """The screen's record (``screen.json``), its ``written`` rows in order, bits included."""
    names = [table, *variants]
    tables = [load_table(n) for n in names]
    rows = candidates(run)
    score = scores(np.stack([r["bits"] for r in rows]), tables, load_envelope(envelope),
                   starts=starts, draws=draws, seed=seed)  # fmt: skip

    def entry(g: int) -> dict[str, Any]:
        r = rows[g]
        return {**r, "name": f"p{r['population']}i{r['index']:03d}",
                "inner_percent": dict(zip(names, score[g].round(3).tolist(), strict=True)),
                "worst": float(score[g].min()), "mean": float(score[g].mean())}  # fmt: skip

    return {"run": str(run), "tables": names, "envelope": envelope, "starts": starts,
            "draws": draws, "seed": seed, "candidates": len(rows),
            "behaviours": len(ranked(score)),
            "written": [entry(g) for g in kept(rows, score, per_population, top)],
            "rank0": [entry(g) for g, r in enumerate(rows) if r["rank0"]]}  # fmt: skip


def markdown(doc: dict[str, Any]) -> str:
    """The written candidates and the populations' rank 0, inner % per table."""
    head = ["candidate", *(Path(t).parent.name or t for t in doc["tables"]), "worst", "mean"]
    lines = [f"{doc['candidates']} distinct candidates, {doc['behaviours']} behaviours, "
             f"{doc['starts']} starts × {doc['draws']} draws of {doc['envelope']}:", "",
             "| " + " | ".join(head) + " |", "|" + "---|" * len(head)]  # fmt: skip
    for label, rows in (("", doc["written"]), (" (rank 0)", doc["rank0"])):
        for r in rows:
            cells = [f"{v:.1f}" for v in r["inner_percent"].values()]
            lines.append(f"| {r['name']}{label} | " + " | ".join(cells)
                         + f" | {r['worst']:.1f} | {r['mean']:.1f} |")  # fmt: skip
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    """Screen, write the candidates and print them; exit 0 or 2 (module docstring)."""
    ap = argparse.ArgumentParser(prog=PROG, description=__doc__.splitlines()[0])
    ap.add_argument("run", type=Path, metavar="RUN", help="a servobot evolve coverage folder")
    ap.add_argument("--variants", required=True, metavar="T1,T2,...",
                    help="comma-separated calibration files of robot variants")  # fmt: skip
    ap.add_argument("--table", default="paper",
                    help="the gait table RUN was evolved on (default: the paper's)")  # fmt: skip
    ap.add_argument("--envelope", default="default",
                    help="the table world's envelope: none, default or FILE.json (default "
                         "default)")  # fmt: skip
    ap.add_argument("--starts", type=int, default=STARTS, metavar="N",
                    help=f"coverage starts per candidate and table (default {STARTS})")  # fmt: skip
    ap.add_argument("--draws", type=int, default=DRAWS, metavar="D",
                    help=f"draws of the envelope per start (default {DRAWS})")  # fmt: skip
    ap.add_argument("--seed", type=int, default=0, help="seed of the starts and draws (default 0)")
    ap.add_argument("--per-population", type=int, default=PER_POPULATION, metavar="K",
                    help=f"distinct behaviours written per population (default "
                         f"{PER_POPULATION})")  # fmt: skip
    ap.add_argument("--top", type=int, default=0, metavar="N",
                    help="keep only the N best of those, by their worst table (default 0: "
                         "all)")  # fmt: skip
    ap.add_argument("--out", type=Path, default=None, metavar="DIR",
                    help="output folder (default RUN/screen)")  # fmt: skip
    a = ap.parse_args(argv)

    def body() -> int:
        if a.top < 0:
            raise InputError(f"--top must be ≥ 0 (0: all), got {a.top}")
        for name in ("per_population", "starts", "draws"):
            if getattr(a, name) < 1:
                raise InputError(f"--{name.replace('_', '-')} must be ≥ 1, got "
                                 f"{getattr(a, name)}")  # fmt: skip
        variants = [v for v in a.variants.split(",") if v]
        if not variants:
            raise InputError("--variants names no calibration file")
        if len({a.table, *variants}) < 1 + len(variants):
            raise InputError("a gait table is named twice (--table and --variants)")
        out = check_output_dir(a.out or a.run / "screen")
        if (out / "screen.json").exists():
            raise InputError(f"{out} already holds a screen (screen.json): its candidate files "
                             "would mix with this one's; choose another --out")  # fmt: skip
        doc = screen(a.run, a.table, variants, a.envelope, per_population=a.per_population,
                     top=a.top, starts=a.starts, draws=a.draws, seed=a.seed)  # fmt: skip
        for r in doc["written"]:
            header = (f"{a.run} population {r['population']} generation {r['generation']} "
                      f"individual {r['index']}: table-world inner % "
                      + ", ".join(f"{v:.1f}" for v in r["inner_percent"].values()))  # fmt: skip
            r["file"] = str(write_chromosome(out / f"{r['name']}.txt", r["bits"], header))
        for r in doc["written"] + doc["rank0"]:
            del r["bits"]
        atomic_write_json(out / "screen.json", doc)
        print(markdown(doc))
        return 0

    return run_command(PROG, body, lambda: Interrupted("the files written so far", PROG))


if __name__ == "__main__":
    sys.exit(main())
