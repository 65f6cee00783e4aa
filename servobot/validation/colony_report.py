"""The colony validation report: per-world summaries, the table-vs-physics gap, Markdown, the
track figures and the files (``servobot.validation.colony`` collects the per-run records).

Per world: the colony's squares and inner squares (% of the 64 inner squares, the union of
the robots'), the robots' own coverage, docks, how they ended, station waits and blocked
moves per run; in physics also the closest approach of two robot centres. The gap is table
minus physics over the runs whose physics finished.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import matplotlib.pyplot as plt
import numpy as np

from evolve.figures import DPI, draw_arena, draw_colony_robot
from evolve.settings import WorldSettings
from infra.io import atomic_write
from servobot.validation.report import markdown_document, write_report

WORLDS = ("table", "physics")


def _world_summary(recs: list[dict[str, Any]], n_inner: int) -> dict[str, Any]:
    """One world's means over its colony records."""
    if not recs:
        return {"runs": 0}
    colony = [r["colony"] for r in recs]
    robots = [b for r in recs for b in r["robots"]]
    inner = np.array([c["inner_squares"] for c in colony], dtype=float)
    robot_inner = np.array([b["inner_squares"] for b in robots], dtype=float)
    ends: dict[str, int] = {}
    for b in robots:
        ends[b["end"]["name"]] = ends.get(b["end"]["name"], 0) + 1
    out = {
        "runs": len(recs),
        "mean_squares": float(np.mean([c["squares"] for c in colony])),
        "mean_inner_squares": float(inner.mean()),
        "inner_pct": float(100.0 * inner.mean() / n_inner),
        "mean_colony_steps": float(np.mean([c["colony_steps"] for c in colony])),
        "robot_mean_squares": float(np.mean([b["squares"] for b in robots])),
        "robot_inner_pct": float(100.0 * robot_inner.mean() / n_inner),
        "robot_mean_steps": float(np.mean([b["steps"] for b in robots])),
        "docks_per_robot": float(np.mean([b["docks"] for b in robots])),
        "dock_success": float(np.mean([b["docks"] > 0 for b in robots])),
        "station_waits_per_run": float(np.mean([c["station_waits"] for c in colony])),
        "collisions_per_run": float(np.mean([c["collisions"] for c in colony])),
        "ends": ends,
        "mean_wall_s": float(np.mean([r["wall_s"] for r in recs])),
    }
    lows = [r["min_distance_cm"] for r in recs if r.get("min_distance_cm") is not None]
    if lows:
        out["min_distance_cm"] = float(min(lows))
    return out


def summarise_colony(
    runs: list[dict[str, Any]], world: WorldSettings, wall_s: float
) -> dict[str, Any]:
    """Summary of colony run records: per world, and the gap over runs whose physics finished."""
    n_inner = world.inner_square_count
    paired = [r for r in runs if r.get("table") and r.get("physics")]
    t_pair = _world_summary([r["table"] for r in paired], n_inner)
    p_pair = _world_summary([r["physics"] for r in paired], n_inner)
    gap: dict[str, Any] = {"runs": len(paired)}
    if paired:
        diff = [r["table"]["colony"]["inner_squares"] - r["physics"]["colony"]["inner_squares"]
                for r in paired]  # fmt: skip
        gap.update(
            inner_pct_pp=t_pair["inner_pct"] - p_pair["inner_pct"],
            squares=t_pair["mean_squares"] - p_pair["mean_squares"],
            robot_inner_pct_pp=t_pair["robot_inner_pct"] - p_pair["robot_inner_pct"],
            station_waits_per_run=t_pair["station_waits_per_run"] - p_pair["station_waits_per_run"],
            collisions_per_run=t_pair["collisions_per_run"] - p_pair["collisions_per_run"],
            mean_abs_inner_diff=float(np.mean(np.abs(diff))),
        )
    return {
        "starts": len(runs),
        "robots": len(runs[0]["start"]) if runs else 0,
        "physics_ok": len(paired),
        "physics_errors": sum(1 for r in runs if r.get("error")),
        "inner_squares_total": n_inner,
        "table": _world_summary([r["table"] for r in runs if r.get("table")], n_inner),
        "table_paired": t_pair,
        "physics": p_pair,
        "gap": gap,
        "wall_s": round(wall_s, 3),
    }


def _colony_cell(rec: dict[str, Any] | None) -> str:
    if rec is None:
        return "— | — | — | —"
    c = rec["colony"]
    return f"{c['squares']} | {c['inner_squares']} | {c['station_waits']} | {c['collisions']}"


def colony_run_rows(report: dict[str, Any]) -> list[str]:
    """The per-start Markdown table of the colonies (also printed by the CLI)."""
    rows = [
        "| # | table sq | inner | waits | blocked | physics sq | inner | waits | blocked "
        "| closest cm | Δ inner |",
        "|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for r in report["runs"]:
        t, p = r.get("table"), r.get("physics")
        d = (
            "—"
            if not (t and p)
            else f"{t['colony']['inner_squares'] - p['colony']['inner_squares']:+d}"
        )
        low = "—" if not p or p.get("min_distance_cm") is None else f"{p['min_distance_cm']:.1f}"
        phys = f"{_colony_cell(p)} | {low}" if p else f"error: {r.get('error')} | | | |"
        rows.append(f"| {r['index']} | {_colony_cell(t)} | {phys} | {d} |")
    return rows


def _robot_cell(b: dict[str, Any] | None) -> str:
    if b is None:
        return "— | — | — | — | —"
    return (f"{b['squares']} | {b['inner_squares']} | {b['docks']} | {b['steps']} | "
            f"{b['end']['name']}")  # fmt: skip


def robot_rows(report: dict[str, Any]) -> list[str]:
    """Every robot of every start, in both worlds (Markdown)."""
    rows = [
        "| # | robot | start x, y, h | table sq | inner | docks | steps | end | physics sq "
        "| inner | docks | steps | end |",
        "|---|---|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for r in report["runs"]:
        t, p = r.get("table"), r.get("physics")
        for i, s in enumerate(r["start"]):
            tb = t["robots"][i] if t else None
            pb = p["robots"][i] if p else None
            rows.append(
                f"| {r['index']} | {i} | {s['x']:.1f}, {s['y']:.1f}, {s['h']:.1f} | "
                f"{_robot_cell(tb)} | {_robot_cell(pb)} |"
            )
    return rows


def colony_summary_lines(report: dict[str, Any]) -> list[str]:
    """The summary as Markdown lines (also printed by the CLI)."""
    s = report["summary"]
    lines = [
        f"- colonies of {s['robots']}: {s['starts']} starts, physics finished: "
        f"{s['physics_ok']}, physics errors: {s['physics_errors']}; wall time "
        f"{s['wall_s']:.1f} s",
    ]
    for name, key in (("table (all runs)", "table"), ("table (paired)", "table_paired"),
                      ("physics", "physics")):  # fmt: skip
        w = s[key]
        if not w.get("runs"):
            lines.append(f"- {name}: no runs")
            continue
        closest = (
            f", closest centres {w['min_distance_cm']:.2f} cm" if "min_distance_cm" in w else ""
        )
        lines.append(
            f"- {name}: colony inner {w['mean_inner_squares']:.2f} = {w['inner_pct']:.1f}% of "
            f"{s['inner_squares_total']} (squares {w['mean_squares']:.2f}); per robot inner "
            f"{w['robot_inner_pct']:.1f}%, docks {w['docks_per_robot']:.2f}, steps "
            f"{w['robot_mean_steps']:.0f}, ends {w['ends']}; per run station waits "
            f"{w['station_waits_per_run']:.2f}, blocked moves {w['collisions_per_run']:.2f}, "
            f"colony steps {w['mean_colony_steps']:.0f}{closest}; {w['mean_wall_s']:.2f} s/run"
        )
    g = s["gap"]
    if g.get("runs"):
        lines.append(
            f"- gap table − physics over {g['runs']} paired runs: colony inner "
            f"{g['inner_pct_pp']:+.1f} pp (per robot {g['robot_inner_pct_pp']:+.1f} pp), squares "
            f"{g['squares']:+.2f}, station waits {g['station_waits_per_run']:+.2f} and blocked "
            f"moves {g['collisions_per_run']:+.2f} per run, mean |Δ inner| per run "
            f"{g['mean_abs_inner_diff']:.2f}"
        )
    return lines


def colony_report_markdown(report: dict[str, Any]) -> str:
    """``report.md`` of a colony validation."""
    st, su = report["settings"], report["summary"]
    intro = (
        f"Gait table: `{report['table']['source']}`; mode {st['mode']}, up to "
        f"{st['max_steps']} steps per robot; {su['starts']} colony starts of {su['robots']} "
        "robots."
    )
    return markdown_document(
        report, "Colony validation: table simulation vs MuJoCo physics", intro,
        [("Summary", colony_summary_lines(report)), ("Per start", colony_run_rows(report)),
         ("Per robot", robot_rows(report))],
    )  # fmt: skip


def colony_tracks_figure(
    path: Path, run: dict[str, Any], tracks: dict[str, np.ndarray], world: WorldSettings,
    disc_radius: float,
) -> None:  # fmt: skip
    """``tracks{k}.png``: every robot's track in the table world (left) and in physics
    (right) from colony start k, one colour per robot, each robot's final disc."""
    fig, axes = plt.subplots(1, 2, figsize=(11.0, 5.6))
    for ax, w in zip(axes, WORLDS, strict=True):
        rec, track = run.get(w), tracks.get(f"{w}_{run['index']}")
        draw_arena(ax, world)
        if rec is None or track is None:
            ax.set_title(f"{w}: {run.get('error') or 'no run'}", fontsize=8)
            continue
        for i, b in enumerate(rec["robots"]):
            label = f"robot {i}: {b['inner_squares']} inner, {b['docks']} docks, {b['end']['name']}"
            draw_colony_robot(ax, i, track[:, i], label, b["end"]["code"], disc_radius)
        c = rec["colony"]
        ax.set_title(
            f"{w}: colony {c['inner_squares']} inner squares, {c['station_waits']} station "
            f"waits, {c['collisions']} blocked moves", fontsize=8,
        )  # fmt: skip
        ax.legend(loc="upper left", fontsize=6.5, framealpha=0.9)
    fig.suptitle(f"colony start {run['index']}", fontsize=9)
    atomic_write(path, lambda p: fig.savefig(p, dpi=DPI, bbox_inches="tight"))
    plt.close(fig)


def write_colony_report(
    out: Path, report: dict[str, Any], tracks: dict[str, np.ndarray], world: WorldSettings
) -> None:
    """``report.json``, ``report.md``, ``tracks.npz`` and ``tracks{k}.png``, atomically."""
    write_report(out, report, tracks, markdown=colony_report_markdown(report))
    radius = report["settings"]["ColonySettings"]["disc_radius"]
    for run in report["runs"]:
        colony_tracks_figure(out / f"tracks{run['index']}.png", run, tracks, world, radius)


__all__ = [
    "colony_report_markdown",
    "colony_run_rows",
    "colony_summary_lines",
    "colony_tracks_figure",
    "robot_rows",
    "summarise_colony",
    "write_colony_report",
]
