"""Checkpoint files of the GA: compressed ``.npz`` written atomically, read with named errors.

A checkpoint stores the run's settings as JSON text; resuming from a file written with other
settings is refused, so results of different runs never mix. Readers raise the caller's
``error`` class (as ``infra.io.read_json`` does) with a message naming the file.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from infra.bounds import LIMITS, machine_memory_bytes
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
    """All arrays of ``path``; ``error`` naming the file if it is missing, a folder, cannot be
    read, holds more than half the machine's memory uncompressed, or lacks one of ``keys``."""
    path = Path(path)
    if path.is_dir():
        raise error(f"{path}: is a folder, not a {what}")
    if not path.exists():
        raise error(f"{path}: no such {what}")
    limit = LIMITS.memory_fraction * machine_memory_bytes()
    try:
        with np.load(path, allow_pickle=False) as z:
            size = sum(info.file_size for info in z.zip.infolist())
            if size > limit:
                raise ValueError(f"{size:,} bytes uncompressed, more than this machine allows")
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


def check_array(
    data: dict[str, np.ndarray],
    key: str,
    shape: tuple[int, ...],
    path: Path,
    *,
    bits: bool = False,
    error: type[Exception] = ValueError,
) -> np.ndarray:
    """``data[key]`` if it has ``shape`` (−1 = any length) and is numeric and finite (0/1
    integers with ``bits``), else ``error`` naming the file and the array."""
    arr = data[key]
    ok_shape = arr.ndim == len(shape) and all(
        w in (-1, n) for w, n in zip(shape, arr.shape, strict=True)
    )
    kinds = "biu" if bits else "biuf"
    ok = ok_shape and arr.dtype.kind in kinds
    if ok and arr.size:
        ok = bool(np.isin(arr, (0, 1)).all()) if bits else bool(np.isfinite(arr).all())
    if not ok:
        want = "0/1 bits" if bits else "finite numbers"
        raise error(
            f"{path}: corrupt checkpoint: {key!r} is {arr.dtype} {arr.shape}, expected {want} "
            f"of shape {shape}; delete it to start over"
        )
    return arr


__all__ = ["check_array", "check_settings", "read_npz", "write_npz"]
