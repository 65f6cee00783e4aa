"""The validation report: per-world summaries, the table-vs-physics gap, Markdown and files.

Pure functions over the per-run records that ``servobot.validation.lone.validate`` collects; see
that module for the record layout.
"""

from __future__ import annotations

import io
from pathlib import Path
from typing import Any

import numpy as np

from evolve.interpreter import END_DOCKED
from evolve.settings import WorldSettings
from infra.io import atomic_write, atomic_write_json, atomic_write_text


def _world_summary(recs: list[dict[str, Any]], n_inner: int) -> dict[str, Any]:
    if not recs:
        return {"runs": 0}
    inner = np.array([r["inner_squares"] for r in recs], dtype=float)
    ends: dict[str, int] = {}
    for r in recs:
        ends[r["end"]["name"]] = ends.get(r["end"]["name"], 0) + 1
    return {
        "runs": len(recs),
        "mean_squares": float(np.mean([r["squares"] for r in recs])),
        "mean_inner_squares": float(inner.mean()),
        "inner_pct": float(100.0 * inner.mean() / n_inner),
        "mean_steps": float(np.mean([r["steps"] for r in recs])),
        "docks_total": int(sum(r["docks"] for r in recs)),
        "dock_success": float(np.mean([r["docks"] > 0 for r in recs])),
        "docked_end": int(sum(r["end"]["code"] == END_DOCKED for r in recs)),
        "ends": ends,
        "mean_wall_s": float(np.mean([r["wall_s"] for r in recs])),
    }


def summarise(runs: list[dict[str, Any]], world: WorldSettings, wall_s: float) -> dict[str, Any]:
    """Summary of per-run records: per world, and the gap over runs whose physics finished."""
    n_inner = world.inner_square_count
    table = [r["table"] for r in runs if r.get("table")]
    paired = [r for r in runs if r.get("table") and r.get("physics")]
    t_pair = _world_summary([r["table"] for r in paired], n_inner)
    p_pair = _world_summary([r["physics"] for r in paired], n_inner)
    gap: dict[str, Any] = {"runs": len(paired)}
    if paired:
        gap.update(
            inner_pct_pp=t_pair["inner_pct"] - p_pair["inner_pct"],
            squares=t_pair["mean_squares"] - p_pair["mean_squares"],
            dock_success_pp=100.0 * (t_pair["dock_success"] - p_pair["dock_success"]),
            mean_abs_inner_diff=float(
                np.mean(
                    [
                        abs(r["table"]["inner_squares"] - r["physics"]["inner_squares"])
                        for r in paired
                    ]
                )
            ),
        )
    return {
        "starts": len(runs),
        "physics_ok": len(paired),
        "physics_errors": sum(1 for r in runs if r.get("error")),
        "inner_squares_total": n_inner,
        "table": _world_summary(table, n_inner),
        "table_paired": t_pair,
        "physics": p_pair,
        "gap": gap,
        "wall_s": round(wall_s, 3),
    }


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


def _cell(rec: dict[str, Any] | None) -> str:
    if rec is None:
        return "— | — | — | — | —"
    return (
        f"{rec['squares']} | {rec['inner_squares']} | {rec['docks']} | {rec['steps']} | "
        f"{rec['end']['name']}"
    )


def run_rows(report: dict[str, Any]) -> list[str]:
    """The per-start Markdown table (also printed by the CLI)."""
    rows = [
        "| # | start x, y, h | table sq | inner | docks | steps | end "
        "| physics sq | inner | docks | steps | end | Δ inner |",
        "|---|---|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for r in report["runs"]:
        s = r["start"]
        t, p = r.get("table"), r.get("physics")
        d = "—" if not (t and p) else f"{t['inner_squares'] - p['inner_squares']:+d}"
        phys = _cell(p) if p else f"error: {r.get('error')} | | | |"
        rows.append(
            f"| {r['index']} | {s['x']:.1f}, {s['y']:.1f}, {s['h']:.1f} | {_cell(t)} | "
            f"{phys} | {d} |"
        )
    return rows


def summary_lines(report: dict[str, Any]) -> list[str]:
    """The summary as Markdown lines (also printed by the CLI)."""
    s = report["summary"]
    lines = [
        f"- starts: {s['starts']}, physics finished: {s['physics_ok']}, "
        f"physics errors: {s['physics_errors']}; wall time {s['wall_s']:.1f} s",
    ]
    for name, key in (("table (all runs)", "table"), ("table (paired)", "table_paired"),
                      ("physics", "physics")):  # fmt: skip
        w = s[key]
        if not w.get("runs"):
            lines.append(f"- {name}: no runs")
            continue
        lines.append(
            f"- {name}: mean squares {w['mean_squares']:.2f}, mean inner "
            f"{w['mean_inner_squares']:.2f} = {w['inner_pct']:.1f}% of {s['inner_squares_total']}, "
            f"docks {w['docks_total']} (success {100 * w['dock_success']:.0f}% of runs), "
            f"mean steps {w['mean_steps']:.0f}, ends {w['ends']}, {w['mean_wall_s']:.2f} s/run"
        )
    g = s["gap"]
    if g.get("runs"):
        lines.append(
            f"- gap table − physics over {g['runs']} paired runs: inner {g['inner_pct_pp']:+.1f} "
            f"pp, squares {g['squares']:+.2f}, docking success {g['dock_success_pp']:+.0f} pp, "
            f"mean |Δ inner| per run {g['mean_abs_inner_diff']:.2f}"
        )
    return lines


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
    "markdown_document",
    "report_markdown",
    "run_rows",
    "summarise",
    "summary_lines",
    "write_report",
]
