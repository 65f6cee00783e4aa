"""Does a controller's behaviour in the table world predict its reality gap? The premise of the
transferability approach (Koos, Mouret & Doncieux 2013; ``servobot anytime --method transfer``),
checked on a physics matrix with many starts per controller.

    python -m servobot.robustness.transfer MATRIX --table PATH [--envelope none|default|FILE]
        [--seed 0] [--draws 16] [--descriptor-starts 4] [--neighbours 1 3 5]
        [--out runs/transfer_check]

MATRIX is a finished ``servobot robustness`` folder (e.g. ``OUT/matrix`` of
``python -m servobot.robustness.measure``). For each coverage chromosome and physics world:
its disparity d = table − physics, the mean inner squares (of 64) over the matrix's starts, the
table side in the arm's own world (``ranking.table_runs``: ``--envelope``, ``--draws`` draws per
start). Its behaviour is ``evolve.anytime.behaviour`` from ``--descriptor-starts`` fixed starts,
the ones method transfer draws at ``--seed``. Controllers are grouped by population (a name
``p{k}g…``, as ``measure`` names them; otherwise each is its own group), and each group's
disparities are predicted from the other groups only: the k nearest behaviours' mean
(``predict_disparity``), beside the other groups' plain mean. A predictor worth feeding back
beats the plain mean and, subtracted from the table fitness, ranks the controllers closer to
physics. Writes ``OUT/transfer.json`` and ``OUT/transfer.md``.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Any

import numpy as np

from evolve.anytime import behaviour, predict_disparity
from evolve.envelope import load_envelope
from evolve.evaluation import evaluate
from evolve.population import stage_rng
from evolve.settings import WorldSettings
from evolve.starts import coverage_starts
from evolve.table import load_table
from servobot.robustness.floor import (
    FloorError,
    coverage_genomes,
    read_matrix,
    report_main,
    table_side_parser,
)
from servobot.robustness.measure import physics_runs
from servobot.robustness.ranking import groups_of, rho, table_runs

PROG = "python -m servobot.robustness.transfer"


def held_out_predictions(
    descriptors: np.ndarray, disparity: np.ndarray, groups: np.ndarray, k: int
) -> tuple[np.ndarray, np.ndarray]:
    """(kNN prediction, plain mean) of each disparity from the other groups only."""
    knn, mean = np.zeros(len(disparity)), np.zeros(len(disparity))
    for g in np.unique(groups):
        mine = groups == g
        if mine.all():
            raise ValueError("one group only: nothing to predict it from")
        knn[mine] = predict_disparity(descriptors[~mine], disparity[~mine], descriptors[mine], k)
        mean[mine] = disparity[~mine].mean()
    return knn, mean


def transfer_check(
    matrix: Path, *, table, envelope, seed: int, draws: int, descriptor_starts: int,
    neighbours: list[int],
) -> dict[str, Any]:  # fmt: skip
    """Per world of ``matrix`` and each k of ``neighbours``: how well behaviour predicts the
    held-out groups' disparities (module docstring)."""
    doc, record = read_matrix(matrix)
    genomes = coverage_genomes(record)
    if len(genomes) < 3:
        raise FloorError(f"{matrix}: {len(genomes)} coverage chromosomes; at least 3 needed")
    names = [g.label for g in genomes]
    groups = groups_of(names)
    if len(np.unique(groups)) < 2:
        raise FloorError(f"{matrix}: all chromosomes are of one population")
    starts = np.asarray(doc["start_poses"]["coverage"], dtype=np.float64)
    own = table_runs(genomes, starts, table=table, envelope=envelope, seed=seed, draws=draws,
                     steps=doc["steps"]).mean(axis=1)  # fmt: skip
    world = WorldSettings()
    probe = coverage_starts(stage_rng(seed, "anytime", 2), descriptor_starts, world)
    bits = np.stack([g.bits for g in genomes])
    ev = evaluate(bits, probe, table=table, mode="coverage", max_steps=doc["steps"])
    descriptors = behaviour(ev, world)
    out: dict[str, Any] = {}
    for w in (w["name"] for w in doc["worlds"]):
        phys = np.nanmean(physics_runs(matrix, w, names, doc["starts"]), axis=1)
        ok = np.isfinite(phys)
        d = own[ok] - phys[ok]
        rows = []
        for k in neighbours:
            knn, mean = held_out_predictions(descriptors[ok], d, groups[ok], k)
            rows.append({
                "neighbours": k,
                "spearman_predicted_vs_disparity": rho(knn, d),
                "mean_abs_error": float(np.abs(knn - d).mean()),
                "mean_abs_error_of_the_mean": float(np.abs(mean - d).mean()),
                "spearman_table_vs_physics": rho(own[ok], phys[ok]),
                "spearman_corrected_vs_physics": rho(own[ok] - knn, phys[ok]),
            })  # fmt: skip
        out[w] = {"chromosomes": int(ok.sum()), "groups": int(len(np.unique(groups[ok]))),
                  "disparity_mean": float(d.mean()), "disparity_std": float(d.std()),
                  "by_neighbours": rows}  # fmt: skip
    return out


def _markdown(doc: dict[str, Any]) -> str:
    lines = [f"# Does behaviour predict the reality gap? {doc['matrix']}", "",
             f"Table side: envelope {doc['envelope_name']} ({doc['draws']} draws per start); "
             f"behaviour from {doc['descriptor_starts']} starts (seed {doc['seed']}); inner "
             "squares of 64; each population predicted from the others.", "",
             "| world | chromosomes (groups) | disparity mean ± std | k | Spearman predicted vs "
             "disparity | mean abs error: kNN / others' mean | Spearman vs physics: table / "
             "table − predicted |", "|---|---|---|---|---|---|---|"]  # fmt: skip
    for w, r in doc["worlds"].items():
        for row in r["by_neighbours"]:
            lines.append(
                f"| {w} | {r['chromosomes']} ({r['groups']}) | {r['disparity_mean']:.1f} ± "
                f"{r['disparity_std']:.1f} | {row['neighbours']} | "
                f"{row['spearman_predicted_vs_disparity']:.2f} | {row['mean_abs_error']:.1f} / "
                f"{row['mean_abs_error_of_the_mean']:.1f} | "
                f"{row['spearman_table_vs_physics']:.2f} / "
                f"{row['spearman_corrected_vs_physics']:.2f} |"
            )
    return "\n".join(lines) + "\n"


def _parser() -> argparse.ArgumentParser:
    p = table_side_parser(PROG, __doc__, "none")
    p.add_argument("matrix", type=Path, help="a finished `servobot robustness` folder")
    p.add_argument("--descriptor-starts", type=int, default=4, help="behaviour starts (4)")
    p.add_argument("--neighbours", type=int, nargs="+", default=[1, 3, 5], help="k (1 3 5)")
    p.add_argument("--out", type=Path, default=Path("runs/transfer_check"))
    return p


def main(argv: list[str] | None = None) -> int:
    p = _parser()
    a = p.parse_args(argv)
    if a.descriptor_starts < 1 or min(a.neighbours) < 1 or a.draws < 1:
        p.error("--descriptor-starts, --neighbours and --draws must be ≥ 1")

    def make() -> dict[str, Any]:
        worlds = transfer_check(
            a.matrix, table=load_table(a.table), envelope=load_envelope(a.envelope), seed=a.seed,
            draws=a.draws, descriptor_starts=a.descriptor_starts, neighbours=a.neighbours,
        )  # fmt: skip
        return {"matrix": str(a.matrix), "envelope_name": a.envelope, "draws": a.draws,
                "seed": a.seed, "descriptor_starts": a.descriptor_starts,
                "worlds": worlds}  # fmt: skip

    return report_main(PROG, a.out, "transfer", make, _markdown)


if __name__ == "__main__":
    sys.exit(main())
