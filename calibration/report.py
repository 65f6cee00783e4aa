"""Print the measured gait table beside Figure 4 and draw the comparison PNG."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from evolve.table import PAPER_TABLE
from infra.io import atomic_write

TOLERANCE = np.array([1.0, 1.0, 1.5])
"""Target accuracy of (F cm, T cm, dH deg) against Figure 4 (issue 2)."""
COLUMNS = ("F", "T", "dH")


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


def save_figure(
    path: str | Path, values: np.ndarray, std: np.ndarray, paper: np.ndarray = PAPER_TABLE
) -> Path:
    """PNG with F, T and dH per gait: paper markers, simulation mean ± per-cycle std."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    gaits = np.arange(len(paper))
    fig, axes = plt.subplots(3, 1, figsize=(9, 8), sharex=True)
    for c, (ax, unit) in enumerate(zip(axes, ("cm", "cm", "deg"), strict=True)):
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
    fig.tight_layout()

    def write(p: Path) -> None:
        fig.savefig(p, dpi=110)

    try:
        return atomic_write(path, write)
    finally:
        plt.close(fig)
