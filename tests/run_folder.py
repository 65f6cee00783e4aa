"""Comparing run folders bit for bit (tests' helper, not a test module)."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np


def result_files(folder: Path) -> dict[str, bytes | dict]:
    """Every result file under ``folder`` (npz as arrays, summary without wall time)."""
    out: dict[str, bytes | dict] = {}
    for p in sorted(folder.rglob("*")):
        if not p.is_file() or p.suffix == ".png":
            continue
        rel = str(p.relative_to(folder))
        if p.suffix == ".npz":
            with np.load(p) as z:
                out[rel] = {k: z[k].tobytes() for k in z.files}
        elif p.name == "summary.json":
            doc = json.loads(p.read_text())
            doc.pop("wall_s"), doc.pop("resumed")
            out[rel] = doc
        else:
            out[rel] = p.read_bytes()
    return out
