"""The validation report: per-world summaries, the table-vs-physics gap, Markdown and files.

Pure functions over the per-run records that ``servobot.validation.lone.validate`` collects; see
that module for the record layout. A colony's report (``servobot.validation.colony_report``)
shares the frame: ``summarise_runs``, ``summary_markdown``, ``markdown_table`` and the cells.
"""

from __future__ import annotations

import io
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from evolve.interpreter import END_DOCKED
from evolve.settings import WorldSettings
from infra.io import atomic_write, atomic_write_json, atomic_write_text

WORLD_SUMMARIES = (("table (all runs)", "table"), ("table (paired)", "table_paired"),
                   ("physics", "physics"))  # fmt: skip
"""The summary's worlds: (name in Markdown, key): the table world over all runs and over the
runs whose physics finished (paired), physics over those."""
GAP = (("inner_pct_pp", "inner_pct", 1.0), ("squares", "mean_squares", 1.0),
       ("dock_success_pp", "dock_success", 100.0))  # fmt: skip
"""The gap table − physics of a lone robot: (name, key of the world summaries, scale)."""


def count_ends(recs: list[dict[str, Any]]) -> dict[str, int]:
    """How many runs ended how, by end name, in order of first appearance."""
    ends: dict[str, int] = {}
    for r in recs:
        ends[r["end"]["name"]] = ends.get(r["end"]["name"], 0) + 1
    return ends


def _world_summary(recs: list[dict[str, Any]], n_inner: int) -> dict[str, Any]:
    if not recs:
        return {"runs": 0}
    inner = np.array([r["inner_squares"] for r in recs], dtype=float)
    return {
        "runs": len(recs),
        "mean_squares": float(np.mean([r["squares"] for r in recs])),
        "mean_inner_squares": float(inner.mean()),
        "inner_pct": float(100.0 * inner.mean() / n_inner),
        "mean_steps": float(np.mean([r["steps"] for r in recs])),
        "docks_total": int(sum(r["docks"] for r in recs)),
        "dock_success": float(np.mean([r["docks"] > 0 for r in recs])),
        "docked_end": int(sum(r["end"]["code"] == END_DOCKED for r in recs)),
        "ends": count_ends(recs),
        "mean_wall_s": float(np.mean([r["wall_s"] for r in recs])),
    }


def summarise_runs(
    runs: list[dict[str, Any]], world: WorldSettings, wall_s: float,
    world_summary: Callable[[list[dict[str, Any]], int], dict[str, Any]],
    gap: tuple[tuple[str, str, float], ...], inner: Callable[[dict[str, Any]], int],
    **head: Any,
) -> dict[str, Any]:  # fmt: skip
    """Summary of per-run records (one robot's or a colony's): ``world_summary`` of each
    world, and the ``gap`` table − physics over the runs whose physics finished, with the mean
    absolute difference of their ``inner`` squares; ``head`` follows the start count."""
    n_inner = world.inner_square_count
    paired = [r for r in runs if r.get("table") and r.get("physics")]
    t_pair = world_summary([r["table"] for r in paired], n_inner)
    p_pair = world_summary([r["physics"] for r in paired], n_inner)
    diff: dict[str, Any] = {"runs": len(paired)}
    if paired:
        diff.update({name: scale * (t_pair[key] - p_pair[key]) for name, key, scale in gap})
        diff["mean_abs_inner_diff"] = float(
            np.mean(np.abs([inner(r["table"]) - inner(r["physics"]) for r in paired]))
        )
    return {
        "starts": len(runs),
        **head,
        "physics_ok": len(paired),
        "physics_errors": sum(1 for r in runs if r.get("error")),
        "inner_squares_total": n_inner,
        "table": world_summary([r["table"] for r in runs if r.get("table")], n_inner),
        "table_paired": t_pair,
        "physics": p_pair,
        "gap": diff,
        "wall_s": round(wall_s, 3),
    }


def summarise(runs: list[dict[str, Any]], world: WorldSettings, wall_s: float) -> dict[str, Any]:
    """Summary of per-run records: per world, and the gap over runs whose physics finished."""
    return summarise_runs(runs, world, wall_s, _world_summary, GAP, lambda r: r["inner_squares"])


def write_report(
    out: Path, report: dict[str, Any], tracks: dict[str, np.ndarray], markdown: str | None = None
) -> None:
    """Write ``report.json``, ``report.md`` (``markdown``, default ``report_markdown``) and
    ``tracks.npz`` atomically into ``out``."""
    out.mkdir(parents=True, exist_ok=True)

    def write_npz(p: Path) -> None:
        buf = io.BytesIO()
        np.savez_compressed(buf, **tracks)
        p.write_bytes(buf.getvalue())

    atomic_write(out / "tracks.npz", write_npz)
    atomic_write_json(out / "report.json", report)
    atomic_write_text(out / "report.md", report_markdown(report) if markdown is None else markdown)


def robot_cells(rec: dict[str, Any] | None) -> str:
    """One robot's record in one world as five Markdown cells (dashes for none)."""
    if rec is None:
        return "— | — | — | — | —"
    return (
        f"{rec['squares']} | {rec['inner_squares']} | {rec['docks']} | {rec['steps']} | "
        f"{rec['end']['name']}"
    )


def markdown_table(columns: str, rows: list[str]) -> list[str]:
    """A Markdown table: the ``columns`` (``"a | b"``) as its header, then ``rows``."""
    return [f"| {columns} |", "|" + "---|" * (columns.count("|") + 1), *rows]


def inner_delta(table: dict[str, Any] | None, physics: dict[str, Any] | None) -> str:
    """Table minus physics inner squares of one run (a dash unless both worlds finished)."""
    if not (table and physics):
        return "—"
    return f"{table['inner_squares'] - physics['inner_squares']:+d}"


def physics_error(run: dict[str, Any]) -> str:
    """The physics cells of a run whose physics failed."""
    return f"error: {run.get('error')} | | | |"


def pose_cell(start: dict[str, Any]) -> str:
    """A start pose ``{"x", "y", "h"}`` as one Markdown cell."""
    return f"{start['x']:.1f}, {start['y']:.1f}, {start['h']:.1f}"


def run_rows(report: dict[str, Any]) -> list[str]:
    """The per-start Markdown table (also printed by the CLI)."""
    rows = []
    for r in report["runs"]:
        t, p = r.get("table"), r.get("physics")
        phys = robot_cells(p) if p else physics_error(r)
        cells = [pose_cell(r["start"]), robot_cells(t), phys, inner_delta(t, p)]
        rows.append(f"| {r['index']} | {' | '.join(cells)} |")
    columns = ("# | start x, y, h | table sq | inner | docks | steps | end | physics sq | inner "
               "| docks | steps | end | Δ inner")  # fmt: skip
    return markdown_table(columns, rows)


def summary_markdown(
    report: dict[str, Any], first: str, world_line: Callable[[dict[str, Any], dict[str, Any]], str],
    gap_line: Callable[[dict[str, Any]], str],
) -> list[str]:  # fmt: skip
    """A summary as Markdown lines: ``first``, then ``world_line(world summary, summary)`` per
    world in ``WORLD_SUMMARIES`` that has runs, then ``gap_line(gap)`` when there is one."""
    s = report["summary"]
    lines = [first]
    for name, key in WORLD_SUMMARIES:
        w = s[key]
        lines.append(f"- {name}: {world_line(w, s)}" if w.get("runs") else f"- {name}: no runs")
    if s["gap"].get("runs"):
        lines.append(gap_line(s["gap"]))
    return lines


def summary_lines(report: dict[str, Any]) -> list[str]:
    """The summary as Markdown lines (also printed by the CLI)."""
    s = report["summary"]
    first = (
        f"- starts: {s['starts']}, physics finished: {s['physics_ok']}, "
        f"physics errors: {s['physics_errors']}; wall time {s['wall_s']:.1f} s"
    )

    def world_line(w: dict[str, Any], s: dict[str, Any]) -> str:
        return ", ".join([
            f"mean squares {w['mean_squares']:.2f}",
            f"mean inner {w['mean_inner_squares']:.2f} = {w['inner_pct']:.1f}% of "
            f"{s['inner_squares_total']}",
            f"docks {w['docks_total']} (success {100 * w['dock_success']:.0f}% of runs)",
            f"mean steps {w['mean_steps']:.0f}",
            f"ends {w['ends']}",
            f"{w['mean_wall_s']:.2f} s/run",
        ])  # fmt: skip

    def gap_line(g: dict[str, Any]) -> str:
        return f"- gap table − physics over {g['runs']} paired runs: " + ", ".join([
            f"inner {g['inner_pct_pp']:+.1f} pp",
            f"squares {g['squares']:+.2f}",
            f"docking success {g['dock_success_pp']:+.0f} pp",
            f"mean |Δ inner| per run {g['mean_abs_inner_diff']:.2f}",
        ])  # fmt: skip

    return summary_markdown(report, first, world_line, gap_line)


def markdown_document(
    report: dict[str, Any], title: str, intro: str, sections: list[tuple[str, list[str]]]
) -> str:
    """A validation's ``report.md``: title, intro, the ``(heading, lines)`` sections, then the
    runs' errors and the chromosome."""
    lines = [f"# {title}", "", intro, ""]
    for heading, body in sections:
        lines += [f"## {heading}", "", *body, ""]
    errors = [r for r in report["runs"] if r.get("error")]
    if errors:
        lines += ["## Errors", ""]
        lines += [f"- run {r['index']}: {r['error']}" for r in errors]
        lines.append("")
    lines += ["## Chromosome", "", "```", report["chromosome"].rstrip(), "```", ""]
    return "\n".join(lines)


def report_markdown(report: dict[str, Any]) -> str:
    """``report.md``: settings in brief, per-start table, summary, errors."""
    st = report["settings"]
    intro = (
        f"Gait table: `{report['table']['source']}`; mode {st['mode']}, "
        f"{st['max_steps']} steps per run; {report['summary']['starts']} starts."
    )
    return markdown_document(
        report, "Validation: table simulation vs MuJoCo physics", intro,
        [("Summary", summary_lines(report)), ("Per start", run_rows(report))],
    )  # fmt: skip


__all__ = [
    "WORLD_SUMMARIES",
    "count_ends",
    "inner_delta",
    "markdown_document",
    "markdown_table",
    "physics_error",
    "pose_cell",
    "report_markdown",
    "robot_cells",
    "run_rows",
    "summarise",
    "summarise_runs",
    "summary_lines",
    "summary_markdown",
    "write_report",
]
