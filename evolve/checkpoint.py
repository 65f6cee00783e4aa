"""Checkpoint files of the GA: compressed ``.npz`` written atomically, read with named errors.

A checkpoint stores the run's settings as JSON text; resuming from a file written with other
settings is refused, so results of different runs never mix. Readers raise the caller's
``error`` class (as ``infra.io.read_json`` does) with a message naming the file.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from infra.io import atomic_write


def write_npz(path: str | Path, **arrays: Any) -> Path:
    """Write ``arrays`` to ``path`` as a compressed ``.npz``, atomically."""

    def write(tmp: Path) -> None:
        with open(tmp, "wb") as fh:
            np.savez_compressed(fh, **arrays)

    return atomic_write(path, write)


def read_npz(
    path: str | Path,
    what: str,
    keys: tuple[str, ...] = (),
    *,
    error: type[Exception] = ValueError,
) -> dict[str, np.ndarray]:
    """All arrays of ``path``; ``error`` naming the file if it cannot be read or lacks one
    of ``keys``."""
    path = Path(path)
    try:
        with np.load(path, allow_pickle=False) as z:
            data = {k: z[k] for k in z.files}
    except Exception as exc:  # zipfile.BadZipFile, OSError, ValueError, EOFError, ...
        raise error(
            f"{path}: corrupt {what} ({type(exc).__name__}: {exc}); delete it to start over"
        ) from exc
    missing = [k for k in keys if k not in data]
    if missing:
        raise error(f"{path}: corrupt {what}: missing {missing}; delete it to start over")
    return data


def check_settings(
    stored: np.ndarray, expected: str, path: Path, *, error: type[Exception] = ValueError
) -> None:
    """Refuse a file whose stored settings text differs from this run's."""
    if str(stored) != expected:
        raise error(
            f"{path}: checkpoint was written with different settings (seed, sizes, table, "
            "world or navigation section); use the same options, or run without --resume"
        )


__all__ = ["check_settings", "read_npz", "write_npz"]
