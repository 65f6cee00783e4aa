"""How test matrices' coverage runs end in physics, and what each end costs, per world (issue 16):
``python -m servobot.robustness.ends MATRIX... [--only NAME] [--out DIR]``.

A world's physics coverage falls short of ``shipped`` in two ways: runs that last the 600 steps
cover less (reach: shorter strides, ``python -m servobot.robustness.reach``), or more runs end
early, the store empty or the robot in the kill zone. This splits every physics coverage run
of the MATRIX folders (finished ``servobot robustness`` folders, their
``runs/WORLD/NAME/report.json``; several pool, e.g. one chromosome's starts of several seeds)
by how it ended, and reports per world: the runs, their mean inner %, the runs that lasted the
step limit (count, inner %, docks), the others (count by end, inner %, docks, steps), what the
early ends cost the world: the step-limit runs' mean inner % less the world's. The step-limit
runs' mean is what the world would cover had every run lasted (a navigation section that docked
every hand-off); what is left between it and ``shipped``'s is the reach. How sure each figure
is: the standard error of the world's mean over its runs, and its drop below ``shipped`` paired
over the runs both worlds made (the same matrix, chromosome and start) with its standard error.
``--only NAME`` keeps the chromosomes whose name holds NAME. Writes ``DIR/ends.json`` and
``DIR/ends.md`` (DIR defaults to the first MATRIX) and prints the Markdown. Exit 0, or 2 naming
what is missing.

Runs validated since the forty-fifth session record their hand-offs (``evolve.handoff``: each
switch from coverage to navigation and how it came out); for them each world also reports the
hand-offs docked (docked / (docked + failed), as ``evolve.handoff.handoff_rate``) and how many
early ends came during an approach (the navigation section failed) rather than while covering.
"""

from __future__ import annotations

import argparse
from collections import Counter
from pathlib import Path
from typing import Any

import numpy as np
from scipy import stats

from evolve.handoff import CUT, DOCKED, Handoff, handoff_rate
from evolve.interpreter import END_NAMES, END_STEP_LIMIT
from infra.command import Interrupted, run_command
from infra.errors import InputError
from infra.io import write_report
from servobot.robustness.floor import read_matrix
from servobot.robustness.matrix import RUNS_DIR
from servobot.robustness.measure import cell_report
from servobot.robustness.worlds import SHIPPED
from servobot.validation.lone import NAVIGATION_MODE

PROG = "python -m servobot.robustness.ends"
STEP_LIMIT = END_NAMES[END_STEP_LIMIT]


def runs_by_world(matrices: list[Path], only: str = "") -> dict[str, list[dict[str, Any]]]:
    """Per world (in the first matrix's order, then any new ones), the physics outcome of every
    finished coverage run of ``matrices`` whose chromosome name holds ``only``: ``end`` (its
    name), ``inner`` (% of the world's inner squares), ``docks``, ``steps``, ``handoffs`` and
    ``key`` (matrix, chromosome, run), the same for one start in every world."""
    out: dict[str, list[dict[str, Any]]] = {}
    for matrix in matrices:
        doc, _ = read_matrix(matrix)
        for world in doc["worlds"]:
            runs = out.setdefault(world["name"], [])
            for c in world["per_chromosome"]:
                if c["mode"] == NAVIGATION_MODE or only not in c["name"]:
                    continue
                report = cell_report(matrix, world["name"], c["name"])
                try:
                    runs += _cell_runs(report, (str(matrix), c["name"]))
                except (KeyError, TypeError, ZeroDivisionError) as exc:
                    path = matrix / RUNS_DIR / world["name"] / c["name"] / "report.json"
                    raise InputError(f"{path}: not a matrix cell report ({exc!r})") from exc
    out = {w: runs for w, runs in out.items() if runs}
    if not out:
        raise InputError(f"{', '.join(map(str, matrices))}: no physics coverage run"
                         + (f" of a chromosome named *{only}*" if only else ""))  # fmt: skip
    return out


def _cell_runs(report: dict[str, Any], cell: tuple[str, str]) -> list[dict[str, Any]]:
    """The finished physics runs of one matrix cell's ``report.json`` (``runs_by_world``' rows),
    each keyed by ``cell`` (matrix, chromosome) and its place in the cell."""
    total = report["summary"]["inner_squares_total"]
    done = [(i, run["physics"]) for i, run in enumerate(report["runs"])
            if run["error"] is None and run["physics"] is not None]  # fmt: skip
    return [{"end": p["end"]["name"], "inner": 100.0 * p["inner_squares"] / total,
             "docks": p["docks"], "steps": p["steps"], "handoffs": p.get("handoffs"),
             "key": (*cell, i)}
            for i, p in done]  # fmt: skip


def _mean(values: list[float]) -> float | None:
    return float(np.mean(values)) if values else None


def _se(values: list[float]) -> float | None:
    """The standard error of the mean of ``values`` (None below two)."""
    return float(stats.sem(values)) if len(values) > 1 else None


def paired_drop(
    reference: list[dict[str, Any]], runs: list[dict[str, Any]]
) -> dict[str, Any] | None:
    """The reference world's inner % less this world's over the runs both made (same ``key``):
    ``pairs``, ``mean`` (pp, positive = this world covers less) and its standard error ``se``
    (None below two pairs). None when no run pairs."""
    ref = {r["key"]: r["inner"] for r in reference}
    diffs = [ref[r["key"]] - r["inner"] for r in runs if r["key"] in ref]
    if not diffs:
        return None
    return {"pairs": len(diffs), "mean": float(np.mean(diffs)), "se": _se(diffs)}


def approaches(runs: list[dict[str, Any]]) -> dict[str, Any] | None:
    """The hand-offs of the ``runs`` that recorded theirs (``servobot validate`` since the
    forty-fifth session), pooled: ``runs`` (how many recorded), ``evolve.handoff.handoff_rate``'s
    counts and ``dock_rate``, and ``early_in_approach``: the runs that ended early with an
    approach open (the navigation section failed; the others ended while covering). None when
    no run recorded its hand-offs."""
    known = [r for r in runs if r.get("handoffs") is not None]
    if not known:
        return None
    rate = handoff_rate(Handoff(tuple(h["pose"]), h["power"], h["step"], h["outcome"])
                        for r in known for h in r["handoffs"])  # fmt: skip
    failed = [r for r in known if r["end"] != STEP_LIMIT and r["handoffs"]
              and r["handoffs"][-1]["outcome"] not in (DOCKED, CUT)]  # fmt: skip
    return {"runs": len(known), **rate, "early_in_approach": len(failed)}


def split_by_end(runs: list[dict[str, Any]]) -> dict[str, Any]:
    """A world's runs split into those that lasted the step limit and the others (early ends,
    counted by kind), with ``early_cost``: the step-limit runs' mean inner % less all runs'
    (pp; None when no run lasted), and the runs' hand-offs (``approaches``)."""
    full = [r for r in runs if r["end"] == STEP_LIMIT]
    early = [r for r in runs if r["end"] != STEP_LIMIT]

    def means(rs: list[dict[str, Any]], keys: tuple[str, ...]) -> dict[str, Any]:
        return {"runs": len(rs), **{k: _mean([r[k] for r in rs]) for k in keys}}

    whole, lasted = means(runs, ("inner",)), means(full, ("inner", "docks"))
    return {
        **whole,
        "inner_se": _se([r["inner"] for r in runs]),
        "step_limit": lasted,
        "early": {**means(early, ("inner", "docks", "steps")),
                  "by_end": dict(sorted(Counter(r["end"] for r in early).items()))},
        "early_cost": None if lasted["inner"] is None else lasted["inner"] - whole["inner"],
        "handoffs": approaches(runs),
    }  # fmt: skip


def matrix_ends(matrices: list[Path], only: str = "") -> dict[str, Any]:
    """The record ``ends.json``: the matrices read, the name filter and each world's split, with
    its ``drop`` below ``shipped`` (``paired_drop``; None for ``shipped`` or without it)."""
    runs = runs_by_world(matrices, only)
    ref = runs.get(SHIPPED)
    return {"matrices": [str(m) for m in matrices], "only": only,
            "worlds": [{"world": w, **split_by_end(r),
                        "drop": None if ref is None or w == SHIPPED else paired_drop(ref, r)}
                       for w, r in runs.items()]}  # fmt: skip


def _f(v: float | None, digits: int = 1) -> str:
    return "—" if v is None else f"{v:.{digits}f}"


def _drop_cell(drop: dict[str, Any] | None) -> str:
    if drop is None:
        return "—"
    se = "" if drop["se"] is None else f" ± {drop['se']:.1f}"
    return f"{drop['mean']:.1f}{se} ({drop['pairs']})"


def _approach_cells(a: dict[str, Any] | None, runs: int) -> str:
    """The two hand-off cells of a world's row; the runs that recorded them named when not all."""
    if a is None:
        return "— | —"
    rate = "—" if a["dock_rate"] is None else f"{100 * a['dock_rate']:.1f} %"
    some = "" if a["runs"] == runs else f" ({a['runs']} runs recorded them)"
    return f"{a['docked']} of {a['docked'] + a['failed']}, {rate}{some} | {a['early_in_approach']}"


def markdown(doc: dict[str, Any]) -> str:
    """One row per world: runs, inner %, the step-limit runs, the early ends, their cost."""
    which = f" of the chromosomes named *{doc['only']}*" if doc["only"] else ""
    lines = [f"Physics coverage runs{which} by how they end (`{'`, `'.join(doc['matrices'])}`): "
             "inner % of the inner squares, mean over the runs.", "",
             "| world | runs | inner % | lasted the step limit: runs, inner %, docks "
             "| ended early: runs (by end), inner %, docks, steps | early ends cost, pp "
             "| hand-offs docked (of those that finished) | early ends during an approach "
             f"| inner % s.e. | drop below `{SHIPPED}`, pp ± s.e. (paired runs) |",
             "|---|---|---|---|---|---|---|---|---|---|"]  # fmt: skip
    for w in doc["worlds"]:
        s, e = w["step_limit"], w["early"]
        kinds = ", ".join(f"{k} {n}" for k, n in e["by_end"].items())
        early = f"{e['runs']}{f' ({kinds})' if kinds else ''}"
        lines.append(f"| {w['world']} | {w['runs']} | {_f(w['inner'])} "
                     f"| {s['runs']}, {_f(s['inner'])}, {_f(s['docks'])} "
                     f"| {early}, {_f(e['inner'])}, {_f(e['docks'])}, {_f(e['steps'], 0)} "
                     f"| {_f(w['early_cost'])} "
                     f"| {_approach_cells(w['handoffs'], w['runs'])} "
                     f"| {_f(w['inner_se'])} | {_drop_cell(w['drop'])} |")  # fmt: skip
    return "\n".join(lines) + "\n"


def main(argv: list[str] | None = None) -> int:
    """Split, write and print; exit 0 or 2 (module docstring)."""
    ap = argparse.ArgumentParser(prog=PROG, description=__doc__.splitlines()[0])
    ap.add_argument("matrices", type=Path, nargs="+", metavar="MATRIX",
                    help="finished servobot robustness folders, pooled")  # fmt: skip
    ap.add_argument("--only", default="", metavar="NAME",
                    help="keep the chromosomes whose name holds NAME (default: all)")  # fmt: skip
    ap.add_argument("--out", type=Path, default=None, metavar="DIR",
                    help="where ends.{json,md} go (default the first MATRIX)")  # fmt: skip
    a = ap.parse_args(argv)

    def body() -> int:
        doc = matrix_ends(a.matrices, a.only)
        write_report(a.out or a.matrices[0], "ends", doc, markdown(doc))
        return 0

    return run_command(PROG, body, lambda: Interrupted("the files written so far", PROG))


if __name__ == "__main__":
    raise SystemExit(main())
