"""Colony validations pooled: ``python -m servobot.validation.colony_pool DIR... [--replay
FIELD=VALUE ...]``.

Each DIR is a colony validation (``servobot validate --robots R``: ``DIR/report.json``) or a
folder of them (``DIR/pop{k}/report.json``, as the reproduction's ``colony_validation``). The
runs of every report found are pooled (each finalist's runs weigh alike when every finalist
ran the same starts) and summarised per world over the runs whose physics finished: colony
inner %, docks per robot, robots live at the end per run and each robot's (by its index in the
team), the hand-offs that failed (a robot whose store empties before it docks, % of all
hand-offs: issue 17's lives are lost to these and to the kill zone), and how the robots ended,
in all and at the station (``colony_report.ended_at_station``, recomputed from the final
poses, so reports written before that count existed pool too).

``--replay`` runs every report's colony starts again in the table world (the report's
chromosome, gait table, ``WorldSettings`` and ``ColonySettings`` with the given fields
replaced, e.g. ``contact_yaw_deg=9.3`` or ``blocking=cancel``) and pools those table runs
against the report's physics runs: what a table-world rule would have predicted for the same
colonies (issue 17: which rule makes the table world crowd as physics does). ``--envelope E
--draws N`` replays them in an envelope of variation (SPEC §9), each start N times with the
draws keyed (report seed, draw), the table side pooled over all N × runs; the cycle scatter
takes σ from ``--table`` (the report's gait table file), else the shipped robot's.
"""

from __future__ import annotations

import argparse
import json
import sys
from collections import Counter, defaultdict
from pathlib import Path
from typing import Any

import numpy as np

from evolve.codec import parse_chromosome
from evolve.envelope import NONE, Envelope, load_envelope
from evolve.interpreter import END_NAMES, END_POWER_EMPTY, LIVE_ENDS, run_colony
from evolve.settings import ColonySettings, WorldSettings, settings_from_record
from evolve.table import GaitTable, load_table
from evolve.world import TableColony
from infra.bounds import check_int
from infra.errors import InputError
from servobot.validation.colony import colony_record
from servobot.validation.colony_report import WORLDS, ended_at_station

PROG = "python -m servobot.validation.colony_pool"


def report_files(folder: Path) -> list[Path]:
    """``folder/report.json``, else ``folder/pop*/report.json`` in population order; an
    ``InputError`` naming ``folder`` when it holds neither."""
    own = folder / "report.json"
    if own.is_file():
        return [own]
    found = sorted(folder.glob("pop*/report.json"), key=lambda p: (len(p.parent.name), p))
    if not found:
        raise InputError(f"{folder}: no report.json and no pop*/report.json in it")
    return found


def read_report(path: Path) -> dict[str, Any]:
    """A colony validation's ``report.json``; an ``InputError`` naming ``path`` when it is not
    readable JSON or lacks a field ``pool`` reads."""
    try:
        report = json.loads(path.read_text())
    except (OSError, ValueError) as exc:
        raise InputError(f"{path}: not a readable report ({exc})") from None
    try:
        pool([report])
    except InputError:  # no run with physics: pools as nothing
        pass
    except (KeyError, TypeError, IndexError, ValueError) as exc:
        raise InputError(f"{path}: not a colony validation report (bad or missing field "
                         f"{exc})") from None  # fmt: skip
    return report


def replay(
    report: dict[str, Any], *, envelope: Envelope = NONE, draw: int = 0,
    table: GaitTable | None = None, **changes: Any,
) -> dict[str, Any]:  # fmt: skip
    """``report`` with the table record of every run whose physics finished replaced by the
    same colony start run again in the table world, its ``ColonySettings`` fields ``changes``
    replaced (``InputError`` naming a bad field or value), in ``envelope`` with the draws of
    key (report seed, ``draw``) at the run's index. ``table``: the report's gait table with
    its per-cycle σ for the envelope's scatter (``InputError`` when its values are not the
    report's); None: the report's values, σ the shipped robot's."""
    name = "replay"
    settings = report["settings"]
    world = settings_from_record(WorldSettings, settings["WorldSettings"], name, InputError)
    doc = {**settings["ColonySettings"], **changes}
    colony = settings_from_record(ColonySettings, doc, name, InputError)
    bits = parse_chromosome(report["chromosome"])
    values = np.asarray(report["table"]["values"], dtype=np.float64)
    if table is not None and not np.array_equal(table.values, values):
        raise InputError(f"--table {table.source}: not the gait table the report ran on")
    key = (int(settings.get("seed") or 0), draw)
    runs = []
    for i, run in enumerate(report["runs"]):
        if run.get("table") and run.get("physics"):
            start = np.array([[p["x"], p["y"], p["h"]] for p in run["start"]])
            sim = TableColony(values if table is None else table, start, world, colony,
                              envelope=envelope, envelope_key=key, start=i)  # fmt: skip
            res = run_colony(bits, sim, mode="coverage", settings=world, colony=colony,
                             max_steps=settings["max_steps"])  # fmt: skip
            run = {**run, "table": colony_record(res, 0.0)}
        runs.append(run)
    return {**report, "runs": runs}


def pool(
    reports: list[dict[str, Any]], table_reports: list[dict[str, Any]] | None = None
) -> dict[str, Any]:
    """Per world, over the runs of every colony report whose physics finished: ``runs``,
    ``inner_pct`` (colony inner squares, % of the inner squares), ``docks_per_robot``,
    ``live_per_run``, ``live_by_robot`` (robot i's fraction of runs live at the end, over the
    runs that have a robot i), ``failed_handoffs_pct`` (robots whose store emptied, % of those
    plus all docks: a store empties only in navigation mode, so each such robot is a hand-off
    that never docked), ``robots``, ``ends`` and ``ends_at_station`` (robots by end name);
    ``gap_inner_pp`` = table − physics. ``table_reports`` (replays of ``reports``) give the
    table world's runs in their place."""
    out: dict[str, Any] = {}
    for w in WORLDS:
        inner, docks = [], []
        by_robot: defaultdict[int, list[bool]] = defaultdict(list)
        ends: Counter[str] = Counter()
        at_station: Counter[str] = Counter()
        for rep in table_reports if w == "table" and table_reports is not None else reports:
            world = rep["settings"]["WorldSettings"]
            n_inner, dock = (world["grid_n"] - 2) ** 2, tuple(world["dock_point"])
            for run in rep["runs"]:
                if not (run.get("table") and run.get("physics")):
                    continue
                rec = run[w]
                inner.append(100.0 * rec["colony"]["inner_squares"] / n_inner)
                for i, b in enumerate(rec["robots"]):
                    by_robot[i].append(b["end"]["code"] in LIVE_ENDS)
                    docks.append(b["docks"])
                    ends[b["end"]["name"]] += 1
                    if ended_at_station(b, dock):
                        at_station[b["end"]["name"]] += 1
        if not inner:
            raise InputError("no colony run whose physics finished in the reports given")
        empty = ends[END_NAMES[END_POWER_EMPTY]]
        out[w] = {
            "runs": len(inner), "inner_pct": float(np.mean(inner)),
            "docks_per_robot": float(np.mean(docks)),
            "live_per_run": sum(map(sum, by_robot.values())) / len(inner),
            "live_by_robot": [float(np.mean(by_robot[i])) for i in sorted(by_robot)],
            "failed_handoffs_pct": 100.0 * empty / max(sum(docks) + empty, 1),
            "robots": len(docks), "ends": dict(ends), "ends_at_station": dict(at_station),
        }  # fmt: skip
    out["gap_inner_pp"] = out["table"]["inner_pct"] - out["physics"]["inner_pct"]
    return out


def pool_markdown(pooled: dict[str, Any]) -> str:
    """The pooled summary as a Markdown table: a row per world, ends as % of the robots."""
    names = sorted({e for w in WORLDS for e in pooled[w]["ends"]})
    rows = []
    for w in WORLDS:
        s = pooled[w]
        cells = [f"{100 * s['ends'].get(e, 0) / s['robots']:.0f} % "
                 f"({s['ends_at_station'].get(e, 0)} of {s['ends'].get(e, 0)})"
                 for e in names]  # fmt: skip
        by_robot = " / ".join(f"{v:.2f}" for v in s["live_by_robot"])
        rows.append(f"| {w} | {s['runs']} | {s['inner_pct']:.1f} | {s['docks_per_robot']:.2f} | "
                    f"{s['failed_handoffs_pct']:.1f} | {s['live_per_run']:.2f} | {by_robot} | "
                    f"{' | '.join(cells)} |")  # fmt: skip
    end_cols = " | ".join(f"{e} (at the station)" for e in names)
    head = ("| world | runs | colony inner % | docks / robot | failed hand-offs % | live / run "
            f"| live by robot | {end_cols} |")  # fmt: skip
    return "\n".join([head, "|" + "---|" * (7 + len(names)), *rows,
                      "", f"gap table − physics: {pooled['gap_inner_pp']:+.1f} pp"])  # fmt: skip


def _changes(items: list[str]) -> dict[str, Any]:
    """``FIELD=VALUE`` items as a dict, each value read as JSON, else kept as a string."""
    out = {}
    for item in items:
        field, sep, value = item.partition("=")
        if not sep or not field:
            raise InputError(f"--replay: FIELD=VALUE expected, got {item!r}")
        try:
            out[field] = json.loads(value)
        except ValueError:
            out[field] = value
    return out


def main(argv: list[str] | None = None) -> int:
    """Print the pooled summary; exit 0, or 2 naming a folder or report it cannot use."""
    ap = argparse.ArgumentParser(prog=PROG, description=__doc__.splitlines()[0])
    ap.add_argument("folders", type=Path, nargs="+", metavar="DIR",
                    help="colony validation folders (report.json or pop*/report.json)")
    ap.add_argument("--replay", nargs="+", metavar="FIELD=VALUE", default=None,
                    help="run the table side again with these ColonySettings fields replaced "
                         "(JSON values, e.g. contact_yaw_deg=9.3 blocking='\"cancel\"'; "
                         "a bare word is a string)")  # fmt: skip
    ap.add_argument("--envelope", default=None, metavar="none|default|FILE.json",
                    help="replay the table side in this envelope (SPEC §9)")  # fmt: skip
    ap.add_argument("--draws", type=int, default=1, metavar="N",
                    help="with --envelope: replay each start N times, N draws (1)")  # fmt: skip
    ap.add_argument("--table", default=None, metavar="PATH",
                    help="with --envelope: the reports' gait table file, whose per-cycle σ "
                         "the scatter takes (default: the shipped robot's σ)")  # fmt: skip
    ap.add_argument("--json", action="store_true", help="print the pooled numbers as JSON")
    args = ap.parse_args(argv)
    try:
        check_int(args.draws, "--draws", lo=1)
        if args.envelope is None and (args.draws != 1 or args.table is not None):
            raise InputError("--draws and --table go with --envelope")
        changes = _changes(args.replay or [])
        envelope = NONE if args.envelope is None else load_envelope(args.envelope)
        table = None if args.table is None else load_table(args.table)
        reports = []
        for path in (p for folder in args.folders for p in report_files(folder)):
            reports.append(read_report(path))
        replays = None
        if args.replay is not None or args.envelope is not None:
            replays = [replay(r, envelope=envelope, draw=d, table=table, **changes)
                       for d in range(args.draws) for r in reports]  # fmt: skip
        pooled = pool(reports, replays)
    except InputError as exc:
        print(f"{PROG}: {exc}", file=sys.stderr)
        return 2
    print(json.dumps(pooled, indent=1) if args.json else pool_markdown(pooled))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
