"""More random lineages for an evolved stage: its folder grown to name more populations.

Population k of a stage draws its numbers from child 1 + k of the stage's seed
(``evolve.population.stage_seeds``), never from how many populations run, so a stage of P
populations is the first P of the same stage with N > P, bit for bit. Growing the folder
rewrites its ownership record (``settings.json``) and its checkpoints' recorded settings to
name N populations; ``servobot evolve STAGE <the same options> --populations N --resume``
then keeps populations 0 … P−1 from their checkpoints, evolves P … N−1, and writes the
outputs of all N (Figure 9, summary, bests): the files of a fresh N-population run.

Run: ``python -m evolve.grow STAGE_DIR --populations N`` (``STAGE_DIR`` = ``RUN/navigation``
or ``RUN/coverage``). Growing an interrupted stage is allowed; a second grow to the same N
changes nothing. Only navigation and coverage stages grow: theirs is the independence the
tests check (a colony stage's teams and partners are not covered).
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path
from typing import Any

import numpy as np

from evolve.checkpoint import read_npz, write_npz
from infra.errors import InputError
from infra.io import atomic_write_json, read_json
from infra.rundir import COMMAND_KEY, RECORD_FILE, folder_lock, record_command

GROWABLE = ("evolve navigation", "evolve coverage")
"""The stage commands whose folders may grow."""


class GrowError(InputError, ValueError):
    """A folder that cannot grow; the message names the folder or file and why."""


def _grown(doc: dict[str, Any], populations: int) -> dict[str, Any]:
    """``doc`` (a stage's settings) naming ``populations`` populations."""
    return {**doc, "GASettings": {**doc["GASettings"], "populations": populations}}


def _settings_text(record: dict[str, Any]) -> str:
    """The settings text a stage's checkpoints carry: its record less the command, sorted."""
    return json.dumps({k: v for k, v in record.items() if k != COMMAND_KEY}, sort_keys=True)


def grow(folder: str | Path, populations: int) -> tuple[int, int]:
    """Grow the stage in ``folder`` to ``populations``; returns (populations before,
    checkpoints rewritten). Every file is checked before any is written."""
    folder = Path(folder)
    record_path = folder / RECORD_FILE
    if not folder.is_dir():
        raise GrowError(f"{folder}: no such folder; STAGE_DIR is a stage's, e.g. RUN/coverage")
    with folder_lock(folder, option="STAGE_DIR"):
        record = read_json(record_path, what="stage settings record", error=lambda msg: GrowError(
            f"{msg}; STAGE_DIR is a stage's folder, e.g. RUN/coverage"))  # fmt: skip
        command = record_command(record)
        if command not in GROWABLE:
            raise GrowError(f"{record_path}: a {command!r} run; only {' and '.join(GROWABLE)} "
                            "stages grow")  # fmt: skip
        before = record.get("GASettings", {}).get("populations")
        if not isinstance(before, int):
            raise GrowError(f"{record_path}: names no GASettings.populations")
        if populations < before:
            raise GrowError(f"{folder}: holds {before} populations; --populations must be ≥ "
                            f"{before}, got {populations}")  # fmt: skip
        old_text = _settings_text(record)
        new_record = _grown(record, populations)
        new_text = _settings_text(new_record)
        todo = []
        for path in sorted((folder / "checkpoints").glob("*.npz")):
            data = read_npz(path, "checkpoint", ("settings",), error=GrowError)
            text = str(data["settings"])
            if text == new_text:  # grown before
                continue
            if text != old_text:
                raise GrowError(f"{path}: checkpoint written with settings other than "
                                f"{record_path}'s; nothing was changed")  # fmt: skip
            todo.append((path, data))
        for path, data in todo:
            write_npz(path, **(data | {"settings": np.str_(new_text)}))
        atomic_write_json(record_path, new_record)
    return before, len(todo)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m evolve.grow",
                                 description=__doc__.splitlines()[0])  # fmt: skip
    ap.add_argument("stage_dir", type=Path, help="a stage's folder, RUN/navigation or RUN/coverage")
    ap.add_argument("--populations", type=int, required=True, help="populations it will hold")
    args = ap.parse_args(argv)
    try:
        before, rewritten = grow(args.stage_dir, args.populations)
    except InputError as exc:
        print(f"evolve.grow: {exc}", file=sys.stderr)
        return 2
    print(f"{args.stage_dir}: {before} → {args.populations} populations ({rewritten} checkpoints "
          f"rewritten); continue it with its own options and --populations {args.populations} "
          "--resume")  # fmt: skip
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
