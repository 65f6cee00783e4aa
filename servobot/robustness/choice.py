"""Choosing each population's finalist by physics: does a physics check of a population's best
genomes pick a controller that does better in physics than the GA's choice? And how do the
physics runs end, against the table's (issue 16)?

    python -m servobot.robustness.choice MATRIX [--selection-worlds shipped station-seen]
        [--candidates 3 6 12] [--out runs/choice]

MATRIX is a finished ``servobot robustness`` folder whose chromosomes are named
``p{k}g{generation}r{rank}`` (``python -m servobot.robustness.measure``: population k's
genomes in the GA's rank order). Its starts are split into two halves (even and odd indices).
On one half, each population's finalist is chosen among its K best-ranked genomes three ways:
by physics (the mean inner squares over ``--selection-worlds``), by the table (the matrix's
table side, the exact world, on the same starts) and by the GA (rank 0, no check); each choice
is scored in physics on the other half, in every world. The halves take turns and the
populations are averaged, beside the mean of all K candidates. A physics choice worth its
runs beats the GA's on the held-out half. Writes ``OUT/choice.json`` and ``OUT/choice.md``.
"""

from __future__ import annotations

import argparse
import re
import sys
from collections import Counter
from pathlib import Path
from typing import Any

import numpy as np

from evolve.settings import WorldSettings
from servobot.robustness.floor import FloorError, read_matrix, report_main
from servobot.robustness.measure import cell_runs, inner_squares

PROG = "python -m servobot.robustness.choice"
NAME = re.compile(r"^p(\d+)g(\d+)r(\d+)$")
"""A sampled genome's label: population, generation, rank in the GA's order."""
CHOOSERS = ("physics", "table", "ga")
"""How a population's finalist is chosen (module docstring)."""


def held_out_choice(
    physics: dict[str, np.ndarray], table: np.ndarray, populations: list[list[int]], k: int,
    selection_worlds: list[str],
) -> dict[str, dict[str, float]]:  # fmt: skip
    """Per chooser of ``CHOOSERS`` and ``"candidates"`` (their mean): the held-out physics
    inner squares of the chosen genome, per world, averaged over both halves and the
    populations. ``physics[w]`` and ``table`` are (G, S) inner squares per run; each entry of
    ``populations`` lists a population's row indices, best-ranked first."""
    starts = table.shape[1]
    out = {c: {w: [] for w in physics} for c in (*CHOOSERS, "candidates")}
    for half in (0, 1):
        pick = np.arange(starts) % 2 == half
        for rows in populations:
            cand = np.asarray(rows[:k])
            by_physics = np.mean([physics[w][cand][:, pick].mean(axis=1) for w in
                                  selection_worlds], axis=0)  # fmt: skip
            chosen = {"physics": cand[int(np.argmax(by_physics))],
                      "table": cand[int(np.argmax(table[cand][:, pick].mean(axis=1)))],
                      "ga": cand[0]}  # fmt: skip
            for w, runs in physics.items():
                for c, g in chosen.items():
                    out[c][w].append(runs[g, ~pick].mean())
                out["candidates"][w].append(runs[cand][:, ~pick].mean())
    return {c: {w: float(np.mean(v)) for w, v in ws.items()} for c, ws in out.items()}


def ends(runs: list[list[dict[str, Any]]]) -> dict[str, Any]:
    """How the runs of one world end, physics against the table on the same starts: counts
    of each end, and docks per run."""
    flat = [r for cell in runs for r in cell if r["physics"] is not None]
    side = {s: Counter(r[s]["end"]["name"] for r in flat) for s in ("physics", "table")}
    docks = {s: float(np.mean([r[s]["docks"] for r in flat])) for s in ("physics", "table")}
    return {"runs": len(flat), "physics": dict(side["physics"]), "table": dict(side["table"]),
            "docks_per_run": docks}  # fmt: skip


def choice_report(
    matrix: Path, candidates: list[int], selection_worlds: list[str]
) -> dict[str, Any]:
    """``held_out_choice`` for each K of ``candidates``, and ``ends`` per world, of
    ``matrix`` (``FloorError`` naming what does not fit)."""
    doc, _ = read_matrix(matrix)
    worlds = [w["name"] for w in doc["worlds"]]
    missing = [w for w in selection_worlds if w not in worlds]
    if missing:
        raise FloorError(f"{matrix}: no world {', '.join(missing)} (it has {', '.join(worlds)})")
    folder = matrix / "runs" / worlds[0]
    names = sorted(p.name for p in folder.iterdir() if NAME.match(p.name))
    if not names:
        raise FloorError(
            f"{matrix}: no chromosome named p{{k}}g{{generation}}r{{rank}} in {folder} (a "
            "matrix of `python -m servobot.robustness.measure`)"
        )
    if doc["starts"] < 2:
        raise FloorError(f"{matrix}: {doc['starts']} start; two halves need at least 2")
    keys = [tuple(int(v) for v in NAME.match(n).groups()) for n in names]  # type: ignore[union-attr]
    order = sorted(range(len(names)), key=lambda i: (keys[i][0], keys[i][2]))
    populations: dict[int, list[int]] = {}
    for i in order:
        populations.setdefault(keys[i][0], []).append(i)
    reports = {w: cell_runs(matrix, w, names) for w in worlds}
    percent = 100.0 / WorldSettings().inner_square_count
    physics = {w: inner_squares(reports[w], doc["starts"], "physics") * percent for w in worlds}
    table = inner_squares(reports[worlds[0]], doc["starts"], "table") * percent
    by_k = {k: held_out_choice(physics, table, list(populations.values()), k, selection_worlds)
            for k in candidates}  # fmt: skip
    return {"matrix": str(matrix), "starts": doc["starts"], "genomes": len(names),
            "populations": len(populations), "selection_worlds": selection_worlds,
            "by_candidates": by_k, "ends": {w: ends(reports[w]) for w in worlds}}  # fmt: skip


def _markdown(doc: dict[str, Any]) -> str:
    worlds = list(doc["ends"])
    lines = [f"# Choosing the finalist by physics: {doc['matrix']}", "",
             f"{doc['genomes']} genomes of {doc['populations']} populations, {doc['starts']} "
             f"starts in two halves; chosen on one by physics in "
             f"{' + '.join(doc['selection_worlds'])}, scored on the other. Physics inner "
             "coverage (%) of the chosen genome on the held-out half:", "",
             "| K | " + " | ".join(f"{c}: {' / '.join(worlds)}" for c in
                                    (*CHOOSERS, "candidates")) + " |",
             "|---|" + "---|" * (len(CHOOSERS) + 1)]  # fmt: skip
    for k, row in doc["by_candidates"].items():
        cells = [" / ".join(f"{row[c][w]:.1f}" for w in worlds) for c in (*CHOOSERS, "candidates")]
        lines.append(f"| {k} | " + " | ".join(cells) + " |")
    lines += ["", "How the runs end (physics against the table on the same starts):", "",
              "| world | runs | physics ends | table ends | docks per run: physics / table |",
              "|---|---|---|---|---|"]  # fmt: skip
    for w, e in doc["ends"].items():
        fmt = lambda c: ", ".join(f"{n} {v}" for n, v in sorted(c.items()))  # noqa: E731
        lines.append(f"| {w} | {e['runs']} | {fmt(e['physics'])} | {fmt(e['table'])} | "
                     f"{e['docks_per_run']['physics']:.2f} / {e['docks_per_run']['table']:.2f} |")
    return "\n".join(lines) + "\n"


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(PROG, description=__doc__,
                                formatter_class=argparse.RawDescriptionHelpFormatter)  # fmt: skip
    p.add_argument("matrix", type=Path, help="a finished `servobot robustness` folder")
    p.add_argument("--selection-worlds", nargs="+", default=["shipped", "station-seen"],
                   help="worlds whose physics runs choose (shipped station-seen)")  # fmt: skip
    p.add_argument("--candidates", type=int, nargs="+", default=[3, 6, 12],
                   help="K: a population's best-ranked genomes to choose from (3 6 12)")
    p.add_argument("--out", type=Path, default=Path("runs/choice"))
    a = p.parse_args(argv)
    if min(a.candidates) < 1:
        p.error("--candidates must be ≥ 1")
    return report_main(PROG, a.out, "choice",
                       lambda: choice_report(a.matrix, a.candidates, a.selection_worlds),
                       _markdown)  # fmt: skip


if __name__ == "__main__":
    sys.exit(main())
