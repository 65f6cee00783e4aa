"""The test matrix's outputs: ``robustness.json``, ``robustness.md`` and ``robustness.png``.

Pure functions over the cells' validation reports (``servobot.validation.lone.validate``)::

    {"worlds": [{"name", "description", "model", "model_sha256",
                 "physics_inner_percent",   # mean over the coverage chromosomes (None if none)
                 "dock_rate",               # mean over the navigation sections (None if none)
                 "drop_vs_shipped_pp",      # shipped − this world, inner % (docking % if only
                                            # sections), None without a shipped world
                 "physics_errors",
                 "per_chromosome": [{"file", "name", "mode", "physics_inner_percent",
                                     "dock_rate", "ends": {end name: count}, "runs",
                                     "physics_errors"}]}],
     "table_inner_percent", "table_dock_rate",
     "table_per_chromosome": [{"file", "name", "mode", "table_inner_percent", "dock_rate",
                               "ends", "runs"}],
     "starts", "steps", "navigation_steps", "seed", "table": {"source", "sha256"},
     "start_poses": {"coverage" | "navigation": [[x, y, h], ...]}}

Inner percents are % of the 64 inner squares over the runs whose physics finished (SPEC §5);
a dock rate is the share of runs (0–1) that docked at least once. A navigation section's
inner percents are None (it is judged by docking). The table world is the same in every
world; it is reported once, from the first world's cells, after checking that every world's
cells ran the same table runs (``same_table_runs``).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from infra.io import atomic_write, atomic_write_json, atomic_write_text
from servobot.robustness.worlds import SHIPPED
from servobot.validation.lone import NAVIGATION_MODE as NAVIGATION

ROBUSTNESS_OUTPUTS = ("robustness.json", "robustness.md", "robustness.png")
"""The matrix's own files in its folder."""
DPI = 130
"""Resolution of ``robustness.png``."""


def _entry(report: dict[str, Any], side: str, controller: dict[str, Any]) -> dict[str, Any]:
    """One controller's figures in one world (``side``: ``table`` or ``physics``)."""
    s = report["summary"][side]
    runs = s.get("runs", 0)
    inner = s["inner_pct"] if runs and controller["mode"] != NAVIGATION else None
    return {
        **controller,
        f"{side}_inner_percent": inner,
        "dock_rate": s["dock_success"] if runs else None,
        "ends": dict(s.get("ends", {})),
        "runs": runs,
    }


def _mean(values: list[float | None]) -> float | None:
    kept = [v for v in values if v is not None]
    return float(np.mean(kept)) if kept else None


def _table_runs(report: dict[str, Any]) -> list[Any]:
    """A report's table side without wall times: (start, table record) per run."""
    return [(r["start"], {k: v for k, v in (r["table"] or {}).items() if k != "wall_s"})
            for r in report["runs"]]  # fmt: skip


LATER_KEYS = ("handoffs",)
"""Record keys that runs validated before them lack (since the forty-fifth session: a coverage
run's hand-offs): a matrix resumed or reused across the change compares them only where both
runs have them."""


def _same_run(a: tuple[Any, dict[str, Any]], b: tuple[Any, dict[str, Any]]) -> bool:
    """Whether two (start, table record) pairs are one run (``LATER_KEYS`` where both have them)."""
    (start_a, rec_a), (start_b, rec_b) = a, b
    skip = {k for k in LATER_KEYS if (k in rec_a) != (k in rec_b)}
    return start_a == start_b and all(rec_a.get(k) == rec_b.get(k)
                                      for k in (rec_a.keys() | rec_b.keys()) - skip)  # fmt: skip


def same_table_runs(reports: list[dict[str, Any]], name: str) -> None:
    """Check that every world's cell of controller ``name`` ran the same starts and table runs
    (the table world does not depend on the physics world); ``RuntimeError`` otherwise."""
    first = _table_runs(reports[0])
    for rep in reports[1:]:
        runs = _table_runs(rep)
        if len(runs) != len(first) or not all(map(_same_run, first, runs)):
            raise RuntimeError(f"{name}: the table world differs between physics worlds (a bug)")


def _aggregate(entries: list[dict[str, Any]], side: str) -> tuple[float | None, float | None]:
    """(mean inner % over coverage chromosomes, mean dock rate over navigation sections)."""
    inner = _mean([e[f"{side}_inner_percent"] for e in entries if e["mode"] != NAVIGATION])
    dock = _mean([e["dock_rate"] for e in entries if e["mode"] == NAVIGATION])
    return inner, dock


def summarise_matrix(
    worlds: list[dict[str, Any]],
    controllers: list[dict[str, Any]],
    reports: dict[tuple[str, str], dict[str, Any]],
    head: dict[str, Any],
) -> dict[str, Any]:
    """``robustness.json``'s document (module docstring) from the cells' reports, keyed by
    (world name, controller name). ``worlds``: ``{"name", "description", "model",
    "model_sha256"}`` each; ``controllers``: ``{"file", "name", "mode"}`` each; ``head``:
    ``starts``, ``steps``, ... copied in front."""
    for c in controllers:
        same_table_runs([reports[(w["name"], c["name"])] for w in worlds], c["name"])
    first = worlds[0]["name"]
    table = [_entry(reports[(first, c["name"])], "table", c) for c in controllers]
    t_inner, t_dock = _aggregate(table, "table")
    out_worlds = []
    for w in worlds:
        per = []
        for c in controllers:
            rep = reports[(w["name"], c["name"])]
            per.append(
                _entry(rep, "physics", c) | {"physics_errors": rep["summary"]["physics_errors"]}
            )
        inner, dock = _aggregate(per, "physics")
        out_worlds.append({
            **w, "physics_inner_percent": inner, "dock_rate": dock,
            "physics_errors": sum(e["physics_errors"] for e in per), "per_chromosome": per,
        })  # fmt: skip
    shipped = next((w for w in out_worlds if w["name"] == SHIPPED), None)
    for w in out_worlds:
        w["drop_vs_shipped_pp"] = _drop(shipped, w)
    return {
        "worlds": out_worlds,
        "table_inner_percent": t_inner,
        "table_dock_rate": t_dock,
        "table_per_chromosome": table,
        **head,
    }


def _headline(w: dict[str, Any]) -> float | None:
    """A world's headline figure in %: mean inner %, else mean docking % (sections only)."""
    if w["physics_inner_percent"] is not None:
        return w["physics_inner_percent"]
    return None if w["dock_rate"] is None else 100.0 * w["dock_rate"]


def _drop(shipped: dict[str, Any] | None, w: dict[str, Any]) -> float | None:
    """Shipped's headline figure minus ``w``'s, percentage points (positive: worse here)."""
    if shipped is None:
        return None
    a, b = _headline(shipped), _headline(w)
    return None if a is None or b is None else a - b


# --------------------------------------------------------------------------- the grid


def grid(doc: dict[str, Any]) -> tuple[list[str], list[str], np.ndarray]:
    """(row labels, column labels, values %): one row per controller (coverage: inner %;
    navigation: docking %), columns the table world then each physics world; NaN where a
    value is missing."""
    cols = ["table", *(w["name"] for w in doc["worlds"])]
    rows, values = [], []
    for k, t in enumerate(doc["table_per_chromosome"]):
        nav = t["mode"] == NAVIGATION
        rows.append(f"{t['name']} (docking %)" if nav else t["name"])
        cells = [t, *(w["per_chromosome"][k] for w in doc["worlds"])]
        sides = ["table", *(["physics"] * len(doc["worlds"]))]
        values.append([_percent(c, s, nav) for c, s in zip(cells, sides, strict=True)])
    return rows, cols, np.array(values, dtype=float).reshape(len(rows), len(cols))


def _percent(entry: dict[str, Any], side: str, nav: bool) -> float:
    v = (None if entry["dock_rate"] is None else 100.0 * entry["dock_rate"]) if nav else (
        entry[f"{side}_inner_percent"])  # fmt: skip
    return np.nan if v is None else float(v)


def _fmt(v: float | None, signed: bool = False) -> str:
    if v is None or not np.isfinite(v):
        return "—"
    return f"{v:+.1f}" if signed else f"{v:.1f}"


def matrix_table(doc: dict[str, Any]) -> list[str]:
    """The grid as Markdown table lines: one row per controller, the table world then each
    physics world, a mean row and each world's drop vs shipped (pp)."""
    rows, cols, vals = grid(doc)
    worlds = doc["worlds"]
    lines = ["| chromosome | " + " | ".join(cols) + " |", "|---" * (len(cols) + 1) + "|"]
    for label, row in zip(rows, vals, strict=True):
        lines.append(f"| {label} | " + " | ".join(_fmt(v) for v in row) + " |")
    t_head = doc["table_inner_percent"]
    if t_head is None and doc["table_dock_rate"] is not None:
        t_head = 100.0 * doc["table_dock_rate"]
    lines.append("| **mean** | " + " | ".join(_fmt(v) for v in
                 [t_head, *(_headline(w) for w in worlds)]) + " |")  # fmt: skip
    lines.append("| **drop vs shipped (pp)** | | " + " | ".join(
        _fmt(w["drop_vs_shipped_pp"], signed=True) for w in worlds) + " |")  # fmt: skip
    return lines


MEAN_AND_DROP = (
    "Mean: coverage chromosomes' inner % (navigation sections' docking % when "
    "there is no coverage chromosome); drop: shipped − world, positive = worse."
)
"""What ``matrix_table``'s last two rows mean."""


def markdown(doc: dict[str, Any]) -> str:
    """``robustness.md``: the grid with a mean row and each world's drop vs shipped, the
    worlds, end reasons and the settings."""
    _, cols, _ = grid(doc)
    worlds = doc["worlds"]
    lines = [
        "# Robustness: controllers in physics worlds (table world beside them)", "",
        f"{doc['starts']} starts per controller, the same in every world; {doc['steps']} steps "
        f"per coverage run, {doc['navigation_steps']} per navigation run; seed {doc['seed']}; "
        f"gait table `{doc['table']['source']}` (values sha256 {doc['table']['sha256'][:12]}).",
        "Coverage chromosomes: % of the 64 inner squares reached (mean over the runs); "
        "navigation sections: % of runs that dock.", "",
        *matrix_table(doc),
    ]  # fmt: skip
    lines += ["", MEAN_AND_DROP, "",
              "## Worlds", "", "| world | what it changes | model sha256 | physics errors |",
              "|---|---|---|---|"]  # fmt: skip
    for w in worlds:
        lines.append(f"| {w['name']} | {w['description']} | `{w['model_sha256'][:12]}` | "
                     f"{w['physics_errors']} |")  # fmt: skip
    lines += ["", "## How runs end", "", "| chromosome | " + " | ".join(cols) + " |",
              "|---" * (len(cols) + 1) + "|"]  # fmt: skip
    for k, t in enumerate(doc["table_per_chromosome"]):
        ends = [t["ends"], *(w["per_chromosome"][k]["ends"] for w in worlds)]
        lines.append(
            f"| {t['name']} | "
            + " | ".join(", ".join(f"{n} {c}" for n, c in sorted(e.items())) or "—" for e in ends)
            + " |"
        )
    lines += ["", "## Chromosomes", ""]
    lines += [f"- {t['name']}: `{t['file']}` ({t['mode']})" for t in doc["table_per_chromosome"]]
    return "\n".join(lines) + "\n"


def figure(doc: dict[str, Any], path: Path) -> Path:
    """``robustness.png``: the grid as a heatmap (``heatmap``)."""
    return heatmap(path, *grid(doc), "inner squares reached, % (navigation: docking %)")


def heatmap(
    path: Path, rows: list[str], cols: list[str], vals: np.ndarray, title: str,
    last_row_apart: bool = False,
) -> Path:  # fmt: skip
    """A grid of percents as a heatmap (0–100 %), values annotated, the first column (the
    table world) set apart from the physics worlds by a line, and the last row from the
    others when ``last_row_apart``."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(1.3 * len(cols) + 2.5, 0.55 * len(rows) + 1.8))
    im = ax.imshow(np.ma.masked_invalid(vals), cmap="viridis", vmin=0.0, vmax=100.0,
                   aspect="auto")  # fmt: skip
    for (i, j), v in np.ndenumerate(vals):
        ax.text(j, i, _fmt(v), ha="center", va="center", fontsize=9,
                color="black" if np.isfinite(v) and v > 60 else "white")  # fmt: skip
    ax.axvline(0.5, color="white", linewidth=3)
    if last_row_apart:
        ax.axhline(len(rows) - 1.5, color="white", linewidth=3)
    ax.set_xticks(range(len(cols)), cols, rotation=30, ha="right")
    ax.set_yticks(range(len(rows)), rows)
    ax.set_title(title, fontsize=10)
    fig.colorbar(im, ax=ax, label="%")
    try:
        return atomic_write(path, lambda p: fig.savefig(p, dpi=DPI, bbox_inches="tight"))
    finally:
        plt.close(fig)


def write_outputs(out: Path, doc: dict[str, Any]) -> None:
    """``robustness.{json,md,png}`` into ``out``, atomically."""
    atomic_write_json(out / "robustness.json", doc)
    atomic_write_text(out / "robustness.md", markdown(doc))
    figure(doc, out / "robustness.png")


__all__ = [
    "MEAN_AND_DROP",
    "ROBUSTNESS_OUTPUTS",
    "figure",
    "grid",
    "heatmap",
    "markdown",
    "matrix_table",
    "same_table_runs",
    "summarise_matrix",
    "write_outputs",
]
