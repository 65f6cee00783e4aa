"""A fixed workload of the table world (lone coverage, navigation, colony) and its results as
the code computed them before the envelope of variation existed (SPEC §9: the envelope
``none`` is the world of §3, bit for bit).

``tests/data/envelope_none.npz`` was written by the code at commit a72e42b (before
``evolve.envelope``) with::

    PYTHONPATH=$PWD python3 tests/envelope_workload.py tests/data/envelope_none.npz

and is never rewritten: ``tests/test_envelope.py`` compares today's kernels and interpreter
with it.
"""

from __future__ import annotations

import dataclasses
import sys
from pathlib import Path

import numpy as np

from evolve import evaluate, evaluate_colony
from evolve.settings import ColonySettings, WorldSettings
from evolve.starts import colony_starts, coverage_starts, navigation_starts
from evolve.table import PAPER_TABLE

EXPECTED = Path(__file__).parent / "data" / "envelope_none.npz"
WORLD = WorldSettings()
NEAR_STATION = dataclasses.replace(WORLD, coverage_start_x=(400, 470), coverage_start_y=(190, 310))
"""Starts close to the station: runs dock, charge and back up."""
COLONY = ColonySettings()
LOW_POWER_FIRST = [0, 0, 1, 1, 0, 0, 0, 0, 0]
"""Gene 0 loops forever and first tests low power, to navigation: such runs dock often."""
START_POWER = 3.95
"""Just under the low-power threshold."""


@dataclasses.dataclass(frozen=True)
class Workload:
    """Genomes and starts of the three kinds of runs (P × S each)."""

    coverage: np.ndarray
    coverage_starts: np.ndarray
    navigation: np.ndarray
    navigation_starts: np.ndarray
    colony: np.ndarray
    colony_starts: np.ndarray


def workload(seed: int = 2024) -> Workload:
    """1600 coverage runs (half near the station), 800 navigation runs, 400 colony runs of 3."""
    rng = np.random.default_rng(seed)
    cov = rng.integers(0, 2, size=(400, 16, 30), dtype=np.uint8)
    cov[::2, 0, :9] = LOW_POWER_FIRST
    cov_starts = np.concatenate(
        [coverage_starts(rng, 2, WORLD), coverage_starts(rng, 2, NEAR_STATION)]
    )
    nav = rng.integers(0, 2, size=(400, 8, 30), dtype=np.uint8)
    nav_starts = navigation_starts(rng, 2, WORLD)
    col = rng.integers(0, 2, size=(200, 16, 30), dtype=np.uint8)
    col[::2, 0, :9] = LOW_POWER_FIRST
    col_starts = np.concatenate(
        [colony_starts(rng, 1, WORLD, COLONY), colony_starts(rng, 1, NEAR_STATION, COLONY)]
    )
    return Workload(cov, cov_starts, nav, nav_starts, col, col_starts)


LONE_FIELDS = ("squares", "inner_squares", "steps", "docks", "end", "final_pose")
COLONY_FIELDS = LONE_FIELDS + (
    "colony_steps", "robot_squares", "robot_inner_squares", "collisions", "station_waits",
)  # fmt: skip


def results(w: Workload, **envelope) -> dict[str, np.ndarray]:
    """Every output array of the workload, keyed ``coverage_*``, ``navigation_*``,
    ``colony_*``; ``envelope``: extra keyword arguments of ``evaluate``/``evaluate_colony``."""
    kw = dict(table=PAPER_TABLE, **envelope)
    cov = evaluate(w.coverage, w.coverage_starts, mode="coverage", start_power=START_POWER, **kw)
    nav = evaluate(w.navigation, w.navigation_starts, mode="navigation", **kw)
    col = evaluate_colony(w.colony, w.colony_starts, mode="coverage", start_power=START_POWER,
                          colony=COLONY, **kw)  # fmt: skip
    out = {f"coverage_{f}": getattr(cov, f) for f in LONE_FIELDS}
    out |= {f"navigation_{f}": getattr(nav, f) for f in LONE_FIELDS}
    out |= {f"colony_{f}": getattr(col, f) for f in COLONY_FIELDS}
    return out


if __name__ == "__main__":
    path = Path(sys.argv[1])
    path.parent.mkdir(parents=True, exist_ok=True)
    np.savez_compressed(path, **results(workload()))
    print(f"wrote {path}")
