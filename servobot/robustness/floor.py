"""How closely can any table world predict one physics run? The noise floor of issue 16's
agreement measures (Spearman of the controllers' mean fitness, mean per-run |Δ inner squares|).

    servobot robustness CHROMOSOME... --worlds shipped,station-seen --starts N --seed S --out A
    servobot robustness CHROMOSOME... --worlds shipped,station-seen --starts N --seed S \\
        --noise-seed T --out B
    python -m servobot.robustness.floor A B [--table PATH] [--envelope default]
        [--draws 16] [--realisations 4] [--out runs/floor]

A and B hold the same coverage chromosomes run from the same start poses in the same physics
worlds, under two draws of the servo noise. Per world, the two physics runs of each
(chromosome, start) are compared as a table world would be: physics predicting itself. A
predictor that knew each start's mean physics outcome would still miss a run by
E|A − B| / √2, were the runs normal about that mean: the floor of the mean per-run |Δ|.
Beside it, the table side of the same bound: the envelope's prediction (its mean over
``--draws`` draws per start) against one draw of it (``ranking.noise_ceiling``; the block
seen in ``station-seen``, unseen elsewhere). Writes ``OUT/floor.json`` and ``OUT/floor.md``.

Units: inner squares reached of the 64 (SPEC §5 test), per run or a chromosome's mean.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from evolve.codec import FULL_GENES, parse_chromosome
from evolve.envelope import load_envelope
from evolve.table import load_table
from infra.errors import InputError
from infra.io import write_report
from servobot.robustness.measure import physics_runs
from servobot.robustness.ranking import Genome, agreement, noise_ceiling, seen

PROG = "python -m servobot.robustness.floor"
SEEN_WORLDS = ("station-seen",)
"""Physics worlds whose station block the rangefinders see (the envelope's block always seen)."""


class FloorError(InputError, ValueError):
    """Two matrices that are not the same runs under another noise draw; the message says why."""


def read_matrix(folder: Path) -> tuple[dict[str, Any], dict[str, Any]]:
    """(robustness.json, settings.json) of a finished ``servobot robustness`` folder."""
    try:
        doc = json.loads((folder / "robustness.json").read_text())
        record = json.loads((folder / "settings.json").read_text())
    except (OSError, ValueError) as exc:
        raise FloorError(f"{folder}: not a finished `servobot robustness` folder ({exc})") from exc
    return doc, record


def _noise_seed(doc: dict[str, Any]) -> int:
    return doc.get("noise_seed", doc["seed"])


def coverage_genomes(record: dict[str, Any]) -> list[Genome]:
    """The matrix's 16-gene chromosomes, by name (navigation sections have no inner squares)."""
    out = []
    for c in record["controllers"]:
        bits = parse_chromosome(c["chromosome"], name=c["name"])
        if bits.shape[0] == FULL_GENES:
            out.append(Genome(c["name"], bits))
    return out


def physics_floor(a: Path, b: Path) -> tuple[dict[str, dict[str, float]], list[Genome], np.ndarray]:
    """Per world both matrices ran: ``agreement`` of A's physics runs (as the prediction)
    with B's, run by run, and ``best_abs_delta``: the mean |Δ| per run of a predictor that
    knew each start's mean physics outcome, were the runs normal about it (E|A − B| / √2);
    with the coverage genomes and their start poses. ``FloorError`` when
    the two are not the same chromosomes, starts and steps under different servo noise."""
    (doc_a, rec_a), (doc_b, rec_b) = read_matrix(a), read_matrix(b)
    for key in ("starts", "steps", "start_poses"):
        if doc_a[key] != doc_b[key]:
            raise FloorError(f"{a} and {b} differ in {key}: the floor needs the same runs")
    if rec_a["controllers"] != rec_b["controllers"]:
        raise FloorError(f"{a} and {b} hold different chromosomes")
    if _noise_seed(doc_a) == _noise_seed(doc_b):
        raise FloorError(
            f"{a} and {b} share their servo noise (seed {_noise_seed(doc_a)}): run one with "
            "`servobot robustness --noise-seed`"
        )
    genomes = coverage_genomes(rec_a)
    if not genomes:
        raise FloorError(f"{a}: no 16-gene chromosomes (navigation sections have no coverage)")
    names = [g.label for g in genomes]
    in_b = {w["name"] for w in doc_b["worlds"]}
    worlds = [w["name"] for w in doc_a["worlds"] if w["name"] in in_b]
    per = {}
    for w in worlds:
        pa = physics_runs(a, w, names, doc_a["starts"])
        pb = physics_runs(b, w, names, doc_b["starts"])
        ok = ~(np.isnan(pa) | np.isnan(pb)).any(axis=1)  # a physics error drops its chromosome
        both = agreement(pa[ok], pb[ok])
        per[w] = both | {"chromosomes": int(ok.sum()),
                         "best_abs_delta": both["mean_abs_delta"] / math.sqrt(2.0)}  # fmt: skip
    return per, genomes, np.asarray(doc_a["start_poses"]["coverage"], dtype=np.float64)


def _markdown(doc: dict[str, Any]) -> str:
    lines = [f"# Noise floor: {doc['a']} vs {doc['b']}", "",
             f"{doc['chromosomes']} coverage chromosomes × {doc['starts']} starts; table side: "
             f"envelope {doc['envelope_name']}, {doc['draws']} draws per start against one, "
             f"{doc['realisations']} times", "",
             "| world | physics vs physics: Spearman | mean abs Δ per run | best predictor's "
             "mean abs Δ (normal runs) | envelope vs one draw: Spearman | mean abs Δ per run |",
             "|---|---|---|---|---|---|"]  # fmt: skip
    for w, ph in doc["physics"].items():
        t = doc["table"][w]
        lines.append(f"| {w} | {ph['spearman']:.2f} | {ph['mean_abs_delta']:.1f} | "
                     f"{ph['best_abs_delta']:.1f} | {t['spearman']:.2f} | "
                     f"{t['mean_abs_delta']:.1f} |")  # fmt: skip
    return "\n".join(lines) + "\n"


def table_side_parser(prog: str, doc: str | None, envelope: str) -> argparse.ArgumentParser:
    """A parser with the table side's options of the matrix reports: ``--table``,
    ``--envelope`` (default ``envelope``), ``--draws`` and ``--seed``."""
    fmt = argparse.RawDescriptionHelpFormatter
    p = argparse.ArgumentParser(prog, description=doc, formatter_class=fmt)
    p.add_argument("--table", default="paper", help="gait table of the table side (paper|PATH)")
    p.add_argument("--envelope", default=envelope,
                   help=f"the table world's variation: none|default|FILE ({envelope})")  # fmt: skip
    p.add_argument("--draws", type=int, default=16, help="envelope draws per start (16)")
    p.add_argument("--seed", type=int, default=0, help="seed of the envelope's draws (0)")
    return p


def _parser() -> argparse.ArgumentParser:
    p = table_side_parser(PROG, __doc__, "default")
    p.add_argument("a", type=Path, help="a `servobot robustness` folder")
    p.add_argument("b", type=Path, help="the same runs under another --noise-seed")
    p.add_argument("--realisations", type=int, default=4, help="single draws scored (4)")
    p.add_argument("--out", type=Path, default=Path("runs/floor"))
    return p


def report_main(
    prog: str, out: Path, name: str, make: Callable[[], dict[str, Any]],
    markdown: Callable[[dict[str, Any]], str],
) -> int:  # fmt: skip
    """An analysis command's ending: ``make()`` the report and ``write_report`` it as
    ``out/NAME.json`` and ``out/NAME.md`` (0), or say why it cannot be made (2: an input that
    does not fit, a missing or unreadable file)."""
    try:
        doc = make()
    except (InputError, ValueError, KeyError, OSError) as exc:
        print(f"{prog}: {exc}", file=sys.stderr)
        return 2
    write_report(out, name, doc, markdown(doc))
    return 0


def main(argv: list[str] | None = None) -> int:
    a = _parser().parse_args(argv)

    def make() -> dict[str, Any]:
        envelope, table = load_envelope(a.envelope), load_table(a.table)
        physics, genomes, starts = physics_floor(a.a, a.b)
        return {
            "a": str(a.a), "b": str(a.b), "chromosomes": len(genomes), "starts": len(starts),
            "envelope_name": a.envelope, "envelope": envelope.to_dict(), "draws": a.draws,
            "realisations": a.realisations, "physics": physics,
            "table": {w: noise_ceiling(genomes, starts, table=table,
                                       envelope=seen(envelope, w in SEEN_WORLDS), seed=a.seed,
                                       draws=a.draws, realisations=a.realisations)
                      for w in physics},
        }  # fmt: skip

    return report_main(PROG, a.out, "floor", make, _markdown)


if __name__ == "__main__":
    sys.exit(main())
