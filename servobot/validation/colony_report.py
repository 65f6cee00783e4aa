"""The colony validation report: per-world summaries, the table-vs-physics gap, Markdown, the
track figures and the files (``servobot.validation.colony`` collects the per-run records).

Per world: the colony's squares and inner squares (% of the 64 inner squares, the union of
the robots'), the robots' own coverage, docks, how they ended (in all and at the station),
the robots live at the end (``evolve.interpreter.LIVE_ENDS``), station waits and blocked moves
per run; in physics also the closest approach of two robot centres. The gap is table minus
physics over the runs whose physics finished.
"""

from __future__ import annotations

from functools import partial
from pathlib import Path
from typing import Any

import matplotlib.pyplot as plt
import numpy as np

from evolve.figures import DPI, draw_arena, draw_colony_robot
from evolve.interpreter import LIVE_ENDS
from evolve.settings import WorldSettings
from infra.io import atomic_write
from servobot.validation.report import (
    count_ends,
    inner_delta,
    markdown_document,
    markdown_table,
    physics_error,
    pose_cell,
    robot_cells,
    summarise_runs,
    summary_markdown,
    write_report,
)

WORLDS = ("table", "physics")
AT_STATION_CM = 70.0
"""A robot ended at the station when its final centre lies within this distance of
``WorldSettings.dock_point`` (cm): the docking box and the lane in front of it, where robots
that queue or jam for the station end [chosen, for the report only]."""


COLONY_GAP = (("inner_pct_pp", "inner_pct", 1.0), ("squares", "mean_squares", 1.0),
              ("robot_inner_pct_pp", "robot_inner_pct", 1.0),
              ("station_waits_per_run", "station_waits_per_run", 1.0),
              ("collisions_per_run", "collisions_per_run", 1.0))  # fmt: skip
"""The gap table − physics of a colony: (name, key of the world summaries, scale)."""


def ended_at_station(robot: dict[str, Any], dock_point: tuple[float, float]) -> bool:
    """Whether a robot record's final centre lies within ``AT_STATION_CM`` of ``dock_point``."""
    x, y = robot["final_pose"][:2]
    return bool(np.hypot(x - dock_point[0], y - dock_point[1]) <= AT_STATION_CM)


def _world_summary(
    recs: list[dict[str, Any]], n_inner: int, dock_point: tuple[float, float]
) -> dict[str, Any]:
    """One world's means over its colony records."""
    if not recs:
        return {"runs": 0}
    colony = [r["colony"] for r in recs]
    robots = [b for r in recs for b in r["robots"]]
    inner = np.array([c["inner_squares"] for c in colony], dtype=float)
    robot_inner = np.array([b["inner_squares"] for b in robots], dtype=float)
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
        "ends": count_ends(robots),
        "ends_at_station": count_ends([b for b in robots if ended_at_station(b, dock_point)]),
        "live_at_end_per_run": float(
            np.mean([sum(b["end"]["code"] in LIVE_ENDS for b in r["robots"]) for r in recs])
        ),
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
    return summarise_runs(
        runs, world, wall_s, partial(_world_summary, dock_point=world.dock_point), COLONY_GAP,
        lambda r: r["colony"]["inner_squares"], robots=len(runs[0]["start"]) if runs else 0,
    )  # fmt: skip


def per_robot(report: dict[str, Any], key: str) -> dict[str, list[float]]:
    """Each robot's mean ``key`` of its robot records (``docks``, ``station_waits``, ...) over
    a colony validation's runs, per world: ``{"table": [R], "physics": [R]}`` (physics: the
    runs whose physics finished; an empty list when none did)."""
    out = {}
    for w in WORLDS:
        recs = [r[w]["robots"] for r in report["runs"] if r.get(w)]
        robots = len(recs[0]) if recs else 0
        out[w] = [float(np.mean([rs[i][key] for rs in recs])) for i in range(robots)]
    return out


def _colony_cells(rec: dict[str, Any] | None) -> str:
    if rec is None:
        return "— | — | — | —"
    c = rec["colony"]
    return f"{c['squares']} | {c['inner_squares']} | {c['station_waits']} | {c['collisions']}"


def colony_run_rows(report: dict[str, Any]) -> list[str]:
    """The per-start Markdown table of the colonies (also printed by the CLI)."""
    rows = []
    for r in report["runs"]:
        t, p = r.get("table"), r.get("physics")
        d = inner_delta(t and t["colony"], p and p["colony"])
        low = "—" if not p or p.get("min_distance_cm") is None else f"{p['min_distance_cm']:.1f}"
        phys = f"{_colony_cells(p)} | {low}" if p else physics_error(r)
        rows.append(f"| {r['index']} | {_colony_cells(t)} | {phys} | {d} |")
    columns = ("# | table sq | inner | waits | blocked | physics sq | inner | waits | blocked "
               "| closest cm | Δ inner")  # fmt: skip
    return markdown_table(columns, rows)


def robot_rows(report: dict[str, Any]) -> list[str]:
    """Every robot of every start, in both worlds (Markdown)."""
    rows = []
    for r in report["runs"]:
        t, p = r.get("table"), r.get("physics")
        for i, s in enumerate(r["start"]):
            tb = t["robots"][i] if t else None
            pb = p["robots"][i] if p else None
            rows.append(
                f"| {r['index']} | {i} | {pose_cell(s)} | {robot_cells(tb)} | {robot_cells(pb)} |"
            )
    columns = ("# | robot | start x, y, h | table sq | inner | docks | steps | end | physics sq "
               "| inner | docks | steps | end")  # fmt: skip
    return markdown_table(columns, rows)


def colony_summary_lines(report: dict[str, Any]) -> list[str]:
    """The summary as Markdown lines (also printed by the CLI)."""
    s = report["summary"]
    first = (
        f"- colonies of {s['robots']}: {s['starts']} starts, physics finished: "
        f"{s['physics_ok']}, physics errors: {s['physics_errors']}; wall time "
        f"{s['wall_s']:.1f} s"
    )

    def world_line(w: dict[str, Any], s: dict[str, Any]) -> str:
        closest = (
            f", closest centres {w['min_distance_cm']:.2f} cm" if "min_distance_cm" in w else ""
        )
        return (
            f"colony inner {w['mean_inner_squares']:.2f} = {w['inner_pct']:.1f}% of "
            f"{s['inner_squares_total']} (squares {w['mean_squares']:.2f}); per robot inner "
            f"{w['robot_inner_pct']:.1f}%, docks {w['docks_per_robot']:.2f}, steps "
            f"{w['robot_mean_steps']:.0f}, ends {w['ends']} (at the station "
            f"{w.get('ends_at_station', '—')}); per run live at the end "
            f"{w['live_at_end_per_run']:.2f}, station waits "
            f"{w['station_waits_per_run']:.2f}, blocked moves {w['collisions_per_run']:.2f}, "
            f"colony steps {w['mean_colony_steps']:.0f}{closest}; {w['mean_wall_s']:.2f} s/run"
        )

    def gap_line(g: dict[str, Any]) -> str:
        return (
            f"- gap table − physics over {g['runs']} paired runs: colony inner "
            f"{g['inner_pct_pp']:+.1f} pp (per robot {g['robot_inner_pct_pp']:+.1f} pp), squares "
            f"{g['squares']:+.2f}, station waits {g['station_waits_per_run']:+.2f} and blocked "
            f"moves {g['collisions_per_run']:+.2f} per run, mean |Δ inner| per run "
            f"{g['mean_abs_inner_diff']:.2f}"
        )

    return summary_markdown(report, first, world_line, gap_line)


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
    "per_robot",
    "robot_rows",
    "summarise_colony",
    "write_colony_report",
]
