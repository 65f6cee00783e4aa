"""Every saved best of a ``"beside"`` colony stage as its team's learned robot (issue 17).

A ``"beside"`` stage (``servobot evolve colony --sections beside``) learns one robot's
coverage section beside fixed partners, and left to itself it may drift (docs/colony.md, "A
coverer learned for its team": at seed 1 the finalists covered the outer ring). This screen
runs the best section of every saved generation of every population as the learned robot of
the stage's own team, from the stage's colony test starts, in the world of SPEC §3 with the
stage's colony settings (``evolve.colony_stage.final_test``), and ranks them by the stage's
run fitness (``ColonySettings.fitness``): the choice among saved bests that the thirtieth
session made by hand.

Run: ``python -m evolve.beside_screen RUN_DIR [--top 10] [--save popK_genG OUT.txt]``: prints
the ``--top`` saved bests, best first (run fitness, colony inner %, robots live of R, docks
per robot, the section alone); ``--save`` writes saved best ``popK_genG`` as a 16-gene
chromosome (its coverage section + the stage's navigation), e.g. for ``servobot validate``.
"""

from __future__ import annotations

import argparse
import re
import sys
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from evolve.checkpoint import read_npz
from evolve.codec import write_chromosome
from evolve.colony_stage import beside_teams, colony_stage, final_test
from evolve.colony_timeline import run_settings
from evolve.population import Stage, stage_seeds
from evolve.settings import ColonySettings, GASettings, WorldSettings
from evolve.table import GaitTable, validate_table
from infra.errors import InputError
from infra.io import read_json

SAVED = re.compile(r"pop(\d+)_gen(\d+)")


class BesideScreenError(InputError, ValueError):
    """The run folder is not a finished ``"beside"`` colony stage, or a name is unknown."""


@dataclass(frozen=True)
class BesideRun:
    """A ``"beside"`` colony stage's record: its settings, its ``Stage`` (team, learned robot
    and navigation, rebuilt by ``colony_stage``) and colony test starts."""

    folder: Path
    world: WorldSettings
    colony: ColonySettings
    ga: GASettings
    table: GaitTable
    stage: Stage
    starts: np.ndarray
    """(T, R, 3): the stage's colony test starts."""

    @property
    def role(self) -> int:
        """The learned robot."""
        return self.stage.evaluate.keywords["role"]


def _bits(rows: Any, what: str, path: Path) -> np.ndarray:
    try:
        arr = np.array([[int(c) for c in r] for r in rows], dtype=np.uint8)
    except (TypeError, ValueError):
        raise BesideScreenError(f"{path}: {what} is not a list of bit strings") from None
    if arr.ndim != 2 or arr.shape[1] != 30:
        raise BesideScreenError(f"{path}: {what} is not a section of 30-bit genes")
    return arr


def load_beside_run(run_dir: str | Path) -> BesideRun:
    """The ``"beside"`` stage of ``run_dir`` (``RUN_DIR/colony/settings.json``);
    ``BesideScreenError`` naming what is missing."""
    world, colony, ga, values, source = run_settings(run_dir)
    path = Path(run_dir, "colony", "settings.json")
    if colony.sections != "beside":
        raise BesideScreenError(f"{path}: sections {colony.sections!r}: not a 'beside' stage")
    if ga is None or values is None:
        raise BesideScreenError(f"{path}: the GA settings or the gait table are not recorded")
    doc = read_json(path, what="colony settings", error=BesideScreenError)
    nav = _bits(doc.get("navigation_section"), "navigation_section", path)
    if "partner_sections" in doc:
        partners = np.stack([_bits(s, "partner_sections", path) for s in doc["partner_sections"]])
    else:
        partners = _bits(doc.get("partner_section"), "partner_section", path)
    stage = colony_stage(world, colony, nav, partners=partners, robot=doc.get("beside_robot"))
    test_seq, _ = stage_seeds(ga.seed, stage.name, ga.populations)
    starts = stage.starts(np.random.Generator(np.random.PCG64(test_seq)), ga.test_starts, world)
    table = GaitTable(validate_table(values), source=source or "recorded")
    return BesideRun(Path(run_dir, "colony"), world, colony, ga, table, stage, starts)


def saved_bests(run: BesideRun) -> dict[str, np.ndarray]:
    """``popK_genG`` → the (8, 30) best coverage section saved at generation G of population
    K, in population then generation order."""
    files = [(SAVED.fullmatch(f.stem), f) for f in (run.folder / "populations").glob("*.npz")]
    files = sorted((int(m[1]), int(m[2]), f) for m, f in files if m)
    if not files:
        raise BesideScreenError(f"{run.folder}/populations: no saved generations")
    return {f.stem: read_npz(f, "saved generation", ("best",))["best"] for _, _, f in files}


def screen(run: BesideRun) -> list[dict[str, Any]]:
    """Every saved best as the learned robot, on the stage's colony test starts: rows of
    ``final_test`` (``name`` added), highest run fitness first (ties: saved order)."""
    saved = saved_bests(run)
    teams = beside_teams(run.stage, run.stage.genomes(np.stack(list(saved.values()))))
    rows = final_test(teams, run.starts, run.table, run.world, run.colony, lone_robot=run.role)
    for row, name in zip(rows, saved, strict=True):
        row["name"] = name
        del row["population"]
    order = np.argsort([-r["run_fitness"] for r in rows], kind="stable")
    return [rows[i] for i in order]


def save_chromosome(run: BesideRun, name: str, out: Path) -> None:
    """Write saved best ``name`` (``popK_genG``) + the stage's navigation to ``out``."""
    saved = saved_bests(run)
    if name not in saved:
        raise BesideScreenError(f"{run.folder}: no saved best {name!r} (e.g. {next(iter(saved))})")
    bits = run.stage.genomes(saved[name][None])[0]
    write_chromosome(out, bits, f"saved best {name} of {run.folder} (robot {run.role} of its team)")


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m evolve.beside_screen",
                                 description=__doc__.splitlines()[0])  # fmt: skip
    ap.add_argument("run_dir", type=Path, help="a run folder with a 'beside' colony stage")
    ap.add_argument("--top", type=int, default=10, help="saved bests printed (10)")
    ap.add_argument("--save", nargs=2, metavar=("popK_genG", "OUT"), default=None,
                    help="write this saved best as a 16-gene chromosome file")  # fmt: skip
    args = ap.parse_args(argv)
    try:
        run = load_beside_run(args.run_dir)
        if args.save is not None:
            save_chromosome(run, args.save[0], Path(args.save[1]))
            print(f"wrote {args.save[1]}")
            return 0
        rows = screen(run)
    except InputError as exc:
        print(f"evolve.beside_screen: {exc}", file=sys.stderr)
        return 2
    r = run.colony.robots
    print(f"{args.run_dir}: {len(rows)} saved bests as robot {run.role} of {r}, "
          f"{len(run.starts)} colony test starts, run fitness {run.colony.fitness}")  # fmt: skip
    for row in rows[: args.top]:
        print(
            f"{row['name']}  fitness {row['run_fitness']:.2f}  colony inner "
            f"{row['colony_inner_percent']:.1f} %  live {row['live_at_end_per_run']:.2f} of {r}"
            f"  docks {row['docks_per_robot']:.2f}  alone {row['one_robot_inner_percent']:.1f} %"
        )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
