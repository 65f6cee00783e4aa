"""How far from the station a test matrix's robots get, per world (issue 16):
``python -m servobot.robustness.reach MATRIX [--out DIR]``.

A coverage robot of SPEC §5 leaves the station, walks until its store reads low, walks back
and charges, about seven times in 600 steps: what it can cover is what its excursions reach.
A robot whose strides are shorter (the ``slippery`` world's, 12–15 % on the straight gaits)
reaches less far on the same controller and loses the far squares, even when every run lasts
to the step limit and docks as often (docs/robustness.md, "A controller evolved on the slippery
robot's table"). This reads every pose of every run of MATRIX (a finished ``servobot
robustness`` folder, its ``runs/WORLD/NAME/tracks.npz``) and reports, per world and coverage
chromosome, the physics runs' mean and 90th-percentile distance of the robot's centre from
the dock point (``WorldSettings.dock_point``) and the westmost x it reached (mean over the
runs), the table world's once beside them. Writes ``DIR/reach.json``, ``DIR/reach.md`` and
``DIR/reach.png`` (each world's distances pooled over its chromosomes, as cumulative
distributions; DIR defaults to MATRIX) and prints the Markdown. Exit 0, or 2 naming what is
missing.

Units: table units (1 unit = 1 cm of the MuJoCo arena), SPEC §1's frame (x east, y north).
"""

from __future__ import annotations

import argparse
import zipfile
from pathlib import Path
from typing import Any

import numpy as np

from evolve.settings import WorldSettings
from infra.command import Interrupted, run_command
from infra.errors import InputError
from infra.io import atomic_write, write_report
from servobot.robustness.floor import read_matrix
from servobot.robustness.matrix import RUNS_DIR
from servobot.robustness.report import DPI
from servobot.validation.lone import NAVIGATION_MODE

PROG = "python -m servobot.robustness.reach"
QUANTILE = 90.0
"""Percentile of a run's distances from the dock point reported as its reach, %."""
TABLE = "table"
"""The table world's column (its runs are the same in every physics world)."""


def dock_distances(track: np.ndarray, dock_point: tuple[float, float]) -> np.ndarray:
    """Distance (units) of each pose of ``track`` (N, 3: x, y, heading) from ``dock_point``."""
    xy = np.asarray(track, dtype=float)[:, :2]
    return np.hypot(xy[:, 0] - dock_point[0], xy[:, 1] - dock_point[1])


def track_reach(track: np.ndarray, dock_point: tuple[float, float]) -> tuple[float, float, float]:
    """(mean distance, ``QUANTILE``-th percentile distance from ``dock_point``, least x) of a
    run's poses ``track`` (N, 3: x, y, heading; units, degrees), every pose counted once."""
    track = np.asarray(track, dtype=float)
    d = dock_distances(track, dock_point)
    return float(d.mean()), float(np.percentile(d, QUANTILE)), float(track[:, 0].min())


def cell_tracks(folder: Path, side: str) -> list[np.ndarray]:
    """The ``side`` (``table`` or ``physics``) tracks of a matrix cell folder, run by run."""
    try:
        with np.load(folder / "tracks.npz") as npz:
            keys = sorted((k for k in npz.files if k.startswith(f"{side}_")),
                          key=lambda k: int(k.rsplit("_", 1)[1]))  # fmt: skip
            return [npz[k] for k in keys]
    except (OSError, ValueError, zipfile.BadZipFile) as exc:
        raise InputError(f"{folder}: no readable tracks.npz ({exc})") from exc


def _summary(tracks: list[np.ndarray], dock_point: tuple[float, float]) -> dict[str, Any]:
    per_run = np.array([track_reach(t, dock_point) for t in tracks]).reshape(-1, 3)
    mean, reach, west = per_run.mean(axis=0) if len(per_run) else (np.nan,) * 3
    return {"runs": len(tracks), "mean_distance": float(mean), "reach": float(reach),
            "west_x": float(west)}  # fmt: skip


def matrix_reach(matrix: Path, world: WorldSettings | None = None) -> dict[str, Any]:
    """The record ``reach.json``: per world (the table world first) its coverage chromosomes'
    ``_summary`` and the distances of all their poses pooled (for the figure)."""
    dock = (world or WorldSettings()).dock_point
    doc, _ = read_matrix(matrix)
    worlds = doc["worlds"]
    names = [c["name"] for c in worlds[0]["per_chromosome"] if c["mode"] != NAVIGATION_MODE]
    if not names:
        raise InputError(f"{matrix}: no coverage chromosome (navigation sections have no reach)")
    columns = [(TABLE, worlds[0]["name"], "table"),
               *((w["name"], w["name"], "physics") for w in worlds)]  # fmt: skip
    out = []
    for label, world_name, side in columns:
        rows, pooled = [], []
        for name in names:
            tracks = cell_tracks(matrix / RUNS_DIR / world_name / name, side)
            rows.append({"name": name, **_summary(tracks, dock)})
            pooled += [dock_distances(t, dock) for t in tracks]
        flat = np.concatenate(pooled) if pooled else np.zeros(0)
        out.append({"world": label, "per_chromosome": rows,
                    **{k: float(np.mean([r[k] for r in rows]))
                       for k in ("mean_distance", "reach", "west_x")},
                    "distances": np.sort(flat).round(1).tolist()})  # fmt: skip
    return {"matrix": str(matrix), "dock_point": list(dock), "quantile": QUANTILE,
            "worlds": out}  # fmt: skip


def markdown(doc: dict[str, Any]) -> str:
    """Per chromosome and world: mean distance / reach / westmost x, units."""
    worlds = doc["worlds"]
    head = ["chromosome", *(w["world"] for w in worlds)]
    lines = [f"Distance of the robot's centre from the dock point {tuple(doc['dock_point'])}: "
             f"mean / {doc['quantile']:.0f}th percentile / westmost x, units (mean over the "
             f"runs; `{doc['matrix']}`).", "",
             "| " + " | ".join(head) + " |", "|" + "---|" * len(head)]  # fmt: skip

    def cell(r: dict[str, Any]) -> str:
        return f"{r['mean_distance']:.0f} / {r['reach']:.0f} / {r['west_x']:.0f}"

    for i, row in enumerate(worlds[0]["per_chromosome"]):
        lines.append(f"| {row['name']} | " + " | ".join(cell(w["per_chromosome"][i])
                                                       for w in worlds) + " |")  # fmt: skip
    lines.append("| **mean** | " + " | ".join(f"**{cell(w)}**" for w in worlds) + " |")
    return "\n".join(lines) + "\n"


def figure(doc: dict[str, Any], path: Path) -> Path:
    """``reach.png``: each world's pooled distances as a cumulative distribution."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(7.0, 4.2))
    for w in doc["worlds"]:
        d = np.asarray(w["distances"])
        if d.size:
            ax.plot(d, np.arange(1, d.size + 1) / d.size, label=w["world"],
                    linestyle="--" if w["world"] == TABLE else "-")  # fmt: skip
    ax.set_xlabel("distance from the dock point, units (cm)")
    ax.set_ylabel("share of the poses")
    ax.set_title("How far the robots get from the station", fontsize=10)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    try:
        return atomic_write(path, lambda p: fig.savefig(p, dpi=DPI, bbox_inches="tight"))
    finally:
        plt.close(fig)


def main(argv: list[str] | None = None) -> int:
    """Measure, write and print; exit 0 or 2 (module docstring)."""
    ap = argparse.ArgumentParser(prog=PROG, description=__doc__.splitlines()[0])
    ap.add_argument("matrix", type=Path, metavar="MATRIX",
                    help="a finished servobot robustness folder")  # fmt: skip
    ap.add_argument("--out", type=Path, default=None, metavar="DIR",
                    help="where reach.{json,md,png} go (default MATRIX)")  # fmt: skip
    a = ap.parse_args(argv)

    def body() -> int:
        doc = matrix_reach(a.matrix)
        out = a.out or a.matrix
        write_report(out, "reach", doc, markdown(doc))
        figure(doc, out / "reach.png")
        return 0

    return run_command(PROG, body, lambda: Interrupted("the files written so far", PROG))


if __name__ == "__main__":
    raise SystemExit(main())
