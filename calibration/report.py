"""Print the measured gait table beside Figure 4 and draw the comparison PNG."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from evolve.settings import WorldSettings
from evolve.table import DV, DV_STD, PAPER_TABLE
from infra.io import atomic_write

TOLERANCE = np.array([1.0, 1.0, 1.5])
"""Target accuracy of (F cm, T cm, dH deg) against Figure 4 (issue 2)."""
COLUMNS = ("F", "T", "dH")
PAPER_COST_V = WorldSettings().gait_cost_v
"""The paper's voltage drop per gait cycle (SPEC §3), V."""
PAPER_STILL_GAIT = WorldSettings().still_gait
"""The gait the paper charges nothing for."""


def draw_dv(ax: Any, gaits: np.ndarray, series: list[tuple[str, np.ndarray, np.ndarray]]) -> None:
    """Voltage drop per cycle of each (label, dV, std) series (series without a measured dV
    are left out) beside the paper's constant (gait 7: 0)."""
    series = [s for s in series if not np.all(np.isnan(s[1]))]
    width = 0.8 / max(len(series), 1)
    for k, (label, dv, dv_std) in enumerate(series):
        x = gaits + (k - (len(series) - 1) / 2) * width
        ax.bar(x, dv, width=width, yerr=dv_std, capsize=2, color=f"C{k}", alpha=0.8, label=label)
    paper = np.full(len(gaits), PAPER_COST_V)
    paper[PAPER_STILL_GAIT] = 0.0
    ax.hlines(paper, gaits - 0.45, gaits + 0.45, color="k", lw=1.5, label="paper")
    top = max([PAPER_COST_V, *(float(np.nanmax(s[1] + s[2])) for s in series)])
    ax.set_ylim(0.0, 1.35 * top)
    ax.set_ylabel("dV per cycle (V)")
    ax.grid(alpha=0.3)
    ax.legend(loc="upper center", fontsize=8, ncol=len(series) + 1)


def within_tolerance(values: np.ndarray, paper: np.ndarray = PAPER_TABLE) -> np.ndarray:
    """(16, 3) bool: |measured − paper| ≤ tolerance for each entry (NaN rows are False)."""
    return np.abs(np.asarray(values) - paper) <= TOLERANCE


def format_table(values: np.ndarray, std: np.ndarray, paper: np.ndarray = PAPER_TABLE) -> str:
    """Figure 4's two columns (gaits 0-7, then 8-15): measured ± std, paper, error per entry.

    Errors outside the tolerance (1 cm, 1 cm, 1.5°) are marked with ``!``.
    """
    ok = within_tolerance(values, paper)
    head = "gait " + " |".join(f"{c + (' cm' if c != 'dH' else ' deg'):^28}" for c in COLUMNS)
    sub = "     " + " |".join(f"{'sim ± std':>13} {'paper':>6} {'err':>6} " for _ in COLUMNS)
    lines = ["Figure 4, rebuilt in MuJoCo (sim = mean of the measured cycles):", head, sub]
    for block in (range(0, 8), range(8, 16)):
        lines.append("-" * len(sub))
        for g in block:
            cells = []
            for c in range(3):
                v, s, p = values[g, c], std[g, c], paper[g, c]
                mark = " " if ok[g, c] else "!"
                cells.append(f"{v:7.2f} ±{s:4.2f} {p:6.1f} {v - p:+6.2f}{mark}")
            lines.append(f"{g:4d} " + " |".join(cells))
    n_ok = int(ok.sum())
    worst = np.nanmax(np.abs(values - paper), axis=0)
    lines.append("-" * len(sub))
    lines.append(
        f"{n_ok}/48 entries within tolerance (F, T ±1.0 cm, dH ±1.5 deg); largest errors "
        f"F {worst[0]:.2f} cm, T {worst[1]:.2f} cm, dH {worst[2]:.2f} deg"
    )
    return "\n".join(lines)


def format_energy(energy: np.ndarray, paper_cost_v: float = PAPER_COST_V) -> str:
    """Energy and voltage drop per cycle of each gait (``evolve.table.ENERGY_COLUMNS``) beside
    the paper's constant drop."""
    lines = [
        f"Energy per cycle from the servo model (dV = voltage drop; paper: {paper_cost_v} V for "
        "every gait but 7):",
        "gait  energy J ± std    dV V ± std         dV / paper",
    ]
    for g, (e, e_std, dv, dv_std) in enumerate(energy):
        lines.append(
            f"{g:4d} {e:7.3f} ±{e_std:6.3f}  {dv:.5f} ±{dv_std:.5f}   {dv / paper_cost_v:6.2f}"
        )
    return "\n".join(lines)


def save_figure(
    path: str | Path,
    values: np.ndarray,
    std: np.ndarray,
    paper: np.ndarray = PAPER_TABLE,
    *,
    energy: np.ndarray | None = None,
) -> Path:
    """PNG with F, T and dH per gait: paper markers, simulation mean ± per-cycle std; with
    ``energy`` (16, 4) a fourth panel: voltage drop per cycle beside the paper's constant."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    gaits = np.arange(len(paper))
    rows = 3 if energy is None else 4
    fig, axes = plt.subplots(rows, 1, figsize=(9, 8 + 2.4 * (rows - 3)), sharex=True)
    if energy is not None:
        draw_dv(axes[3], gaits, [("MuJoCo", energy[:, DV], energy[:, DV_STD])])
    for c, (ax, unit) in enumerate(zip(axes, ("cm", "cm", "deg"), strict=False)):
        ax.bar(gaits, paper[:, c], width=0.6, color="0.8", label="paper (Figure 4)")
        ax.errorbar(
            gaits,
            values[:, c],
            yerr=std[:, c],
            fmt="o",
            color="C0",
            capsize=3,
            label="MuJoCo mean ± per-cycle std",
        )
        ax.fill_between(
            gaits,
            paper[:, c] - TOLERANCE[c],
            paper[:, c] + TOLERANCE[c],
            step="mid",
            color="C2",
            alpha=0.15,
            label="tolerance",
        )
        ax.set_ylabel(f"{COLUMNS[c]} ({unit})")
        ax.axhline(0.0, color="k", lw=0.5)
        ax.grid(alpha=0.3)
    axes[0].legend(loc="upper right", fontsize=8)
    axes[-1].set_xticks(gaits)
    axes[-1].set_xlabel("gait")
    fig.suptitle("ServoBot gait table: MuJoCo calibration vs the paper's Figure 4")
    return save_png(fig, path)


def save_png(fig: Any, path: str | Path) -> Path:
    """Write a matplotlib figure as a PNG atomically (110 dpi) and close it."""
    import matplotlib.pyplot as plt

    fig.tight_layout()
    try:
        return atomic_write(path, lambda p: fig.savefig(p, dpi=110))
    finally:
        plt.close(fig)
