"""Compare gait tables of different robots (``servobot compare``): Figure 4 side by side.

``compare_tables(specs, out)`` loads two or more gait tables (calibration files or ``paper``)
and writes into ``out``:

- ``compare.png``: F, T and dH per gait, each table's mean ± per-cycle std beside the others
  over the paper's Figure 4 (grey), and, when any table measured it, the voltage drop per
  cycle beside the paper's constant;
- ``compare.csv``: one row per gait and quantity (F cm, T cm, dH deg, dV V), each table's
  value and each table's difference from the first (the reference), so a user sees at a glance
  what a change of robot did.

Every file is written atomically.
"""

from __future__ import annotations

import csv
import io
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from calibration.report import TOLERANCE, draw_dv, save_png, within_tolerance
from evolve.table import DV, DV_STD, N_GAITS, PAPER_TABLE, GaitTable, load_table
from infra.errors import InputError
from infra.io import atomic_write_text
from infra.rundir import run_folder

FIGURE_FILE = "compare.png"
CSV_FILE = "compare.csv"
COMPARE_FILES = (FIGURE_FILE, CSV_FILE)
"""What a comparison writes into its folder besides ``settings.json``."""


class CompareError(InputError, ValueError):
    """Tables that cannot be compared (fewer than two, labels that do not match)."""


QUANTITIES = (("F", "cm"), ("T", "cm"), ("dH", "deg"), ("dV", "V"))
"""Compared quantities and their units: the gait table's three columns and the voltage drop."""


@dataclass(frozen=True)
class Comparison:
    """Tables side by side: ``values[k]`` is table k's (16, 4) F, T, dH, dV (NaN: not measured)."""

    labels: list[str]
    values: np.ndarray
    """(n_tables, 16, 4)."""
    std: np.ndarray
    """(n_tables, 16, 4) per-cycle std (NaN where the file has none)."""
    figure_path: Path | None = None
    csv_path: Path | None = None

    @property
    def diff(self) -> np.ndarray:
        """(n_tables, 16, 4): each table minus the first."""
        return self.values - self.values[0]

    def summary(self) -> str:
        """One line per table: entries within Figure 4's tolerance and its largest changes."""
        lines = []
        for k, label in enumerate(self.labels):
            ok = int(within_tolerance(self.values[k, :, :3]).sum())
            line = f"{label}: {ok}/48 entries within Figure 4's tolerance"
            if k > 0:
                parts = []
                for q, (name, unit) in enumerate(QUANTITIES):
                    d = self.diff[k, :, q]
                    if np.all(np.isnan(d)):
                        continue
                    g = int(np.nanargmax(np.abs(d)))
                    fmt = ".4f" if name == "dV" else ".2f"
                    parts.append(f"{name} {d[g]:+{fmt}} {unit} (gait {g})")
                line += f"; largest change from {self.labels[0]}: " + ", ".join(parts)
            lines.append(line)
        return "\n".join(lines)


def default_labels(specs: list[str]) -> list[str]:
    """A short unique name per table: ``paper``, else the folder of a ``gait_table.json`` or the
    file's stem (``#k`` appended to repeats)."""
    names = []
    for spec in specs:
        p = Path(spec)
        if spec == "paper":
            names.append("paper")
        else:
            names.append(p.parent.name or p.stem if p.stem == "gait_table" else p.stem)
    return [n if names.count(n) == 1 else f"{n}#{k}" for k, n in enumerate(names)]


def _columns(table: GaitTable) -> tuple[np.ndarray, np.ndarray]:
    """(16, 4) values and std of F, T, dH, dV (dV NaN for a table without energy)."""
    values = np.full((N_GAITS, 4), np.nan)
    std = np.full((N_GAITS, 4), np.nan)
    values[:, :3] = table.values
    if table.std is not None:
        std[:, :3] = table.std
    if table.energy is not None:
        values[:, 3], std[:, 3] = table.energy[:, DV], table.energy[:, DV_STD]
    return values, std


def compare(specs: list[str], labels: list[str] | None = None) -> Comparison:
    """Load the tables (``evolve.table.load_table`` specs) and line them up."""
    if len(specs) < 2:
        raise CompareError(f"compare needs two or more gait tables, got {len(specs)}")
    labels = labels or default_labels(specs)
    if len(labels) != len(specs):
        raise CompareError(f"{len(labels)} labels for {len(specs)} tables")
    repeated = sorted({lb for lb in labels if labels.count(lb) > 1})
    if repeated:
        raise CompareError(
            f"--labels: {', '.join(map(repr, repeated))} given twice; each table needs its own "
            "label (the figure's legend and the CSV's columns are named by them)"
        )
    cols = [_columns(load_table(s)) for s in specs]
    return Comparison(labels, np.stack([c[0] for c in cols]), np.stack([c[1] for c in cols]))


def write_csv(path: str | Path, cmp: Comparison) -> Path:
    """One row per gait and quantity: each table's value, then each table minus the first."""
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    ref = cmp.labels[0]
    w.writerow(
        ["gait", "quantity", "unit", *cmp.labels, *(f"{lb} - {ref}" for lb in cmp.labels[1:])]
    )
    for g in range(N_GAITS):
        for q, (name, unit) in enumerate(QUANTITIES):
            vals = [_cell(v) for v in cmp.values[:, g, q]]
            diffs = [_cell(v) for v in cmp.diff[1:, g, q]]
            w.writerow([g, name, unit, *vals, *diffs])
    return atomic_write_text(path, buf.getvalue())


def _cell(v: float) -> str:
    return "" if np.isnan(v) else f"{v:.6g}"


def save_comparison_figure(path: str | Path, cmp: Comparison) -> Path:
    """Figure 4 of every table side by side over the paper's values (PNG)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    gaits = np.arange(N_GAITS)
    has_dv = not np.all(np.isnan(cmp.values[:, :, 3]))
    rows = 4 if has_dv else 3
    fig, axes = plt.subplots(rows, 1, figsize=(10, 2.7 * rows + 0.6), sharex=True)
    n = len(cmp.labels)
    width = 0.8 / n
    for c, ax in enumerate(axes[:3]):
        name, unit = QUANTITIES[c]
        ax.bar(gaits, PAPER_TABLE[:, c], width=0.85, color="0.88", label="paper (Figure 4)")
        for k, label in enumerate(cmp.labels):
            x = gaits + (k - (n - 1) / 2) * width
            ax.errorbar(x, cmp.values[k, :, c], yerr=np.nan_to_num(cmp.std[k, :, c]),
                        fmt="o", ms=4, capsize=2, color=f"C{k}", label=label)  # fmt: skip
        ax.set_ylabel(f"{name} ({unit})")
        ax.axhline(0.0, color="k", lw=0.5)
        ax.grid(alpha=0.3)
    axes[0].legend(loc="upper right", fontsize=8, ncol=min(n + 1, 4))
    if has_dv:
        series = [(lb, cmp.values[k, :, 3], np.nan_to_num(cmp.std[k, :, 3]))
                  for k, lb in enumerate(cmp.labels)]  # fmt: skip
        draw_dv(axes[3], gaits, series)
    axes[-1].set_xticks(gaits)
    axes[-1].set_xlabel("gait")
    fig.suptitle(
        f"Gait tables compared ({', '.join(cmp.labels)}); tolerance of Figure 4: "
        f"{TOLERANCE[0]:g} cm, {TOLERANCE[2]:g}°"
    )
    return save_png(fig, path)


def compare_tables(
    specs: list[str], out: str | Path, labels: list[str] | None = None, *, force: bool = False
) -> Comparison:
    """Compare the tables and write ``compare.png`` and ``compare.csv`` into ``out`` (a run
    folder of its own: ``infra.rundir.run_folder``; ``force`` replaces another comparison)."""
    cmp = compare(specs, labels)
    out = Path(out)
    record = {"tables": [str(s) for s in specs], "labels": list(cmp.labels)}
    with run_folder(out, record, owned=COMPARE_FILES, resumable=False, force=force,
                    command="compare"):
        csv_path = write_csv(out / CSV_FILE, cmp)
        fig_path = save_comparison_figure(out / FIGURE_FILE, cmp)
    return Comparison(cmp.labels, cmp.values, cmp.std, fig_path, csv_path)


__all__ = [
    "COMPARE_FILES",
    "CompareError",
    "Comparison",
    "compare",
    "compare_tables",
    "default_labels",
    "write_csv",
]
